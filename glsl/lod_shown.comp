#version 460
// The instances a moved camera's final image shows (its visibility
// buffer, drawn from the LOD lists: a pixel's id is a slot of the lists'
// buffer, entry id >> batch_shift), flagged VISIBLE_SHOWN in this frame's
// array for the next frame's early phase (glsl/lod_cull.comp). A moved
// camera's early phase has no tiles to test against and lists every
// batch of the instances that passed last frame, which all pass again:
// while the camera keeps moving an instance once seen would be listed
// early for good (meso 10^9 at 2,025 A orbiting 1 degree a frame: 38 M
// spheres drawn by the sixth frame, 13.4 M still). One invocation per
// SHOWN_RUN pixels of a row-major run, a flag set where the entry changes
// along it.
#include "shared.glsl"

layout(local_size_x = 64) in;

const uint SHOWN_RUN = 16u;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// The visibility buffer as 32-bit words (2k: pixel k's id).
layout(set = 0, binding = 1) uniform usamplerBuffer visWordTex;
// The LOD lists (the frame's batch table).
layout(set = 0, binding = 2) uniform usamplerBuffer batchTex;
// Per instance and view, two arrays (glsl/lod_cull.comp's; the cull
// wrote this frame's before).
layout(set = 0, binding = 3) buffer Visible { uint visible[]; };
#include "push/lod_shown.glsl"

void main() {
    uint n = g.cam.dims.x * g.cam.dims.y;
    uint first = FLAT_ID * SHOWN_RUN;
    if (first >= n) return;
    uint now = (1u - pc.parity) * 2u * pc.instances;
    uint last = NO_SPHERE;
    for (uint k = first; k < min(first + SHOWN_RUN, n); ++k) {
        uint id = texelFetch(visWordTex, int(2u * k)).x;
        uint e = id == NO_SPHERE ? NO_SPHERE : id >> pc.batch_shift;
        if (e != last && e != NO_SPHERE) {
            // (the camera's flag: 2k + 0)
            atomicOr(visible[now + 2u * (texelFetch(batchTex, int(e)).x & BATCH_INSTANCE_MASK)], VISIBLE_SHOWN);
        }
        last = e;
    }
}
