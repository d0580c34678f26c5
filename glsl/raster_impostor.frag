#version 460
// Fragment half of the graphics raster baseline (see raster_impostor.vert).
#extension GL_EXT_shader_atomic_int64 : require
#include "raster_common.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) buffer Vis { uint64_t vis[]; };

layout(push_constant) uniform Push { uint view_index; } pc;

layout(location = 0) flat in uint v_id;

void main() {
    View v = pc.view_index == 0u ? g.cam : g.light;
    vec4 s = spheres[v_id];
    ivec2 p = ivec2(gl_FragCoord.xy);
    bool persp = v.dir.w != 0.0; // (a real GPU skips the side not taken)
    float d = hit_depth(v, view_space(v, s.xyz, persp), s.w, vec2(p), persp);
    if (d >= 0.0) atomicMin(vis[uint(p.y) * v.dims.x + uint(p.x)], vis_key(d, v_id));
}
