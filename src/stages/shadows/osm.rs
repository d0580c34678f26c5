//! Opacity shadow maps (after the WebGL particle paper), the baseline for translucent shadows:
//! `--osm-slices` depth slices evenly covering the light-space depth range of
//! the scene, each an `--osm-size`² map, stored slice-major in one storage
//! buffer (the seed's 8 x 8 atlas of slices is the same array addressed by
//! tile).
//!
//! Passes, each its own timestamp scope; the frame graph derives the
//! barrier between them from what each reads and writes:
//! - `osm_raster`: clear, then every sphere adds its optical depth
//!   `tau = -ln(1 - alpha)` (fixed point, integer atomicAdd) to the slice of
//!   its entry depth at each texel centre its disk covers; big footprints go
//!   through 8-row band jobs as in the rasterizer;
//! - `osm_prefix`: per texel, an in-place inclusive prefix sum over the
//!   slices (fixed point in, float optical depth out);
//! - `osm_shadow`: per visible pixel, `exp(-tau)` at P's light depth, linear
//!   between slice ends, bilinear over texels, minus the receiver's own
//!   deposit (see glsl/osm_shadow.comp for the self-shadowing trade-off).
//!
//! Fixed point rather than float atomics: the result does not depend on the
//! order of the additions (identical frames, reproducible tests) and needs
//! no `shaderBufferFloat32AtomicAdd`; 2^16 steps per unit of optical depth
//! lose nothing visible (a step is 1.5e-5 of transmittance), and one slice of
//! one texel would need about 9,000 fully opaque spheres starting in it to
//! wrap a u32.
//!
//! Opacity 1 would be an infinite optical depth: alpha is clamped to
//! [`ALPHA_MAX`], so a fully opaque sphere leaves 0.001 of the light through
//! (below one 8-bit step).

use super::{FrameCheck, ShadowInputs};
use super::{Lookup, LookupKind, ShadowParams, ShadowSetup, ShadowTechnique};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::gpu::blocks::{OsmRasterPush as RasterPush, PrefixPush};
use crate::gpu::consts::R_BANDS_FULL;
use crate::passes::bands::{BandArgs, BandJob, BandPipelines, JobList};
use crate::passes::scene::SCENE_GEOMETRY;
use crate::passes::{LOCAL_SIZE, spirv};
use crate::settings::ShadowMode;
use crate::stages::raster::compute::RASTER_COUNTERS;
use crate::vk::pipeline::{Binding, PipelineDesc, rw, texel, uniform};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
use std::any::Any;

/// Fixed-point steps per unit of optical depth.
pub const FIXED_SCALE: f32 = 65536.0;
/// Largest opacity used (opaque spheres leave 1 - ALPHA_MAX of the light).
pub const ALPHA_MAX: f32 = 0.999;
/// Footprints above this many texels go to band jobs.
pub const BIG_AREA: u32 = 256;
/// Band jobs per frame at first (past them a sphere's own invocation
/// visits it; a footprint past BAND_INLINE_SAFE texels has the frame drawn
/// again with twice the jobs).
pub const JOB_CAPACITY: u32 = 1 << 18;
/// u32 words after the opacity slices that no pass may touch (GPU-AV does
/// not check atomics, so tests look at these instead).
pub const GUARD_WORDS: u64 = 64;
pub const GUARD_PATTERN: u32 = 0x05A0_F00D;

/// Fixed-point optical depth of one sphere of opacity `alpha`.
pub fn tau_fixed(alpha: f32) -> u32 {
    let a = alpha.clamp(0.0, ALPHA_MAX) as f64;
    (-(1.0 - a).ln() * FIXED_SCALE as f64).round() as u32
}

/// Same counter words as the camera raster (glsl/osm_raster.comp), and
/// R_BANDS_FULL.
const COUNTER_BYTES: u64 = (R_BANDS_FULL as u64 + 1) * 4;

pub struct OpacityShadows {
    pub light: Camera,
    slices: u32,
    sphere_count: u32,
    /// Light depth range (relative to the light's centre plane) the slices cover.
    z_min: f32,
    z_max: f32,
    opacity_map: Buffer,
    jobs: JobList,
    /// [0] bands requested, [1] bands run, [4..7] indirect dispatch args.
    counters: Buffer,
    raster: BandPipelines,
    args: BandArgs,
    prefix: ComputePipeline,
}

/// The lookup's binding (glsl/lookup_osm.glsl): the prefix-summed optical
/// depths as floats.
const LOOKUP: [Binding; 1] = [texel("tauTex", ash::vk::Format::R32_SFLOAT)];

