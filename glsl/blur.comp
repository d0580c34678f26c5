#version 460
// Separable bilateral blur (after the semantic SSDO paper) of the SSDO result (ambient
// visibility, bounce, screen-space key-light visibility; pack_ao). AXIS
// (specialization constant 1) picks the direction: one shader, two
// pipelines. Weights: Gaussian in taps x Gaussian in view depth x normal
// agreement^8 (three squarings) x (semantic) same region at the active
// level. HALF: one value per 2x2 block, the weights from the blocks'
// records (ssdo_record.glsl: one fetch per tap; shade.comp upsamples the
// result); else one per pixel, the weights from the pixels' edge keys
// (blur_key: view distance and region in 4 bytes, written by ssdo.comp),
// so edges between spheres stay sharp even when spheres are only a few
// pixels wide. The centre tap has weight 1.
#include "ssdo_common.glsl"
#include "ssdo_record.glsl"

layout(local_size_x_id = 0) in;
#include "spec/blur.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer recordTex;
layout(set = 0, binding = 2) uniform usamplerBuffer inTex;
layout(set = 0, binding = 3) writeonly buffer Out { uint outv[]; };
layout(set = 0, binding = 4) uniform usamplerBuffer keyTex;  // per pixel: blur_key

#include "push/blur.glsl"

#define TILE_LIST_ID SPEC_NEXT_ID
#define TILE_LIST_BINDING 5
#include "tiles.glsl"

// What the weights compare at tap j: covered, view distance, normal, region.
bool geometry(uint j, out float z, out vec3 n, out uint region) {
    if (HALF) {
        Record r = unpack_record(texelFetch(recordTex, int(j)));
        z = r.z;
        n = r.n;
        region = pc.level_b != 0u ? r.region_b : r.region_a;
        return r.covered;
    }
    // Per pixel: the edge key ssdo.comp wrote; no normal (spheres are a
    // few pixels wide here: depth and region keep the edges).
    uint k = texelFetch(keyTex, int(j)).x;
    z = blur_key_z(k);
    n = vec3(0.0, 0.0, 1.0);
    region = blur_key_region(k);
    return k != BLUR_KEY_BACKGROUND;
}

void main() {
    uint hw = HALF ? g.counts.y : g.cam.dims.x, hh = HALF ? g.counts.z : g.cam.dims.y;
    uvec2 b;
    if (!tile_pixel(hw, hh, HALF, b) || !(HALF ? IN_ACTIVE_BLOCK(b) : IN_ACTIVE(b))) return;
    uint i = b.y * hw + b.x;
    float z0;
    vec3 n0;
    uint reg0;
    uint centre = texelFetch(inTex, int(i)).x;
    if (TILE_LIST == 2u || !geometry(i, z0, n0, reg0)) {
        outv[i] = centre;
        return;
    }
    // Per pixel, without a hierarchy, every sphere is its own region (the
    // blur keeps to the sphere). Per block the regions are the
    // representatives': there, without a hierarchy, as in plain mode,
    // depth and normal alone keep the edges.
    bool regions = SEMANTIC && (!HALF || g.counts.w == 0u);
    ivec2 step = AXIS == 0u ? ivec2(1, 0) : ivec2(0, 1);
    // Per block the Gaussian is as wide as the radius: the receivers'
    // 4x4-block rotation pattern (ssdo.comp) then averages out instead of
    // showing as grain on large spheres; per pixel half the radius, which
    // keeps the creases of small spheres (plain SSDO's Spearman with the
    // ray-traced AO 0.929; 0.912 with the wide kernel).
    const float sigma = HALF ? max(float(RADIUS), 0.5) : max(float(RADIUS) * 0.5, 0.5);
    vec2 acc_v = vec2(0.0);
    float acc_s = 0.0, wsum = 0.0;
    vec3 acc_b = vec3(0.0);
    // Straight-line taps (a clamped fetch and a zero weight instead of
    // `continue`): lavapipe would run every skipped path anyway.
    for (int k = -RADIUS; k <= RADIUS; ++k) {
        ivec2 t = ivec2(b) + k * step;
        bool inside = t.x >= 0 && t.y >= 0 && t.x < int(hw) && t.y < int(hh);
        t = clamp(t, ivec2(0), ivec2(int(hw) - 1, int(hh) - 1));
        uint j = uint(t.y) * hw + uint(t.x);
        float zj;
        vec3 nj;
        uint rj;
        bool ok = geometry(j, zj, nj, rj) && inside && (!regions || rj == reg0);
        float dz = (zj - z0) / pc.sigma_z;
        float c = max(dot(n0, nj), 0.0);
        c *= c;
        c *= c;
        float wk = exp(-0.5 * float(k * k) / (sigma * sigma) - 0.5 * dz * dz) * c * c;
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
