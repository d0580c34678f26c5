//! The renderer: scene buffers, screen targets, the passes, and frames in
//! flight. A frame is recorded by [`graph`] (the one pass list). Settings
//! change through setters that update uniforms and push constants; a
//! shadow technique or SSDO is created the first time it is chosen and
//! kept, so the viewer never rebuilds the renderer.

pub mod frame;
pub mod graph;
pub mod targets;
pub mod tiles;

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::gpu::{Globals, GpuSphere, SphereAttr};
use crate::passes::blur::{BlurPass, BlurPush};
use crate::passes::coverage::CoveragePass;
use crate::passes::raster::{RasterPass, ViewIndex};
use crate::passes::raster_graphics::GraphicsRasterPass;
use crate::passes::shade::{ShadeMode, ShadePass};
use crate::passes::shadows::deep::{DeepShadows, DeepStats};
use crate::passes::shadows::issm::Issm;
use crate::passes::shadows::osm::OpacityShadows;
use crate::passes::shadows::shadow_map::ShadowMap;
use crate::passes::shadows::{
    self, FrameCheck, Lookup, LookupKind, ShadowParams, ShadowSetup, ShadowTechnique,
};
use crate::passes::ssdo::{PrepPush, Receivers, SphereBuffers, SsdoPass, SsdoPush, Taps};
use crate::scene::Scene;
use crate::semantic::{self, LevelChoice};
use crate::settings::{RasterMode, RenderSettings, ShadowMode, SsdoMode};
use crate::vk::guard::Destroy;
use crate::vk::{Buffer, Context, PassTimes, Recorder};
use ash::vk;
use frame::FrameSlot;
use glam::DVec3;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use targets::Targets;

pub use graph::SHADOW_DIFFUSE;

/// Renderers constructed in this process (tests check the viewer makes one).
pub static RENDERERS_CREATED: AtomicU64 = AtomicU64::new(0);

/// Frames the deep lists may ask to render again (pool growth) before the
/// frame fails.
const MAX_RETRIES: usize = 4;

pub struct Renderer<'c> {
    ctx: &'c Context,
    settings: RenderSettings,
    /// Per-frame resources, so a frame can be recorded while the previous
    /// one still runs (the viewer); `render_frame` uses them one at a time.
    slots: Vec<FrameSlot>,
    next_slot: usize,
    res: Resources,
}

/// A shadow technique made once and kept; `stale` after the light or the
/// spheres changed while another technique was active.
struct Kept {
    technique: Box<dyn ShadowTechnique>,
    stale: bool,
}

impl Destroy for Kept {
    fn destroy_with(&mut self, ctx: &Context) {
        self.technique.destroy(ctx);
    }
}

/// The SSDO, screen-space shadow and blur pipelines, and the per-sphere
/// receivers' buffers once a frame has used them.
struct SsdoState {
    pass: SsdoPass,
    blur: BlurPass,
    spheres: Option<SphereBuffers>,
}

impl Destroy for SsdoState {
    fn destroy_with(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.blur.destroy(ctx);
        self.spheres.destroy_with(ctx);
    }
}

/// Push constants of the screen-space passes for one frame.
pub(crate) struct SsdoParams {
    pub prep: PrepPush,
    pub ssdo: SsdoPush,
    pub taps: Taps,
    /// Blur taps on each side (one of [`BLUR_RADII`]).
    pub blur_radius: i32,
    pub blur: BlurPush,
    /// The screen-space key-light march (`--shadows none` with SSDO).
    pub screen: ShadowParams,
}

impl SsdoParams {
    /// How far (pixels) a pixel's SSDO value reaches back through the blur
    /// and the upsample: each blur axis reads `blur_radius` pixels, or
    /// blocks, then the upsample the blocks next to the pixel's own.
    pub fn blur_reach_px(&self) -> u32 {
        let r = self.blur_radius.max(0) as u32;
        if self.taps.per_block() {
            crate::gpu::consts::SSDO_BLOCK * (r + 2)
        } else {
            r
        }
    }
}

/// SSDO taps when spheres are large on screen: per 2x2 block (the AO is
/// smooth over a block there), 8 directions x (1 near + 5 far steps),
/// blurred 2 blocks each side and upsampled. Spearman with the ray-traced
/// AO (tests/ao.rs scene at 1280x960, radius ~30 px): 12 x (1+4) 0.937,
/// 8 x (1+4) 0.935, 8 x (1+5) 0.938; per pixel (before) 0.936.
pub const SSDO_TAPS_LARGE: (Taps, i32) = (
    Taps {
        dirs: 8,
        steps: 5,
        receivers: Receivers::Block,
        perspective: false,
    },
    2,
);
/// ... and when they are small (typical radius under
/// [`SSDO_SMALL_RADIUS_PX`] pixels): per pixel, 8 directions x (1 + 5
/// steps), blurred 2 px each side.
pub const SSDO_TAPS_SMALL: (Taps, i32) = (
    Taps {
        dirs: 8,
        steps: 5,
        receivers: Receivers::Pixel,
        perspective: false,
    },
    2,
);
/// ... and when they are a few pixels wide (typical radius under
/// [`SSDO_SPHERE_RADIUS_PX`]): per visible sphere, SSDO_SPHERE_DIRS
/// directions (8 azimuths x 4 elevations) from the surface point facing
/// each, the 4 elevations of an azimuth sharing its 12 taps along one
/// screen line; weighted per pixel by its normal in shade; no blur (no
/// per-pixel noise). Spearman with the ray-traced AO (tests/ao.rs scene x
/// 27 at radius ~1.4 / ~0.7 / ~2.8 px), and the capsid's `ssdo` ms at
/// 1080p: 8 taps per line 0.851 / 0.834 / 0.843, 88 ms; 12: 0.874 /
/// 0.860 / 0.867, 111 ms; 16: 0.881 / 0.864 / 0.875, 133 ms; 32 spiral
/// directions x 5 taps each (unshared) 0.858 / 0.847 / 0.853, 151 ms.
pub const SSDO_TAPS_SPHERE: (Taps, i32) = (
    Taps {
        dirs: crate::gpu::consts::SSDO_SPHERE_DIRS,
        steps: 12,
        receivers: Receivers::Sphere,
        perspective: false,
    },
    0,
);
/// Below this typical sphere radius on screen (pixels) SSDO runs per
/// visible sphere. Spearman per sphere vs per pixel: ~1.4 px 0.874 vs
/// 0.827, ~1.7 px 0.862 vs 0.850, ~2.1 px 0.863 vs 0.867, ~2.8 px 0.867
/// vs 0.884: the per-pixel path ranks a little better from about 2 px, at
/// 2.5x the cost (the 1M capsid at 1080p, 2.8 px, is below this).
pub const SSDO_SPHERE_RADIUS_PX: f64 = 3.0;
/// Below this typical sphere radius on screen (pixels) the small set: per
/// block the AO loses the pixel-to-pixel creases of small spheres.
/// Spearman of the ao AOV with the ray-traced reference (tests/ao.rs
/// scene), per block vs per pixel: radius ~8 px 0.865 vs 0.929, ~16 px
/// 0.922 vs 0.938, ~30 px 0.937 vs 0.936; 9x the atoms at ~3 px 0.623 vs
/// 0.871.
pub const SSDO_SMALL_RADIUS_PX: f64 = 16.0;

