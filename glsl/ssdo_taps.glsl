// The SSDO tap helpers shared by the per-pixel/per-block receivers
// (ssdo.comp) and the per-sphere ones (ssdo_sphere.comp). Needs, before
// inclusion: `Globals g`, `recordTex`, `visWordTex`, scene.glsl (with
// SCENE_ATTRIBUTES), push constants `pc`
// (SsdoPush), the specialization constants SEMANTIC and PERSP, and
// ssdo_record.glsl. With TAP_DEPTH_BLOCKED defined the taps read the depth
// words from `tapDepthTex` (ssdo_prep.comp's block-ordered copy) instead.
#ifndef SSDO_TAPS_GLSL
#define SSDO_TAPS_GLSL

Record record_at(uvec2 b) { return unpack_record(texelFetch(recordTex, int(b.y * g.counts.y + b.x))); }

// The region hashes of sphere id (batch record b: scene_batch_of) at the
// two active levels; without a hierarchy every sphere is its own region.
uvec2 regions_of(uvec4 b, uint id) {
    if (g.counts.w != 0u) return uvec2(region_hash(batch_index(b, id)));
    return uvec2(region_hash(batch_region(b, id, pc.level_a)), region_hash(batch_region(b, id, pc.level_b)));
}

// Occluder weight of a surface with regions (qa, qb) for a receiver (ra, rb).
float region_weight(uint ra, uint rb, Record q) {
    if (!SEMANTIC) return 1.0;
    float da = ra != q.region_a ? 1.0 : 0.0;
    float db = rb != q.region_b ? 1.0 : 0.0;
    return mix(da, db, pc.blend);
}

// Tap space: view coordinates (right, up, depth from the centre plane)
// for orthographic cameras, world coordinates for perspective ones.
vec3 to_space(vec3 p) {
    if (PERSP) return p;
    vec3 q = p - g.cam.center.xyz;
    return vec3(dot(q, g.cam.right.xyz), dot(q, g.cam.up.xyz), dot(q, g.cam.dir.xyz));
}
vec3 dir_to_space(vec3 d) {
    if (PERSP) return d;
    return vec3(dot(d, g.cam.right.xyz), dot(d, g.cam.up.xyz), dot(d, g.cam.dir.xyz));
}
// Distance from the viewer, comparable with the occluder's.
float depth_of(vec3 s) { return PERSP ? view_z(g.cam, s, true) : s.z; }

// The surface seen at tap-space point s: its pixel, view distance and
// tap-space position, exactly from the pixel's depth key (one 4-byte
// fetch; the block's record is fetched only for occluders). Straight-line
// code: the fetch always happens (at a clamped pixel) and `valid` says
// whether it counts (on screen, not background), so the march has no
// branches for lavapipe to run both sides of.
bool surface_seen(vec3 s, out uvec2 q, out float qz, out vec3 qp) {
    uint w = g.cam.dims.x, h = g.cam.dims.y;
    float ppu = g.cam.center.w, iw = g.cam.right.w, ih = g.cam.up.w;
    vec2 org = vec2(g.cam.dims.zw);
    // (image coordinates, then the window's)
    vec2 px = (PERSP ? round(project_px(g.cam, s, true))
                     : round(vec2(s.x * ppu + 0.5 * iw - 0.5, 0.5 * ih - s.y * ppu - 0.5))) - org;
    bool inside = px.x >= 0.0 && px.y >= 0.0 && px.x < float(w) && px.y < float(h);
    q = uvec2(clamp(px, vec2(0.0), vec2(float(w) - 1.0, float(h) - 1.0)));
#ifdef TAP_DEPTH_BLOCKED
    // ssdo_prep.comp's copy, four words per 2x2 block (SSDO_BLOCK = 2)
    uint j = 4u * ((q.y >> 1u) * g.counts.y + (q.x >> 1u)) + 2u * (q.y & 1u) + (q.x & 1u);
    uint depth_bits = texelFetch(tapDepthTex, int(j)).x;
#else
    uint j = q.y * w + q.x;
    uint depth_bits = texelFetch(visWordTex, int(2u * j + 1u)).x;
#endif
    vec2 pc2 = vec2(q) + org;
    qz = key_view_z(g.cam, pc2, uintBitsToFloat(depth_bits), PERSP);
    qp = PERSP ? point_at(g.cam, pc2, qz, true)
               : vec3((pc2.x + 0.5 - 0.5 * iw) / ppu, (0.5 * ih - 0.5 - pc2.y) / ppu, qz);
    return inside && depth_bits != 0xFFFFFFFFu;
}

float dist2(vec3 a, vec3 b) { vec3 d = a - b; return dot(d, d); }
#endif
