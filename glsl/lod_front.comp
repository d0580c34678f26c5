#version 460
// The camera's front instances, for an early phase with no usable
// history (the first frame, or after a large move: glsl/lod_cull.comp
// lists early every batch of the instances its history flags name, and
// the late phase tests the rest against that early image; last frame's
// instances seen from far elsewhere leave it sparse, and behind its holes
// the late phase lists everything: the bench's orbit, at 2,025 A after a
// 4x zoom in, drew 110 M spheres late against 13.4 M for a still camera).
// One invocation per instance: its molecule's bounding sphere (level 0)
// placed in the camera's view,
//   MODE 0: the nearest depth of any instance whose centre falls in a
//           cell (2^pc.cell_shift pixels a side) kept per cell (atomicMin
//           on the depth's bits: non-negative floats order as uints);
//   MODE 1: the history flag VISIBLE_PASSED set in last frame's array
//           (pc.parity) for the instance whose nearest depth is its
//           cell's, and cleared for the others (the flag the early phase
//           reads without last tiles: only after a small move does it
//           read VISIBLE_SHOWN).
// Cells about as wide as a typical instance's radius on screen
// (src/stages/raster/lod.rs `front_shift`; they lie in the camera's early
// depth tiles' buffer, built later in the frame); meso 10^9 at 2,025 A
// (instances ~25 px), the bench's orbit: 8 px cells listed 31 M spheres
// early, 16 px 13.6 M, 32 px 2.3 M, and the early image's holes sent 26,
// 13 and 46 M late; at the overview (~6 px) 16 px cells gained nothing,
// 4 px 19.9 -> 11.1 M in a first frame. A cell's nearest by the nearest point of each bounding
// sphere over every cell under it (not only its centre's) lets a few
// large molecules take every cell: 2.5 M early, 48 M late.
// A heuristic only: whatever the early phase lists, the late phase lists
// what is not hidden, so the image is the same (tests/instanced.rs).
#include "raster_common.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// Per molecule type and level: the level's bounding sphere (lod_cull.comp's).
layout(set = 0, binding = 1) uniform samplerBuffer lodBoundTex;
// Per instance and view, two arrays (lod_cull.comp's).
layout(set = 0, binding = 2) buffer Visible { uint visible[]; };
// Per cell: the nearest depth bits (all ones: none).
layout(set = 0, binding = 3) buffer Front { uint front[]; };
#include "scene.glsl"
#include "push/lod_front.glsl"

layout(constant_id = 1) const bool PERSP = false;
layout(constant_id = 2) const uint MODE = 0u;

void main() {
    uint k = FLAT_ID;
    if (k >= pc.instances) return;
    View v = g.cam;
    uint m = texelFetch(instanceRowTex, int(k)).x;
    vec4 bs = texelFetch(lodBoundTex, int(2u * m * MAX_LOD_LEVELS));
    vec3 cv = view_space(v, instance_apply(k, bs.xyz), PERSP);
    ivec4 rc = sphere_rect(v, cv, bs.w, PERSP);
    bool inside = rc.x <= rc.z && rc.y <= rc.w;
    // (its rectangle's centre, within the window as the rectangle is
    // where it is inside; clamped for the others, which read a cell too)
    ivec2 c = clamp((rc.xy + rc.zw) / 2 - ivec2(v.dims.zw), ivec2(0), ivec2(v.dims.xy) - 1);
    uint cells_x = (v.dims.x + (1u << pc.cell_shift) - 1u) >> pc.cell_shift;
    uint cell = (uint(c.y) >> pc.cell_shift) * cells_x + (uint(c.x) >> pc.cell_shift);
    float near = max(PERSP ? length(cv) - bs.w : cv.z + v.depth.x - bs.w, 0.0);
    if (MODE == 0u) {
        if (inside) atomicMin(front[cell], floatBitsToUint(near));
        return;
    }
    uint at = pc.parity * 2u * pc.instances + 2u * k;
    bool seed = inside && near <= uintBitsToFloat(front[cell]);
    uint old = visible[at];
    visible[at] = seed ? old | VISIBLE_PASSED : old & ~VISIBLE_PASSED;
}
