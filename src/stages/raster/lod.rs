//! The views' sphere lists of an instanced scene with levels of detail
//! (glsl/lod_cull.comp, lod_hiz.comp, lod_bounds.comp, lod_args.comp).
//! `lod_cull`: one invocation per instance tests its bounding sphere
//! against the camera's window and chooses its level from its size on
//! screen; `light_cull`, after the camera's raster: the same in the key
//! light's view with the camera's level, over the light texels the
//! camera's visible points may read. The kept instances' batches of that
//! level are listed per view, and the rasterizer visits a list in place of
//! the view's order, dispatched indirectly. The four lists lie in one
//! buffer, the scene's ([`LodBuffers::lists`]): in a frame that draws
//! them they are its batch table, and a sphere's id is its slot there, so
//! ids stay 32-bit however many atoms the scene represents. Each view's list is drawn in
//! two phases: first the batches of the instances that passed its
//! occlusion test last frame that last frame's image does not hide, then,
//! against the depth tiles of that early image, what the early phase
//! deferred (those batches, the other instances) that is not hidden
//! (`lod_occlusion`, `raster_late`; `light_occlusion`,
//! `light_raster_late`). Culled instances cost one invocation of a cull
//! and nothing after it.

use crate::error::Result;
use crate::gpu::GpuView;
use crate::gpu::blocks::{
    LodArgsPush, LodBoundsPush, LodCullPush, LodFrontPush, LodHizPush, LodShownPush,
};
use crate::gpu::consts::{
    BATCH_EMPTY, CULL_DEFERRED_BATCHES, CULL_DEFERRED_INSTANCES, CULL_EARLY, HIZ_FINE_TILES,
    HIZ_MIN_SHIFT, LOD_ARGS, LOD_BATCHES, LOD_DEFER_BATCH_ARGS, LOD_DEFER_BATCHES,
    LOD_DEFER_INSTANCE_ARGS, LOD_DEFER_INSTANCES, LOD_LIST_TAIL, LOD_RECEIVERS_AT, LOD_SPHERES,
    LOD_TILES_CHANGED, LOD_VIEWS, LOD_WORDS, NO_LEVEL_YET, VISIBLE_PASSED, VISIBLE_SHOWN,
};
use crate::passes::scene::{LodBuffers, MAX_SLOTS, SCENE_GEOMETRY, SceneBuffers};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::vk::pipeline::{Binding, PipelineDesc, ro, rw, texel, uniform};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder};
use ash::vk::Format;

pub use super::compute::LodView;
use super::compute::ViewIndex;

const BINDINGS: [Binding; 12] = [
    uniform("GlobalsBlock"),
    texel("lodBoundTex", Format::R32G32B32A32_SFLOAT),
    rw("Levels"),
    rw("List"),
    rw("Counters"),
    rw("Visible"),
    texel("hizTex", Format::R32_UINT),
    ro("Region"),
    texel("hizPrevTex", Format::R32_UINT),
    texel("batchBoundTex", Format::R32G32B32A32_SFLOAT),
    texel("cullOrderTex", Format::R32_UINT),
    rw("Deferred"),
];

const SHOWN_BINDINGS: [Binding; 4] = [
    uniform("GlobalsBlock"),
    texel("visWordTex", Format::R32_UINT),
    texel("batchTex", Format::R32G32_UINT),
    rw("Visible"),
];

const FRONT_BINDINGS: [Binding; 4] = [
    uniform("GlobalsBlock"),
    texel("lodBoundTex", Format::R32G32B32A32_SFLOAT),
    rw("Visible"),
    rw("Front"),
];

/// The most cells glsl/lod_front.comp keeps a nearest depth for, in the
/// camera's early depth tiles' buffer (not yet built in the frame when it
/// runs: [`LodCull::front_steps`]); past them the cells grow wider than
/// `front_shift` would have them.
const FRONT_CELLS: u32 = HIZ_FINE_TILES;

/// The front cells' shift for a `w` x `h` window where a typical
/// instance is `r` pixels in radius: cells about as wide as that radius
/// (the largest power of two within it, from 2 to 64 pixels), or wider
/// where they would not fit FRONT_CELLS.
fn front_shift(w: u32, h: u32, r: f32) -> u32 {
    let want = if r >= 2.0 {
        (r.min(64.0) as u32).ilog2()
    } else {
        1
    };
    fitting_shift(w, h, want, FRONT_CELLS)
}

/// The least shift from `least` whose tiles (2^shift pixels a side) over
/// a `w` x `h` window are at most `most`.
fn fitting_shift(w: u32, h: u32, least: u32, most: u32) -> u32 {
    (least..28)
        .find(|&s| tiles(w, h, 1 << s) <= most as u64)
        .unwrap_or(28)
}

/// Pixels one invocation of glsl/lod_shown.comp reads (its SHOWN_RUN).
const SHOWN_RUN: u64 = 16;

const BOUNDS_BINDINGS: [Binding; 3] = [
    uniform("GlobalsBlock"),
    texel("visWordTex", Format::R32_UINT),
    rw("Region"),
];

const HIZ_BINDINGS: [Binding; 6] = [
    uniform("GlobalsBlock"),
    texel("visWordTex", Format::R32_UINT),
    rw("Hiz"),
    ro("Region"),
    texel("hizPrevTex", Format::R32_UINT),
    rw("Counters"),
];

/// Receiver tiles of the light map (glsl/lod_receivers.glsl) at most: a
/// 512^2 map's texels (a larger map's tiles are 2x2 texels or more).
const RECEIVER_TILES: u32 = HIZ_FINE_TILES / 4;

/// Bytes of the light region buffer: its rectangle (4 words), then a
/// receiver depth word per receiver tile (glsl/lod_bounds.comp).
const REGION_BYTES: u64 = (LOD_RECEIVERS_AT as u64 + RECEIVER_TILES as u64) * 4;

/// The receiver tiles' shift for a `w` x `h` light map: its fine depth
/// tiles' ([`hiz_shift`]) or coarser, within [`RECEIVER_TILES`].
pub fn receiver_shift(w: u32, h: u32) -> u32 {
    fitting_shift(w, h, hiz_shift(ViewIndex::Light, w, h), RECEIVER_TILES)
}

/// What the light's cull needs of the shadow lookup: the farthest it
/// reads from a point's texel (`Lookup::reach`), how far behind a point a
/// caster may still darken it (`Lookup::depth_slack`), the light map
/// (width, height), and whether the region and receivers hold points
/// already (`preset`: the see-through count emptied them and added its
/// fragments' spheres, whose points are not in the visibility buffer;
/// [`LightRegion`]).
#[derive(Clone, Copy, Debug)]
pub struct LightReads {
    pub reach: i32,
    pub slack: f32,
    pub map: (u32, u32),
    pub preset: bool,
}

/// The light's region and receiver words (glsl/lod_bounds.comp,
/// lod_receivers.glsl) as another pass adds to them before the light's
/// cull: the buffer, the receiver tiles' shift and the lookup's depth
/// slack.
#[derive(Clone, Copy)]
pub struct LightRegion<'b> {
    pub region: &'b Buffer,
    pub shift: u32,
    pub slack: f32,
    map: (u32, u32),
}

