#version 460
// Test-only: writes the SSDO hemisphere sample directions for a given normal
// and rotation so tests/ssdo.rs can check their distribution.
#include "ssdo_common.glsl"
layout(local_size_x = 64) in;
layout(set = 0, binding = 0) writeonly buffer Out { vec4 dirs[]; };
layout(push_constant) uniform Push { vec4 normal; uint count; float rot; uint pad0, pad1; } pc;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count) return;
    dirs[i] = vec4(hemisphere_sample(i, normalize(pc.normal.xyz), pc.rot), 0.0);
}
