// Screen-space key-light shadows (after the semantic SSDO paper), the stand-in when no
// light-space technique runs (--shadows none with SSDO on): march the
// visibility buffer's depths from the visible point toward the key light in
// fixed steps; a step that passes behind a visible surface (within
// `thickness`) of another sphere is in shadow. Noisy by design (a per-pixel
// rotated start): computed at SSDO resolution and blurred with it.
// Parameters: shadow_f0.x = march length, shadow_f0.y = thickness (world
// units), shadow_u.x = steps.
#include "ssdo_common.glsl"

float key_visibility(Surface s, uint pixel) {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    vec3 x = s.p + s.n * 1e-3;
    vec3 l = -normalize(g.light_dir.xyz);
    float rot = hash12(uvec2(s.img));
    vec2 org = vec2(g.cam.dims.zw);
    float march = g.shadow_f0.x, thickness = g.shadow_f0.y;
    uint steps = g.shadow_u.x;
    for (uint j = 1u; j <= steps; ++j) {
        vec3 p = x + l * (march * (float(j) - 1.0 + rot) / float(steps));
        vec2 px = round(project_px(g.cam, p, PERSP)) - org;
        if (px.x < 0.0 || px.y < 0.0 || px.x >= float(w) || px.y >= float(h)) break;
        uint q = uint(px.y) * w + uint(px.x);
        uvec2 v = texelFetch(visTex, int(q)).xy;
        if (v.x == NO_SPHERE || v.x == s.id) continue;
        float dz = view_z(g.cam, p, PERSP) - key_view_z(g.cam, px + org, uintBitsToFloat(v.y), PERSP);
        if (dz > 0.0 && dz < thickness) return 0.0;
    }
    return 1.0;
}
