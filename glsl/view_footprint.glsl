// The camera-style footprint of a sphere in a view (raster.comp,
// oit_splat.comp): its rectangle, and per pixel its exact front-hit depth
// key. Needs, before inclusion: the PERSP specialization constant and
// scene.glsl.
#ifndef VIEW_FOOTPRINT_GLSL
#define VIEW_FOOTPRINT_GLSL
#include "raster_common.glsl"
// The view is loaded once per sphere (or band) and travels with the
// footprint: loading it per pixel doubled the pass's cost on lavapipe.
// Orthographic footprints also carry their plane coordinates per pixel,
// so a pixel costs two multiply-adds, not pixel_plane's divisions.
struct Footprint {
    View v;
    vec3 cv;
    float r;
    ivec4 rect;
    vec2 origin; // plane coordinates of pixel (0, 0) relative to the centre
    float step;  // world units per pixel
};

Footprint view_footprint(View v, uint id) {
    Footprint f;
    f.v = v;
    vec4 s = scene_sphere(id);
    f.cv = view_space(f.v, s.xyz, PERSP);
    f.r = s.w;
    // (an unused slot of an instanced batch has no footprint)
    f.rect = scene_instanced() && s.w < 0.0 ? ivec4(1, 1, 0, 0) : sphere_rect(f.v, f.cv, s.w, PERSP);
    f.step = 1.0 / f.v.center.w;
    f.origin = vec2(0.5 - 0.5 * f.v.right.w, 0.5 * f.v.up.w - 0.5) * vec2(f.step, f.step) - f.cv.xy;
    return f;
}

// Depth key of the sphere's front hit at pixel t (image coordinates), -1
// on a miss.
float footprint_depth(Footprint f, ivec2 t) {
    if (PERSP) return hit_depth(f.v, f.cv, f.r, vec2(t), true);
    vec2 dxy = f.origin + vec2(t.x, -t.y) * f.step;
    float disc = f.r * f.r - dot(dxy, dxy);
    return disc < 0.0 ? -1.0 : max(f.cv.z - sqrt(disc) + f.v.depth.x, 0.0);
}

// Index in the buffer window of pixel t.
uint footprint_pixel(Footprint f, ivec2 t) {
    return uint(t.y - int(f.v.dims.w)) * f.v.dims.x + uint(t.x - int(f.v.dims.z));
}
#endif
