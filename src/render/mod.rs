//! The renderer: scene buffers, screen targets, the stages, and frames in
//! flight. A frame is recorded by [`graph`] (the one pass list, wiring the
//! stages' outputs to the next ones' inputs). Settings change through
//! [`Renderer::update`]; a shadow technique or SSDO is created the first
//! time it is chosen and kept, so the viewer never rebuilds the renderer.
//! [`Renderer::inspect`] reads back what a frame left (tests, debugging).

pub mod frame;
pub mod graph;
pub mod inspect;
pub mod nesting;
mod submit;
pub mod targets;
pub mod tiles;

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::gpu::Globals;
use crate::passes::scene::{SceneBuffers, SceneGeom};
use crate::scene::Scene;
use crate::semantic;
use crate::settings::{RasterMode, RenderSettings, ShadowMode, SsdoMode};
use crate::stages::see_through::SeeThrough;
use crate::stages::shading::ShadeFrame;
use crate::stages::shadows::{Lookup, ShadowSetup};
use crate::stages::ssdo::{SceneScale, SsdoModes, SsdoParams};
use crate::vk::guard::Destroy;
use crate::vk::{Buffer, Context};
use frame::FrameSlot;
use glam::DVec3;
use std::sync::atomic::{AtomicU64, Ordering};
use targets::Targets;

pub use inspect::Inspect;

/// Renderers constructed in this process (tests check the viewer makes one).
pub static RENDERERS_CREATED: AtomicU64 = AtomicU64::new(0);

pub struct Renderer<'c> {
    ctx: &'c Context,
    settings: RenderSettings,
    /// Per-frame resources, so a frame can be recorded while the previous
    /// one still runs (the viewer); `render_frame` uses them one at a time.
    slots: Vec<FrameSlot>,
    next_slot: usize,
    /// The ids the last frame recorded may name (per-id buffers sized by
    /// them are remade when they change: a frame in flight reads them).
    last_ids: u32,
    /// A tiled image's camera spheres so far (the LOD cull's, summed over
    /// its tiles from the first: `set_tile`, `render_row`).
    tiles_drawn: Option<u64>,
    res: Resources,
}

/// Everything on the GPU except the frame slots.
pub(crate) struct Resources {
    /// CPU copy of the geometry: light views are fitted to it.
    geom: SceneGeom,
    /// The scene is an instanced model expanded (`Scene::expanded`).
    expanded: bool,
    /// Scene ids to input indices when rules hid spheres (the id AOV).
    ids: Option<std::sync::Arc<crate::scene::paint::IdMap>>,
    /// Some sphere's colour has alpha below 1 (see-through).
    translucent: bool,
    /// Bounding sphere of the sphere centres (camera depth offsets, zoom).
    bounds: (DVec3, f64),
    /// Typical sphere radius (screen-space effect radii).
    typical_radius: f64,
    /// A nested scene's placements.
    placements: Option<u64>,
    /// The most bytes a storage buffer may hold: SSDO may use per-sphere
    /// receivers where their flags (a bit per id) fit one (not so past
    /// ~10^9 ids on lavapipe's 128 MiB).
    storage_range: u32,
    globals: Globals,
    /// Write the colour buffer as BGRA (for BGRA swapchains).
    bgra: bool,
    /// The scene's buffers (plain spheres or instanced molecules).
    scene: SceneBuffers,
    targets: Targets,
    stages: graph::Stages,
    /// Kept host-visible buffer for `set_positions`.
    staging: Option<Buffer>,
}

/// The most bytes the per-sphere SSDO receivers' buffers may take (else
/// spheres of a few pixels take the per-pixel taps; SARS-CoV-2 at 1080p
/// takes 46 MB): `Resources::scale`.
const SSDO_SPHERE_BYTES: u64 = 96 << 20;

/// Typical sphere radius (median of a sample of the represented spheres)
/// to scale screen-space effects.
fn typical_radius(scene: &Scene) -> f32 {
    let n = scene.represented();
    let step = (n / 4096).max(1);
    let mut r: Vec<f32> = (0..n)
        .step_by(step as usize)
        .filter_map(|i| scene.sphere(i).map(|s| s.radius))
        .collect();
    r.sort_by(|a, b| a.total_cmp(b));
    r.get(r.len() / 2).copied().unwrap_or(1.0)
}

