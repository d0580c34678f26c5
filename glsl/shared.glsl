// GPU data shared with Rust. Mirrors src/gpu.rs exactly: every struct is made
// of 16-byte vectors so std140/std430 and #[repr(C)] agree without padding
// surprises; tests/gpu_layout.rs checks every field offset on the device.
#ifndef SHARED_GLSL
#define SHARED_GLSL

#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require

// A view: orthographic or perspective camera (also the key light's view).
struct View {
    vec4 center; // xyz view centre; w pixels per world unit on the view plane (H / h)
    vec4 right;  // xyz r = normalize(cross(d, up)); w image width in pixels
    vec4 up;     // xyz u = cross(r, d); w image height in pixels
    vec4 dir;    // xyz d (view direction); w eye distance from centre (0 = orthographic)
    vec4 depth;  // x offset added to orthographic depth so keys stay positive; yzw unused
    uvec4 dims;  // x W, y H; zw unused
};

struct Globals {
    View cam;
    View light;
    vec4 light_dir;   // xyz normalised key-light direction (from light toward scene)
    vec4 background;  // rgb background colour, a unused
    uvec4 counts;     // x sphere count, yzw unused
    vec4 params;      // free parameters (per feature), see src/gpu.rs
};

struct SphereAttr {
    uvec4 region; // region ids per hierarchy level, outermost first
    uint color;   // RGBA8 (R in the low byte)
    uint flags;
    uint pad0;
    uint pad1;
};

// Flat invocation index; dispatch() folds large 1D grids into y.
#define FLAT_ID (gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * gl_NumWorkGroups.x * gl_WorkGroupSize.x)

const uint64_t VIS_EMPTY = 0xFFFFFFFFFFFFFFFFul;
const uint NO_SPHERE = 0xFFFFFFFFu;

// Plane coordinates of a pixel centre (DESIGN.md camera convention).
vec2 pixel_plane(View v, vec2 px) {
    float w = v.right.w, h = v.up.w;
    float hh = h / v.center.w; // view height in world units
    return vec2(((px.x + 0.5) / w - 0.5) * hh * w / h, (0.5 - (px.y + 0.5) / h) * hh);
}

// Ray through a pixel: origin and unit direction in world space.
void view_ray(View v, vec2 px, out vec3 origin, out vec3 dir) {
    vec2 p = pixel_plane(v, px);
    if (v.dir.w == 0.0) {
        origin = v.center.xyz + p.x * v.right.xyz + p.y * v.up.xyz;
        dir = v.dir.xyz;
    } else {
        origin = v.center.xyz - v.dir.w * v.dir.xyz;
        dir = normalize(v.dir.w * v.dir.xyz + p.x * v.right.xyz + p.y * v.up.xyz);
    }
}

// Sphere centre in view coordinates: relative to the view centre
// (orthographic) or to the eye (perspective), along (r, u, d).
vec3 view_space(View v, vec3 c) {
    vec3 o = v.dir.w == 0.0 ? v.center.xyz : v.center.xyz - v.dir.w * v.dir.xyz;
    vec3 q = c - o;
    return vec3(dot(q, v.right.xyz), dot(q, v.up.xyz), dot(q, v.dir.xyz));
}

// Exact ray-sphere test for the pixel's ray against a sphere given in view
// coordinates (cv) with radius r. Returns the depth key (>= 0) or -1 on a miss.
// Orthographic depth: distance along d from the view centre plane + offset.
// Perspective depth: distance along the ray from the eye (near hits only).
float hit_depth(View v, vec3 cv, float r, vec2 px) {
    vec2 p = pixel_plane(v, px);
    if (v.dir.w == 0.0) {
        vec2 dxy = p - cv.xy;
        float disc = r * r - dot(dxy, dxy);
        if (disc < 0.0) return -1.0;
        return max(cv.z - sqrt(disc) + v.depth.x, 0.0);
    }
    vec3 dir = normalize(vec3(p, v.dir.w));
    float b = dot(cv, dir);
    float disc = b * b - (dot(cv, cv) - r * r);
    if (disc < 0.0) return -1.0;
    float t = b - sqrt(disc);
    return t > 0.0 ? t : -1.0;
}

uint64_t vis_key(float depth, uint id) {
    return (uint64_t(floatBitsToUint(depth)) << 32) | uint64_t(id);
}

uint pack_rgba8(vec4 c) {
    uvec4 u = uvec4(clamp(c, 0.0, 1.0) * 255.0 + 0.5);
    return u.r | (u.g << 8) | (u.b << 16) | (u.a << 24);
}

vec4 unpack_rgba8(uint c) {
    return vec4(c & 0xFFu, (c >> 8) & 0xFFu, (c >> 16) & 0xFFu, c >> 24) / 255.0;
}

#endif
