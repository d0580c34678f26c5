#version 460
// Test-only: the SSDO sample directions as ssdo.comp makes them (the table
// entry i % 64 rotated by (i / 64) / 128 + rot of a turn about the normal)
// so tests/ssdo.rs can check their distribution.
#include "ssdo_common.glsl"
layout(local_size_x = 64) in;
layout(set = 0, binding = 0) writeonly buffer Out { vec4 dirs[]; };
layout(set = 0, binding = 1) uniform SampleTable { vec4 samples[64]; };
layout(push_constant) uniform Push { vec4 normal; uint count; float rot; uint pad0, pad1; } pc;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    float rot = fract(float(i / 64u) / 128.0 + pc.rot);
    dirs[i] = vec4(table_sample(samples[i % 64u], tangent_frame(normalize(pc.normal.xyz)), rot), 0.0);
}
