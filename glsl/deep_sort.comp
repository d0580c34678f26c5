#version 460
// Deep shadow lists, pass 4 (sort): one workgroup per 8x8 tile, one
// invocation per texel. A texel's entries are contiguous (deep_alloc), so
// its invocation sorts the run in place by (depth, sphere id) - ids break
// ties so the order is unique and frames are reproducible: runs of up to 256
// entries as 64-bit keys (depth made order-preserving as an unsigned int,
// then id) in private memory, longer ones directly in the buffers, both with
// Shell sort (fill order is arbitrary, and often reversed for regular
// scenes, which insertion sort handles worst).
// A workgroup-wide bitonic sort in shared memory for deep texels was tried:
// on lavapipe its ~45 barriers per texel made the pass 10x slower than this
// (1M-sphere lattice, texels of 65..300 entries); on a GPU it may pay off.
// Then the invocation walks its sorted run once to write the next links
// (entry i -> i + 1, last -> DEEP_NONE), the uncompressed transmittance after
// each entry (running product of 1 - alpha), and the nodes (depth, V) of an
// epsilon-compressed piecewise-linear visibility function V'(z) with
// |V' - V| <= eps (deep shadow maps on the GPU, Eq. 1): greedy segments through a slope window
// as in Lokovic & Veach, a step (|jump| > eps at one depth) being two nodes
// with the same depth, before and after (the paper's surface rule).
//
// Node layout: two SoA arrays (depth, V) of twice the entry capacity; the
// texel whose entries start at head keeps its nodes at 2 * head ... in order,
// texels[].nodes of them. A run of n entries never has more than 2n nodes:
// the samples fed are the 2n points (z_i, V before entry i), (z_i, V after
// it); every node is emitted at an anchor, and each anchor is a later sample
// than the previous one (a segment ends at its last accepted sample, which
// follows its anchor; a step anchors at the current sample), the first node
// being sample 0 and the closing node the last accepted sample after the
// final anchor. The bound is reached by distinct depths with alpha > 2 eps:
// the first entry gives the first node and its step, each later one a
// segment end and a step (mixed-60-translucent in tests/deep.rs: 2.0/entry).
// So the node run fits the texel's 2n slots with no second allocation, at the
// price of 16 bytes per entry slot; writes are still clamped to 2n slots.
#include "deep.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) buffer Texels { DeepTexel texels[]; };
layout(set = 0, binding = 2) buffer Depth { float e_depth[]; };
layout(set = 0, binding = 3) buffer Alpha { float e_alpha[]; };
layout(set = 0, binding = 4) buffer Ids { uint e_id[]; };
layout(set = 0, binding = 5) writeonly buffer Next { uint e_next[]; };
layout(set = 0, binding = 6) writeonly buffer Trans { float e_trans[]; };
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };
// Node slot s lives in the array of its parity at s / 2: each array then
// holds one word per entry slot, so the node arrays stay within
// maxStorageBufferRange as long as the entry arrays do (4M spheres on
// lavapipe need more than 128 MiB of node slots).
layout(set = 0, binding = 8) writeonly buffer NodeDepthEven { float n_depth0[]; };
layout(set = 0, binding = 9) writeonly buffer NodeVisEven { float n_vis0[]; };
layout(set = 0, binding = 10) writeonly buffer NodeDepthOdd { float n_depth1[]; };
layout(set = 0, binding = 11) writeonly buffer NodeVisOdd { float n_vis1[]; };

#include "push/deep_sort.glsl"

bool before(float da, uint ia, float db, uint ib) {
    return da < db || (da == db && ia < ib);
}

const uint GAPS[9] = uint[](1577u, 701u, 301u, 132u, 57u, 23u, 10u, 4u, 1u);
const uint LOCAL_SORT = 256u; // 3 KB of private memory per invocation

// Float bits <-> unsigned keys with the same order (no NaNs here).
uint order_key(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}

float from_key(uint k) {
    return uintBitsToFloat((k & 0x80000000u) != 0u ? k & 0x7FFFFFFFu : ~k);
}

void sort_local(uint base, uint n) {
    uint64_t keys[LOCAL_SORT];
    float alphas[LOCAL_SORT];
    for (uint i = 0u; i < n; ++i) {
        keys[i] = (uint64_t(order_key(e_depth[base + i])) << 32) | uint64_t(e_id[base + i]);
        alphas[i] = e_alpha[base + i];
    }
    for (int gi = 3; gi < 9; ++gi) {
        uint gap = GAPS[gi];
        if (gap >= n) continue;
        for (uint i = gap; i < n; ++i) {
            uint64_t k = keys[i];
            float a = alphas[i];
            uint j = i;
            while (j >= gap && keys[j - gap] > k) {
                keys[j] = keys[j - gap];
                alphas[j] = alphas[j - gap];
                j -= gap;
            }
            keys[j] = k;
            alphas[j] = a;
        }
    }
    for (uint i = 0u; i < n; ++i) {
        e_depth[base + i] = from_key(uint(keys[i] >> 32));
        e_id[base + i] = uint(keys[i] & 0xFFFFFFFFul);
        e_alpha[base + i] = alphas[i];
    }
}

