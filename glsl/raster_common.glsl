// Screen-space footprint of a sphere in a view, shared by the raster passes.
#ifndef RASTER_COMMON_GLSL
#define RASTER_COMMON_GLSL
#include "shared.glsl"

// Extent along one plane axis of a sphere seen from the eye (perspective):
// the tangent directions of the sphere in the (axis, depth) plane.
vec2 persp_extent(float a, float z, float r, float dist) {
    float l2 = a * a + z * z;
    if (l2 <= r * r) return vec2(-1e30, 1e30); // eye inside: covers everything
    float l = sqrt(l2);
    float ang = atan(a, z);
    float del = asin(r / l);
    float lo = ang - del, hi = ang + del;
    const float HALF_PI = 1.5707963;
    float x0 = lo <= -HALF_PI ? -1e30 : dist * tan(lo);
    float x1 = hi >= HALF_PI ? 1e30 : dist * tan(hi);
    return vec2(x0, x1);
}

// The inclusive pixel rectangle (x0, y0, x1, y1), in image coordinates,
// whose centres lie within the plane ranges xr, yr, clipped to the view's
// buffer window; empty when x0 > x1 or y0 > y1.
ivec4 plane_rect(View v, vec2 xr, vec2 yr) {
    float ppu = v.center.w, w = v.right.w, h = v.up.w;
    // plane -> pixel: px = x*ppu + W/2 - 0.5, py = H/2 - y*ppu - 0.5; a small
    // slack absorbs rounding between this inverse and pixel_plane().
    const float SLACK = 1e-3;
    float fx0 = clamp(xr.x * ppu + 0.5 * w - 0.5 - SLACK, -1.0, w);
    float fx1 = clamp(xr.y * ppu + 0.5 * w - 0.5 + SLACK, -1.0, w);
    float fy0 = clamp(0.5 * h - yr.y * ppu - 0.5 - SLACK, -1.0, h);
    float fy1 = clamp(0.5 * h - yr.x * ppu - 0.5 + SLACK, -1.0, h);
    ivec4 rect = ivec4(ceil(fx0), ceil(fy0), floor(fx1), floor(fy1));
    ivec2 lo = ivec2(v.dims.zw), hi = min(lo + ivec2(v.dims.xy), ivec2(int(w), int(h))) - 1;
    return ivec4(max(rect.xy, lo), min(rect.zw, hi));
}

// The pixel rectangle (plane_rect) whose centres may see the sphere.
// `persp` (v.dir.w != 0) comes from a specialization constant or a
// literal: lavapipe runs the straight-line code of an if that no lane
// takes, and the perspective side's atan, asin and tans would run for
// every orthographic sphere.
ivec4 sphere_rect(View v, vec3 cv, float r, bool persp) {
    vec2 xr, yr;
    if (!persp) {
        xr = vec2(cv.x - r, cv.x + r);
        yr = vec2(cv.y - r, cv.y + r);
    } else {
        if (cv.z + r <= 0.0) return ivec4(1, 1, 0, 0); // behind the eye
        xr = persp_extent(cv.x, cv.z, r, v.dir.w);
        yr = persp_extent(cv.y, cv.z, r, v.dir.w);
    }
    return plane_rect(v, xr, yr);
}

#endif
