#version 460
// variants: SHADOW_NONE SHADOW_ISSM SHADOW_DEEP SHADOW_SM SHADOW_OSM SHADOW_SCREEN SHADOW_BUFFER
// The one full-resolution pass over the frame after the rasterizer: the
// visible surface rebuilt from (pixel ray, sphere id), the key-light lookup
// of the active technique (compiled in per variant), the pixel's SSDO
// result (per pixel, or upsampled from the 2x2 blocks), and three-point
// lighting with a tone map into the colour buffer. The shadow and ao AOVs
// (unorm16 each) go to a second buffer when AOVS is set. Background pixels only write the background.
//
// Shadow rule of the ISSM paper: shadowed areas keep ambient and a fraction
// of the key's diffuse term, and lose its specular term.
#include "shared.glsl"

layout(local_size_x_id = 0) in;
#include "spec/shade.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer visTex;
layout(set = 0, binding = 4) uniform usamplerBuffer recordTex;  // per 2x2 block, ssdo_record.glsl
layout(set = 0, binding = 5) uniform usamplerBuffer aoTex;  // per pixel or 2x2 block, pack_ao
layout(set = 0, binding = 6) writeonly buffer Color { uint color[]; };
layout(set = 0, binding = 7) writeonly buffer Aov { uint aov[]; };
// Per listed sphere (AO_SPHERE): its entry from the flags ssdo_prep set and
// the list's per-word bases (ssdo_list.comp).
layout(set = 0, binding = 8) uniform usamplerBuffer sphereAoTex;
layout(set = 0, binding = 2) uniform usamplerBuffer flagTex;
layout(set = 0, binding = 3) uniform usamplerBuffer wordBaseTex;
#define SCENE_ATTRIBUTES
#include "scene.glsl"

#include "push/shade.glsl"

// The shadow AOV counts other spheres only (lookup_issm.glsl).
#define ISSM_SELF_TEST AOVS
#include "lookup.glsl"
#include "ssdo_common.glsl"
#include "ssdo_record.glsl"
#define TILE_LIST_ID SPEC_NEXT_ID
#define TILE_LIST_BINDING 9
#include "tiles.glsl"

// See-through spheres (SEE_THROUGH): per pixel the head and count of its
// fragments in front of the opaque surface (oit_splat.comp, oit_alloc.comp)
// and the fragments (depth key, sphere id).
layout(set = 0, binding = 11) uniform usamplerBuffer oitHeadTex;
// (the pool as RG32UI texels: a gather per scan step, where a storage load
// at per-lane addresses is a scalar loop on lavapipe)
layout(set = 0, binding = 12) uniform usamplerBuffer oitFragTex;
// (the fragment lists' counters: F_COMPOSITE_CUT)
layout(set = 0, binding = 13) buffer OitCounters { uint oit_counters[]; };

vec3 linear_to_srgb(vec3 c) { return pow(clamp(c, 0.0, 1.0), vec3(1.0 / 2.2)); }

// Filmic tone curve (Narkowicz's fit of ACES) on the luminance: a toe that
// keeps shadows dark and a shoulder that keeps highlights, mid-tones near
// linear. The colour is scaled by the curve's ratio, so a hue stays a hue;
// what would leave [0,1] moves toward its grey of the same luminance.
vec3 filmic(vec3 c) {
    float l = dot(c, vec3(0.2126, 0.7152, 0.0722));
    float x = 0.5 * l;
    float t = clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
    vec3 o = c * (t / max(l, 1e-6));
    float m = max(o.r, max(o.g, o.b));
    if (m > 1.0) o = mix(vec3(t), o, (1.0 - t) / max(m - t, 1e-6));
    return o;
}

void put_color(uint i, vec4 c) {
    if (WIDE) {
        uvec4 u = uvec4(clamp(c, 0.0, 1.0) * 65535.0 + 0.5);
        color[2u * i] = u.r | (u.g << 16);
        color[2u * i + 1u] = u.b | (u.a << 16);
    } else {
        color[i] = pack_rgba8(SWAP_RB ? c.bgra : c);
    }
}

