// The per-sphere / per-band skeleton shared by the camera and light
// rasterizers, the deep lists' count and fill passes and the opacity maps.
// One invocation per sphere visits small footprints itself; footprints
// larger than pc.big_area texels are cut into BAND_ROWS-row bands appended
// to a job list, and a second pipeline of the same shader (specialization
// constant BAND_PASS = 1, dispatched indirectly after band_args.comp) runs
// one workgroup per band, so one big sphere never serialises thousands of
// texels on one invocation. When the job list is full the sphere's own
// invocation visits its whole footprint instead (band_inline() lets the
// includer remember that, e.g. for the deep lists' fill pass, and flag a
// footprint that lavapipe's loop limit may cut: the frame is then drawn
// again with a longer list).
//
// Before including, define:
//   struct Footprint { ...; ivec4 rect; }   inclusive texel rectangle
//   Footprint band_footprint(uint id);
//   void visit(uint id, Footprint f, ivec2 t);
//   bool band_queue();          false: do not queue (a previous pass did),
//                               only replay the spheres band_replay() names
//   void band_inline(uint id, uint area);  the job list was full for this
//                               sphere (of `area` texels): its invocation
//                               visits it
//   bool band_replay(uint id);
//   #define BAND_REQ, BAND_RUN  word indices of counters[]
//   (optionally) #define SPHERE_AT(i): the sphere of invocation i
// with buffers jobs[] (uvec2: sphere id, first row) and counters[] (uint),
// and push constants pc.sphere_count, pc.big_area, pc.job_capacity.
#ifndef BANDS_GLSL
#define BANDS_GLSL
#include "shared.glsl"

// The sphere the i-th invocation rasterizes (an includer may visit them in
// another order: raster.comp's light view).
#ifndef SPHERE_AT
#define SPHERE_AT(i) (i)
#endif
// What an includer does after an invocation visited (part of) a sphere's
// footprint (oit_splat.comp: the key light's receivers of its fragments).
#ifndef BAND_VISITED
#define BAND_VISITED(id, f)
#endif

layout(constant_id = 1) const uint BAND_PASS = 0;

// One loop over the rectangle, the column stepping and wrapping into the
// next row (selects, no division). Measured on lavapipe against rows x
// per-row disk spans: the same camera raster, the light raster of 1-texel
// spheres 38 -> 35 ms (1M capsid): the loop overhead of the short rows
// cost more than the corners' ray tests.
void visit_rect(uint id, Footprint f, ivec4 rc) {
    int n = (rc.z - rc.x + 1) * (rc.w - rc.y + 1);
    ivec2 t = rc.xy;
    for (int i = 0; i < n; ++i) {
        visit(id, f, t);
        bool wrap = t.x == rc.z;
        t = wrap ? ivec2(rc.x, t.y + 1) : ivec2(t.x + 1, t.y);
    }
}

// One copy of the visit loop, entered by small footprints, by spheres the
// deep lists' fill pass replays, and when the job list is full: on lavapipe
// a loop that no lane enters still runs its body once, so each extra copy
// (there were three) cost every vector of spheres a full visit.
// Sphere `id`: its footprint visited here up to `big_area` texels, else
// queued in bands.
void band_sphere_id(uint id, uint big_area) {
    Footprint f = band_footprint(id);
    ivec4 rc = f.rect;
    if (rc.x > rc.z || rc.y > rc.w) return;
    uint area = uint(rc.z - rc.x + 1) * uint(rc.w - rc.y + 1);
    bool here = area <= big_area;
    if (!here) {
        if (!band_queue()) {
            here = band_replay(id);
        } else {
            uint nb = uint(rc.w - rc.y) / BAND_ROWS + 1u;
            uint base = atomicAdd(counters[BAND_REQ], nb);
            bool queued = base < pc.job_capacity && nb <= pc.job_capacity - base;
            // Queued: the bands; the job list is full: void the slots this
            // sphere got and visit here.
            uint last = min(base + nb, pc.job_capacity);
            for (uint j = base; j < last; ++j) {
                jobs[j] = queued ? uvec2(id, uint(rc.y) + (j - base) * BAND_ROWS) : uvec2(NO_SPHERE, 0u);
            }
            if (!queued) band_inline(id, area);
            here = !queued;
        }
    }
    if (here) {
        visit_rect(id, f, rc);
        BAND_VISITED(id, f);
    }
}

void band_sphere() {
    uint i = FLAT_ID;
    if (i >= pc.sphere_count) return;
    band_sphere_id(SPHERE_AT(i), pc.big_area);
}

void band_job() {
    uint job = gl_WorkGroupID.x + gl_WorkGroupID.y * gl_NumWorkGroups.x;
    if (job >= counters[BAND_RUN]) return;
    uvec2 jb = jobs[job];
    if (jb.x == NO_SPHERE) return;
    Footprint f = band_footprint(jb.x);
    ivec4 rc = f.rect;
    int y0 = int(jb.y);
    int rows = min(int(BAND_ROWS), rc.w - y0 + 1);
    int width = rc.z - rc.x + 1;
    // Row and column by a float reciprocal: an integer division by a
    // non-constant is 8 scalar divisions per vector on lavapipe. Exact
    // here: (i + 0.5) / width is at least 0.5 / width from an integer and
    // i < 2^22, far above the float error.
    float inv_w = 1.0 / float(width);
    for (int i = int(gl_LocalInvocationID.x); i < width * rows; i += int(gl_WorkGroupSize.x)) {
        int r = int((float(i) + 0.5) * inv_w);
        visit(jb.x, f, ivec2(rc.x + i - r * width, y0 + r));
    }
    BAND_VISITED(jb.x, f);
}

// (an includer may run its own per-sphere pass: BAND_SPHERE_MAIN)
#ifndef BAND_SPHERE_MAIN
#define BAND_SPHERE_MAIN band_sphere
#endif

void main() {
    if (BAND_PASS != 0u) {
        band_job();
    } else {
        BAND_SPHERE_MAIN();
    }
}
#endif
