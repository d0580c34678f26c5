// Sampling and view helpers for SSDO (after the semantic SSDO paper), shared with the test-only
// sample probe so tests check the very code the pass runs.
#ifndef SSDO_COMMON_GLSL
#define SSDO_COMMON_GLSL
#include "shared.glsl"

// Radical inverse in base b: the Halton sequence.
float halton(uint i, uint b) {
    float f = 1.0, r = 0.0;
    while (i > 0u) {
        f /= float(b);
        r += f * float(i % b);
        i /= b;
    }
    return r;
}

// Malley's method: a uniform point on the unit disk (concentric mapping)
// lifted to the hemisphere gives a cosine-weighted direction (z up).
vec3 malley(vec2 u) {
    vec2 o = 2.0 * u - 1.0;
    vec2 d = vec2(0.0);
    if (o.x != 0.0 || o.y != 0.0) {
        const float PI_4 = 0.78539816;
        float r, th;
        if (abs(o.x) > abs(o.y)) { r = o.x; th = PI_4 * (o.y / o.x); }
        else { r = o.y; th = 2.0 * PI_4 - PI_4 * (o.x / o.y); }
        d = r * vec2(cos(th), sin(th));
    }
    return vec3(d, sqrt(max(0.0, 1.0 - dot(d, d))));
}

// Orthonormal basis around n (Frisvad / Duff et al.).
mat3 tangent_frame(vec3 n) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float b = n.x * n.y * a;
    vec3 t = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    vec3 bt = vec3(b, s + n.y * n.y * a, -n.y);
    return mat3(t, bt, n);
}

// Sample direction i of n around normal n, rotated per pixel by `rot` (0..1)
// so neighbouring pixels use different directions (the blur removes the noise).
vec3 hemisphere_sample(uint i, vec3 n, float rot) {
    vec2 u = vec2(halton(i + 1u, 2u), halton(i + 1u, 3u));
    u.y = fract(u.y + rot);
    return tangent_frame(n) * malley(u);
}

// A direction of the sample table (tangent space xyz: Halton + Malley,
// made on the CPU by src/stages/ssdo/record.rs) rotated about the normal by
// rot (0..1 of a turn) into the frame of the normal.
// rotated_frame() folds the rotation into the frame once per pixel.
mat3 rotated_frame(mat3 frame, float rot) {
    float ca = cos(6.2831853 * rot), sa = sin(6.2831853 * rot);
    return frame * mat3(ca, sa, 0.0, -sa, ca, 0.0, 0.0, 0.0, 1.0);
}
vec3 table_sample(vec4 t, mat3 frame, float rot) {
    return rotated_frame(frame, rot) * t.xyz;
}

// The per-pixel SSDO result in 32 bits: the near and far visibilities
// (8 bits each; multiplied only after the blur, since a product of few-
// sample fractions is biased), the incoming bounce as RGB 4:4:4 (clamped
// to 1), and the screen-space key-light visibility (4 bits; --shadows none).
uint pack_ao(vec2 v, vec3 bounce, float screen_vis) {
    uvec2 vv = uvec2(clamp(v, 0.0, 1.0) * 255.0 + 0.5);
    uvec3 b = uvec3(clamp(bounce, 0.0, 1.0) * 15.0 + 0.5);
    return vv.x | (vv.y << 8) | (b.r << 16) | (b.g << 20) | (b.b << 24)
         | (uint(clamp(screen_vis, 0.0, 1.0) * 15.0 + 0.5) << 28);
}
void unpack_ao(uint u, out vec2 v, out vec3 bounce, out float screen_vis) {
    v = vec2(float(u & 0xFFu), float((u >> 8) & 0xFFu)) / 255.0;
    bounce = vec3(float((u >> 16) & 15u), float((u >> 20) & 15u), float((u >> 24) & 15u)) / 15.0;
    screen_vis = float(u >> 28) / 15.0;
}

