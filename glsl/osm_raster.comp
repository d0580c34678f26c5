#version 460
// Opacity shadow maps (seed 004), pass 1: every sphere adds its optical depth
// tau = -ln(1 - alpha) to the depth slice containing its ENTRY depth (the
// surface point nearest the light) along the light ray through each texel
// centre its disk covers. Slices are stored slice-major: slice k of the
// N x N map is opacity[k * N * N + texel] (the seed's 8 x 8 atlas of a 2D
// texture is the same array addressed by tile; a storage buffer needs no
// atlas). Accumulation is an integer atomicAdd of tau in fixed point
// (pc.tau_fixed = round(tau * 2^16), computed on the CPU): deterministic,
// order-independent and needing no float-atomic feature.
//
// Large footprints are cut into 8-row bands run by whole workgroups (the
// raster's scheme: jobs appended here, raster_args.comp turns the count into
// indirect dispatch arguments, bands = 1 runs them); a full job list falls
// back to this invocation looping over the band.
//
// Keep texel_entry_slice() identical to the one in osm_shadow.comp: the
// shadow lookup recomputes the receiver's own deposit to remove it.
#include "raster_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) buffer Opacity { uint opacity[]; };
layout(set = 0, binding = 3) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; }; // [0] bands requested, [1] run

layout(push_constant) uniform Push {
    uint bands;        // 0: one invocation per sphere; 1: one workgroup per band job
    uint sphere_count;
    uint big_area;     // footprints above this many texels go to band jobs
    uint job_capacity;
    uint tau_fixed;    // optical depth of one sphere, fixed point 2^16
    uint slices;
    float z_min;       // light depth (relative to the light's centre plane) of slice 0's start
    float inv_dz;      // slices per world unit
} pc;

const int BAND_ROWS = 8;
const uint MAX_X = 65535;

// Slice of the sphere's entry depth along the light ray through texel t's
// centre, or -1 when the ray misses the sphere.
int texel_entry_slice(View L, vec3 cv, float r, ivec2 t) {
    vec2 p = pixel_plane(L, vec2(t));
    vec2 dxy = p - cv.xy;
    float disc = r * r - dot(dxy, dxy);
    if (disc < 0.0) return -1;
    float z = cv.z - sqrt(disc);
    return clamp(int(floor((z - pc.z_min) * pc.inv_dz)), 0, int(pc.slices) - 1);
}

void deposit(View L, vec3 cv, float r, ivec2 t) {
    int k = texel_entry_slice(L, cv, r, t);
    if (k < 0) return;
    uint texels = L.dims.x * L.dims.y;
    atomicAdd(opacity[uint(k) * texels + uint(t.y) * L.dims.x + uint(t.x)], pc.tau_fixed);
}

void deposit_rect(View L, vec3 cv, float r, ivec4 rc) {
    for (int y = rc.y; y <= rc.w; ++y) {
        for (int x = rc.x; x <= rc.z; ++x) deposit(L, cv, r, ivec2(x, y));
    }
}

void sphere_main() {
    uint id = FLAT_ID;
    if (id >= pc.sphere_count) return;
    View L = g.light;
    vec4 s = spheres[id];
    vec3 cv = view_space(L, s.xyz);
    ivec4 rc = sphere_rect(L, cv, s.w);
    if (rc.x > rc.z || rc.y > rc.w) return;
    uint area = uint(rc.z - rc.x + 1) * uint(rc.w - rc.y + 1);
    if (area <= pc.big_area) {
        deposit_rect(L, cv, s.w, rc);
        return;
    }
    uint nb = uint(rc.w - rc.y) / uint(BAND_ROWS) + 1u;
    uint base = atomicAdd(counters[0], nb);
    for (uint b = 0u; b < nb; ++b) {
        int y0 = rc.y + int(b) * BAND_ROWS;
        if (base + b < pc.job_capacity) {
            jobs[base + b] = uvec2(id, uint(y0));
        } else {
            deposit_rect(L, cv, s.w, ivec4(rc.x, y0, rc.z, min(y0 + BAND_ROWS - 1, rc.w)));
        }
    }
}

void band_main() {
    uint job = gl_WorkGroupID.x + gl_WorkGroupID.y * MAX_X;
    if (job >= counters[1]) return;
    uvec2 jb = jobs[job];
    View L = g.light;
    vec4 s = spheres[jb.x];
    vec3 cv = view_space(L, s.xyz);
    ivec4 rc = sphere_rect(L, cv, s.w);
    int y0 = int(jb.y);
    int rows = min(BAND_ROWS, rc.w - y0 + 1);
    int width = rc.z - rc.x + 1;
    for (int i = int(gl_LocalInvocationID.x); i < width * rows; i += int(gl_WorkGroupSize.x)) {
        deposit(L, cv, s.w, ivec2(rc.x + i % width, y0 + i / width));
    }
}

void main() {
    if (pc.bands != 0u) {
        band_main();
    } else {
        sphere_main();
    }
}
