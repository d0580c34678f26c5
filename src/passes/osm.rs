//! Opacity shadow maps (seed 004), the baseline for translucent shadows:
//! `--osm-slices` depth slices evenly covering the light-space depth range of
//! the scene, each an `--osm-size`² map, stored slice-major in one storage
//! buffer (the seed's 8 x 8 atlas of slices is the same array addressed by
//! tile).
//!
//! Passes, each its own timestamp scope followed by a full barrier:
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

use super::bands::{BandArgs, BandCounters};
use super::raster::RASTER_COUNTERS;
use super::{LOCAL_SIZE, ShadowInputs, spirv};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::settings::ShadowMapParams;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context, Profiler, barrier};
use ash::vk;
use bytemuck::{Pod, Zeroable};
use gpu_allocator::MemoryLocation;

/// Fixed-point steps per unit of optical depth.
pub const FIXED_SCALE: f32 = 65536.0;
/// Largest opacity used (opaque spheres leave 1 - ALPHA_MAX of the light).
pub const ALPHA_MAX: f32 = 0.999;
/// Footprints above this many texels go to band jobs.
pub const BIG_AREA: u32 = 256;
/// Band jobs per frame before the per-sphere fallback loop.
pub const JOB_CAPACITY: u32 = 1 << 18;
/// u32 words after the opacity slices that no pass may touch (GPU-AV does
/// not check atomics, so tests look at these instead).
pub const GUARD_WORDS: u64 = 64;
pub const GUARD_PATTERN: u32 = 0x05A0_F00D;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct RasterPush {
    bands: u32,
    sphere_count: u32,
    big_area: u32,
    job_capacity: u32,
    tau_fixed: u32,
    slices: u32,
    z_min: f32,
    inv_dz: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct PrefixPush {
    texels: u32,
    slices: u32,
    inv_scale: f32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ShadowPush {
    tau_fixed: u32,
    slices: u32,
    z_min: f32,
    inv_dz: f32,
    inv_scale: f32,
}

/// Fixed-point optical depth of one sphere of opacity `alpha`.
pub fn tau_fixed(alpha: f32) -> u32 {
    let a = alpha.clamp(0.0, ALPHA_MAX) as f64;
    (-(1.0 - a).ln() * FIXED_SCALE as f64).round() as u32
}

/// Same counter words as the camera raster (glsl/osm_raster.comp).
const OSM_COUNTERS: BandCounters = BandCounters {
    job_capacity: JOB_CAPACITY,
    ..RASTER_COUNTERS
};

pub struct OpacityShadows {
    pub light: Camera,
    slices: u32,
    sphere_count: u32,
    /// Light depth range (relative to the light's centre plane) the slices cover.
    z_min: f32,
    z_max: f32,
    opacity_map: Buffer,
    jobs: Buffer,
    /// [0] bands requested, [1] bands run, [4..7] indirect dispatch args.
    counters: Buffer,
    raster: ComputePipeline,
    args: BandArgs,
    prefix: ComputePipeline,
    shadow: ComputePipeline,
}

impl OpacityShadows {
    pub const RASTER_NAME: &'static str = "osm_raster";
    pub const PREFIX_NAME: &'static str = "osm_prefix";
    pub const NAME: &'static str = "osm_shadow";

    /// `light` is the orthographic light view the renderer puts in
    /// `Globals.light` (size `params.osm_size`); `spheres` give the depth range.
    pub fn new(
        ctx: &Context,
        light: Camera,
        spheres: impl Iterator<Item = ([f32; 3], f32)>,
        params: &ShadowMapParams,
    ) -> Result<Self> {
        if light.fov_deg.is_some() {
            return Err(Error::Invalid(
                "opacity shadow maps need an orthographic light view".into(),
            ));
        }
        let slices = params.osm_slices.max(1);
        let texels = light.width as u64 * light.height as u64;
        let words = texels * slices as u64;
        let range = ctx.props.limits.max_storage_buffer_range as u64;
        if (words + GUARD_WORDS) * 4 > range {
            return Err(Error::Invalid(format!(
                "--shadows osm: {slices} slices of {}² need {} MiB, more than the device's \
                 maxStorageBufferRange ({} MiB); lower --osm-size or --osm-slices",
                light.width,
                (words * 4) >> 20,
                range >> 20
            )));
        }
        let (mut lo, mut hi, mut count) = (f64::MAX, f64::MIN, 0u32);
        for (c, r) in spheres {
            let c = glam::DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
            let z = (c - light.center).dot(light.dir);
            lo = lo.min(z - r as f64);
            hi = hi.max(z + r as f64);
            count += 1;
        }
        if lo > hi {
            (lo, hi) = (-1.0, 1.0);
        }
        // A hair of margin so the extreme entries stay inside.
        let pad = 1e-4 * (hi - lo).max(1e-3);
        let (z_min, z_max) = ((lo - pad) as f32, (hi + pad) as f32);

        let pipe =
            |name: &str, spirv: &[u8], bindings: &[vk::DescriptorType], push: usize, local| {
                ComputePipeline::new(
                    ctx,
                    &PipelineDesc {
                        name,
                        spirv,
                        bindings,
                        push_size: push as u32,
                        local_size: local,
                        constants: &[],
                    },
                )
            };
        let s = STORAGE;
        // Guarded: an error part way destroys what was made.
        let mut bufs = ctx.guard(Vec::new());
        let mut pipes = ctx.guard(Vec::new());
        let args = ctx.guard(BandArgs::new(ctx, "osm band args")?);
        let map = Buffer::storage(ctx, "osm opacity slices", (words + GUARD_WORDS) * 4)?;
        let guard = vec![GUARD_PATTERN; GUARD_WORDS as usize];
        let up = map.upload(ctx, words * 4, bytemuck::cast_slice(&guard));
        bufs.push(map);
        up?;
        bufs.push(Buffer::storage(
            ctx,
            "osm band jobs",
            JOB_CAPACITY as u64 * 8,
        )?);
        bufs.push(Buffer::new(
            ctx,
            "osm counters",
            32,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )?);
        pipes.push(pipe(
            "osm raster",
            spirv::OSM_RASTER_COMP,
            &[UNIFORM, s, s, s, s],
            std::mem::size_of::<RasterPush>(),
            LOCAL_SIZE,
        )?);
        pipes.push(pipe(
            "osm prefix",
            spirv::OSM_PREFIX_COMP,
            &[s],
            std::mem::size_of::<PrefixPush>(),
            LOCAL_SIZE,
        )?);
        pipes.push(pipe(
            "osm shadow",
            spirv::OSM_SHADOW_COMP,
            &[UNIFORM, s, s, s, s, s],
            std::mem::size_of::<ShadowPush>(),
            LOCAL_SIZE,
        )?);
        let mut b = bufs.keep().into_iter();
        let mut nb = || b.next().expect("buffers");
        let (opacity_map, jobs, counters) = (nb(), nb(), nb());
        let mut p = pipes.keep().into_iter();
        let mut np = || p.next().expect("pipelines");
        let (raster, prefix, shadow) = (np(), np(), np());
        log::info!(
            "osm: {slices} slices of {}², depth {z_min:.2}..{z_max:.2} (slice {:.3}), texel {:.3}",
            light.width,
            (z_max - z_min) / slices as f32,
            light.view_height / light.width as f64
        );
        Ok(OpacityShadows {
            light,
            slices,
            sphere_count: count,
            z_min,
            z_max,
            opacity_map,
            jobs,
            counters,
            raster,
            args: args.keep(),
            prefix,
            shadow,
        })
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

    /// Bytes of every buffer this pass owns.
    pub fn memory_bytes(&self) -> u64 {
        self.opacity_map.size + self.jobs.size + self.counters.size
    }

    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        prof: &mut Profiler,
        f: &ShadowInputs,
    ) -> Result<()> {
        let dev = &ctx.device;
        let texels = self.texels();
        let words = texels * self.slices as u64;
        let tau = tau_fixed(f.opacity);
        let inv_dz = self.inv_dz();

        prof.begin(ctx, cmd, Self::RASTER_NAME)?;
        unsafe {
            dev.cmd_fill_buffer(cmd, self.opacity_map.raw, 0, words * 4, 0);
            dev.cmd_fill_buffer(cmd, self.counters.raw, 0, 32, 0);
        }
        barrier(dev, cmd);
        let bufs = [
            f.globals,
            f.spheres,
            &self.opacity_map,
            &self.jobs,
            &self.counters,
        ];
        let push = |bands| RasterPush {
            bands,
            sphere_count: self.sphere_count,
            big_area: BIG_AREA,
            job_capacity: JOB_CAPACITY,
            tau_fixed: tau,
            slices: self.slices,
            z_min: self.z_min,
            inv_dz,
        };
        self.args.record(
            ctx,
            cmd,
            (&self.raster, &push(0)),
            (&self.raster, &push(1)),
            &bufs,
            self.sphere_count,
            &self.counters,
            &OSM_COUNTERS,
        )?;
        prof.end(ctx, cmd)?;
        barrier(dev, cmd);

        prof.begin(ctx, cmd, Self::PREFIX_NAME)?;
        self.prefix.dispatch(
            ctx,
            cmd,
            &[&self.opacity_map],
            &PrefixPush {
                texels: texels as u32,
                slices: self.slices,
                inv_scale: 1.0 / FIXED_SCALE,
            },
            texels,
        )?;
        prof.end(ctx, cmd)?;
        barrier(dev, cmd);

        prof.begin(ctx, cmd, Self::NAME)?;
        self.shadow.dispatch(
            ctx,
            cmd,
            &[
                f.globals,
                f.spheres,
                f.vis,
                f.gpos,
                &self.opacity_map,
                f.shadow,
            ],
            &ShadowPush {
                tau_fixed: tau,
                slices: self.slices,
                z_min: self.z_min,
                inv_dz,
                inv_scale: 1.0 / FIXED_SCALE,
            },
            f.pixels,
        )?;
        prof.end(ctx, cmd)?;
        barrier(dev, cmd);
        Ok(())
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

    pub fn destroy(&mut self, ctx: &Context) {
        super::destroy_all(ctx, &[&self.raster, &self.prefix, &self.shadow]);
        self.args.destroy(ctx);
        self.opacity_map.destroy(ctx);
        self.jobs.destroy(ctx);
        self.counters.destroy(ctx);
    }
}