/// Light depth range of the spheres in a light view, with a hair of margin
/// so the extreme entries stay inside.
fn depth_range(light: &Camera, spheres: impl Iterator<Item = ([f32; 3], f32)>) -> (f32, f32) {
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for (c, r) in spheres {
        let c = glam::DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
        let z = (c - light.center).dot(light.dir);
        lo = lo.min(z - r as f64);
        hi = hi.max(z + r as f64);
    }
    if lo > hi {
        (lo, hi) = (-1.0, 1.0);
    }
    let pad = 1e-4 * (hi - lo).max(1e-3);
    ((lo - pad) as f32, (hi + pad) as f32)
}

impl OpacityShadows {
    pub const RASTER_NAME: &'static str = "osm_raster";
    pub const PREFIX_NAME: &'static str = "osm_prefix";

    pub fn new(setup: &ShadowSetup) -> Result<Self> {
        let ctx = setup.ctx;
        let params = &setup.settings.shadow_maps;
        let light = setup.fit(params.osm_size)?;
        if light.fov_deg.is_some() {
            return Err(Error::Internal(
                "opacity shadow maps need an orthographic light view".into(),
            ));
        }
        let slices = params.osm_slices.max(1);
        let texels = light.width as u64 * light.height as u64;
        let words = texels * slices as u64;
        let range = ctx.props.limits.max_storage_buffer_range as u64;
        if (words + GUARD_WORDS) * 4 > range {
            return Err(Error::DeviceLimit(format!(
                "--shadows osm: {slices} slices of {}² need {} MiB, more than the device's \
                 maxStorageBufferRange ({} MiB); lower --osm-size or --osm-slices",
                light.width,
                (words * 4) >> 20,
                range >> 20
            )));
        }
        let (z_min, z_max) = depth_range(&light, Self::centres(setup));
        // Guarded: an error part way destroys what was made.
        let args = ctx.guard(BandArgs::new(ctx, "osm band args")?);
        let raster = ctx.guard(BandPipelines::new(
            ctx,
            &PipelineDesc {
                name: "osm raster",
                shader: spirv::OSM_RASTER_COMP,
                bindings: &[
                    &[
                        uniform("GlobalsBlock"),
                        rw("Opacity"),
                        rw("Jobs"),
                        rw("Counters"),
                    ][..],
                    &SCENE_GEOMETRY,
                ]
                .concat(),
                push_size: std::mem::size_of::<RasterPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
                scene: setup.scene,
            },
            &[],
        )?);
        let prefix = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "osm prefix",
                shader: spirv::OSM_PREFIX_COMP,
                bindings: &[rw("Opacity")],
                push_size: std::mem::size_of::<PrefixPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
                scene: 0,
            },
        )?);
        let map = ctx.guard(Buffer::storage(
            ctx,
            "osm opacity slices",
            (words + GUARD_WORDS) * 4,
        )?);
        let guard = vec![GUARD_PATTERN; GUARD_WORDS as usize];
        map.upload(ctx, words * 4, bytemuck::cast_slice(&guard))?;
        let jobs = ctx.guard(JobList::new(
            ctx,
            "osm band jobs",
            setup.settings.band_jobs.unwrap_or(JOB_CAPACITY),
        )?);
        let counters = crate::passes::bands::counters_buffer(ctx, "osm counters", COUNTER_BYTES)?;
        let o = OpacityShadows {
            light,
            slices,
            sphere_count: setup.geom.slots(),
            z_min,
            z_max,
            opacity_map: map.keep(),
            jobs: jobs.keep(),
            counters,
            raster: raster.keep(),
            args: args.keep(),
            prefix: prefix.keep(),
        };
        o.log();
        Ok(o)
    }

    /// Entries of the band job list (grown where a frame asked more).
    pub fn job_capacity(&self) -> u32 {
        self.jobs.capacity()
    }

    fn centres<'a>(setup: &'a ShadowSetup) -> impl Iterator<Item = ([f32; 3], f32)> + 'a {
        setup.geom.spheres()
    }

    fn log(&self) {
        log::info!(
            "osm: {} slices of {}², depth {:.2}..{:.2} (slice {:.3}), texel {:.3}",
            self.slices,
            self.light.width,
            self.z_min,
            self.z_max,
            (self.z_max - self.z_min) / self.slices as f32,
            self.light.view_height / self.light.width as f64
        );
    }

    pub fn texels(&self) -> u64 {
        self.light.width as u64 * self.light.height as u64
    }

    pub fn slices(&self) -> u32 {
        self.slices
    }

    /// Light depth range covered by the slices (relative to the light's
    /// centre plane, along the light direction).
    pub fn depth_range(&self) -> (f32, f32) {
        (self.z_min, self.z_max)
    }

    fn inv_dz(&self) -> f32 {
        self.slices as f32 / (self.z_max - self.z_min).max(1e-6)
    }

    /// Bytes of the opacity slices (the technique's map memory).
    pub fn map_bytes(&self) -> u64 {
        self.opacity_map.size
    }

    /// The prefix-summed optical depths, slice-major (`[k * texels + t]` =
    /// optical depth from the light through the end of slice k at texel t).
    pub fn read_optical_depth(&self, ctx: &Context) -> Result<Vec<f32>> {
        self.opacity_map
            .download_pod(ctx, 0, self.texels() * self.slices as u64)
    }

    /// True when the guard words after the slices are intact.
    pub fn guard_ok(&self, ctx: &Context) -> Result<bool> {
        let g: Vec<u32> =
            self.opacity_map
                .download_pod(ctx, self.texels() * self.slices as u64, GUARD_WORDS)?;
        Ok(g.iter().all(|&w| w == GUARD_PATTERN))
    }
}