fn normalized(v: DVec3) -> [f32; 4] {
    // (validated directions; the fallback only keeps NaN off the GPU)
    let l = crate::camera::unit(v).unwrap_or(DVec3::NEG_Z);
    [l.x as f32, l.y as f32, l.z as f32, 0.0]
}

impl Resources {
    /// Depth offset that keeps a view's orthographic depth keys positive.
    fn depth_offset(&self, view: &Camera) -> f64 {
        let (c, r) = self.bounds;
        (c - view.center).length() + r + 1.0
    }

    /// Puts the active technique's light view (or the camera) in the globals.
    fn update_light_view(&mut self, settings: &RenderSettings) {
        self.globals.light = match self.stages.shadows.light() {
            Some(l) => l.to_gpu(self.depth_offset(&l)),
            None => settings.camera.to_gpu(self.depth_offset(&settings.camera)),
        };
        self.globals.light_dir = normalized(settings.light);
    }

    fn scale(&self) -> SceneScale {
        SceneScale {
            typical_radius: self.typical_radius,
            center: self.bounds.0,
            // (a bit per id this frame may name, and one per sphere of
            // every level of every instance: past ~10^9 atoms the visible
            // spheres outnumber the pixels and per-pixel receivers cost
            // less; meso 10^9 overview 721 against 803 ms, SARS-CoV-2 353
            // against 397 the other way; and their buffers within
            // SSDO_SPHERE_BYTES: the 10^12 nested overview's LOD lists, 12
            // spheres a pixel, made them 180 MB)
            sphere_receivers: crate::stages::ssdo::sphere_flags_fit(
                self.scene.frame_slots().max(self.scene.all_level_slots),
                self.storage_range,
            ) && crate::stages::ssdo::passes::SphereBuffers::bytes_for(
                self.scene.frame_slots(),
                self.targets.pixels,
            ) <= SSDO_SPHERE_BYTES,
        }
    }

    /// The SSDO stage's parameters for this camera (computed whether SSDO
    /// runs or not: shade's upsample and outlines read some).
    pub(crate) fn ssdo_params(&self, settings: &RenderSettings) -> SsdoParams {
        self.stages.ssdo.params(&settings.camera, self.scale())
    }

