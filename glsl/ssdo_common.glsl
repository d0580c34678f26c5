// Sampling and view helpers for SSDO (seed 001), shared with the test-only
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
// made on the CPU by src/passes/ssdo.rs) rotated about the normal by
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
#endif
