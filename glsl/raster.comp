#version 460
// Compute rasterization of sphere impostors, one invocation per sphere: small
// footprints are tested pixel by pixel here (exact ray-sphere, 64-bit
// atomicMin of depth|id); large ones are split into 8-row bands appended to a
// job list that raster_bands.comp handles with a whole workgroup per band, so
// one big sphere never serialises thousands of pixels on one invocation.
#extension GL_EXT_shader_atomic_int64 : require
#include "raster_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) writeonly buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; }; // [0] bands requested

layout(push_constant) uniform Push {
    uint view_index;   // 0 camera, 1 key light
    uint big_area;     // footprints larger than this (pixels) go to bands
    uint job_capacity; // entries in jobs[]
    uint sphere_count;
} pc;

const uint BAND_ROWS = 8;

void raster_rect(View v, vec3 cv, float r, uint id, ivec4 rc) {
    uint w = v.dims.x;
    for (int y = rc.y; y <= rc.w; ++y) {
        for (int x = rc.x; x <= rc.z; ++x) {
            float d = hit_depth(v, cv, r, vec2(x, y));
            if (d >= 0.0) atomicMin(vis[uint(y) * w + uint(x)], vis_key(d, id));
        }
    }
}

void main() {
    uint id = FLAT_ID;
    if (id >= pc.sphere_count) return;
    View v = pc.view_index == 0 ? g.cam : g.light;
    vec4 s = spheres[id];
    vec3 cv = view_space(v, s.xyz);
    ivec4 rc = sphere_rect(v, cv, s.w);
    if (rc.x > rc.z || rc.y > rc.w) return;
    uint area = uint(rc.z - rc.x + 1) * uint(rc.w - rc.y + 1);
    if (area <= pc.big_area) {
        raster_rect(v, cv, s.w, id, rc);
        return;
    }
    uint bands = uint(rc.w - rc.y) / BAND_ROWS + 1;
    uint base = atomicAdd(counters[0], bands);
    for (uint b = 0; b < bands; ++b) {
        int y0 = rc.y + int(b * BAND_ROWS);
        if (base + b < pc.job_capacity) {
            jobs[base + b] = uvec2(id, uint(y0));
        } else {
            // Job list full: rasterize this band here (slow but exact).
            raster_rect(v, cv, s.w, id, ivec4(rc.x, y0, rc.z, min(y0 + int(BAND_ROWS) - 1, rc.w)));
        }
    }
}
