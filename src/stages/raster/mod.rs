//! The raster stage: the camera's visibility buffer (64-bit depth|id per
//! pixel) from the compute rasterizer ([`compute`], which also draws the
//! light-space maps) or the graphics baseline ([`graphics`]), and the tile
//! lists of the covered regions ([`coverage`]) the per-pixel passes after
//! it run on.

pub mod compute;
pub mod coverage;
pub mod graphics;
pub mod lod;

use crate::error::{Error, Result};
use crate::gpu::consts::{CAM_EARLY, CAM_LATE, CAM_RECHECK};
use crate::passes::scene::SceneBuffers;
use crate::passes::tiles::{Tiles, lists_buffer};
use crate::vk::guard::Destroy;
use crate::vk::{Buffer, Context, Recorder};
use compute::{PerBatch, RasterIo, RasterPass, TileTest, ViewIndex};
use coverage::CoveragePass;
use graphics::GraphicsRasterPass;
use lod::{Image, LightReads, LodCull, LodView};

/// The stage's screen targets: the visibility buffer (8 B/px + guard
/// words) and the tile lists (4 B per 256 pixels).
pub struct RasterTargets {
    pub vis: Buffer,
    pub tiles: Buffer,
}

impl RasterTargets {
    pub fn new(ctx: &Context, width: u32, height: u32) -> Result<Self> {
        let pixels = width as u64 * height as u64;
        let vis = ctx.guard(compute::vis_buffer(ctx, "visibility", pixels)?);
        let tiles = lists_buffer(ctx, width, height)?;
        Ok(RasterTargets {
            vis: vis.keep(),
            tiles,
        })
    }

    pub fn bytes(&self) -> u64 {
        self.vis.size + self.tiles.size
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.vis.destroy(ctx);
        self.tiles.destroy(ctx);
    }
}

crate::impl_destroy!(RasterTargets);

/// What the stage draws: the scene, seen by the camera (`globals`).
pub struct RasterInputs<'a> {
    pub globals: &'a Buffer,
    pub scene: &'a SceneBuffers,
    pub perspective: bool,
    /// The image (graphics baseline) and the frame's buffers (compute:
    /// the window) in pixels.
    pub image: (u32, u32),
    pub size: (u32, u32),
    /// See-through spheres are drawn by the fragment lists, not here.
    pub see_through: bool,
    /// The LOD cull's camera list (this frame's) in place of the order.
    pub lod: bool,
    /// The camera's pixels per world unit (perspective: at its view
    /// plane).
    pub pixels_per_unit: f64,
}

/// The largest typical atom radius, in pixels, at which the camera's LOD
/// lists are drawn per batch (closer, per slot). Meso 10^9 at 1080p,
/// camera raster (+ recheck) per slot -> per batch: 2,025 A (~0.9 px)
/// 323 -> 166 ms, 506 A (~3.6 px) 197 -> 165, 400 A 171 -> 141, but
/// 330 A 144 -> 193 and 127 A (~15 px) 138 -> 149; the 10^12 scene at
/// 127 A 117 -> 243: one invocation draws its part's candidates one after
/// another, or in bands, where the per-slot raster draws a vector of them
/// side by side.
const CAM_BATCH_MAX_PIXELS: f64 = 5.0;

/// The same for a perspective camera, at its view plane (atoms nearer the
/// eye are larger on screen). Meso 10^9 at 1080p, `--fov 20`, camera
/// raster per slot -> per batch: ~2 px (1,012 A) 389 -> 347 ms, ~2.7 px
/// 370 -> 359, ~4 px 162 -> 194; `--fov 10` at ~0.9 px 819 -> 594.
const CAM_BATCH_MAX_PIXELS_PERSP: f64 = 3.0;

/// The camera's visibility buffer as a rasterization's target.
fn camera_io<'a>(
    io: &RasterInputs<'a>,
    t: &'a RasterTargets,
    lod: Option<LodView<'a>>,
    clear: bool,
) -> RasterIo<'a> {
    let (w, h) = io.size;
    RasterIo {
        globals: io.globals,
        scene: io.scene,
        target: &t.vis,
        texels: w as u64 * h as u64,
        lod,
        clear,
        tested: None,
    }
}

pub struct RasterStage {
    /// The compute rasterizer (also the light views' and its sphere orders).
    pub compute: RasterPass,
    coverage: CoveragePass,
    /// The vertex/fragment baseline, when `--raster graphics`.
    graphics: Option<GraphicsRasterPass>,
    /// The views' lists of an instanced scene with levels of detail.
    pub lod: Option<LodCull>,
    /// Whether the last frame recorded ran the LOD cull.
    lod_used: std::cell::Cell<bool>,
    /// Whether the last frame recorded drew a camera list per batch (its
    /// early or late phase).
    cam_batched: std::cell::Cell<bool>,
    /// The scene's typical (median) atom radius, world units
    /// ([`CAM_BATCH_MAX_PIXELS`], [`CAM_BATCH_MAX_PIXELS_PERSP`]).
    atom_radius: f32,
}

