//! Compute rasterization of sphere impostors into a 64-bit depth|id
//! visibility buffer (camera view or key-light view, same code).

use crate::error::Result;
use crate::gpu::GpuView;
use crate::gpu::blocks::RasterPush;
use crate::gpu::consts::{
    CAM_EARLY, CAM_LATE, CAM_PER_SLOT, CAM_RECHECK, LOD_ARGS, LOD_BATCH_ARGS, LOD_RECHECK_ARGS,
    R_ARGS, R_BANDS_FULL, R_BANDS_REQ, R_BANDS_RUN, RASTER_ORDER, SCENE_PLAIN,
};
use crate::passes::bands::{BandArgs, BandCounters, BandJob, BandPipelines, JobList};
use crate::passes::scene::{SCENE_ATTRIBUTES, SCENE_GEOMETRY, SceneBuffers, SceneGeom};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::vk::guard::Destroy;
use crate::vk::pipeline::{PipelineDesc, rw, texel, uniform};
use crate::vk::{Buffer, ComputePipeline, Context, PassBuilder};
use glam::DVec3;

/// Footprints above this many pixels are split into 8-row bands run by whole
/// workgroups; below, one invocation loops over the pixels itself. Measured
/// on lavapipe (capsid at 1080p, raster pass): 100k spheres 1525 ms with 64,
/// 1249 ms with 256, 371 ms with 1024, 1M unchanged (517-549 ms): CPU
/// implementations want long per-invocation loops. On GPUs long loops
/// serialise a lane, so they get a smaller threshold (not yet measured).
pub fn big_area(ctx: &Context) -> u32 {
    if ctx.info.kind == "cpu" { 1024 } else { 256 }
}
/// Band jobs a frame's raster sequences may each queue at first: past
/// that a sphere's own invocation draws it (loop-limited on lavapipe) and
/// the frame is drawn again with a list twice as long
/// ([`RasterPass::after_frame`]).
pub const JOB_CAPACITY: u32 = 1 << 20;
/// u64 words after the visibility buffer that no pass may touch (GPU-AV does
/// not check atomics, so tests look at these instead).
pub const VIS_GUARD_WORDS: u64 = 64;
pub const GUARD_PATTERN: u64 = 0x5AFE_C0DE_5AFE_C0DE;
/// Counter words (src/gpu_consts.rs R_*): bands requested, bands run,
/// indirect dispatch arguments.
pub const RASTER_COUNTERS: BandCounters = BandCounters {
    job_capacity: JOB_CAPACITY,
    requested: R_BANDS_REQ,
    run: R_BANDS_RUN,
    args: R_ARGS,
};

/// Which views' LOD lists are drawn per batch (glsl/raster.comp
/// `batch_part`; else per slot, as tests compare).
#[derive(Clone, Copy, Debug)]
pub struct PerBatch {
    pub light: bool,
    pub camera: bool,
}

/// Which view a raster pass draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewIndex {
    Camera = 0,
    Light = 1,
}

/// A list of batches the rasterizer visits in place of a view's order
/// (the LOD cull's, src/stages/raster/lod.rs, in the scene's
/// `LodBuffers::lists`), dispatched indirectly.
#[derive(Clone, Copy)]
pub struct LodView<'b> {
    /// Its first entry in the lists.
    pub base: u32,
    /// The most entries it holds (its count may pass them: the frame is
    /// drawn again with longer lists).
    pub capacity: u32,
    pub counters: &'b Buffer,
    /// Its words in `counters` (LOD_BATCHES, LOD_ARGS, ... from it).
    pub words: u32,
    /// Byte offset of its indirect dispatch arguments in `counters`.
    pub args_offset: u64,
}