impl<'b> LightRegion<'b> {
    /// Empties the rectangle (x0, y0 the largest int, x1, y1 the least)
    /// and the receiver words of a `map` light map.
    pub fn empty(&self, p: &mut PassBuilder<'b>) {
        let (mw, mh) = self.map;
        let at = LOD_RECEIVERS_AT as u64 * 4;
        let used = (tiles(mw, mh, 1 << self.shift) * 4).min(self.region.size - at);
        p.fill_at(self.region, at, used, 0);
        p.fill_at(self.region, 0, 8, i32::MAX as u32);
        p.fill_at(self.region, 8, 8, i32::MIN as u32);
    }
}

/// Depth tile words of a view: its fine tiles, then its coarse ones (8x8
/// fine each), then its super ones (8x8 coarse).
const HIZ_WORDS: u64 = HIZ_FINE_TILES as u64 * 65 / 64 + 4096;

/// Tiles of `side` pixels a side over a `w` x `h` window.
fn tiles(w: u32, h: u32, side: u32) -> u64 {
    w.div_ceil(side) as u64 * h.div_ceil(side) as u64
}

/// The fine depth tiles' shift for `view`'s `w` x `h` window: the finest
/// from its least (the camera's HIZ_MIN_SHIFT; a light map's texel: its
/// spheres are mostly smaller than a texel, so a map of them has holes
/// between, and a tile of several texels holding one hole hides nothing)
/// whose tiles fit HIZ_FINE_TILES and, with the coarse ones, HIZ_WORDS.
pub fn hiz_shift(view: ViewIndex, w: u32, h: u32) -> u32 {
    let count = |s: u32| tiles(w, h, 1 << s);
    let least = match view {
        ViewIndex::Camera => HIZ_MIN_SHIFT,
        ViewIndex::Light => 0,
    };
    (least..28)
        .find(|&s| {
            count(s) <= HIZ_FINE_TILES as u64 && count(s) + count(s + 3) + count(s + 6) <= HIZ_WORDS
        })
        .unwrap_or(28)
}

/// Where the camera's 2-px depth tiles start in its tile buffers, after
/// its fine, coarse and super tiles, for a `w` x `h` window: the per-atom
/// test of its batch raster (glsl/raster.comp `tiles_hide`) reads them for
/// atoms of a few pixels, where a 4-px tile's farthest depth hides few
/// (the batch cull keeps its coarser tiles: 2-px ones there cost the 10^12
/// scene at 506 A 7x its raster). They are made with the 4-px tiles
/// (glsl/lod_hiz.comp, a 4-px tile's quadrants); None where those are
/// coarser or the buffer has no room (windows past ~2.7 M pixels).
pub fn micro_base(w: u32, h: u32) -> Option<u32> {
    let s = hiz_shift(ViewIndex::Camera, w, h);
    let base = tiles(w, h, 1 << s) + tiles(w, h, 8 << s) + tiles(w, h, 64 << s);
    (s == 2 && base + tiles(w, h, 2) <= HIZ_WORDS).then_some(base as u32)
}

/// Batches the early phases may defer with lists of `capacity`: a
/// quarter (meso 10^9 deferred at most 148 k batches a view at 8,100 /
/// 2,025 / 506 A, where the lists held 0.5-4 M; the lists grow 4x past
/// what a frame asks).
fn deferral_room(capacity: u32) -> u32 {
    (capacity / 4).max(1)
}

/// The deferral buffer: an entry (8 bytes) per instance, then `batches`.
fn deferral_buffer(ctx: &Context, instances: u32, batches: u32) -> Result<Buffer> {
    let entries = instances.max(1) as u64 + batches as u64;
    Buffer::storage(ctx, "LOD deferred", entries * 8)
}

/// A view's late list is `LATE + view` (index in `lists` and the counter
/// words).
const LATE: usize = 2;

/// Most entries a list may hold (its tail included): the four lists'
/// slots are 32-bit ids, and their 8-byte entries are one storage buffer
/// (`range` bytes at most; lavapipe: 128 MiB, 4 M entries a list, 2.7 *
/// 10^8 spheres a view).
fn max_list_entries(shift: u32, range: u32) -> u32 {
    let by_ids = (MAX_SLOTS >> shift) / LOD_VIEWS as u64;
    let by_range = range as u64 / (8 * LOD_VIEWS as u64);
    by_ids.min(by_range) as u32
}

/// The initial capacity of a list when not given: an eighth of the
/// full-detail batches, at least 2^16 and at most 2^20 (grown as a frame
/// asks, [`LodCull::grow_lists`]).
fn initial_capacity(most: u32) -> u32 {
    (most / 8).clamp(1 << 16, 1 << 20)
}

/// Spheres and batches a frame's cull kept, per view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LodCounts {
    /// The camera's two phases together.
    pub camera_batches: u32,
    pub camera_spheres: u32,
    /// The light's two phases together.
    pub light_batches: u32,
    pub light_spheres: u32,
    /// Of the camera's: drawn late (not seen last frame, not hidden).
    pub late_spheres: u32,
    /// Of the light's: drawn late.
    pub light_late_spheres: u32,
    /// Per view (camera, light): the instances and batches its early
    /// phase deferred to the late one (batches past the deferral room were
    /// counted, not kept: their instances were deferred from them on).
    pub deferred: [[u32; 2]; 2],
}

/// Whether the camera went from view `a` to `b` by a small move: turned by
/// at most 8 degrees, zoomed by at most 1.5x, panned by at most half the
/// image's height. Then the instances last frame's image showed are a
/// better early list than those that passed its tests, which a moving
/// camera's early phase passes every frame (glsl/lod_shown.comp); after a
/// larger move the early image they give is sparse, and the late phase
/// lists more (meso 10^9 at 2,025 A, frame ms with the passed flags ->
/// the shown ones: `bench --orbit 1` 1,221 -> 977, 5: 1,347 -> 1,122, 10:
/// 1,342 -> 1,331, 20: 1,215 -> 1,296; bench's orbit of 72 degrees a
/// frame, every fourth zoomed 4x: 1,513 -> 1,732). Only then are the
/// last final tiles read, where the last view saw each instance, batch and
/// atom (`LodCullPush::prev`, `RasterPush::prev`); after a larger move they
/// are emptied.
pub fn small_move(a: &GpuView, b: &GpuView) -> bool {
    let v = |x: [f32; 4]| glam::DVec3::new(x[0] as f64, x[1] as f64, x[2] as f64);
    let turn = v(a.dir).dot(v(b.dir)).clamp(-1.0, 1.0).acos().to_degrees();
    let zoom = |x: f32, y: f32| {
        let r = x as f64 / y as f64;
        r.max(1.0 / r)
    };
    let ppu = a.center[3] as f64;
    let pan = (v(a.center) - v(b.center)).length() * ppu;
    a.dims == b.dims
        && turn <= 8.0
        && zoom(a.center[3], b.center[3]) <= 1.5
        && (a.dir[3] == b.dir[3] || zoom(a.dir[3], b.dir[3]) <= 1.5)
        && pan <= 0.5 * a.up[3] as f64
}

