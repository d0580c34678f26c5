// The scene's spheres by id, for every pass that reads them: plain (one
// texel per sphere, id = index) or instanced (molecule atoms stored once,
// id = slot: entry id >> BATCH_SHIFT of the batch table, atom id &
// BATCH_MASK of that entry's run of one instance's molecule), chosen by the
// specialization constant SCENE_SPEC (src/passes/scene.rs sets it for
// every pipeline of a renderer; lavapipe runs both sides of a branch on
// data, so the plain scene does not pay for the instanced path). The
// batch table is the static one (every instance's full detail, in
// expanded order, so depth ties resolve as in the expanded scene) or, in
// a frame that draws the LOD cull's lists, those lists: a slot is then a
// list position, so ids stay 32-bit however many atoms are represented.
// The batch shift is the scene's: 3 (8 slots) for molecules of a few
// beads, where 64-slot batches would leave most lanes idle, up to 6.
//
// Needs `Globals g` before inclusion (scene_region reads g.scene). Define
// SCENE_ATTRIBUTES first for colours and regions. Bindings 24-32 are the
// scene's (by name in Rust: SCENE_GEOMETRY, SCENE_ATTRIBUTES).
#ifndef SCENE_GLSL
#define SCENE_GLSL
#include "shared.glsl"

layout(constant_id = 30) const uint SCENE_SPEC = 0u; // = SCENE_KIND_ID, checked in Rust
const uint SCENE_KIND = SCENE_SPEC & 0xFFu;
const uint BATCH_SHIFT = SCENE_SPEC >> 8u;
const uint BATCH_MASK = (1u << BATCH_SHIFT) - 1u;

// Plain: centre, radius per sphere. Instanced: the molecules' atoms, each in
// its molecule's frame.
layout(set = 0, binding = 24) uniform samplerBuffer sphereTex;
// Instanced: per batch (RG32UI) its instance | level of detail <<
// BATCH_INSTANCE_BITS (or BATCH_EMPTY: no atoms), and its index among
// that level's batches; `scene_batch` makes its record from the two
// tables below.
layout(set = 0, binding = 25) uniform usamplerBuffer batchTex;
// Instanced: per instance (RG32UI) its molecule type and the expanded
// index of its first atom (its low 32 bits).
layout(set = 0, binding = 31) uniform usamplerBuffer instanceRowTex;
// Instanced: per (molecule type, level < MAX_LOD_LEVELS), RGBA32UI: level
// 0's holds the number of levels (| LEVEL_MAPPED on a nested scene's
// proxy, on every level), its first stored atom, its switch size (f32
// bits: most pixels per world unit it is drawn at), its atoms.
layout(set = 0, binding = 32) uniform usamplerBuffer levelTex;
// Instanced: 2 texels (rigid: quaternion xyzw, translation) or 3 (affine:
// the rows m_i0 m_i1 m_i2 v_i) per instance.
layout(set = 0, binding = 26) uniform samplerBuffer instanceTex;
// Instanced with levels of detail: per stored atom of a coarse level, the
// index within its molecule of the atom it stands for (what the id AOV
// names); a coarse batch's third word is its instance's first expanded
// index.
layout(set = 0, binding = 30) uniform usamplerBuffer originTex;
#ifdef SCENE_ATTRIBUTES
// Plain: 4 region words per sphere (R32UI). Instanced: the atom's chain
// within its molecule.
layout(set = 0, binding = 27) uniform usamplerBuffer attrTex;
// RGBA8 per sphere (plain) or atom (instanced).
layout(set = 0, binding = 28) uniform usamplerBuffer colorTex;
// Instanced: 4 region words per molecule type (its tree levels).
layout(set = 0, binding = 29) uniform usamplerBuffer moleculeTex;
#endif

bool scene_instanced() { return SCENE_KIND != SCENE_PLAIN; }

// The record of sphere id's batch: its instance, first stored atom, the
// expanded index of that atom (a coarse batch: of its instance's first;
// low 32 bits), atom count | molecule type << 8 | BATCH_COARSE (zeros for
// the empty batch). src/passes/scene.rs `BatchTables::record` is the same.
uvec4 scene_batch(uint id) {
    uvec2 e = texelFetch(batchTex, int(id >> BATCH_SHIFT)).xy;
    uint k = e.x & BATCH_INSTANCE_MASK, l = min(e.x >> BATCH_INSTANCE_BITS, MAX_LOD_LEVELS - 1u);
    uvec2 row = texelFetch(instanceRowTex, int(k)).xy;
    uvec4 lv = texelFetch(levelTex, int(row.x * MAX_LOD_LEVELS + l));
    bool coarse = l != 0u || (lv.x & LEVEL_MAPPED) != 0u;
    uint a = e.y << BATCH_SHIFT;
    uvec4 r = uvec4(k, lv.y + a, row.y + (coarse ? 0u : a),
                    min(lv.w - a, 1u << BATCH_SHIFT) | (row.x << 8) | (coarse ? BATCH_COARSE : 0u));
    return e.x == BATCH_EMPTY ? uvec4(0u) : r;
}
uint scene_lane(uint id) { return id & BATCH_MASK; }