    /// How shade reads key-light visibility this frame.
    pub(crate) fn lookup(&self, settings: &RenderSettings, ssdo: &SsdoParams) -> Lookup<'_> {
        let screen = settings.ssdo_on().then_some(ssdo.screen);
        self.stages.shadows.lookup(settings.opacity, screen)
    }

    /// Makes the pipelines this frame's modes need (the first time), and
    /// the frame's uniforms: the lookup's parameters, the half size.
    /// Returns the stages' parameters for the frame (computed once here).
    fn prepare(&mut self, ctx: &Context, settings: &RenderSettings) -> Result<FrameParams> {
        // The batch table: the LOD lists, or the static one (made by
        // `ensure_orders` the first time a frame draws every atom).
        self.scene.listed.set(self.lod_lists(settings));
        let perspective = settings.camera.fov_deg.is_some();
        if self.scene.listed.get() {
            let light = settings.shadows != ShadowMode::None;
            self.stages.raster.enable_batches(ctx, light, perspective)?;
        }
        self.globals.counts[0] = self.scene.frame_slots();
        let (hw, hh) = self.targets.half();
        self.globals.counts[1] = hw;
        self.globals.counts[2] = hh;
        self.globals.alpha = [settings.opacity, 0.0, 0.0, 0.0];
        let see_through = self.see_through(settings);
        if see_through {
            settings.check_see_through(self.translucent)?;
            self.stages
                .raster
                .enable_see_through(ctx, self.scene.listed.get(), perspective)?;
            if self.stages.see_through.is_none() {
                let mut st = SeeThrough::new(
                    ctx,
                    self.scene.spec,
                    self.scene.frame_slots(),
                    settings.band_jobs,
                )?;
                // (made by an image's first frame: a tile when tiled)
                st.set_tiled(settings.window.is_some(), true);
                self.stages.see_through = Some(st);
            }
            if let Some(s) = &mut self.stages.see_through {
                s.prepare(
                    ctx,
                    self.targets.pixels,
                    settings.deep.see_through_fragments,
                )?;
                s.ensure_ids(ctx, self.scene.frame_slots())?;
                // (the camera's two lists: glsl/oit_pick.comp)
                if let (true, Some(l)) = (self.scene.listed.get(), &self.stages.raster.lod) {
                    s.ensure_picks(ctx, 2 * l.capacity(), self.scene.colors.size / 4)?;
                }
            }
        }
        let p = self.ssdo_params(settings);
        // The lookup borrows the technique: keep what the pipelines need.
        let (plain, shade) = {
            let l = self.lookup(settings, &p);
            let frame = ShadeFrame::new(
                settings,
                &l,
                &p,
                self.bgra,
                self.typical_radius,
                see_through,
            );
            let plain: Lookup<'static> = Lookup {
                kind: l.kind,
                soft: l.soft,
                bindings: l.bindings,
                buffers: Vec::new(),
                params: l.params,
            };
            (plain, frame)
        };
        self.globals.shadow_f0 = plain.params.f0;
        self.globals.shadow_f1 = plain.params.f1;
        self.globals.shadow_u = plain.params.u;
        self.stages.shade.prepare(ctx, shade.mode, &plain)?;
        if settings.ssdo_on() {
            let counts = (self.scene.frame_slots(), self.targets.pixels);
            self.stages
                .ssdo
                .prepare(ctx, &p, ssdo_modes(settings), &plain, counts)?;
        }
        Ok(FrameParams {
            ssdo: p,
            shade,
            see_through,
        })
    }

    /// Whether this frame has see-through spheres: a colour's alpha below
    /// 1, or `--opacity` below 1 (it multiplies every alpha).
    pub(crate) fn see_through(&self, settings: &RenderSettings) -> bool {
        !settings.opaque_view && (self.translucent || settings.opacity < 1.0)
    }

    /// Whether the views draw the LOD cull's lists this frame: an
    /// instanced scene with levels of detail, where every pass that draws
    /// the spheres can take them (the compute rasterizer's views and the
    /// see-through fragments, which visit the camera's lists; the deep
    /// lists and opacity maps draw every atom, in the views' orders).
    pub(crate) fn lod_lists(&self, settings: &RenderSettings) -> bool {
        self.scene.lod.is_some()
            && settings.raster == RasterMode::Compute
            && !matches!(settings.shadows, ShadowMode::Deep | ShadowMode::Osm)
    }
}

/// The stages' parameters of one frame: computed by `prepare`, recorded by
/// `record_frame`.
pub(crate) struct FrameParams {
    pub ssdo: SsdoParams,
    pub shade: ShadeFrame,
    /// The see-through stage runs (its lists are prepared).
    pub see_through: bool,
}

/// The SSDO stage's switches from the settings.
fn ssdo_modes(settings: &RenderSettings) -> SsdoModes {
    SsdoModes {
        semantic: settings.ssdo == SsdoMode::Semantic,
        blur: settings.ssdo_knobs.blur,
        lists: settings.tile_lists,
    }
}

impl<'c> Renderer<'c> {
    pub fn new(ctx: &'c Context, scene: &Scene, settings: RenderSettings) -> Result<Self> {
        let proxies = nesting::proxies_of(scene, settings.lod.pixels())?;
        Self::with_proxies(ctx, scene, settings, proxies.as_ref())
    }