impl RasterStage {
    /// The stage for a scene (its SCENE_SPEC and levels of detail, its
    /// typical atom radius `atom_radius`). `lod`: the LOD lists' initial
    /// length (`--lod-list-batches`), the cull's deferral room, the views
    /// drawn per batch.
    pub fn new(
        ctx: &Context,
        graphics: bool,
        scene_buffers: &mut SceneBuffers,
        lod: &crate::settings::LodParams,
        atom_radius: f32,
        band_jobs: Option<u32>,
    ) -> Result<Self> {
        let scene = scene_buffers.spec;
        if graphics && scene & 0xFF != crate::gpu::consts::SCENE_PLAIN {
            return Err(Error::Input(
                "--raster graphics draws plain scenes only: an instanced scene needs --raster compute"
                    .into(),
            ));
        }
        let graphics = ctx.guard(if graphics {
            Some(GraphicsRasterPass::new(ctx)?)
        } else {
            None
        });
        let per_batch = PerBatch {
            light: !lod.lod_light_per_slot,
            camera: !lod.lod_camera_per_slot,
        };
        let compute = ctx.guard(RasterPass::new(ctx, scene, per_batch, band_jobs)?);
        let coverage = ctx.guard(CoveragePass::new(ctx)?);
        let lod = match &mut scene_buffers.lod {
            Some(l) => Some(LodCull::new(ctx, scene, l, lod)?),
            None => None,
        };
        Ok(RasterStage {
            compute: compute.keep(),
            coverage: coverage.keep(),
            graphics: graphics.keep(),
            lod,
            lod_used: std::cell::Cell::new(false),
            cam_batched: std::cell::Cell::new(false),
            atom_radius,
        })
    }

    /// After a frame: whether it must be drawn again because a LOD list
    /// (the lists, `scene`'s) or the band job list overflowed (grown). The
    /// GPU must be idle.
    /// `bands_full`: the frame's band flag; `lod_words`: its copy of the
    /// LOD counters ([`Self::lod_counters`]).
    pub fn after_frame(
        &mut self,
        ctx: &Context,
        scene: &mut SceneBuffers,
        bands_full: bool,
        lod_words: &[u32],
    ) -> Result<bool> {
        let jobs = self.compute.after_frame(ctx, bands_full)?;
        let lists = match (&mut self.lod, &mut scene.lod) {
            (Some(l), Some(buffers)) if self.lod_used.get() => {
                l.grow_lists(ctx, buffers, lod_words)?
            }
            _ => false,
        };
        Ok(jobs || lists)
    }

    /// Whether the LOD lists grow before the next frame.
    pub fn growth_pending(&self) -> bool {
        self.lod.as_ref().is_some_and(|l| l.growth_pending())
    }

    /// Before a frame, the GPU idle: the LOD lists grow to what the last
    /// frame asked (`LodCull::apply_growth`).
    pub fn before_frame(&mut self, ctx: &Context, scene: &mut SceneBuffers) -> Result<()> {
        match (&mut self.lod, &mut scene.lod) {
            (Some(l), Some(buffers)) => l.apply_growth(ctx, buffers),
            _ => Ok(()),
        }
    }

    /// `lod_cull`: this frame's camera list, when the scene has levels of
    /// detail. Returns whether it was recorded.
    pub fn record_cull(
        &self,
        rec: &mut Recorder,
        globals: &Buffer,
        scene: &SceneBuffers,
        perspective: bool,
        views: [&crate::gpu::GpuView; 2],
    ) -> Result<bool> {
        let Some(l) = &self.lod else {
            return Ok(false);
        };
        l.note_views(views);
        self.lod_used.set(true);
        rec.pass(LodCull::NAME, |p| l.steps(p, globals, scene, perspective))?;
        Ok(true)
    }