/// Everything on the GPU except the frame slots.
pub(crate) struct Resources {
    sphere_count: u32,
    /// CPU copy of the geometry: light views are fitted to it.
    geom: Vec<GpuSphere>,
    /// Bounding sphere of the sphere centres (camera depth offsets, zoom).
    bounds: (DVec3, f64),
    /// Typical sphere radius (screen-space effect radii), useful hierarchy
    /// levels and zoom thresholds of the semantic level choice.
    typical_radius: f64,
    levels: Vec<u32>,
    thresholds: Vec<f64>,
    globals: Globals,
    /// Write the colour buffer as BGRA (for BGRA swapchains).
    bgra: bool,
    spheres: Buffer,
    attrs: Buffer,
    /// One RGBA8 word per sphere (the colour of `attrs`, compact).
    colors: Buffer,
    targets: Targets,
    raster: RasterPass,
    coverage: CoveragePass,
    /// The vertex/fragment baseline, when `--raster graphics`.
    raster_graphics: Option<GraphicsRasterPass>,
    shade: ShadePass,
    techniques: Vec<Kept>,
    /// Index into `techniques` of the active one (None = `--shadows none`).
    active: Option<usize>,
    ssdo: Option<SsdoState>,
    /// The active technique's light-space structure is up to date (nothing
    /// it depends on changed since it was built): skip its passes.
    light_cached: bool,
    /// Reuse light-space structures while valid (`set_light_cache`).
    light_cache: bool,
    /// Kept host-visible buffer for `set_positions`.
    staging: Option<Buffer>,
}

/// Typical sphere radius (median of a sample) to scale screen-space effects.
fn typical_radius(scene: &Scene) -> f32 {
    let step = (scene.spheres.len() / 4096).max(1);
    let mut r: Vec<f32> = scene
        .spheres
        .iter()
        .step_by(step)
        .map(|s| s.radius)
        .collect();
    r.sort_by(|a, b| a.total_cmp(b));
    r.get(r.len() / 2).copied().unwrap_or(1.0)
}

pub use crate::camera::default_camera;

/// As `Scene::bounding_sphere`, from the GPU geometry.
fn bounding_sphere(geom: &[GpuSphere]) -> (DVec3, f64) {
    let Some(first) = geom.first() else {
        return (DVec3::ZERO, 0.0);
    };
    let c0 = glam::Vec3::new(first[0], first[1], first[2]);
    let (lo, hi) = geom.iter().fold((c0, c0), |(lo, hi), g| {
        let c = glam::Vec3::new(g[0], g[1], g[2]);
        (lo.min(c), hi.max(c))
    });
    let c = (lo + hi) * 0.5;
    let r = geom
        .iter()
        .map(|g| glam::Vec3::new(g[0], g[1], g[2]).distance(c) + g[3])
        .fold(0.0f32, f32::max);
    (c.as_dvec3(), r as f64)
}

fn normalized(v: DVec3) -> [f32; 4] {
    // (validated directions; the fallback only keeps NaN off the GPU)
    let l = crate::camera::unit(v).unwrap_or(DVec3::NEG_Z);
    [l.x as f32, l.y as f32, l.z as f32, 0.0]
}

impl Resources {
    fn active_shadow(&self) -> Option<&dyn ShadowTechnique> {
        self.active.map(|i| self.techniques[i].technique.as_ref())
    }