impl ShadowTechnique for OpacityShadows {
    fn mode(&self) -> ShadowMode {
        ShadowMode::Osm
    }

    /// A sphere's bands did not fit and its own invocation visited more
    /// than BAND_INLINE_SAFE texels (R_BANDS_FULL): twice the jobs,
    /// the frame drawn again.
    fn after_frame(&mut self, ctx: &Context, words: &[u32]) -> Result<FrameCheck> {
        if words.first().is_none_or(|&w| w == 0) {
            return Ok(FrameCheck::Done);
        }
        self.jobs.grow(ctx, "opacity maps")?;
        Ok(FrameCheck::Retry)
    }

    fn readback(&self) -> Option<(&Buffer, u64, u64)> {
        Some((&self.counters, R_BANDS_FULL as u64 * 4, 1))
    }

    fn light(&self) -> &Camera {
        &self.light
    }

    /// `osm_raster` (optical depth deposits) and `osm_prefix` (per-texel
    /// prefix sums over the slices).
    fn record_light<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        let texels = self.texels();
        let words = texels * self.slices as u64;
        let tau = tau_fixed(f.opacity);
        rec.pass(Self::RASTER_NAME, |p| {
            p.fill(&self.opacity_map, words * 4, 0);
            p.fill(&self.counters, COUNTER_BYTES, 0);
            let push = RasterPush {
                sphere_count: self.sphere_count,
                big_area: BIG_AREA,
                job_capacity: self.jobs.capacity(),
                tau_fixed: tau,
                slices: self.slices,
                z_min: self.z_min,
                inv_dz: self.inv_dz(),
                pad: 0,
            };
            let mut bindings = vec![
                ("GlobalsBlock", f.globals),
                ("Opacity", &self.opacity_map),
                ("Jobs", &self.jobs.buf),
                ("Counters", &self.counters),
            ];
            bindings.extend(f.scene.geometry());
            self.args.steps(
                p,
                &BandJob {
                    spheres: &self.raster.spheres,
                    bands: &self.raster.bands,
                    push: &push,
                    bindings: &bindings,
                    sphere_count: self.sphere_count,
                    indirect: None,
                    counters: &self.counters,
                    layout: &self.jobs.layout(RASTER_COUNTERS),
                },
            );
            Ok(())
        })?;
        rec.pass(Self::PREFIX_NAME, |p| {
            p.dispatch(
                &self.prefix,
                &PrefixPush {
                    texels: texels as u32,
                    slices: self.slices,
                    inv_scale: 1.0 / FIXED_SCALE,
                },
                Grid::Invocations(texels),
                &[("Opacity", &self.opacity_map)],
            );
            Ok(())
        })
    }

    fn lookup(&self, opacity: f32) -> Lookup<'_> {
        Lookup {
            kind: LookupKind::Opacity,
            soft: false,
            bindings: &LOOKUP,
            buffers: vec![("tauTex", &self.opacity_map)],
            params: ShadowParams {
                f0: [self.z_min, self.inv_dz(), 1.0 / FIXED_SCALE, 0.0],
                u: [tau_fixed(opacity), self.slices, 0, 0],
                ..Default::default()
            },
        }
    }

    fn refit(&mut self, setup: &ShadowSetup) -> Result<()> {
        self.light = setup.fit(self.light.width)?;
        (self.z_min, self.z_max) = depth_range(&self.light, Self::centres(setup));
        self.sphere_count = setup.geom.slots();
        self.log();
        Ok(())
    }

    fn memory(&self) -> Vec<(&'static str, u64)> {
        vec![(
            "osm",
            self.opacity_map.size + self.jobs.buf.size + self.counters.size,
        )]
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }

    fn destroy(&mut self, ctx: &Context) {
        self.raster.destroy(ctx);
        self.prefix.destroy(ctx);
        self.args.destroy(ctx);
        self.opacity_map.destroy(ctx);
        self.jobs.destroy(ctx);
        self.counters.destroy(ctx);
    }
}
