#version 460
// Levels of detail and culling of an instanced scene, per view in two
// phases (the list filled: VIEW early, 2 + VIEW late; 0 camera, 1 key
// light):
//   early (MODE CULL_EARLY, one invocation per instance, and one per
//     further chunk of CULL_CHUNK_BATCHES batches of a large one: lavapipe
//     ends a shader invocation's loops after 65,535 back-edges; every
//     invocation tests its chunk, and its instance, alike): the camera's
//     chooses the instance's level from its size on screen (the coarsest
//     whose switch size it is within, src/scene/instanced/lod.rs) and
//     keeps it for the other phases, so every view draws the same
//     (instance, atom) slots and the ISSM's self-shadow test stays exact;
//     that level's bounds (sphere and box), placed with the instance's
//     transform, are tested against the view's window (the camera's pixel
//     window: the frustum, and a tile's window when tiling; the key
//     light's: only the light texels a visible point's lookup may read,
//     the rectangle of the camera's visible points, lod_bounds.comp, grown
//     by the farthest the technique's lookup reads, pc.reach: the others
//     cannot shadow anything the camera sees; it runs after the camera's
//     raster). An instance in the window that passed the occlusion test
//     last frame and that last frame's final depth tiles (`hizPrevTex`)
//     do not hide whole has each batch of its level (64 atoms in a
//     spatial run: a protein at full detail is ~26 spheres deep on its
//     own) tested by its bounding sphere, the same way: listed if those
//     tiles do not hide it, else deferred. The other instances in the
//     window are deferred whole.
//   late (after the early list was rasterized and this frame's depth
//     tiles built, lod_hiz.comp): what the early phase deferred is tested
//     against the early image: a deferred batch on its own
//     (CULL_DEFERRED_BATCHES, one invocation each), a deferred instance
//     (CULL_DEFERRED_INSTANCES: a chunk, or its rest) whole and then each
//     of its batches not listed early; what is not hidden is listed. An
//     instance or batch whose nearest point is farther than the farthest
//     depth of every pixel tile its rectangle touches is hidden (two-phase
//     occlusion culling, as niagara and Mol* do it: exact, what it drops
//     could not win a pixel); the instances' results are the next frame's
//     history. The early tests place the bounds in the view those last
//     tiles were made in (pc.prev): a view moved a little lists early what
//     last frame's image showed, and the late phase tests the rest against
//     this frame's (after a large move the host empties the tiles:
//     nothing hidden, and the camera's history names only the front
//     instances, lod_front.comp); after a small move the camera's early
//     phase reads which instances the last final image showed
//     (pc.history).
// What is visible in the final image is drawn in one phase or the other:
// exact, whatever the last frame was (a camera that moved only moves work
// to the late phase). Where the deferral buffer is full, the instance is
// deferred from the batch that did not fit on, and the late phase tests
// the rest of it as before, recomputing the early tests.
// A kept batch is appended to the view's list, which the rasterizer visits
// instead of the view order (dispatched indirectly, lod_args.comp). The
// four lists lie in one buffer, list v from entry v * (pc.capacity +
// LOD_LIST_TAIL): in a frame that draws them, a sphere's id is its slot in
// that buffer (scene.glsl's batchTex is the lists). Entries past a count
// name the empty batch (the host fills them).
#include "raster_common.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform GlobalsBlock { Globals g; };
// (the levels and the instances' molecule types: scene.glsl's levelTex
// and instanceRowTex)
// Per molecule type and level (< MAX_LOD_LEVELS), in the molecule's frame
// (src/passes/scene.rs `lod_bounds`): the bounding sphere of the level's
// spheres, then its box's half-extents.
layout(set = 0, binding = 2) uniform samplerBuffer lodBoundTex;
// Per instance: the level the camera chose.
layout(set = 0, binding = 4) buffer Levels { uint levels[]; };
layout(set = 0, binding = 5) buffer List { uvec2 list[]; };
layout(set = 0, binding = 6) buffer Counters { uint counters[]; };
// Per instance and view (2k + view), two arrays (pc.parity picks): last
// frame's (read) and this frame's (written: an instance's chunks run side
// by side and all read last frame's). VISIBLE_PASSED: it passed the
// occlusion test (early: listed; late: not hidden); VISIBLE_SHOWN (the
// camera's, a moved one's frames, glsl/lod_shown.comp): the final image
// shows it. pc.history says which the early phase reads.
layout(set = 0, binding = 7) buffer Visible { uint visible[]; };
// The view's farthest depth word per fine tile, then per coarse one,
// then per super one (lod_hiz.comp; fine tiles of 2^pc.hiz_shift pixels,
// 8x8 of each level the next's).
layout(set = 0, binding = 8) uniform usamplerBuffer hizTex;
// The same of the view's last final image (the history the early phases
// test batches against).
layout(set = 0, binding = 10) uniform usamplerBuffer hizPrevTex;
// Per batch of each (molecule type, level): its bounding sphere in the
// molecule's frame (the level's first: lodBoundTex's box w).
layout(set = 0, binding = 11) uniform samplerBuffer batchBoundTex;
// The light texels of the camera's visible points (lod_bounds.comp).
layout(set = 0, binding = 9) readonly buffer Region { int region[]; };
// The instances in the order invocations take them (by molecule type:
// alike batch loops side by side), then pc.chunks pairs (instance, first
// batch) for the further chunks of instances of more than
// CULL_CHUNK_BATCHES level-0 batches (src/passes/scene.rs `cull_chunks`).
layout(set = 0, binding = 12) uniform usamplerBuffer cullOrderTex;
// What a view's early phase leaves to its late one: per early invocation
// (first pc.instances + pc.chunks entries) the instance and the batch its
// late test starts from (to the end of that batch's chunk), then
// (pc.deferred entries) batches as the lists hold them.
layout(set = 0, binding = 13) buffer Deferred { uvec2 deferred[]; };
#include "scene.glsl"
#include "push/lod_cull.glsl"

