#version 460
// The depth tiles of a view's early raster (pc.view_index: the camera's
// visibility buffer or the light map) for the late occlusion test
// (lod_cull.comp): MODE 0 (the camera) and 3 (the light), one invocation
// per fine tile of the window (T x T pixels, T = 2^pc.hiz_shift), the
// farthest depth word of its pixels (an empty pixel's word is all ones:
// nothing behind it is hidden); MODE 1,
// one per coarse tile (8T x 8T), the farthest of its 8x8 fine tiles;
// MODE 2, one per super tile (64T x 64T), of its 8x8 coarse tiles. They
// lie in that order in `hiz`; the camera's 4-px fine tiles also write
// their 2-px quadrants after them (pc.micro_base: the per-atom test of
// its batch raster, glsl/raster.comp `tiles_hide`), the light's are
// bounded by its receivers. (Each view its own MODE: lavapipe runs both
// sides of a branch, uniform ones too.)
#include "shared.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// The visibility buffer as 32-bit words (2k + 1: pixel k's depth).
layout(set = 0, binding = 1) uniform usamplerBuffer visWordTex;
layout(set = 0, binding = 2) buffer Hiz { uint hiz[]; };
// The light's receiver depths (lod_bounds.comp: per receiver tile, the
// farthest of the visible points whose lookup is centred in it).
layout(set = 0, binding = 3) readonly buffer Region { int region[]; };
// With pc.compare: last frame's final tiles, and the LOD counters whose
// LOD_TILES_CHANGED word is set where a fine tile differs (the camera's
// recheck runs only then: src/gpu_consts.rs).
layout(set = 0, binding = 4) uniform usamplerBuffer hizPrevTex;
layout(set = 0, binding = 5) buffer Counters { uint counters[]; };
#include "lod_receivers.glsl"

layout(constant_id = 1) const uint MODE = 0u;
#include "push/lod_hiz.glsl"

void main() {
    uvec4 dims = pc.view_index == 0u ? g.cam.dims : g.light.dims;
    uint w = dims.x, h = dims.y;
    uint T = 1u << pc.hiz_shift;
    uvec2 tf = (uvec2(w, h) + T - 1u) / T;
    uint i = FLAT_ID;
    uint far = 0u;
    if (MODE == 0u || MODE == 3u) {
        if (i >= tf.x * tf.y) return;
        uvec2 o = uvec2(i % tf.x, i / tf.x) * T;
        uint x1 = min(o.x + T, w), y1 = min(o.y + T, h);
        // (the camera's 2-px tiles of a 4-px one, pc.micro_base: its
        // quadrants, q[row][column])
        uvec4 q = uvec4(0u);
        for (uint y = o.y; y < y1; ++y) {
            for (uint x = o.x; x < x1; ++x) {
                uint word = texelFetch(visWordTex, int(2u * (y * w + x) + 1u)).x;
                far = max(far, word);
                if (MODE == 0u) {
                    bool right = x - o.x >= 2u, low = y - o.y >= 2u;
                    q = max(q, uvec4(!low && !right, !low && right, low && !right, low && right) * word);
                }
            }
        }
        if (MODE == 0u && pc.micro_base != 0u) {
            uint mw = (w + 1u) / 2u;
            for (uint k = 0u; k < 4u; ++k) {
                uvec2 m = o / 2u + uvec2(k & 1u, k >> 1u);
                if (2u * m.x >= w || 2u * m.y >= h) continue;
                uint at = pc.micro_base + m.y * mw + m.x;
                hiz[at] = q[k];
                if (pc.compare != 0u && texelFetch(hizPrevTex, int(at)).x != q[k]) {
                    atomicOr(counters[LOD_TILES_CHANGED], 1u);
                }
            }
        }
        // A light tile hides what lies farther from the light than every
        // visible point whose lookup reads it (those centred in a tile
        // within its reach), grown by the lookup's slack: a lookup counts
        // only casters nearer the light than its point, so the rest
        // shadows nothing the camera sees; a tile no such point reads
        // hides everything (meso 10^9 at 2,025 A: the plasma below the
        // deepest points the camera sees between the proteins).
        if (MODE == 3u) {
            // (the texels within the reach, then their receiver tiles)
            ivec2 t = ivec2(i % tf.x, i / tf.x) << pc.hiz_shift;
            int RS = int(pc.receiver_shift);
            ivec2 a = max(t - pc.reach, ivec2(0)) >> RS;
            ivec2 b = min(t + int(T) - 1 + pc.reach, ivec2(w, h) - 1) >> RS;
            // (a window of more than RECEIVER_WINDOW depth tiles a side is
            // taken as read to any depth, nothing hidden: the loop over its
            // receiver tiles (as many or fewer) would pass lavapipe's 65,535
            // back-edges; a PCF radius of 300 texels on a 2048^2 map spans
            // 302, ISSM's t <= 64 on a 512^2 map 129)
            int side = ((t.x + int(T) - 1 + pc.reach) >> pc.hiz_shift) - ((t.x - pc.reach) >> pc.hiz_shift) + 1;
            bool all = pc.reach >= 1 << 20 || side > RECEIVER_WINDOW;
            uint deepest = all ? 0xFFFFFFFFu : 0u;
            b = all ? a - 1 : b;
            int rw = (int(w) + (1 << RS) - 1) >> RS;
            for (int y = a.y; y <= b.y; ++y) {
                for (int x = a.x; x <= b.x; ++x) {
                    deepest = max(deepest, uint(region[receiver_word(y * rw + x)]));
                }
            }
            far = min(far, deepest);
        }
        hiz[i] = far;
        if (pc.compare != 0u && texelFetch(hizPrevTex, int(i)).x != far) {
            atomicOr(counters[LOD_TILES_CHANGED], 1u);
        }
    } else {
        // (the level below: fine for MODE 1, coarse for MODE 2)
        uint below = MODE == 1u ? 0u : tf.x * tf.y;
        uvec2 tb = MODE == 1u ? tf : (uvec2(w, h) + 8u * T - 1u) / (8u * T);
        uvec2 tc = (tb + 7u) / 8u;
        if (i >= tc.x * tc.y) return;
        uvec2 o = uvec2(i % tc.x, i / tc.x) * 8u;
        uint x1 = min(o.x + 8u, tb.x), y1 = min(o.y + 8u, tb.y);
        for (uint y = o.y; y < y1; ++y) {
            for (uint x = o.x; x < x1; ++x) far = max(far, hiz[below + y * tb.x + x]);
        }
        hiz[below + tb.x * tb.y + i] = far;
    }
}