/// What one rasterization reads and writes: the scene, and the
/// depth|id target (the camera's visibility buffer or a light map).
#[derive(Clone, Copy)]
pub struct RasterIo<'b> {
    pub globals: &'b Buffer,
    pub scene: &'b SceneBuffers,
    pub target: &'b Buffer,
    /// Texels of `target` (cleared first).
    pub texels: u64,
    /// The view's list from the LOD cull (this frame's), visited in place
    /// of its order; None: every atom, in the view's order.
    pub lod: Option<LodView<'b>>,
    /// Clear `target` first (not for the camera's late phase, which adds
    /// to the early one's image).
    pub clear: bool,
    /// The camera's list drawn per batch, each atom tested against depth
    /// tiles first (with `lod`); None: per slot.
    pub tested: Option<TileTest<'b>>,
}

/// The most rows a window may have for the camera's per-batch passes (the
/// raster's and the see-through fragments'): a candidate's band appends
/// (at most 1,025 each) stay within lavapipe's loop bound (glsl/raster.comp).
pub const CAM_BATCH_MAX_ROWS: u32 = 8192;

/// How the camera's LOD list is tested per atom (glsl/raster.comp
/// `batch_part`): the mode (CAM_EARLY, CAM_RECHECK, CAM_LATE) and the
/// depth tiles of this frame's early image and of last frame's final one,
/// both of fine tiles of 2^`shift` pixels, and of 2-px tiles from word
/// `micro_base` (0: none).
#[derive(Clone, Copy)]
pub struct TileTest<'b> {
    pub mode: u32,
    pub now: &'b Buffer,
    pub prev: &'b Buffer,
    /// The view `prev` was made in.
    pub prev_view: GpuView,
    pub shift: u32,
    pub micro_base: u32,
}

pub struct RasterPass {
    /// Orthographic views (the camera's and the light's) and perspective
    /// camera views (specialization constant 2).
    pipes: [BandPipelines; 2],
    /// The same with SEE_THROUGH (constant 3: the camera view skips
    /// spheres whose alpha is below 1), made the first time a frame has
    /// see-through spheres.
    see_through: Option<[BandPipelines; 2]>,
    /// The key light's LOD lists drawn per batch (constant 4,
    /// LIGHT_BATCHES: glsl/raster.comp `batch_part`), made the first time
    /// a frame draws them (instanced scenes; else per slot). The per-batch
    /// variants are per-sphere pipelines only: their bands are the
    /// orthographic per-slot pipeline's (the same band code: ~10 ms of
    /// start-up each).
    light_batches: Option<ComputePipeline>,
    /// Whether this renderer draws the light's lists per batch.
    light_per_batch: bool,
    /// The camera's LOD lists per batch, tested against depth tiles
    /// (constant 5: CAM_EARLY, CAM_RECHECK, CAM_LATE), for orthographic
    /// and perspective cameras (constant 2), each made the first time a
    /// frame that draws the lists has such a camera.
    cam_batches: [Option<[ComputePipeline; 3]>; 2],
    /// The same with SEE_THROUGH (their atoms' per-slot path skips
    /// see-through spheres), made the first time such a frame has
    /// see-through spheres.
    cam_batches_see: [Option<[ComputePipeline; 3]>; 2],
    /// Whether this renderer draws the camera's lists per batch.
    cam_per_batch: bool,
    /// Kept to make them.
    scene: u32,
    args: BandArgs,
    jobs: JobList,
    big_area: u32,
    /// RASTER_COUNTERS' words, then R_BANDS_FULL (kept over a frame).
    counters: Buffer,
    /// The order each view visits the spheres in ([`view_order`]).
    orders: [ViewOrder; 2],
}

/// One view's sphere order, one u32 per sphere (instanced scenes: per
/// batch), and the direction it was sorted for (none: never sorted, or the
/// spheres moved since).
struct ViewOrder {
    name: &'static str,
    buf: Buffer,
    dir: Option<DVec3>,
}

impl Destroy for ViewOrder {
    fn destroy_with(&mut self, ctx: &Context) {
        self.buf.destroy(ctx);
    }
}

impl ViewOrder {
    fn new(ctx: &Context, name: &'static str) -> Result<Self> {
        Ok(ViewOrder {
            name,
            buf: Buffer::storage(ctx, name, 4)?,
            dir: None,
        })
    }

