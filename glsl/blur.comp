#version 460
// Separable bilateral blur (seed 001) of the per-pixel SSDO result (ambient
// visibility, bounce, screen-space key-light visibility; pack_ao), which
// also recombines its 2x2 interleaved direction sets. AXIS (specialization
// constant 1) picks the direction: one shader, two pipelines. Weights:
// Gaussian in pixels x Gaussian in view depth (each pixel's own, from its
// depth key) x normal agreement^8 x (semantic) same region at the active
// level (normals and regions from the pixels' half-resolution records), so
// edges between spheres stay sharp. The centre tap has weight 1.
#include "ssdo_common.glsl"
#include "ssdo_record.glsl"
#include "tiles.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const uint AXIS = 0;
layout(constant_id = 2) const bool SEMANTIC = true;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer recordTex;
layout(set = 0, binding = 2) uniform usamplerBuffer inTex;
layout(set = 0, binding = 3) writeonly buffer Out { uint outv[]; };
layout(set = 0, binding = 4) uniform usamplerBuffer visTex;

layout(push_constant) uniform Push {
    int radius;      // taps on each side, in pixels
    float sigma_z;   // depth tolerance (world units)
    uint level_b;    // 1: edges at level b, 0: level a
    uint pad;
} pc;

Record record_of(uvec2 px) {
    uvec2 b = px / SSDO_BLOCK;
    return unpack_record(texelFetch(recordTex, int(b.y * g.counts.y + b.x)));
}

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uvec2 px;
    if (!tile_pixel(w, h, px)) return;
    uint i = px.y * w + px.x;
    uvec2 v0 = texelFetch(visTex, int(i)).xy;
    uint centre = texelFetch(inTex, int(i)).x;
    if (v0.x == NO_SPHERE) {
        outv[i] = centre;
        return;
    }
    float z0 = key_view_z(g.cam, i, uintBitsToFloat(v0.y));
    Record r = record_of(px);
    uint r0 = pc.level_b != 0u ? r.region_b : r.region_a;
    ivec2 step = AXIS == 0u ? ivec2(1, 0) : ivec2(0, 1);
    float sigma_px = max(float(pc.radius) * 0.5, 0.5);
    vec2 acc_v = vec2(0.0);
    float acc_s = 0.0, wsum = 0.0;
    vec3 acc_b = vec3(0.0);
    for (int k = -pc.radius; k <= pc.radius; ++k) {
        ivec2 t = ivec2(px) + k * step;
        if (t.x < 0 || t.y < 0 || t.x >= int(w) || t.y >= int(h)) continue;
        uint j = uint(t.y) * w + uint(t.x);
        uvec2 vj = texelFetch(visTex, int(j)).xy;
        if (vj.x == NO_SPHERE) continue;
        Record q = record_of(uvec2(t));
        if (SEMANTIC && (pc.level_b != 0u ? q.region_b : q.region_a) != r0) continue;
        float dz = (key_view_z(g.cam, j, uintBitsToFloat(vj.y)) - z0) / pc.sigma_z;
        float wk = exp(-0.5 * float(k * k) / (sigma_px * sigma_px)) * exp(-0.5 * dz * dz)
                 * pow(max(dot(r.n, q.n), 0.0), 8.0);
        if (k == 0) wk = 1.0;
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
