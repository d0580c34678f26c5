// 8x8 pixel tiles per 64-invocation workgroup, in an interleaved order:
// lavapipe's two worker threads each take a fixed half of a dispatch's
// workgroups (docs/LAVAPIPE.md), so consecutive workgroups alternate between
// the two halves of the tile list and a lopsided image still splits evenly.
#ifndef TILES_GLSL
#define TILES_GLSL

// The top-left pixel of this workgroup's tile (false: no tile, the whole
// workgroup has nothing to do).
bool tile_origin(uint w, uint h, out uvec2 origin) {
    uint tiles_x = (w + 7u) / 8u, tiles_y = (h + 7u) / 8u;
    uint tiles = tiles_x * tiles_y;
    uint wg = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (wg >= tiles) return false;
    uint first = (tiles + 1u) / 2u;
    uint tile = wg < first ? 2u * wg : 2u * (wg - first) + 1u;
    origin = uvec2(tile % tiles_x, tile / tiles_x) * 8u;
    return true;
}

// Whether pixel px of the buffer is in the active rectangle (see
// ACTIVE_RECT in shared.glsl; needs `Globals g`).
#define IN_ACTIVE(px) (float(px.x) >= ACTIVE_RECT(g).x && float(px.y) >= ACTIVE_RECT(g).y && float(px.x) < ACTIVE_RECT(g).z && float(px.y) < ACTIVE_RECT(g).w)

// Whether 2x2 block b (half resolution) overlaps the active rectangle.
#define IN_ACTIVE_BLOCK(b) (float(2u * b.x + 1u) >= ACTIVE_RECT(g).x && float(2u * b.y + 1u) >= ACTIVE_RECT(g).y && float(2u * b.x) < ACTIVE_RECT(g).z && float(2u * b.y) < ACTIVE_RECT(g).w)

// The pixel this invocation shades in a w x h image, or false past the edge.
bool tile_pixel(uint w, uint h, out uvec2 px) {
    uvec2 origin;
    if (!tile_origin(w, h, origin)) return false;
    px = origin + uvec2(gl_LocalInvocationID.x & 7u, gl_LocalInvocationID.x >> 3);
    return px.x < w && px.y < h;
}
#endif