    fn stale(&self, dir: DVec3) -> bool {
        self.dir.is_none_or(|o| {
            o.normalize_or_zero().dot(dir.normalize_or_zero()) < ORDER_STALE_DEG.to_radians().cos()
        })
    }

    fn set(&mut self, ctx: &Context, geom: &SceneGeom, dir: DVec3) -> Result<()> {
        let order = view_order(geom, dir);
        let bytes = (order.len().max(1) * 4) as u64;
        if self.buf.size != bytes {
            let fresh = Buffer::storage(ctx, self.name, bytes)?;
            let mut old = std::mem::replace(&mut self.buf, fresh);
            old.destroy(ctx);
        }
        if !order.is_empty() {
            self.buf.upload(ctx, 0, bytemuck::cast_slice(&order))?;
        }
        self.dir = Some(dir);
        Ok(())
    }
}

/// Spheres per run of a view order (one 64-invocation workgroup).
pub const ORDER_RUN: usize = LOCAL_SIZE as usize;

/// A view's direction may turn this far (degrees) before its order is
/// sorted again: any order rasterizes the same image, a stale one only
/// turns fewer visits away early.
pub const ORDER_STALE_DEG: f64 = 30.0;

/// The order in which a view looking along `dir` visits the spheres: runs
/// of [`ORDER_RUN`] consecutive input spheres (neighbours in space for
/// molecules, grids and procedural scenes; an instanced scene's batches,
/// listed as batches, not spheres), split by their mean centre
/// across the view into two halves of equal run count (one side of the
/// image, then the other), each sorted front to back. On lavapipe each of
/// the two worker threads takes a fixed half of a dispatch's workgroups:
/// so both go front to back, and the rasterizer's early-depth test turns
/// more of the later, farther visits away before their 64-bit atomics;
/// both have alike work where the scene is alike on both sides; and their
/// atomics and early-depth reads fall on different cache lines. Measured
/// (1080p, raster pass, 2 threads), input order -> halves interleaved by
/// depth rank -> halves split across the view: camera view of the 1M
/// capsid 92 -> 76 -> 66 ms (light view 47.1 -> 42.6 -> 24.7 on a faster
/// day: 27.9 with depth ranks), of the 1M lattice 84 -> 37 -> 35 (light 27
/// -> 23), of the 1TII 6x6x5 lattice 80 -> 45 -> 45 (light 26 -> 24); the
/// 1M random cube (its runs span the cube) unchanged. In input order a
/// lattice's layers come back to front, and the capsid's first half is
/// shell, its second shell and the hidden core. With one thread the
/// capsid's camera view does not change (144 vs 148 ms): the gain is the
/// halves'. Runs stay contiguous, so a vector's spheres still lie side by
/// side.
pub fn view_order(geom: &SceneGeom, dir: DVec3) -> Vec<u32> {
    let d = dir.normalize_or_zero();
    let across = d.any_orthonormal_vector();
    // (across, depth, run) of each run's mean centre.
    let all = geom.runs(ORDER_RUN);
    let mut runs: Vec<(f64, f64, usize)> = all
        .iter()
        .enumerate()
        .map(|(k, (c, _))| (c.dot(across), c.dot(d), k))
        .collect();
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let half = runs.len().div_ceil(2);
    let (first, second) = runs.split_at_mut(half);
    first.sort_by(|a, b| a.1.total_cmp(&b.1));
    second.sort_by(|a, b| a.1.total_cmp(&b.1));
    if geom.orders_batches() {
        return runs.iter().map(|&(_, _, k)| k as u32).collect();
    }
    let mut order = Vec::with_capacity(geom.len() as usize);
    for &(_, _, k) in runs.iter() {
        order.extend(all[k].1.clone());
    }
    order
}

/// A visibility buffer with its guard words.
pub fn vis_buffer(ctx: &Context, name: &str, pixels: u64) -> Result<Buffer> {
    let buf = Buffer::storage(ctx, name, (pixels + VIS_GUARD_WORDS) * 8)?;
    let guard = vec![GUARD_PATTERN; VIS_GUARD_WORDS as usize];
    let buf = ctx.guard(buf);
    buf.upload(ctx, pixels * 8, bytemuck::cast_slice(&guard))?;
    Ok(buf.keep())
}

