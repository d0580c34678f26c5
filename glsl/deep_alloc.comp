#version 460
// Deep shadow lists, pass 2 (allocate): one 64-invocation workgroup per 8x8
// tile, one invocation per texel. A shared-memory prefix sum over the
// tile's texel counts gives every texel its offset inside the tile; one
// invocation then reserves ceil(total / 64) chunks for the whole tile with a
// single atomicAdd on the global pool counter (the tile's chunk table is
// that contiguous run: first chunk + chunk count). If the run does not fit,
// the tile is flagged overflowed, gets no chunks, and the fill and shadow
// passes skip it; the pool counter still advances, so after the frame it
// holds exactly the number of chunks the whole map needs (the renderer grows
// the pool to that and renders again). Nothing waits on another invocation
// except through barrier().
#include "deep.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) buffer Texels { DeepTexel texels[]; };
layout(set = 0, binding = 2) writeonly buffer Tiles { DeepTile tiles[]; };
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

#include "push/deep_alloc.glsl"

shared uint s_scan[64];
shared uint s_first;
shared uint s_max;
shared uint s_nonempty;

void main() {
    uint map_w = g.light.dims.x, map_h = g.light.dims.y;
    uint tiles_x = (map_w + DEEP_TILE - 1u) / DEEP_TILE;
    uint l = gl_LocalInvocationID.x;
    uvec2 t = gl_WorkGroupID.xy * DEEP_TILE + uvec2(l % DEEP_TILE, l / DEEP_TILE);
    bool inside = t.x < map_w && t.y < map_h;
    uint ti = t.y * map_w + t.x;
    uint c = inside ? texels[ti].count : 0u;
    if (l == 0u) {
        s_max = 0u;
        s_nonempty = 0u;
    }
    s_scan[l] = c;
    barrier();
    if (c > 0u) {
        atomicMax(s_max, c);
        atomicAdd(s_nonempty, 1u);
    }
    // Inclusive Hillis-Steele scan (64 entries, 6 steps).
    for (uint off = 1u; off < 64u; off <<= 1) {
        uint v = l >= off ? s_scan[l - off] : 0u;
        barrier();
        s_scan[l] += v;
        barrier();
    }
    uint total = s_scan[63];
    uint offset = s_scan[l] - c; // exclusive
    if (l == 0u) {
        uint k = (total + DEEP_CHUNK - 1u) / DEEP_CHUNK;
        uint first = DEEP_NONE, chunks = 0u, flags = 0u;
        if (k > 0u) {
            uint base = atomicAdd(counters[C_CHUNKS], k);
            if (base < pc.chunk_capacity && k <= pc.chunk_capacity - base) {
                first = base;
                chunks = k;
            } else {
                flags = DEEP_TILE_OVERFLOWED;
                atomicOr(counters[C_OVERFLOW], 1u);
                atomicAdd(counters[C_DROPPED], total);
            }
            atomicAdd(counters[C_ENTRIES], total);
            atomicMax(counters[C_MAX_COUNT], s_max);
            atomicAdd(counters[C_NONEMPTY], s_nonempty);
        }
        tiles[gl_WorkGroupID.y * tiles_x + gl_WorkGroupID.x] = DeepTile(first, chunks, total, flags);
        s_first = first;
    }
    barrier();
    if (inside) {
        uint first = s_first;
        texels[ti].head = (c > 0u && first != DEEP_NONE) ? first * DEEP_CHUNK + offset : DEEP_NONE;
    }
}
