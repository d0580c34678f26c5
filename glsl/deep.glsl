// Deep shadow lists (after deep shadow maps on the GPU): definitions shared by the deep_*.comp passes.
// Mirrors the structs of src/stages/shadows/deep.rs.
//
// Layout (the CUDA paper's, adapted): the key light's N x N map is split into
// 8x8-texel tiles; entries live in chunks of 64 in structure-of-arrays
// buffers (depth, alpha, sphere id, next link, transmittance). A link packs
// chunk << 6 | entry, which is simply the global entry index; DEEP_NONE ends
// a list. Each tile owns a contiguous run of chunks taken from one global
// pool with a single atomicAdd; inside it every texel's entries are
// contiguous (a prefix sum over the tile's texel counts), so a texel's list
// is head, head + 1, ... with its links written after sorting. Its
// epsilon-compressed visibility nodes (depth, V) live in two more SoA arrays
// of twice the entry capacity, at 2 * head, 2 * head + 1, ... (n entries give
// at most 2n nodes; see deep_sort.comp).
#ifndef DEEP_GLSL
#define DEEP_GLSL

#include "shared.glsl"

// DEEP_NONE, DEEP_CHUNK, DEEP_TILE, DEEP_DISK_SLACK, DEEP_TILE_OVERFLOWED
// and the counter word indices C_* come from constants.glsl (src/gpu_consts.rs).

struct DeepTexel {
    uint count; // entries counted (count pass)
    uint fill;  // entries written (fill pass cursor)
    uint head;  // first entry (chunk << 6 | entry), DEEP_NONE if empty or overflowed
    uint nodes; // nodes of the epsilon-compressed visibility function (at 2 * head)
};

struct DeepTile {
    uint first_chunk; // DEEP_NONE if the tile got no chunks
    uint chunks;      // chunks owned (0 when overflowed)
    uint entries;     // entries of all its texels
    uint flags;       // DEEP_TILE_OVERFLOWED
};
const uint DEEP_COUNT = 0u; // splat mode: count entries per texel
const uint DEEP_FILL = 1u;  // splat mode: write entries

// A sphere's light-map footprint: centre in continuous texel coordinates
// (texel x covers [x, x + 1), rows grow downward), radius in texels with
// the slack, inclusive texel rectangle and the list depth (light-space depth
// of the sphere's front point, with the view's depth offset, like hit_depth).
struct Footprint {
    vec2 c;
    float R;
    ivec4 rect;
    float depth;
};

Footprint deep_footprint(View L, vec4 s) {
    precise vec3 q = s.xyz - L.center.xyz;
    precise float x = dot(q, L.right.xyz);
    precise float y = dot(q, L.up.xyz);
    precise float z = dot(q, L.dir.xyz);
    float ppu = L.center.w, n = L.right.w, h = L.up.w;
    Footprint f;
    precise vec2 c = vec2(x * ppu + 0.5 * n, 0.5 * h - y * ppu);
    precise float R = s.w * ppu + DEEP_DISK_SLACK;
    f.c = c;
    f.R = R;
    vec2 lo = clamp(floor(c - R), vec2(-1.0), vec2(n, h));
    vec2 hi = clamp(floor(c + R), vec2(-1.0), vec2(n, h));
    ivec4 r = ivec4(ivec2(lo), ivec2(hi));
    f.rect = ivec4(max(r.xy, ivec2(0)), min(r.zw, ivec2(int(n) - 1, int(h) - 1)));
    f.depth = z - s.w + L.depth.x;
    return f;
}

// Does the disk overlap texel t's square? (Closest point of the square.)
bool deep_overlaps(Footprint f, ivec2 t) {
    precise vec2 d = clamp(f.c, vec2(t), vec2(t) + 1.0) - f.c;
    precise float d2 = dot(d, d);
    return d2 <= f.R * f.R;
}

uint deep_tile_of(ivec2 t, uint map_w) {
    uint tiles_x = (map_w + DEEP_TILE - 1u) / DEEP_TILE;
    return (uint(t.y) / DEEP_TILE) * tiles_x + uint(t.x) / DEEP_TILE;
}

#endif