layout(constant_id = 1) const bool PERSP = false;
// The pass: CULL_EARLY (over every instance, in the cull order),
// CULL_DEFERRED_INSTANCES or CULL_DEFERRED_BATCHES (the late phase, over
// what the early one deferred).
layout(constant_id = 2) const uint MODE = CULL_EARLY;
// The view (0 camera, 1 key light): lavapipe runs both sides of a branch
// on data, so the light's pipeline has no level choice and the camera's
// no light-region test.
layout(constant_id = 3) const uint VIEW = 0u;

// Whether every pixel an instance or batch (bounds centred at view
// coordinates cv: sphere radius r, box half-extent ez along the view)
// could cover already holds a surface nearer than its nearest point: its
// rectangle's tiles of this frame's early image (`prev`: of the last final
// image), fine ones (2^pc.hiz_shift pixels) while they are few, else
// coarse or super ones. (A bool, not the sampler as a parameter: one
// function.)
bool hidden(bool prev, View v, vec3 cv, float r, float ez, ivec4 rc, bool persp) {
    // (less a margin for the f32 rounding of the atoms' keys: a grazing
    // ray's perspective key may lose ~|cv| * 3e-4 to cancellation; the
    // distance from the eye is at least the depth along the view)
    float margin = 1e-4 * (abs(cv.z) + abs(v.depth.x) + r) + 1e-3;
    float zmin = persp ? max(length(cv) - r, cv.z - ez) - 1e-3 * (length(cv) + r)
                       : cv.z - ez + v.depth.x - margin;
    uint near = floatBitsToUint(max(zmin, 0.0));
    ivec2 o = ivec2(v.dims.zw);
    ivec4 b = rc - ivec4(o, o); // window pixels
    int S = int(pc.hiz_shift);
    uvec2 tf = (v.dims.xy + (1u << S) - 1u) >> S;
    // The finest level (fine, coarse: 8x8 fine, super: 8x8 coarse) whose
    // tiles under the rectangle are fewer than 8x8: this function's loops
    // stay within 8 x 8 + 8 back-edges (lavapipe's limit,
    // CULL_CHUNK_BATCHES); past 8x8 super tiles, not hidden.
    int lv = 0;
    while (lv < 3 && ((b.z >> (S + 3 * lv)) - (b.x >> (S + 3 * lv)) >= 8
                      || (b.w >> (S + 3 * lv)) - (b.y >> (S + 3 * lv)) >= 8)) {
        ++lv;
    }
    if (lv == 3) return false;
    int sh = S + 3 * lv;
    uvec2 tc = (v.dims.xy + (8u << S) - 1u) >> (S + 3);
    uint base = lv == 0 ? 0u : (lv == 1 ? tf.x * tf.y : tf.x * tf.y + tc.x * tc.y);
    uint tw = (v.dims.x + (1u << sh) - 1u) >> sh;
    // The key light (orthographic, a texel wider than an atom): per
    // tile, the nearest depth of the bounds over the texel centres the
    // tile holds (the sphere's front at their least distance from its
    // axis, never nearer than the box), and a tile the disc misses hides
    // it unless empty (an empty texel's word is all ones). One-texel
    // tiles at an atom's scale: meso 10^9 at 2,025 A, the light's spheres
    // 9.42 -> 8.35 M and issm_raster 140 -> 92 ms for light_cull +11 ms.
    // (The camera's 4-px tiles gained 3 % of its spheres for more cull
    // time than that saved.)
    float ppu = v.center.w;
    // (a texel centre's offset from the centre, in texels: x + c.x, -(y + c.y);
    // the radius grown past the rasterizer's f32 disc test)
    vec2 c = vec2(0.5 - 0.5 * v.right.w - cv.x * ppu, 0.5 - 0.5 * v.up.w + cv.y * ppu);
    float rp = r * ppu * (1.0 + 1e-4) + 1e-3;
    for (int y = b.y >> sh; y <= (b.w >> sh); ++y) {
        for (int x = b.x >> sh; x <= (b.z >> sh); ++x) {
            // (clamped: the last image's tiles may be of another size)
            int at = min(int(base + uint(y) * tw + uint(x)), textureSize(hizTex) - 1);
            uint word = prev ? texelFetch(hizPrevTex, at).x : texelFetch(hizTex, at).x;
            uint near_t = near;
            if (VIEW == 1u) {
                // the tile's texel centres, in texels from the centre
                vec2 lo = vec2(ivec2(max(x << sh, b.x), max(y << sh, b.y)) + o) + c;
                vec2 hi = vec2(ivec2(min(((x + 1) << sh) - 1, b.z), min(((y + 1) << sh) - 1, b.w)) + o) + c;
                vec2 d = max(max(lo, -hi), vec2(0.0));
                float h2 = rp * rp - dot(d, d);
                float zt = cv.z - min(ez, sqrt(max(h2, 0.0)) / ppu) + v.depth.x - margin;
                near_t = h2 < 0.0 ? 0xFFFFFFFFu : floatBitsToUint(max(zt, 0.0)); // (above every word)
            }
            if (word >= near_t) return false;
        }
    }
    return true;
}

