#version 460
// Microbenchmarks of the lavapipe facts docs/LAVAPIPE.md relies on (run by
// `cargo bench --bench lavapipe`). MODE (specialization constant 1) picks
// one access pattern or control-flow shape; every mode writes one vec4 per
// invocation so nothing is optimized away.
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
layout(local_size_x = 64) in;
layout(constant_id = 1) const uint MODE = 0;
layout(constant_id = 2) const uint FLAG = 0;

layout(set = 0, binding = 0) readonly buffer Src { vec4 src[]; };
layout(set = 0, binding = 1) writeonly buffer Dst { vec4 dst[]; };
layout(set = 0, binding = 2) uniform samplerBuffer srcTex;
layout(set = 0, binding = 3) uniform GlobalsBlock { vec4 table[64]; };
layout(set = 0, binding = 4) uniform usamplerBuffer srcWordTex; // Src as R32UI
layout(set = 0, binding = 5, rgba32f) uniform writeonly imageBuffer dstImg;  // Dst as a storage texel buffer
layout(set = 0, binding = 6, r32ui) uniform writeonly uimageBuffer dstWordImg; // the same as R32UI
layout(set = 0, binding = 7) writeonly buffer DstWords { uint dst_words[]; }; // Dst as 32-bit words

layout(push_constant) uniform Push {
    uint n;     // invocations (and source elements)
    uint taps;  // loads / iterations per invocation
    uint flag;  // runtime branch condition
    uint pad;
} pc;

shared vec4 tile[64];

// A per-lane address: neighbouring lanes read far-apart elements.
const uint MASK = (1u << 21) - 1u; // source elements: 2^21 >= 1920 x 1080
uint addr(uint i, uint k) { return (i * 2654435761u + k * 40503u) & MASK; }

// 16 dependent sin steps without a loop (lavapipe checks a loop's mask
// every iteration, so a loop under a branch says nothing about the branch).
#define SIN4(x) x = sin(x * 1.0001 + 0.3); x = sin(x * 1.0001 + 0.3); x = sin(x * 1.0001 + 0.3); x = sin(x * 1.0001 + 0.3);
#define SIN16(x) SIN4(x) SIN4(x) SIN4(x) SIN4(x)

vec4 heavy(vec4 x, uint iters) {
    for (uint j = 0u; j < iters; ++j) x = sin(x * 1.0001 + 0.3);
    return x;
}

