#version 460
// Opacity shadow maps (after the WebGL particle paper), pass 2: per texel, an inclusive prefix sum
// over the slices, in place. Slice k's word changes from the fixed-point
// optical depth deposited in slice k to the float optical depth accumulated
// from the light through the end of slice k (the seed's "bucket n holds the
// sum of all earlier buckets", done in one pass per texel instead of 64
// render passes). One invocation per texel; consecutive invocations read
// consecutive words of each slice.
#include "shared.glsl"

layout(local_size_x_id = 0) in;

layout(set = 0, binding = 0) buffer Opacity { uint opacity[]; };

#include "push/osm_prefix.glsl"

void main() {
    uint t = FLAT_ID;
    if (t >= pc.texels) return;
    float acc = 0.0;
    for (uint k = 0u; k < pc.slices; ++k) {
        uint a = k * pc.texels + t;
        acc += float(opacity[a]) * pc.inv_scale;
        opacity[a] = floatBitsToUint(acc);
    }
}
