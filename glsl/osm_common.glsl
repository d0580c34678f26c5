// Opacity shadow maps (after the WebGL particle paper): what osm_raster.comp and osm_shadow.comp
// must compute identically (the lookup recomputes the receiver's own deposit
// to remove it). Define OSM_Z_MIN, OSM_INV_DZ and OSM_SLICES before including.
#ifndef OSM_COMMON_GLSL
#define OSM_COMMON_GLSL

// Slice of the sphere's entry depth along the light ray through texel t's
// centre, or -1 when the ray misses the sphere.
int texel_entry_slice(View L, vec3 cv, float r, ivec2 t) {
    vec2 p = pixel_plane(L, vec2(t));
    vec2 dxy = p - cv.xy;
    float disc = r * r - dot(dxy, dxy);
    if (disc < 0.0) return -1;
    float z = cv.z - sqrt(disc);
    return clamp(int(floor((z - OSM_Z_MIN) * OSM_INV_DZ)), 0, int(OSM_SLICES) - 1);
}
#endif
