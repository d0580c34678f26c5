//! The frame graph: scene buffers, render targets and the passes recorded in
//! order, each inside its own timestamp scope.

use crate::camera::Camera;
use crate::error::{Error, Result, VkContext};
use crate::gpu::{Globals, GpuSphere, SphereAttr};
use crate::output::DeepStats;
use crate::passes::ShadowInputs;
use crate::passes::blur::{Axis, BlurPass, BlurPush};
use crate::passes::composite::{CompositeInputs, CompositePass, CompositePush};
use crate::passes::deep::DeepShadows;
use crate::passes::issm::{self, IssmPush, IssmShadowPass};
use crate::passes::osm::OpacityShadows;
use crate::passes::raster::{self, RasterPass, ViewIndex};
use crate::passes::raster_graphics::GraphicsRasterPass;
use crate::passes::resolve::ResolvePass;
use crate::passes::shadow_map::ShadowMap;
use crate::passes::ssdo::{GBuffer, KeyShadowPush, SsdoPass, SsdoPush};
use crate::scene::Scene;
use crate::semantic::{self, LevelChoice};
use crate::settings::{RasterMode, RenderSettings, ShadowMode, SsdoMode};
use crate::vk::guard::Destroy;
use crate::vk::{Buffer, Context, Profiler, barrier};
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::collections::BTreeMap;

/// Fraction of the key light's diffuse term kept in full shadow.
pub const SHADOW_DIFFUSE: f32 = 0.12;

/// Per-pass milliseconds of one frame, in recording order.
pub type PassTimes = Vec<(&'static str, f64)>;

pub struct Renderer<'c> {
    ctx: &'c Context,
    pub settings: RenderSettings,
    pub sphere_count: u32,
    globals_data: Globals,
    /// Bounding sphere of the scene (camera depth offsets, zoom distance).
    bounds: (glam::DVec3, f64),
    /// Write the colour buffer as BGRA (for BGRA swapchains).
    bgra: bool,
    /// Per-frame resources, so a frame can be recorded while the previous
    /// one still runs (the viewer); `render_frame` uses them one at a time.
    slots: Vec<FrameSlot>,
    /// The slot the next frame uses.
    next_slot: usize,
    spheres: Buffer,
    attrs: Buffer,
    vis: Buffer,
    gpos: Buffer,
    gnorm: Buffer,
    gregion: Buffer,
    shadow: Buffer,
    ambient: Buffer,
    /// Blur ping-pong and results: [ambient tmp, shadow tmp, ambient out, shadow out].
    blurred: [Buffer; 4],
    color: Buffer,
    ssdo: Option<SsdoState>,
    raster: RasterPass,
    /// The vertex/fragment baseline, when `--raster graphics`.
    raster_graphics: Option<GraphicsRasterPass>,
    resolve: ResolvePass,
    composite: CompositePass,
    issm: Option<IssmState>,
    deep: Option<DeepShadows>,
    /// Baseline depth shadow map with PCF (`--shadows sm-pcf`).
    shadow_map: Option<ShadowMap>,
    /// Baseline opacity shadow maps (`--shadows osm`).
    osm: Option<OpacityShadows>,
    /// Stats of the last frame's deep lists (after any pool growth).
    pub deep_stats: Option<DeepStats>,
}

/// What one frame in flight owns: its command buffer, fence, timestamp
/// queries and uniform buffer (descriptor sets come from the context's arena
/// of the same slot). Render targets are shared: frames on the one queue run
/// in order, and each frame starts with a full barrier.
struct FrameSlot {
    cmd: vk::CommandBuffer,
    /// Signalled when the frame that last used this slot finished.
    fence: vk::Fence,
    profiler: Profiler,
    globals: Buffer,
    /// A frame was submitted with this slot and its results not yet read.
    pending: bool,
}

impl FrameSlot {
    fn new(ctx: &Context, i: usize) -> Result<Self> {
        let cmd = ctx.command_buffer(&format!("frame {i}"))?;
        let info = vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED);
        let fence = unsafe { ctx.device.create_fence(&info, None) }.vk("vkCreateFence")?;
        ctx.name(fence, &format!("frame fence {i}"));
        let globals = Buffer::new(
            ctx,
            &format!("globals {i}"),
            std::mem::size_of::<Globals>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        Ok(FrameSlot {
            cmd,
            fence,
            profiler: Profiler::new(ctx, 32)?,
            globals,
            pending: false,
        })
    }

