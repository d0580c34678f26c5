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
// the orthographic camera's): one invocation per BATCH_PART_SLOTS slots
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
const uint CAM_PART_AREA = 128u;

// The camera's depth tiles (glsl/lod_hiz.comp, fine tiles of
// 2^pc.hiz_shift pixels first): of this frame's early image, and of last
// frame's final image.
layout(set = 0, binding = 7) uniform usamplerBuffer hizTex;
layout(set = 0, binding = 8) uniform usamplerBuffer hizPrevTex;

// Whether the tiles under window rectangle rc all hold surfaces nearer
// than depth word `near` (last frame's with `prev`): 2x2 tiles of 2 px at
// most (from word pc.micro_base; 0: none), else 2x2 fine tiles (2^pc.hiz_shift
// pixels), else 2x2 coarse ones (8x8 fine), else not hidden. (A bool, not
// the sampler: one function.)
bool tiles_hide(bool prev, View v, ivec4 rc, uint near) {
    ivec2 lo = ivec2(v.dims.zw);
    ivec4 r = rc - ivec4(lo, lo);
    int S = int(pc.hiz_shift);
    ivec4 m = r >> 1, t = r >> S;
    bool micro = pc.micro_base != 0u && m.z - m.x <= 1 && m.w - m.y <= 1;
    bool fine = t.z - t.x <= 1 && t.w - t.y <= 1;
    uint T = 1u << S;
    int base = micro ? int(pc.micro_base)
                     : fine ? 0 : int(((v.dims.x + T - 1u) >> S) * ((v.dims.y + T - 1u) >> S));
    int sh = micro ? 1 : fine ? S : S + 3;
    t = r >> sh;
    if (t.z - t.x > 1 || t.w - t.y > 1) return false;
    int tw = int((v.dims.x + (1u << sh) - 1u) >> sh);
    int last = (prev ? textureSize(hizPrevTex) : textureSize(hizTex)) - 1;
    ivec4 at = min(base + ivec4(t.y * tw + t.x, t.y * tw + t.z, t.w * tw + t.x, t.w * tw + t.z), last);
    uvec4 w = prev ? uvec4(texelFetch(hizPrevTex, at.x).x, texelFetch(hizPrevTex, at.y).x,
                           texelFetch(hizPrevTex, at.z).x, texelFetch(hizPrevTex, at.w).x)
                   : uvec4(texelFetch(hizTex, at.x).x, texelFetch(hizTex, at.y).x,
                           texelFetch(hizTex, at.z).x, texelFetch(hizTex, at.w).x);
    return max(max(w.x, w.y), max(w.z, w.w)) < near;
}

// Instance placement p0 (its linear map's images of the axes ax) into
// view v's pixel coordinates (plane_rect's: x ppu + W/2 - 1/2, H/2 - 1/2 -
// y ppu; a pixel's centre at integer coordinates) and depth: an atom at a
// (the molecule's frame) is at o + (rx . a, ry . a), depth oz + rz . a.
// (`precise`: the camera's early and recheck pipelines must compute alike
// bits, whatever each one's contraction into fused multiply-adds; an atom
// both found hidden behind last frame's tiles would be lost)
struct AtomMap {
    vec3 rx, ry, rz;
    vec2 o;
    float oz;
    // the rounding of the placed centres and of this map: far above
    // either, in world units
    float slack;
};

AtomMap atom_map(View v, vec3 p0, mat3 ax) {
    float ppu = v.center.w;
    precise vec3 rx = (v.right.xyz * ax) * ppu, ry = -(v.up.xyz * ax) * ppu, rz = v.dir.xyz * ax;
    precise vec3 q = p0 - v.center.xyz;
    precise vec2 o = vec2(dot(q, v.right.xyz) * ppu + 0.5 * v.right.w - 0.5,
                  0.5 * v.up.w - 0.5 - dot(q, v.up.xyz) * ppu);
    precise float oz = dot(q, v.dir.xyz);
    precise float slack = 1e-5 * (coord_max(p0) + coord_max(v.center.xyz)) + 1e-3;
    return AtomMap(rx, ry, rz, o, oz, slack);
}

// Atom a's disc in view v's pixels (mapped by m): its centre t and its
// radius r, grown for the map's rounding.
void atom_disc(View v, AtomMap m, vec4 a, out vec2 t, out float r) {
    precise vec2 tp = m.o + vec2(dot(m.rx, a.xyz), dot(m.ry, a.xyz));
    precise float rp = a.w * v.center.w + (m.slack * v.center.w + 1e-3);
    t = tp;
    r = rp;
}

// Atom a's pixel rectangle in view v (mapped by m), grown, and its nearest
// depth key, less the cull's margin for the keys' f32 rounding
// (glsl/lod_cull.comp `hidden`) and the map's.
void atom_rect(View v, AtomMap m, vec4 a, out ivec4 rc, out uint near) {
    vec2 t;
    float r;
    atom_disc(v, m, a, t, r);
    ivec2 lo = ivec2(v.dims.zw), hi = min(lo + ivec2(v.dims.xy), ivec2(int(v.right.w), int(v.up.w))) - 1;
    rc = ivec4(max(ivec2(ceil(t - r)), lo), min(ivec2(floor(t + r)), hi));
    precise float z = m.oz + dot(m.rz, a.xyz);
    precise float zmin = z - a.w + v.depth.x - (1e-4 * (abs(z) + abs(v.depth.x) + a.w) + 1e-3 + m.slack);
    near = floatBitsToUint(max(zmin, 0.0));
}

void batch_part() {
    const uint PARTS = batch_parts(1u << BATCH_SHIFT);
    uint e = FLAT_ID / PARTS;
    if (e >= (pc.sphere_count >> BATCH_SHIFT)) return;
    uint id0 = (pc.list_base + e) << BATCH_SHIFT;
    uvec4 b = scene_batch(id0);
    uint from = (FLAT_ID % PARTS) * BATCH_PART_SLOTS;
    uint count = min(b.w & 0xFFu, from + BATCH_PART_SLOTS);
    View v = LIGHT_BATCHES ? g.light : g.cam;
    vec3 p0 = instance_apply(b.x, vec3(0.0));
    mat3 ax = mat3(instance_linear(b.x, vec3(1.0, 0.0, 0.0)),
                   instance_linear(b.x, vec3(0.0, 1.0, 0.0)),
                   instance_linear(b.x, vec3(0.0, 0.0, 1.0)));
    AtomMap m = atom_map(v, p0, ax);
    // (the camera's early and recheck tests ask whether last frame's tiles
    // hid the atom where last frame's view saw it: pc.prev)
    AtomMap mp = atom_map(pc.prev, p0, ax);
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
            atom_rect(v, m, a, rc, near);
            atom_rect(pc.prev, mp, a, rcp, nearp);
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