// Whether a rectangle of window pixels holds any, and for a light view
// (!cam) whether it meets the texels a visible point's lookup reads: the
// others cannot shadow anything the camera sees.
// (grown one texel more: a lookup's centre texel is kept one inside the
// map, which may move it out of the points' rectangle)
bool over_region(bool cam, ivec4 rc) {
    bool some = rc.x <= rc.z && rc.y <= rc.w;
    int e = pc.reach + 1;
    return cam ? some
               : some && rc.z >= region[0] - e && rc.x <= region[2] + e
                      && rc.w >= region[1] - e && rc.y <= region[3] + e;
}

// A batch's bounding sphere placed with instance k (radius times the
// transform's largest stretch, grown for the rounding of the placed
// centre) in view coordinates, and its rectangle.
void place_batch(View v, bool persp, uint k, uint at, float stretch, float grow,
                 out vec3 bv, out float br, out ivec4 rc) {
    vec4 bb = texelFetch(batchBoundTex, int(at));
    br = bb.w * stretch * 1.001 + grow;
    bv = view_space(v, instance_apply(k, bb.xyz), persp);
    rc = sphere_rect(v, bv, br, persp);
}

// An instance's level bounds (sphere radius r, centred at view
// coordinates cv; the box's turned half-axes ax) in view v: the box's
// half-extent along the view ez (its half-axes' projections on the view's
// axes, grown by slack for the rounding of that difference, never past
// the sphere) and the window rectangle.
void place_bounds(View v, bool persp, vec3 cv, mat3 ax, float r, float slack,
                  out float ez, out ivec4 rc) {
    mat3 axes = transpose(mat3(v.right.xyz, v.up.xyz, v.dir.xyz));
    vec3 ext = min(abs(axes * ax[0]) + abs(axes * ax[1]) + abs(axes * ax[2]) + slack, vec3(r));
    ez = ext.z;
    rc = persp ? sphere_rect(v, cv, r, true)
               : plane_rect(v, cv.x + vec2(-ext.x, ext.x), cv.y + vec2(-ext.y, ext.y));
}