    fn destroy(&mut self, ctx: &Context) {
        unsafe {
            ctx.device.destroy_fence(self.fence, None);
            ctx.device
                .free_command_buffers(ctx.command_pool, &[self.cmd]);
        }
        self.profiler.destroy(ctx);
        self.globals.destroy(ctx);
    }
}

/// SSDO, screen-space key shadows and blur with this frame's parameters.
struct SsdoState {
    /// Typical sphere radius, useful levels and zoom thresholds: kept so a
    /// camera change can re-derive radii and the level choice.
    radius: f64,
    levels: Vec<u32>,
    thresholds: Vec<f64>,
    pass: SsdoPass,
    blur: BlurPass,
    push: SsdoPush,
    key_shadow: KeyShadowPush,
    blur_push: BlurPush,
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

/// The key light's sphere id map and the shadow lookup that reads it.
struct IssmState {
    light: Camera,
    map: Buffer,
    pass: IssmShadowPass,
    push: IssmPush,
}

/// Builds the DESIGN.md default camera for a scene, overridable per field.
#[allow(clippy::too_many_arguments)]
pub fn default_camera(
    scene: &Scene,
    width: u32,
    height: u32,
    view_dir: glam::DVec3,
    up: glam::DVec3,
    center: Option<glam::DVec3>,
    view_height: Option<f64>,
    fov: Option<f64>,
) -> Result<Camera> {
    let (bs_center, bs_radius) = scene.bounding_sphere();
    let center = center.unwrap_or(bs_center.as_dvec3());
    let h = view_height.unwrap_or((2.0 * bs_radius as f64 * 1.05).max(1e-3));
    Camera::new(center, view_dir, up, h, fov, width, height)
}

impl<'c> Renderer<'c> {
    pub fn new(ctx: &'c Context, scene: &Scene, settings: RenderSettings) -> Result<Self> {
        if scene.spheres.is_empty() {
            return Err(Error::Invalid(format!(
                "{}: no spheres to render",
                scene.source
            )));
        }
        if scene.spheres.len() >= (1 << 24) {
            return Err(Error::Invalid(format!(
                "{} spheres: at most 16,777,215 are supported (sphere ids are 24-bit in the id AOV)",
                scene.spheres.len()
            )));
        }
        let cam = &settings.camera;
        let pixels = cam.width as u64 * cam.height as u64;
        // Every light-space technique uses the same view fitted to the
        // spheres, at its own map size. The baselines are built first, so a
        // map the device cannot hold fails before anything else is allocated.
        let fit_light = |size: u32| {
            crate::camera::light_view(
                scene.spheres.iter().map(|s| (s.center, s.radius)),
                settings.light,
                size,
            )
        };
        let shadow_map = ctx.guard(match settings.shadows {
            ShadowMode::SmPcf => Some(ShadowMap::new(
                ctx,
                fit_light(settings.shadow_maps.sm_size)?,
                &settings.shadow_maps,
            )?),
            _ => None,
        });
        let osm = ctx.guard(match settings.shadows {
            ShadowMode::Osm => Some(OpacityShadows::new(
                ctx,
                fit_light(settings.shadow_maps.osm_size)?,
                scene.spheres.iter().map(|s| (s.center, s.radius)),
                &settings.shadow_maps,
            )?),
            _ => None,
        });
        let geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let attrs: Vec<SphereAttr> = scene
            .spheres
            .iter()
            .map(|s| SphereAttr {
                region: s.region,
                color: u32::from_le_bytes(s.color),
                ..Default::default()
            })
            .collect();

        // Each object is guarded until the renderer owns it: an error part
        // way (a buffer over the device limit) destroys what was made.
        let storage =
            |name: &str, size: u64| Ok::<_, Error>(ctx.guard(Buffer::storage(ctx, name, size)?));
        let spheres = storage("spheres", (geom.len() * 16) as u64)?;
        spheres.upload(ctx, 0, bytemuck::cast_slice(&geom))?;
        let attr_buf = storage("sphere attributes", (attrs.len() * 32) as u64)?;
        attr_buf.upload(ctx, 0, bytemuck::cast_slice(&attrs))?;

        let vis = ctx.guard(raster::vis_buffer(ctx, "visibility", pixels)?);
        let gpos = storage("gbuffer position", pixels * 16)?;
        let gnorm = storage("gbuffer normal", pixels * 16)?;
        let gregion = storage("gbuffer regions", pixels * 16)?;
        let shadow = storage("key-light visibility", pixels * 4)?;
        let ambient = storage("ambient visibility+bounce", pixels * 16)?;
        let blurred = [
            storage("ambient blur tmp", pixels * 16)?,
            storage("shadow blur tmp", pixels * 4)?,
            storage("ambient blurred", pixels * 16)?,
            storage("shadow blurred", pixels * 4)?,
        ];
        let color = storage("colour", pixels * 4)?;

        let (bs_center, bs_radius) = scene.bounding_sphere();
        let depth_offset = (bs_center.as_dvec3() - cam.center).length() + bs_radius as f64 + 1.0;
        let issm = ctx.guard(match settings.shadows {
            ShadowMode::Issm | ShadowMode::IssmSoft => {
                let soft = settings.shadows == ShadowMode::IssmSoft;
                let p = &settings.issm;
                let light = fit_light(p.size)?;
                let texel = light.view_height / p.size as f64;
                let (t, stride) = match p.t {
                    Some(t) => (t, 1),
                    None => {
                        let min_r = scene
                            .spheres
                            .iter()
                            .map(|s| s.radius)
                            .fold(f32::MAX, f32::min);
                        let t = issm::auto_t(
                            scene.max_radius(),
                            if soft { p.soft_s } else { 0.0 },
                            texel,
                        );
                        (t, issm::auto_stride(min_r, texel))
                    }
                };
                log::info!(
                    "issm: map {}², texel {texel:.3}, t {t}, stride {stride}",
                    p.size
                );
                let map = ctx.guard(raster::vis_buffer(
                    ctx,
                    "issm",
                    p.size as u64 * p.size as u64,
                )?);
                let pass = IssmShadowPass::new(ctx)?;
                Some(IssmState {
                    map: map.keep(),
                    pass,
                    push: IssmShadowPass::push(p, soft, t, stride),
                    light,
                })
            }
            _ => None,
        });
        // Deep lists use the same tightly fitted light view as the ISSM.
        let deep = ctx.guard(match settings.shadows {
            ShadowMode::Deep => {
                let p = &settings.issm;
                let light = fit_light(p.size)?;
                let radii: Vec<f32> = geom.iter().map(|g| g[3]).collect();
                Some(DeepShadows::new(
                    ctx,
                    light,
                    &radii,
                    settings.deep_pool_chunks,
                )?)
            }
            _ => None,
        });
        let light_cam = issm
            .as_ref()
            .map(|s| s.light)
            .or(deep.as_ref().map(|d| d.light))
            .or(shadow_map.as_ref().map(|s| s.light))
            .or(osm.as_ref().map(|o| o.light));
        let light_gpu = match light_cam {
            Some(l) => {
                let off = (bs_center.as_dvec3() - l.center).length() + bs_radius as f64 + 1.0;
                l.to_gpu(off)
            }
            None => cam.to_gpu(depth_offset),
        };
        let globals_data = Globals {
            cam: cam.to_gpu(depth_offset),
            light: light_gpu,
            light_dir: {
                let l = settings.light.normalize();
                [l.x as f32, l.y as f32, l.z as f32, 0.0]
            },
            background: [0.13, 0.14, 0.17, 1.0],
            counts: [geom.len() as u32, 0, 0, 0],
            params: [0.0; 4],
        };

        let ssdo = ctx.guard(match settings.ssdo {
            SsdoMode::Off => None,
            mode => {
                let r = typical_radius(scene) as f64;
                // Radii in world units, at least a few pixels so far views still sample.
                let px = 1.0 / cam.pixels_per_unit();
                let (levels, choice) = level_choice(scene, cam, &settings.semantic_levels);
                log::info!("semantic levels {levels:?}, choice {choice:?}");
                let semantic = (mode == SsdoMode::Semantic) as u32;
                let thresholds = settings.semantic_levels.clone().unwrap_or_else(|| {
                    semantic::default_thresholds(levels.len(), 2.0 * bs_radius as f64 * 1.05)
                });
                let pass = ctx.guard(SsdoPass::new(ctx)?);
                let blur = BlurPass::new(ctx)?;
                Some(SsdoState {
                    radius: r,
                    levels,
                    thresholds,
                    pass: pass.keep(),
                    blur,
                    push: SsdoPush {
                        r_near: (2.0 * r).max(2.0 * px) as f32,
                        r_far: (8.0 * r).max(8.0 * px) as f32,
                        dirs: 12,
                        steps: 4,
                        semantic,
                        level_a: choice.level_a,
                        level_b: choice.level_b,
                        blend: choice.blend,
                        bounce: 1.0,
                        pad: [0.0; 3],
                    },
                    key_shadow: KeyShadowPush {
                        march: (6.0 * r).max(6.0 * px) as f32,
                        thickness: (2.0 * r).max(px) as f32,
                        steps: 12,
                        pad: 0.0,
                    },
                    blur_push: BlurPush {
                        radius: 4,
                        sigma_z: (0.5 * r).max(px) as f32,
                        semantic,
                        level: if choice.blend >= 0.5 {
                            choice.level_b
                        } else {
                            choice.level_a
                        },
                        blur_shadow: 0,
                        pad: [0.0; 3],
                    },
                })
            }
        });

        // Without a shadow pass, key-light visibility is 1 everywhere.
        ctx.one_shot("init shadow", |cmd| {
            unsafe {
                ctx.device
                    .cmd_fill_buffer(cmd, shadow.raw, 0, vk::WHOLE_SIZE, 1.0f32.to_bits())
            };
            Ok(())
        })?;

        let raster_graphics = ctx.guard(match settings.raster {
            RasterMode::Graphics => Some(GraphicsRasterPass::new(ctx)?),
            RasterMode::Compute => None,
        });
        let mut slots = ctx.guard(Vec::new());
        for i in 0..crate::vk::FRAME_SLOTS {
            slots.push(FrameSlot::new(ctx, i)?);
        }
        let raster = ctx.guard(RasterPass::new(ctx)?);
        let resolve = ctx.guard(ResolvePass::new(ctx)?);
        let composite = CompositePass::new(ctx)?;
        Ok(Renderer {
            ctx,
            sphere_count: geom.len() as u32,
            settings,
            globals_data,
            bounds: (bs_center.as_dvec3(), bs_radius as f64),
            bgra: false,
            slots: slots.keep(),
            next_slot: 0,
            spheres: spheres.keep(),
            attrs: attr_buf.keep(),
            vis: vis.keep(),
            gpos: gpos.keep(),
            gnorm: gnorm.keep(),
            gregion: gregion.keep(),
            shadow: shadow.keep(),
            ambient: ambient.keep(),
            blurred: blurred.map(|b| b.keep()),
            color: color.keep(),
            ssdo: ssdo.keep(),
            raster: raster.keep(),
            raster_graphics: raster_graphics.keep(),
            resolve: resolve.keep(),
            composite,
            issm: issm.keep(),
            deep: deep.keep(),
            shadow_map: shadow_map.keep(),
            osm: osm.keep(),
            deep_stats: None,
        })
    }