void sort_global(uint base, uint n) {
    for (int gi = 0; gi < 9; ++gi) {
        uint gap = GAPS[gi];
        if (gap >= n) continue;
        for (uint i = gap; i < n; ++i) {
            float d = e_depth[base + i];
            float a = e_alpha[base + i];
            uint id = e_id[base + i];
            uint j = i;
            while (j >= gap) {
                uint p = base + j - gap;
                float dp = e_depth[p];
                uint ip = e_id[p];
                if (!before(d, id, dp, ip)) break;
                e_depth[base + j] = dp;
                e_alpha[base + j] = e_alpha[p];
                e_id[base + j] = ip;
                j -= gap;
            }
            e_depth[base + j] = d;
            e_alpha[base + j] = a;
            e_id[base + j] = id;
        }
    }
}

const float BIG = 3.0e38;

// Greedy compression state: anchor (za, va), slope window [lo, hi] of the
// segment leaving the anchor, last accepted depth zl.
float za, va, lo, hi, zl;
bool open_segment;
uint nodes;
uint node_base, node_cap; // the texel's node slots: [node_base, node_base + node_cap)

void emit(float z, float v) {
    if (nodes < node_cap) {
        uint s = node_base + nodes;
        if ((s & 1u) == 0u) {
            n_depth0[s >> 1] = z;
            n_vis0[s >> 1] = v;
        } else {
            n_depth1[s >> 1] = z;
            n_vis1[s >> 1] = v;
        }
    }
    nodes++;
}

void feed(float z, float v) {
    for (int it = 0; it < 2; ++it) {
        float dz = z - za;
        if (dz <= 0.0) {
            // At the anchor's depth: a step larger than eps is a vertical
            // segment (two nodes with the same z, as in the paper).
            if (abs(v - va) > pc.eps) {
                va = v;
                emit(za, va);
                lo = -BIG;
                hi = BIG;
                open_segment = false;
            }
            return;
        }
        float nlo = max(lo, (v - pc.eps - va) / dz);
        float nhi = min(hi, (v + pc.eps - va) / dz);
        if (nlo <= nhi) {
            lo = nlo;
            hi = nhi;
            zl = z;
            open_segment = true;
            return;
        }
        // No single segment stays within eps: end it at the last accepted
        // depth (open_segment is true here: an empty window is unbounded).
        va += 0.5 * (lo + hi) * (zl - za);
        za = zl;
        emit(za, va);
        lo = -BIG;
        hi = BIG;
        open_segment = false;
    }
}

void main() {
    uint map_w = g.light.dims.x, map_h = g.light.dims.y;
    uint l = gl_LocalInvocationID.x;
    uvec2 t = gl_WorkGroupID.xy * DEEP_TILE + uvec2(l % DEEP_TILE, l / DEEP_TILE);
    if (t.x >= map_w || t.y >= map_h) return;
    uint ti = t.y * map_w + t.x;
    DeepTexel tx = texels[ti];
    uint n = min(tx.count, tx.fill);
    uint base = tx.head;
    if (n == 0u || base == DEEP_NONE || base >= pc.entry_capacity || n > pc.entry_capacity - base) {
        texels[ti].nodes = 0u;
        return;
    }
    if (n <= LOCAL_SORT) {
        sort_local(base, n);
    } else {
        sort_global(base, n);
    }
    // Links, transmittance and the compressed visibility function.
    za = e_depth[base];
    va = 1.0;
    lo = -BIG;
    hi = BIG;
    zl = za;
    open_segment = false;
    node_base = 2u * base; // < 2 * entry_capacity (check_capacity keeps it in range)
    node_cap = 2u * n;
    nodes = 0u;
    emit(za, 1.0); // (first depth, 1)
    float v = 1.0;
    bool walked = false;
    for (uint i = 0u; i < n; ++i) {
        // (set in the last step: the compiler cannot know the loop
        // reaches it, as it would an `i < n` after the loop)
        walked = i + 1u == n;
        uint a = base + i;
        float z = e_depth[a];
        feed(z, v);
        v *= 1.0 - e_alpha[a];
        feed(z, v);
        e_trans[a] = v;
        e_next[a] = i + 1u < n ? a + 1u : DEEP_NONE;
    }
    // (the walk is the last loop: where lavapipe's loop limit ran out in
    // the sort or in it, it stopped short; the host refuses the frame)
    if (!walked) atomicAdd(counters[C_SORT_CUT], 1u);
    if (open_segment) emit(zl, va + 0.5 * (lo + hi) * (zl - za));
    texels[ti].nodes = nodes;
    atomicAdd(counters[C_NODES], nodes);
    atomicMax(counters[C_MAX_NODES], nodes);
}
