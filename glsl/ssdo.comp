#version 460
// Semantic screen-space directional occlusion with one indirect bounce
// (seed 001). Per pixel, cosine-weighted hemisphere directions (Halton +
// Malley, rotated per pixel):
// - near radius: one sample point per direction; far radius: a fixed-step
//   march along the direction up to the far radius (the paper's occluder
//   search), the first occluder found counts;
// - a sample is an occluder if the surface seen at its projection is closer
//   to the viewer than the sample, lies within the radius, and (semantic
//   mode) belongs to a different region than the receiver: the region test
//   is a blend of two hierarchy levels (weight `blend` on level_b);
// - visibility = V_near * V_far (multiplying visibilities, not occlusion);
// - bounce (Ritschel et al.): sum over far occluders of
//   (albedo/pi) * L_direct(Q) * A_s * cos_s * cos_r / d^2, A_s = pi r^2 / N.
#include "ssdo_common.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Attrs { SphereAttr attrs[]; };
layout(set = 0, binding = 2) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 4) readonly buffer GNorm { vec4 gnorm[]; };
layout(set = 0, binding = 5) readonly buffer GRegion { uvec4 gregion[]; };
layout(set = 0, binding = 6) readonly buffer Shadow { float shadow[]; };
layout(set = 0, binding = 7) writeonly buffer Ambient { vec4 ambient[]; };

layout(push_constant) uniform Push {
    float r_near;
    float r_far;
    uint dirs;
    uint steps;
    uint semantic; // 0 plain, 1 semantic
    uint level_a;
    uint level_b;
    float blend;   // weight of level_b in the region test
    float bounce;  // bounce strength
    float pad0, pad1, pad2;
} pc;

vec3 srgb_to_linear(vec3 c) { return pow(c, vec3(2.2)); }

// Occluder weight of the surface at pixel q for receiver regions rr (0..1).
float region_weight(uvec4 rr, uint q) {
    if (pc.semantic == 0u) return 1.0;
    uvec4 rq = gregion[q];
    float da = rr[pc.level_a] != rq[pc.level_a] ? 1.0 : 0.0;
    float db = rr[pc.level_b] != rq[pc.level_b] ? 1.0 : 0.0;
    return mix(da, db, pc.blend);
}

// Returns the pixel index seen at s, or -1 when off screen or background.
int pixel_at(vec3 s) {
    vec2 px = round(project_px(g.cam, s));
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    if (px.x < 0.0 || px.y < 0.0 || px.x >= float(w) || px.y >= float(h)) return -1;
    uint q = uint(px.y) * w + uint(px.x);
    return gnorm[q].w == 0.0 ? -1 : int(q);
}

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    vec4 n4 = gnorm[i];
    if (n4.w == 0.0) {
        ambient[i] = vec4(1.0, 0.0, 0.0, 0.0);
        return;
    }
    vec3 x = gpos[i].xyz, n = n4.xyz;
    uvec4 rr = gregion[i];
    float rot = hash12(uvec2(i % w, i / w));
    vec3 l_key = -normalize(g.light_dir.xyz);
    float occ_near = 0.0, occ_far = 0.0;
    vec3 bounce = vec3(0.0);
    float area = 3.14159265 * pc.r_far * pc.r_far / float(pc.dirs);
    for (uint k = 0u; k < pc.dirs; ++k) {
        vec3 dir = hemisphere_sample(k, n, rot);
        // near: one sample at a Halton-distributed distance
        float lam = mix(0.2, 1.0, fract(halton(k + 1u, 5u) + rot));
        vec3 s = x + n * 1e-3 + lam * pc.r_near * dir;
        int q = pixel_at(s);
        if (q >= 0 && uint(q) != i) {
            vec3 qp = gpos[q].xyz;
            if (view_z(g.cam, qp) < view_z(g.cam, s) && distance(qp, x) < pc.r_near)
                occ_near += region_weight(rr, uint(q));
        }
        // far: fixed-step search for the first occluder
        for (uint j = 1u; j <= pc.steps; ++j) {
            float t = (float(j) - 0.5 + 0.5 * rot) / float(pc.steps);
            vec3 sf = x + n * 1e-3 + t * pc.r_far * dir;
            int qf = pixel_at(sf);
            if (qf < 0 || uint(qf) == i) continue;
            vec3 qp = gpos[qf].xyz;
            float d = distance(qp, x);
            if (view_z(g.cam, qp) < view_z(g.cam, sf) && d < pc.r_far) {
                float wgt = region_weight(rr, uint(qf));
                occ_far += wgt;
                // Light bounced off the occluder's directly lit surface.
                vec3 nq = gnorm[qf].xyz;
                vec3 to_x = (x - qp) / max(d, 1e-4);
                float cs = max(dot(nq, to_x), 0.0), cr = max(dot(n, -to_x), 0.0);
                uint idq = uint(vis[qf] & 0xFFFFFFFFul);
                vec3 alb = srgb_to_linear(unpack_rgba8(attrs[idq].color).rgb);
                vec3 lq = alb * max(dot(nq, l_key), 0.0) * shadow[qf];
                float d2 = max(d * d, 0.25 * pc.r_near * pc.r_near);
                bounce += wgt * lq * (area * cs * cr / d2) / 3.14159265;
                break;
            }
        }
    }
    float v = (1.0 - occ_near / float(pc.dirs)) * (1.0 - occ_far / float(pc.dirs));
    uint id = uint(vis[i] & 0xFFFFFFFFul);
    vec3 alb = srgb_to_linear(unpack_rgba8(attrs[id].color).rgb);
    ambient[i] = vec4(v, pc.bounce * alb * bounce);
}
