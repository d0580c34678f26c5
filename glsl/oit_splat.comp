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
#extension GL_KHR_shader_subgroup_arithmetic : enable
#extension GL_KHR_shader_subgroup_basic : enable
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
// Instanced scenes whose key light culls (pc.receivers): the light's
// region and receiver depths (lod_bounds.comp's words; the host emptied
// them before this pass and lod_bounds adds the opaque points after):
// the count adds each sphere that made a fragment (its disc and far side
// in light space), whose lookups shade makes.
layout(set = 0, binding = 12) buffer Region { int region[]; };
#include "lod_receivers.glsl"
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

// (the count: whether this invocation's visits of the sphere made one)
bool made = false;

// Adds light-texel rectangle [lo, hi] (clamped to +-1e9) of points whose
// lookups shade makes, their farthest depth word `word` (slack and margins
// included), where `some`: the receiver tiles of the centre texels within
// it (kept one inside the map, as lod_bounds.comp does), and the region's
// rectangle once per subgroup (each lane's atomics on the same four words
// cost the count 57 ms more at meso 10^9's 2,025 A).
void add_light_points(bool some, vec2 lo, vec2 hi, uint word) {
    if (some) {
        int size = int(g.light.dims.x);
        int S = int(pc.receiver_shift);
        int tw = (size + (1 << S) - 1) >> S;
        ivec2 c0 = clamp(ivec2(round(lo)), ivec2(1), ivec2(size - 2)) >> S;
        ivec2 c1 = clamp(ivec2(round(hi)), ivec2(1), ivec2(size - 2)) >> S;
        for (int ty = c0.y; ty <= c1.y; ++ty) {
            for (int tx = c0.x; tx <= c1.x; ++tx) atomicMax(region[receiver_word(ty * tw + tx)], int(word));
        }
    }
    ivec2 a = subgroupMin(some ? ivec2(floor(lo)) : ivec2(1 << 30));
    ivec2 b = subgroupMax(some ? ivec2(ceil(hi)) : ivec2(-(1 << 30)));
    if (subgroupElect() && a.x <= b.x) {
        atomicMin(region[0], a.x);
        atomicMin(region[1], a.y);
        atomicMax(region[2], b.x);
        atomicMax(region[3], b.y);
    }
}

// The light texels of sphere id's fragments' lookups: its disc in light
// texels (grown past the rounding of the points shade finds on it) and
// its far side's depth word grown by the lookup's slack and
// lod_bounds.comp's margin.
void add_receivers(uint id) {
    if (!made) return;
    made = false;
    vec4 s = scene_sphere(id);
    View L = g.light;
    float ppu = L.center.w;
    vec3 q = s.xyz - L.center.xyz;
    vec2 p = vec2(dot(q, L.right.xyz) * ppu + 0.5 * L.right.w - 0.5,
                  0.5 * L.up.w - dot(q, L.up.xyz) * ppu - 0.5);
    float grow = 1e-5 * (coord_max(s.xyz) + coord_max(L.center.xyz)) + 1e-3;
    float rp = (s.w * 1.001 + grow) * ppu + 0.01;
    float z = dot(q, L.dir.xyz) + L.depth.x;
    float zf = z + s.w * 1.001 + grow + pc.slack + 1e-4 * (abs(z) + abs(L.depth.x)) + 1e-3;
    uint word = floatBitsToUint(max(zf, 0.0));
    vec2 lo = clamp(p - rp, vec2(-1e9), vec2(1e9)), hi = clamp(p + rp, vec2(-1e9), vec2(1e9));
    add_light_points(true, lo, hi, word);
}

