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

// Pixel coordinates (continuous, pixel centres at integers) of a world point.
vec2 project_px(View v, vec3 p) {
    float ppu = v.center.w, w = v.right.w, h = v.up.w;
    vec2 xy;
    if (v.dir.w == 0.0) {
        vec3 q = p - v.center.xyz;
        xy = vec2(dot(q, v.right.xyz), dot(q, v.up.xyz));
    } else {
        vec3 q = p - (v.center.xyz - v.dir.w * v.dir.xyz);
        float z = max(dot(q, v.dir.xyz), 1e-6);
        xy = vec2(dot(q, v.right.xyz), dot(q, v.up.xyz)) * (v.dir.w / z);
    }
    return vec2(xy.x * ppu + 0.5 * w - 0.5, 0.5 * h - xy.y * ppu - 0.5);
}

// Distance along the view direction (larger = farther from the viewer).
float view_z(View v, vec3 p) {
    vec3 o = v.dir.w == 0.0 ? v.center.xyz : v.center.xyz - v.dir.w * v.dir.xyz;
    return dot(p - o, v.dir.xyz);
}

float hash12(uvec2 p) {
    uint h = p.x * 1664525u + p.y * 1013904223u;
    h ^= h >> 16; h *= 0x7feb352du; h ^= h >> 15; h *= 0x846ca68bu; h ^= h >> 16;
    return float(h) / 4294967296.0;
}
#endif
