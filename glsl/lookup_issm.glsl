// Implicit Sphere Shadow Map lookup (seed 000). The light ray from P toward
// the key light is tested exactly against the spheres stored in the
// (2t+1)^2 texel patch of the ISSM (nearest sphere id per light texel)
// around P's light texel. A sphere never shadows itself (identity check).
//
// Soft shadows (specialization constant SOFT), as derived from the garbled
// seed text (docs/SEEDS-NOTES.md): with k = distance along the light ray to
// the occluder's closest approach and dist = distance of the ray to the
// occluder centre r away,
//   s_eff = s * (1 - exp(-k^2 / (2 b^2)))     penumbra widens with distance k
//   s'    = dist - r                          gap between ray and occluder
//   shadow strength = (1 - s'/s_eff)^x for s' < s_eff, full inside (dist < r)
// and the illumination is the minimum over the patch. s -> 0 gives the hard
// result exactly. Hard mode compiles without the soft math.
//
// Parameters: shadow_u.x = t, shadow_u.y = stride (texel step outside the
// dense 3x3 core), shadow_f0.xyz = (s, x, b). ISSM_CORE_ONLY (a
// specialization constant of the including shader, set when t <= 1)
// compiles the outer patch loop out: on lavapipe its empty iterations
// would still run for every pixel. ISSM_QUAD (t = 0) reads only the 2x2
// texels whose centres surround P's light position: 4 occluder tests, not
// 9 (hard shade 68 -> 55 ms on the 1M capsid at 1080p, 3 alternating
// runs; its hard mask there agrees with exact rays on 98.44 % of pixels
// against 98.84 % for 3x3).
layout(set = 0, binding = 16) uniform usamplerBuffer issmTex; // R32UI view: even texels = sphere ids
// The same map as RGBA32UI: two light texels per fetch (ids in x and z).
layout(set = 0, binding = 17) uniform usamplerBuffer issmPairTex;

// How strongly one occluder shadows p, as a fraction num / den (den > 0):
// 1 where the light ray crosses it (full shadow), else the soft penumbra's
// 1 - s'/s_eff = (s_eff - s') / s_eff, 0 outside it. The shadow strength
// (1 - s'/s_eff)^x grows with this closeness, so the minimum illumination
// over the patch is 1 - (max closeness)^x: one pow per pixel, not one per
// occluder; and the max is kept as a fraction compared by cross-multiplying,
// so a pixel divides once, not once per occluder. No sqrt in the hit test:
// the far hit k + sqrt(r^2 - d^2) is ahead iff k > 0 or p is inside the
// sphere. Selects, no early returns: lavapipe runs every branch anyway,
// with mask bookkeeping on top. `inv2b2` = 1 / (2 b^2).
vec2 occluder_closeness(vec3 p, vec3 dl, vec4 s, float inv2b2) {
    vec3 oc = s.xyz - p;
    float k = dot(oc, dl);
    float l2 = dot(oc, oc), r2 = s.w * s.w;
    float d2 = max(l2 - k * k, 0.0);
    bool hit = d2 < r2 && (k > 0.0 || l2 < r2);
    if (!SOFT) return vec2(hit ? 1.0 : 0.0, 1.0);
    float se = g.shadow_f0.x * (1.0 - exp(-k * k * inv2b2));
    float gap = sqrt(d2) - s.w;
    bool near = g.shadow_f0.x > 0.0 && k > 0.0 && gap < se;
    return hit ? vec2(1.0) : (near ? vec2(se - gap, se) : vec2(0.0, 1.0));
}

// The larger of two closeness fractions (denominators > 0).
vec2 max_closeness(vec2 a, vec2 b) { return b.x * a.y > a.x * b.y ? b : a; }

// Sphere id stored at light texel t (NO_SPHERE outside or empty): the low
// word of the 64-bit depth|id key, read as 32 bits.
uint texel_id(ivec2 t, int size) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(size)))) return NO_SPHERE;
    return texelFetch(issmTex, 2 * (t.y * size + t.x)).x;
}

