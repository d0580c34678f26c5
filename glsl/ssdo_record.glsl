// The half-resolution SSDO record (one RGBA32UI texel per 2x2 block), what
// the SSDO taps and the blur read of a neighbour in one fetch:
//   x  view distance of the block's representative pixel (float bits;
//      +inf = background)
//   y  its normal, octahedral snorm16x2
//   z  region ids at the two active hierarchy levels, 15-bit hashes, and the
//      representative's position in the block (2 bits)
//   w  direct key-light radiance albedo * max(N.L, 0) * visibility (RGB8,
//      linear) and the key-light visibility (A8; with ISSM exact where
//      N.L > 0 only: the records' lookup skips the own-sphere test, which
//      matters only where the radiance's max(N.L, 0) is 0)
// ssdo_prep.comp writes it; src/stages/ssdo/record.rs unpacks it on the CPU (tests).
#ifndef SSDO_RECORD_GLSL
#define SSDO_RECORD_GLSL

const float RECORD_BACKGROUND = 1.0 / 0.0;

struct Record {
    float z;
    vec3 n;
    uint region_a, region_b;
    uvec2 sub;   // representative pixel within its 2x2 block
    vec3 radiance;
    float visibility;
    bool covered;
};

uint region_hash(uint r) { return (r * 2654435761u) >> 17; }

uvec4 pack_record(Record r) {
    return uvec4(floatBitsToUint(r.z), pack_normal(r.n),
                 (r.region_a & 0x7FFFu) | ((r.region_b & 0x7FFFu) << 15) | ((r.sub.x | (r.sub.y << 1)) << 30),
                 pack_rgba8(vec4(r.radiance, r.visibility)));
}

Record unpack_record(uvec4 t) {
    Record r;
    r.z = uintBitsToFloat(t.x);
    r.covered = !isinf(r.z);
    r.n = unpack_normal(t.y);
    r.region_a = t.z & 0x7FFFu;
    r.region_b = (t.z >> 15) & 0x7FFFu;
    r.sub = uvec2((t.z >> 30) & 1u, t.z >> 31);
    vec4 c = unpack_rgba8(t.w);
    r.radiance = c.rgb;
    r.visibility = c.a;
    return r;
}

// Full-resolution pixel of a half-resolution block's representative.
vec2 record_pixel(uvec2 block, Record r) { return vec2(SSDO_BLOCK * block + r.sub); }
#endif
