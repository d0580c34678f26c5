#version 460
// Separable bilateral blur (seed 001) of ambient visibility + bounce (vec4)
// and, when it comes from the noisy screen-space march, key-light
// visibility. Specialization constant 1 picks the axis (0 horizontal,
// 1 vertical): one shader, two pipelines. Weights: Gaussian in pixels x
// Gaussian in view depth x normal agreement^8 x (semantic) same region at
// the active level, so edges between spheres stay sharp.
#include "ssdo_common.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const uint AXIS = 0;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 2) readonly buffer GNorm { vec4 gnorm[]; };
layout(set = 0, binding = 3) readonly buffer GRegion { uvec4 gregion[]; };
layout(set = 0, binding = 4) readonly buffer InA { vec4 in_a[]; };
layout(set = 0, binding = 5) readonly buffer InS { float in_s[]; };
layout(set = 0, binding = 6) writeonly buffer OutA { vec4 out_a[]; };
layout(set = 0, binding = 7) writeonly buffer OutS { float out_s[]; };

layout(push_constant) uniform Push {
    int radius;      // taps on each side
    float sigma_z;   // depth tolerance (world units)
    uint semantic;
    uint level;      // region level used for edges
    uint blur_shadow;
    float pad0, pad1, pad2;
} pc;

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    vec4 n4 = gnorm[i];
    if (n4.w == 0.0) {
        out_a[i] = in_a[i];
        out_s[i] = in_s[i];
        return;
    }
    ivec2 p = ivec2(i % w, i / w);
    ivec2 step = AXIS == 0u ? ivec2(1, 0) : ivec2(0, 1);
    float z0 = view_z(g.cam, gpos[i].xyz);
    uint r0 = gregion[i][pc.level];
    float sigma_px = max(float(pc.radius) * 0.5, 0.5);
    vec4 acc_a = vec4(0.0);
    float acc_s = 0.0, wsum = 0.0;
    for (int k = -pc.radius; k <= pc.radius; ++k) {
        ivec2 t = p + k * step;
        if (t.x < 0 || t.y < 0 || t.x >= int(w) || t.y >= int(h)) continue;
        uint j = uint(t.y) * w + uint(t.x);
        vec4 nj = gnorm[j];
        if (nj.w == 0.0) continue;
        if (pc.semantic != 0u && gregion[j][pc.level] != r0) continue;
        float dz = (view_z(g.cam, gpos[j].xyz) - z0) / pc.sigma_z;
        float wk = exp(-0.5 * float(k * k) / (sigma_px * sigma_px)) * exp(-0.5 * dz * dz)
                 * pow(max(dot(n4.xyz, nj.xyz), 0.0), 8.0);
        acc_a += wk * in_a[j];
        acc_s += wk * in_s[j];
        wsum += wk;
    }
    // The centre tap always has weight 1, so wsum >= 1.
    out_a[i] = acc_a / wsum;
    out_s[i] = pc.blur_shadow != 0u ? acc_s / wsum : in_s[i];
}
