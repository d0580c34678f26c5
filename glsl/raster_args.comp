#version 460
// Turns the band count into indirect dispatch arguments (2D so any count fits
// under maxComputeWorkGroupCount) and records how many bands will run.
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) buffer Counters { uint counters[]; }; // [0] requested, [1] run, [4..6] dispatch args
layout(push_constant) uniform Push { uint job_capacity; } pc;

const uint MAX_X = 65535;

void main() {
    uint n = min(counters[0], pc.job_capacity);
    counters[1] = n;
    counters[4] = min(n, MAX_X);
    counters[5] = n == 0 ? 0 : (n + MAX_X - 1) / MAX_X;
    counters[6] = 1;
}