// Instance k's transform applied to a point of its molecule: the
// operations of src/scene/instanced.rs (apply_rigid, apply_affine) in the
// same order, each rounded to f32 (`precise`: no fused multiply-add), so
// an instanced render and the render of its expanded spheres are the same
// bits.
vec3 instance_apply(uint k, vec3 x) {
    if (SCENE_KIND == SCENE_AFFINE) {
        vec4 r0 = texelFetch(instanceTex, int(3u * k));
        vec4 r1 = texelFetch(instanceTex, int(3u * k + 1u));
        vec4 r2 = texelFetch(instanceTex, int(3u * k + 2u));
        precise float px = ((r0.x * x.x + r0.y * x.y) + r0.z * x.z) + r0.w;
        precise float py = ((r1.x * x.x + r1.y * x.y) + r1.z * x.z) + r1.w;
        precise float pz = ((r2.x * x.x + r2.y * x.y) + r2.z * x.z) + r2.w;
        return vec3(px, py, pz);
    }
    vec4 q = texelFetch(instanceTex, int(2u * k));
    vec4 t = texelFetch(instanceTex, int(2u * k + 1u));
    precise vec3 c = vec3(q.y * x.z - q.z * x.y, q.z * x.x - q.x * x.z, q.x * x.y - q.y * x.x);
    precise vec3 u = 2.0 * c;
    precise vec3 d = vec3(q.y * u.z - q.z * u.y, q.z * u.x - q.x * u.z, q.x * u.y - q.y * u.x);
    precise vec3 p = ((x + q.w * u) + d) + t.xyz;
    return p;
}

// Instance k's transform without its translation, applied to a vector:
// its linear map (the batch rasterizers project atoms by it). Not the
// difference of two placed points: far from the origin (the 10^12 scene's
// 10^5 A) that loses ~10^-2 of a unit axis, times a proxy molecule's
// hundreds of A.
vec3 instance_linear(uint k, vec3 x) {
    if (SCENE_KIND == SCENE_AFFINE) {
        vec4 r0 = texelFetch(instanceTex, int(3u * k));
        vec4 r1 = texelFetch(instanceTex, int(3u * k + 1u));
        vec4 r2 = texelFetch(instanceTex, int(3u * k + 2u));
        precise vec3 y = vec3(dot(r0.xyz, x), dot(r1.xyz, x), dot(r2.xyz, x));
        return y;
    }
    // (`precise`: pipelines that must agree compute it alike)
    vec4 q = texelFetch(instanceTex, int(2u * k));
    precise vec3 u = 2.0 * cross(q.xyz, x);
    precise vec3 y = x + q.w * u + cross(q.xyz, u);
    return y;
}

// A point's largest coordinate: the f32 rounding of a placed point is
// ~1e-7 of it (the cull's and the light raster's margins).
float coord_max(vec3 p) { return max(max(abs(p.x), abs(p.y)), abs(p.z)); }

// The batch record of sphere `id` for the `batch_*` readers below (plain:
// none): a pass that reads several things of one sphere makes it once
// (its three dependent fetches cost meso 10^9 at 2,025 A ~10 ms of SSDO
// per extra reader).
uvec4 scene_batch_of(uint id) { return scene_instanced() ? scene_batch(id) : uvec4(0u); }

// Centre (world) and radius of sphere `id`; a radius below 0 means no
// sphere (a slot past its batch's atoms).
vec4 batch_sphere(uvec4 b, uint id) {
    if (!scene_instanced()) return texelFetch(sphereTex, int(id));
    uint lane = scene_lane(id), count = b.w & 0xFFu;
    // (a slot past the batch's atoms reads its last atom: no fetch past
    // the molecule table's end; the LOD lists' empty batch has none)
    vec4 a = texelFetch(sphereTex, int(b.y + min(lane, max(count, 1u) - 1u)));
    return vec4(instance_apply(b.x, a.xyz), lane < count ? a.w : -1.0);
}
vec4 scene_sphere(uint id) { return batch_sphere(scene_batch_of(id), id); }

// The index of sphere `id` in input (expanded) order: what the id AOV
// names, and what per-sphere noise is seeded with.
uint batch_index(uvec4 b, uint id) {
    if (!scene_instanced()) return id;
    uint lane = scene_lane(id);
    return b.z + ((b.w & BATCH_COARSE) != 0u ? texelFetch(originTex, int(b.y + lane)).x : lane);
}
uint scene_index(uint id) { return batch_index(scene_batch_of(id), id); }

#ifdef SCENE_ATTRIBUTES
// The sphere's colour word (RGBA8).
uint batch_color(uvec4 b, uint id) {
    if (!scene_instanced()) return texelFetch(colorTex, int(id)).x;
    return texelFetch(colorTex, int(b.y + scene_lane(id))).x;
}
uint scene_color(uint id) { return batch_color(scene_batch_of(id), id); }

// The sphere's alpha (1 opaque): its colour's A byte times the frame's
// opacity (--opacity, Globals.alpha.x).
float batch_alpha(uvec4 b, uint id) {
    return float(batch_color(b, id) >> 24u) / 255.0 * g.alpha.x;
}
float scene_alpha(uint id) { return batch_alpha(scene_batch_of(id), id); }

// Region id of sphere `id` at hierarchy `level`: plain, from its 4 words
// (one 4-byte gather: a 16-byte texel and a dynamic pick of one word cost
// ssdo_prep ~4 ms of its ~28 on the 1M capsid at 1080p on lavapipe).
// Instanced: the tree levels' from the molecule table, the instance at
// the molecule level, instance * stride + chain at the chain level (as
// src/scene/instanced.rs `Instancing::regions`).
uint batch_region(uvec4 b, uint id, uint level) {
    if (!scene_instanced()) return texelFetch(attrTex, int(4u * id + level)).x;
    uint tree = texelFetch(moleculeTex, int(4u * ((b.w >> 8) & BATCH_TYPE_MASK) + min(level, 3u))).x;
    uint chain = texelFetch(attrTex, int(b.y + scene_lane(id))).x;
    return level < g.scene.x ? tree : (level == g.scene.z ? b.x : b.x * g.scene.y + chain);
}
uint scene_region(uint id, uint level) { return batch_region(scene_batch_of(id), id, level); }
#endif
#endif