/// Which image of a view its depth tiles are made of ([`LodCull::tiles_of`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Image {
    /// This frame's early image: the late phase tests against it.
    Early,
    /// The final image: the next frame's early phase tests against it.
    Final,
}

pub struct LodCull {
    /// The orthographic and perspective cameras' (constant 1) and the
    /// key light's (constant 3, the view), each per pass (constant 2:
    /// CULL_EARLY, CULL_DEFERRED_INSTANCES, CULL_DEFERRED_BATCHES).
    cull: [[ComputePipeline; 3]; 3],
    args: ComputePipeline,
    /// The depth tiles (the camera's fine, coarse, super: [`hiz_shift`];
    /// the light's fine).
    hiz: [ComputePipeline; 4],
    /// Per instance and view: it passed the occlusion test, in two arrays
    /// (last frame's, this frame's: `parity`).
    visible: Buffer,
    /// What a view's early phase defers to its late one: an entry per
    /// instance, then [`LodCull::deferred`] batch entries (one view at a
    /// time: the camera's late phase reads them before the light's early
    /// one).
    deferral: Buffer,
    /// The batch entries as given (else they follow the lists' capacity).
    deferred_given: Option<u32>,
    /// Per view: its depth tiles (of this frame's early image).
    hiz_tiles: [Buffer; 2],
    /// Per view: the depth tiles of its last final image, and their shift
    /// (28 until one is made: one tile).
    hiz_prev: [Buffer; 2],
    prev_shift: [std::cell::Cell<u32>; 2],
    /// This frame's light lookup reach (texels, `Lookup::reach`): the
    /// light's cull phases and depth tiles read it.
    reach: std::cell::Cell<i32>,
    /// Batches each list will hold from the next frame on (a frame asked
    /// more than three quarters of them).
    pending: Option<u32>,
    /// Per view: its GPU view of the last frame recorded, and whether this
    /// frame's differs.
    last_views: std::cell::RefCell<[Option<GpuView>; 2]>,
    moved: [std::cell::Cell<bool>; 2],
    /// Per view: the view its last final tiles were made in, where this
    /// frame's early phase places what it tests against them
    /// (`LodCullPush::prev`; tested where the view is now, a moved view's
    /// last tiles sent most batches to the late phase behind a sparse
    /// early image: an orbiting bench at 506 A on 10^9 drew 2.3x as much
    /// late); None: those tiles are emptied first (no last frame, or a
    /// large move: nothing hidden, every batch of the history's instances
    /// drawn early, untested; the camera's history then names the front
    /// instances, [`LodCull::front_steps`]).
    prev_views: std::cell::Cell<[Option<GpuView>; 2]>,
    /// `visible` holds a frame's result (cleared before the first).
    history: std::cell::Cell<bool>,
    /// The instances a moved camera's final image shows, flagged
    /// VISIBLE_SHOWN (glsl/lod_shown.comp), whether last frame did, and
    /// which flag this frame's camera early phase reads
    /// (LodCullPush.history).
    shown: ComputePipeline,
    shown_written: std::cell::Cell<bool>,
    /// The front instances seeding the camera's history where it has
    /// none to use (glsl/lod_front.comp; nearest, seed x orthographic,
    /// perspective).
    front: [ComputePipeline; 4],
    /// Whether the front instances seed it (`LodParams::lod_no_front`).
    front_seeding: bool,
    history_flag: std::cell::Cell<u32>,
    /// The light texels of the camera's visible points (x0, y0, x1, y1).
    region: Buffer,
    /// Orthographic and perspective cameras (constant 1).
    bounds: [ComputePipeline; 2],
    /// Per view LOD_WORDS words: batches, spheres, dispatch arguments.
    counters: Buffer,
    /// Per instance: the camera's level.
    levels: Buffer,
    /// Batches a list holds (camera, light (early), camera, light (late)
    /// in the scene's [`LodBuffers::lists`], each followed by
    /// LOD_LIST_TAIL empty entries: the last workgroup's lanes read past
    /// the count).
    capacity: u32,
    /// The most a list can ever need: the scene's full-detail batches
    /// (and the most the ids allow).
    most: u32,
    instances: u32,
    /// Further chunks of large instances the early phases take
    /// (`LodBuffers::chunk_count`).
    chunks: u32,
    /// Which visibility array holds last frame's (flipped per frame).
    parity: std::cell::Cell<u32>,
    per: u32,
}

/// The scene's level-of-detail buffers (a cull is made only for a scene
/// that has them).
fn lod_buffers(scene: &SceneBuffers) -> Result<&LodBuffers> {
    scene
        .lod
        .as_ref()
        .ok_or_else(|| crate::error::Error::Internal("the scene has no levels of detail".into()))
}

/// Counter word `k` of list `list` in the LOD counters `w` (LOD_VIEWS x
/// LOD_WORDS words, downloaded or the frame's readback copy); 0 past them.
fn lod_word(w: &[u32], list: usize, k: u32) -> u32 {
    w.get(list * LOD_WORDS as usize + k as usize)
        .copied()
        .unwrap_or(0)
}

impl LodCull {
    pub const NAME: &'static str = "lod_cull";
    pub const OCCLUSION: &'static str = "lod_occlusion";
    pub const LATE: &'static str = "raster_late";
    pub const LIGHT_CULL: &'static str = "light_cull";
    pub const LIGHT_OCCLUSION: &'static str = "light_occlusion";
    pub const LIGHT_LATE: &'static str = "light_raster_late";

