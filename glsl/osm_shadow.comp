#version 460
// Opacity shadow maps (seed 004), pass 3: per visible point P, the optical
// depth accumulated from the light up to P's light depth z, read from the
// prefix-summed slices with linear interpolation between slice ends:
//   u = (z - z_min) / dz,  k = floor(u),  tau(z) = mix(S[k-1], S[k], u - k)
// (S[k] = optical depth through the end of slice k, S[-1] = 0), bilinearly
// filtered over the 4 texel centres around P's projection; visibility is
// exp(-tau) (Beer-Lambert; with tau = -ln(1 - alpha) per sphere this is the
// product of (1 - alpha) over the spheres in front, as the deep lists give).
//
// Self-shadowing: P lies on its own sphere, whose deposit sits at the
// sphere's entry depth, in P's slice or an earlier one; the interpolation
// would count it partly (light-facing P) or fully (P on the far side). The
// receiver's id is known (low word of the visibility buffer), so its own
// deposit at each texel is recomputed exactly as osm_raster.comp made it and
// its interpolated share is subtracted. What remains is the slice
// quantization of OTHER spheres: an occluder whose entry lies in P's slice
// counts by (u - k) instead of 1, and a sphere just behind P in that slice
// counts by (u - k) instead of 0 (bonded atoms interpenetrate, so this is
// common at 64 slices); and the texel-centre rays differ from P's own ray
// near occluder silhouettes (softened by the bilinear filter).
//
// texel_entry_slice() is shared with osm_raster.comp (osm_common.glsl).
#include "shared.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 4) readonly buffer Opacity { float tau[]; };
layout(set = 0, binding = 5) writeonly buffer Shadow { float shadow[]; };

layout(push_constant) uniform Push {
    uint tau_fixed;   // one sphere's optical depth, fixed point (as osm_raster)
    uint slices;
    float z_min;
    float inv_dz;
    float inv_scale;  // fixed point -> optical depth
} pc;

#include "osm_common.glsl"

// Optical depth in front of slice position u at texel t, without the
// receiver's own deposit (own = receiver centre in view space, radius).
float optical_depth(View L, ivec2 t, float u, vec3 own_cv, float own_r) {
    uint n = L.dims.x;
    uint texels = n * L.dims.y;
    uint ti = uint(t.y) * n + uint(t.x);
    int k = min(int(floor(u)), int(pc.slices) - 1);
    float f = u - float(k);
    float lo = k > 0 ? tau[uint(k - 1) * texels + ti] : 0.0;
    float hi = tau[uint(k) * texels + ti];
    float d = mix(lo, hi, f);
    int j = texel_entry_slice(L, own_cv, own_r, t);
    if (j >= 0) d -= float(pc.tau_fixed) * pc.inv_scale * clamp(u - float(j), 0.0, 1.0);
    return max(d, 0.0);
}

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    uint64_t key = vis[i];
    if (key == VIS_EMPTY) {
        shadow[i] = 1.0;
        return;
    }
    uint self_id = uint(key & 0xFFFFFFFFul);
    vec4 s = spheres[self_id];
    vec3 p = gpos[i].xyz;
    View L = g.light;
    vec3 own_cv = view_space(L, s.xyz);
    vec3 q = p - L.center.xyz;
    float n = L.right.w;
    vec2 uv = light_uv(L, p) - 0.5;
    float z = dot(q, L.dir.xyz);
    float u = clamp((z - pc.z_min) * pc.inv_dz, 0.0, float(pc.slices));

    vec2 base = floor(uv);
    vec2 fr = uv - base;
    ivec2 b = ivec2(base);
    int last = int(n) - 1;
    float v = 0.0;
    for (int dy = 0; dy <= 1; ++dy) {
        for (int dx = 0; dx <= 1; ++dx) {
            float wgt = (dx == 0 ? 1.0 - fr.x : fr.x) * (dy == 0 ? 1.0 - fr.y : fr.y);
            if (wgt <= 0.0) continue;
            ivec2 t = clamp(b + ivec2(dx, dy), ivec2(0), ivec2(last));
            v += wgt * exp(-optical_depth(L, t, u, own_cv, s.w));
        }
    }
    shadow[i] = clamp(v, 0.0, 1.0);
}
