#version 460
// The LOD cull's batch counts (camera early, light, camera late) into the rasterizer's indirect
// dispatch arguments: enough workgroups for every slot of the listed
// batches, 2D as band_args.comp makes them.
#include "constants.glsl"

layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Counters { uint counters[]; };
#include "push/lod_args.glsl"

void main() {
    for (uint v = 0u; v < LOD_VIEWS; ++v) {
        uint w = v * LOD_WORDS;
        uint n = min(counters[w + LOD_BATCHES], pc.capacity);
        uint groups = (n * pc.per + pc.local_size - 1u) / pc.local_size;
        counters[w + LOD_ARGS] = min(groups, MAX_GROUPS_X);
        counters[w + LOD_ARGS + 1u] = groups == 0u ? 0u : (groups + MAX_GROUPS_X - 1u) / MAX_GROUPS_X;
        counters[w + LOD_ARGS + 2u] = 1u;
    }
}
