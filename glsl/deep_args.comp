#version 460
// Deep shadow lists: turns the band job count into indirect dispatch
// arguments (2D so any count fits) and records how many bands will run.
#include "deep.glsl"

layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Counters { uint counters[]; };
layout(push_constant) uniform Push { uint job_capacity; } pc;

void main() {
    uint n = min(counters[C_BANDS_REQ], pc.job_capacity);
    counters[C_BANDS_RUN] = n;
    counters[C_ARGS] = min(n, DEEP_MAX_X);
    counters[C_ARGS + 1u] = n == 0u ? 0u : (n + DEEP_MAX_X - 1u) / DEEP_MAX_X;
    counters[C_ARGS + 2u] = 1u;
}
