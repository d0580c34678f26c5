#version 460
// Deep shadow lists, passes 1 and 3 (count and fill), one pipeline for both
// so that both enumerate exactly the same (sphere, texel) pairs:
//   mode DEEP_COUNT: atomicAdd the texel's entry count;
//   mode DEEP_FILL:  take a slot with the texel's atomic fill cursor and
//                    write the entry at head + slot (head from deep_alloc).
// Every sphere whose light-space disk overlaps a texel's square gets an entry
// there (conservative, not only texel centres, not only the nearest sphere),
// so the light ray from any point inside the texel can only cross spheres
// listed in that texel.
//
// Why count -> allocate -> fill instead of the paper's allocate-on-the-fly:
// the CUDA version lets one thread grab a chunk while the others of the tile
// busy-wait on it in a "pending" state. Vulkan gives no forward-progress
// guarantee between invocations, so a spin-wait can hang; with separate
// passes every atomic is wait-free and each texel's entries end up
// contiguous, which also makes the per-texel sort and the walk cheap.
//
// Large footprints (more than big_area texels) are cut into 8-row bands:
// the count pass appends them to a job list that whole workgroups process
// (bands = 1, dispatched indirectly), so one big sphere never serialises
// thousands of texels on one invocation. If the job list is full the sphere
// is marked in inline_bits and its own invocation loops (both modes agree).
#include "deep.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
layout(set = 0, binding = 1) readonly buffer Spheres { vec4 spheres[]; };
layout(set = 0, binding = 2) buffer Texels { DeepTexel texels[]; };
layout(set = 0, binding = 3) readonly buffer Tiles { DeepTile tiles[]; };
layout(set = 0, binding = 4) writeonly buffer Depth { float e_depth[]; };
layout(set = 0, binding = 5) writeonly buffer Alpha { float e_alpha[]; };
layout(set = 0, binding = 6) writeonly buffer Ids { uint e_id[]; };
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };
layout(set = 0, binding = 8) buffer Jobs { uvec2 jobs[]; };
layout(set = 0, binding = 9) buffer Inline { uint inline_bits[]; };

layout(push_constant) uniform Push {
    uint mode;           // DEEP_COUNT or DEEP_FILL
    uint bands;          // 0: one invocation per sphere; 1: one workgroup per band job
    uint sphere_count;
    uint big_area;       // footprints above this many texels go to band jobs
    uint job_capacity;   // entries of jobs[]
    uint entry_capacity; // entries of the list arrays (pool chunks * 64)
    float opacity;       // alpha of every entry
    uint pad;
} pc;

void visit(uint id, Footprint f, ivec2 t, uint map_w) {
    if (!deep_overlaps(f, t)) return;
    uint ti = uint(t.y) * map_w + uint(t.x);
    if (pc.mode == DEEP_COUNT) {
        atomicAdd(texels[ti].count, 1u);
        return;
    }
    // A tile that did not fit in the pool has no chunks: skip it.
    if ((tiles[deep_tile_of(t, map_w)].flags & DEEP_TILE_OVERFLOWED) != 0u) return;
    uint slot = atomicAdd(texels[ti].fill, 1u);
    uint head = texels[ti].head;
    uint addr = head + slot;
    // Never write outside the texel's run (would only happen if count and
    // fill disagreed; counted so tests see it).
    if (slot >= texels[ti].count || head == DEEP_NONE || addr >= pc.entry_capacity) {
        atomicAdd(counters[C_FILL_ERRORS], 1u);
        return;
    }
    e_depth[addr] = f.depth;
    e_alpha[addr] = pc.opacity;
    e_id[addr] = id;
}

void visit_rect(uint id, Footprint f, ivec4 rc, uint map_w) {
    for (int y = rc.y; y <= rc.w; ++y) {
        for (int x = rc.x; x <= rc.z; ++x) {
            visit(id, f, ivec2(x, y), map_w);
        }
    }
}

bool is_inline(uint id) {
    return (inline_bits[id >> 5] & (1u << (id & 31u))) != 0u;
}

void sphere_main() {
    uint id = FLAT_ID;
    if (id >= pc.sphere_count) return;
    View L = g.light;
    uint map_w = L.dims.x;
    Footprint f = deep_footprint(L, spheres[id]);
    ivec4 rc = f.rect;
    if (rc.x > rc.z || rc.y > rc.w) return;
    uint area = uint(rc.z - rc.x + 1) * uint(rc.w - rc.y + 1);
    if (area <= pc.big_area) {
        visit_rect(id, f, rc, map_w);
        return;
    }
    uint nb = uint(rc.w - rc.y) / DEEP_BAND_ROWS + 1u;
    if (pc.mode == DEEP_COUNT) {
        uint base = atomicAdd(counters[C_BANDS_REQ], nb);
        if (base < pc.job_capacity && nb <= pc.job_capacity - base) {
            for (uint b = 0u; b < nb; ++b) jobs[base + b] = uvec2(id, uint(rc.y) + b * DEEP_BAND_ROWS);
            return;
        }
        // The job list is full: void the slots we got and loop here instead.
        for (uint j = base; j < min(base + nb, pc.job_capacity); ++j) jobs[j] = uvec2(DEEP_NONE, 0u);
        atomicOr(inline_bits[id >> 5], 1u << (id & 31u));
        visit_rect(id, f, rc, map_w);
    } else if (is_inline(id)) {
        visit_rect(id, f, rc, map_w);
    }
}

void band_main() {
    uint job = gl_WorkGroupID.x + gl_WorkGroupID.y * DEEP_MAX_X;
    if (job >= counters[C_BANDS_RUN]) return;
    uvec2 jb = jobs[job];
    if (jb.x == DEEP_NONE) return;
    View L = g.light;
    uint map_w = L.dims.x;
    Footprint f = deep_footprint(L, spheres[jb.x]);
    ivec4 rc = f.rect;
    int y0 = int(jb.y);
    int rows = min(int(DEEP_BAND_ROWS), rc.w - y0 + 1);
    int width = rc.z - rc.x + 1;
    for (int i = int(gl_LocalInvocationID.x); i < width * rows; i += int(gl_WorkGroupSize.x)) {
        visit(jb.x, f, ivec2(rc.x + i % width, y0 + i / width), map_w);
    }
}

void main() {
    if (pc.bands != 0u) {
        band_main();
    } else {
        sphere_main();
    }
}
