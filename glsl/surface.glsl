// Visibility-buffer shading: the visible surface of a pixel, rebuilt
// exactly from its (pixel ray, sphere id) instead of a stored G-buffer.
// Needs, before inclusion: `Globals g`, the visibility buffer as a uniform
// texel buffer `visTex` (RG32UI: x = sphere id, y = depth key bits; both
// ~0 = background), scene.glsl (with SCENE_ATTRIBUTES for albedo_of) and
// the specialization constant PERSP (a perspective camera).
// Texel fetches are vector gathers on lavapipe (docs/LAVAPIPE.md).
#ifndef SURFACE_GLSL
#define SURFACE_GLSL
#include "shared.glsl"
#include "scene.glsl"

struct Surface {
    vec3 p;     // world position
    vec3 n;     // unit normal
    uint id;    // sphere index
    float key;  // depth key of the visibility buffer
    vec2 img;   // the pixel's image coordinates
    vec4 sphere; // its sphere: centre, radius
    uvec4 batch; // its batch record (scene_batch_of: the batch_* readers)
};

bool covered(uint i) { return texelFetch(visTex, int(i)).x != NO_SPHERE; }

// The surface of sphere `id` seen through full-resolution pixel q of the
// buffer window: its front hit (key 0; surface_of for the visibility
// buffer's sphere, shade.comp's see-through fragments for theirs).
Surface surface_for(uvec2 q, uint id) {
    Surface s;
    s.img = vec2(q + g.cam.dims.zw);
    s.id = id;
    s.key = 0.0;
    s.batch = scene_batch_of(id);
    vec4 sp = batch_sphere(s.batch, id);
    s.sphere = sp;
    vec3 o, d;
    view_ray(g.cam, s.img, PERSP, o, d);
    // Exact hit recomputed relative to the sphere centre for precision.
    vec3 oc = o - sp.xyz;
    float b = dot(oc, d);
    float disc = max(b * b - (dot(oc, oc) - sp.w * sp.w), 0.0);
    float t = -b - sqrt(disc);
    s.p = o + t * d;
    s.n = normalize(s.p - sp.xyz);
    return s;
}

// Surface of full-resolution pixel q of the buffer window (false for
// background). Callers pass the pixel, not its index: recovering it with
// % and / is 8 scalar integer divisions per vector on lavapipe.
bool surface_of(uvec2 q, out Surface s) {
    uint i = q.y * g.cam.dims.x + q.x;
    uvec2 v = texelFetch(visTex, int(i)).xy;
    if (v.x == NO_SPHERE) return false;
    s = surface_for(q, v.x);
    s.key = uintBitsToFloat(v.y);
    return true;
}

// Linear albedo of a sphere from its RGBA8 colour word (scene_color): the
// attribute texels (32 B per sphere then) held it too, but as a random
// fetch per pixel they cost ~10 ms of the 1M capsid's shade on lavapipe.
vec3 srgb_to_linear(vec3 c) { return pow(c, vec3(2.2)); }
#ifdef SCENE_ATTRIBUTES
vec3 albedo_of(uint id) { return srgb_to_linear(unpack_rgba8(scene_color(id)).rgb); }
vec3 surface_albedo(Surface s) { return srgb_to_linear(unpack_rgba8(batch_color(s.batch, s.id)).rgb); }
#endif
#endif
