#version 460
// Test-only: copies every field of the shared structs, in declaration order,
// into a flat array so tests/gpu_layout.rs can compare GLSL offsets with Rust.
#include "shared.glsl"
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Attrs { SphereAttr attrs[]; };
layout(set = 0, binding = 2) writeonly buffer Out { uint words[]; };

uint k = 0;
void put4(vec4 v) { for (int i = 0; i < 4; ++i) words[k++] = floatBitsToUint(v[i]); }
void put4u(uvec4 v) { for (int i = 0; i < 4; ++i) words[k++] = v[i]; }
void put_view(View v) { put4(v.center); put4(v.right); put4(v.up); put4(v.dir); put4(v.depth); put4u(v.dims); }

void main() {
    put_view(g.cam);
    put_view(g.light);
    put4(g.light_dir);
    put4(g.background);
    put4u(g.counts);
    put4(g.params);
    put4(g.shadow_f0);
    put4(g.shadow_f1);
    put4u(g.shadow_u);
    put4u(g.scene);
    put4(g.alpha);
    for (int a = 0; a < 2; ++a) {
        put4u(attrs[a].region);
    }
}