    /// The composited colour buffer (RGBA8 or BGRA8 texels, row-major).
    pub fn color_buffer(&self) -> &Buffer {
        &self.color
    }

    pub fn is_bgra(&self) -> bool {
        self.bgra
    }

    /// Writes the colour buffer as BGRA from the next frame on.
    pub fn set_bgra(&mut self, bgra: bool) {
        self.bgra = bgra;
    }

    /// Moves the camera (same image size); light-space maps are camera
    /// independent, screen-space radii and the semantic level follow it.
    pub fn set_camera(&mut self, cam: Camera) -> Result<()> {
        let old = &self.settings.camera;
        if (cam.width, cam.height) != (old.width, old.height) {
            return Err(Error::Invalid(
                "set_camera: the image size cannot change; make a new renderer".into(),
            ));
        }
        let (c, r) = self.bounds;
        self.globals_data.cam = cam.to_gpu((c - cam.center).length() + r + 1.0);
        if let Some(st) = &mut self.ssdo {
            let px = 1.0 / cam.pixels_per_unit();
            let rad = st.radius;
            st.push.r_near = (2.0 * rad).max(2.0 * px) as f32;
            st.push.r_far = (8.0 * rad).max(8.0 * px) as f32;
            st.key_shadow.march = (6.0 * rad).max(6.0 * px) as f32;
            st.key_shadow.thickness = (2.0 * rad).max(px) as f32;
            st.blur_push.sigma_z = (0.5 * rad).max(px) as f32;
            let choice =
                semantic::choose(semantic::zoom_distance(&cam, c), &st.thresholds, &st.levels);
            st.push.level_a = choice.level_a;
            st.push.level_b = choice.level_b;
            st.push.blend = choice.blend;
            st.blur_push.level = if choice.blend >= 0.5 {
                choice.level_b
            } else {
                choice.level_a
            };
        }
        self.settings.camera = cam;
        Ok(())
    }