impl RasterPass {
    pub const NAME: &'static str = "raster";

    /// The rasterizer's pipelines (orthographic, perspective) with or
    /// without SEE_THROUGH.
    fn pipelines(ctx: &Context, scene: u32, see_through: bool) -> Result<[BandPipelines; 2]> {
        let st = see_through as u32;
        let ortho = ctx.guard(Self::pipeline(ctx, scene, &[0, st])?);
        let persp = Self::pipeline(ctx, scene, &[1, st])?;
        Ok([ortho.keep(), persp])
    }

    /// The rasterizer's two pipelines with constants 2, 3, ... (PERSP,
    /// SEE_THROUGH, LIGHT_BATCHES, CAM_BATCHES).
    fn pipeline(ctx: &Context, scene: u32, constants: &[u32]) -> Result<BandPipelines> {
        Self::with_desc(scene, |desc| BandPipelines::new(ctx, desc, constants))
    }

    /// Its per-sphere pipeline alone (a per-batch variant).
    fn sphere_pipeline(ctx: &Context, scene: u32, constants: &[u32]) -> Result<ComputePipeline> {
        Self::with_desc(scene, |desc| BandPipelines::pass(ctx, desc, 0, constants))
    }

    fn with_desc<T>(scene: u32, make: impl FnOnce(&PipelineDesc) -> Result<T>) -> Result<T> {
        let bindings = [
            &[
                uniform("GlobalsBlock"),
                rw("Vis"),
                rw("Jobs"),
                rw("Counters"),
                texel("visWordTex", ash::vk::Format::R32_UINT),
                texel("orderTex", ash::vk::Format::R32_UINT),
                texel("hizTex", ash::vk::Format::R32_UINT),
                texel("hizPrevTex", ash::vk::Format::R32_UINT),
            ][..],
            &SCENE_GEOMETRY,
            &SCENE_ATTRIBUTES,
        ]
        .concat();
        make(&PipelineDesc {
            name: "raster spheres",
            shader: spirv::RASTER_COMP,
            bindings: &bindings,
            push_size: std::mem::size_of::<RasterPush>() as u32,
            local_size: LOCAL_SIZE,
            constants: &[],
            scene,
        })
    }

    /// The rasterizer for a scene of this SCENE_SPEC (passes::scene);
    /// `per_batch`: an instanced scene's light and camera lists per batch.
    /// `band_jobs`: the job list's first length (None: [`JOB_CAPACITY`]).
    pub fn new(
        ctx: &Context,
        scene: u32,
        per_batch: PerBatch,
        band_jobs: Option<u32>,
    ) -> Result<Self> {
        let [ortho, persp] = Self::pipelines(ctx, scene, false)?;
        let ortho = ctx.guard(ortho);
        let persp = ctx.guard(persp);
        let args = ctx.guard(BandArgs::new(ctx, "raster band args")?);
        let jobs = ctx.guard(JobList::new(
            ctx,
            "raster band jobs",
            band_jobs.unwrap_or(JOB_CAPACITY),
        )?);
        let counters = ctx.guard(crate::passes::bands::counters_buffer(
            ctx,
            "raster counters",
            (R_BANDS_FULL as u64 + 1) * 4,
        )?);
        // (R_BANDS_FULL: no frame fills it)
        counters.upload(ctx, R_BANDS_FULL as u64 * 4, &0u32.to_le_bytes())?;
        let camera = ctx.guard(ViewOrder::new(ctx, "camera sphere order")?);
        let light = ViewOrder::new(ctx, "light sphere order")?;
        Ok(RasterPass {
            pipes: [ortho.keep(), persp.keep()],
            see_through: None,
            light_batches: None,
            light_per_batch: per_batch.light && scene & 0xFF != SCENE_PLAIN,
            cam_batches: [None, None],
            cam_batches_see: [None, None],
            cam_per_batch: per_batch.camera && scene & 0xFF != SCENE_PLAIN,
            scene,
            args: args.keep(),
            jobs: jobs.keep(),
            big_area: big_area(ctx),
            counters: counters.keep(),
            orders: [camera.keep(), light],
        })
    }