// The per-pixel blur's edge key in one word: the view distance's float
// with its low 12 mantissa bits replaced by a 12-bit hash of the region at
// the blur's level (relative depth error under 2^-11). A tap then reads 4
// bytes instead of the visibility key, the sphere and its attributes.
const uint BLUR_KEY_BACKGROUND = 0xFFFFFFFFu;  // (a NaN: no real distance)
uint blur_key(float z, uint region) { return (floatBitsToUint(z) & 0xFFFFF000u) | (region & 0xFFFu); }
float blur_key_z(uint k) { return uintBitsToFloat(k & 0xFFFFF000u); }
uint blur_key_region(uint k) { return k & 0xFFFu; }

float hash12(uvec2 p) {
    uint h = p.x * 1664525u + p.y * 1013904223u;
    h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15; h *= 0x846ca68bu; h ^= h >> 16;
    return float(h) / 4294967296.0;
}

// Per-sphere SSDO (ssdo_sphere.comp; spheres a few pixels wide on screen):
// its directions in camera coordinates (right, up, view direction):
// SSDO_SPHERE_AZIMUTHS azimuths x SPHERE_ELEVATIONS elevation bands of
// equal area over the directions a visible surface's hemisphere reaches
// (view-direction component from -1, toward the viewer, to
// SPHERE_DIR_ZMAX). A sphere turns its azimuths by its own angle
// (sphere_rot / azimuths of a turn); shade.comp weights the directions by
// the pixel's normal.
const uint SPHERE_ELEVATIONS = SSDO_SPHERE_DIRS / SSDO_SPHERE_AZIMUTHS;
const float SPHERE_DIR_ZMAX = 0.25;
#define SPHERE_ZE(e) (-1.0 + (1.0 + SPHERE_DIR_ZMAX) * (float(e) + 0.5) / float(SPHERE_ELEVATIONS))
#define SPHERE_HE(e) sqrt(1.0 - SPHERE_ZE(e) * SPHERE_ZE(e))
// The camera-like frame (right, up, z) about a view ray z (perspective: the
// ray toward the sphere, so its directions sit alike on every sphere).
mat3 sphere_basis(vec3 z, vec3 up) {
    vec3 x = normalize(cross(z, up));
    return mat3(x, cross(x, z), z);
}

// The sphere's turn of its azimuths (0..1 of the azimuth step) and the
// offset of its taps along them (0..1 of a step).
float sphere_rot(uint id) { return hash12(uvec2(id, 0x9E37u)); }
float sphere_jitter(uint id) { return hash12(uvec2(id, 0x51EDu)); }

// The per-sphere result (RGBA32UI per sphere): the directions' occluder
// weights as the real spherical harmonics to band 2 of their cosine-lobe
// sum E(n) = sum_k w_k max(n.d_k, 0) (Ramamoorthi and Hanrahan's
// irradiance environment maps: the clamped cosine has almost nothing above
// band 2), 9 coefficients in fixed point in x, y, w (11/11/10 bits) and
// the incoming bounce RGB 4:4:4 in z. shade then evaluates 9 terms per
// pixel where it summed 32 directions (that sum with its hash, cos and sin
// was ~7 ms of the 1M capsid's shade on lavapipe); the coefficients are in
// the sphere's camera-like frame, the azimuth turn already applied.
struct SH9 {
    vec4 a;  // Y00, Y1-1, Y10, Y11
    vec4 b;  // Y2-2, Y2-1, Y20, Y21
    float c; // Y22
};
SH9 sh9_basis(vec3 d) {
    SH9 s;
    s.a = vec4(0.282095, 0.488603 * d.y, 0.488603 * d.z, 0.488603 * d.x);
    s.b = vec4(1.092548 * d.x * d.y, 1.092548 * d.y * d.z, 0.315392 * (3.0 * d.z * d.z - 1.0), 1.092548 * d.x * d.z);
    s.c = 0.546274 * (d.x * d.x - d.y * d.y);
    return s;
}
float sh9_dot(SH9 x, SH9 y) { return dot(x.a, y.a) + dot(x.b, y.b) + x.c * y.c; }

