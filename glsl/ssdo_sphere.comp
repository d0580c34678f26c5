#version 460
// Semantic SSDO per visible sphere, for spheres a few pixels wide on screen
// (the per-pixel receivers of ssdo.comp cost some 50 gathers per covered
// pixel there, most of a frame on lavapipe; a sphere of radius 1.5 px
// covers about 7 pixels). Receivers are the points c + r d_k of each
// visible sphere (listed by ssdo_list.comp), one per direction d_k of
// ssdo_common.glsl's set: the surface point whose normal is d_k. Per
// direction, as ssdo.comp's far term, the first occluder along its ray
// (no near sample: the first taps lie within two radii), found from taps
// that the directions of one azimuth share (below). An occluder is a
// surface seen closer to the viewer than the ray, within the radius, not
// this sphere, and (semantic) in another region than the sphere; the
// bounce comes off the line's first occluder's lit surface. The
// per-direction occluder weights go to the sphere's result as the
// spherical harmonics of their cosine-lobe sum (sphere_ao_pack), which
// shade.comp evaluates at each pixel's normal: per-pixel AO from
// per-sphere work, without noise to blur.
#extension GL_EXT_control_flow_attributes : require
#include "shared.glsl"

layout(local_size_x_id = 0) in;
#include "spec/ssdo_sphere.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer recordTex;
layout(set = 0, binding = 2) writeonly buffer SphereAo { uvec4 sphere_ao[]; };
layout(set = 0, binding = 3) readonly buffer List { uint list[]; };
layout(set = 0, binding = 4) readonly buffer Counters { uint counters[]; };
#define SCENE_ATTRIBUTES
#include "scene.glsl"
// The visibility buffer as 32-bit words: depth (odd) and id (even) halves.
layout(set = 0, binding = 7) uniform usamplerBuffer visWordTex;
// The taps' depth words, four per 2x2 block (ssdo_prep.comp): the taps'
// fetches were mostly cache misses in the visibility buffer's rows.
layout(set = 0, binding = 8) uniform usamplerBuffer tapDepthTex;
#define TAP_DEPTH_BLOCKED

#include "push/ssdo.glsl"

#include "ssdo_common.glsl"
#include "ssdo_record.glsl"
#include "ssdo_taps.glsl"

// Occluder weight of the surface seen at pixel q, whose block record is
// rec. Without a hierarchy every sphere is its own region: the pixel's own
// sphere (one id fetch). With one, the record's regions (as ssdo.comp's
// taps): the hierarchy's regions span many spheres, and the record is
// fetched for the bounce anyway (an id and an attribute fetch saved).
float occluder_weight(uvec2 own, uvec2 q, Record rec) {
    if (!SEMANTIC) return 1.0;
    uvec2 rq;
    if (g.counts.w != 0u) {
        rq = uvec2(region_hash(scene_index(texelFetch(visWordTex, int(2u * (q.y * g.cam.dims.x + q.x))).x)));
    } else {
        rq = uvec2(rec.region_a, rec.region_b);
    }
    return mix(own.x != rq.x ? 1.0 : 0.0, own.y != rq.y ? 1.0 : 0.0, pc.blend);
}

