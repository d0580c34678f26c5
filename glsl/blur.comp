#version 460
// Separable bilateral blur (seed 001) of the per-pixel SSDO result (ambient
// visibility, bounce, screen-space key-light visibility; pack_ao), which
// also recombines its 2x2 interleaved direction sets. AXIS (specialization
// constant 1) picks the direction: one shader, two pipelines. Weights:
// Gaussian in pixels x Gaussian in view depth x normal agreement^8 (three squarings) x
// (semantic) same region at the active level, all exact per pixel (depth
// key, sphere, attributes), so edges between spheres stay sharp even when
// spheres are only a few pixels wide. The centre tap has weight 1.
#include "ssdo_common.glsl"
#include "tiles.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const uint AXIS = 0;
layout(constant_id = 2) const bool SEMANTIC = true;
// Taps on each side, in pixels: a constant so the loop unrolls and its
// spatial weights fold (lavapipe runs a loop to its slowest lane).
layout(constant_id = 3) const int RADIUS = 2;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 2) uniform usamplerBuffer inTex;
layout(set = 0, binding = 3) writeonly buffer Out { uint outv[]; };
layout(set = 0, binding = 4) uniform usamplerBuffer visTex;
layout(set = 0, binding = 5) uniform samplerBuffer sphereTex;
layout(set = 0, binding = 6) uniform usamplerBuffer attrTex;

layout(push_constant) uniform Push {
    float sigma_z;   // depth tolerance (world units)
    uint level;      // hierarchy level of the region test
    uint pad0, pad1;
} pc;

// The surface at pixel j with key texel v: view distance, normal, region.
void surface_at(uint j, uvec2 v, out float z, out vec3 n, out uint region) {
    z = key_view_z(g.cam, j, uintBitsToFloat(v.y));
    vec4 sp = texelFetch(sphereTex, int(v.x));
    n = normalize(point_at(g.cam, image_px(g.cam, j), z) - sp.xyz);
    region = g.counts.w != 0u ? v.x : (SEMANTIC ? texelFetch(attrTex, int(2u * v.x))[pc.level] : 0u);
}

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uvec2 px;
    if (!tile_pixel(w, h, px) || !IN_ACTIVE(px)) return;
    uint i = px.y * w + px.x;
    uvec2 v0 = texelFetch(visTex, int(i)).xy;
    uint centre = texelFetch(inTex, int(i)).x;
    if (v0.x == NO_SPHERE) {
        outv[i] = centre;
        return;
    }
    float z0;
    vec3 n0;
    uint r0;
    surface_at(i, v0, z0, n0, r0);
    ivec2 step = AXIS == 0u ? ivec2(1, 0) : ivec2(0, 1);
    const float sigma_px = max(float(RADIUS) * 0.5, 0.5);
    vec2 acc_v = vec2(0.0);
    float acc_s = 0.0, wsum = 0.0;
    vec3 acc_b = vec3(0.0);
    // Straight-line taps (a clamped fetch and a zero weight instead of
    // `continue`): lavapipe would run every skipped path anyway.
    for (int k = -RADIUS; k <= RADIUS; ++k) {
        ivec2 t = ivec2(px) + k * step;
        bool inside = t.x >= 0 && t.y >= 0 && t.x < int(w) && t.y < int(h);
        t = clamp(t, ivec2(0), ivec2(int(w) - 1, int(h) - 1));
        uint j = uint(t.y) * w + uint(t.x);
        uvec2 vj = texelFetch(visTex, int(j)).xy;
        bool ok = inside && vj.x != NO_SPHERE;
        vj.x = ok ? vj.x : v0.x;  // (a valid sphere for the fetches below)
        float zj;
        vec3 nj;
        uint rj;
        surface_at(j, vj, zj, nj, rj);
        ok = ok && (!SEMANTIC || rj == r0);
        float dz = (zj - z0) / pc.sigma_z;
        float c = max(dot(n0, nj), 0.0);
        c *= c;
        c *= c;
        float wk = exp(-0.5 * float(k * k) / (sigma_px * sigma_px) - 0.5 * dz * dz) * c * c;
        if (k == 0) wk = 1.0;  // folds: k is a constant after unrolling
        wk = ok ? wk : 0.0;
        vec2 vv;
        float sv;
        vec3 bb;
        unpack_ao(texelFetch(inTex, int(j)).x, vv, bb, sv);
        acc_v += wk * vv;
        acc_b += wk * bb;
        acc_s += wk * sv;
        wsum += wk;
    }
    outv[i] = pack_ao(acc_v / wsum, acc_b / wsum, acc_s / wsum);
}
