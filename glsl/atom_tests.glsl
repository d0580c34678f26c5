// The per-batch rasters' atom tests (glsl/raster.comp CAM_BATCHES and
// LIGHT_BATCHES, glsl/oit_splat.comp BATCHES): an instance's placement as
// a linear map into a view's pixels, an atom's disc, rectangle and nearest
// depth key through it, and whether depth tiles hide a rectangle. Before
// inclusion: scene.glsl, push constants pc.hiz_shift and pc.micro_base,
// TILE_WORD(prev, i) / TILE_TEXELS(prev), the depth word of tile texel i
// and the texels of the tiles (`prev`: last frame's final ones), and the
// camera's PERSP specialization constant (cam_map, cam_rect).
#ifndef ATOM_TESTS_GLSL
#define ATOM_TESTS_GLSL

// Whether the tiles under window rectangle rc all hold surfaces nearer
// than depth word `near` (last frame's with `prev`): 2x2 tiles of 2 px at
// most (from word pc.micro_base; 0: none), else 2x2 fine tiles (2^pc.hiz_shift
// pixels), else 2x2 coarse ones (8x8 fine), else not hidden. (A bool, not
// the sampler: one function.)
bool tiles_hide(bool prev, View v, ivec4 rc, uint near) {
    ivec2 lo = ivec2(v.dims.zw);
    ivec4 r = rc - ivec4(lo, lo);
    int S = int(pc.hiz_shift);
    ivec4 m = r >> 1, t = r >> S;
    bool micro = pc.micro_base != 0u && m.z - m.x <= 1 && m.w - m.y <= 1;
    bool fine = t.z - t.x <= 1 && t.w - t.y <= 1;
    uint T = 1u << S;
    int base = micro ? int(pc.micro_base)
                     : fine ? 0 : int(((v.dims.x + T - 1u) >> S) * ((v.dims.y + T - 1u) >> S));
    int sh = micro ? 1 : fine ? S : S + 3;
    t = r >> sh;
    if (t.z - t.x > 1 || t.w - t.y > 1) return false;
    int tw = int((v.dims.x + (1u << sh) - 1u) >> sh);
    int last = TILE_TEXELS(prev) - 1;
    ivec4 at = min(base + ivec4(t.y * tw + t.x, t.y * tw + t.z, t.w * tw + t.x, t.w * tw + t.z), last);
    uvec4 w = uvec4(TILE_WORD(prev, at.x), TILE_WORD(prev, at.y), TILE_WORD(prev, at.z), TILE_WORD(prev, at.w));
    return max(max(w.x, w.y), max(w.z, w.w)) < near;
}

// Instance placement p0 (its linear map's images of the axes ax) into
// view v's pixel coordinates (plane_rect's: x ppu + W/2 - 1/2, H/2 - 1/2 -
// y ppu; a pixel's centre at integer coordinates) and depth: an atom at a
// (the molecule's frame) is at o + (rx . a, ry . a), depth oz + rz . a.
// (`precise`: the camera's early and recheck pipelines must compute alike
// bits, whatever each one's contraction into fused multiply-adds; an atom
// both found hidden behind last frame's tiles would be lost)
struct AtomMap {
    vec3 rx, ry, rz;
    vec2 o;
    float oz;
    // the rounding of the placed centres and of this map: far above
    // either, in world units
    float slack;
};

// Instance k's placement: its origin's image p0 and its linear map's
// images of the axes ax (the AtomMap's inputs).
void instance_map(uint k, out vec3 p0, out mat3 ax) {
    p0 = instance_apply(k, vec3(0.0));
    ax = mat3(instance_linear(k, vec3(1.0, 0.0, 0.0)),
              instance_linear(k, vec3(0.0, 1.0, 0.0)),
              instance_linear(k, vec3(0.0, 0.0, 1.0)));
}

AtomMap atom_map(View v, vec3 p0, mat3 ax) {
    float ppu = v.center.w;
    precise vec3 rx = (v.right.xyz * ax) * ppu, ry = -(v.up.xyz * ax) * ppu, rz = v.dir.xyz * ax;
    precise vec3 q = p0 - v.center.xyz;
    precise vec2 o = vec2(dot(q, v.right.xyz) * ppu + 0.5 * v.right.w - 0.5,
                  0.5 * v.up.w - 0.5 - dot(q, v.up.xyz) * ppu);
    precise float oz = dot(q, v.dir.xyz);
    precise float slack = 1e-5 * (coord_max(p0) + coord_max(v.center.xyz)) + 1e-3;
    return AtomMap(rx, ry, rz, o, oz, slack);
}

// Atom a's disc in view v's pixels (mapped by m): its centre t and its
// radius r, grown for the map's rounding.
void atom_disc(View v, AtomMap m, vec4 a, out vec2 t, out float r) {
    precise vec2 tp = m.o + vec2(dot(m.rx, a.xyz), dot(m.ry, a.xyz));
    precise float rp = a.w * v.center.w + (m.slack * v.center.w + 1e-3);
    t = tp;
    r = rp;
}