    /// Makes the SEE_THROUGH pipelines (the first frame with see-through
    /// spheres; the per-batch camera's with `batches`: it draws the LOD
    /// lists, from a `perspective` camera or not).
    pub fn enable_see_through(
        &mut self,
        ctx: &Context,
        batches: bool,
        perspective: bool,
    ) -> Result<()> {
        if self.see_through.is_none() {
            self.see_through = Some(Self::pipelines(ctx, self.scene, true)?);
        }
        let slot = &mut self.cam_batches_see[perspective as usize];
        if batches && self.cam_per_batch && slot.is_none() {
            *slot = Some(Self::cam_pipelines(ctx, self.scene, true, perspective)?);
        }
        Ok(())
    }

    /// The camera's per-batch pipelines (CAM_EARLY, CAM_RECHECK, CAM_LATE),
    /// with SEE_THROUGH or not, for a perspective camera or not.
    fn cam_pipelines(
        ctx: &Context,
        scene: u32,
        see: bool,
        persp: bool,
    ) -> Result<[ComputePipeline; 3]> {
        let constants = |mode| [persp as u32, see as u32, 0, mode];
        let pipe = |mode| Self::sphere_pipeline(ctx, scene, &constants(mode));
        let early = ctx.guard(pipe(CAM_EARLY)?);
        let recheck = ctx.guard(pipe(CAM_RECHECK)?);
        let late = pipe(CAM_LATE)?;
        Ok([early.keep(), recheck.keep(), late])
    }

    /// Makes the per-batch pipelines (the first frame that draws the LOD
    /// lists, the light's with `light`, the camera's for a `perspective`
    /// camera or not; nothing for a view drawn per slot).
    pub fn enable_batches(&mut self, ctx: &Context, light: bool, perspective: bool) -> Result<()> {
        if light && self.light_per_batch && self.light_batches.is_none() {
            self.light_batches = Some(Self::sphere_pipeline(ctx, self.scene, &[0, 0, 1])?);
        }
        let slot = &mut self.cam_batches[perspective as usize];
        if self.cam_per_batch && slot.is_none() {
            *slot = Some(Self::cam_pipelines(ctx, self.scene, false, perspective)?);
        }
        Ok(())
    }

    /// Whether the camera's LOD lists may be drawn per batch, tested
    /// against depth tiles, in a window `h` rows high from a `perspective`
    /// camera or an orthographic one: the pipelines are made (with
    /// `see_through` spheres, the SEE_THROUGH ones), and the window's rows
    /// keep an invocation's band appends within lavapipe's loop bound
    /// (glsl/raster.comp).
    pub fn cam_batches_fit(&self, perspective: bool, see_through: bool, h: u32) -> bool {
        self.cam_pipes(see_through, perspective).is_some() && h <= CAM_BATCH_MAX_ROWS
    }

    /// The camera's per-batch pipelines for frames with `see_through`
    /// spheres or without, from a `perspective` camera or not (None: not
    /// made).
    fn cam_pipes(&self, see_through: bool, perspective: bool) -> Option<&[ComputePipeline; 3]> {
        let sets = if see_through {
            &self.cam_batches_see
        } else {
            &self.cam_batches
        };
        sets[perspective as usize].as_ref()
    }

    /// After a frame, the GPU idle: whether a sphere's bands did not fit
    /// the job list (R_BANDS_FULL); the list is then twice as long
    /// and the frame must be drawn again (its own invocation drew that
    /// sphere, and on lavapipe a footprint past 65,535 pixels loses rows).
    /// `full`: the frame's copy of that word ([`Self::bands_flag`]).
    pub fn after_frame(&mut self, ctx: &Context, full: bool) -> Result<bool> {
        if !full {
            return Ok(false);
        }
        let at = R_BANDS_FULL as u64;
        self.counters.upload(ctx, at * 4, &0u32.to_le_bytes())?;
        self.jobs.grow(ctx, "the raster")?;
        Ok(true)
    }

