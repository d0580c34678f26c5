// Baseline hard shadows (after the Metal protein viewer paper): depth shadow map lookup with a
// slope-scaled depth bias and percentage-closer filtering on a Vogel disk.
//
// The map is the key light's visibility buffer written by the compute sphere
// rasterizer (sm_raster): per texel, the light depth of the nearest sphere
// SURFACE (plus the view's depth offset) as float bits in the high word and
// the sphere id in the low word. P = gpos is projected into the light view
// and its light depth compared with the stored one:
//   lit  iff  depth(P) - bias <= map depth,
//   bias = c + s * min(tan(theta), tan_max)     (theta: angle of N to the light)
// where c and s (world units) come from --sm-bias and --sm-slope-bias times
// the texel size (s also times the lookup reach, see src/stages/shadows/shadow_map.rs).
//
// PCF: `samples` taps at offsets radius * sqrt((k + 0.5) / N) at angles
// k * 2.4 + phi (the golden-angle Vogel disk of the seed), phi a per-pixel
// hash so the banding of a fixed pattern turns into fine noise; visibility is
// the fraction of taps that pass. samples <= 1 is one tap at P's texel.
//
// Receivers facing away from the light (N . L <= 0): the depth map
// necessarily holds the receiver's own lit cap in front of P, but the shadow
// AOV counts occlusion by OTHER spheres only (DESIGN.md). There, a tap whose
// nearest sphere is the receiver itself (the id half of the key; on an
// instanced scene, or the same placed centre) counts as unoccluded. The
// same holds within the grazing band where tan(theta) would exceed tan_max
// (N . L < 1 / sqrt(1 + tan_max^2), about 5.7 degrees from the terminator
// for tan_max = 10): no finite slope bias avoids acne there. All
// other receivers use the plain biased depth test, so their acne and
// peter-panning are exactly those of a classic shadow map.
// Parameters: shadow_f0 = (bias_const, bias_slope, tan_max, PCF radius in
// texels) in world units, shadow_u.x = PCF taps.
layout(set = 0, binding = 16) uniform usamplerBuffer mapTex; // RG32UI: x = id, y = depth bits

const float GOLDEN_ANGLE = 2.4;
const float TWO_PI = 6.2831853;

// Integer hash (PCG-style) of the pixel index -> [0, 1).
float hash01(uint x) {
    uint s = x * 747796405u + 2891336453u;
    uint w = ((s >> ((s >> 28u) + 4u)) ^ s) * 277803737u;
    w = (w >> 22u) ^ w;
    return float(w >> 8) * (1.0 / 16777216.0);
}

float key_visibility(Surface s, uint pixel) {
    vec3 p = s.p;
    vec3 n = s.n;
    View L = g.light;
    vec3 q = p - L.center.xyz;
    float size = L.right.w;
    // Texel-index coordinates (texel centres at integers).
    vec2 uv = light_uv(L, p) - 0.5;
    float pd = dot(q, L.dir.xyz) + L.depth.x;
    float bias_const = g.shadow_f0.x, bias_slope = g.shadow_f0.y;
    float tan_max = g.shadow_f0.z, radius = g.shadow_f0.w;

    float ndl = dot(n, -L.dir.xyz);
    bool back = ndl * sqrt(1.0 + tan_max * tan_max) <= 1.0;
    float tan_t = back ? tan_max : min(sqrt(max(1.0 - ndl * ndl, 0.0)) / ndl, tan_max);
    float bias = bias_const + bias_slope * tan_t;
    float test_depth = pd - bias;

    uint taps = max(g.shadow_u.x, 1u);
    float phi = taps > 1u ? TWO_PI * hash01(image_index(g.cam, s.img)) : 0.0;
    int last = int(size) - 1;
    float lit = 0.0;
    for (uint k = 0u; k < taps; ++k) {
        vec2 off = vec2(0.0);
        if (taps > 1u) {
            float r = radius * sqrt((float(k) + 0.5) / float(taps));
            float a = float(k) * GOLDEN_ANGLE + phi;
            off = r * vec2(cos(a), sin(a));
        }
        ivec2 t = clamp(ivec2(round(uv + off)), ivec2(0), ivec2(last));
        uvec2 m = texelFetch(mapTex, t.y * int(size) + t.x).xy;
        // (the receiver's own sphere: on an instanced scene drawn through
        // the LOD lists a sphere's id is its slot in the view's list, so
        // the light's id of it is another; its placed centre is the same)
        bool own = m.x == s.id;
        if (scene_instanced() && back && m.x != NO_SPHERE) {
            own = own || scene_sphere(m.x).xyz == s.sphere.xyz;
        }
        if (m.x == NO_SPHERE || (back && own)) {
            lit += 1.0;
            continue;
        }
        float d = uintBitsToFloat(m.y);
        lit += test_depth <= d ? 1.0 : 0.0;
    }
    return lit / float(taps);
}
