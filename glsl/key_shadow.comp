#version 460
// Screen-space key-light shadows (seed 001): march the depth buffer from the
// visible point toward the key light in fixed steps; a step that passes
// behind a visible surface (within `thickness`) of another sphere is in
// shadow. Used when no exact shadow technique runs (--shadows none); the
// ISSM and deep lists are exact for spheres, so their result is used as is.
#include "ssdo_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 2) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 3) readonly buffer GNorm { vec4 gnorm[]; };
layout(set = 0, binding = 4) writeonly buffer Shadow { float shadow[]; };

layout(push_constant) uniform Push {
    float march;     // march length in world units
    float thickness; // assumed thickness of visible surfaces
    uint steps;
    float pad;
} pc;

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    vec4 n4 = gnorm[i];
    if (n4.w == 0.0) { shadow[i] = 1.0; return; }
    uint self_id = uint(vis[i] & 0xFFFFFFFFul);
    vec3 x = gpos[i].xyz + n4.xyz * 1e-3;
    vec3 l = -normalize(g.light_dir.xyz);
    float rot = hash12(uvec2(i % w, i / w));
    float v = 1.0;
    for (uint j = 1u; j <= pc.steps; ++j) {
        vec3 p = x + l * (pc.march * (float(j) - 1.0 + rot) / float(pc.steps));
        vec2 px = round(project_px(g.cam, p));
        if (px.x < 0.0 || px.y < 0.0 || px.x >= float(w) || px.y >= float(h)) break;
        uint q = uint(px.y) * w + uint(px.x);
        if (gnorm[q].w == 0.0 || uint(vis[q] & 0xFFFFFFFFul) == self_id) continue;
        float dz = view_z(g.cam, p) - view_z(g.cam, gpos[q].xyz);
        if (dz > 0.0 && dz < pc.thickness) { v = 0.0; break; }
    }
    shadow[i] = v;
}
