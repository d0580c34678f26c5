// 8x8 pixel tiles per 64-invocation workgroup.
//
// TILE_LIST (a specialization constant, id TILE_LIST_ID, which the
// includer defines with TILE_LIST_BINDING for the lists' buffer):
//   0: every tile of the grid, in an interleaved order: lavapipe's two
//      worker threads each take a fixed half of a dispatch's workgroups
//      (docs/LAVAPIPE.md), so consecutive workgroups alternate between the
//      two halves of the tile list and a lopsided image still splits evenly;
//   1: only the tiles of the 16x16-pixel regions coverage.comp found
//      covered (their list order, built by atomics from both halves of the
//      image, interleaves too), 4 workgroups per region at full
//      resolution, 1 at half (a region is 8x8 blocks);
//   2: only the background regions' tiles. The includer compiles its
//      background path alone there: lavapipe would run the covered path's
//      straight-line code on them even though no lane takes it.
// Needs `Globals g` (the camera's buffer size) before inclusion.
#ifndef TILES_GLSL
#define TILES_GLSL

layout(constant_id = TILE_LIST_ID) const uint TILE_LIST = 0u;
layout(set = 0, binding = TILE_LIST_BINDING) readonly buffer TileLists { uint tile_lists[]; };

// The top-left pixel of this workgroup's tile of a w x h grid (the full
// resolution, or the half-resolution blocks when half_grid) (false: no
// tile, the whole workgroup has nothing to do).
bool tile_origin(uint w, uint h, bool half_grid, out uvec2 origin) {
    uint wg = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (TILE_LIST == 0u) {
        uint tiles_x = (w + 7u) / 8u, tiles_y = (h + 7u) / 8u;
        uint tiles = tiles_x * tiles_y;
        if (wg >= tiles) return false;
        uint first = (tiles + 1u) / 2u;
        uint tile = wg < first ? 2u * wg : 2u * (wg - first) + 1u;
        origin = uvec2(tile % tiles_x, tile / tiles_x) * 8u;
        return true;
    }
    uint k = half_grid ? wg : wg >> 2;
    if (k >= tile_lists[TILE_LIST == 1u ? TL_COVERED : TL_BACKGROUND]) return false;
    uint regions = ((g.cam.dims.x + TL_REGION - 1u) / TL_REGION) * ((g.cam.dims.y + TL_REGION - 1u) / TL_REGION);
    uint e = tile_lists[TL_LIST + (TILE_LIST == 1u ? k : regions - 1u - k)];
    uvec2 r = uvec2(e & 0xFFFFu, e >> 16);
    origin = half_grid ? r * 8u : r * TL_REGION + uvec2(wg & 1u, (wg >> 1) & 1u) * 8u;
    return true;
}

// Whether pixel px of the buffer is in the active rectangle (see
// ACTIVE_RECT in shared.glsl; needs `Globals g`).
#define IN_ACTIVE(px) (float(px.x) >= ACTIVE_RECT(g).x && float(px.y) >= ACTIVE_RECT(g).y && float(px.x) < ACTIVE_RECT(g).z && float(px.y) < ACTIVE_RECT(g).w)

// Whether 2x2 block b (half resolution) overlaps the active rectangle.
#define IN_ACTIVE_BLOCK(b) (float(2u * b.x + 1u) >= ACTIVE_RECT(g).x && float(2u * b.y + 1u) >= ACTIVE_RECT(g).y && float(2u * b.x) < ACTIVE_RECT(g).z && float(2u * b.y) < ACTIVE_RECT(g).w)

// The pixel (or block) this invocation handles in a w x h grid, or false
// past the edge.
bool tile_pixel(uint w, uint h, bool half_grid, out uvec2 px) {
    uvec2 origin;
    if (!tile_origin(w, h, half_grid, origin)) return false;
    px = origin + uvec2(gl_LocalInvocationID.x & 7u, gl_LocalInvocationID.x >> 3);
    return px.x < w && px.y < h;
}
#endif
