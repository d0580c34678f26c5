#version 460
// The LOD cull's counts into indirect dispatch arguments: per list
// (camera early, light early, camera late, light late) the rasterizer's,
// enough workgroups for every slot of the listed batches (and for one
// invocation per BATCH_PART_SLOTS of them: the per-batch rasters); per
// view the late phase's two cull passes', one invocation per deferred
// instance and per deferred batch (lod_cull.comp, 64 a workgroup). 2D as
// band_args.comp makes them.
#include "constants.glsl"
#include "grid.glsl"
#include "batch_parts.glsl"

layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Counters { uint counters[]; };
#include "push/lod_args.glsl"

void dispatch_args(uint at, uint invocations, uint local_size) {
    uvec3 a = grid_of((invocations + local_size - 1u) / local_size);
    counters[at] = a.x;
    counters[at + 1u] = a.y;
    counters[at + 2u] = a.z;
}

void main() {
    for (uint v = 0u; v < LOD_VIEWS; ++v) {
        uint w = v * LOD_WORDS;
        uint listed = min(counters[w + LOD_BATCHES], pc.capacity);
        dispatch_args(w + LOD_ARGS, listed * pc.per, pc.local_size);
        uint parts = listed * batch_parts(pc.per);
        dispatch_args(w + LOD_BATCH_ARGS, parts, pc.local_size);
        // (the camera's recheck: nothing where its tiles are last frame's)
        if (v == 0u) {
            bool changed = counters[LOD_TILES_CHANGED] != 0u;
            dispatch_args(LOD_RECHECK_ARGS, changed ? parts : 0u, pc.local_size);
        }
        if (v < 2u) {
            dispatch_args(w + LOD_DEFER_INSTANCE_ARGS, counters[w + LOD_DEFER_INSTANCES], 64u);
            dispatch_args(w + LOD_DEFER_BATCH_ARGS, min(counters[w + LOD_DEFER_BATCHES], pc.deferred), 64u);
        }
    }
}