    /// [`Renderer::new`] for a nested scene whose proxies were made for
    /// these settings' `--lod-pixels` already
    /// ([`nesting::proxies_of`]).
    pub fn with_proxies(
        ctx: &'c Context,
        scene: &Scene,
        settings: RenderSettings,
        proxies: Option<&crate::scene::instanced::nested::Proxies>,
    ) -> Result<Self> {
        if scene.spheres.is_empty() || scene.represented() == 0 {
            return Err(Error::Input(format!(
                "{}: no spheres to render",
                scene.source
            )));
        }
        if scene.instancing.is_none() && scene.spheres.len() > crate::scene::MAX_SPHERES {
            return Err(Error::Input(format!(
                "{} spheres: at most {} are supported (sphere ids are 24-bit in the id AOV)",
                scene.spheres.len(),
                crate::scene::MAX_SPHERES
            )));
        }
        let cam = settings.camera;
        // Each object is guarded until the renderer owns it: an error part
        // way (a buffer over the device limit) destroys what was made.
        // (a nested scene: the placements this camera opens, the others by
        // their proxies; the rest of the renderer sees the nested scene)
        let resolved = nesting::resolved(scene, &cam, proxies)?;
        let drawn = resolved.as_ref().unwrap_or(scene);
        // (the proxies' fits: the resolved scene's molecule types)
        let fitted = proxies
            .filter(|_| resolved.is_some())
            .map(|p| p.fits.as_slice());
        let (scene_buffers, geom) = SceneBuffers::new(ctx, drawn, settings.lod.pixels(), fitted)?;
        drop(resolved);
        let mut scene_buffers = ctx.guard(scene_buffers);
        let win = checked_window(&cam, settings.window, settings.raster)?;
        let targets = ctx.guard(Targets::new(
            ctx,
            win.width,
            win.height,
            settings.aovs,
            settings.look.color16,
        )?);
        let mut slots = ctx.guard(Vec::new());
        for i in 0..crate::vk::FRAME_SLOTS {
            slots.push(FrameSlot::new(ctx, i)?);
        }

        let (bs_center, bs_radius) = scene.bounding_sphere();
        let levels = semantic::useful_levels(scene);
        let thresholds = settings
            .ssdo_knobs
            .semantic_levels
            .as_ref()
            .map(|l| l.0.clone())
            .unwrap_or_else(|| {
                semantic::default_thresholds(levels.len(), 2.0 * bs_radius as f64 * 1.05)
            });
        // Without a hierarchy every sphere is its own region (semantic SSDO
        // then equals plain SSDO).
        let no_levels = levels.is_empty() as u32;
        let typical = typical_radius(scene);
        let stages = ctx.guard(graph::Stages::new(
            ctx,
            &settings,
            levels,
            thresholds,
            &mut scene_buffers,
            typical,
        )?);
        let mut res = Resources {
            geom,
            expanded: scene.expanded,
            ids: scene.id_map().map(std::sync::Arc::new),
            translucent: scene.has_translucent(),
            bounds: (bs_center.as_dvec3(), bs_radius as f64),
            typical_radius: typical as f64,
            placements: scene.nesting().map(|n| n.placements.len() as u64),
            storage_range: ctx.props.limits.max_storage_buffer_range,
            globals: Globals {
                background: background_word(settings.look.background),
                scene: crate::passes::scene::levels_word(scene),
                ..Default::default()
            },
            bgra: false,
            scene: scene_buffers.keep(),
            targets: targets.keep(),
            stages: stages.keep(),
            staging: None,
        };
        res.globals.counts = [res.scene.slots, 0, 0, no_levels];
        res.globals.cam = cam.to_gpu_window(res.depth_offset(&cam), settings.window);
        res.globals.params = [0.0, 0.0, win.width as f32, win.height as f32];
        let mut r = Renderer {
            ctx,
            settings,
            slots: slots.keep(),
            next_slot: 0,
            last_ids: 0,
            tiles_drawn: None,
            res,
        };
        // From here on `r` owns everything (Drop destroys it on error).
        r.set_shadows(r.settings.shadows)?;
        r.set_ssdo(r.settings.ssdo)?;
        if r.settings.ssdo != SsdoMode::Off {
            log::info!(
                "semantic levels {:?}, choice {:?}",
                r.res.stages.ssdo.levels(),
                r.res.stages.ssdo.level_choice(&cam, r.res.scale())
            );
        }
        RENDERERS_CREATED.fetch_add(1, Ordering::Relaxed);
        Ok(r)
    }

    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    /// Changes settings for the next frames: `edit` gets a copy of the
    /// current ones. What a live renderer can change: the camera (a new
    /// image size reallocates the screen targets; a window or AOV change
    /// too), the light, the shadow technique, SSDO, blur, opacity, the
    /// look and the tile lists; light-space structures and pipelines are
    /// rebuilt only when what they depend on changed. The rasterizer, the
    /// technique parameters, the deep pool and the semantic levels are
    /// fixed when the renderer is made: changing one is an error.
    pub fn update(&mut self, edit: impl FnOnce(&mut RenderSettings)) -> Result<()> {
        let mut next = self.settings.clone();
        edit(&mut next);
        let cur = &self.settings;
        let fixed = [
            ("--raster", next.raster != cur.raster),
            ("the ISSM parameters", next.issm != cur.issm),
            (
                "the shadow-map parameters",
                next.shadow_maps != cur.shadow_maps,
            ),
            ("--deep-pool-chunks", next.deep != cur.deep),
            (
                "--semantic-levels",
                next.ssdo_knobs.semantic_levels != cur.ssdo_knobs.semantic_levels,
            ),
        ];
        if let Some((what, _)) = fixed.iter().find(|f| f.1) {
            return Err(Error::Input(format!(
                "{what} cannot change on a live renderer: make a new one"
            )));
        }
        if !(0.0..=1.0).contains(&next.opacity) {
            return Err(Error::Input("--opacity must be between 0 and 1".into()));
        }
        if crate::camera::unit(next.light).is_none() {
            return Err(Error::Input(
                "--light must be a finite non-zero direction".into(),
            ));
        }
        let cur = std::mem::replace(&mut self.settings, next);
        let applied = self.apply(&cur);
        if applied.is_err() {
            self.settings = cur;
        }
        applied
    }