    fn setup<'a>(&'a self, ctx: &'a Context, settings: &'a RenderSettings) -> ShadowSetup<'a> {
        ShadowSetup {
            ctx,
            spheres: &self.geom,
            light_dir: settings.light,
            settings,
        }
    }

    /// Depth offset that keeps a view's orthographic depth keys positive.
    fn depth_offset(&self, view: &Camera) -> f64 {
        let (c, r) = self.bounds;
        (c - view.center).length() + r + 1.0
    }

    /// Puts the active technique's light view (or the camera) in the globals.
    fn update_light_view(&mut self, settings: &RenderSettings) {
        let light = self.active_shadow().map(|t| *t.light());
        self.globals.light = match light {
            Some(l) => l.to_gpu(self.depth_offset(&l)),
            None => settings.camera.to_gpu(self.depth_offset(&settings.camera)),
        };
        self.globals.light_dir = normalized(settings.light);
    }

    fn level_choice(&self, cam: &Camera) -> LevelChoice {
        semantic::choose(
            semantic::zoom_distance(cam, self.bounds.0),
            &self.thresholds,
            &self.levels,
        )
    }

    /// Screen-space radii in world units (at least a few pixels so far
    /// views still sample) and the semantic level for this camera.
    pub(crate) fn ssdo_params(&self, settings: &RenderSettings) -> SsdoParams {
        let cam = &settings.camera;
        let r = self.typical_radius;
        let px = 1.0 / cam.pixels_per_unit();
        let choice = self.level_choice(cam);
        // the blur's (and the upsample's) region level: the one weighted more
        let level_b = choice.blend >= 0.5;
        let taps = if r / px < SSDO_SPHERE_RADIUS_PX {
            SSDO_TAPS_SPHERE
        } else if r / px < SSDO_SMALL_RADIUS_PX {
            SSDO_TAPS_SMALL
        } else {
            SSDO_TAPS_LARGE
        };
        SsdoParams {
            prep: PrepPush {
                level_a: choice.level_a,
                level_b: choice.level_b,
                pad: [0; 2],
            },
            ssdo: SsdoPush {
                r_near: (2.0 * r).max(2.0 * px) as f32,
                // 12 radii: the rank correlation of the ambient visibility
                // with Tachyon's unbounded sky-light AO (tests/look.rs) is
                // 0.90/0.84 at 8 radii, 0.94/0.90 at 12, 0.95/0.93 at 16
                // (1TII / 3P3W): the same taps, so the same cost.
                r_far: (12.0 * r).max(8.0 * px) as f32,
                blend: choice.blend,
                bounce: 1.0,
                level_a: choice.level_a,
                level_b: choice.level_b,
                blur_level_b: level_b as u32,
                pad: 0,
            },
            taps: Taps {
                perspective: cam.fov_deg.is_some(),
                ..taps.0
            },
            blur_radius: taps.1,
            blur: BlurPush {
                sigma_z: (0.5 * r).max(px) as f32,
                level_b: level_b as u32,
                pad: [0; 2],
            },
            screen: ShadowParams {
                f0: [
                    (6.0 * r).max(6.0 * px) as f32,
                    (2.0 * r).max(px) as f32,
                    0.0,
                    0.0,
                ],
                u: [12, 0, 0, 0],
                ..Default::default()
            },
        }
    }

    /// How shade reads key-light visibility this frame.
    pub(crate) fn lookup(&self, settings: &RenderSettings) -> Lookup<'_> {
        match self.active_shadow() {
            Some(t) => t.lookup(settings.opacity),
            None if settings.ssdo_on() => {
                Lookup::plain(LookupKind::Screen, self.ssdo_params(settings).screen)
            }
            None => Lookup::plain(LookupKind::None, ShadowParams::default()),
        }
    }

    pub(crate) fn shade_mode(&self, settings: &RenderSettings, lookup: &Lookup) -> ShadeMode {
        let taps = self.ssdo_params(settings).taps;
        ShadeMode {
            kind: lookup.kind,
            soft: lookup.soft,
            ao: settings.ssdo_on(),
            ao_half: settings.ssdo_on() && taps.per_block(),
            ao_sphere: settings.ssdo_on() && taps.per_sphere(),
            swap_rb: self.bgra,
            aovs: settings.aovs,
            core_only: lookup.core_only(),
            quad: lookup.quad(),
            outline: self.outline_px(settings) > 0,
            wide: settings.look.color16,
            fog: settings.look.fog.is_some_and(|f| f.0[1] > f.0[0]),
            perspective: settings.camera.fov_deg.is_some(),
            lists: settings.tile_lists && self.outline_px(settings) == 0,
        }
    }

    /// Silhouette line width in buffer pixels.
    pub(crate) fn outline_px(&self, settings: &RenderSettings) -> u32 {
        settings.look.outline.round() as u32
    }

    /// Makes the pipelines this frame's modes need (the first time), and
    /// the frame's uniforms: the lookup's parameters, the half size.
    fn prepare(&mut self, ctx: &Context, settings: &RenderSettings) -> Result<()> {
        let (hw, hh) = self.targets.half();
        self.globals.counts[1] = hw;
        self.globals.counts[2] = hh;
        // The lookup borrows the technique: keep what the pipelines need.
        let (plain, mode) = {
            let l = self.lookup(settings);
            let mode = self.shade_mode(settings, &l);
            let plain: Lookup<'static> = Lookup {
                kind: l.kind,
                soft: l.soft,
                bindings: l.bindings,
                buffers: Vec::new(),
                params: l.params,
            };
            (plain, mode)
        };
        self.globals.shadow_f0 = plain.params.f0;
        self.globals.shadow_f1 = plain.params.f1;
        self.globals.shadow_u = plain.params.u;
        self.shade.prepare(ctx, mode, &plain)?;
        let taps = self.ssdo_params(settings).taps;
        if settings.ssdo_on()
            && let Some(st) = &mut self.ssdo
        {
            let semantic = settings.ssdo == SsdoMode::Semantic;
            st.pass
                .prepare(ctx, &plain, semantic, taps, settings.tile_lists)?;
            if taps.per_sphere()
                && st.spheres.as_ref().map(|b| b.spheres) != Some(self.sphere_count)
            {
                if let Some(mut old) = st.spheres.take() {
                    old.destroy(ctx);
                }
                st.spheres = Some(SphereBuffers::new(ctx, self.sphere_count)?);
            }
            st.blur.prepare(ctx, semantic, settings.tile_lists)?;
        }
        Ok(())
    }
}

