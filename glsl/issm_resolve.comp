#version 460
// ISSM resolve (after issm_raster): each light texel's nearest sphere as a
// light-space record (centre along the light view's right, up and
// direction from its centre; radius), so the lookup reads one 16-byte
// texel per patch texel instead of an id and then the sphere it names (on
// lavapipe a texel fetch costs per lane whatever its width, and the
// lookup's fetches were its cost), and tests in light space. Empty texels
// get ISSM_EMPTY (shared.glsl): no ray passes near them.
#include "shared.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer issmTex; // R32UI view: even words = ids
layout(set = 0, binding = 3) writeonly buffer Resolved { vec4 resolved[]; };

#include "push/issm_resolve.glsl"
#include "scene.glsl"

void main() {
    uint i = FLAT_ID;
    if (i >= pc.texels) return;
    uint id = texelFetch(issmTex, int(2u * i)).x;
    vec4 s = scene_sphere(id == NO_SPHERE ? 0u : id);
    resolved[i] = id == NO_SPHERE ? ISSM_EMPTY : vec4(light_space(g.light, s.xyz), s.w);
}