    /// Brings the GPU state from `cur` to `self.settings`.
    fn apply(&mut self, cur: &RenderSettings) -> Result<()> {
        let next = &self.settings;
        if next.opacity != cur.opacity {
            // deep lists and opacity maps hold the opacity
            self.res.stages.shadows.uncache();
        }
        if next.look.background != cur.look.background {
            self.res.globals.background = background_word(next.look.background);
        }
        if next.light != cur.light {
            self.res.light_changed(self.ctx, &self.settings)?;
        }
        if self.settings.shadows != cur.shadows {
            self.set_shadows(self.settings.shadows)?;
        }
        if self.settings.ssdo != cur.ssdo {
            self.set_ssdo(self.settings.ssdo)?;
        }
        let next = &self.settings;
        let (old_cam, cam) = (cur.camera, next.camera);
        if (old_cam.width, old_cam.height) != (cam.width, cam.height)
            || next.window != cur.window
            || next.aovs != cur.aovs
            || next.look.color16 != cur.look.color16
        {
            return self.resize_window(cam, next.window);
        }
        self.res.globals.cam = cam.to_gpu_window(self.res.depth_offset(&cam), next.window);
        self.res.update_light_view(&self.settings);
        Ok(())
    }
}

impl Resources {
    /// The light or the spheres changed: every technique refits (the
    /// caller then puts the new light view in the globals).
    fn light_changed(&mut self, ctx: &Context, settings: &RenderSettings) -> Result<()> {
        let Resources {
            geom,
            stages,
            scene,
            ..
        } = self;
        stages.shadows.light_changed(&ShadowSetup {
            ctx,
            geom,
            scene: scene.spec,
            light_dir: settings.light,
            settings,
        })
    }
}

impl<'c> Renderer<'c> {
    /// Chooses the shadow technique; it is created the first time and kept.
    fn set_shadows(&mut self, mode: crate::settings::ShadowMode) -> Result<()> {
        let Resources {
            geom,
            stages,
            scene,
            ..
        } = &mut self.res;
        if matches!(mode, ShadowMode::Deep | ShadowMode::Osm) {
            // (they draw every atom: sized by the static table's slots)
            geom.check_full_detail()?;
        }
        stages.shadows.choose(
            mode,
            &ShadowSetup {
                ctx: self.ctx,
                geom,
                scene: scene.spec,
                light_dir: self.settings.light,
                settings: &self.settings,
            },
        )?;
        self.settings.shadows = mode;
        self.res.update_light_view(&self.settings);
        Ok(())
    }

    /// Chooses the SSDO mode; its pipelines are created the first time.
    fn set_ssdo(&mut self, mode: SsdoMode) -> Result<()> {
        if mode != SsdoMode::Off {
            self.res.stages.ssdo.enable(self.ctx)?;
        }
        self.settings.ssdo = mode;
        Ok(())
    }

