// Indirect dispatch arguments for a count of workgroups (the host's
// Grid::Invocations folds alike, src/vk/pipeline.rs `fold_groups`): one row
// up to MAX_GROUPS_X, past it `rows` rows of groups / rows rounded up, so
// fewer than `rows` groups run past the count. (Rows of MAX_GROUPS_X ran
// up to 65,534 more, each an empty workgroup of ~1.3 us on lavapipe: meso
// 10^9 at 2,025 A, 209 k batches in 262,140 groups, 68 ms of the camera
// raster.) Readers index rows by gl_NumWorkGroups.x (FLAT_ID).
#ifndef GRID_GLSL
#define GRID_GLSL
#include "constants.glsl"

uvec3 grid_of(uint groups) {
    uint rows = (groups + MAX_GROUPS_X - 1u) / MAX_GROUPS_X;
    return uvec3(rows == 0u ? 0u : (groups + rows - 1u) / rows, rows, 1u);
}
#endif