impl<'c> Renderer<'c> {
    pub fn new(ctx: &'c Context, scene: &Scene, settings: RenderSettings) -> Result<Self> {
        if scene.spheres.is_empty() {
            return Err(Error::Input(format!(
                "{}: no spheres to render",
                scene.source
            )));
        }
        if scene.spheres.len() > crate::scene::MAX_SPHERES {
            return Err(Error::Input(format!(
                "{} spheres: at most {} are supported (sphere ids are 24-bit in the id AOV)",
                scene.spheres.len(),
                crate::scene::MAX_SPHERES
            )));
        }
        let cam = settings.camera;
        let geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let attrs: Vec<SphereAttr> = scene
            .spheres
            .iter()
            .map(|s| SphereAttr { region: s.region })
            .collect();

        // Each object is guarded until the renderer owns it: an error part
        // way (a buffer over the device limit) destroys what was made.
        let spheres = ctx.guard(Buffer::storage(ctx, "spheres", (geom.len() * 16) as u64)?);
        spheres.upload(ctx, 0, bytemuck::cast_slice(&geom))?;
        let attr_buf = ctx.guard(Buffer::storage(
            ctx,
            "sphere attributes",
            std::mem::size_of_val(attrs.as_slice()).max(16) as u64,
        )?);
        attr_buf.upload(ctx, 0, bytemuck::cast_slice(&attrs))?;
        let colors: Vec<u32> = scene
            .spheres
            .iter()
            .map(|s| u32::from_le_bytes(s.color))
            .collect();
        let color_buf = ctx.guard(Buffer::storage(
            ctx,
            "sphere colours",
            (colors.len().max(1) * 4) as u64,
        )?);
        color_buf.upload(ctx, 0, bytemuck::cast_slice(&colors))?;
        let win = checked_window(&cam, settings.window, settings.raster)?;
        let targets = ctx.guard(Targets::new(
            ctx,
            win.width,
            win.height,
            settings.aovs,
            settings.look.color16,
        )?);
        let raster_graphics = ctx.guard(match settings.raster {
            RasterMode::Graphics => Some(GraphicsRasterPass::new(ctx)?),
            RasterMode::Compute => None,
        });
        let mut slots = ctx.guard(Vec::new());
        for i in 0..crate::vk::FRAME_SLOTS {
            slots.push(FrameSlot::new(ctx, i)?);
        }
        let raster = ctx.guard(RasterPass::new(ctx)?);
        let coverage = ctx.guard(CoveragePass::new(ctx)?);

        let (bs_center, bs_radius) = scene.bounding_sphere();
        let levels = semantic::useful_levels(scene);
        let thresholds = settings.semantic_levels.clone().unwrap_or_else(|| {
            semantic::default_thresholds(levels.len(), 2.0 * bs_radius as f64 * 1.05)
        });
        let mut res = Resources {
            sphere_count: geom.len() as u32,
            geom,
            bounds: (bs_center.as_dvec3(), bs_radius as f64),
            typical_radius: typical_radius(scene) as f64,
            levels,
            thresholds,
            globals: Globals {
                background: background_word(settings.look.background),
                ..Default::default()
            },
            bgra: false,
            spheres: spheres.keep(),
            attrs: attr_buf.keep(),
            colors: color_buf.keep(),
            targets: targets.keep(),
            raster: raster.keep(),
            coverage: coverage.keep(),
            raster_graphics: raster_graphics.keep(),
            shade: ShadePass::new(),
            techniques: Vec::new(),
            active: None,
            ssdo: None,
            light_cached: false,
            light_cache: false,
            staging: None,
        };
        // Without a hierarchy every sphere is its own region (semantic SSDO
        // then equals plain SSDO).
        let no_levels = res.levels.is_empty() as u32;
        res.globals.counts = [res.sphere_count, 0, 0, no_levels];
        res.globals.cam = cam.to_gpu_window(res.depth_offset(&cam), settings.window);
        res.globals.params = [0.0, 0.0, win.width as f32, win.height as f32];
        let mut r = Renderer {
            ctx,
            settings,
            slots: slots.keep(),
            next_slot: 0,
            res,
        };
        // From here on `r` owns everything (Drop destroys it on error).
        r.set_shadows(r.settings.shadows)?;
        r.set_ssdo(r.settings.ssdo)?;
        if r.settings.ssdo != SsdoMode::Off {
            log::info!(
                "semantic levels {:?}, choice {:?}",
                r.res.levels,
                r.res.level_choice(&cam)
            );
        }
        RENDERERS_CREATED.fetch_add(1, Ordering::Relaxed);
        Ok(r)
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    pub fn sphere_count(&self) -> u32 {
        self.res.sphere_count
    }

    /// Whether the key light's view has its sphere order for the current
    /// spheres (sorted by the first frame that draws that view).
    pub fn light_order_ready(&self) -> bool {
        self.res.raster.order_ready(ViewIndex::Light)
    }

    /// The composited colour buffer (RGBA8 or BGRA8 texels, row-major).
    pub fn color_buffer(&self) -> &Buffer {
        &self.res.targets.color
    }

    pub fn is_bgra(&self) -> bool {
        self.res.bgra
    }

    /// Writes the colour buffer as BGRA from the next frame on.
    pub fn set_bgra(&mut self, bgra: bool) {
        self.res.bgra = bgra;
    }

    /// Moves the camera (same image size): light-space maps are camera
    /// independent; screen-space radii and the semantic level follow it.
    pub fn set_camera(&mut self, cam: Camera) -> Result<()> {
        let old = &self.settings.camera;
        if (cam.width, cam.height) != (old.width, old.height) {
            return Err(Error::Internal(
                "set_camera: the image size changed; call resize".into(),
            ));
        }
        self.res.globals.cam = cam.to_gpu_window(self.res.depth_offset(&cam), self.settings.window);
        self.settings.camera = cam;
        if self.res.active.is_none() {
            self.res.update_light_view(&self.settings);
        }
        Ok(())
    }

    /// A new image size: reallocates the screen targets only (the whole
    /// image: any window is dropped).
    pub fn resize(&mut self, cam: Camera) -> Result<()> {
        self.resize_window(cam, None)
    }

    /// Frames from now on hold `window` of the image (None: all of it):
    /// the tiles of an image too large for one allocation. Reallocates the
    /// screen targets when the window's size changes.
    pub fn set_window(&mut self, window: Option<crate::camera::Window>) -> Result<()> {
        self.resize_window(self.settings.camera, window)
    }

    /// `set_window` for a tile that keeps only `kept` (image coordinates,
    /// inside the window): the per-pixel passes after the rasterizer skip
    /// the margin beyond the blur's reach around it (they are only read
    /// there).
    pub fn set_tile(
        &mut self,
        window: crate::camera::Window,
        kept: crate::camera::Window,
    ) -> Result<()> {
        self.resize_window(self.settings.camera, Some(window))?;
        let reach = self.res.ssdo_params(&self.settings).blur_reach_px()
            + self.res.outline_px(&self.settings)
            + crate::render::tiles::ALIGN;
        let lo = |k: u32, w: u32| k.saturating_sub(reach).max(w) - w;
        let hi = |k: u32, n: u32, w: u32, size: u32| (k + n + reach - w).min(size);
        self.res.globals.params = [
            lo(kept.x, window.x) as f32,
            lo(kept.y, window.y) as f32,
            hi(kept.x, kept.width, window.x, window.width) as f32,
            hi(kept.y, kept.height, window.y, window.height) as f32,
        ];
        Ok(())
    }

    fn resize_window(&mut self, cam: Camera, window: Option<crate::camera::Window>) -> Result<()> {
        let win = checked_window(&cam, window, self.settings.raster)?;
        let t = &self.res.targets;
        let wide = self.settings.look.color16;
        if (t.width, t.height) != (win.width, win.height)
            || t.aovs != self.settings.aovs
            || t.wide != wide
        {
            self.wait_idle()?;
            let targets = Targets::new(self.ctx, win.width, win.height, self.settings.aovs, wide)?;
            let mut old = std::mem::replace(&mut self.res.targets, targets);
            old.destroy(self.ctx);
        }
        self.settings.camera = cam;
        self.settings.window = window;
        self.res.globals.params = [0.0, 0.0, win.width as f32, win.height as f32];
        self.res.globals.cam = cam.to_gpu_window(self.res.depth_offset(&cam), window);
        self.res.update_light_view(&self.settings);
        Ok(())
    }

    /// New sphere centres (a trajectory frame), in the scene's order: only
    /// the positions are uploaded (through a kept staging buffer); the
    /// bounds follow them and every light-space structure is rebuilt by
    /// the next frame, since the spheres moved.
    pub fn set_positions(&mut self, positions: &[[f32; 3]]) -> Result<()> {
        if positions.len() != self.res.geom.len() {
            return Err(Error::Input(format!(
                "{} positions for {} spheres",
                positions.len(),
                self.res.geom.len()
            )));
        }
        let limit = crate::scene::MAX_COORDINATE;
        if let Some(i) = positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite() && c.abs() <= limit))
        {
            return Err(Error::Input(format!(
                "position {i} ({:?}) is not finite or beyond ±{limit:e}",
                positions[i]
            )));
        }
        // Frames in flight read the sphere buffer.
        self.wait_idle()?;
        for (g, p) in self.res.geom.iter_mut().zip(positions) {
            g[0] = p[0];
            g[1] = p[1];
            g[2] = p[2];
        }
        let Resources {
            spheres,
            geom,
            staging,
            ..
        } = &mut self.res;
        spheres.upload_with(self.ctx, bytemuck::cast_slice(geom.as_slice()), staging)?;
        self.res.bounds = bounding_sphere(&self.res.geom);
        self.res.raster.spheres_moved();
        self.res.light_cached = false;
        for k in &mut self.res.techniques {
            k.stale = true;
        }
        if let Some(i) = self.res.active {
            self.refit(i)?;
        }
        let cam = self.settings.camera;
        self.res.globals.cam = cam.to_gpu_window(self.res.depth_offset(&cam), self.settings.window);
        self.res.update_light_view(&self.settings);
        Ok(())
    }

    /// A new key-light direction: the active technique refits its light
    /// view now, the others when they are chosen again.
    pub fn set_light(&mut self, dir: DVec3) -> Result<()> {
        if crate::camera::unit(dir).is_none() {
            return Err(Error::Input(
                "--light must be a finite non-zero direction".into(),
            ));
        }
        self.settings.light = dir;
        self.res.light_cached = false;
        for k in &mut self.res.techniques {
            k.stale = true;
        }
        if let Some(i) = self.res.active {
            self.refit(i)?;
        }
        self.res.update_light_view(&self.settings);
        Ok(())
    }

    fn refit(&mut self, i: usize) -> Result<()> {
        // Frames in flight read the light view from their own uniform copy
        // (written at submit), so nothing waits here.
        let Resources {
            geom, techniques, ..
        } = &mut self.res;
        let setup = ShadowSetup {
            ctx: self.ctx,
            spheres: geom,
            light_dir: self.settings.light,
            settings: &self.settings,
        };
        techniques[i].technique.refit(&setup)?;
        techniques[i].stale = false;
        Ok(())
    }

    /// Chooses the shadow technique; it is created the first time and kept.
    pub fn set_shadows(&mut self, mode: ShadowMode) -> Result<()> {
        let found = self
            .res
            .techniques
            .iter()
            .position(|k| k.technique.mode() == mode);
        let index = match (mode, found) {
            (ShadowMode::None, _) => None,
            (_, Some(i)) => {
                if self.res.techniques[i].stale {
                    self.refit(i)?;
                }
                Some(i)
            }
            (_, None) => {
                let setup = self.res.setup(self.ctx, &self.settings);
                match shadows::create(mode, &setup)? {
                    Some(t) => {
                        self.res.techniques.push(Kept {
                            technique: t,
                            stale: false,
                        });
                        Some(self.res.techniques.len() - 1)
                    }
                    None => None,
                }
            }
        };
        if index != self.res.active {
            self.res.light_cached = false;
        }
        self.res.active = index;
        self.settings.shadows = mode;
        self.res.update_light_view(&self.settings);
        Ok(())
    }

    /// Sorts the views' sphere orders that are stale (the view turned far,
    /// or the spheres moved) before a frame draws them: the camera's when
    /// the compute rasterizer draws it, the light's when the technique
    /// draws that view (others never pay for it).
    fn ensure_orders(&mut self) -> Result<()> {
        let views = [
            (
                ViewIndex::Camera,
                self.settings.camera.dir,
                self.settings.raster == RasterMode::Compute,
            ),
            (
                ViewIndex::Light,
                self.settings.light,
                self.settings.shadows.draws_light_view(),
            ),
        ];
        for (view, dir, drawn) in views {
            if drawn && self.res.raster.order_stale(view, dir) {
                // Frames in flight read the order.
                self.wait_idle()?;
                let t = std::time::Instant::now();
                self.res
                    .raster
                    .set_order(self.ctx, view, &self.res.geom, dir)?;
                log::debug!(
                    "{view:?} sphere order sorted in {:.1} ms",
                    t.elapsed().as_secs_f64() * 1e3
                );
            }
        }
        Ok(())
    }

    /// Chooses the SSDO mode; its pipelines are created the first time.
    pub fn set_ssdo(&mut self, mode: SsdoMode) -> Result<()> {
        if mode != SsdoMode::Off && self.res.ssdo.is_none() {
            self.res.ssdo = Some(SsdoState {
                pass: SsdoPass::new(self.ctx)?,
                blur: BlurPass::new(),
                spheres: None,
            });
        }
        self.settings.ssdo = mode;
        Ok(())
    }

    pub fn set_blur(&mut self, on: bool) {
        self.settings.blur = on;
    }

    /// Opacity of every sphere (translucent shadows with deep lists / osm).
    pub fn set_opacity(&mut self, opacity: f32) -> Result<()> {
        if !(0.0..=1.0).contains(&opacity) {
            return Err(Error::Input("--opacity must be between 0 and 1".into()));
        }
        if opacity != self.settings.opacity {
            // deep lists and opacity maps hold the opacity
            self.res.light_cached = false;
        }
        self.settings.opacity = opacity;
        Ok(())
    }

    pub fn pixels(&self) -> u64 {
        self.res.targets.pixels
    }

    /// Device memory of this renderer's buffers by class (bytes requested,
    /// before allocator alignment): what a user sizing a data set needs to
    /// know is which part grows with spheres, pixels or the light map.
    pub fn memory_by_class(&self) -> BTreeMap<String, u64> {
        let mut m = BTreeMap::new();
        let mut add = |class: &str, bytes: u64| {
            if bytes > 0 {
                *m.entry(class.to_string()).or_insert(0) += bytes;
            }
        };
        add(
            "scene",
            self.res.spheres.size
                + self.res.attrs.size
                + self.res.colors.size
                + self.res.raster.order_bytes(),
        );
        add(
            "uniforms",
            self.slots.iter().map(|f| f.globals.size).sum::<u64>(),
        );
        let (vis, gbuffer, ssdo) = self.res.targets.memory();
        add("visibility", vis + self.res.raster.memory_bytes());
        add("gbuffer", gbuffer);
        add("ssdo", ssdo);
        if let Some(b) = self.res.ssdo.as_ref().and_then(|s| s.spheres.as_ref()) {
            add("ssdo_spheres", b.bytes());
        }
        if let Some(t) = self.res.active_shadow() {
            for (class, bytes) in t.memory() {
                add(class, bytes);
            }
        }
        m
    }

    /// Renders one frame and waits for it; when the active technique asks
    /// (the deep lists grew their pool), renders it again.
    pub fn render_frame(&mut self) -> Result<PassTimes> {
        for _ in 0..=MAX_RETRIES {
            let slot = self.submit()?;
            let times = self
                .finish_slot(slot)?
                .ok_or_else(|| Error::Internal("frame results missing".into()))?;
            if self.after_frame()? == FrameCheck::Done {
                return Ok(times);
            }
        }
        Err(Error::DeviceLimit(
            "deep shadow list pool still overflows after growing it".into(),
        ))
    }

    fn after_frame(&mut self) -> Result<FrameCheck> {
        let check = match self.res.active {
            Some(i) => self.res.techniques[i].technique.after_frame(self.ctx)?,
            None => FrameCheck::Done,
        };
        if check == FrameCheck::Retry {
            self.res.light_cached = false;
        }
        Ok(check)
    }

    /// Reuse the light-space structure (ISSM map, deep lists, shadow maps)
    /// across frames while the light, the spheres and the opacity stay as
    /// they are: only the camera then costs (the viewer's orbit, the
    /// bench's cached runs). Off by default.
    pub fn set_light_cache(&mut self, on: bool) {
        self.res.light_cache = on;
        if !on {
            self.res.light_cached = false;
        }
    }

    /// Whether the light cache is on.
    pub fn light_cache(&self) -> bool {
        self.res.light_cache
    }

    /// Whether the next frame reuses the light-space structure.
    pub fn light_cached(&self) -> bool {
        self.res.light_cached
    }

    /// Records and submits the next frame without waiting for it; returns
    /// the per-pass times of the frame that used this slot before (already
    /// finished, or waited for: at most one other frame stays in flight).
    /// A technique that checks each frame (deep lists) makes this wait like
    /// `render_frame`.
    pub fn render_frame_pipelined(&mut self) -> Result<Option<PassTimes>> {
        if self.res.active_shadow().is_some_and(|t| t.checks_frames()) {
            return self.render_frame().map(Some);
        }
        let slot = self.next_slot;
        let previous = self.finish_slot(slot)?;
        self.submit()?;
        Ok(previous)
    }

    /// Waits for every frame in flight.
    pub fn wait_idle(&mut self) -> Result<()> {
        for i in 0..self.slots.len() {
            self.slots[i].wait(self.ctx)?;
        }
        Ok(())
    }

    /// Waits for the frame last submitted with `slot` and reads its timings.
    fn finish_slot(&mut self, slot: usize) -> Result<Option<PassTimes>> {
        let fs = &mut self.slots[slot];
        fs.wait(self.ctx)?;
        if !fs.pending {
            return Ok(None);
        }
        fs.pending = false;
        fs.profiler.results(self.ctx).map(Some)
    }

    /// Records and submits one frame in the next slot (whose previous frame
    /// must have finished); returns the slot.
    fn submit(&mut self) -> Result<usize> {
        self.ensure_orders()?;
        let ctx = self.ctx;
        let dev = &ctx.device;
        let slot = self.next_slot;
        self.next_slot = (slot + 1) % self.slots.len();
        let Renderer {
            settings,
            slots,
            res,
            ..
        } = self;
        res.prepare(ctx, settings)?;
        let fs = &mut slots[slot];
        fs.wait(ctx)?;
        match fs.globals.mapped_mut() {
            Some(m) => m.copy_from_slice(bytemuck::bytes_of(&res.globals)),
            None => fs
                .globals
                .upload(ctx, 0, bytemuck::bytes_of(&res.globals))?,
        }
        // This slot's previous frame finished: its descriptor sets are free.
        fs.arena.reset(ctx)?;
        let cmd = fs.cmd;
        // SAFETY: the slot's previous submission finished (its fence).
        unsafe {
            dev.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .map_err(|result| Error::Vk {
                    call: "vkResetCommandBuffer",
                    result,
                })?;
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            dev.begin_command_buffer(cmd, &begin)
                .map_err(|result| Error::Vk {
                    call: "vkBeginCommandBuffer",
                    result,
                })?;
        }
        fs.profiler.begin_frame(ctx, cmd);
        let recorded = {
            let mut rec = Recorder::new(ctx, cmd, &mut fs.arena, Some(&mut fs.profiler));
            rec.restrict_to(graph::pass_names());
            res.record_frame(settings, &fs.globals, &mut rec)
        };
        // SAFETY: cmd is in the recording state.
        unsafe { dev.end_command_buffer(cmd) }.map_err(|result| Error::Vk {
            call: "vkEndCommandBuffer",
            result,
        })?;
        recorded?;
        // The light-space structure this frame builds serves the next ones
        // until something it depends on changes.
        res.light_cached = res.light_cache && res.active.is_some();
        let cmds = [cmd];
        let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
        // SAFETY: the fence is unsignalled only by this submission.
        unsafe {
            dev.reset_fences(&[fs.fence]).map_err(|result| Error::Vk {
                call: "vkResetFences",
                result,
            })?;
            dev.queue_submit(ctx.queue, &submit, fs.fence)
                .map_err(|result| Error::Vk {
                    call: "vkQueueSubmit",
                    result,
                })?;
        }
        fs.pending = true;
        Ok(slot)
    }

    /// Records the frame into a throwaway command buffer that is never
    /// submitted and returns the recorder's log of steps and barriers
    /// (tests check it with [`crate::vk::barrier::check_hazards`]).
    pub fn frame_log(&mut self) -> Result<Vec<crate::vk::barrier::Event>> {
        self.ensure_orders()?;
        let ctx = self.ctx;
        self.res.prepare(ctx, &self.settings)?;
        let cmd = ctx.command_buffer("frame log")?;
        let mut arena = crate::vk::descriptors::DescriptorArena::default();
        let begin = vk::CommandBufferBeginInfo::default();
        // SAFETY: a fresh command buffer, freed below, never submitted.
        let result = unsafe { ctx.device.begin_command_buffer(cmd, &begin) }
            .map_err(|result| Error::Vk {
                call: "vkBeginCommandBuffer",
                result,
            })
            .and_then(|_| {
                let mut rec = Recorder::new(ctx, cmd, &mut arena, None);
                rec.restrict_to(graph::pass_names());
                rec.keep_log();
                self.res
                    .record_frame(&self.settings, &self.slots[0].globals, &mut rec)?;
                Ok(rec.take_log())
            });
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe {
            let _ = ctx.device.end_command_buffer(cmd);
            ctx.device.free_command_buffers(ctx.command_pool, &[cmd]);
        }
        arena.destroy(ctx);
        result
    }

    /// Visibility buffer (depth|id per pixel), without the guard words.
    pub fn read_vis(&self) -> Result<Vec<u64>> {
        self.res
            .targets
            .vis
            .download_pod(self.ctx, 0, self.pixels())
    }

    /// The guard words after the visibility buffer (must stay GUARD_PATTERN).
    pub fn read_vis_guard(&self) -> Result<Vec<u64>> {
        self.res.targets.vis.download_pod(
            self.ctx,
            self.pixels(),
            crate::passes::raster::VIS_GUARD_WORDS,
        )
    }

    /// The colour buffer: one RGBA8 word per pixel, or two (RGBA16) with
    /// `look.color16`.
    pub fn read_color(&self) -> Result<Vec<u32>> {
        let words = if self.res.targets.wide { 2 } else { 1 };
        self.res
            .targets
            .color
            .download_pod(self.ctx, 0, self.pixels() * words)
    }

    /// Visible positions: xyz world (the shader's reconstruction from the
    /// pixel ray and the sphere, redone on the CPU in f32), w the depth key
    /// (-1 = background).
    pub fn read_gpos(&self) -> Result<Vec<[f32; 4]>> {
        let cam = &self.settings.camera;
        let vis = self.read_vis()?;
        Ok(vis
            .iter()
            .enumerate()
            .map(|(i, &k)| {
                if k == crate::gpu::VIS_EMPTY {
                    return [0.0, 0.0, 0.0, -1.0];
                }
                let s = self.res.geom[(k & 0xFFFF_FFFF) as usize];
                let win = self.settings.window();
                let (x, y) = (i as u32 % win.width + win.x, i as u32 / win.width + win.y);
                let c = glam::DVec3::new(s[0] as f64, s[1] as f64, s[2] as f64);
                let p = crate::reference::visible_point(cam, x, y, c, s[3] as f64);
                [
                    p.x as f32,
                    p.y as f32,
                    p.z as f32,
                    f32::from_bits((k >> 32) as u32),
                ]
            })
            .collect())
    }

    /// Keep (or stop keeping) the shadow and ao AOVs: reallocates the
    /// screen targets; the next frame writes them.
    pub fn set_aovs(&mut self, on: bool) -> Result<()> {
        if self.settings.aovs == on {
            return Ok(());
        }
        self.settings.aovs = on;
        self.resize_window(self.settings.camera, self.settings.window)
    }

    /// The shadow and ao AOVs as shade wrote them (unorm16 each).
    fn read_aov(&self) -> Result<Vec<u32>> {
        if !self.res.targets.aovs {
            return Err(Error::Input(
                "the shadow and ao AOVs are off: set RenderSettings::aovs or call set_aovs(true) \
                 before rendering"
                    .into(),
            ));
        }
        self.res
            .targets
            .aov
            .download_pod(self.ctx, 0, self.pixels())
    }

    /// Key-light visibility per pixel (1 on background), 16-bit precision.
    pub fn read_shadow(&self) -> Result<Vec<f32>> {
        Ok(self
            .read_aov()?
            .into_iter()
            .map(|a| (a & 0xFFFF) as f32 / 65535.0)
            .collect())
    }

    /// Ambient visibility per pixel as shade used it (x: after the blur
    /// and the upsample; the bounce, yzw, is not kept at full resolution
    /// and reads 0), 16-bit precision; 1 without SSDO.
    pub fn read_ambient(&self) -> Result<Vec<[f32; 4]>> {
        Ok(self
            .read_aov()?
            .into_iter()
            .map(|a| [(a >> 16) as f32 / 65535.0, 0.0, 0.0, 0.0])
            .collect())
    }

    /// The last frame's tile lists (passes/coverage.rs, TL_* words), whole.
    pub fn read_tile_lists(&self) -> Result<Vec<u32>> {
        let b = &self.res.targets.tiles;
        b.download_pod(self.ctx, 0, b.size / 4)
    }

    /// The last frame's per-sphere SSDO list (the spheres `ssdo_prep`
    /// flagged, in list order) and the workgroups counted for it; `None`
    /// without per-sphere buffers (tests).
    pub fn read_sphere_list(&self) -> Result<Option<(Vec<u32>, u32)>> {
        let Some(sb) = self.res.ssdo.as_ref().and_then(|st| st.spheres.as_ref()) else {
            return Ok(None);
        };
        let counters: Vec<u32> = sb.counters.download_pod(self.ctx, 0, 4)?;
        let n = counters[crate::gpu::consts::S_LISTED as usize];
        if n > sb.spheres {
            return Err(Error::Internal(format!(
                "per-sphere list: {n} entries for {} spheres",
                sb.spheres
            )));
        }
        let list = sb.list.download_pod(self.ctx, 0, n as u64)?;
        Ok(Some((
            list,
            counters[crate::gpu::consts::S_GROUPS as usize],
        )))
    }

    /// The half-resolution SSDO records of the last frame (tests).
    pub fn read_records(&self) -> Result<Vec<crate::passes::ssdo::Record>> {
        let (hw, hh) = self.res.targets.half();
        let raw: Vec<[u32; 4]> =
            self.res
                .targets
                .records
                .download_pod(self.ctx, 0, hw as u64 * hh as u64)?;
        Ok(raw
            .into_iter()
            .map(crate::passes::ssdo::Record::unpack)
            .collect())
    }

    fn technique<T: 'static>(&self) -> Option<&T> {
        self.res
            .active_shadow()
            .and_then(|t| t.as_any().downcast_ref::<T>())
    }

    /// The ISSM light view and patch half-size t, when ISSM is active.
    pub fn issm_info(&self) -> Option<(Camera, u32)> {
        self.technique::<Issm>().map(|s| (s.light, s.push.t as u32))
    }

    pub fn read_issm(&self) -> Result<Option<Vec<u64>>> {
        self.technique::<Issm>()
            .map(|s| s.read_map(self.ctx))
            .transpose()
    }

    /// The baseline depth shadow map, when `--shadows sm-pcf` is active.
    pub fn shadow_map(&self) -> Option<&ShadowMap> {
        self.technique::<ShadowMap>()
    }

    /// The baseline opacity shadow maps, when `--shadows osm` is active.
    pub fn opacity_shadows(&self) -> Option<&OpacityShadows> {
        self.technique::<OpacityShadows>()
    }

    /// The deep shadow lists, when `--shadows deep` is active.
    pub fn deep(&self) -> Option<&DeepShadows> {
        self.technique::<DeepShadows>()
    }

    /// Stats of the last frame's deep lists (after any pool growth).
    pub fn deep_stats(&self) -> Option<DeepStats> {
        self.deep().and_then(|d| d.stats.clone())
    }

    /// SSDO's far search radius for the current camera (world units): the
    /// reach of its occlusion (the AO reference uses the same).
    pub fn ssdo_far_radius(&self) -> f64 {
        self.res.ssdo_params(&self.settings).ssdo.r_far as f64
    }

    /// Who receives SSDO for the current camera: per 2x2 block (spheres
    /// large on screen), per pixel, or per visible sphere (a few pixels
    /// wide).
    pub fn ssdo_receivers(&self) -> Receivers {
        self.res.ssdo_params(&self.settings).taps.receivers
    }

    /// The semantic level choice of this frame, when SSDO runs.
    pub fn level_choice(&self) -> Option<LevelChoice> {
        self.settings
            .ssdo_on()
            .then(|| self.res.level_choice(&self.settings.camera))
    }
}

