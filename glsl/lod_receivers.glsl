// The light's receiver depths in the LOD region buffer (after its
// rectangle's four words): word LOD_RECEIVERS_AT + t for receiver tile t
// (2^receiver_shift texels a side: a 512^2 map's texels, its fine depth
// tiles), the farthest light depth word of the camera's visible points
// whose lookup is centred in the tile (grown by the lookup's depth slack;
// 0: none). lod_bounds.comp takes the maxima, lod_hiz.comp reads them.
// Needs, before inclusion, `region[]` (the Region buffer).
#ifndef LOD_RECEIVERS_GLSL
#define LOD_RECEIVERS_GLSL
int receiver_word(int tile) { return LOD_RECEIVERS_AT + tile; }
#endif