    /// The band-overflow word (R_BANDS_FULL: buffer, byte offset) the
    /// host reads after each frame.
    pub fn bands_flag(&self) -> (&Buffer, u64) {
        (&self.counters, R_BANDS_FULL as u64 * 4)
    }

    /// Entries of the band job list.
    pub fn job_capacity(&self) -> u32 {
        self.jobs.capacity()
    }

    /// Band jobs and counters (with the visibility buffers they serve).
    pub fn memory_bytes(&self) -> u64 {
        self.jobs.buf.size + self.counters.size
    }

    /// The view orders, 4 bytes per sphere (instanced: per batch) each
    /// (with the scene).
    pub fn order_bytes(&self) -> u64 {
        self.orders.iter().map(|o| o.buf.size).sum()
    }

    /// Whether `view`'s order must be sorted (again) for `dir`.
    pub fn order_stale(&self, view: ViewIndex, dir: DVec3) -> bool {
        self.orders[view as usize].stale(dir)
    }

    /// The spheres moved (a trajectory frame): every order is sorted again
    /// before its view is next drawn.
    pub fn spheres_moved(&mut self) {
        for o in &mut self.orders {
            o.dir = None;
        }
    }

    /// `view`'s order buffer (what its raster visits the spheres in).
    pub fn order(&self, view: ViewIndex) -> &Buffer {
        &self.orders[view as usize].buf
    }

    /// Whether `view` has an order sorted for the current spheres.
    pub fn order_ready(&self, view: ViewIndex) -> bool {
        self.orders[view as usize].dir.is_some()
    }

    /// Sorts `view`'s order for these spheres and direction and uploads it
    /// (no frame may be using it: the caller waits first).
    pub fn set_order(
        &mut self,
        ctx: &Context,
        view: ViewIndex,
        geom: &SceneGeom,
        dir: DVec3,
    ) -> Result<()> {
        self.orders[view as usize].set(ctx, geom, dir)
    }

