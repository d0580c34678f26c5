// Implicit Sphere Shadow Map lookup (after the ISSM paper). The light ray from P toward
// the key light is tested exactly against the spheres stored in the
// (2t+1)^2 texel patch of the ISSM (nearest sphere per light texel) around
// P's light texel. A sphere never shadows itself.
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
// The map is read resolved (issm_resolve.comp): per texel its sphere's
// light-space centre and radius, one 16-byte fetch, instead of an id and a
// dependent sphere fetch. In light space the light ray from P is the line
// (P.x, P.y) along -z, so the tests need no projections.
//
// Parameters: shadow_u.x = t, shadow_u.y = stride (texel step outside the
// dense 3x3 core), shadow_f0.xyz = (s, x, b). ISSM_CORE_ONLY (a
// specialization constant of the including shader, set when t <= 1)
// compiles the outer patch loop out: on lavapipe its empty iterations
// would still run for every pixel. ISSM_QUAD (t = 0) reads only the 2x2
// texels whose centres surround P's light position: 4 occluder tests, not
// 9 (its hard mask on the 1M capsid agrees with exact rays on 98.44 % of
// pixels against 98.84 % for 3x3).
layout(set = 0, binding = 16) uniform samplerBuffer issmResolvedTex; // RGBA32F per texel

// P in light space, and (ISSM_SELF_TEST) its own sphere's centre there:
// the centre a texel of its own sphere carries, within a rounding
// tolerance. The includer defines ISSM_SELF_TEST (a constant expression).
struct LightPoint {
    vec3 p;
    vec3 own;
    float own_eps2;
};

// How strongly one occluder o (light-space centre, radius) shadows P, as a
// fraction num / den (den > 0): 1 where the light ray crosses it (full
// shadow), else the soft penumbra's 1 - s'/s_eff = (s_eff - s') / s_eff, 0
// outside it. The shadow strength (1 - s'/s_eff)^x grows with this
// closeness, so the minimum illumination over the patch is
// 1 - (max closeness)^x: one pow per pixel, not one per occluder; and the
// max is kept as a fraction compared by cross-multiplying, so a pixel
// divides once, not once per occluder. k = P.z - o.z is the distance from
// P toward the light to the closest approach, d2 the squared distance of
// the ray from the centre; the far hit k + sqrt(r^2 - d^2) is ahead iff
// k > 0 or P is inside the sphere.
//
// P's own sphere: with ISSM_SELF_TEST (the shadow AOV, which counts other
// spheres only) it is excluded by its centre and the inside clause is
// kept. Without it (the colour), neither is needed: a visible P lies inside
// no other sphere, and its own sphere hits only where P faces away from
// the light (k = -r N.L > 0), where the key light's diffuse and specular
// terms are 0 whatever the visibility; on the lit side k < 0, and the
// soft penumbra needs k > 0 too. Selects, no early returns: lavapipe runs
// every branch anyway, with mask bookkeeping on top. `inv2b2` = 1 / (2 b^2).
vec2 occluder_closeness(LightPoint lp, vec4 o, float inv2b2) {
    vec2 dxy = o.xy - lp.p.xy;
    float d2 = dot(dxy, dxy);
    float k = lp.p.z - o.z;
    float r2 = o.w * o.w;
    bool other = true, ahead = k > 0.0;
    if (ISSM_SELF_TEST) {
        vec3 dc = o.xyz - lp.own;
        other = dot(dc, dc) > lp.own_eps2;
        ahead = ahead || d2 + k * k < r2;
    }
    bool hit = other && d2 < r2 && ahead;
    if (!SOFT) return vec2(hit ? 1.0 : 0.0, 1.0);
    float se = g.shadow_f0.x * (1.0 - exp(-k * k * inv2b2));
    float gap = sqrt(d2) - o.w;
    bool near = other && g.shadow_f0.x > 0.0 && k > 0.0 && gap < se;
    return hit ? vec2(1.0) : (near ? vec2(se - gap, se) : vec2(0.0, 1.0));
}

// The larger of two closeness fractions (denominators > 0).
vec2 max_closeness(vec2 a, vec2 b) { return b.x * a.y > a.x * b.y ? b : a; }

vec2 index_closeness(LightPoint lp, int i, float inv2b2) {
    return occluder_closeness(lp, texelFetch(issmResolvedTex, i), inv2b2);
}

// Texel t of the patch, empty outside the map.
vec2 texel_closeness(LightPoint lp, ivec2 t, int size, float inv2b2) {
    bool inside = all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, ivec2(size)));
    vec4 o = texelFetch(issmResolvedTex, inside ? t.y * size + t.x : 0);
    return occluder_closeness(lp, inside ? o : ISSM_EMPTY, inv2b2);
}

float key_visibility(Surface s, uint pixel) {
    View L = g.light;
    LightPoint lp;
    lp.p = light_space(L, s.p);
    if (ISSM_SELF_TEST) {
        lp.own = light_space(L, s.sphere.xyz);
        // Distinct spheres are never this close (1e-3 of the radius); the
        // two computations of the own centre round alike, or nearly.
        lp.own_eps2 = 1e-6 * s.sphere.w * s.sphere.w;
    }
    vec2 uv = light_space_uv(L, lp.p) - 0.5; // texel centres at integers
    ivec2 c = ivec2(round(uv));
    int size = int(L.dims.x);
    int t = int(g.shadow_u.x), stride = int(max(g.shadow_u.y, 1u));
    float inv2b2 = 0.5 / (g.shadow_f0.z * g.shadow_f0.z);
    vec2 m = vec2(0.0, 1.0); // the largest closeness so far, as a fraction
    // Dense core: the spheres nearest the light around P. With ISSM_QUAD
    // the 2x2 texels whose centres surround P's light position, else the
    // 3x3 around P's own texel. The core is kept inside the map (size >=
    // 16), so it needs no bounds test per texel: at the border it reads the
    // edge's own texels instead of empty ones outside, and testing an extra
    // sphere never adds a wrong shadow (the hit test is exact). A row whose
    // vector of pixels is already fully shadowed ends the loop.
    const int n = ISSM_QUAD ? 2 : 3;
    ivec2 lo = ISSM_QUAD ? clamp(ivec2(floor(uv)), ivec2(0), ivec2(size - 2))
                         : clamp(c, ivec2(1), ivec2(size - 2)) - 1;
    int first = lo.y * size + lo.x;
    for (int dy = 0; dy < n && m.x < m.y; ++dy) {
        for (int dx = 0; dx < n; ++dx) {
            m = max_closeness(m, index_closeness(lp, first + dy * size + dx, inv2b2));
        }
    }
    // The rest of the (2t+1)^2 patch, every `stride` texels: the stride is at
    // most the smallest sphere radius in texels, so every sphere whose disk
    // is visible from the light lands on at least one sample.
    int lim = ISSM_CORE_ONLY ? 0 : (t / stride) * stride;
    for (int dy = -lim; !ISSM_CORE_ONLY && dy <= lim && m.x < m.y; dy += stride) {
        for (int dx = -lim; dx <= lim; dx += stride) {
            if (abs(dx) <= 1 && abs(dy) <= 1) continue;
            m = max_closeness(m, texel_closeness(lp, c + ivec2(dx, dy), size, inv2b2));
        }
    }
    if (!SOFT) return 1.0 - m.x;
    return m.x <= 0.0 ? 1.0 : 1.0 - pow(m.x / m.y, g.shadow_f0.y);
}