/// The window a frame's buffers hold (all of the image for None), checked:
/// inside the image, and only with the compute rasterizer.
fn checked_window(
    cam: &Camera,
    window: Option<crate::camera::Window>,
    raster: RasterMode,
) -> Result<crate::camera::Window> {
    let win = window.unwrap_or(crate::camera::Window::whole(cam));
    if !win.fits(cam) {
        return Err(Error::Input(format!(
            "window {win:?} is not inside the {}x{} image",
            cam.width, cam.height
        )));
    }
    if window.is_some() && raster == RasterMode::Graphics {
        return Err(Error::Input(
            "tiles need --raster compute (the graphics baseline draws whole images)".into(),
        ));
    }
    Ok(win)
}

/// The shader's background word: rgb (display-encoded) and the mode in a
/// (0 gradient, 1 flat colour, 2 transparent).
fn background_word(b: crate::settings::Background) -> [f32; 4] {
    use crate::settings::Background;
    match b {
        Background::Gradient => [0.13, 0.14, 0.17, 0.0],
        Background::Color(c) => [
            c[0] as f32 / 255.0,
            c[1] as f32 / 255.0,
            c[2] as f32 / 255.0,
            1.0,
        ],
        Background::Transparent => [0.0, 0.0, 0.0, 2.0],
    }
}