    /// Clears `io.target` (its first `io.texels` words) and rasterizes
    /// every sphere into it from `view` (steps of the caller's pass).
    pub fn steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        io: &RasterIo<'b>,
        view: ViewIndex,
        perspective: bool,
        see_through: bool,
    ) -> Result<()> {
        let RasterIo {
            globals,
            scene,
            target: vis,
            texels: pixels,
            ref lod,
            clear,
            tested,
        } = *io;
        // (a LOD list's slots are ids, from its first; a view order's
        // batches are the static table's)
        let (sphere_count, list_base) = match (lod.as_ref(), scene.lod.as_ref()) {
            (Some(l), Some(buffers)) => {
                ((buffers.list_entries - l.base) << (scene.spec >> 8), l.base)
            }
            (Some(_), None) => {
                return Err(crate::error::Error::Internal(
                    "a LOD list of a scene without levels".into(),
                ));
            }
            (None, _) => (scene.slots, RASTER_ORDER),
        };
        let order = &self.orders[view as usize];
        if lod.is_none() && !self.order_ready(view) {
            return Err(crate::error::Error::Internal(format!(
                "the {} was not sorted",
                order.name
            )));
        }
        if clear {
            p.fill(vis, pixels * 8, u32::MAX);
        }
        // (not R_BANDS_FULL: kept over the frame)
        p.fill(&self.counters, R_BANDS_FULL as u64 * 4, 0);
        let push = RasterPush {
            view_index: view as u32,
            big_area: self.big_area,
            job_capacity: self.jobs.capacity(),
            sphere_count,
            list_base,
            hiz_shift: tested.map_or(0, |t| t.shift),
            micro_base: tested.map_or(0, |t| t.micro_base),
            pad: 0,
            prev: tested.map_or(GpuView::default(), |t| t.prev_view),
        };
        let pipes = match (&self.see_through, see_through) {
            (Some(p), true) => p,
            (None, true) => {
                return Err(crate::error::Error::Internal(
                    "see-through raster pipelines were not made".into(),
                ));
            }
            _ => &self.pipes,
        };
        // (the key light's LOD lists per batch where the scene allows it)
        // (and the camera's, tested, where asked)
        let per_batch = match (view, tested) {
            (ViewIndex::Light, _) => self.light_batches.as_ref(),
            (ViewIndex::Camera, Some(t)) if t.mode != CAM_PER_SLOT => {
                let Some(c) = self.cam_pipes(see_through, perspective) else {
                    return Err(crate::error::Error::Internal(
                        "the camera's per-batch pipelines were not made".into(),
                    ));
                };
                c.get(t.mode as usize - CAM_EARLY as usize)
            }
            _ => None,
        };
        // (the recheck's arguments are empty where the camera's tiles are
        // last frame's: glsl/lod_args.comp)
        let args = match tested {
            Some(t) if t.mode == CAM_RECHECK => LOD_RECHECK_ARGS,
            _ => LOD_BATCH_ARGS,
        };
        let batches = match (per_batch, lod.as_ref()) {
            (Some(b), Some(l)) => Some((b, l.args_offset + ((args - LOD_ARGS) * 4) as u64)),
            _ => None,
        };
        // (a per-batch variant's bands: the per-slot one's of its
        // projection; its opaque spheres alone are queued)
        let projection = (view == ViewIndex::Camera && perspective) as usize;
        let (spheres, bands) = match batches {
            Some((b, _)) => (b, &self.pipes[projection].bands),
            None => (&pipes[projection].spheres, &pipes[projection].bands),
        };
        let mut bindings = vec![
            ("GlobalsBlock", globals),
            ("Vis", vis),
            ("Jobs", &self.jobs.buf),
            ("Counters", &self.counters),
            ("visWordTex", vis),
            (
                "orderTex",
                match &scene.lod {
                    Some(l) if lod.is_some() => &l.lists,
                    _ => &order.buf,
                },
            ),
            // (untested: any texel buffer, unread)
            ("hizTex", tested.map_or(vis, |t| t.now)),
            ("hizPrevTex", tested.map_or(vis, |t| t.prev)),
        ];
        bindings.extend(scene.geometry());
        bindings.extend(scene.attributes());
        self.args.steps(
            p,
            &BandJob {
                spheres,
                bands,
                push: &push,
                bindings: &bindings,
                sphere_count,
                indirect: lod.as_ref().map(|l| {
                    (
                        l.counters,
                        batches.map_or(l.args_offset, |(_, offset)| offset),
                    )
                }),
                counters: &self.counters,
                layout: &self.jobs.layout(RASTER_COUNTERS),
            },
        );
        Ok(())
    }

    /// The pass `name`: the key light's view rasterized into `map` (the
    /// ISSM's id map, the baseline's depth map).
    pub fn record_light_map<'b>(
        &'b self,
        rec: &mut crate::vk::Recorder,
        name: &'static str,
        io: &RasterIo<'b>,
    ) -> Result<()> {
        rec.pass(name, |p| self.steps(p, io, ViewIndex::Light, false, false))
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for p in self
            .pipes
            .iter_mut()
            .chain(self.see_through.iter_mut().flatten())
        {
            p.destroy(ctx);
        }
        for p in self
            .light_batches
            .iter_mut()
            .chain(self.cam_batches.iter_mut().flatten().flatten())
            .chain(self.cam_batches_see.iter_mut().flatten().flatten())
        {
            p.destroy(ctx);
        }
        self.args.destroy(ctx);
        self.jobs.destroy(ctx);
        self.counters.destroy(ctx);
        for o in &mut self.orders {
            o.destroy_with(ctx);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::GpuSphere;

    /// The order is a permutation of whole runs, and each half of it (what
    /// one lavapipe thread takes) goes front to back along the view.
    #[test]
    fn view_order_is_runs_front_to_back_in_each_half() {
        // 1000 spheres on a jittered line through the origin, in a shuffled
        // run order: runs lie at different depths along (1, 1, 1).
        let mut geom: Vec<GpuSphere> = Vec::new();
        for k in 0..1000u32 {
            let run = (k / ORDER_RUN as u32 * 7919) % 16;
            let t = run as f32 * 10.0 + (k % 5) as f32 * 0.1;
            geom.push([t, t + 0.5, t - 0.5, 1.0]);
        }
        let dir = DVec3::new(-1.0, -1.0, -1.0);
        let order = view_order(&SceneGeom::Plain(geom.clone()), dir);
        let mut seen = order.clone();
        seen.sort_unstable();
        assert_eq!(seen, (0..1000).collect::<Vec<u32>>(), "not a permutation");
        let runs: Vec<&[u32]> = {
            let mut v = Vec::new();
            let mut i = 0;
            while i < order.len() {
                let first = order[i] as usize;
                assert_eq!(first % ORDER_RUN, 0, "a run starts mid-run at {i}");
                let len = ORDER_RUN.min(geom.len() - first);
                v.push(&order[i..i + len]);
                i += len;
            }
            v
        };
        for r in &runs {
            assert!(r.windows(2).all(|w| w[1] == w[0] + 1), "run not contiguous");
        }
        let depth = |r: &[u32]| {
            r.iter()
                .map(|&i| {
                    let s = geom[i as usize];
                    DVec3::new(s[0] as f64, s[1] as f64, s[2] as f64).dot(dir.normalize())
                })
                .sum::<f64>()
                / r.len() as f64
        };
        let half = runs.len().div_ceil(2);
        for part in [&runs[..half], &runs[half..]] {
            let d: Vec<f64> = part.iter().map(|r| depth(r)).collect();
            assert!(
                d.windows(2).all(|w| w[0] <= w[1]),
                "not front to back: {d:?}"
            );
        }
        // nearest to the light first: the largest t along -(1,1,1)
        assert!(depth(runs[0]) < depth(runs[half - 1]));
    }

    /// Runs scattered over a plane containing the view direction: the
    /// first half holds the runs on one side across the view, the second
    /// those on the other, each front to back.
    #[test]
    fn view_order_splits_the_halves_across_the_view() {
        let dir = DVec3::new(0.3, -1.0, 0.2).normalize();
        let across = dir.any_orthonormal_vector();
        let runs: usize = 37;
        let mut geom: Vec<GpuSphere> = Vec::new();
        for k in 0..runs {
            // pseudo-random across and depth positions per run
            let a = ((k * 7919) % 101) as f64 - 50.0;
            let z = ((k * 104_729) % 97) as f64 - 48.0;
            for j in 0..ORDER_RUN {
                let c = across * (a + 0.01 * j as f64) + dir * z;
                geom.push([c.x as f32, c.y as f32, c.z as f32, 1.0]);
            }
        }
        let order = view_order(&SceneGeom::Plain(geom.clone()), dir);
        let at = |r: usize| {
            let s = geom[order[r * ORDER_RUN] as usize];
            let c = DVec3::new(s[0] as f64, s[1] as f64, s[2] as f64);
            (c.dot(across), c.dot(dir))
        };
        let half = runs.div_ceil(2);
        let first: Vec<(f64, f64)> = (0..half).map(at).collect();
        let second: Vec<(f64, f64)> = (half..runs).map(at).collect();
        let max_first = first.iter().map(|p| p.0).fold(f64::MIN, f64::max);
        let min_second = second.iter().map(|p| p.0).fold(f64::MAX, f64::min);
        assert!(max_first < min_second, "halves overlap across the view");
        for part in [&first, &second] {
            assert!(
                part.windows(2).all(|w| w[0].1 <= w[1].1 + 1e-6),
                "not front to back: {part:?}"
            );
        }
    }

    #[test]
    fn an_empty_scene_has_an_empty_order() {
        assert!(view_order(&SceneGeom::Plain(Vec::new()), DVec3::Z).is_empty());
    }
}
crate::impl_destroy!(RasterPass);
