#version 460
// Visibility buffer -> G-buffer: world position + view depth, normal. The
// sphere id stays in the low word of the visibility buffer for later passes.
#include "shared.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) readonly buffer Vis { uint64_t vis[]; };
layout(set = 0, binding = 3) writeonly buffer GPos { vec4 gpos[]; };    // xyz world, w depth key
layout(set = 0, binding = 4) writeonly buffer GNorm { vec4 gnorm[]; };  // xyz normal, w 1 (0 = background)
layout(set = 0, binding = 5) readonly buffer Attrs { SphereAttr attrs[]; };
// The regions buffer of seed 001: region ids of the visible sphere per level.
layout(set = 0, binding = 6) writeonly buffer GRegion { uvec4 gregion[]; };

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uint i = FLAT_ID;
    if (i >= w * h) return;
    uint64_t key = vis[i];
    if (key == VIS_EMPTY) {
        gpos[i] = vec4(0.0, 0.0, 0.0, -1.0);
        gnorm[i] = vec4(0.0);
        gregion[i] = uvec4(NO_SPHERE);
        return;
    }
    uint id = uint(key & 0xFFFFFFFFul);
    vec4 s = spheres[id];
    vec3 o, d;
    view_ray(g.cam, vec2(i % w, i / w), o, d);
    // Exact hit recomputed in world space relative to the sphere centre for precision.
    vec3 oc = o - s.xyz;
    float b = dot(oc, d);
    float disc = max(b * b - (dot(oc, oc) - s.w * s.w), 0.0);
    float t = -b - sqrt(disc);
    vec3 p = o + t * d;
    vec3 n = normalize(p - s.xyz);
    gpos[i] = vec4(p, uintBitsToFloat(uint(key >> 32)));
    gnorm[i] = vec4(n, 1.0);
    gregion[i] = attrs[id].region;
}
