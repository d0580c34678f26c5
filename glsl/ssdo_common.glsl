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

// Per-sphere SSDO (ssdo_sphere.comp; spheres a few pixels wide on screen):
// its directions in camera coordinates (right, up, view direction):
// SSDO_SPHERE_AZIMUTHS azimuths x SPHERE_ELEVATIONS elevation bands of
// equal area over the directions a visible surface's hemisphere reaches
// (view-direction component from -1, toward the viewer, to
// SPHERE_DIR_ZMAX); direction k = azimuth k / E, band k % E. A sphere
// turns its azimuths by its own angle (sphere_rot / azimuths of a turn);
// shade.comp weights the directions by the pixel's normal.
const uint SPHERE_ELEVATIONS = SSDO_SPHERE_DIRS / SSDO_SPHERE_AZIMUTHS;
const float SPHERE_DIR_ZMAX = 0.25;
#define SPHERE_ZE(e) (-1.0 + (1.0 + SPHERE_DIR_ZMAX) * (float(e) + 0.5) / float(SPHERE_ELEVATIONS))
#define SPHERE_HE(e) sqrt(1.0 - SPHERE_ZE(e) * SPHERE_ZE(e))
#define SPHERE_DIR(k) vec3(SPHERE_HE(uint(k) % SPHERE_ELEVATIONS) * cos(6.2831853 * float(uint(k) / SPHERE_ELEVATIONS) / float(SSDO_SPHERE_AZIMUTHS)), \
                           SPHERE_HE(uint(k) % SPHERE_ELEVATIONS) * sin(6.2831853 * float(uint(k) / SPHERE_ELEVATIONS) / float(SSDO_SPHERE_AZIMUTHS)), SPHERE_ZE(uint(k) % SPHERE_ELEVATIONS))
const vec3 SPHERE_DIR_TABLE[32] = vec3[](
    SPHERE_DIR(0), SPHERE_DIR(1), SPHERE_DIR(2), SPHERE_DIR(3),
    SPHERE_DIR(4), SPHERE_DIR(5), SPHERE_DIR(6), SPHERE_DIR(7),
    SPHERE_DIR(8), SPHERE_DIR(9), SPHERE_DIR(10), SPHERE_DIR(11),
    SPHERE_DIR(12), SPHERE_DIR(13), SPHERE_DIR(14), SPHERE_DIR(15),
    SPHERE_DIR(16), SPHERE_DIR(17), SPHERE_DIR(18), SPHERE_DIR(19),
    SPHERE_DIR(20), SPHERE_DIR(21), SPHERE_DIR(22), SPHERE_DIR(23),
    SPHERE_DIR(24), SPHERE_DIR(25), SPHERE_DIR(26), SPHERE_DIR(27),
    SPHERE_DIR(28), SPHERE_DIR(29), SPHERE_DIR(30), SPHERE_DIR(31));
// (the table above is written for these counts)
const int SPHERE_DIR_TABLE_CHECK[SSDO_SPHERE_DIRS == 32u ? 1 : -1] = int[](0);

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
// cos, sin of the azimuth turn
vec2 sphere_turn(float rot) {
    float a = 6.2831853 * rot / float(SSDO_SPHERE_AZIMUTHS);
    return vec2(cos(a), sin(a));
}

// The per-sphere result (RGBA32UI per sphere): the far occluder weight of
// each direction in thirds, 2 bits each (directions 0-15 in x, 16-31 in
// y), and the incoming bounce RGB 4:4:4 in z (w unused).
uvec2 sphere_ao_bit(uint k, float w) {
    uint b = uint(clamp(w, 0.0, 1.0) * 3.0 + 0.5) << (2u * (k & 15u));
    return k < 16u ? uvec2(b, 0u) : uvec2(0u, b);
}
uint sphere_ao_bounce(vec3 bounce) {
    uvec3 b = uvec3(clamp(bounce, 0.0, 1.0) * 15.0 + 0.5);
    return b.r | (b.g << 4) | (b.b << 8);
}

// Near and far visibility at a surface of sphere id whose normal in camera
// coordinates is nc: the cosine-weighted share of the sphere's directions
// without occluders (far only: near is 1).
void sphere_ao_at(uvec4 t, uint id, vec3 nc, out vec2 v, out vec3 bounce) {
    vec2 cs = sphere_turn(sphere_rot(id));
    // the normal turned back instead of every direction turned
    vec3 nb = vec3(cs.x * nc.x + cs.y * nc.y, -cs.y * nc.x + cs.x * nc.y, nc.z);
    float ws = 0.0, wf = 0.0;
    for (uint k = 0u; k < SSDO_SPHERE_DIRS; ++k) {
        uint b = ((k < 16u ? t.x : t.y) >> (2u * (k & 15u))) & 3u;
        float w = max(dot(nb, SPHERE_DIR_TABLE[k]), 0.0);
        wf += w * float(b);
        ws += w;
    }
    v = vec2(1.0, 1.0 - wf / (3.0 * max(ws, 1e-6)));
    uint bb = t.z;
    bounce = vec3(float(bb & 15u), float((bb >> 4) & 15u), float((bb >> 8) & 15u)) / 15.0;
}
#endif