    /// The cull of a scene (SCENE_SPEC `scene`) with levels `lod`, whose
    /// lists it makes: each view's starts `params.lod_list_batches` long
    /// (default [`initial_capacity`]) and grows on overflow
    /// ([`LodCull::grow_lists`]); the deferral room and the kept history
    /// as `params` says.
    pub fn new(
        ctx: &Context,
        scene: u32,
        lod: &mut LodBuffers,
        params: &crate::settings::LodParams,
    ) -> Result<Self> {
        let (list_batches, deferred_batches) =
            (params.lod_list_batches, params.lod_deferred_batches);
        let bindings = [&BINDINGS[..], &SCENE_GEOMETRY].concat();
        let make = |name: &str, (persp, view): (u32, u32), mode: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: spirv::LOD_CULL_COMP,
                    bindings: &bindings,
                    push_size: std::mem::size_of::<LodCullPush>() as u32,
                    local_size: 64,
                    constants: &[persp, mode, view],
                    scene,
                },
            )
        };
        let passes = |pv: (u32, u32), names: [&str; 3]| -> Result<[ComputePipeline; 3]> {
            let early = ctx.guard(make(names[0], pv, CULL_EARLY)?);
            let inst = ctx.guard(make(names[1], pv, CULL_DEFERRED_INSTANCES)?);
            let batches = make(names[2], pv, CULL_DEFERRED_BATCHES)?;
            Ok([early.keep(), inst.keep(), batches])
        };
        let ortho = ctx.guard(passes(
            (0, 0),
            [
                "lod cull",
                "lod cull deferred instances",
                "lod cull deferred batches",
            ],
        )?);
        let persp = ctx.guard(passes(
            (1, 0),
            [
                "lod cull perspective",
                "lod cull deferred instances perspective",
                "lod cull deferred batches perspective",
            ],
        )?);
        let light = ctx.guard(passes(
            (0, 1),
            [
                "light cull",
                "light cull deferred instances",
                "light cull deferred batches",
            ],
        )?);
        let args = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "lod args",
                shader: spirv::LOD_ARGS_COMP,
                bindings: &[rw("Counters")],
                push_size: std::mem::size_of::<LodArgsPush>() as u32,
                local_size: 1,
                constants: &[],
                scene: 0,
            },
        )?);
        let hiz = |name: &str, mode: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: spirv::LOD_HIZ_COMP,
                    bindings: &HIZ_BINDINGS,
                    push_size: std::mem::size_of::<LodHizPush>() as u32,
                    local_size: 64,
                    constants: &[mode],
                    scene: 0,
                },
            )
        };
        let hiz_fine = ctx.guard(hiz("lod depth tiles", 0)?);
        let hiz_coarse = ctx.guard(hiz("lod coarse depth tiles", 1)?);
        let hiz_super = ctx.guard(hiz("lod super depth tiles", 2)?);
        let hiz_light_fine = ctx.guard(hiz("lod light depth tiles", 3)?);
        // (a view lists each instance once, at one level: never more than
        // the full-detail batches)
        let shift = scene >> 8;
        let most = lod.base_batches.clamp(
            1,
            max_list_entries(shift, ctx.props.limits.max_storage_buffer_range) - LOD_LIST_TAIL,
        );
        let capacity = list_batches
            .unwrap_or(initial_capacity(most))
            .clamp(1, most);
        let counters = ctx.guard(crate::passes::bands::counters_buffer(
            ctx,
            "LOD counters",
            (LOD_VIEWS * LOD_WORDS) as u64 * 4,
        )?);
        let instances = lod.instance_count.max(1) as u64 * 4;
        // (two arrays of a word per instance and view: last frame's, this
        // frame's; `parity`)
        let visible = ctx.guard(Buffer::storage(ctx, "LOD visible", 4 * instances)?);
        let tiles_buffer = |name: &str| Buffer::storage(ctx, name, HIZ_WORDS * 4);
        let hiz_camera = ctx.guard(tiles_buffer("LOD camera depth tiles")?);
        let hiz_light = ctx.guard(tiles_buffer("LOD light depth tiles")?);
        let prev_camera = ctx.guard(tiles_buffer("LOD camera last depth tiles")?);
        let prev_light = ctx.guard(tiles_buffer("LOD light last depth tiles")?);
        let region = ctx.guard(Buffer::storage(ctx, "LOD light region", REGION_BYTES)?);
        let bounds = |name: &str, persp: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: spirv::LOD_BOUNDS_COMP,
                    bindings: &BOUNDS_BINDINGS,
                    push_size: std::mem::size_of::<LodBoundsPush>() as u32,
                    local_size: 64,
                    constants: &[persp],
                    scene: 0,
                },
            )
        };
        let shown = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "lod shown instances",
                shader: spirv::LOD_SHOWN_COMP,
                bindings: &SHOWN_BINDINGS,
                push_size: std::mem::size_of::<LodShownPush>() as u32,
                local_size: 64,
                constants: &[],
                scene: 0,
            },
        )?);
        let front_bindings = [&FRONT_BINDINGS[..], &SCENE_GEOMETRY].concat();
        let front = |name: &str, persp: u32, mode: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: spirv::LOD_FRONT_COMP,
                    bindings: &front_bindings,
                    push_size: std::mem::size_of::<LodFrontPush>() as u32,
                    local_size: 64,
                    constants: &[persp, mode],
                    scene,
                },
            )
        };
        let front_near = ctx.guard(front("lod front nearest", 0, 0)?);
        let front_near_p = ctx.guard(front("lod front nearest perspective", 1, 0)?);
        let front_seed = ctx.guard(front("lod front seed", 0, 1)?);
        let front_seed_p = ctx.guard(front("lod front seed perspective", 1, 1)?);
        let bounds_o = ctx.guard(bounds("lod light region", 0)?);
        let bounds_p = ctx.guard(bounds("lod light region perspective", 1)?);
        let levels = ctx.guard(Buffer::storage(ctx, "LOD levels", instances)?);
        let deferred = deferred_batches.unwrap_or(deferral_room(capacity));
        let early = lod.instance_count + lod.chunk_count;
        let deferral = ctx.guard(deferral_buffer(ctx, early, deferred)?);
        // (`deferred` is derived from here on: LodCull::deferred)
        Self::set_lists(ctx, lod, capacity)?;
        Ok(LodCull {
            cull: [ortho.keep(), persp.keep(), light.keep()],
            deferral: deferral.keep(),
            deferred_given: deferred_batches,
            args: args.keep(),
            hiz: [
                hiz_fine.keep(),
                hiz_coarse.keep(),
                hiz_super.keep(),
                hiz_light_fine.keep(),
            ],
            visible: visible.keep(),
            hiz_tiles: [hiz_camera.keep(), hiz_light.keep()],
            hiz_prev: [prev_camera.keep(), prev_light.keep()],
            prev_shift: [std::cell::Cell::new(28), std::cell::Cell::new(28)],
            reach: std::cell::Cell::new(1 << 29),
            pending: None,
            last_views: std::cell::RefCell::new([None, None]),
            history_flag: std::cell::Cell::new(VISIBLE_PASSED),
            shown_written: std::cell::Cell::new(false),
            moved: [std::cell::Cell::new(true), std::cell::Cell::new(true)],
            prev_views: std::cell::Cell::new([None; 2]),
            history: std::cell::Cell::new(false),
            shown: shown.keep(),
            front: [
                front_near.keep(),
                front_near_p.keep(),
                front_seed.keep(),
                front_seed_p.keep(),
            ],
            front_seeding: !params.lod_no_front,
            region: region.keep(),
            bounds: [bounds_o.keep(), bounds_p.keep()],
            counters: counters.keep(),
            levels: levels.keep(),
            capacity,
            most,
            instances: lod.instance_count,
            chunks: lod.chunk_count,
            parity: std::cell::Cell::new(0),
            per: 1 << shift,
        })
    }

    /// The bindings of a cull phase of `view`.
    fn cull_bindings<'b>(
        &'b self,
        globals: &'b Buffer,
        lod: &'b LodBuffers,
        scene: &'b SceneBuffers,
        view: ViewIndex,
    ) -> Vec<(&'static str, &'b Buffer)> {
        let mut bindings = vec![
            ("GlobalsBlock", globals),
            ("lodBoundTex", &lod.bounds),
            ("Levels", &self.levels),
            ("List", &lod.lists),
            ("Counters", &self.counters),
            ("Visible", &self.visible),
            ("hizTex", &self.hiz_tiles[view as usize]),
            ("Region", &self.region),
            ("hizPrevTex", &self.hiz_prev[view as usize]),
            ("batchBoundTex", &lod.batch_bounds),
            ("cullOrderTex", &lod.cull_order),
            ("Deferred", &self.deferral),
        ];
        bindings.extend(scene.geometry());
        bindings
    }

    fn args_step<'b>(&'b self, p: &mut PassBuilder<'b>) {
        p.dispatch(
            &self.args,
            &LodArgsPush {
                per: self.per,
                capacity: self.capacity,
                local_size: LOCAL_SIZE,
                deferred: self.deferred(),
            },
            Grid::Groups([1, 1, 1]),
            &[("Counters", &self.counters)],
        );
    }

    /// The last steps of every cull phase: `list` (of `view`; counter
    /// words `list` too) emptied, the cull dispatched into it (an early
    /// phase over every instance; a late one, reading depth tiles of
    /// 2^hiz_shift pixels, over what the early one deferred), and the
    /// dispatch arguments of every list and deferral.
    #[allow(clippy::too_many_arguments)]
    fn cull_into<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        list: usize,
        view: ViewIndex,
        perspective: bool,
        hiz_shift: u32,
    ) -> Result<()> {
        let lod = lod_buffers(scene)?;
        // (only this list: the others' entries name spheres drawn already)
        let entries = (self.capacity + LOD_LIST_TAIL) as u64;
        p.fill_at(
            &lod.lists,
            list as u64 * entries * 8,
            entries * 8,
            BATCH_EMPTY,
        );
        let bindings = self.cull_bindings(globals, lod, scene, view);
        // (camera orthographic, perspective; the light)
        let pipes = match view {
            ViewIndex::Camera => perspective as usize,
            ViewIndex::Light => 2,
        };
        let push = LodCullPush {
            instances: self.instances,
            capacity: self.capacity,
            hiz_shift,
            reach: self.reach.get(),
            deferred: self.deferred(),
            chunks: self.chunks,
            parity: self.parity.get(),
            history: match view {
                ViewIndex::Camera => self.history_flag.get(),
                ViewIndex::Light => VISIBLE_PASSED,
            },
            // (emptied tiles hide nothing wherever it is placed: the
            // view itself)
            prev: self.prev_views.get()[view as usize]
                .or(self.last_views.borrow()[view as usize])
                .unwrap_or_default(),
        };
        let cull = &self.cull[pipes];
        if list < LATE {
            p.dispatch(
                &cull[CULL_EARLY as usize],
                &push,
                Grid::Invocations(self.instances as u64 + self.chunks as u64),
                &bindings,
            );
        } else {
            // (the early list's counter words hold its deferrals' arguments)
            let args = |word: u32| ((view as u32 * LOD_WORDS + word) * 4) as u64;
            for (mode, word) in [
                (CULL_DEFERRED_INSTANCES, LOD_DEFER_INSTANCE_ARGS),
                (CULL_DEFERRED_BATCHES, LOD_DEFER_BATCH_ARGS),
            ] {
                p.dispatch(
                    &cull[mode as usize],
                    &push,
                    Grid::Indirect(&self.counters, args(word)),
                    &bindings,
                );
            }
        }
        self.args_step(p);
        Ok(())
    }

    /// The steps of `lod_cull`: the camera's early list and its dispatch
    /// arguments.
    pub fn steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        perspective: bool,
    ) -> Result<()> {
        self.cull_steps(p, globals, scene, ViewIndex::Camera, perspective, None)
    }

    /// The steps of `light_cull` (after the camera's raster): the light
    /// texels of the camera's visible points (from `vis`, a `size` window)
    /// and their farthest depth from the light per receiver tile
    /// ([`receiver_shift`]), and
    /// the light's early list of what may shadow them (read as `reads`
    /// says; the light's depth tiles take it too).
    #[allow(clippy::too_many_arguments)]
    pub fn light_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        vis: &'b Buffer,
        perspective: bool,
        size: (u32, u32),
        reads: LightReads,
    ) -> Result<()> {
        self.reach.set(reads.reach);
        self.cull_steps(
            p,
            globals,
            scene,
            ViewIndex::Light,
            perspective,
            Some((vis, size, reads)),
        )
    }

    fn cull_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        view: ViewIndex,
        perspective: bool,
        vis: Option<(&'b Buffer, (u32, u32), LightReads)>,
    ) -> Result<()> {
        if view == ViewIndex::Camera {
            p.fill(&self.counters, self.counters.size, 0);
            // (a moved camera's atoms hidden behind last frame's tiles
            // where it saw them are rechecked whatever the tiles: the
            // word says the tiles changed)
            if self.camera_moved() {
                p.fill_at(&self.counters, LOD_TILES_CHANGED as u64 * 4, 4, 1);
            }
            if !self.history.replace(true) {
                p.fill(&self.visible, self.visible.size, 0);
                p.fill(&self.levels, self.levels.size, NO_LEVEL_YET);
                for b in &self.hiz_prev {
                    p.fill(b, b.size, 0);
                }
            }
        }
        if let Some((vis, (w, h), reads)) = vis {
            let region = self.light_region(reads.map, reads.slack);
            if !reads.preset {
                region.empty(p);
            }
            p.dispatch(
                &self.bounds[perspective as usize],
                &LodBoundsPush {
                    hiz_shift: region.shift,
                    slack: reads.slack,
                    pad: [0; 2],
                },
                Grid::Invocations(tiles(w, h, 16)),
                &[
                    ("GlobalsBlock", globals),
                    ("visWordTex", vis),
                    ("Region", &self.region),
                ],
            );
        }
        // (the early phase reads the last final image's tiles, emptied
        // where they cannot be placed: nothing hidden, every batch of the
        // instances last frame's flags name drawn early: `history_flag`)
        if self.prev_views.get()[view as usize].is_none() {
            let b = &self.hiz_prev[view as usize];
            p.fill(b, b.size, u32::MAX);
            if view == ViewIndex::Camera && self.front_seeding {
                self.front_steps(p, globals, scene, perspective)?;
            }
        }
        let shift = self.prev_shift[view as usize].get();
        self.cull_into(p, globals, scene, view as usize, view, perspective, shift)
    }

    /// Where the camera's early phase has no tiles to test against (no
    /// last frame, or a large move): its history flags set for the front
    /// instances only, the nearest per cell of the window
    /// (glsl/lod_front.comp), so that the early image covers the window
    /// and the late phase's tests hide what lies behind.
    fn front_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        perspective: bool,
    ) -> Result<()> {
        let lod = lod_buffers(scene)?;
        // (this frame's camera: note_views keeps it)
        let (w, h, ppu) = self.last_views.borrow()[0]
            .map_or((1, 1, 0.0), |v| (v.dims[0], v.dims[1], v.center[3]));
        let shift = front_shift(w, h, lod.instance_radius * ppu);
        // (the flag it sets is VISIBLE_PASSED: without last tiles to read
        // the camera's early phase reads no other, `note_views`)
        let push = LodFrontPush {
            instances: self.instances,
            parity: self.parity.get(),
            cell_shift: shift,
            pad: 0,
        };
        // (the cells lie in the camera's early depth tiles' buffer: this
        // frame's are built after the early raster, and nothing reads last
        // frame's, whose final tiles are `hiz_prev`)
        let cells = &self.hiz_tiles[0];
        p.fill(cells, tiles(w, h, 1 << shift) * 4, u32::MAX);
        let mut bindings = vec![
            ("GlobalsBlock", globals),
            ("lodBoundTex", &lod.bounds),
            ("Visible", &self.visible),
            ("Front", cells),
        ];
        bindings.extend(scene.geometry());
        for pipe in [perspective as usize, 2 + perspective as usize] {
            p.dispatch(
                &self.front[pipe],
                &push,
                Grid::Invocations(self.instances as u64),
                &bindings,
            );
        }
        Ok(())
    }

    /// Dispatches that build the depth tiles of `view`'s image `vis` (`w`
    /// x `h`) into `tiles_buf`: fine ones of 2^shift pixels, then coarse and
    /// super ones; with `compare`, LOD_TILES_CHANGED set where a fine (or
    /// 2-px) tile differs from last frame's.
    #[allow(clippy::too_many_arguments)]
    fn tiles_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        vis: &'b Buffer,
        (tiles_buf, compare): (&'b Buffer, bool),
        view: ViewIndex,
        (w, h): (u32, u32),
        shift: u32,
    ) {
        // (any other texel buffer where nothing is compared)
        let prev = &self.hiz_prev[view as usize];
        let hb = [
            ("GlobalsBlock", globals),
            ("visWordTex", vis),
            ("Hiz", tiles_buf),
            ("Region", &self.region),
            ("hizPrevTex", if compare { prev } else { vis }),
            ("Counters", &self.counters),
        ];
        let push = LodHizPush {
            view_index: view as u32,
            hiz_shift: shift,
            reach: self.reach.get(),
            receiver_shift: receiver_shift(w, h),
            compare: compare as u32,
            // (the camera's 2-px tiles, for its atoms: `micro_base`)
            micro_base: match view {
                ViewIndex::Camera => micro_base(w, h).unwrap_or(0),
                ViewIndex::Light => 0,
            },
            pad: [0; 2],
        };
        let fine = match view {
            ViewIndex::Camera => &self.hiz[0],
            ViewIndex::Light => &self.hiz[3],
        };
        p.dispatch(fine, &push, Grid::Invocations(tiles(w, h, 1 << shift)), &hb);
        for (level, side) in [(1, 8), (2, 64)] {
            p.dispatch(
                &self.hiz[level],
                &push,
                Grid::Invocations(tiles(w, h, side << shift)),
                &hb,
            );
        }
    }

    /// The steps of `lod_occlusion` (`light_occlusion`): the depth tiles
    /// of `view`'s early image `vis` (`w` x `h`), its late list and the
    /// arguments.
    #[allow(clippy::too_many_arguments)]
    pub fn occlusion_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        vis: &'b Buffer,
        view: ViewIndex,
        perspective: bool,
        size: (u32, u32),
    ) -> Result<()> {
        let shift = self.tiles_of(p, globals, vis, (view, Image::Early), size);
        let list = LATE + view as usize;
        self.cull_into(p, globals, scene, list, view, perspective, shift)
    }

    /// The depth tiles of `view`'s image `vis` (`size`): of its early
    /// image, the late phase's test (the camera's compared with last
    /// frame's), or of its final image, the next frame's early phase's.
    /// Returns their shift.
    pub fn tiles_of<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        vis: &'b Buffer,
        (view, image): (ViewIndex, Image),
        size: (u32, u32),
    ) -> u32 {
        let shift = hiz_shift(view, size.0, size.1);
        let v = view as usize;
        let (buf, compare) = match image {
            Image::Early => (&self.hiz_tiles[v], view == ViewIndex::Camera),
            Image::Final => {
                self.prev_shift[v].set(shift);
                (&self.hiz_prev[v], false)
            }
        };
        self.tiles_steps(p, globals, vis, (buf, compare), view, size, shift);
        shift
    }

    /// After a moved camera's late raster: the instances its final image
    /// `vis` (`size`, drawn from the LOD lists) shows, flagged
    /// VISIBLE_SHOWN in this frame's array (what the next frame's early
    /// phase lists after a small move: glsl/lod_shown.comp). Nothing for a
    /// still camera, whose flags of passing are as good.
    pub fn shown_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        vis: &'b Buffer,
        scene: &'b SceneBuffers,
        (w, h): (u32, u32),
    ) -> Result<()> {
        if !self.camera_moved() {
            return Ok(());
        }
        let lod = lod_buffers(scene)?;
        self.shown_written.set(true);
        p.dispatch(
            &self.shown,
            &LodShownPush {
                batch_shift: self.per.trailing_zeros(),
                parity: self.parity.get(),
                instances: self.instances,
                pad: 0,
            },
            Grid::Invocations((w as u64 * h as u64).div_ceil(SHOWN_RUN)),
            &[
                ("GlobalsBlock", globals),
                ("visWordTex", vis),
                ("batchTex", &lod.lists),
                ("Visible", &self.visible),
            ],
        );
        Ok(())
    }

    /// Before a frame's culls: the camera's and the light's GPU views, to
    /// know whether each moved since the last frame.
    pub fn note_views(&self, views: [&GpuView; 2]) {
        // (this frame reads what the last one wrote)
        self.parity.set(1 - self.parity.get());
        let mut last = self.last_views.borrow_mut();
        let small = last[0].is_some_and(|l| small_move(&l, views[0]));
        let mut prev = [None; 2];
        for (i, v) in views.into_iter().enumerate() {
            let moved = last[i].is_none_or(|l| bytemuck::bytes_of(&l) != bytemuck::bytes_of(v));
            self.moved[i].set(moved);
            // (after a small move only: the last tiles placed in the last
            // view send to the late phase what they hid, and the last
            // image seen from far elsewhere hides little of the new one's
            // late work; also the same projection and size, so the tiles
            // read alike)
            prev[i] = last[i].filter(|l| small_move(l, v));
            last[i] = Some(*v);
        }
        self.prev_views.set(prev);
        // (last frame's shown flags where it wrote them and the camera
        // moved a little since; a still camera's early phase tests the
        // instances that passed against last frame's tiles, valid again)
        let shown = self.shown_written.replace(false) && self.moved[0].get() && small;
        self.history_flag
            .set(if shown { VISIBLE_SHOWN } else { VISIBLE_PASSED });
    }

    /// The camera's depth tiles: of this frame's early image, of last
    /// frame's final image.
    pub fn camera_tiles(&self) -> (&Buffer, &Buffer) {
        (&self.hiz_tiles[0], &self.hiz_prev[0])
    }

    /// Whether the camera moved since the last frame.
    pub fn camera_moved(&self) -> bool {
        self.moved[0].get()
    }

    /// The view the camera's last final tiles were made in, where its
    /// atoms are placed to be tested against them: None where there are
    /// none yet or they were emptied (after a large move).
    pub fn camera_prev_view(&self) -> Option<GpuView> {
        self.prev_views.get()[0]
    }

    /// The shift of the camera's last final tiles (28: none yet).
    pub fn camera_prev_shift(&self) -> u32 {
        self.prev_shift[0].get()
    }

    /// `view`'s late list.
    pub fn late(&self, view: ViewIndex) -> LodView<'_> {
        self.list_view(LATE + view as usize)
    }

    /// `view`'s list (the camera's early one).
    pub fn view(&self, view: ViewIndex) -> LodView<'_> {
        self.list_view(view as usize)
    }

    fn list_view(&self, i: usize) -> LodView<'_> {
        LodView {
            base: i as u32 * (self.capacity + LOD_LIST_TAIL),
            capacity: self.capacity,
            counters: &self.counters,
            words: i as u32 * LOD_WORDS,
            args_offset: ((i as u32 * LOD_WORDS + LOD_ARGS) * 4) as u64,
        }
    }

    /// Each instance's level in the last frame (after the frame).
    pub fn levels(&self, ctx: &Context) -> Result<Vec<u32>> {
        self.levels.download_pod(ctx, 0, self.instances as u64)
    }

    /// The instances of the last frame's camera early list, an entry per
    /// batch listed (`lod`: the scene's lists).
    pub fn camera_early_instances(&self, ctx: &Context, lod: &LodBuffers) -> Result<Vec<u32>> {
        let word = self.counter_words(ctx)?;
        let n = word(0, LOD_BATCHES).min(self.capacity) as u64;
        if n == 0 {
            return Ok(Vec::new());
        }
        let entries: Vec<[u32; 2]> = lod.lists.download_pod(ctx, 0, n)?;
        Ok(entries
            .into_iter()
            .map(|e| e[0] & crate::gpu::consts::BATCH_INSTANCE_MASK)
            .collect())
    }

    /// Each instance's camera flags of the last frame (VISIBLE_PASSED,
    /// VISIBLE_SHOWN), as the next frame's early phase reads them.
    pub fn camera_flags(&self, ctx: &Context) -> Result<Vec<u32>> {
        let n = self.instances as u64;
        let both: Vec<u32> =
            self.visible
                .download_pod(ctx, (1 - self.parity.get()) as u64 * 2 * n, 2 * n)?;
        Ok(both.into_iter().step_by(2).collect())
    }

    /// The counters (LOD_VIEWS x LOD_WORDS words from the start).
    pub fn counters(&self) -> &Buffer {
        &self.counters
    }

    /// The last frame's counters (after the frame): `word(list, k)` reads
    /// counter word `k` of list `list`.
    fn counter_words(&self, ctx: &Context) -> Result<impl Fn(usize, u32) -> u32> {
        let w: Vec<u32> = self
            .counters
            .download_pod(ctx, 0, (LOD_VIEWS * LOD_WORDS) as u64)?;
        Ok(move |list: usize, k: u32| lod_word(&w, list, k))
    }

    /// What the last frame's cull kept (after the frame).
    pub fn counts(&self, ctx: &Context) -> Result<LodCounts> {
        let word = self.counter_words(ctx)?;
        Ok(LodCounts {
            camera_batches: word(0, LOD_BATCHES) + word(LATE, LOD_BATCHES),
            camera_spheres: word(0, LOD_SPHERES) + word(LATE, LOD_SPHERES),
            light_batches: word(1, LOD_BATCHES) + word(LATE + 1, LOD_BATCHES),
            light_spheres: word(1, LOD_SPHERES) + word(LATE + 1, LOD_SPHERES),
            late_spheres: word(LATE, LOD_SPHERES),
            light_late_spheres: word(LATE + 1, LOD_SPHERES),
            deferred: [0, 1].map(|v| [word(v, LOD_DEFER_INSTANCES), word(v, LOD_DEFER_BATCHES)]),
        })
    }

    /// Makes `lod`'s lists (camera, light, camera late, light late) of
    /// `capacity` batches each, then their tails (the old ones
    /// destroyed).
    fn set_lists(ctx: &Context, lod: &mut LodBuffers, capacity: u32) -> Result<()> {
        let entries = LOD_VIEWS * (capacity + LOD_LIST_TAIL);
        let lists = Buffer::storage(ctx, "LOD lists", entries as u64 * 8)?;
        let mut old = std::mem::replace(&mut lod.lists, lists);
        old.destroy(ctx);
        lod.list_entries = entries;
        Ok(())
    }

    /// Batches each list holds now.
    pub fn capacity(&self) -> u32 {
        self.capacity
    }

    /// Batch entries the deferral buffer holds now (after one per
    /// instance): as given, else [`deferral_room`] of the lists' capacity.
    fn deferred(&self) -> u32 {
        self.deferred_given
            .unwrap_or_else(|| deferral_room(self.capacity))
    }

    /// After a frame that drew the lists: if a list was given more batches
    /// than it holds (the cull dropped the rest), or more than three
    /// quarters of them (a viewer zooming in asks more frame after frame),
    /// makes them all LOD_MAX_STRIDE (4) times as long as the most asked (at
    /// most the full-detail batches): one level finer has up to 4x the
    /// batches, and an orthographic view switches every instance of a type
    /// in the same frame (meso 10^8 fly-in: 272 k -> 752 k batches in one
    /// notch). `words`: the frame's copy of the counters. Returns whether
    /// the frame overflowed and must be drawn again. The GPU must be idle.
    pub fn grow_lists(
        &mut self,
        ctx: &Context,
        lod: &mut LodBuffers,
        words: &[u32],
    ) -> Result<bool> {
        let asked = (0..LOD_VIEWS as usize)
            .map(|list| lod_word(words, list, LOD_BATCHES))
            .max()
            .unwrap_or(0);
        let overflow = asked > self.capacity;
        let capacity = asked
            .saturating_mul(crate::scene::instanced::lod::LOD_MAX_STRIDE)
            .clamp(asked.min(self.most), self.most);
        if asked as u64 * 4 <= self.capacity as u64 * 3 || capacity <= self.capacity {
            return Ok(overflow);
        }
        // A frame that fit keeps its lists until the next one: its ids are
        // their slots, which the AOVs read back.
        self.pending = Some(capacity);
        if overflow {
            self.apply_growth(ctx, lod)?;
        }
        Ok(overflow)
    }

    /// Before a frame (the GPU idle): the lists the last frame asked for.
    pub fn apply_growth(&mut self, ctx: &Context, lod: &mut LodBuffers) -> Result<()> {
        let Some(capacity) = self.pending.take() else {
            return Ok(());
        };
        Self::set_lists(ctx, lod, capacity)?;
        if self.deferred_given.is_none() {
            let d = deferral_buffer(ctx, self.instances + self.chunks, deferral_room(capacity))?;
            let mut old = std::mem::replace(&mut self.deferral, d);
            old.destroy(ctx);
        }
        log::debug!(
            "LOD lists grown from {} to {capacity} batches",
            self.capacity
        );
        self.capacity = capacity;
        Ok(())
    }

    /// The light's region words for a `map` light map and a lookup's
    /// depth `slack`.
    pub fn light_region(&self, map: (u32, u32), slack: f32) -> LightRegion<'_> {
        LightRegion {
            region: &self.region,
            shift: receiver_shift(map.0, map.1),
            slack,
            map,
        }
    }

    /// Device memory of the light region: its rectangle and receiver words
    /// (a fixed size: what the light map's tiles need at most).
    pub fn region_bytes(&self) -> u64 {
        self.region.size
    }

    /// Whether the lists grow before the next frame.
    pub fn growth_pending(&self) -> bool {
        self.pending.is_some()
    }

    /// Device memory: counters, levels, history and depth tiles (the
    /// lists are the scene's; the light region's words are the light
    /// map's, [`LodCull::region_bytes`]).
    pub fn memory_bytes(&self) -> u64 {
        self.counters.size
            + self.levels.size
            + self.visible.size
            + self.deferral.size
            + self.hiz_tiles.iter().map(|b| b.size).sum::<u64>()
            + self.hiz_prev.iter().map(|b| b.size).sum::<u64>()
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for p in self.cull.iter_mut().flatten() {
            p.destroy(ctx);
        }
        self.args.destroy(ctx);
        for p in &mut self.hiz {
            p.destroy(ctx);
        }
        self.visible.destroy(ctx);
        self.shown.destroy(ctx);
        for f in &mut self.front {
            f.destroy(ctx);
        }
        self.deferral.destroy(ctx);
        self.region.destroy(ctx);
        for p in &mut self.bounds {
            p.destroy(ctx);
        }
        for b in self.hiz_tiles.iter_mut().chain(&mut self.hiz_prev) {
            b.destroy(ctx);
        }
        self.counters.destroy(ctx);
        self.levels.destroy(ctx);
    }
}

