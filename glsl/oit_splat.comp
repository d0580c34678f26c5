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
// BATCHES: the camera's depth tiles of this frame's final opaque image
// (lod_hiz.comp: per tile the farthest depth word of its pixels; fine
// tiles of 2^pc.hiz_shift pixels, then coarse and super ones, 2-px ones
// from pc.micro_base).
layout(set = 0, binding = 10) uniform usamplerBuffer hizTex;
// BATCHES: per invocation (a part of a picked batch) the atoms the count
// found may make fragments, a bit each: the fill visits those without
// testing the part's atoms again.
layout(set = 0, binding = 11) buffer Masks { uint masks[]; };
#define SCENE_ATTRIBUTES
#include "scene.glsl"
#define SPHERE_AT(i) (scene_instanced() \
    ? (texelFetch(orderTex, int((i) >> BATCH_SHIFT)).x << BATCH_SHIFT) | scene_lane(i) \
    : texelFetch(orderTex, int(i)).x)
#include "push/oit_splat.glsl"

layout(constant_id = 2) const bool PERSP = false;
layout(constant_id = 3) const uint MODE = 0u;
// The picked batches per batch (an orthographic camera's LOD lists), as
// raster.comp's CAM_BATCHES: one invocation per BATCH_PART_SLOTS slots of
// a picked batch reads its record and transform once and projects each
// atom by the transform's linear map; only the see-through atoms whose
// rectangle the final opaque image's tiles do not hide take the per-slot
// path (band_sphere_id: the same footprints, so the same fragments). Per
// slot, each of the ~11 M slots of meso 10^9's overview paid its batch
// record and placement, most of them for an atom behind the opaque
// surface (count 237 and fill 274 ms with no pixel visited).
layout(constant_id = 4) const bool BATCHES = false;

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
void splat_spheres();
#define BAND_SPHERE_MAIN splat_spheres
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

#define TILE_WORD(prev, i) texelFetch(hizTex, (i)).x
#define TILE_TEXELS(prev) textureSize(hizTex)
#include "atom_tests.glsl"
#include "batch_parts.glsl"
// (raster.comp's: a part's loops stay within lavapipe's 65,535 back-edges)
const uint CAM_PART_AREA = 128u;

uint part_candidates(uint id0, uint from);

void batch_part() {
    const uint PARTS = batch_parts(1u << BATCH_SHIFT);
    uint e = FLAT_ID / PARTS;
    // (the dispatch rounds up to whole workgroups: past the picked ones)
    if (e >= min(counters[F_PICKED], pc.sphere_count >> BATCH_SHIFT)) return;
    uint id0 = texelFetch(orderTex, int(e)).x << BATCH_SHIFT;
    uint from = (FLAT_ID % PARTS) * BATCH_PART_SLOTS;
    uint cand = 0u;
    if (MODE == 0u) {
        cand = part_candidates(id0, from);
        masks[FLAT_ID] = cand;
    } else {
        cand = masks[FLAT_ID];
    }
    for (; cand != 0u; cand &= cand - 1u) {
        band_sphere_id(id0 + from + uint(findLSB(cand)), min(pc.big_area, CAM_PART_AREA));
    }
}

// The atoms of a part (slots from `from` of the batch at slot id0) that
// may make a fragment: see-through, and the final opaque image's tiles do
// not hide their rectangle.
uint part_candidates(uint id0, uint from) {
    uvec4 b = scene_batch(id0);
    uint count = min(b.w & 0xFFu, from + BATCH_PART_SLOTS);
    View v = g.cam;
    vec3 p0 = instance_apply(b.x, vec3(0.0));
    mat3 ax = mat3(instance_linear(b.x, vec3(1.0, 0.0, 0.0)),
                   instance_linear(b.x, vec3(0.0, 1.0, 0.0)),
                   instance_linear(b.x, vec3(0.0, 0.0, 1.0)));
    AtomMap m = atom_map(v, p0, ax);
    uint cand = 0u;
    for (uint j = from; j < count; ++j) {
        vec4 a = texelFetch(sphereTex, int(b.y + j));
        float alpha = float(texelFetch(colorTex, int(b.y + j)).x >> 24u) / 255.0 * g.alpha.x;
        ivec4 rc;
        uint near;
        atom_rect(v, m, a, rc, near);
        bool draw = alpha < 1.0 && rc.x <= rc.z && rc.y <= rc.w && !tiles_hide(false, v, rc, near);
        cand |= draw ? 1u << (j - from) : 0u;
    }
    return cand;
}

void splat_spheres() {
    if (BATCHES) {
        batch_part();
    } else {
        band_sphere();
    }
}
