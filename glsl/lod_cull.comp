#version 460
// Levels of detail and culling of an instanced scene, one invocation per
// instance, for one view (pc.view_index): the instance's bounding sphere
// is placed with its transform and tested against the view's pixel
// window (sphere_rect: the frustum, and a tile's window when tiling); the
// camera's pass chooses its level from its size on screen (the coarsest
// whose switch size it is within, src/scene/instanced/lod.rs) and keeps
// it for the light's pass, so both views draw the same (instance, atom)
// slots and the ISSM's self-shadow test stays exact. A kept instance
// appends its level's batches to the view's list, which the rasterizer
// visits instead of the view order (dispatched indirectly, lod_args.comp).
// Entries past the count name the empty batch (the host fills them).
#include "raster_common.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// Per (molecule type, level): first batch of the level within the
// instance's coarse batches (level 0: the number of levels), batches,
// switch size (f32 bits, pixels per world unit), spheres.
layout(set = 0, binding = 1) uniform usamplerBuffer lodLevelTex;
// Per molecule type: bounding sphere in its frame.
layout(set = 0, binding = 2) uniform samplerBuffer lodBoundTex;
// Per instance: molecule type, first level-0 batch, first coarse batch.
layout(set = 0, binding = 3) uniform usamplerBuffer lodInstanceTex;
// Per instance: the level the camera chose.
layout(set = 0, binding = 4) buffer Levels { uint levels[]; };
layout(set = 0, binding = 5) buffer List { uint list[]; };
layout(set = 0, binding = 6) buffer Counters { uint counters[]; };
#include "scene.glsl"
#include "push/lod_cull.glsl"

layout(constant_id = 1) const bool PERSP = false;

void main() {
    uint k = FLAT_ID;
    if (k >= pc.instances) return;
    uvec4 ik = texelFetch(lodInstanceTex, int(k));
    uint m = ik.x;
    vec4 bs = texelFetch(lodBoundTex, int(m));
    bool cam = pc.view_index == 0u;
    View v = cam ? g.cam : g.light;
    vec3 cv = view_space(v, instance_apply(k, bs.xyz), PERSP && cam);
    uint base = m * MAX_LOD_LEVELS;
    uint level;
    if (cam) {
        // pixels per world unit at the instance's nearest point
        float ppu = v.center.w;
        if (PERSP) {
            float z = cv.z - bs.w;
            ppu = z > 0.0 ? ppu * v.dir.w / z : 1e30;
        }
        uint n = texelFetch(lodLevelTex, int(base)).x;
        level = 0u;
        for (uint l = 1u; l < n; ++l) {
            if (ppu <= uintBitsToFloat(texelFetch(lodLevelTex, int(base + l)).z)) level = l;
        }
        levels[k] = level;
    } else {
        level = levels[k];
    }
    ivec4 rc = sphere_rect(v, cv, bs.w, PERSP && cam);
    if (rc.x > rc.z || rc.y > rc.w) return;
    uvec4 e = texelFetch(lodLevelTex, int(base + level));
    uint first = level == 0u ? ik.y : ik.z + e.x;
    uint w = pc.view_index * LOD_WORDS;
    uint at = atomicAdd(counters[w + LOD_BATCHES], e.y);
    atomicAdd(counters[w + LOD_SPHERES], e.w);
    uint last = min(at + e.y, pc.capacity);
    for (uint j = at; j < last; ++j) list[j] = first + (j - at);
}