    pub fn pixels(&self) -> u64 {
        self.settings.camera.width as u64 * self.settings.camera.height as u64
    }

    /// Device memory of this renderer's buffers by class (bytes requested,
    /// before allocator alignment): what a user sizing a data set needs to
    /// know is which part grows with spheres, pixels or the light map.
    pub fn memory_by_class(&self) -> BTreeMap<String, u64> {
        let sum = |bs: &[&Buffer]| bs.iter().map(|b| b.size).sum::<u64>();
        let mut m = BTreeMap::new();
        let mut add = |class: &str, bytes: u64| {
            if bytes > 0 {
                *m.entry(class.to_string()).or_insert(0) += bytes;
            }
        };
        add("scene", sum(&[&self.spheres, &self.attrs]));
        add(
            "uniforms",
            self.slots.iter().map(|f| f.globals.size).sum::<u64>(),
        );
        add("visibility", self.vis.size + self.raster.memory_bytes());
        add(
            "gbuffer",
            sum(&[
                &self.gpos,
                &self.gnorm,
                &self.gregion,
                &self.shadow,
                &self.ambient,
                &self.color,
            ]) + self.blurred.iter().map(|b| b.size).sum::<u64>(),
        );
        add("issm_map", self.issm.as_ref().map_or(0, |s| s.map.size));
        if let Some(d) = &self.deep {
            let (pool, tables) = d.memory_split();
            add("deep_pool", pool);
            add("deep_tables", tables);
        }
        add(
            "shadow_map",
            self.shadow_map.as_ref().map_or(0, |s| s.memory_bytes()),
        );
        add("osm", self.osm.as_ref().map_or(0, |o| o.memory_bytes()));
        m
    }

