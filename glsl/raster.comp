#version 460
// Compute rasterization of sphere impostors (camera or key-light view, push
// constant view_index): exact ray-sphere test per covered pixel and a 64-bit
// atomicMin of depth|id into the visibility buffer. The band skeleton
// (bands.glsl) gives small footprints to one invocation per sphere and
// large ones, in 8-row bands, to whole workgroups (BAND_PASS = 1).
#extension GL_EXT_shader_atomic_int64 : require
#include "raster_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 2) buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };
// The same visibility buffer as 32-bit words: the early-depth load of a
// key's depth word (lavapipe: a vector gather, where a storage load at
// per-lane addresses is a scalar loop).
layout(set = 0, binding = 5) uniform usamplerBuffer visWordTex;

// Each view visits the spheres in its order (orderTex): 64-sphere runs of
// the input, the two halves of the dispatch (lavapipe's two threads) on
// either side of the view and each sorted front to back, so the
// early-depth test turns more of the later visits away before their
// atomics, and the halves take alike work on different cache lines
// (glsl/bands.glsl's SPHERE_AT; src/stages/raster/compute.rs `view_order`).
// (instanced scenes: the order is over batches of 2^BATCH_SHIFT slots; a
// LOD list, pc.list_base != RASTER_ORDER, is visited in its own order:
// its slots are the ids)
layout(set = 0, binding = 6) uniform usamplerBuffer orderTex;
// The spheres as texels (scene.glsl): in a view's order a sphere's address
// is not the invocation's, and a storage load at per-lane addresses is a
// scalar loop per component on lavapipe; a texel fetch is a vector gather.
#define SCENE_ATTRIBUTES
#include "scene.glsl"
#define SPHERE_AT(i) (scene_instanced() \
    ? (pc.list_base != RASTER_ORDER ? (pc.list_base << BATCH_SHIFT) + (i) \
       : (texelFetch(orderTex, int((i) >> BATCH_SHIFT)).x << BATCH_SHIFT) | scene_lane(i)) \
    : texelFetch(orderTex, int(i)).x)

#include "push/raster.glsl"

// Perspective camera (specialization constant 2; the light view is
// always orthographic): a branch on the view's data would run both sides.
layout(constant_id = 2) const bool PERSP = false;

// See-through spheres (alpha below 1) are drawn by the fragment lists
// (oit_splat.comp), not into the camera's visibility buffer: with
// SEE_THROUGH the camera view skips them (the light views draw them all).
layout(constant_id = 3) const bool SEE_THROUGH = false;

#include "view_footprint.glsl"

Footprint band_footprint(uint id) {
    Footprint f = view_footprint(pc.view_index == 0u ? g.cam : g.light, id);
    if (SEE_THROUGH && pc.view_index == 0u && scene_alpha(id) < 1.0) f.rect = ivec4(1, 1, 0, 0);
    return f;
}

void visit(uint id, Footprint f, ivec2 t) {
    float d = footprint_depth(f, t);
    if (d < 0.0) return;
    // Early depth (as Schuetz et al.): a plain load first, and the 64-bit
    // atomic only where this sphere is nearer (measured on lavapipe: the
    // scattered atomics are most of the pass; the 1M capsid's raster went
    // from 147 to 107 ms at 1080p).
    uint k = footprint_pixel(f, t);
    uint64_t key = vis_key(d, id);
    // (depth bits of positive floats order as unsigned integers; the empty
    // key is all ones; ties go to the atomic, which keeps the smaller id)
    if (texelFetch(visWordTex, int(2u * k + 1u)).x >= floatBitsToUint(d)) atomicMin(vis[k], key);
}


bool band_queue() { return true; }
// (the job list was full: this invocation draws the footprint itself,
// and lavapipe ends its loops after 65,535 back-edges, so a footprint
// past that would lose its last rows, and a per-batch invocation's
// candidates together sooner: the frame is drawn again with a longer
// list, src/stages/raster/compute.rs `after_frame`)
void band_inline(uint id, uint area) { atomicOr(counters[R_BANDS_FULL], 1u); }
bool band_replay(uint id) { return false; }
#define BAND_REQ R_BANDS_REQ
#define BAND_RUN R_BANDS_RUN
#define BAND_SPHERE_MAIN raster_spheres
void raster_spheres();
#include "bands.glsl"