// The background at a pixel, display-encoded (background.a: 0 gradient,
// 1 flat colour, 2 transparent).
vec4 background_at(uvec2 px) {
    uint mode = uint(g.background.a);
    if (mode == 2u) return vec4(0.0);
    if (mode == 1u) return vec4(g.background.rgb, 1.0);
    // Vertical gradient keeps silhouettes readable against the background.
    float t = (float(px.y) + float(g.cam.dims.w)) / g.cam.up.w;
    return vec4(mix(g.background.rgb * 1.25, g.background.rgb * 0.6, t), 1.0);
}

uint region_of(uint id) {
    return g.counts.w != 0u ? 0u : scene_region(id, pc.level);
}

// Silhouette lines (as ChimeraX's and Mol*'s): a pixel lies on a line when
// a pixel within outline_px (a cross and its diagonals) shows a surface
// nearer by more than edge_dz, or of another region at the chosen level
// and not farther; background pixels when one is covered. The line falls
// on the far side of the edge, so it is outline_px wide.
bool on_outline(uvec2 px, bool cov, float z, uint region) {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    int steps = int(pc.outline_px + 0.5);
    for (int k = 1; k <= steps; ++k) {
        int d = max(1, int(float(k) * 0.70710678 + 0.5));
        ivec2 offs[8] = ivec2[](ivec2(k, 0), ivec2(-k, 0), ivec2(0, k), ivec2(0, -k),
                                ivec2(d, d), ivec2(-d, d), ivec2(d, -d), ivec2(-d, -d));
        for (int o = 0; o < 8; ++o) {
            ivec2 q = ivec2(px) + offs[o];
            if (q.x < 0 || q.y < 0 || q.x >= int(w) || q.y >= int(h)) continue;
            uint j = uint(q.y) * w + uint(q.x);
            uvec2 v = texelFetch(visTex, int(j)).xy;
            if (v.x == NO_SPHERE) continue;
            if (!cov) return true;
            float zq = key_view_z(g.cam, vec2(q + ivec2(g.cam.dims.zw)), uintBitsToFloat(v.y), PERSP);
            if (z - zq > pc.edge_dz) return true;
            uint rq = region_of(v.x);
            if (g.counts.w == 0u && rq != region && (zq < z || (zq == z && rq < region))) return true;
        }
    }
    return false;
}

// The SSDO result at a pixel from the half-resolution blocks: the four
// nearest block centres, bilinear weights x the blur's depth, normal and
// region agreement with the pixel's exact surface. The pixel's own block is
// always among them (its record is covered: this pixel is), and a small
// floor on the agreement keeps the sum positive where no block shows this
// surface (a sphere too small to be any block's representative).
void ssdo_at(uvec2 px, float z, vec3 n, uint id, out vec2 v, out vec3 bounce, out float screen_vis) {
    uint hw = g.counts.y, hh = g.counts.z;
    bool regions = g.counts.w == 0u;
    uint reg = regions ? region_hash(scene_region(id, pc.level)) : 0u;
    vec2 f = (vec2(px) - 0.5) * 0.5;
    vec2 b0 = floor(f);
    vec2 fr = f - b0;
    v = vec2(0.0);
    bounce = vec3(0.0);
    screen_vis = 0.0;
    float wsum = 0.0;
    for (int k = 0; k < 4; ++k) {
        ivec2 o = ivec2(k & 1, k >> 1);
        ivec2 bk = clamp(ivec2(b0) + o, ivec2(0), ivec2(int(hw) - 1, int(hh) - 1));
        uint j = uint(bk.y) * hw + uint(bk.x);
        Record q = unpack_record(texelFetch(recordTex, int(j)));
        vec2 bw = mix(1.0 - fr, fr, vec2(o));
        float dz = (q.z - z) / pc.ao_sigma_z;
        float c = max(dot(n, q.n), 0.0);
        c *= c;
        c *= c;
        bool same = !regions || (pc.ao_level_b != 0u ? q.region_b : q.region_a) == reg;
        float agree = exp(-0.5 * dz * dz) * c * c * (same ? 1.0 : 0.0);
        float wk = q.covered ? bw.x * bw.y * (agree + 1e-3) : 0.0;
        vec2 vv;
        vec3 bb;
        float sv;
        unpack_ao(texelFetch(aoTex, int(j)).x, vv, bb, sv);
        v += wk * vv;
        bounce += wk * bb;
        screen_vis += wk * sv;
        wsum += wk;
    }
    float inv = 1.0 / max(wsum, 1e-12);
    v *= inv;
    bounce *= inv;
    screen_vis *= inv;
}

