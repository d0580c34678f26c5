#version 460
// Opacity shadow maps (after the WebGL particle paper), pass 1: every sphere adds its optical depth
// tau = -ln(1 - alpha) to the depth slice containing its ENTRY depth (the
// surface point nearest the light) along the light ray through each texel
// centre its disk covers. Slices are stored slice-major: slice k of the
// N x N map is opacity[k * N * N + texel] (the seed's 8 x 8 atlas of a 2D
// texture is the same array addressed by tile; a storage buffer needs no
// atlas). Accumulation is an integer atomicAdd of tau in fixed point
// (pc.tau_fixed = round(tau * 2^16), computed on the CPU): deterministic,
// order-independent and needing no float-atomic feature.
//
// Large footprints are cut into 8-row bands run by whole workgroups: the
// band skeleton of bands.glsl, as in the rasterizer.
//
// texel_entry_slice() is shared with osm_shadow.comp (osm_common.glsl).
#include "raster_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 2) buffer Opacity { uint opacity[]; };
layout(set = 0, binding = 3) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };

#include "push/osm_raster.glsl"
#include "scene.glsl"

#define OSM_Z_MIN pc.z_min
#define OSM_INV_DZ pc.inv_dz
#define OSM_SLICES pc.slices
#include "osm_common.glsl"

struct Footprint {
    vec3 cv;
    float r;
    ivec4 rect;
};

Footprint band_footprint(uint id) {
    View L = g.light;
    vec4 s = scene_sphere(id);
    Footprint f;
    f.cv = view_space(L, s.xyz, false);
    f.r = s.w;
    // light views are orthographic; an unused slot of an instanced batch
    // has no footprint
    f.rect = scene_instanced() && s.w < 0.0 ? ivec4(1, 1, 0, 0) : sphere_rect(L, f.cv, s.w, false);
    return f;
}

void visit(uint id, Footprint f, ivec2 t) {
    View L = g.light;
    int k = texel_entry_slice(L, f.cv, f.r, t);
    if (k < 0) return;
    uint texels = L.dims.x * L.dims.y;
    atomicAdd(opacity[uint(k) * texels + uint(t.y) * L.dims.x + uint(t.x)], pc.tau_fixed);
}

bool band_queue() { return true; }
// (the job list was full: this invocation visits the footprint; lavapipe
// ends a loop after 65,535 back-edges, so a larger one would lose rows:
// the frame is drawn again with a longer list, src/stages/shadows/osm.rs)
void band_inline(uint id, uint area) {
    if (area > BAND_INLINE_SAFE) atomicOr(counters[R_BANDS_FULL], 1u);
}
bool band_replay(uint id) { return false; }
#define BAND_REQ R_BANDS_REQ
#define BAND_RUN R_BANDS_RUN
#include "bands.glsl"
