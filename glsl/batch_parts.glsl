// The per-batch rasters (glsl/raster.comp LIGHT_BATCHES, CAM_BATCHES) take
// a batch of `batch_slots` slots in this many invocations of
// BATCH_PART_SLOTS slots each (one for smaller batches); lod_args.comp
// dispatches as many.
#ifndef BATCH_PARTS_GLSL
#define BATCH_PARTS_GLSL
#include "constants.glsl"

uint batch_parts(uint batch_slots) { return max(batch_slots / BATCH_PART_SLOTS, 1u); }
// The largest footprint a camera part visits itself (larger ones go to
// bands): raster.comp's CAM_BATCHES and oit_splat.comp's BATCHES.
const uint CAM_PART_AREA = 128u;
#endif