crate::impl_destroy!(LodCull);

#[cfg(test)]
mod tests {
    use super::*;

    /// Front cells about a typical instance's radius wide (a power of two
    /// from 2 to 64 pixels), wider where they would be too many.
    #[test]
    fn front_cells_follow_the_instances_size() {
        assert_eq!(front_shift(1920, 1080, 25.4), 4);
        assert_eq!(front_shift(1920, 1080, 6.4), 2);
        assert_eq!(front_shift(1920, 1080, 101.7), 6);
        assert_eq!(front_shift(1920, 1080, 1000.0), 6);
        assert_eq!(front_shift(1920, 1080, 0.3), 1);
        // (2-px cells at 4K: 2,073,600 of them, past FRONT_CELLS)
        assert_eq!(front_shift(3840, 2160, 0.3), 2);
        assert!(tiles(16384, 16384, 1 << front_shift(16384, 16384, 0.0)) <= FRONT_CELLS as u64);
    }

    /// A small move: a turn up to 8 degrees, a zoom up to 1.5x, a pan up
    /// to half the image height, the same window; not past any of those.
    #[test]
    fn small_moves_are_told_from_large_ones() {
        let base = crate::camera::Camera::new(
            glam::DVec3::new(10.0, -5.0, 3.0),
            glam::DVec3::new(0.0, 0.0, -1.0),
            glam::DVec3::Y,
            200.0,
            None,
            400,
            300,
        )
        .unwrap();
        let view = |c: &crate::camera::Camera| c.to_gpu(0.0);
        let turned = |deg: f64| {
            let mut c = base;
            c.dir = glam::DQuat::from_rotation_y(deg.to_radians()) * c.dir;
            view(&c)
        };
        let zoomed = |f: f64| {
            let mut c = base;
            c.view_height *= f;
            view(&c)
        };
        // (300 px tall, 1.5 px per unit: half the height is 100 units)
        let panned = |u: f64| {
            let mut c = base;
            c.center += c.right * u;
            view(&c)
        };
        let b = view(&base);
        assert!(small_move(&b, &b));
        assert!(small_move(&b, &turned(7.0)) && !small_move(&b, &turned(9.0)));
        assert!(small_move(&b, &zoomed(1.4)) && !small_move(&b, &zoomed(1.6)));
        assert!(small_move(&b, &zoomed(1.0 / 1.4)) && !small_move(&b, &zoomed(1.0 / 1.6)));
        assert!(small_move(&b, &panned(90.0)) && !small_move(&b, &panned(110.0)));
        let mut wider = b;
        wider.dims[0] += 1;
        assert!(!small_move(&b, &wider));
    }

