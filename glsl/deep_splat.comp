#version 460
// Deep shadow lists, passes 1 and 3 (count and fill), one pipeline for both
// so that both enumerate exactly the same (sphere, texel) pairs:
//   mode DEEP_COUNT: atomicAdd the texel's entry count;
//   mode DEEP_FILL:  take a slot with the texel's atomic fill cursor and
//                    write the entry at head + slot (head from deep_alloc).
// Every sphere whose light-space disk overlaps a texel's square gets an entry
// there (conservative, not only texel centres, not only the nearest sphere),
// so the light ray from any point inside the texel can only cross spheres
// listed in that texel.
//
// Why count -> allocate -> fill instead of the paper's allocate-on-the-fly:
// the CUDA version lets one thread grab a chunk while the others of the tile
// busy-wait on it in a "pending" state. Vulkan gives no forward-progress
// guarantee between invocations, so a spin-wait can hang; with separate
// passes every atomic is wait-free and each texel's entries end up
// contiguous, which also makes the per-texel sort and the walk cheap.
//
// Large footprints (more than big_area texels) are cut into 8-row bands
// (the skeleton of bands.glsl): the count pass appends them to a job list
// that whole workgroups process, so one big sphere never serialises
// thousands of texels on one invocation; the fill pass replays the same
// jobs. If the job list is full the sphere is marked in inline_bits and its
// own invocation loops in both modes. The mode is specialization constant 2.
#include "deep.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 2) buffer Texels { DeepTexel texels[]; };
// What the fill reads of the texel and tile tables, as texels (a gather,
// where a storage load at per-lane addresses is a scalar loop on
// lavapipe): the texels' count and head words one R32 word each (their
// fill cursors change in this pass; those words are never read through the
// view), the tiles whole (RGBA32UI: first_chunk, chunks, entries, flags).
layout(set = 0, binding = 3) uniform usamplerBuffer deepTexelWordTex;
layout(set = 0, binding = 10) uniform usamplerBuffer deepTileTex;
layout(set = 0, binding = 4) writeonly buffer Depth { float e_depth[]; };
layout(set = 0, binding = 5) writeonly buffer Alpha { float e_alpha[]; };
layout(set = 0, binding = 6) writeonly buffer Ids { uint e_id[]; };
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };
layout(set = 0, binding = 8) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 9) buffer Inline { uint inline_bits[]; };

layout(constant_id = 2) const uint MODE = DEEP_COUNT;

#include "push/deep_splat.glsl"
#define SCENE_ATTRIBUTES
#include "scene.glsl"
// The light's sphere order (src/stages/raster/compute.rs `view_order`: runs
// front to back along the light, the dispatch's two halves on either side
// of it; instanced scenes: batches): each texel's entries arrive nearly in
// depth order, which deep_sort's Shell sort moves little.
layout(set = 0, binding = 11) uniform usamplerBuffer orderTex;
#define SPHERE_AT(i) (scene_instanced() \
    ? (texelFetch(orderTex, int((i) >> BATCH_SHIFT)).x << BATCH_SHIFT) | scene_lane(i) \
    : texelFetch(orderTex, int(i)).x)

Footprint band_footprint(uint id) {
    vec4 s = scene_sphere(id);
    Footprint f = deep_footprint(g.light, s);
    // (an unused slot of an instanced batch has no footprint)
    if (scene_instanced() && s.w < 0.0) f.rect = ivec4(1, 1, 0, 0);
    return f;
}

void visit(uint id, Footprint f, ivec2 t) {
    if (!deep_overlaps(f, t)) return;
    uint map_w = g.light.dims.x;
    uint ti = uint(t.y) * map_w + uint(t.x);
    if (MODE == DEEP_COUNT) {
        atomicAdd(texels[ti].count, 1u);
        return;
    }
    // A tile that did not fit in the pool has no chunks: skip it.
    if ((texelFetch(deepTileTex, int(deep_tile_of(t, map_w))).w & DEEP_TILE_OVERFLOWED) != 0u) return;
    uint slot = atomicAdd(texels[ti].fill, 1u);
    uint head = texelFetch(deepTexelWordTex, int(4u * ti + 2u)).x;
    uint addr = head + slot;
    // Never write outside the texel's run (would only happen if count and
    // fill disagreed; counted so tests see it).
    if (slot >= texelFetch(deepTexelWordTex, int(4u * ti)).x || head == DEEP_NONE
        || addr >= pc.entry_capacity) {
        atomicAdd(counters[C_FILL_ERRORS], 1u);
        return;
    }
    e_depth[addr] = f.depth;
    e_alpha[addr] = scene_alpha(id);
    e_id[addr] = id;
}

// The count pass queues the band jobs; the fill pass replays them (and the
// spheres whose job list was full, marked in inline_bits).
bool band_queue() { return MODE == DEEP_COUNT; }
// (the job list was full: this invocation counts the footprint and the fill
// replays it; lavapipe ends a loop after 65,535 back-edges, so a larger one
// would lose rows: the frame is drawn again with a longer list,
// src/stages/shadows/deep/mod.rs `grow_jobs`; a smaller one is exact here)
void band_inline(uint id, uint area) {
    atomicOr(inline_bits[id >> 5], 1u << (id & 31u));
    if (area > BAND_INLINE_SAFE) atomicOr(counters[C_BANDS_FULL], 1u);
}
bool band_replay(uint id) { return (inline_bits[id >> 5] & (1u << (id & 31u))) != 0u; }
#define BAND_REQ C_BANDS_REQ
#define BAND_RUN C_BANDS_RUN
#include "bands.glsl"