    /// `lod_occlusion` and `raster_late`: the camera's instances that were
    /// not drawn early and are not hidden behind what was, added to its
    /// visibility buffer (after `record` with `io.lod`).
    pub fn record_late(
        &self,
        rec: &mut Recorder,
        io: &RasterInputs,
        t: &RasterTargets,
    ) -> Result<()> {
        let Some(l) = &self.lod else {
            return Ok(());
        };
        // The early list again where its atoms were tested against last
        // frame's tiles: those they hid that this frame's early image does
        // not (what the early image hides could not win a pixel; so every
        // atom that shows is drawn, whatever last frame was).
        let mut again = camera_io(io, t, Some(l.view(ViewIndex::Camera)), false);
        again.tested = self.tile_test(io, CAM_EARLY).map(|t| TileTest {
            mode: CAM_RECHECK,
            ..t
        });
        // A moved camera's recheck comes before the late test, and the
        // early tiles are made again after it: its early image lacks the
        // atoms whose pixels changed hands (a 1/1000 degree turn at 2,025 A
        // leaves holes along silhouettes), and a hole in a tile lets every
        // batch over it through to the late list (3.4 M spheres against
        // 0.1 M at 640x360).
        let recheck_first = again.tested.is_some() && l.camera_moved();
        rec.pass(LodCull::OCCLUSION, |p| {
            if recheck_first {
                l.tiles_of(
                    p,
                    io.globals,
                    &t.vis,
                    (ViewIndex::Camera, Image::Early),
                    io.size,
                );
                self.compute
                    .steps(p, &again, ViewIndex::Camera, io.perspective, io.see_through)?;
            }
            l.occlusion_steps(
                p,
                io.globals,
                io.scene,
                &t.vis,
                ViewIndex::Camera,
                io.perspective,
                io.size,
            )
        })?;
        let mut target = camera_io(io, t, Some(l.late(ViewIndex::Camera)), false);
        target.tested = self.tile_test(io, CAM_LATE);
        self.cam_batched
            .set(self.cam_batched.get() || target.tested.is_some());
        rec.pass(LodCull::LATE, |p| {
            if again.tested.is_some() && !recheck_first {
                self.compute
                    .steps(p, &again, ViewIndex::Camera, io.perspective, io.see_through)?;
            }
            // (see-through spheres: skipped here too, the fragments' lists
            // draw them)
            self.compute.steps(
                p,
                &target,
                ViewIndex::Camera,
                io.perspective,
                io.see_through,
            )?;
            // (the final image's depth tiles: next frame's early batches)
            l.tiles_of(
                p,
                io.globals,
                &t.vis,
                (ViewIndex::Camera, Image::Final),
                io.size,
            );
            l.shown_steps(p, io.globals, &t.vis, io.scene, io.size)?;
            Ok(())
        })
    }

    /// `light_cull` (after `record_late`): the light's list of what may
    /// shadow a point the camera sees (whose lookup reads as `reads` says).
    pub fn record_light_cull(
        &self,
        rec: &mut Recorder,
        io: &RasterInputs,
        t: &RasterTargets,
        reads: LightReads,
    ) -> Result<()> {
        let Some(l) = &self.lod else {
            return Ok(());
        };
        rec.pass(LodCull::LIGHT_CULL, |p| {
            l.light_steps(
                p,
                io.globals,
                io.scene,
                &t.vis,
                io.perspective,
                io.size,
                reads,
            )
        })
    }

    /// The LOD cull, when the last frame recorded ran it (what its
    /// counters and levels then hold).
    pub fn last_cull(&self) -> Option<&LodCull> {
        self.lod.as_ref().filter(|_| self.lod_used.get())
    }

    /// The LOD cull's counters (LOD_VIEWS x LOD_WORDS words), when the
    /// frame recorded ran it: the host reads them after the frame.
    pub fn lod_counters(&self) -> Option<&Buffer> {
        self.last_cull().map(|l| l.counters())
    }

    /// Whether the last frame recorded drew the camera's LOD lists per
    /// batch, each atom tested against depth tiles (in its early or late
    /// phase).
    pub fn camera_per_batch(&self) -> bool {
        self.cam_batched.get()
    }

    /// A frame is recorded without the LOD cull.
    pub fn no_cull(&self) {
        self.lod_used.set(false);
    }