    /// Renders one frame; when the deep-list pool overflowed, grows it and
    /// renders the frame again (the overflowed frame's image is discarded).
    pub fn render_frame(&mut self) -> Result<PassTimes> {
        let mut times = self.submit_frame()?;
        let Some(deep) = &self.deep else {
            return Ok(times);
        };
        let mut stats = deep.read_stats(self.ctx)?;
        let overflowed = stats.overflowed;
        for _ in 0..4 {
            if !stats.overflowed {
                break;
            }
            let needed = stats.chunks_used;
            if let Some(d) = &mut self.deep {
                d.grow(self.ctx, needed)?;
            }
            times = self.submit_frame()?;
            stats = self
                .deep
                .as_ref()
                .map(|d| d.read_stats(self.ctx))
                .transpose()?
                .unwrap_or(stats);
        }
        if stats.overflowed {
            return Err(Error::Invalid(
                "deep shadow list pool still overflows after growing it".into(),
            ));
        }
        // Report that this frame needed a retry even though the final one fit.
        stats.overflowed = overflowed;
        self.deep_stats = Some(stats);
        Ok(times)
    }

    /// Records, submits and waits for one frame; returns per-pass times.
    fn submit_frame(&mut self) -> Result<PassTimes> {
        let slot = self.submit()?;
        self.finish_slot(slot)?
            .ok_or_else(|| Error::Invalid("frame results missing".into()))
    }

    /// Records and submits the next frame without waiting for it; returns
    /// the per-pass times of the frame that used this slot before (already
    /// finished, or waited for: at most one other frame stays in flight).
    /// Deep lists need their overflow check after every frame, so with
    /// `--shadows deep` this waits like `render_frame`.
    pub fn render_frame_pipelined(&mut self) -> Result<Option<PassTimes>> {
        if self.deep.is_some() {
            return self.render_frame().map(Some);
        }
        let slot = self.next_slot;
        let previous = self.finish_slot(slot)?;
        self.submit()?;
        Ok(previous)
    }

