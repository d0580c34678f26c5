#version 460
// Semantic SSDO per visible sphere, for spheres a few pixels wide on screen
// (the per-pixel receivers of ssdo.comp cost some 50 gathers per covered
// pixel there, most of a frame on lavapipe; a sphere of radius 1.5 px
// covers about 7 pixels). Receivers are the points c + r d_k of each
// visible sphere (listed by ssdo_list.comp), one per direction d_k of
// ssdo_common.glsl's sphere_dir: the surface point whose normal is d_k.
// Per direction, as ssdo.comp's far term: a fixed-step search for the
// first occluder (no near sample: the first step lies within two radii), an occluder being a surface seen closer to the
// viewer than the sample, within the radius, not this sphere, and
// (semantic) in another region than the sphere; the bounce off the far
// occluder's lit surface. The per-direction occluder weights go to the
// sphere's word (sphere_ao_bits) and shade.comp weights them by each
// pixel's normal: per-pixel AO from per-sphere work, without noise to blur.
#include "shared.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 1) const bool SEMANTIC = true;
layout(constant_id = 2) const uint STEPS = 5;
layout(constant_id = 3) const bool PERSP = false;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer recordTex;
layout(set = 0, binding = 2) writeonly buffer SphereAo { uvec4 sphere_ao[]; };
layout(set = 0, binding = 3) readonly buffer List { uint list[]; };
layout(set = 0, binding = 4) readonly buffer Counters { uint counters[]; };
layout(set = 0, binding = 5) uniform samplerBuffer sphereTex;
layout(set = 0, binding = 6) uniform usamplerBuffer attrTex;
// The visibility buffer as 32-bit words: depth (odd) and id (even) halves.
layout(set = 0, binding = 7) uniform usamplerBuffer visWordTex;

layout(push_constant) uniform Push {
    float r_near;
    float r_far;
    float blend;   // weight of level b in the region test
    float bounce;  // bounce strength
    uint level_a;
    uint level_b;
    uint blur_level_b;
    uint pad1;
} pc;

#include "ssdo_common.glsl"
#include "ssdo_record.glsl"
#include "ssdo_taps.glsl"

// The receiver's regions (ra, rb) at the two levels of sphere id.
uvec2 regions_of(uint id) {
    if (g.counts.w != 0u) return uvec2(region_hash(id));  // no hierarchy: own region
    uvec4 r = texelFetch(attrTex, int(2u * id));
    return uvec2(region_hash(r[pc.level_a]), region_hash(r[pc.level_b]));
}

// Occluder weight of the surface seen at pixel q: its own sphere's regions
// (one id fetch, then its attributes), not its block record's.
float occluder_weight(uvec2 own, uvec2 q) {
    if (!SEMANTIC) return 1.0;
    uint qid = texelFetch(visWordTex, int(2u * (q.y * g.cam.dims.x + q.x))).x;
    uvec2 rq = regions_of(qid);
    return mix(own.x != rq.x ? 1.0 : 0.0, own.y != rq.y ? 1.0 : 0.0, pc.blend);
}

void main() {
    uint job = (gl_WorkGroupID.x + gl_WorkGroupID.y * MAX_GROUPS_X) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    if (job >= counters[S_LISTED]) return;
    uint id = list[job];
    vec4 sp = texelFetch(sphereTex, int(id));
    vec3 c = to_space(sp.xyz);
    float r = sp.w;
    // a seen surface farther from the centre than this is not this sphere
    // (visible surfaces lie outside every sphere; 1 % for rounding)
    float self2 = (1.01 * r) * (1.01 * r);
    uvec2 own = SEMANTIC ? regions_of(id) : uvec2(0u);
    mat3 basis = PERSP ? sphere_basis(normalize(sp.xyz - (g.cam.center.xyz - g.cam.dir.w * g.cam.dir.xyz)), g.cam.up.xyz)
                       : mat3(1.0);
    float rot = sphere_rot(id);
    uvec2 word = uvec2(0u);
    vec3 bounce = vec3(0.0);
    // each direction stands for 1/(K/2) of a receiver's hemisphere
    float area = 3.14159265 * pc.r_far * pc.r_far / (0.5 * float(SSDO_SPHERE_DIRS));
    for (uint k = 0u; k < SSDO_SPHERE_DIRS; ++k) {
        vec3 d = basis * sphere_dir(k, rot);
        vec3 x = c + r * d;
        uvec2 qpx;
        float qz;
        vec3 qp;
        bool found = false;
        uvec2 fpx = uvec2(0u);
        vec3 fp = vec3(0.0);
        for (uint j = 1u; j <= STEPS; ++j) {
            float tt = (float(j) - 0.5 + 0.5 * rot) / float(STEPS);
            vec3 sf = x + tt * pc.r_far * d;
            bool seen = surface_seen(sf, qpx, qz, qp);
            bool hit = seen && !found && qz < depth_of(sf) && dist2(qp, x) < pc.r_far * pc.r_far
                    && dist2(qp, c) > self2;
            if (hit) {
                found = true;
                fpx = qpx;
                fp = qp;
            }
        }
        float wf = 0.0;
        if (found) {
            wf = occluder_weight(own, fpx);
            // Light bounced off the occluder's directly lit surface.
            Record q = record_at(fpx / SSDO_BLOCK);
            float dd = distance(fp, x);
            vec3 to_x = (x - fp) / max(dd, 1e-4);
            float cs = max(dot(dir_to_space(q.n), to_x), 0.0), cr = max(dot(d, -to_x), 0.0);
            float d2 = max(dd * dd, 0.25 * pc.r_near * pc.r_near);
            bounce += wf * q.radiance * (area * cs * cr / d2) / 3.14159265;
        }
        word |= sphere_ao_bit(k, wf);
    }
    // the mean over the hemisphere a pixel sees: half the directions
    sphere_ao[id] = uvec4(word, sphere_ao_bounce(pc.bounce * bounce * 0.5), 0u);
}