// The LOD lists per batch (LIGHT_BATCHES: the key light's; CAM_BATCHES:
// the camera's): one invocation per BATCH_PART_SLOTS slots
// of a listed batch (pc.sphere_count: the list's slots; dispatched by
// LOD_BATCH_ARGS). The per-slot raster pays each slot's setup (batch
// record, placement, rectangle: ~8.6 ns on lavapipe) though most slots
// draw nothing: the light's spheres are mostly smaller than its texels
// and cover no texel centre; most of the camera's lie behind nearer atoms
// of their own protein. Here the batch's record and transform are read
// once, each atom is projected by the transform's linear map (its images
// of the view's axes) with a margin over both frames' rounding, and only
// the atoms that may draw take the per-slot path (band_sphere_id: the
// same footprint, keys and bands, so the same image). An invocation's
// loops stay within lavapipe's 65,535 back-edges: 32 atoms, then at most
// 32 candidates of at most BATCH_PART_AREA texels each (larger footprints
// go to bands) with their band appends (at most 1,025 each in a window of
// 8,192 rows: the host's bound): 49 k.
#include "batch_parts.glsl"
layout(constant_id = 4) const bool LIGHT_BATCHES = false;
// The camera's test (CAM_EARLY, CAM_RECHECK, CAM_LATE; CAM_PER_SLOT: none).
layout(constant_id = 5) const uint CAM_BATCHES = CAM_PER_SLOT;
const uint BATCH_PART_AREA = 512u;

// The camera's depth tiles (glsl/lod_hiz.comp, fine tiles of
// 2^pc.hiz_shift pixels first): of this frame's early image, and of last
// frame's final image.
layout(set = 0, binding = 7) uniform usamplerBuffer hizTex;
layout(set = 0, binding = 8) uniform usamplerBuffer hizPrevTex;

// (raster.comp's two tile buffers: this frame's early image, last frame's
// final one)
#define TILE_WORD(prev, i) ((prev) ? texelFetch(hizPrevTex, (i)).x : texelFetch(hizTex, (i)).x)
#define TILE_TEXELS(prev) ((prev) ? textureSize(hizPrevTex) : textureSize(hizTex))
#include "atom_tests.glsl"

void batch_part() {
    const uint PARTS = batch_parts(1u << BATCH_SHIFT);
    uint e = FLAT_ID / PARTS;
    if (e >= (pc.sphere_count >> BATCH_SHIFT)) return;
    uint id0 = (pc.list_base + e) << BATCH_SHIFT;
    uvec4 b = scene_batch(id0);
    uint from = (FLAT_ID % PARTS) * BATCH_PART_SLOTS;
    uint count = min(b.w & 0xFFu, from + BATCH_PART_SLOTS);
    View v = LIGHT_BATCHES ? g.light : g.cam;
    vec3 p0;
    mat3 ax;
    instance_map(b.x, p0, ax);
    // (cam_map: atom_map but for a perspective camera; the light's
    // pipeline is orthographic)
    AtomMap m = cam_map(v, p0, ax);
    // (the camera's early and recheck tests ask whether last frame's tiles
    // hid the atom where last frame's view saw it: pc.prev)
    AtomMap mp = cam_map(pc.prev, p0, ax);
    uint cand = 0u;
    for (uint j = from; j < count; ++j) {
        vec4 a = texelFetch(sphereTex, int(b.y + j));
        bool draw;
        if (LIGHT_BATCHES) {
            // The atoms whose disc may hold a texel centre: the nearest
            // centre within the radius, or a radius that may reach past it.
            vec2 t;
            float r;
            atom_disc(v, m, a, t, r);
            vec2 d = t - round(t);
            draw = r >= 0.5 || dot(d, d) <= r * r;
        } else {
            ivec4 rc, rcp;
            uint near, nearp;
            cam_rect(v, m, a, rc, near);
            cam_rect(pc.prev, mp, a, rcp, nearp);
            bool some = rc.x <= rc.z && rc.y <= rc.w;
            bool hid_prev = CAM_BATCHES != CAM_LATE && tiles_hide(true, pc.prev, rcp, nearp);
            bool hid_now = CAM_BATCHES != CAM_EARLY && tiles_hide(false, v, rc, near);
            draw = some && (CAM_BATCHES == CAM_EARLY ? !hid_prev
                           : CAM_BATCHES == CAM_RECHECK ? hid_prev && !hid_now : !hid_now);
        }
        cand |= draw ? 1u << (j - from) : 0u;
    }
    for (; cand != 0u; cand &= cand - 1u) {
        band_sphere_id(id0 + from + uint(findLSB(cand)), min(pc.big_area, LIGHT_BATCHES ? BATCH_PART_AREA : CAM_PART_AREA));
    }
}

void raster_spheres() {
    if (LIGHT_BATCHES || CAM_BATCHES != CAM_PER_SLOT) {
        batch_part();
    } else {
        band_sphere();
    }
}
