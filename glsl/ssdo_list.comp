#version 460
// Per-sphere SSDO, step 1: the spheres ssdo_prep.comp marked visible this
// frame, compacted into a list (one atomic per listed sphere), and the
// number of workgroups of `group` invocations the list needs, for
// band_args.comp's indirect dispatch arguments.
#include "shared.glsl"

layout(local_size_x_id = 0) in;
layout(set = 0, binding = 0) readonly buffer Flags { uint flags[]; };
layout(set = 0, binding = 1) writeonly buffer List { uint list[]; };
layout(set = 0, binding = 2) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    uint sphere_count;
    uint group;  // workgroup size of ssdo_sphere.comp (a power of two)
    uint pad0, pad1;
} pc;

void main() {
    uint id = FLAT_ID;
    if (id >= pc.sphere_count || flags[id] == 0u) return;
    uint slot = atomicAdd(counters[S_LISTED], 1u);
    list[slot] = id;
    // (a mask, not %: lavapipe divides every lane by a non-constant one
    // at a time, masked or not)
    if ((slot & (pc.group - 1u)) == 0u) atomicAdd(counters[S_GROUPS], 1u);
}
