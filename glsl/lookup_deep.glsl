// Deep shadow lists lookup (after deep shadow maps on the GPU): the texel of the light map containing
// P's projection lists every sphere whose disk overlaps that texel, hence
// every sphere the ray from P toward the key light can cross. Walk the list
// front to back (sorted by depth from the light) and test the ray exactly
// against each entry except the receiver: visibility = product of
// (1 - alpha) over the spheres crossed with their far intersection ahead of
// P. Entries starting beyond P's own depth cannot be crossed ahead of P,
// which ends the walk early, as does zero visibility.
// Parameters: shadow_u.x = entry capacity.
#include "deep.glsl"

// (read as texels: a gather, where a storage load at per-lane addresses is
// a scalar loop on lavapipe; a DeepTexel or DeepTile is one RGBA32UI texel)
layout(set = 0, binding = 16) uniform usamplerBuffer deepTexelTex;
layout(set = 0, binding = 17) uniform usamplerBuffer deepTileTex;
layout(set = 0, binding = 18) uniform samplerBuffer deepDepthTex;
layout(set = 0, binding = 19) uniform samplerBuffer deepAlphaTex;
layout(set = 0, binding = 20) uniform usamplerBuffer deepIdTex;

float key_visibility(Surface s, uint pixel) {
    vec3 p = s.p;
    View L = g.light;
    vec3 dl = -L.dir.xyz; // toward the light
    vec3 q = p - L.center.xyz;
    float n = L.right.w, hh = L.up.w;
    vec2 u = light_uv(L, p);
    // The texel containing P (clamped: the light view encloses every sphere).
    ivec2 t = clamp(ivec2(floor(u)), ivec2(0), ivec2(int(n) - 1, int(hh) - 1));
    uint map_w = L.dims.x;
    // An overflowed tile: this frame is discarded and rendered again with a
    // larger pool.
    if ((texelFetch(deepTileTex, int(deep_tile_of(t, map_w))).w & DEEP_TILE_OVERFLOWED) != 0u) return 1.0;
    // (count, fill, head, nodes)
    uvec4 tx = texelFetch(deepTexelTex, int(uint(t.y) * map_w + uint(t.x)));
    uint cnt = min(tx.x, tx.y);
    float pd = dot(q, L.dir.xyz) + L.depth.x;
    float limit = pd + 1e-3 + 1e-5 * abs(pd);
    float v = 1.0;
    uint addr = tx.z;
    uint capacity = g.shadow_u.x;
    for (uint k = 0u; k < cnt && addr < capacity; ++k) {
        if (texelFetch(deepDepthTex, int(addr)).x > limit) break;
        uint id = texelFetch(deepIdTex, int(addr)).x;
        if (id != s.id && id < g.counts.x) {
            vec4 sp = scene_sphere(id);
            vec3 oc = sp.xyz - p;
            float kk = dot(oc, dl);
            vec3 perp = oc - kk * dl;
            float d2 = dot(perp, perp);
            float r2 = sp.w * sp.w;
            // Crossed with the far intersection ahead of P (toward the light).
            if (d2 < r2 && kk + sqrt(r2 - d2) > 0.0) {
                v *= 1.0 - texelFetch(deepAlphaTex, int(addr)).x;
                if (v <= 0.0) break;
            }
        }
        // (a texel's entries are contiguous, head + k: no dependent fetch of
        // the link, which deep_sort still writes)
        addr += 1u;
    }
    return v;
}