// A batch sphere's radius placed with instance k (p: its molecule's
// centre c placed) is times the transform's largest stretch: 1 for a
// rigid one; an affine one's bounded by Gershgorin's circles of A^T A,
// its columns taken from unit offsets.
float instance_stretch(uint k, vec3 c, vec3 p) {
    if (SCENE_KIND != SCENE_AFFINE) return 1.0;
    mat3 a = mat3(instance_apply(k, c + vec3(1.0, 0.0, 0.0)) - p,
                  instance_apply(k, c + vec3(0.0, 1.0, 0.0)) - p,
                  instance_apply(k, c + vec3(0.0, 0.0, 1.0)) - p);
    mat3 ata = transpose(a) * a;
    float row = 0.0;
    for (int i = 0; i < 3; ++i) {
        row = max(row, abs(ata[i].x) + abs(ata[i].y) + abs(ata[i].z));
    }
    // (never below 1: the atoms' radii are not scaled)
    return max(sqrt(row), 1.0) * 1.001;
}

// How much a batch sphere placed with an instance at p grows for the
// rounding of its placed centre.
float batch_grow(vec3 p) { return 1e-6 * coord_max(p) + 1e-4; }

// Appends batch entry e to list li (an atomicAdd each: a count first and
// the entries in a second loop would need both loops to agree, lane by
// lane; past the capacity it is only counted).
void list_batch(uint li, uvec2 e) {
    uint at = atomicAdd(counters[li * LOD_WORDS + LOD_BATCHES], 1u);
    if (at < pc.capacity) list[li * (pc.capacity + LOD_LIST_TAIL) + at] = e;
}

// Atoms of batch j of a level of `atoms` atoms.
uint batch_atoms(uint atoms, uint j) { return min(atoms - (j << BATCH_SHIFT), 1u << BATCH_SHIFT); }