/// Useful hierarchy levels and the choice for this camera (thresholds from
/// `--semantic-levels` or the defaults relative to the scene size).
pub fn level_choice(
    scene: &Scene,
    cam: &Camera,
    thresholds: &Option<Vec<f64>>,
) -> (Vec<u32>, LevelChoice) {
    let levels = semantic::useful_levels(scene);
    let (c, r) = scene.bounding_sphere();
    let full = 2.0 * r as f64 * 1.05;
    let t = thresholds
        .clone()
        .unwrap_or_else(|| semantic::default_thresholds(levels.len(), full));
    let choice = semantic::choose(semantic::zoom_distance(cam, c.as_dvec3()), &t, &levels);
    (levels, choice)
}

impl Drop for Renderer<'_> {
    fn drop(&mut self) {
        let ctx = self.ctx;
        ctx.wait_idle();
        self.slots.destroy_with(ctx);
        let r = &mut self.res;
        r.raster.destroy(ctx);
        r.coverage.destroy(ctx);
        r.raster_graphics.destroy_with(ctx);
        r.shade.destroy(ctx);
        r.techniques.destroy_with(ctx);
        r.ssdo.destroy_with(ctx);
        r.targets.destroy(ctx);
        r.spheres.destroy(ctx);
        r.attrs.destroy(ctx);
        r.colors.destroy(ctx);
        r.staging.destroy_with(ctx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::passes::blur::BLUR_RADII;

    /// The blur pipelines are made for a fixed set of radii: every tap
    /// set's radius must be one of them.
    #[test]
    fn tap_sets_blur_with_a_prepared_radius() {
        for (_, radius) in [SSDO_TAPS_LARGE, SSDO_TAPS_SMALL] {
            assert!(BLUR_RADII.contains(&radius), "radius {radius}");
        }
    }
}