// Three-point lighting of a surface (unit normal n, toward the viewer v)
// with ambient visibility and bounce amb and key-light visibility
// vis_key, through the filmic curve (linear colour).
vec3 lit(vec3 albedo, vec3 n, vec3 v, vec4 amb, float vis_key) {
    vec3 l_key = -normalize(g.light_dir.xyz);
    // Fill: from the camera's side opposite the key, softer. Rim: from behind.
    vec3 l_fill = normalize(-l_key + 2.0 * v);
    vec3 l_rim = normalize(-v + 0.5 * g.cam.up.xyz);

    float nk = max(dot(n, l_key), 0.0);
    vec3 hk = normalize(l_key + v);
    // x^48 by squarings (x^3, then 4 squarings): pow is a log and an exp
    float s1 = max(dot(n, hk), 0.0), s3 = s1 * s1 * s1;
    s3 *= s3;
    s3 *= s3;
    s3 *= s3;
    float spec = s3 * s3 * step(0.0, dot(n, l_key));
    // The look (issue "Images people publish", measured against Tachyon in
    // tests/look.rs): the unlit term is a sky light weighted by the ambient
    // visibility, so occlusion reads as clearly as the key's shadows; the
    // key keeps only a small fraction of its diffuse in full shadow; fill
    // and rim are small and occluded too, so they do not wash creases out.
    float ao = amb.x;
    float key = nk * mix(pc.knobs.shadow_diffuse, 1.0, vis_key);
    float fill = 0.06 * max(dot(n, l_fill), 0.0);
    float rf = 1.0 - max(dot(n, v), 0.0);
    float rim = 0.08 * rf * rf * rf * max(dot(n, l_rim) + 0.3, 0.0);
    // Without SSDO there is no occlusion to carry: a flat ambient. With it
    // the sky light goes as the cube of the ambient visibility: SSDO sees
    // occluders within 12 radii only, so deep creases stay lighter than a
    // ray tracer's unbounded AO; the cube brings them down (against
    // Tachyon's 64-sample AO, tools/look-vs-tachyon.sh, 1TII / 3P3W:
    // luminance spread 0.68x / 0.69x -> 0.97x / 0.97x of Tachyon's, rank
    // correlation 0.953 / 0.936 -> 0.964 / 0.943, mean grey 164 / 160 ->
    // 148 / 142 against 150 / 139).
    float sky = AO ? 0.8 * ao * ao * ao : 0.4;
    // The bounce at half strength: at full strength the light bounced into
    // creases of white spheres made them brighter than the rims around
    // them (rank correlation with Tachyon 0.909 -> 0.935 on 3P3W).
    vec3 c = albedo * (key + fill * ao + sky) + 0.5 * albedo * albedo * amb.yzw
           + vec3(0.25 * spec * vis_key) + vec3(rim * ao);
    return filmic(c);
}

// Linear colour c at view distance z, depth-cued (FOG) and
// display-encoded, with its alpha (fog fades to a transparent background).
vec4 display(vec3 c, float z, uvec2 px) {
    float alpha = 1.0;
    if (FOG) {
        // depth cue toward the background (display-linear), or toward
        // transparency over a transparent one
        float f = clamp((z - pc.fog_near) / (pc.fog_far - pc.fog_near), 0.0, 1.0);
        vec4 bg = background_at(px);
        if (bg.a == 0.0) {
            alpha = 1.0 - f;
        } else {
            c = mix(c, pow(bg.rgb, vec3(2.2)), f);
        }
    }
    return vec4(linear_to_srgb(c), alpha);
}