    /// Waits for the frame last submitted with `slot` and reads its timings.
    fn finish_slot(&mut self, slot: usize) -> Result<Option<PassTimes>> {
        let ctx = self.ctx;
        let fs = &mut self.slots[slot];
        unsafe { ctx.device.wait_for_fences(&[fs.fence], true, u64::MAX) }.vk("vkWaitForFences")?;
        if !fs.pending {
            return Ok(None);
        }
        fs.pending = false;
        fs.profiler.results(ctx).map(Some)
    }

    /// Records and submits one frame in the next slot (whose previous frame
    /// must have finished); returns the slot.
    fn submit(&mut self) -> Result<usize> {
        let ctx = self.ctx;
        let dev = &ctx.device;
        let slot = self.next_slot;
        self.next_slot = (slot + 1) % self.slots.len();
        {
            let fs = &mut self.slots[slot];
            unsafe { dev.wait_for_fences(&[fs.fence], true, u64::MAX) }.vk("vkWaitForFences")?;
            match fs.globals.mapped_mut() {
                Some(m) => m.copy_from_slice(bytemuck::bytes_of(&self.globals_data)),
                None => fs
                    .globals
                    .upload(ctx, 0, bytemuck::bytes_of(&self.globals_data))?,
            }
        }
        // This slot's previous frame finished: its descriptor sets are free.
        ctx.begin_descriptor_frame(slot)?;
        let cmd = self.slots[slot].cmd;
        unsafe {
            dev.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .vk("vkResetCommandBuffer")?;
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            dev.begin_command_buffer(cmd, &begin)
                .vk("vkBeginCommandBuffer")?;
        }
        let recorded = self.record(slot);
        unsafe { dev.end_command_buffer(cmd) }.vk("vkEndCommandBuffer")?;
        recorded?;
        let fs = &mut self.slots[slot];
        let cmds = [cmd];
        let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
        unsafe {
            dev.reset_fences(&[fs.fence]).vk("vkResetFences")?;
            dev.queue_submit(ctx.queue, &submit, fs.fence)
                .vk("vkQueueSubmit")?;
        }
        fs.pending = true;
        Ok(slot)
    }

