#version 460
// Implicit Sphere Shadow Map lookup (seed 000). For each visible point P, the
// light ray from P toward the key light is tested exactly against the spheres
// stored in the (2t+1)^2 texel patch of the ISSM (nearest sphere per light
// texel) around P's light texel. A sphere never shadows itself (identity
// check on the id).
//
// Soft shadows, as derived from the garbled seed text (docs/SEEDS-NOTES.md):
// with k = distance along the light ray to the occluder's closest approach
// and dist = distance of the ray to the occluder centre r away,
//   s_eff = s * (1 - exp(-k^2 / (2 b^2)))     penumbra widens with distance k
//   s'    = dist - r                          gap between ray and occluder
//   shadow strength = (1 - s'/s_eff)^x for s' < s_eff, full inside (dist < r)
// and the illumination is the minimum over the patch. s -> 0 gives the hard
// result exactly.
#include "shared.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 4) readonly buffer Issm { uint64_t issm[]; };
layout(set = 0, binding = 5) writeonly buffer Shadow { float shadow[]; };

layout(push_constant) uniform Push {
    int t;         // patch half-size in texels
    int stride;    // texel step outside the dense 3x3 core (1 = every texel)
    float soft_s;  // 0 = hard shadows
    float soft_x;
    float soft_b;
} pc;

float occluder_visibility(vec3 p, vec3 dl, vec4 s) {
    vec3 oc = s.xyz - p;
    float k = dot(oc, dl);
    float d2 = max(dot(oc, oc) - k * k, 0.0);
    if (d2 < s.w * s.w) {
        // The ray crosses the sphere; it occludes if the far hit is ahead.
        return k + sqrt(s.w * s.w - d2) > 0.0 ? 0.0 : 1.0;
    }
    if (pc.soft_s <= 0.0 || k <= 0.0) return 1.0;
    float se = pc.soft_s * (1.0 - exp(-k * k / (2.0 * pc.soft_b * pc.soft_b)));
    float gap = sqrt(d2) - s.w;
    if (gap >= se) return 1.0;
    return 1.0 - pow(1.0 - gap / se, pc.soft_x);
}

// Sphere id stored at light texel t (NO_SPHERE outside or empty).
uint texel_id(ivec2 t, int size) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(size)))) return NO_SPHERE;
    uint64_t k = issm[uint(t.y) * uint(size) + uint(t.x)];
    return k == VIS_EMPTY ? NO_SPHERE : uint(k & 0xFFFFFFFFul);
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
    vec3 p = gpos[i].xyz;
    View L = g.light;
    vec3 dl = -L.dir.xyz; // toward the light
    ivec2 c = ivec2(round(light_uv(L, p) - 0.5));
    int size = int(L.dims.x);
    float v = 1.0;
    // Neighbouring texels mostly hold the same sphere: remember the last two
    // ids tested and skip repeats (a min over the same occluder is a no-op).
    uint last0 = NO_SPHERE, last1 = NO_SPHERE;
    // Dense core: the spheres nearest the light around P's own texel.
    for (int dy = -1; dy <= 1 && v > 0.0; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            uint id = texel_id(c + ivec2(dx, dy), size);
            if (id == NO_SPHERE || id == self_id || id == last0 || id == last1) continue;
            last1 = last0;
            last0 = id;
            v = min(v, occluder_visibility(p, dl, spheres[id]));
        }
    }
    // The rest of the (2t+1)^2 patch, every `stride` texels: the stride is at
    // most the smallest sphere radius in texels, so every sphere whose disk
    // is visible from the light lands on at least one sample.
    int lim = (pc.t / pc.stride) * pc.stride;
    for (int dy = -lim; dy <= lim && v > 0.0; dy += pc.stride) {
        for (int dx = -lim; dx <= lim; dx += pc.stride) {
            if (abs(dx) <= 1 && abs(dy) <= 1) continue;
            uint id = texel_id(c + ivec2(dx, dy), size);
            if (id == NO_SPHERE || id == self_id || id == last0 || id == last1) continue;
            last1 = last0;
            last0 = id;
            v = min(v, occluder_visibility(p, dl, spheres[id]));
        }
    }
    shadow[i] = v;
}