// The pixel's see-through fragments composited front to back over `base`
// (display-encoded, straight alpha): each lit like an opaque surface with
// its key-light visibility and no ambient occlusion (SSDO sees the opaque
// surface), weighted by its alpha. The fragments are taken in (depth key,
// id) order by selection: each scan of the pixel's run keeps the least 8
// after the last taken; a transmittance below 1/1024 ends the walk (what
// lies behind could change the pixel by at most a quarter of an 8-bit
// step), so a pixel with n fragments costs about n x (layers that show / 8),
// not a full sort. Measured on the 1M capsid, half see-through, 1080p (19
// fragments per covered pixel on average, 184 at most): one fragment a scan
// 549 ms; an in-place insertion sort 869 ms; the least 8 in a register
// array 1175 ms (lavapipe puts a dynamically indexed array in memory);
// later, in one run: one a scan 275, the least 4 in named registers (a
// min/max network, no indexing) 211, 6 201, 8 202 ms.
vec4 composite(uvec2 px, uint i, vec4 base) {
    uvec2 hc = texelFetch(oitHeadTex, int(i)).xy;
    uint head = hc.x, n = hc.y;
    if (n == 0u || head == F_NONE) return base;
    vec3 o, vdir;
    view_ray(g.cam, vec2(px + g.cam.dims.zw), PERSP, o, vdir);
    vec3 v = -vdir;
    vec3 acc = vec3(0.0);
    float acc_a = 0.0, T = 1.0;
    // Fragments as 64-bit keys (depth bits above id: the (depth, id) order);
    // b0..b7 the least after `last`, sorted (taken from the front).
    uint64_t last = 0ul;
    uint taken = 0u;
    bool whole = false;
    while (taken < n && T >= 1.0 / 1024.0) {
        uint64_t b0 = VIS_EMPTY, b1 = VIS_EMPTY, b2 = VIS_EMPTY, b3 = VIS_EMPTY;
        uint64_t b4 = VIS_EMPTY, b5 = VIS_EMPTY, b6 = VIS_EMPTY, b7 = VIS_EMPTY;
        for (uint b = 0u; b < n; ++b) {
            uvec2 f = texelFetch(oitFragTex, int(head + b)).xy;
            uint64_t k = (uint64_t(f.x) << 32) | uint64_t(f.y);
            // (the first scan, taken == 0, takes from every fragment)
            k = (taken == 0u || k > last) ? k : VIS_EMPTY;
            uint64_t t0 = min(b0, k); k = max(b0, k); b0 = t0;
            uint64_t t1 = min(b1, k); k = max(b1, k); b1 = t1;
            uint64_t t2 = min(b2, k); k = max(b2, k); b2 = t2;
            uint64_t t3 = min(b3, k); k = max(b3, k); b3 = t3;
            uint64_t t4 = min(b4, k); k = max(b4, k); b4 = t4;
            uint64_t t5 = min(b5, k); k = max(b5, k); b5 = t5;
            uint64_t t6 = min(b6, k); k = max(b6, k); b6 = t6;
            b7 = min(b7, k);
        }
        for (uint j = 0u; j < 8u && b0 != VIS_EMPTY && T >= 1.0 / 1024.0; ++j) {
            last = b0;
            b0 = b1;
            b1 = b2;
            b2 = b3;
            b3 = b4;
            b4 = b5;
            b5 = b6;
            b6 = b7;
            b7 = VIS_EMPTY;
            ++taken;
            uint id = uint(last & 0xFFFFFFFFul);
            Surface fs = surface_for(px, id);
#if defined(SHADOW_SCREEN)
            float vis_key = 1.0;
#else
            float vis_key = USE_SHADOW ? key_visibility(fs, i) : 1.0;
#endif
            vec3 c = lit(albedo_of(id), fs.n, v, vec4(1.0, 0.0, 0.0, 0.0), vis_key);
            vec4 d = display(c, view_z(g.cam, fs.p, PERSP), px);
            float w = T * scene_alpha(id) * d.a;
            acc += w * d.rgb;
            acc_a += w;
            T -= w;
        }
        // The walk's own end, as a flag: lavapipe ends an invocation's
        // loops after 65,535 back-edges (thousands of faint fragments in a
        // pixel), and a test after the loop would be folded away.
        whole = taken >= n || T < 1.0 / 1024.0;
    }
    if (!whole) atomicAdd(oit_counters[F_COMPOSITE_CUT], 1u);
    float out_a = acc_a + T * base.a;
    vec3 rgb = acc + T * base.a * base.rgb;
    return vec4(out_a > 0.0 ? rgb / out_a : vec3(0.0), out_a);
}

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uvec2 px;
    if (!tile_pixel(w, h, false, px) || !IN_ACTIVE(px)) return;
    uint i = px.y * w + px.x;
    Surface s;
    if (TILE_LIST == 2u || !surface_of(px, s)) {
        vec4 bg = background_at(px);
        if (OUTLINE && on_outline(px, false, 0.0, 0u)) bg = vec4(0.0, 0.0, 0.0, 1.0);
        if (SEE_THROUGH && TILE_LIST != 2u) bg = composite(px, i, bg);
        put_color(i, bg);
        if (AOVS) aov[i] = 0xFFFFFFFFu;
        return;
    }
    vec3 albedo = surface_albedo(s);
    vec3 n = s.n;
    vec3 o, vdir;
    view_ray(g.cam, vec2(px + g.cam.dims.zw), PERSP, o, vdir);
    vec3 v = -vdir;

    vec4 amb = vec4(1.0, 0.0, 0.0, 0.0);
    float screen_vis = 1.0;
    float z = view_z(g.cam, s.p, PERSP);
    if (AO) {
        vec2 v;
        vec3 bounce;
        if (AO_SPHERE) {
            // (perspective: the frame about this pixel's ray, nearly the
            // sphere's that ssdo_sphere.comp used)
            mat3 b = !PERSP ? mat3(g.cam.right.xyz, g.cam.up.xyz, g.cam.dir.xyz)
                                        : sphere_basis(vdir, g.cam.up.xyz);
            vec3 nc = n * b;
            uint w = s.id >> 5u;
            uint below = texelFetch(flagTex, int(w)).x & ((1u << (s.id & 31u)) - 1u);
            uint entry = texelFetch(wordBaseTex, int(w)).x + uint(bitCount(below));
            sphere_ao_at(texelFetch(sphereAoTex, int(entry)), nc, v, bounce);
#if defined(SHADOW_SCREEN)
            uvec2 blk = px / SSDO_BLOCK;
            screen_vis = unpack_record(texelFetch(recordTex, int(blk.y * g.counts.y + blk.x))).visibility;
#endif
        } else if (AO_HALF) {
            ssdo_at(px, z, n, s.id, v, bounce, screen_vis);
        } else {
            unpack_ao(texelFetch(aoTex, int(i)).x, v, bounce, screen_vis);
        }
        amb = vec4(v.x * v.y, bounce);
    }
#if defined(SHADOW_SCREEN)
    float vis_key = screen_vis;
#else
    float vis_key = USE_SHADOW ? key_visibility(s, i) : 1.0;
#endif
    vec4 c = display(lit(albedo, n, v, amb, vis_key), z, px);
    if (OUTLINE && on_outline(px, true, z, region_of(s.id))) c = vec4(0.0, 0.0, 0.0, 1.0);
    if (SEE_THROUGH) c = composite(px, i, c);
    put_color(i, c);
    if (AOVS) aov[i] = uint(clamp(vis_key, 0.0, 1.0) * 65535.0 + 0.5) | (uint(clamp(amb.x, 0.0, 1.0) * 65535.0 + 0.5) << 16);
}