void main() {
    uint job = (gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x) * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
    if (job >= counters[S_LISTED]) return;
    uint id = list[job];
    uvec4 bt = scene_batch_of(id);
    vec4 sp = batch_sphere(bt, id);
    vec3 c = to_space(sp.xyz);
    float r = sp.w;
    // a seen surface farther from the centre than this is not this sphere
    // (visible surfaces lie outside every sphere; 1 % for rounding)
    float self2 = (1.01 * r) * (1.01 * r);
    uvec2 own = SEMANTIC ? regions_of(bt, id) : uvec2(0u);
    mat3 basis = PERSP ? sphere_basis(normalize(sp.xyz - (g.cam.center.xyz - g.cam.dir.w * g.cam.dir.xyz)), g.cam.up.xyz)
                       : mat3(1.0);
    uint index = batch_index(bt, id);
    float rot = sphere_rot(index), jit = sphere_jitter(index);
    vec3 zb = basis[2];
    SH9 acc;
    acc.a = vec4(0.0);
    acc.b = vec4(0.0);
    acc.c = 0.0;
    vec3 bounce = vec3(0.0);
    // each direction stands for 1/(K/2) of a receiver's hemisphere
    float area = 3.14159265 * pc.r_far * pc.r_far / (0.5 * float(SSDO_SPHERE_DIRS));
    float reach = r + pc.r_far, rf2 = pc.r_far * pc.r_far;
    // taps start where the lowest elevation's search does (t = r_far / 10)
    float s_lo = (r + 0.1 * pc.r_far) * SPHERE_HE(0u);
    // view depth per unit along the sphere's view axis
    float zdepth = PERSP ? dot(zb, g.cam.dir.xyz) : 1.0;
    for (uint a = 0u; a < SSDO_SPHERE_AZIMUTHS; ++a) {
        // One screen-space line from the centre per azimuth: every
        // elevation's ray x_e + t d_e (x_e = c + r d_e) projects onto it
        // (orthographic exactly; perspective up to the angle between the
        // sphere's and the tap's lines of sight), at distance (r + t) h_e
        // from the centre. So a tap on the line serves all elevations: the
        // seen surface occludes elevation e if it is nearer the viewer
        // than that ray where the ray crosses the tap's line of sight.
        float phi = 6.2831853 * (float(a) + rot) / float(SSDO_SPHERE_AZIMUTHS);
        vec2 cs = vec2(cos(phi), sin(phi));
        vec3 u = basis * vec3(cs, 0.0);
        // Per elevation e, the ray x_e + t d_e (x_e = c + r d_e, d_e =
        // h_e u + z_e zb, a unit vector) is searched from t = r_far / 10
        // to r_far: taps at s in ((r + r_far / 10) h_e, (r + r_far) h_e].
        // The tests below are written with the elevation's constants
        // (h_e, z_e) only, per tap, so nothing per elevation stays live
        // across the march (lavapipe spilled the per-elevation points and
        // bounds: 66 -> 57 ms with this and one occluder point per line).
        bool found[SPHERE_ELEVATIONS];
        for (uint e = 0u; e < SPHERE_ELEVATIONS; ++e) found[e] = false;
        float near_s = r + 0.1 * pc.r_far;
        float inv2r = 0.5 / r, r2 = r * r;
        bool any = false;
        uvec2 first = uvec2(0u);
        vec3 first_p = vec3(0.0); // the line's first occluder's surface
        // Unrolled (STEPS is a specialization constant): the taps' gathers
        // no longer wait on the previous tap's tests. ssdo 77.5 -> 63.5 ms on
        // the 1M capsid at 1080p (lavapipe, 3 alternating pairs); unrolling
        // the azimuths too made it 39 % slower, and the per-pixel march of
        // ssdo.comp gained nothing from it.
        [[unroll]] for (uint j = 0u; j < STEPS; ++j) {
            float s = s_lo + (reach - s_lo) * (float(j) + 0.5 * jit) / float(STEPS);
            vec3 p = c + s * u;
            uvec2 qpx;
            float qz;
            vec3 qp;
            bool seen = surface_seen(p, qpx, qz, qp);
            vec3 q = qp - c;
            float q2 = dot(q, q), qu = dot(q, u), qzb = dot(q, zb);
            bool valid = seen && q2 > self2;
            // nearer the viewer than the ray: qz < depth(p) + s zdepth z_e / h_e
            float dz = qz - depth_of(p), sz = s * zdepth;
            // |qp - x_e|^2 < r_far^2  <=>  h_e qu + z_e qzb > t_far
            float t_far = (q2 + r2 - rf2) * inv2r;
            bool hit_any = false;
            for (uint e = 0u; e < SPHERE_ELEVATIONS; ++e) {
                float h = SPHERE_HE(e), z = SPHERE_ZE(e);
                float se = s * (1.0 / h);
                bool hit = valid && !found[e] && se > near_s && se <= reach
                        && dz < sz * (z / h) && h * qu + z * qzb > t_far;
                found[e] = found[e] || hit;
                hit_any = hit_any || hit;
            }
            first = hit_any && !any ? qpx : first;
            first_p = hit_any && !any ? qp : first_p;
            any = any || hit_any;
        }
        // The line's first occluder's record: its regions (semantic) and the
        // light it reflects, for every elevation it occludes (one fetch per
        // azimuth, not per direction).
        Record q = record_at(first / SSDO_BLOCK);
        float wq = any ? occluder_weight(own, first, q) : 0.0;
        vec3 qn = dir_to_space(q.n);
        for (uint e = 0u; e < SPHERE_ELEVATIONS; ++e) {
            vec3 d = SPHERE_HE(e) * u + SPHERE_ZE(e) * zb;
            vec3 x = c + r * d;
            float wf = found[e] ? wq : 0.0;
            float dd = distance(first_p, x);
            vec3 to_x = (x - first_p) / max(dd, 1e-4);
            float cs_q = max(dot(qn, to_x), 0.0), cr = max(dot(d, -to_x), 0.0);
            float d2 = max(dd * dd, 0.25 * pc.r_near * pc.r_near);
            bounce += wf * q.radiance * (area * cs_q * cr / d2) / 3.14159265;
            // (the direction in the sphere's frame)
            SH9 y = sh9_basis(vec3(SPHERE_HE(e) * cs, SPHERE_ZE(e)));
            acc.a += wf * y.a;
            acc.b += wf * y.b;
            acc.c += wf * y.c;
        }
    }
    // the mean over the hemisphere a pixel sees: half the directions
    // (at the sphere's list entry: shade finds it by sphere_entry)
    sphere_ao[job] = sphere_ao_pack(acc, pc.bounce * bounce * 0.5);
}
