#version 460
// The depth tiles of a view's early raster (pc.view_index: the camera's
// visibility buffer or the light map) for the late occlusion test
// (lod_cull.comp): MODE 0, one invocation per 16x16 pixels of the window,
// the farthest depth word of its pixels (an empty pixel's word is all
// ones: nothing behind it is hidden); MODE 1, one per 128x128, the
// farthest of its 8x8 tiles of 16.
#include "shared.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// The visibility buffer as 32-bit words (2k + 1: pixel k's depth).
layout(set = 0, binding = 1) uniform usamplerBuffer visWordTex;
layout(set = 0, binding = 2) buffer Hiz { uint hiz[]; };

layout(constant_id = 1) const uint MODE = 0u;
#include "push/lod_hiz.glsl"

void main() {
    uvec4 dims = pc.view_index == 0u ? g.cam.dims : g.light.dims;
    uint w = dims.x, h = dims.y;
    uvec2 t16 = (uvec2(w, h) + 15u) / 16u;
    uint i = FLAT_ID;
    uint far = 0u;
    if (MODE == 0u) {
        if (i >= t16.x * t16.y) return;
        uvec2 o = uvec2(i % t16.x, i / t16.x) * 16u;
        uint x1 = min(o.x + 16u, w), y1 = min(o.y + 16u, h);
        for (uint y = o.y; y < y1; ++y) {
            for (uint x = o.x; x < x1; ++x) {
                far = max(far, texelFetch(visWordTex, int(2u * (y * w + x) + 1u)).x);
            }
        }
        hiz[i] = far;
    } else {
        uvec2 t128 = (uvec2(w, h) + 127u) / 128u;
        if (i >= t128.x * t128.y) return;
        uvec2 o = uvec2(i % t128.x, i / t128.x) * 8u;
        uint x1 = min(o.x + 8u, t16.x), y1 = min(o.y + 8u, t16.y);
        for (uint y = o.y; y < y1; ++y) {
            for (uint x = o.x; x < x1; ++x) far = max(far, hiz[y * t16.x + x]);
        }
        hiz[t16.x * t16.y + i] = far;
    }
}
