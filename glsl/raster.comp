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
void band_inline(uint id) {}
bool band_replay(uint id) { return false; }
#define BAND_REQ R_BANDS_REQ
#define BAND_RUN R_BANDS_RUN
#include "bands.glsl"
