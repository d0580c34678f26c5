// A technique that computes key-light visibility in a pass of its own
// (one float per pixel) instead of a lookup compiled into shade: the
// generic way in for a new technique (see src/stages/shadows/constant.rs).
layout(set = 0, binding = 16) uniform samplerBuffer visibilityTex; // R32F per pixel

float key_visibility(Surface s, uint pixel) { return texelFetch(visibilityTex, int(pixel)).x; }
