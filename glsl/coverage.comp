#version 460
// Tile lists: which 16x16-pixel regions of the visibility buffer show a
// sphere. The per-pixel passes after it (ssdo_prep, ssdo, blur, shade)
// run their full code only on covered regions and a variant compiled to
// the background path alone on the others (glsl/tiles.glsl): lavapipe runs
// the straight-line code of a branch no lane takes (docs/LAVAPIPE.md), so
// a background pixel in the full shader cost as much as a covered one.
// One invocation per region (256 id fetches); ARGS = 1: one invocation
// turns the two counts into indirect dispatch arguments. Word layout:
// TL_* in src/gpu_consts.rs.
#include "shared.glsl"
#include "grid.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const bool ARGS = false;
// See-through spheres: a pixel with fragments (oit_splat.comp) is covered.
layout(constant_id = 2) const bool SEE_THROUGH = false;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer visTex;
layout(set = 0, binding = 2) buffer TileLists { uint tile_lists[]; };
layout(set = 0, binding = 3) uniform usamplerBuffer oitCountTex;

void write_args(uint at, uint groups) {
    uvec3 a = grid_of(groups);
    tile_lists[at] = a.x;
    tile_lists[at + 1u] = a.y;
    tile_lists[at + 2u] = a.z;
}

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint rx = (w + TL_REGION - 1u) / TL_REGION, ry = (h + TL_REGION - 1u) / TL_REGION;
    uint regions = rx * ry;
    if (ARGS) {
        if (FLAT_ID != 0u) return;
        uint c = tile_lists[TL_COVERED], b = tile_lists[TL_BACKGROUND];
        // a region is 4 full-resolution 8x8 tiles, or one 8x8 tile of blocks
        write_args(TL_ARGS, 4u * c);
        write_args(TL_ARGS + 3u, 4u * b);
        write_args(TL_ARGS + 6u, c);
        write_args(TL_ARGS + 9u, b);
        return;
    }
    uint r = FLAT_ID;
    if (r >= regions) return;
    uvec2 reg = uvec2(r % rx, r / rx);
    uvec2 o = reg * TL_REGION;
    uvec2 last = uvec2(w - 1u, h - 1u);
    bool covered = false;
    // (straight-line: every fetch happens, at a clamped pixel)
    for (uint y = 0u; y < TL_REGION; ++y) {
        for (uint x = 0u; x < TL_REGION; ++x) {
            uvec2 p = min(o + uvec2(x, y), last);
            bool hit = texelFetch(visTex, int(p.y * w + p.x)).x != NO_SPHERE;
            if (SEE_THROUGH) hit = hit || texelFetch(oitCountTex, int(p.y * w + p.x)).x != 0u;
            covered = covered || hit;
        }
    }
    uint packed = reg.x | (reg.y << 16);
    if (covered) {
        uint s = atomicAdd(tile_lists[TL_COVERED], 1u);
        tile_lists[TL_LIST + s] = packed;
    } else {
        uint s = atomicAdd(tile_lists[TL_BACKGROUND], 1u);
        tile_lists[TL_LIST + regions - 1u - s] = packed;
    }
}
