// Opacity shadow maps (after the WebGL particle paper), pass 3: per visible point P, the optical
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
// Parameters: shadow_u.x = one sphere's optical depth (fixed point),
// shadow_u.y = slices, shadow_f0 = (z_min, slices per world unit, fixed
// point -> optical depth).
layout(set = 0, binding = 16) uniform samplerBuffer tauTex; // R32F: prefix-summed optical depth, slice-major

#define OSM_Z_MIN g.shadow_f0.x
#define OSM_INV_DZ g.shadow_f0.y
#define OSM_SLICES g.shadow_u.y
#include "osm_common.glsl"

// Optical depth in front of slice position u at texel t, without the
// receiver's own deposit (own = receiver centre in view space, radius).
float optical_depth(View L, ivec2 t, float u, vec3 own_cv, float own_r) {
    uint n = L.dims.x;
    uint texels = n * L.dims.y;
    uint ti = uint(t.y) * n + uint(t.x);
    int k = min(int(floor(u)), int(OSM_SLICES) - 1);
    float f = u - float(k);
    float lo = k > 0 ? texelFetch(tauTex, int(uint(k - 1) * texels + ti)).x : 0.0;
    float hi = texelFetch(tauTex, int(uint(k) * texels + ti)).x;
    float d = mix(lo, hi, f);
    int j = texel_entry_slice(L, own_cv, own_r, t);
    if (j >= 0) d -= float(g.shadow_u.x) * g.shadow_f0.z * clamp(u - float(j), 0.0, 1.0);
    return max(d, 0.0);
}

float key_visibility(Surface s, uint pixel) {
    vec4 sp = scene_sphere(s.id);
    vec3 p = s.p;
    View L = g.light;
    vec3 own_cv = view_space(L, sp.xyz, false);
    vec3 q = p - L.center.xyz;
    float n = L.right.w;
    vec2 uv = light_uv(L, p) - 0.5;
    float z = dot(q, L.dir.xyz);
    float u = clamp((z - OSM_Z_MIN) * OSM_INV_DZ, 0.0, float(OSM_SLICES));

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
            v += wgt * exp(-optical_depth(L, t, u, own_cv, sp.w));
        }
    }
    return clamp(v, 0.0, 1.0);
}
