// Key-light visibility at a visible point, for the technique the including
// shader was compiled for (build.rs compiles shade.comp and ssdo_prep.comp
// once per SHADOW_* variant). Each lookup declares its own bindings from
// binding 16 on and reads its parameters from Globals.shadow_*:
//   float key_visibility(Surface s, uint pixel)
// counts occlusion by OTHER spheres only (DESIGN.md's shadow AOV).
#ifndef LOOKUP_GLSL
#define LOOKUP_GLSL
#include "surface.glsl"

#if defined(SHADOW_ISSM)
#include "lookup_issm.glsl"
#elif defined(SHADOW_DEEP)
#include "lookup_deep.glsl"
#elif defined(SHADOW_SM)
#include "lookup_sm.glsl"
#elif defined(SHADOW_OSM)
#include "lookup_osm.glsl"
#elif defined(SHADOW_SCREEN)
#include "lookup_screen.glsl"
#elif defined(SHADOW_BUFFER)
#include "lookup_buffer.glsl"
#else
float key_visibility(Surface s, uint pixel) { return 1.0; }
#endif
#endif