// Atom a's pixel rectangle in view v (mapped by m), grown, and its nearest
// depth key, less the cull's margin for the keys' f32 rounding
// (glsl/lod_cull.comp `hidden`) and the map's.
void atom_rect(View v, AtomMap m, vec4 a, out ivec4 rc, out uint near) {
    vec2 t;
    float r;
    atom_disc(v, m, a, t, r);
    ivec2 lo = ivec2(v.dims.zw), hi = min(lo + ivec2(v.dims.xy), ivec2(int(v.right.w), int(v.up.w))) - 1;
    rc = ivec4(max(ivec2(ceil(t - r)), lo), min(ivec2(floor(t + r)), hi));
    precise float z = m.oz + dot(m.rz, a.xyz);
    precise float zmin = z - a.w + v.depth.x - (1e-4 * (abs(z) + abs(v.depth.x) + a.w) + 1e-3 + m.slack);
    near = floatBitsToUint(max(zmin, 0.0));
}

// The camera's map of an instance: atom_map's for an orthographic
// camera; for a perspective one (PERSP) into view space from the eye,
// unscaled: an atom at a (the molecule's frame) is at (o + (rx . a, ry .
// a), oz + rz . a) along right, up and the view direction.
AtomMap cam_map(View v, vec3 p0, mat3 ax) {
    if (!PERSP) return atom_map(v, p0, ax);
    precise vec3 rx = v.right.xyz * ax, ry = v.up.xyz * ax, rz = v.dir.xyz * ax;
    precise vec3 eye = v.center.xyz - v.dir.w * v.dir.xyz;
    precise vec3 q = p0 - eye;
    precise vec2 o = vec2(dot(q, v.right.xyz), dot(q, v.up.xyz));
    precise float oz = dot(q, v.dir.xyz);
    precise float slack = 1e-5 * (coord_max(p0) + coord_max(eye)) + 1e-3;
    return AtomMap(rx, ry, rz, o, oz, slack);
}

// Atom a's pixel rectangle in the camera's view v (mapped by cam_map's m),
// grown, and its nearest depth key less a margin: atom_rect's for an
// orthographic camera. Perspective: the sphere's centre c from the eye and
// radius r (grown by the map's slack); along each plane axis its image
// lies between its two tangents from the eye, of slopes (c.a c.z +- r
// sqrt(c.a^2 + c.z^2 - r^2)) / (c.z^2 - r^2) (plane coordinates are the
// eye distance times the slope); a sphere reaching the eye's plane takes
// the whole window. Its nearest depth (the ray distance from the eye) is
// at least |c| - r. (`precise` throughout: the early and recheck
// pipelines must compute alike bits, see AtomMap.)
void cam_rect(View v, AtomMap m, vec4 a, out ivec4 rc, out uint near) {
    if (!PERSP) {
        atom_rect(v, m, a, rc, near);
        return;
    }
    ivec2 lo = ivec2(v.dims.zw), hi = min(lo + ivec2(v.dims.xy), ivec2(int(v.right.w), int(v.up.w))) - 1;
    precise vec3 c = vec3(m.o + vec2(dot(m.rx, a.xyz), dot(m.ry, a.xyz)), m.oz + dot(m.rz, a.xyz));
    precise float r = a.w + m.slack;
    if (c.z + r <= 0.0) {
        rc = ivec4(1, 1, 0, 0); // behind the eye
    } else if (c.z - r <= 1e-3 * r) {
        rc = ivec4(lo, hi);
    } else {
        precise float d = c.z * c.z - r * r;
        precise vec2 t = r * sqrt(c.xy * c.xy + d);
        precise vec2 mn = (c.xy * c.z - t) / d, mx = (c.xy * c.z + t) / d;
        float ppu = v.center.w * v.dir.w;
        // (plane -> pixel as plane_rect, less and plus a margin for the
        // rounding of the slopes)
        precise vec2 f0 = vec2(mn.x * ppu + 0.5 * v.right.w, 0.5 * v.up.w - mx.y * ppu) - 0.55;
        precise vec2 f1 = vec2(mx.x * ppu + 0.5 * v.right.w, 0.5 * v.up.w - mn.y * ppu) - 0.45;
        f0 = clamp(f0, vec2(-1.0), vec2(v.right.w, v.up.w));
        f1 = clamp(f1, vec2(-1.0), vec2(v.right.w, v.up.w));
        rc = ivec4(max(ivec2(ceil(f0)), lo), min(ivec2(floor(f1)), hi));
    }
    // (less glsl/lod_cull.comp `hidden`'s margin: a grazing ray's key may
    // lose ~|c| * 3e-4 to cancellation)
    precise float l = length(c);
    precise float zmin = l - r - (1e-3 * (l + r) + m.slack);
    near = floatBitsToUint(max(zmin, 0.0));
}
#endif
