#version 460
// Final shading: three-point lighting (key with shadows, fill, rim), ambient
// scaled by ambient visibility plus the indirect bounce, written as RGBA8.
// Shadow rule of the ISSM paper: shadowed areas keep ambient and a fraction of
// the key's diffuse term, and lose its specular term.
#include "shared.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Attrs { SphereAttr attrs[]; };
layout(set = 0, binding = 2) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) readonly buffer GPos { vec4 gpos[]; };
layout(set = 0, binding = 4) readonly buffer GNorm { vec4 gnorm[]; };
layout(set = 0, binding = 5) readonly buffer Shadow { float shadow[]; }; // key-light visibility
layout(set = 0, binding = 6) readonly buffer Ambient { vec4 ambient[]; }; // x visibility, yzw bounce rgb
layout(set = 0, binding = 7) writeonly buffer Color { uint color[]; };

layout(push_constant) uniform Push {
    uint use_shadow;
    uint use_ambient;
    float shadow_diffuse; // fraction of key diffuse kept in full shadow
    uint swap_rb;         // 1 = write BGRA (swapchains that want it)
} pc;

vec3 srgb_to_linear(vec3 c) { return pow(c, vec3(2.2)); }
vec3 linear_to_srgb(vec3 c) { return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)); }

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    vec4 n4 = gnorm[i];
    if (n4.w == 0.0) {
        // Vertical gradient keeps silhouettes readable against the background.
        float t = float(i / w) / float(h);
        vec3 bg = mix(g.background.rgb * 1.25, g.background.rgb * 0.6, t);
        color[i] = pack_rgba8(vec4(pc.swap_rb != 0u ? bg.bgr : bg, 1.0));
        return;
    }
    uint id = uint(vis[i] & 0xFFFFFFFFul);
    vec3 albedo = srgb_to_linear(unpack_rgba8(attrs[id].color).rgb);
    vec3 n = n4.xyz;
    vec3 o, vdir;
    view_ray(g.cam, vec2(i % w, i / w), o, vdir);
    vec3 v = -vdir;

    vec3 l_key = -normalize(g.light_dir.xyz);
    // Fill: from the camera's side opposite the key, softer. Rim: from behind.
    vec3 l_fill = normalize(-l_key + 2.0 * v);
    vec3 l_rim = normalize(-v + 0.5 * g.cam.up.xyz);

    float vis_key = pc.use_shadow != 0 ? shadow[i] : 1.0;
    vec4 amb = pc.use_ambient != 0 ? ambient[i] : vec4(1.0, 0.0, 0.0, 0.0);

    float nk = max(dot(n, l_key), 0.0);
    vec3 hk = normalize(l_key + v);
    float spec = pow(max(dot(n, hk), 0.0), 48.0) * step(0.0, dot(n, l_key));
    // Weights chosen so a fully shadowed surface keeps about a third of its
    // lit brightness after gamma: shadows read clearly without going black.
    float key_diffuse = nk * mix(pc.shadow_diffuse, 1.0, vis_key);
    float fill = 0.14 * max(dot(n, l_fill), 0.0);
    float rim = 0.22 * pow(1.0 - max(dot(n, v), 0.0), 3.0) * max(dot(n, l_rim) + 0.3, 0.0);
    // Ambient carries the occlusion: it must weigh enough for AO to read.
    float ambient_term = (pc.use_ambient != 0 ? 0.5 : 0.16) * amb.x;
    float key_weight = pc.use_ambient != 0 ? 0.85 : 1.1;

    vec3 c = albedo * (key_weight * key_diffuse + fill + ambient_term) + albedo * amb.yzw
           + vec3(0.3 * spec * vis_key) + vec3(rim);
    // Exponential tone map: saturated CPK colours would otherwise clip in
    // the light and lose the shading that shows shape.
    c = vec3(1.0) - exp(-1.5 * c);
    vec3 outc = linear_to_srgb(c);
    color[i] = pack_rgba8(vec4(pc.swap_rb != 0u ? outc.bgr : outc, 1.0));
}