void main() {
    uint view = VIEW;
    bool cam = VIEW == 0u;
    View v = cam ? g.cam : g.light;
    bool persp = PERSP && cam;
    // (the early list's counter words hold what it deferred)
    uint dw = view * LOD_WORDS;
    uint late_list = 2u + view;
    uint batch_room = pc.instances + pc.chunks;
    if (MODE == CULL_DEFERRED_BATCHES) {
        // One batch the early phase found hidden behind last frame's
        // image (and in the window): listed late if this frame's early
        // image does not hide it.
        if (FLAT_ID >= min(counters[dw + LOD_DEFER_BATCHES], pc.deferred)) return;
        uvec2 e = deferred[batch_room + FLAT_ID];
        uint k = e.x & BATCH_INSTANCE_MASK, level = e.x >> BATCH_INSTANCE_BITS;
        uint m = texelFetch(instanceRowTex, int(k)).x;
        uint base = m * MAX_LOD_LEVELS;
        vec3 c = texelFetch(lodBoundTex, int(2u * base)).xyz;
        vec3 p = instance_apply(k, c);
        float stretch = instance_stretch(k, c, p);
        uint first = uint(texelFetch(lodBoundTex, int(2u * (base + level) + 1u)).w);
        vec3 bv;
        float br;
        ivec4 rc;
        place_batch(v, persp, k, first + e.y, stretch, batch_grow(p), bv, br, rc);
        if (hidden(false, v, bv, br, br, rc, persp)) return;
        list_batch(late_list, e);
        uint atoms = texelFetch(levelTex, int(base + level)).w;
        atomicAdd(counters[late_list * LOD_WORDS + LOD_SPHERES], batch_atoms(atoms, e.y));
        return;
    }
    uint k, from = 0u;
    if (MODE == CULL_EARLY) {
        if (FLAT_ID >= pc.instances + pc.chunks) return;
        // The cull order runs along a Morton curve within each molecule
        // type (x, y, z bits weighing 1, 2, 4): walked backwards where the
        // view looks down it, the lists run near to far, and the
        // rasterizers' early-depth test turns more visits away before
        // their atomics (meso 10^9 at 2,025 A: camera raster 695 ms the
        // wrong way, 584 this way).
        bool backwards = dot(v.dir.xyz, vec3(1.0, 2.0, 4.0)) < 0.0;
        k = texelFetch(cullOrderTex, int(backwards ? pc.instances - 1u - FLAT_ID : FLAT_ID)).x;
        if (FLAT_ID >= pc.instances) {
            // an instance's further chunk
            int at = int(pc.instances + 2u * (FLAT_ID - pc.instances));
            k = texelFetch(cullOrderTex, at).x;
            from = texelFetch(cullOrderTex, at + 1).x;
        }
    } else {
        if (FLAT_ID >= counters[dw + LOD_DEFER_INSTANCES]) return;
        uvec2 e = deferred[FLAT_ID];
        k = e.x;
        from = e.y;
    }
    bool late = MODE != CULL_EARLY;
    uint m = texelFetch(instanceRowTex, int(k)).x;
    uint base = m * MAX_LOD_LEVELS;
    // (level 0's sphere: the molecule's size, what the level is chosen by)
    vec4 bs = texelFetch(lodBoundTex, int(2u * base));
    vec3 p = instance_apply(k, bs.xyz);
    vec3 cv = view_space(v, p, persp);
    uint level;
    if (cam) {
        // pixels per world unit at the instance's nearest point
        float ppu = v.center.w;
        if (PERSP) {
            float z = cv.z - bs.w;
            ppu = z > 0.0 ? ppu * v.dir.w / z : 1e30;
        }
        // The coarsest level whose switch size the instance is within; a
        // coarser one than last frame's only below its switch size by the
        // band LOD_BAND, so a level never flickers at its switch (no
        // popping while a viewer zooms). Never above a switch size: the
        // silhouette guarantee holds at every size a level is drawn at.
        uint n = texelFetch(levelTex, int(base)).x & LEVEL_COUNT_MASK;
        uint prev = levels[k];
        level = 0u;
        uint banded = 0u;
        for (uint l = 1u; l < n; ++l) {
            float sw = uintBitsToFloat(texelFetch(levelTex, int(base + l)).z);
            if (ppu <= sw) level = l;
            if (ppu * LOD_BAND <= sw) banded = l;
        }
        if (prev != NO_LEVEL_YET && prev <= level) level = max(prev, banded);
        levels[k] = level;
    } else {
        // (A light level of its own for what the image does not show,
        // which only casts, was tried: 2,025 A -13 ms, 506 A -47 ms, but
        // coarse casters above the view's edge shadowed darker than the
        // same proteins' fine atoms in the view: shadows changed as a
        // caster entered the screen.)
        level = levels[k];
    }
    // This invocation's batches: from `from` to the end of its chunk
    // (none: a further chunk of a coarse level's fewer batches).
    uint atoms = texelFetch(levelTex, int(base + level)).w;
    uint batches = (atoms + BATCH_MASK) >> BATCH_SHIFT;
    uint end = min(batches, (from / CULL_CHUNK_BATCHES + 1u) * CULL_CHUNK_BATCHES);
    if (from >= end) return;
    // The level's bounds (same centre).
    float r = texelFetch(lodBoundTex, int(2u * (base + level))).w;
    vec3 be = texelFetch(lodBoundTex, int(2u * (base + level) + 1u)).xyz;
    // The box's turned half-axes (the transform applied to the box's
    // face centres, so an affine instance's too).
    mat3 ax = mat3(instance_apply(k, bs.xyz + vec3(be.x, 0.0, 0.0)) - p,
                   instance_apply(k, bs.xyz + vec3(0.0, be.y, 0.0)) - p,
                   instance_apply(k, bs.xyz + vec3(0.0, 0.0, be.z)) - p);
    float slack = 1e-3 * r + 1e-6 * coord_max(p);
    float ez;
    ivec4 rc;
    place_bounds(v, persp, cv, ax, r, slack, ez, rc);
    // (the same in the view last frame's final tiles were made in: the
    // early test asks whether last frame's image hid it, wherever the
    // view is now)
    vec3 cvp = view_space(pc.prev, p, persp);
    float ezp;
    ivec4 rcp;
    place_bounds(pc.prev, persp, cvp, ax, r, slack, ezp, rcp);
    // (a light view: only what can shadow a point the camera sees)
    bool inside = over_region(cam, rc);
    uint h = 2u * k + view;
    uint last_at = pc.parity * 2u * pc.instances + h;
    uint now_at = (1u - pc.parity) * 2u * pc.instances + h;
    // (the early phase's candidates: the instances seen last frame that
    // the last final image does not hide whole; the late phase recomputes
    // the same test on the same tiles)
    bool listed_early = inside && (visible[last_at] & pc.history) != 0u
                        && !hidden(true, pc.prev, cvp, r, ezp, rcp, persp);
    if (late) {
        bool seen = inside && !hidden(false, v, cv, r, ez, rc, persp);
        visible[now_at] = seen ? VISIBLE_PASSED : 0u;
        if (!seen) return;
    } else if (!listed_early) {
        // (outside: not seen; inside: the late phase tests it whole)
        if (!inside) {
            visible[now_at] = 0u;
        } else {
            deferred[atomicAdd(counters[dw + LOD_DEFER_INSTANCES], 1u)] = uvec2(k, from);
        }
        return;
    } else {
        visible[now_at] = VISIBLE_PASSED;
    }
    uint first = uint(texelFetch(lodBoundTex, int(2u * (base + level) + 1u)).w);
    float stretch = instance_stretch(k, bs.xyz, p);
    float grow = batch_grow(p);
    uint li = late ? late_list : view;
    uint word = k | (level << BATCH_INSTANCE_BITS);
    uint spheres = 0u;
    // (early: the first batch the deferral buffer had no room for; the
    // late phase tests it and the rest as a deferred instance)
    uint full = end;
    for (uint j = from; j < end; ++j) {
        vec3 bv;
        float br;
        ivec4 brc;
        place_batch(v, persp, k, first + j, stretch, grow, bv, br, brc);
        vec3 bvp;
        ivec4 brcp;
        place_batch(pc.prev, persp, k, first + j, stretch, grow, bvp, br, brcp);
        bool in_window = over_region(cam, brc);
        bool early = listed_early && in_window && !hidden(true, pc.prev, bvp, br, br, brcp, persp);
        bool keep = late ? !early && in_window && !hidden(false, v, bv, br, br, brc, persp)
                         : early;
        if (keep) {
            list_batch(li, uvec2(word, j));
            spheres += batch_atoms(atoms, j);
        }
        // Early: a batch in the window that last frame's image hides is
        // deferred; the late phase tests it alone against this frame's
        // early image (no instance loop recomputed).
        if (!late && in_window && !early && full == end) {
            uint at = atomicAdd(counters[dw + LOD_DEFER_BATCHES], 1u);
            if (at < pc.deferred) {
                deferred[batch_room + at] = uvec2(word, j);
            } else {
                full = j;
            }
        }
    }
    if (spheres > 0u) atomicAdd(counters[li * LOD_WORDS + LOD_SPHERES], spheres);
    if (full < end) {
        deferred[atomicAdd(counters[dw + LOD_DEFER_INSTANCES], 1u)] = uvec2(k, full);
    }
}
