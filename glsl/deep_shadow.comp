#version 460
// Deep shadow lists, pass 5 (shadow lookup): for each visible point P, the
// texel of the light map containing P's projection lists every sphere whose
// disk overlaps that texel, hence every sphere the ray from P toward the key
// light can cross. Walk the list front to back (sorted by depth from the
// light) and test the ray exactly against each entry except the receiver:
// visibility = product of (1 - alpha) over the spheres crossed with their far
// intersection ahead of P. Entries starting beyond P's own depth cannot be
// crossed ahead of P, which ends the walk early, as does zero visibility.
#include "deep.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 4) readonly buffer Texels { DeepTexel texels[]; };
layout(set = 0, binding = 5) readonly buffer Tiles { DeepTile tiles[]; };
layout(set = 0, binding = 6) readonly buffer Depth { float e_depth[]; };
layout(set = 0, binding = 7) readonly buffer Alpha { float e_alpha[]; };
layout(set = 0, binding = 8) readonly buffer Ids { uint e_id[]; };
layout(set = 0, binding = 9) readonly buffer Next { uint e_next[]; };
layout(set = 0, binding = 10) writeonly buffer Shadow { float shadow[]; };

layout(push_constant) uniform Push {
    uint entry_capacity;
    uint sphere_count;
} pc;

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    uint64_t key = vis[i];
    if (key == VIS_EMPTY) {
        shadow[i] = 1.0;
        return;
    }
    uint self_id = uint(key & 0xFFFFFFFFul);
    vec3 p = gpos[i].xyz;
    View L = g.light;
    vec3 dl = -L.dir.xyz; // toward the light
    vec3 q = p - L.center.xyz;
    float n = L.right.w, hh = L.up.w;
    vec2 u = light_uv(L, p);
    // The texel containing P (clamped: the light view encloses every sphere).
    ivec2 t = clamp(ivec2(floor(u)), ivec2(0), ivec2(int(n) - 1, int(hh) - 1));
    uint map_w = L.dims.x;
    if ((tiles[deep_tile_of(t, map_w)].flags & DEEP_TILE_OVERFLOWED) != 0u) {
        // This frame is discarded and rendered again with a larger pool.
        shadow[i] = 1.0;
        return;
    }
    DeepTexel tx = texels[uint(t.y) * map_w + uint(t.x)];
    uint cnt = min(tx.count, tx.fill);
    float pd = dot(q, L.dir.xyz) + L.depth.x;
    float limit = pd + 1e-3 + 1e-5 * abs(pd);
    float v = 1.0;
    uint addr = tx.head;
    for (uint k = 0u; k < cnt && addr < pc.entry_capacity; ++k) {
        if (e_depth[addr] > limit) break;
        uint id = e_id[addr];
        if (id != self_id && id < pc.sphere_count) {
            vec4 s = spheres[id];
            vec3 oc = s.xyz - p;
            float kk = dot(oc, dl);
            vec3 perp = oc - kk * dl;
            float d2 = dot(perp, perp);
            float r2 = s.w * s.w;
            // Crossed with the far intersection ahead of P (toward the light).
            if (d2 < r2 && kk + sqrt(r2 - d2) > 0.0) {
                v *= 1.0 - e_alpha[addr];
                if (v <= 0.0) break;
            }
        }
        addr = e_next[addr];
    }
    shadow[i] = v;
}