    /// `update` for a tile of a large image: frames hold `window` of the
    /// image and keep only `kept` (image coordinates, inside the window):
    /// the per-pixel passes after the rasterizer skip the margin beyond
    /// the blur's reach around it (they are only read there).
    pub fn set_tile(
        &mut self,
        window: crate::camera::Window,
        kept: crate::camera::Window,
    ) -> Result<()> {
        self.resize_window(self.settings.camera, Some(window))?;
        // (a plan's tiles start at the image's corner: its stats start there)
        if let Some(st) = self.res.stages.see_through.as_mut() {
            st.set_tiled(true, kept.x == 0 && kept.y == 0);
        }
        if kept.x == 0 && kept.y == 0 {
            self.tiles_drawn = Some(0);
        }
        let reach = self.res.ssdo_params(&self.settings).blur_reach_px()
            + crate::stages::shading::outline_px(&self.settings)
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
        let (aovs, wide) = (self.settings.aovs, self.settings.look.color16);
        if (t.width, t.height) != (win.width, win.height)
            || t.shade.aovs != aovs
            || t.shade.wide != wide
        {
            self.wait_idle()?;
            let targets = Targets::new(self.ctx, win.width, win.height, aovs, wide)?;
            let mut old = std::mem::replace(&mut self.res.targets, targets);
            old.destroy(self.ctx);
        }
        if window.is_none()
            && let Some(st) = self.res.stages.see_through.as_mut()
        {
            st.set_tiled(false, false);
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
        let SceneGeom::Plain(plain) = &self.res.geom else {
            return Err(Error::Input(
                "an instanced scene's spheres cannot be moved one by one (no trajectories)".into(),
            ));
        };
        if positions.len() != plain.len() {
            return Err(Error::Input(format!(
                "{} positions for {} spheres",
                positions.len(),
                plain.len()
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
        let Resources {
            scene,
            geom,
            staging,
            ..
        } = &mut self.res;
        let SceneGeom::Plain(plain) = geom else {
            return Err(Error::Internal(
                "set_positions on an instanced scene".into(),
            ));
        };
        for (g, p) in plain.iter_mut().zip(positions) {
            g[0] = p[0];
            g[1] = p[1];
            g[2] = p[2];
        }
        scene
            .spheres
            .upload_with(self.ctx, bytemuck::cast_slice(plain.as_slice()), staging)?;
        self.res.bounds = self.res.geom.bounding_sphere();
        self.res.stages.raster.compute.spheres_moved();
        self.res.light_changed(self.ctx, &self.settings)?;
        let cam = self.settings.camera;
        self.res.globals.cam = cam.to_gpu_window(self.res.depth_offset(&cam), self.settings.window);
        self.res.update_light_view(&self.settings);
        Ok(())
    }

    /// New sphere colours (RGBA8, alpha 255 opaque), one per sphere record
    /// in the scene's order (an instanced scene's molecule atoms): the
    /// viewer's colour and see-through presets. Alpha changes the shadows
    /// (deep lists) and whether the see-through passes run.
    pub fn set_colors(&mut self, colors: &[[u8; 4]]) -> Result<()> {
        let words = self.res.scene.colour_words(colors)?;
        // Frames in flight read the colour buffer.
        self.wait_idle()?;
        self.res
            .scene
            .colors
            .upload(self.ctx, 0, bytemuck::cast_slice(&words))?;
        self.res.translucent = colors.iter().any(|c| c[3] < 255);
        self.res.light_changed(self.ctx, &self.settings)?;
        Ok(())
    }

    /// Reuse the light-space structure (ISSM map, deep lists, shadow maps)
    /// across frames while the light, the spheres and the opacity stay as
    /// they are: only the camera then costs (the viewer's orbit, the
    /// bench's cached runs). Off by default.
    pub fn set_light_cache(&mut self, on: bool) {
        // (with levels of detail the light's list follows the camera's
        // choice: its map is drawn every frame)
        self.res
            .stages
            .shadows
            .set_cache(on && self.res.scene.lod.is_none());
    }

    /// Writes the colour buffer as BGRA from the next frame on.
    pub fn set_bgra(&mut self, bgra: bool) {
        self.res.bgra = bgra;
    }

    /// The composited colour buffer (RGBA8 or BGRA8 texels, row-major).
    pub fn color_buffer(&self) -> &Buffer {
        &self.res.targets.shade.color
    }

    /// What the renderer holds and its last frame left: read-backs of its
    /// buffers, the active technique, its choices for the current camera.
    pub fn inspect(&self) -> Inspect<'_, 'c> {
        Inspect { r: self }
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
) -> (Vec<u32>, semantic::LevelChoice) {
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
        r.stages.destroy(ctx);
        r.targets.destroy(ctx);
        r.scene.destroy(ctx);
        r.staging.destroy_with(ctx);
    }
}
