#version 460
// See-through spheres in a frame that draws the LOD lists: which listed
// batches the fragments' count and fill visit (oit_splat.comp, through
// orderTex as the static table's order), so that opaque instances cost
// them nothing (a see-through envelope on meso 10^9: the fragments had
// visited all 1.4 M listed spheres a pass for none of them):
//   MODE 0: per stored atom (levels' copies too), a bit per block of 64
//           stored atoms where one has alpha below 1 (colorTex);
//   MODE 1: per entry of a camera list (pc.list_base: its first entry,
//           counted in word pc.list_word of the LOD counters), appended
//           (its list position) where its stored atoms meet such a block,
//           or every entry where --opacity is below 1;
//   MODE 2: one invocation: the splat's indirect dispatch arguments,
//           pc.per_batch invocations per picked batch (its 2^BATCH_SHIFT
//           slots, or its parts: oit_splat.comp BATCHES).
#include "shared.glsl"
#include "grid.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer LodCounters { uint lod[]; };
layout(set = 0, binding = 2) buffer Blocks { uint blocks[]; };
layout(set = 0, binding = 3) writeonly buffer Picked { uint picked[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };
#define SCENE_ATTRIBUTES
#include "scene.glsl"
#include "push/oit_pick.glsl"

layout(constant_id = 1) const uint MODE = 0u;

bool block_set(uint b) { return ((blocks[b >> 5u] >> (b & 31u)) & 1u) != 0u; }

void main() {
    uint i = FLAT_ID;
    if (MODE == 0u) {
        if (i >= pc.capacity) return;
        if ((texelFetch(colorTex, int(i)).x >> 24u) < 255u) atomicOr(blocks[i >> 11u], 1u << ((i >> 6u) & 31u));
        return;
    }
    if (MODE == 2u) {
        if (i != 0u) return;
        uint n = min(counters[F_PICKED], pc.room);
        uint groups = (n * pc.per_batch + gl_WorkGroupSize.x - 1u) / gl_WorkGroupSize.x;
        uvec3 a = grid_of(groups);
        counters[F_PICK_ARGS] = a.x;
        counters[F_PICK_ARGS + 1u] = a.y;
        counters[F_PICK_ARGS + 2u] = a.z;
        return;
    }
    if (i >= min(lod[pc.list_word], pc.capacity)) return;
    uint entry = pc.list_base + i;
    uvec4 b = scene_batch(entry << BATCH_SHIFT);
    uint count = b.w & 0xFFu;
    if (count == 0u) return;
    uint first = b.y >> 6u, last = (b.y + count - 1u) >> 6u;
    if (g.alpha.x < 1.0 || block_set(first) || block_set(last)) {
        uint at = atomicAdd(counters[F_PICKED], 1u);
        if (at < pc.room) picked[at] = entry;
    }
}