void main() {
    uint i = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * 64u;
    if (i >= pc.n) return;
    vec4 acc = vec4(float(i));
    uint wg = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y;
    if (MODE == 19) return; // the dispatch alone: every invocation returns at once
    if (MODE == 0) {        // storage vec4 load, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) acc += src[addr(i, k)];
    } else if (MODE == 1) { // storage float load, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) acc.x += src[addr(i, k)].x;
    } else if (MODE == 2) { // storage vec4 load, same address in all lanes
        for (uint k = 0u; k < pc.taps; ++k) acc += src[(wg + k) & MASK];
    } else if (MODE == 3) { // uniform texel buffer fetch, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) acc += texelFetch(srcTex, int(addr(i, k)));
    } else if (MODE == 4) { // workgroup shared memory, per-lane address
        tile[gl_LocalInvocationID.x] = src[i];
        barrier();
        for (uint k = 0u; k < pc.taps; ++k) acc += tile[(gl_LocalInvocationID.x * 37u + k * 11u) & 63u];
    } else if (MODE == 5) { // uniform buffer, per-lane index
        for (uint k = 0u; k < pc.taps; ++k) acc += table[(i + k * 7u) & 63u];
    } else if (MODE == 6) { // if/else on a push constant (taken the same way by all lanes)
        if (pc.flag != 0u) acc = heavy(acc, pc.taps); else acc = heavy(acc.yzwx, pc.taps);
    } else if (MODE == 7) { // the same if/else on a specialization constant
        if (FLAG != 0u) acc = heavy(acc, pc.taps); else acc = heavy(acc.yzwx, pc.taps);
    } else if (MODE == 8) { // one lane in 8 loops 8x as long, the others not at all
        acc = heavy(acc, (i & 7u) == 0u ? 8u * pc.taps : 0u);
    } else if (MODE == 9) { // every lane loops the same (same total work as 8)
        acc = heavy(acc, pc.taps);
    } else if (MODE == 10) { // all the work in the first half of the workgroups
        acc = heavy(acc, wg < groups / 2u ? 2u * pc.taps : 0u);
    } else if (MODE == 11) { // the same work in every other workgroup
        acc = heavy(acc, (wg & 1u) == 0u ? 2u * pc.taps : 0u);
    } else if (MODE == 14) { // storage vec4 load, neighbouring lanes read neighbouring elements
        for (uint k = 0u; k < pc.taps; ++k) acc += src[(i + k * 1920u) & MASK];
    } else if (MODE == 15) { // uniform texel buffer fetch, neighbouring addresses
        for (uint k = 0u; k < pc.taps; ++k) acc += texelFetch(srcTex, int((i + k * 1920u) & MASK));
    } else if (MODE == 16) { // storage uint load, neighbouring addresses
        for (uint k = 0u; k < pc.taps; ++k) acc.x += uintBitsToFloat(floatBitsToUint(src[(i + k * 1920u) & MASK].x) & 0x3fffffffu);
    } else if (MODE == 17) { // if/else on a per-lane condition (lanes split both ways)
        if ((i & 1u) != 0u) acc = heavy(acc, pc.taps); else acc = heavy(acc.yzwx, pc.taps);
    } else if (MODE == 18) { // the address arithmetic alone (no loads)
        for (uint k = 0u; k < pc.taps; ++k) acc += vec4(float(addr(i, k)));
    } else if (MODE == 20) { // uniform texel buffer fetch (r32ui), per-lane address
        for (uint k = 0u; k < pc.taps; ++k) acc.x += float(texelFetch(srcWordTex, int(addr(i, k))).x);
    } else if (MODE == 21) { // integer division and remainder by a push constant
        for (uint k = 0u; k < pc.taps; ++k) { uint a = addr(i, k); acc.xy += vec2(float(a / (pc.n >> 10)), float(a % (pc.n >> 10))); }
    } else if (MODE == 22) { // the same split through a float reciprocal
        float inv = 1.0 / float(pc.n >> 10);
        for (uint k = 0u; k < pc.taps; ++k) { uint a = addr(i, k); uint q = uint((float(a) + 0.5) * inv); acc.xy += vec2(float(q), float(a - q * (pc.n >> 10))); }
    } else if (MODE == 23) { // straight-line code (no loop) under a push-constant if that no lane takes
        if (pc.flag == 0u) { SIN16(acc) }
    } else if (MODE == 24) { // the same straight-line code, taken by every lane
        if (pc.flag != 0u) { SIN16(acc) }
    } else if (MODE == 25) { // the same under a specialization-constant if that no lane takes
        if (FLAG == 0u) { SIN16(acc) }
    } else if (MODE == 26) { // the same as a one-trip loop that no lane enters
        for (bool once = pc.flag == 0u; once; once = false) { SIN16(acc) }
    } else if (MODE == 27) { // the one-trip loop, entered by 1 lane in 8
        for (bool once = (i & 7u) == 0u; once; once = false) { SIN16(acc) }
    } else if (MODE == 28) { // storage buffer vec4 store, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) dst[addr(i, k)] = acc + float(k);
    } else if (MODE == 29) { // storage texel buffer (rgba32f) store, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) imageStore(dstImg, int(addr(i, k)), acc + float(k));
    } else if (MODE == 30) { // storage buffer uint store, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) dst_words[addr(i, k)] = i + k;
    } else if (MODE == 31) { // storage texel buffer (r32ui) store, per-lane address
        for (uint k = 0u; k < pc.taps; ++k) imageStore(dstWordImg, int(addr(i, k)), uvec4(i + k));
    } else if (MODE == 32) { // storage buffer vec4 store, neighbouring addresses
        for (uint k = 0u; k < pc.taps; ++k) dst[(i + k * 1920u) & MASK] = acc + float(k);
    } else if (MODE == 33) { // storage texel buffer (rgba32f) store, neighbouring addresses
        for (uint k = 0u; k < pc.taps; ++k) imageStore(dstImg, int((i + k * 1920u) & MASK), acc + float(k));
    } else if (MODE == 12) { // fp16 arithmetic
        f16vec4 h = f16vec4(acc * 1e-6);
        for (uint k = 0u; k < pc.taps * 8u; ++k) h = h * float16_t(0.999) + float16_t(0.001);
        acc = vec4(h);
    } else if (MODE == 13) { // the same in fp32
        vec4 h = acc * 1e-6;
        for (uint k = 0u; k < pc.taps * 8u; ++k) h = h * 0.999 + 0.001;
        acc = h;
    }
    dst[i] = acc;
}
