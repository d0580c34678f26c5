#version 460
// See-through spheres, passes 1 and 3 of the camera's fragment lists (the
// deep lists' count -> allocate -> fill, in the camera view): every sphere
// whose alpha is below 1 (scene_alpha) visits its footprint as the
// rasterizer does (exact ray-sphere test per pixel centre) and, where its
// front hit lies in front of the pixel's nearest opaque surface (the
// visibility buffer's depth word), makes a fragment:
//   MODE 0 (oit_count): atomicAdd the pixel's count;
//   MODE 1 (oit_fill):  take a slot with the pixel's atomic cursor and write
//                       (depth key, sphere id) at head + slot (head from
//                       oit_alloc).
// One pipeline for both modes, so both enumerate the same (sphere, pixel)
// pairs; large footprints go to band jobs (bands.glsl) that the fill pass
// replays, as the deep lists do. Opaque spheres have an empty footprint.
#include "raster_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// The opaque visibility buffer as 32-bit words (2k + 1: pixel k's depth).
layout(set = 0, binding = 1) uniform usamplerBuffer visWordTex;
layout(set = 0, binding = 2) buffer Count { uint counts[]; };
layout(set = 0, binding = 3) buffer Cursor { uint cursor[]; };
// Per pixel (head, count) from oit_alloc (read as texels: a gather, where a
// storage load at per-lane addresses is a scalar loop on lavapipe).
layout(set = 0, binding = 4) uniform usamplerBuffer oitHeadTex;
layout(set = 0, binding = 5) writeonly buffer Frags { uvec2 frags[]; };
layout(set = 0, binding = 6) buffer Counters { uint counters[]; };
layout(set = 0, binding = 7) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 8) buffer Inline { uint inline_bits[]; };

// The camera raster's order (raster.comp): runs of 64 spheres front to
// back, neighbours in space visited together (cache locality; a pixel's
// fragments still arrive in no useful order: shade selects them). In a
// frame that draws the LOD lists: the list positions of the camera's
// listed batches that hold see-through atoms (oit_pick.comp).
layout(set = 0, binding = 9) uniform usamplerBuffer orderTex;
#define SCENE_ATTRIBUTES
#include "scene.glsl"
#define SPHERE_AT(i) (scene_instanced() \
    ? (texelFetch(orderTex, int((i) >> BATCH_SHIFT)).x << BATCH_SHIFT) | scene_lane(i) \
    : texelFetch(orderTex, int(i)).x)
#include "push/oit_splat.glsl"

layout(constant_id = 2) const bool PERSP = false;
layout(constant_id = 3) const uint MODE = 0u;

#include "view_footprint.glsl"

Footprint band_footprint(uint id) {
    Footprint f = view_footprint(g.cam, id);
    if (scene_alpha(id) >= 1.0) f.rect = ivec4(1, 1, 0, 0);
    return f;
}

void visit(uint id, Footprint f, ivec2 t) {
    float d = footprint_depth(f, t);
    if (d < 0.0) return;
    uint k = footprint_pixel(f, t);
    // In front of the opaque surface (the empty key's word is all ones).
    if (floatBitsToUint(d) >= texelFetch(visWordTex, int(2u * k + 1u)).x) return;
    if (MODE == 0u) {
        atomicAdd(counts[k], 1u);
        return;
    }
    uvec2 hc = texelFetch(oitHeadTex, int(k)).xy;
    if (hc.x == F_NONE) return; // its tile did not fit: the frame is rendered again
    uint slot = atomicAdd(cursor[k], 1u);
    uint addr = hc.x + slot;
    if (slot >= hc.y || addr >= pc.capacity) {
        atomicAdd(counters[F_FILL_ERRORS], 1u);
        return;
    }
    frags[addr] = uvec2(floatBitsToUint(d), id);
}

bool band_queue() { return MODE == 0u; }
// (the job list was full: this invocation visits the footprint, its fill
// replays it; lavapipe ends a loop after 65,535 back-edges, so a larger
// one would lose rows: the frame is drawn again with a longer list,
// src/stages/see_through.rs `after_frame`; a smaller one is exact here)
void band_inline(uint id, uint area) {
    atomicOr(inline_bits[id >> 5], 1u << (id & 31u));
    atomicOr(counters[F_INLINED], 1u);
    if (area > BAND_INLINE_SAFE) atomicOr(counters[F_BANDS_FULL], 1u);
}
bool band_replay(uint id) { return (inline_bits[id >> 5] & (1u << (id & 31u))) != 0u; }
#define BAND_REQ F_BANDS_REQ
#define BAND_RUN F_BANDS_RUN
#include "bands.glsl"
