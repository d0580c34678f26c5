#version 460
// Band jobs: turns the number of bands the per-sphere pass queued into
// indirect dispatch arguments (2D so any count fits under
// maxComputeWorkGroupCount) and records how many bands will run. The word
// positions in the pass's counter buffer come as push constants, so raster,
// deep lists and opacity maps share this shader.
#include "constants.glsl"
#include "grid.glsl"

layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Counters { uint counters[]; };
#include "push/band_args.glsl"

void main() {
    uint n = min(counters[pc.requested], pc.job_capacity);
    counters[pc.run] = n;
    uvec3 a = grid_of(n);
    counters[pc.args] = a.x;
    counters[pc.args + 1u] = a.y;
    counters[pc.args + 2u] = a.z;
}