    /// `view`'s LOD list, when the scene has levels of detail.
    pub fn lod_view(&self, view: ViewIndex) -> Option<LodView<'_>> {
        self.lod.as_ref().map(|l| l.view(view))
    }

    /// The camera's early and late LOD lists (what the see-through
    /// fragments visit in a frame that draws the lists).
    pub fn camera_lists(&self) -> Option<[LodView<'_>; 2]> {
        self.lod
            .as_ref()
            .map(|l| [l.view(ViewIndex::Camera), l.late(ViewIndex::Camera)])
    }

    /// The per-batch raster pipelines (a frame that draws the LOD lists;
    /// the light's with `light`; the camera's for a `perspective` camera
    /// or not).
    pub fn enable_batches(&mut self, ctx: &Context, light: bool, perspective: bool) -> Result<()> {
        self.compute.enable_batches(ctx, light, perspective)
    }

    /// How the camera's LOD list of this phase (CAM_EARLY, CAM_LATE; the
    /// recheck is the early one's) is tested per atom: None where it is
    /// drawn per slot (a window too tall, atoms large on screen, per-batch
    /// drawing off) and, before the late phase, where there are no last
    /// tiles to read (none yet, another projection or size; a moved
    /// camera's are read where it saw each atom).
    fn tile_test(&self, io: &RasterInputs, mode: u32) -> Option<TileTest<'_>> {
        let l = self.lod.as_ref()?;
        let (w, h) = io.size;
        let max = if io.perspective {
            CAM_BATCH_MAX_PIXELS_PERSP
        } else {
            CAM_BATCH_MAX_PIXELS
        };
        let small = self.atom_radius as f64 * io.pixels_per_unit <= max;
        if !io.lod
            || !small
            || !self
                .compute
                .cam_batches_fit(io.perspective, io.see_through, h)
        {
            return None;
        }
        let shift = lod::hiz_shift(ViewIndex::Camera, w, h);
        let (now, prev) = l.camera_tiles();
        let prev_view = l.camera_prev_view();
        if mode != CAM_LATE && (prev_view.is_none() || l.camera_prev_shift() != shift) {
            return None;
        }
        Some(TileTest {
            mode,
            now,
            prev,
            prev_view: prev_view.unwrap_or_default(),
            shift,
            micro_base: lod::micro_base(w, h).unwrap_or(0),
        })
    }

    /// The camera's depth tiles of this frame's final image, once
    /// `record_late` made them (`size`: the frame's window): their buffer,
    /// fine tiles' shift and 2-px tiles' first word (0: none).
    pub fn final_camera_tiles(&self, (w, h): (u32, u32)) -> Option<(&Buffer, u32, u32)> {
        let l = self.lod.as_ref()?;
        let shift = lod::hiz_shift(ViewIndex::Camera, w, h);
        Some((
            l.camera_tiles().1,
            shift,
            lod::micro_base(w, h).unwrap_or(0),
        ))
    }

    /// Makes the pipelines that leave see-through spheres to the fragment
    /// lists (the first frame that has some; `batches`: it draws the LOD
    /// lists, from a `perspective` camera or not).
    pub fn enable_see_through(
        &mut self,
        ctx: &Context,
        batches: bool,
        perspective: bool,
    ) -> Result<()> {
        self.compute.enable_see_through(ctx, batches, perspective)?;
        self.coverage.enable_see_through(ctx)
    }

    /// `raster`: the camera's visibility buffer (with `io.see_through`
    /// the opaque spheres' only).
    pub fn record(&self, rec: &mut Recorder, io: &RasterInputs, t: &RasterTargets) -> Result<()> {
        let lod = if io.lod {
            self.lod_view(ViewIndex::Camera)
        } else {
            None
        };
        let mut target = camera_io(io, t, lod, true);
        target.tested = self.tile_test(io, CAM_EARLY);
        self.cam_batched.set(target.tested.is_some());
        rec.pass(RasterPass::NAME, |p| {
            match &self.graphics {
                Some(g) => g.steps(p, &target, io.image),
                None => self.compute.steps(
                    p,
                    &target,
                    ViewIndex::Camera,
                    io.perspective,
                    io.see_through,
                )?,
            }
            Ok(())
        })
    }

    /// `coverage` (with tile lists): the tiles the per-pixel passes run
    /// (`counts`: the see-through fragment counts, when there are some).
    pub fn record_tiles<'a>(
        &self,
        rec: &mut Recorder,
        globals: &Buffer,
        t: &'a RasterTargets,
        counts: Option<&Buffer>,
        size: (u32, u32),
        lists: bool,
    ) -> Result<Tiles<'a>> {
        if !lists {
            return Ok(Tiles::All);
        }
        rec.pass(CoveragePass::NAME, |p| {
            self.coverage
                .steps(p, globals, &t.vis, counts, &t.tiles, size)
        })?;
        Ok(Tiles::Lists(&t.tiles))
    }

    /// Device memory of the sphere orders and LOD cull (scene), the
    /// rasterizer's band buffers (visibility) and the light cull's region
    /// (light_cull: it grows with the light map, not the spheres).
    pub fn memory(&self) -> (u64, u64, u64) {
        let lists = self.lod.as_ref().map_or(0, |l| l.memory_bytes());
        (
            self.compute.order_bytes() + lists,
            self.compute.memory_bytes(),
            self.lod.as_ref().map_or(0, |l| l.region_bytes()),
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.compute.destroy(ctx);
        self.coverage.destroy(ctx);
        self.graphics.destroy_with(ctx);
        self.lod.destroy_with(ctx);
    }
}