void visit(uint id, Footprint f, ivec2 t) {
    float d = footprint_depth(f, t);
    if (d < 0.0) return;
    uint k = footprint_pixel(f, t);
    // In front of the opaque surface (the empty key's word is all ones).
    if (floatBitsToUint(d) >= texelFetch(visWordTex, int(2u * k + 1u)).x) return;
    if (MODE == 0u) {
        atomicAdd(counts[k], 1u);
        made = true;
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
// (per slot and per band: per sphere; the per-batch path collects its
// part's: part_receivers)
#define BAND_VISITED(id, f) \
    if (MODE == 0u && !BATCHES && scene_instanced() && pc.receivers != 0u) add_receivers(id)
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

uint part_candidates(uint id0, uvec4 b, vec3 p0, mat3 ax, uint from);
void part_receivers(uvec4 b, vec3 p0, mat3 ax, uint from, uint shown);

void batch_part() {
    const uint PARTS = batch_parts(1u << BATCH_SHIFT);
    uint e = FLAT_ID / PARTS;
    // (the dispatch rounds up to whole workgroups: past the picked ones)
    if (e >= min(counters[F_PICKED], pc.sphere_count >> BATCH_SHIFT)) return;
    uint id0 = texelFetch(orderTex, int(e)).x << BATCH_SHIFT;
    uint from = (FLAT_ID % PARTS) * BATCH_PART_SLOTS;
    uint cand = 0u;
    uvec4 b = uvec4(0u);
    vec3 p0 = vec3(0.0);
    mat3 ax = mat3(1.0);
    if (MODE == 0u) {
        b = scene_batch(id0);
        instance_map(b.x, p0, ax);
        cand = part_candidates(id0, b, p0, ax, from);
        masks[FLAT_ID] = cand;
    } else {
        cand = masks[FLAT_ID];
    }
    // (the count: which made a fragment here, for the light's receivers;
    // a candidate whose bands were queued adds its own in each band)
    uint shown = 0u;
    for (uint c = cand; c != 0u; c &= c - 1u) {
        uint j = uint(findLSB(c));
        made = false;
        band_sphere_id(id0 + from + j, min(pc.big_area, CAM_PART_AREA));
        shown |= made ? 1u << j : 0u;
    }
    if (MODE == 0u && pc.receivers != 0u) part_receivers(b, p0, ax, from, shown);
}

// The atoms of a part (slots from `from` of batch b at slot id0, placed
// at p0 with the linear map ax) that may make a fragment: see-through, and
// the final opaque image's tiles do not hide their rectangle.
uint part_candidates(uint id0, uvec4 b, vec3 p0, mat3 ax, uint from) {
    uint count = min(b.w & 0xFFu, from + BATCH_PART_SLOTS);
    View v = g.cam;
    AtomMap m = atom_map(v, p0, ax);
    uint cand = 0u;
    for (uint j = from; j < count; ++j) {
        vec4 a = texelFetch(sphereTex, int(b.y + j));
        float alpha = batch_alpha(b, id0 + j);
        ivec4 rc;
        uint near;
        atom_rect(v, m, a, rc, near);
        bool draw = alpha < 1.0 && rc.x <= rc.z && rc.y <= rc.w && !tiles_hide(false, v, rc, near);
        cand |= draw ? 1u << (j - from) : 0u;
    }
    return cand;
}

// add_receivers for the part's atoms that made a fragment (bits of
// `shown` from slot `from`), projected by the transform's linear map into
// the light's texels, together: their rectangle's receiver tiles (a
// batch's atoms mostly share a light texel) take the farthest of their
// depth words. (Per sphere, through its placement again: count 293 -> 411
// ms at meso 10^9's 2,025 A; per atom and tile here ~410.)
void part_receivers(uvec4 b, vec3 p0, mat3 ax, uint from, uint shown) {
    View L = g.light;
    AtomMap lm = atom_map(L, p0, ax);
    vec2 lo = vec2(1e9), hi = vec2(-1e9);
    float zf = 0.0;
    for (uint s = shown; s != 0u; s &= s - 1u) {
        vec4 a = texelFetch(sphereTex, int(b.y + from + uint(findLSB(s))));
        vec2 t;
        float r;
        atom_disc(L, lm, a, t, r);
        lo = min(lo, t - r);
        hi = max(hi, t + r);
        precise float z = lm.oz + dot(lm.rz, a.xyz) + L.depth.x;
        zf = max(zf, z + a.w + 1e-4 * (abs(z) + abs(L.depth.x)));
    }
    lo = clamp(lo - 0.01, vec2(-1e9), vec2(1e9));
    hi = clamp(hi + 0.01, vec2(-1e9), vec2(1e9));
    uint word = floatBitsToUint(max(zf + lm.slack + pc.slack + 1e-3, 0.0));
    add_light_points(shown != 0u, lo, hi, word);
}

void splat_spheres() {
    if (BATCHES) {
        batch_part();
    } else {
        band_sphere();
    }
}
