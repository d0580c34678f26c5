#version 460
// Graphics raster baseline: each sphere is a screen-aligned quad (two
// triangles, vertices pulled from the sphere buffer by gl_VertexIndex) over
// the same pixel rectangle the compute rasterizer tests; the fragment shader
// does the same exact ray-sphere test and atomicMin.
#include "raster_common.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };

layout(push_constant) uniform Push { uint view_index; } pc;

layout(location = 0) flat out uint v_id;

void main() {
    uint id = uint(gl_VertexIndex) / 6u;
    uint corner = uint(gl_VertexIndex) % 6u;
    View v = pc.view_index == 0u ? g.cam : g.light;
    vec4 s = spheres[id];
    ivec4 rc = sphere_rect(v, view_space(v, s.xyz, v.dir.w != 0.0), s.w, v.dir.w != 0.0);
    v_id = id;
    if (rc.x > rc.z || rc.y > rc.w) {
        gl_Position = vec4(2.0, 2.0, 0.0, 1.0); // degenerate, outside: no fragments
        return;
    }
    // Pixel centres x0..x1 are covered by the quad [x0, x1 + 1] in framebuffer units.
    const uvec2 CORNERS[6] = uvec2[](uvec2(0, 0), uvec2(1, 0), uvec2(0, 1), uvec2(1, 0), uvec2(1, 1), uvec2(0, 1));
    uvec2 c = CORNERS[corner];
    vec2 px = vec2(c.x == 0u ? float(rc.x) : float(rc.z + 1), c.y == 0u ? float(rc.y) : float(rc.w + 1));
    vec2 ndc = px / vec2(v.dims.xy) * 2.0 - 1.0;
    gl_Position = vec4(ndc, 0.0, 1.0);
}
