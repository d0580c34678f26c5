#version 460
// Semantic screen-space directional occlusion with one indirect bounce
// (after the semantic SSDO paper). With HALF (spheres large on screen) one receiver per 2x2
// block, the block's representative pixel (ssdo_prep.comp); the blur
// (blur.comp) runs on the blocks and shade.comp upsamples with depth,
// normal and region weights. Else every pixel is a receiver (small spheres:
// the AO changes from pixel to pixel). Receivers are rebuilt exactly from
// (pixel ray, sphere id). Directions come from the
// sample table (a uniform buffer: Halton + Malley, made once on the CPU),
// rotated about the normal by a 4x4 pattern over the blocks. The occluder
// test uses the exact depth of the full-resolution pixel a sample projects
// to (its depth key); regions, normal and reflected light come
// from its block's record. Per direction:
// - near radius: one sample point; far radius: a fixed-step march along the
//   direction up to the far radius (the paper's occluder search), the first
//   occluder found counts;
// - a sample is an occluder if the surface seen at its projection is closer
//   to the viewer than the sample, lies within the radius, and (semantic
//   mode) belongs to a different region than the receiver: the region test
//   is a blend of two hierarchy levels (weight `blend` on level b);
// - visibility = V_near * V_far (multiplying visibilities, not occlusion);
// - bounce (Ritschel et al.): sum over far occluders of
//   (albedo/pi) * L_direct(Q) * A_s * cos_s * cos_r / d^2, A_s = pi r^2 / N.
// Output per receiver (ssdo_common.glsl pack_ao): near and far visibility
// (V = V_near * V_far after the blur), the incoming bounce, and the block's
// screen-space key-light visibility.
#include "shared.glsl"

layout(local_size_x_id = 0) in;
#include "spec/ssdo.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer recordTex;
layout(set = 0, binding = 2) uniform SampleTable { vec4 samples[64]; };
layout(set = 0, binding = 3) writeonly buffer Ao { uint ao[]; };
layout(set = 0, binding = 4) uniform usamplerBuffer visTex;
#define SCENE_ATTRIBUTES
#include "scene.glsl"
// The taps' depth words (ssdo_prep.comp's copy, four per 2x2 block): a tap
// reads only the depth half of a key (a one-component gather; background
// keys are all ones), from half the bytes a row of visibility keys spans
// (meso 10^9 at 2,025 A, per pixel: ssdo 205 -> 195 ms).
layout(set = 0, binding = 7) uniform usamplerBuffer tapDepthTex;
#define TAP_DEPTH_BLOCKED
// Per pixel (not HALF): the blur's edge key of each pixel (blur_key).
layout(set = 0, binding = 8) writeonly buffer Keys { uint keys[]; };

#include "push/ssdo.glsl"

#include "surface.glsl"
#include "ssdo_common.glsl"
#include "ssdo_record.glsl"
#define TILE_LIST_ID SPEC_NEXT_ID
#define TILE_LIST_BINDING 9
#include "tiles.glsl"
#include "ssdo_taps.glsl"

const float BAYER4[16] = float[](0.0, 8.0, 2.0, 10.0, 12.0, 4.0, 14.0, 6.0,
                                 3.0, 11.0, 1.0, 9.0, 15.0, 7.0, 13.0, 5.0);

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    // HALF: one receiver per block, its representative pixel; else every
    // pixel (whose block record gives the screen-space key visibility).
    uvec2 cell;
    if (HALF ? !tile_pixel(g.counts.y, g.counts.z, true, cell) || !IN_ACTIVE_BLOCK(cell)
             : !tile_pixel(w, h, false, cell) || !IN_ACTIVE(cell)) return;
    uvec2 blk = HALF ? cell : cell / SSDO_BLOCK;
    Record own = record_at(blk);
    uvec2 px = HALF ? SSDO_BLOCK * blk + own.sub : cell;
    uint out_index = HALF ? blk.y * g.counts.y + blk.x : px.y * w + px.x;
    Surface s;
    if (TILE_LIST == 2u || !own.covered || !surface_of(px, s)) {
        ao[out_index] = pack_ao(vec2(1.0), vec3(0.0), 1.0);
        if (!HALF) keys[out_index] = BLUR_KEY_BACKGROUND;
        return;
    }
    uint ra = own.region_a, rb = own.region_b;
    if (!HALF) {
        // the pixel's own sphere, which need not be its block's
        uvec2 own_regions = regions_of(s.batch, s.id);
        ra = own_regions.x;
        rb = own_regions.y;
        keys[out_index] = blur_key(view_z(g.cam, s.p, PERSP), pc.blur_level_b != 0u ? rb : ra);
    }
    vec3 x = to_space(s.p), n = dir_to_space(s.n);
    // One rotation of the table per receiver, a 4x4 pattern the blur averages.
    float rot = (BAYER4[(cell.y & 3u) * 4u + (cell.x & 3u)] + 0.5) / 16.0;
    mat3 frame = rotated_frame(tangent_frame(n), rot);
    float occ_near = 0.0, occ_far = 0.0;
    vec3 bounce = vec3(0.0);
    float area = 3.14159265 * pc.r_far * pc.r_far / float(DIRS);
    for (uint kk = 0u; kk < DIRS; ++kk) {
        vec4 t = samples[kk];
        vec3 dir = frame * t.xyz;
        // near: one sample at a Halton-distributed distance
        float lam = fract(t.w + rot) * 0.8 + 0.2;
        vec3 sn = x + n * 1e-3 + lam * pc.r_near * dir;
        uvec2 qpx;
        float qz;
        vec3 qp;
        bool seen = surface_seen(sn, qpx, qz, qp);
        if (seen && qpx != px && qz < depth_of(sn) && dist2(qp, x) < pc.r_near * pc.r_near) {
            occ_near += SEMANTIC ? region_weight(ra, rb, record_at(qpx / SSDO_BLOCK)) : 1.0;
        }
        // far: fixed-step search for the first occluder. Only its pixel is
        // kept in the march; its record and bounce are evaluated once per
        // direction after it (on lavapipe both sides of an `if` run, so
        // work inside the march would be paid on every step).
        bool found = false;
        uvec2 fpx = uvec2(0u);
        vec3 fp = vec3(0.0);
        for (uint j = 1u; j <= STEPS; ++j) {
            float tt = (float(j) - 0.5 + 0.5 * rot) / float(STEPS);
            vec3 sf = x + n * 1e-3 + tt * pc.r_far * dir;
            bool seen = surface_seen(sf, qpx, qz, qp);
            bool hit = seen && !found && qpx != px && qz < depth_of(sf)
                    && dist2(qp, x) < pc.r_far * pc.r_far;
            if (hit) {
                found = true;
                fpx = qpx;
                fp = qp;
            }
        }
        if (found) {
            Record q = record_at(fpx / SSDO_BLOCK);
            float wgt = region_weight(ra, rb, q);
            occ_far += wgt;
            // Light bounced off the occluder's directly lit surface.
            float d = distance(fp, x);
            vec3 to_x = (x - fp) / max(d, 1e-4);
            float cs = max(dot(dir_to_space(q.n), to_x), 0.0), cr = max(dot(n, -to_x), 0.0);
            float d2 = max(d * d, 0.25 * pc.r_near * pc.r_near);
            bounce += wgt * q.radiance * (area * cs * cr / d2) / 3.14159265;
        }
    }
    vec2 v = vec2(1.0 - occ_near / float(DIRS), 1.0 - occ_far / float(DIRS));
    // (the receiver's albedo is applied in shade)
    ao[out_index] = pack_ao(v, pc.bounce * bounce, own.visibility);
}
