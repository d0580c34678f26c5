// The light's batch raster (glsl/raster.comp LIGHT_BATCHES) takes a batch
// of `batch_slots` slots in this many invocations of LIGHT_PART_SLOTS
// slots each (one for smaller batches); lod_args.comp dispatches as many.
#ifndef LIGHT_BATCHES_GLSL
#define LIGHT_BATCHES_GLSL
#include "constants.glsl"

uint light_parts(uint batch_slots) { return max(batch_slots / LIGHT_PART_SLOTS, 1u); }
#endif
