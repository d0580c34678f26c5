#version 460
// See-through spheres, pass 2 of the camera's fragment lists (allocate), as
// deep_alloc.comp does for the light's, one invocation per 8x8-pixel tile:
// a running sum over the tile's 64 counts, one atomicAdd on the pool
// counter for the whole tile; each pixel's fragments are contiguous from
// its head, written with its count (fill and shade read the pair with
// one fetch). (Serial per tile, not a 64-lane shared-memory scan: on
// lavapipe the scan's barriers cost 13 ms at 480x360, the loop about a
// tenth; on a GPU the pass is small either way.) A tile that does not fit
// gets no heads (F_NONE) and the overflow flag is set; the counter still
// advances, so after the frame it holds what the whole frame needs (the
// renderer grows the pool to that and renders the frame again).
#include "shared.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Count { uint counts[]; };
layout(set = 0, binding = 2) writeonly buffer Head { uvec2 heads[]; };
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

#include "push/oit_alloc.glsl"

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint tiles_x = (w + 7u) / 8u;
    uint tile = gl_GlobalInvocationID.x;
    if (tile >= tiles_x * ((h + 7u) / 8u)) return;
    uvec2 o = uvec2(tile % tiles_x, tile / tiles_x) * 8u;
    uint x1 = min(o.x + 8u, w), y1 = min(o.y + 8u, h);
    uint total = 0u, most = 0u, pixels = 0u;
    for (uint y = o.y; y < y1; ++y) {
        for (uint x = o.x; x < x1; ++x) {
            uint c = counts[y * w + x];
            total += c;
            most = max(most, c);
            pixels += c > 0u ? 1u : 0u;
        }
    }
    uint base = F_NONE;
    if (total > 0u) {
        uint b = atomicAdd(counters[F_TOTAL], total);
        if (b < pc.capacity && total <= pc.capacity - b) {
            base = b;
        } else {
            atomicOr(counters[F_OVERFLOW], 1u);
        }
        atomicMax(counters[F_MAX], most);
        atomicAdd(counters[F_PIXELS], pixels);
    }
    uint run = 0u;
    for (uint y = o.y; y < y1; ++y) {
        for (uint x = o.x; x < x1; ++x) {
            uint k = y * w + x;
            uint c = counts[k];
            heads[k] = uvec2((c > 0u && base != F_NONE) ? base + run : F_NONE, c);
            run += c;
        }
    }
}