    fn record(&mut self, slot: usize) -> Result<()> {
        let ctx = self.ctx;
        let pixels = self.pixels();
        let FrameSlot {
            cmd,
            profiler: prof,
            globals,
            ..
        } = &mut self.slots[slot];
        let (cmd, globals): (vk::CommandBuffer, &Buffer) = (*cmd, globals);
        prof.begin_frame(ctx, cmd);
        barrier(&ctx.device, cmd);

        if let Some(gr) = &self.raster_graphics {
            let size = (self.settings.camera.width, self.settings.camera.height);
            prof.begin(ctx, cmd, "raster")?;
            gr.record(
                ctx,
                cmd,
                globals,
                &self.spheres,
                self.sphere_count,
                &self.vis,
                size,
            )?;
            prof.end(ctx, cmd)?;
            barrier(&ctx.device, cmd);
        } else {
            self.raster.record_scoped(
                ctx,
                cmd,
                prof,
                "raster",
                globals,
                &self.spheres,
                self.sphere_count,
                &self.vis,
                pixels,
                ViewIndex::Camera,
            )?;
        }

        if let Some(st) = &self.issm {
            let n = st.light.width as u64 * st.light.height as u64;
            let name = IssmShadowPass::RASTER_NAME;
            let (g, s, c) = (globals, &self.spheres, self.sphere_count);
            self.raster.record_scoped(
                ctx,
                cmd,
                prof,
                name,
                g,
                s,
                c,
                &st.map,
                n,
                ViewIndex::Light,
            )?;
        }

        if let Some(sm) = &self.shadow_map {
            let (g, s, c) = (globals, &self.spheres, self.sphere_count);
            sm.record_raster(ctx, cmd, prof, &self.raster, g, s, c)?;
        }

        prof.begin(ctx, cmd, ResolvePass::NAME)?;
        let (g, s, v, gp, gn) = (globals, &self.spheres, &self.vis, &self.gpos, &self.gnorm);
        self.resolve.record(
            ctx,
            cmd,
            g,
            s,
            v,
            gp,
            gn,
            &self.attrs,
            &self.gregion,
            pixels,
        )?;
        prof.end(ctx, cmd)?;
        barrier(&ctx.device, cmd);

        let inputs = ShadowInputs {
            globals,
            spheres: &self.spheres,
            vis: &self.vis,
            gpos: &self.gpos,
            gnorm: &self.gnorm,
            shadow: &self.shadow,
            opacity: self.settings.opacity,
            pixels,
        };
        if let Some(d) = &self.deep {
            d.record(ctx, cmd, prof, &inputs)?;
        }

        if let Some(st) = &self.issm {
            prof.begin(ctx, cmd, IssmShadowPass::NAME)?;
            st.pass.record(ctx, cmd, &inputs, &st.map, &st.push)?;
            prof.end(ctx, cmd)?;
            barrier(&ctx.device, cmd);
        }

        if let Some(sm) = &self.shadow_map {
            sm.record_shadow(ctx, cmd, prof, &inputs)?;
        }

        if let Some(o) = &self.osm {
            o.record(ctx, cmd, prof, &inputs)?;
        }

        // Light-space shadows (exact or baseline) replace the screen-space ones.
        let exact_shadows = self.issm.is_some()
            || self.deep.is_some()
            || self.shadow_map.is_some()
            || self.osm.is_some();
        let (mut amb_final, mut shadow_final) = (&self.ambient, &self.shadow);
        if let Some(st) = &self.ssdo {
            let gb = GBuffer {
                attrs: &self.attrs,
                vis: &self.vis,
                gpos: &self.gpos,
                gnorm: &self.gnorm,
                gregion: &self.gregion,
            };
            if !exact_shadows {
                // Screen-space key shadows stand in for the exact techniques.
                prof.begin(ctx, cmd, SsdoPass::KEY_SHADOW)?;
                st.pass.record_key_shadow(
                    ctx,
                    cmd,
                    globals,
                    &gb,
                    &self.shadow,
                    &st.key_shadow,
                    pixels,
                )?;
                prof.end(ctx, cmd)?;
                barrier(&ctx.device, cmd);
            }
            prof.begin(ctx, cmd, SsdoPass::NAME)?;
            st.pass.record_ssdo(
                ctx,
                cmd,
                globals,
                &gb,
                &self.shadow,
                &self.ambient,
                &st.push,
                pixels,
            )?;
            prof.end(ctx, cmd)?;
            barrier(&ctx.device, cmd);
            if self.settings.blur {
                // Exact (ISSM/deep) shadows are smooth already: only the
                // noisy screen-space ones are blurred.
                let push = BlurPush {
                    blur_shadow: (!exact_shadows) as u32,
                    ..st.blur_push
                };
                let geo = [&self.gpos, &self.gnorm, &self.gregion];
                let [a_tmp, s_tmp, a_out, s_out] = &self.blurred;
                for (axis, input, output) in [
                    (
                        Axis::Horizontal,
                        [&self.ambient, &self.shadow],
                        [a_tmp, s_tmp],
                    ),
                    (Axis::Vertical, [a_tmp, s_tmp], [a_out, s_out]),
                ] {
                    prof.begin(ctx, cmd, axis.name())?;
                    st.blur
                        .record(ctx, cmd, axis, globals, geo, input, output, &push, pixels)?;
                    prof.end(ctx, cmd)?;
                    barrier(&ctx.device, cmd);
                }
                (amb_final, shadow_final) = (a_out, s_out);
            }
        }

        prof.begin(ctx, cmd, CompositePass::NAME)?;
        let io = CompositeInputs {
            attrs: &self.attrs,
            vis: &self.vis,
            gpos: &self.gpos,
            gnorm: &self.gnorm,
            shadow: shadow_final,
            ambient: amb_final,
            color: &self.color,
        };
        let use_shadow = (exact_shadows || self.ssdo.is_some()) as u32;
        let use_ambient = self.ssdo.is_some() as u32;
        let push = CompositePush {
            use_shadow,
            use_ambient,
            // Lighting rule (issue 4, after the ISSM paper): a fully shadowed
            // point keeps ambient and this fraction of the key's diffuse term,
            // and loses its specular term; partial shadow blends linearly.
            shadow_diffuse: SHADOW_DIFFUSE,
            swap_rb: self.bgra as u32,
        };
        self.composite
            .record(ctx, cmd, globals, &io, &push, pixels)?;
        prof.end(ctx, cmd)?;
        barrier(&ctx.device, cmd);
        Ok(())
    }

