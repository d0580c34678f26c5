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

struct Footprint {
    vec3 cv;
    float r;
    ivec4 rect;
};

View raster_view() { return pc.view_index == 0u ? g.cam : g.light; }

Footprint band_footprint(uint id) {
    View v = raster_view();
    vec4 s = spheres[id];
    Footprint f;
    f.cv = view_space(v, s.xyz);
    f.r = s.w;
    f.rect = sphere_rect(v, f.cv, s.w);
    return f;
}

void visit(uint id, Footprint f, ivec2 t) {
    View v = raster_view();
    float d = hit_depth(v, f.cv, f.r, vec2(t));
    if (d >= 0.0) atomicMin(vis[uint(t.y) * v.dims.x + uint(t.x)], vis_key(d, id));
}

bool band_queue() { return true; }
void band_inline(uint id) {}
bool band_replay(uint id) { return false; }
#define BAND_REQ R_BANDS_REQ
#define BAND_RUN R_BANDS_RUN
#include "bands.glsl"