// The closeness to shadowing s of sphere id, read at a light texel (0 for
// an empty texel and for s's own sphere: a sphere never shadows itself).
vec2 id_closeness(Surface s, vec3 dl, uint id, float inv2b2) {
    if (id == NO_SPHERE || id == s.id) return vec2(0.0, 1.0);
    return occluder_closeness(s.p, dl, texelFetch(sphereTex, int(id)), inv2b2);
}
vec2 texel_closeness(Surface s, vec3 dl, ivec2 t, int size, float inv2b2) {
    return id_closeness(s, dl, texel_id(t, size), inv2b2);
}

float key_visibility(Surface s, uint pixel) {
    View L = g.light;
    vec3 dl = -L.dir.xyz; // toward the light
    vec2 uv = light_uv(L, s.p) - 0.5; // texel centres at integers
    ivec2 c = ivec2(round(uv));
    int size = int(L.dims.x);
    int t = int(g.shadow_u.x), stride = int(max(g.shadow_u.y, 1u));
    float inv2b2 = 0.5 / (g.shadow_f0.z * g.shadow_f0.z);
    vec2 m = vec2(0.0, 1.0); // the largest closeness so far, as a fraction
    // (Repeated ids are tested again: skipping the last two seen saved
    // nothing on lavapipe, where a masked lane runs the body anyway.)
    // Dense core: the spheres nearest the light around P. With ISSM_QUAD
    // the 2x2 texels whose centres surround P's light position, else the
    // 3x3 around P's own texel. The core is kept inside the map (size >=
    // 16), so it needs no bounds test per texel: at the border it reads the
    // edge's own texels instead of empty ones outside, and testing an extra
    // sphere never adds a wrong shadow (the hit test is exact).
    const int n = ISSM_QUAD ? 2 : 3;
    ivec2 lo = ISSM_QUAD ? clamp(ivec2(floor(uv)), ivec2(0), ivec2(size - 2))
                         : clamp(c, ivec2(1), ivec2(size - 2)) - 1;
    int first = lo.y * size + lo.x;
    for (int dy = 0; dy < n && m.x < m.y; ++dy) {
        int i = first + dy * size;
        if (ISSM_QUAD) {
            for (int dx = 0; dx < 2; ++dx) {
                m = max_closeness(m, id_closeness(s, dl, texelFetch(issmTex, 2 * (i + dx)).x, inv2b2));
            }
        } else {
            // The row's three ids from two fetches of texel pairs instead
            // of three fetches (on lavapipe a texel fetch costs per lane
            // whatever its width): texels i, i + 1, i + 2 lie in pairs
            // i / 2 and i / 2 + 1, from their first or second texel.
            uvec4 a = texelFetch(issmPairTex, i >> 1), b = texelFetch(issmPairTex, (i >> 1) + 1);
            bool odd = (i & 1) != 0;
            m = max_closeness(m, id_closeness(s, dl, odd ? a.z : a.x, inv2b2));
            m = max_closeness(m, id_closeness(s, dl, odd ? b.x : a.z, inv2b2));
            m = max_closeness(m, id_closeness(s, dl, odd ? b.z : b.x, inv2b2));
        }
    }
    // The rest of the (2t+1)^2 patch, every `stride` texels: the stride is at
    // most the smallest sphere radius in texels, so every sphere whose disk
    // is visible from the light lands on at least one sample.
    int lim = ISSM_CORE_ONLY ? 0 : (t / stride) * stride;
    for (int dy = -lim; !ISSM_CORE_ONLY && dy <= lim && m.x < m.y; dy += stride) {
        for (int dx = -lim; dx <= lim; dx += stride) {
            if (abs(dx) <= 1 && abs(dy) <= 1) continue;
            m = max_closeness(m, texel_closeness(s, dl, c + ivec2(dx, dy), size, inv2b2));
        }
    }
    if (!SOFT) return 1.0 - m.x;
    return m.x <= 0.0 ? 1.0 : 1.0 - pow(m.x / m.y, g.shadow_f0.y);
}
