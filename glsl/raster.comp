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
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    uint view_index;   // 0 camera, 1 key light
    uint big_area;     // footprints larger than this (pixels) go to bands
    uint job_capacity; // entries in jobs[]
    uint sphere_count;
} pc;

// The view is loaded once per sphere (or band) and travels with the
// footprint: loading it per pixel doubled the pass's cost on lavapipe.
struct Footprint {
    View v;
    vec3 cv;
    float r;
    ivec4 rect;
};

Footprint band_footprint(uint id) {
    Footprint f;
    f.v = pc.view_index == 0u ? g.cam : g.light;
    vec4 s = spheres[id];
    f.cv = view_space(f.v, s.xyz);
    f.r = s.w;
    f.rect = sphere_rect(f.v, f.cv, s.w);
    return f;
}

void visit(uint id, Footprint f, ivec2 t) {
    float d = hit_depth(f.v, f.cv, f.r, vec2(t));
    if (d >= 0.0) atomicMin(vis[uint(t.y) * f.v.dims.x + uint(t.x)], vis_key(d, id));
}

bool band_queue() { return true; }
void band_inline(uint id) {}
bool band_replay(uint id) { return false; }
#define BAND_REQ R_BANDS_REQ
#define BAND_RUN R_BANDS_RUN
#include "bands.glsl"
