// The light's read mask in the LOD region buffer (after its rectangle's
// four words): bit t of word LOD_MASK_AT + t / 32 for fine light depth
// tile t. lod_bounds.comp sets a tile's bit, lod_hiz.comp tests it.
// Needs, before inclusion, `region[]` (the Region buffer).
#ifndef LOD_MASK_GLSL
#define LOD_MASK_GLSL
int mask_word(int tile) { return LOD_MASK_AT + (tile >> 5); }
int mask_bit(int tile) { return 1 << (tile & 31); }
#endif