    /// The light's receiver tiles: its texels up to a 512^2 map, then
    /// coarser than its depth tiles, within the region buffer.
    #[test]
    fn receiver_tiles_fit_the_region_buffer() {
        assert_eq!(receiver_shift(512, 512), 0);
        assert_eq!(receiver_shift(1024, 1024), 1);
        assert_eq!(receiver_shift(2048, 2048), 2);
        assert_eq!(receiver_shift(16, 16), 0);
        for (w, h) in [(1, 16384), (8191, 8193), (16384, 16384), (600, 600)] {
            let s = receiver_shift(w, h);
            assert!(s >= hiz_shift(ViewIndex::Light, w, h), "{w}x{h}");
            assert!(tiles(w, h, 1 << s) <= RECEIVER_TILES as u64, "{w}x{h}");
            assert!(s == 0 || tiles(w, h, 1 << (s - 1)) > RECEIVER_TILES as u64);
        }
    }

    /// Fine tiles of 4 px where they fit (1080p, a 4096^2 light map;
    /// a 512^2 or 1024^2 light map's of one texel), coarser on the largest
    /// windows, and never more words than the buffer holds.
    #[test]
    fn depth_tiles_are_as_fine_as_the_buffer_allows() {
        use ViewIndex::{Camera, Light};
        assert_eq!(hiz_shift(Camera, 1920, 1080), 2);
        assert_eq!(hiz_shift(Camera, 4096, 4096), 2);
        assert_eq!(hiz_shift(Camera, 4097, 4096), 3);
        assert_eq!(hiz_shift(Camera, 16384, 16384), 4);
        assert_eq!(hiz_shift(Camera, 1, 1), 2);
        assert_eq!(hiz_shift(Light, 512, 512), 0);
        assert_eq!(hiz_shift(Light, 1024, 1024), 0);
        assert_eq!(hiz_shift(Light, 2048, 2048), 1);
        assert_eq!(hiz_shift(Light, 4096, 4096), 2);
        for (w, h) in [
            (1, 16384),
            (16384, 1),
            (8191, 8193),
            (16384, 16384),
            (640, 480),
        ] {
            for view in [Camera, Light] {
                let s = hiz_shift(view, w, h);
                let count = |s: u32| tiles(w, h, 1 << s);
                assert!(count(s) <= HIZ_FINE_TILES as u64, "{w}x{h}");
                assert!(count(s) + count(s + 3) <= HIZ_WORDS, "{w}x{h}");
                // the finest that fits
                let least = if view == Camera { HIZ_MIN_SHIFT } else { 0 };
                assert!(
                    s == least || count(s - 1) > HIZ_FINE_TILES as u64,
                    "{w}x{h}"
                );
            }
        }
    }
}
