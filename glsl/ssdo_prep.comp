#version 460
// variants: SHADOW_NONE SHADOW_ISSM SHADOW_DEEP SHADOW_SM SHADOW_OSM SHADOW_SCREEN SHADOW_BUFFER
// SSDO at half resolution, pass 1: for every 2x2 block, one representative
// covered pixel (its position in the block rotates from block to block so
// no corner is favoured) and its record (glsl/ssdo_record.glsl): view
// distance, normal, region hashes, and the direct key light it reflects for
// the bounce, with the key-light visibility of the active technique.
#include "shared.glsl"

layout(local_size_x_id = 0) in;
#include "spec/ssdo_prep.glsl"

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) uniform usamplerBuffer visTex;
#define SCENE_ATTRIBUTES
#include "scene.glsl"
layout(set = 0, binding = 4) writeonly buffer Records { uvec4 records[]; };
layout(set = 0, binding = 5) buffer Flags { uint flags[]; };
// The depth words of the block's four pixels (~0 outside the image and
// for background), block by block, for the taps of ssdo.comp and
// ssdo_sphere.comp: a 64-byte line holds an 8x2-pixel patch, where the
// visibility buffer's rows hold 8x1 pixels and their ids. Fewer cache lines
// per tap neighbourhood (the taps' fetches were mostly cache misses).
layout(set = 0, binding = 7) writeonly buffer TapDepth { uvec4 tap_depth[]; };

#include "push/ssdo_prep.glsl"

// Records feed the colour only: no self test (lookup_issm.glsl).
#define ISSM_SELF_TEST false
#include "lookup.glsl"
#include "ssdo_record.glsl"
#define TILE_LIST_ID SPEC_NEXT_ID
#define TILE_LIST_BINDING 6
#include "tiles.glsl"

void main() {
    uint hw = g.counts.y, hh = g.counts.z;
    uvec2 b;
    if (!tile_pixel(hw, hh, true, b)) return;
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    Record r;
    // The block's four keys in block order (~0 outside the image); none in
    // background regions (the loops compile out).
    const uint N = SSDO_BLOCK * SSDO_BLOCK;
    uvec4 ids = uvec4(NO_SPHERE), dw = uvec4(0xFFFFFFFFu);
    for (uint k = 0u; k < (TILE_LIST == 2u ? 0u : N); ++k) {
        uvec2 px = SSDO_BLOCK * b + uvec2(k % SSDO_BLOCK, k / SSDO_BLOCK);
        uvec2 v = texelFetch(visTex, int(min(px.y, h - 1u) * w + min(px.x, w - 1u))).xy;
        bool inside = px.x < w && px.y < h;
        ids[k] = inside ? v.x : NO_SPHERE;
        dw[k] = inside ? v.y : 0xFFFFFFFFu;
    }
    // The representative: the first covered pixel from a rotating start,
    // found from the ids alone (straight-line; lavapipe would run every
    // candidate's surface rebuild), then rebuilt once.
    uint first = (b.x + SSDO_BLOCK * b.y) % N;
    bool found = false;
    r.sub = uvec2(0u);
    for (uint k = 0u; k < (TILE_LIST == 2u ? 0u : N); ++k) {
        uint c = (first + k) % N;
        bool take = !found && ids[c] != NO_SPHERE;
        r.sub = take ? uvec2(c % SSDO_BLOCK, c / SSDO_BLOCK) : r.sub;
        found = found || take;
    }
    uvec2 rep = SSDO_BLOCK * b + r.sub;
    uint pixel = rep.y * w + rep.x;
    uint out_index = b.y * hw + b.x;
    if (MARK) {
        // The taps' depth words, and the spheres' flag bits (one bit per
        // sphere: ssdo_list.comp reads 32 spheres per word), one atomicOr
        // per distinct flag word of the block (mostly one: neighbouring
        // spheres have neighbouring ids) instead of one per pixel: an
        // executed atomic is a locked instruction per lane on lavapipe.
        uvec4 words = ids >> 5u;
        for (uint k = 0u; k < (TILE_LIST == 2u ? 0u : N); ++k) {
            uint bits = 0u;
            bool first_of_word = ids[k] != NO_SPHERE;
            for (uint i = 0u; i < N; ++i) {
                bool same = ids[i] != NO_SPHERE && words[i] == words[k];
                bits |= same ? 1u << (ids[i] & 31u) : 0u;
                first_of_word = first_of_word && !(same && i < k);
            }
            if (first_of_word) atomicOr(flags[words[k]], bits);
        }
    }
    tap_depth[out_index] = dw;
    Surface s;
    if (TILE_LIST == 2u || !found || !surface_of(rep, s)) {
        records[out_index] = uvec4(floatBitsToUint(RECORD_BACKGROUND), 0u, 0u, 0u);
        return;
    }
    r.covered = true;
    r.z = view_z(g.cam, s.p, PERSP);
    r.n = s.n;
    if (g.counts.w != 0u) {
        // No hierarchy: every sphere is its own region.
        r.region_a = region_hash(batch_index(s.batch, s.id));
        r.region_b = r.region_a;
    } else {
        r.region_a = region_hash(batch_region(s.batch, s.id, pc.level_a));
        r.region_b = region_hash(batch_region(s.batch, s.id, pc.level_b));
    }
    r.visibility = key_visibility(s, pixel);
    vec3 l_key = -normalize(g.light_dir.xyz);
    r.radiance = surface_albedo(s) * max(dot(s.n, l_key), 0.0) * r.visibility;
    records[out_index] = pack_record(r);
}
