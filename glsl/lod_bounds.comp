#version 460
// The light texels a visible point's shadow lookup is centred on: one
// invocation per 16x16 pixels of the camera's visibility buffer (after
// both raster phases) unprojects each covered pixel's hit and takes the
// light-map rectangle of those points (one atomic per word per tile) and,
// per light receiver tile (lod_receivers.glsl), the farthest of their
// depths from the light (an atomicMax where the tile changes from the last
// pixel's). The light's cull (lod_cull.comp) keeps only instances over the
// rectangle, and its depth tiles (lod_hiz.comp) hide everything farther
// from the light than every point whose lookup reaches the tile: nothing
// else can shadow what the camera sees (a lookup counts only casters
// nearer the light than its point, give or take the lookup's depth slack).
#include "shared.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer visWordTex;
// x0, y0, x1, y1 in light texels (the host sets them empty first), then
// the receiver depths (lod_receivers.glsl; zeroed by the host).
layout(set = 0, binding = 2) buffer Region { int region[]; };
#include "lod_receivers.glsl"
#include "push/lod_bounds.glsl"

layout(constant_id = 1) const bool PERSP = false;

void main() {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    uvec2 t16 = (uvec2(w, h) + 15u) / 16u;
    uint i = FLAT_ID;
    if (i >= t16.x * t16.y) return;
    uvec2 o = uvec2(i % t16.x, i / t16.x) * 16u;
    uint x1 = min(o.x + 16u, w), y1 = min(o.y + 16u, h);
    View L = g.light;
    float ppu = L.center.w;
    vec2 lo = vec2(3.0e38), hi = vec2(-3.0e38);
    int size = int(L.dims.x);
    int S = int(pc.hiz_shift);
    int tw = (size + (1 << S) - 1) >> S;
    int last = -1;
    uint far = 0u;
    for (uint y = o.y; y < y1; ++y) {
        for (uint x = o.x; x < x1; ++x) {
            uint key = texelFetch(visWordTex, int(2u * (y * w + x) + 1u)).x;
            if (key == 0xFFFFFFFFu) continue;
            vec3 org, dir;
            view_ray(g.cam, vec2(uvec2(x, y) + g.cam.dims.zw), PERSP, org, dir);
            float t = PERSP ? uintBitsToFloat(key) : uintBitsToFloat(key) - g.cam.depth.x;
            vec3 q = org + t * dir - L.center.xyz;
            vec2 p = vec2(dot(q, L.right.xyz) * ppu + 0.5 * L.right.w - 0.5,
                          0.5 * L.up.w - dot(q, L.up.xyz) * ppu - 0.5);
            lo = min(lo, p);
            hi = max(hi, p);
            // (the depth word the light's raster and cull use, grown by the
            // slack and for the rounding of the unprojected point: the same
            // margin lod_cull.comp takes off a caster's near side)
            float z = dot(q, L.dir.xyz) + L.depth.x;
            uint word = floatBitsToUint(max(z + pc.slack + 1e-4 * (abs(z) + abs(L.depth.x)) + 1e-3, 0.0));
            // (the lookup's centre texel, kept one texel inside the map as
            // ISSM's 3x3 core is: what a lookup reads lies within its
            // reach of it, src/stages/shadows/mod.rs `Lookup::reach`)
            ivec2 c = clamp(ivec2(round(clamp(p, vec2(-1e9), vec2(1e9)))), ivec2(1), ivec2(size - 2));
            int tile = (c.y >> S) * tw + (c.x >> S);
            if (tile != last) {
                if (last >= 0) atomicMax(region[receiver_word(last)], int(far));
                last = tile;
                far = 0u;
            }
            far = max(far, word);
        }
    }
    if (last >= 0) atomicMax(region[receiver_word(last)], int(far));
    if (lo.x > hi.x) return;
    // (clamped: a point far outside the map stays an int)
    ivec2 a = ivec2(floor(clamp(lo, vec2(-1e9), vec2(1e9))));
    ivec2 b = ivec2(ceil(clamp(hi, vec2(-1e9), vec2(1e9))));
    atomicMin(region[0], a.x);
    atomicMin(region[1], a.y);
    atomicMax(region[2], b.x);
    atomicMax(region[3], b.y);
}