    /// Visibility buffer (depth|id per pixel), without the guard words.
    pub fn read_vis(&self) -> Result<Vec<u64>> {
        self.vis.download_pod(self.ctx, 0, self.pixels())
    }

    /// The guard words after the visibility buffer (must stay GUARD_PATTERN).
    pub fn read_vis_guard(&self) -> Result<Vec<u64>> {
        self.vis
            .download_pod(self.ctx, self.pixels(), raster::VIS_GUARD_WORDS)
    }

    pub fn read_color(&self) -> Result<Vec<u32>> {
        self.color.download_pod(self.ctx, 0, self.pixels())
    }

    /// G-buffer positions: xyz world, w depth key (-1 = background).
    pub fn read_gpos(&self) -> Result<Vec<[f32; 4]>> {
        self.gpos.download_pod(self.ctx, 0, self.pixels())
    }

    /// The ISSM light view, patch half-size t and the light-space id map.
    pub fn issm_info(&self) -> Option<(Camera, u32)> {
        self.issm.as_ref().map(|s| (s.light, s.push.t as u32))
    }

    pub fn read_issm(&self) -> Result<Option<Vec<u64>>> {
        match &self.issm {
            Some(st) => Ok(Some(st.map.download_pod(
                self.ctx,
                0,
                st.light.width as u64 * st.light.height as u64,
            )?)),
            None => Ok(None),
        }
    }

    /// The baseline depth shadow map, when `--shadows sm-pcf` is active.
    pub fn shadow_map(&self) -> Option<&ShadowMap> {
        self.shadow_map.as_ref()
    }

    /// The baseline opacity shadow maps, when `--shadows osm` is active.
    pub fn opacity_shadows(&self) -> Option<&OpacityShadows> {
        self.osm.as_ref()
    }

    /// The deep shadow lists, when `--shadows deep` is active.
    pub fn deep(&self) -> Option<&DeepShadows> {
        self.deep.as_ref()
    }

    pub fn read_shadow(&self) -> Result<Vec<f32>> {
        self.shadow.download_pod(self.ctx, 0, self.pixels())
    }

    /// Ambient visibility (x) and bounce (yzw) before the blur.
    pub fn read_ambient_raw(&self) -> Result<Vec<[f32; 4]>> {
        self.ambient.download_pod(self.ctx, 0, self.pixels())
    }

    /// Ambient visibility (x) and bounce (yzw) as the composite uses it
    /// (after the blur when it is on).
    pub fn read_ambient(&self) -> Result<Vec<[f32; 4]>> {
        let b = if self.ssdo.is_some() && self.settings.blur {
            &self.blurred[2]
        } else {
            &self.ambient
        };
        b.download_pod(self.ctx, 0, self.pixels())
    }

    /// The semantic level choice of this frame, when SSDO runs.
    pub fn level_choice(&self) -> Option<LevelChoice> {
        self.ssdo.as_ref().map(|s| LevelChoice {
            level_a: s.push.level_a,
            level_b: s.push.level_b,
            blend: s.push.blend,
        })
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

crate::impl_destroy!(FrameSlot);

impl Destroy for IssmState {
    fn destroy_with(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.map.destroy(ctx);
    }
}

impl Destroy for SsdoState {
    fn destroy_with(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.blur.destroy(ctx);
    }
}

impl Drop for Renderer<'_> {
    fn drop(&mut self) {
        let ctx = self.ctx;
        ctx.wait_idle();
        self.slots.destroy_with(ctx);
        self.raster.destroy(ctx);
        self.raster_graphics.destroy_with(ctx);
        self.resolve.destroy(ctx);
        self.composite.destroy(ctx);
        self.issm.destroy_with(ctx);
        self.deep.destroy_with(ctx);
        self.shadow_map.destroy_with(ctx);
        self.osm.destroy_with(ctx);
        self.ssdo.destroy_with(ctx);
        for b in [
            &mut self.spheres,
            &mut self.attrs,
            &mut self.vis,
            &mut self.gpos,
            &mut self.gnorm,
            &mut self.gregion,
            &mut self.shadow,
            &mut self.ambient,
            &mut self.color,
        ] {
            b.destroy(ctx);
        }
        self.blurred.destroy_with(ctx);
    }
}
