#version 460
// Per-sphere SSDO, step 1: the spheres ssdo_prep.comp marked visible this
// frame (one bit per sphere, 32 per flag word), compacted into a list (a
// word's spheres consecutive, in bit order, from word_base[word]: a
// sphere's list entry, where its result goes, is word_base plus the set
// bits below its own, so the results take a listed sphere's 16 bytes, not
// every sphere's: an instanced scene of 10^7 spheres sees 10^6 at most), and
// the number of workgroups of `group` invocations the list needs, for
// band_args.comp's indirect dispatch arguments. One invocation per flag
// word, one atomic per word with a bit set: an invocation per sphere cost
// ~9 ms for 1M spheres on lavapipe, most of it the masked atomics and
// stores that every vector runs whether or not a lane takes them.
#include "shared.glsl"

layout(local_size_x_id = 0) in;
layout(set = 0, binding = 0) readonly buffer Flags { uint flags[]; };
layout(set = 0, binding = 1) writeonly buffer List { uint list[]; };
layout(set = 0, binding = 2) buffer Counters { uint counters[]; };
layout(set = 0, binding = 3) writeonly buffer WordBase { uint word_base[]; };

#include "push/ssdo_list.glsl"

void main() {
    uint w = FLAT_ID;
    if (w >= pc.words) return;
    uint bits = flags[w];
    if (bits == 0u) return;
    uint n = uint(bitCount(bits));
    uint slot = atomicAdd(counters[S_LISTED], n);
    word_base[w] = slot;
    // (never more than the buffer's pixels: checked, not assumed)
    if (slot + n > pc.capacity) return;
    // the workgroups whose first slot this word's entries fill
    uint g = (1u << pc.group_shift) - 1u;
    uint groups = ((slot + n + g) >> pc.group_shift) - ((slot + g) >> pc.group_shift);
    if (groups != 0u) atomicAdd(counters[S_GROUPS], groups);
    for (; bits != 0u; bits &= bits - 1u) {
        list[slot++] = 32u * w + uint(findLSB(bits));
    }
}
