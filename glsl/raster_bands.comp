#version 460
// One workgroup per band of up to 8 rows of a large sphere's footprint: the
// workgroup's invocations stride over the band's pixels.
#extension GL_EXT_shader_atomic_int64 : require
#include "raster_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) readonly buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 4) readonly buffer Counters { uint counters[]; };

layout(push_constant) uniform Push { uint view_index; } pc;

const int BAND_ROWS = 8;
const uint MAX_X = 65535;

void main() {
    uint job = gl_WorkGroupID.x + gl_WorkGroupID.y * MAX_X;
    if (job >= counters[1]) return;
    View v = pc.view_index == 0 ? g.cam : g.light;
    uvec2 jb = jobs[job];
    vec4 s = spheres[jb.x];
    vec3 cv = view_space(v, s.xyz);
    ivec4 rc = sphere_rect(v, cv, s.w);
    int y0 = int(jb.y);
    int rows = min(BAND_ROWS, rc.w - y0 + 1);
    int width = rc.z - rc.x + 1;
    uint w = v.dims.x;
    for (int i = int(gl_LocalInvocationID.x); i < width * rows; i += int(gl_WorkGroupSize.x)) {
        int x = rc.x + i % width;
        int y = y0 + i / width;
        float d = hit_depth(v, cv, s.w, vec2(x, y));
        if (d >= 0.0) atomicMin(vis[uint(y) * w + uint(x)], vis_key(d, jb.x));
    }
}