// The clamped cosine's band factors (pi, 2 pi / 3, pi / 4) divided by the
// band-0 term of all directions at weight 1 (pi * 0.282095 * K), so the
// band-0 coefficient is the mean weight (0..1), band 1 within +-1.16,
// band 2 within +-0.56.
const float SH_NORM = 3.14159265 * 0.282095 * float(SSDO_SPHERE_DIRS);
const vec3 SH_BAND = vec3(3.14159265, 2.0943951, 0.78539816) / SH_NORM;
// The same sum with every weight 1: over 8 equally spaced azimuths only the
// m = 0 terms survive to band 2, so it depends on n.z alone.
#define SH_Z1(e) (0.488603 * SPHERE_ZE(e))
#define SH_Z2(e) (0.315392 * (3.0 * SPHERE_ZE(e) * SPHERE_ZE(e) - 1.0))
const vec3 SH_ONES = vec3(1.0,
    SH_BAND.y * float(SSDO_SPHERE_AZIMUTHS) * (SH_Z1(0u) + SH_Z1(1u) + SH_Z1(2u) + SH_Z1(3u)),
    SH_BAND.z * float(SSDO_SPHERE_AZIMUTHS) * (SH_Z2(0u) + SH_Z2(1u) + SH_Z2(2u) + SH_Z2(3u)));
// (written for 4 elevations)
const int SH_ONES_CHECK[SPHERE_ELEVATIONS == 4u ? 1 : -1] = int[](0);

uint sh_q(float x, float range, uint bits) {
    float m = float((1u << bits) - 1u);
    return uint(clamp(x / range * 0.5 + 0.5, 0.0, 1.0) * m + 0.5);
}
float sh_dq(uint q, float range, uint bits) {
    float m = float((1u << bits) - 1u);
    return (float(q & ((1u << bits) - 1u)) / m * 2.0 - 1.0) * range;
}
const float SH_R0 = 1.0, SH_R1 = 1.25, SH_R2 = 0.6;

// acc: sum_k w_k Y(d_k) over the sphere's directions.
uvec4 sphere_ao_pack(SH9 acc, vec3 bounce) {
    vec4 a = acc.a * vec4(SH_BAND.x, SH_BAND.yyy);
    vec4 b = acc.b * SH_BAND.z;
    float c = acc.c * SH_BAND.z;
    uvec3 bq = uvec3(clamp(bounce, 0.0, 1.0) * 15.0 + 0.5);
    return uvec4(sh_q(a.x, SH_R0, 11u) | (sh_q(a.y, SH_R1, 11u) << 11) | (sh_q(b.x, SH_R2, 10u) << 22),
                 sh_q(a.z, SH_R1, 11u) | (sh_q(a.w, SH_R1, 11u) << 11) | (sh_q(b.y, SH_R2, 10u) << 22),
                 bq.r | (bq.g << 4) | (bq.b << 8),
                 sh_q(b.z, SH_R2, 10u) | (sh_q(b.w, SH_R2, 10u) << 10) | (sh_q(c, SH_R2, 10u) << 20));
}

// Near and far visibility at a surface of a sphere whose normal in the
// sphere's camera-like frame is nc: the cosine-weighted share of its
// directions without occluders (far only: near is 1).
void sphere_ao_at(uvec4 t, vec3 nc, out vec2 v, out vec3 bounce) {
    SH9 c;
    c.a = vec4(sh_dq(t.x, SH_R0, 11u), sh_dq(t.x >> 11, SH_R1, 11u), sh_dq(t.y, SH_R1, 11u), sh_dq(t.y >> 11, SH_R1, 11u));
    c.b = vec4(sh_dq(t.x >> 22, SH_R2, 10u), sh_dq(t.y >> 22, SH_R2, 10u), sh_dq(t.w, SH_R2, 10u), sh_dq(t.w >> 10, SH_R2, 10u));
    c.c = sh_dq(t.w >> 20, SH_R2, 10u);
    SH9 y = sh9_basis(nc);
    float occluded = sh9_dot(c, y);
    float total = SH_ONES.x * y.a.x + SH_ONES.y * y.a.z + SH_ONES.z * y.b.z;
    v = vec2(1.0, 1.0 - clamp(occluded / max(total, 1e-6), 0.0, 1.0));
    uint bb = t.z;
    bounce = vec3(float(bb & 15u), float((bb >> 4) & 15u), float((bb >> 8) & 15u)) / 15.0;
}
#endif
