//! Compute rasterization of sphere impostors into a 64-bit depth|id
//! visibility buffer (camera view or key-light view, same code).

use super::bands::{BandArgs, BandCounters};
use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context, Profiler, barrier};
use ash::vk;
use bytemuck::{Pod, Zeroable};
use gpu_allocator::MemoryLocation;

/// Footprints above this many pixels are split into 8-row bands run by whole
/// workgroups; below, one invocation loops over the pixels itself. Measured
/// on lavapipe (capsid at 1080p, raster pass): 100k spheres 1525 ms with 64,
/// 1249 ms with 256, 371 ms with 1024, 1M unchanged (517-549 ms): CPU
/// implementations want long per-invocation loops. On GPUs long loops
/// serialise a lane, so they get a smaller threshold (not yet measured).
pub fn big_area(ctx: &Context) -> u32 {
    if ctx.info.kind == "cpu" { 1024 } else { 256 }
}
/// Band jobs per frame before the per-sphere fallback kicks in.
pub const JOB_CAPACITY: u32 = 1 << 20;
/// u64 words after the visibility buffer that no pass may touch (GPU-AV does
/// not check atomics, so tests look at these instead).
pub const VIS_GUARD_WORDS: u64 = 64;
pub const GUARD_PATTERN: u64 = 0x5AFE_C0DE_5AFE_C0DE;
/// Counter words (glsl/raster.comp): [0] bands requested, [1] bands run,
/// [4..7] indirect dispatch arguments.
pub const RASTER_COUNTERS: BandCounters = BandCounters {
    job_capacity: JOB_CAPACITY,
    requested: 0,
    run: 1,
    args: 4,
};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct RasterPush {
    view_index: u32,
    big_area: u32,
    job_capacity: u32,
    sphere_count: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct BandsPush {
    view_index: u32,
}

/// Which view a raster pass draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewIndex {
    Camera = 0,
    Light = 1,
}

pub struct RasterPass {
    spheres: ComputePipeline,
    args: BandArgs,
    bands: ComputePipeline,
    jobs: Buffer,
    big_area: u32,
    /// [0] bands requested, [1] bands run, [4..7] indirect dispatch args.
    counters: Buffer,
}

/// A visibility buffer with its guard words.
pub fn vis_buffer(ctx: &Context, name: &str, pixels: u64) -> Result<Buffer> {
    let buf = Buffer::storage(ctx, name, (pixels + VIS_GUARD_WORDS) * 8)?;
    let guard = vec![GUARD_PATTERN; VIS_GUARD_WORDS as usize];
    buf.upload(ctx, pixels * 8, bytemuck::cast_slice(&guard))?;
    Ok(buf)
}

impl RasterPass {
    pub fn new(ctx: &Context) -> Result<Self> {
        let spheres = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "raster spheres",
                spirv: spirv::RASTER_COMP,
                bindings: &[UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE],
                push_size: std::mem::size_of::<RasterPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        let args = BandArgs::new(ctx, "raster band args")?;
        let bands = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "raster bands",
                spirv: spirv::RASTER_BANDS_COMP,
                bindings: &[UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE],
                push_size: std::mem::size_of::<BandsPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        let jobs = Buffer::storage(ctx, "raster band jobs", JOB_CAPACITY as u64 * 8)?;
        let counters = Buffer::new(
            ctx,
            "raster counters",
            32,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        Ok(RasterPass {
            spheres,
            args,
            bands,
            jobs,
            big_area: big_area(ctx),
            counters,
        })
    }

    pub fn memory_bytes(&self) -> u64 {
        self.jobs.size + self.counters.size
    }

    /// Clears `vis` (its first `pixels` words) and rasterizes every sphere.
    /// The caller opens and closes the timestamp scope.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        globals: &Buffer,
        spheres: &Buffer,
        sphere_count: u32,
        vis: &Buffer,
        pixels: u64,
        view: ViewIndex,
    ) -> Result<()> {
        let dev = &ctx.device;
        unsafe {
            dev.cmd_fill_buffer(cmd, vis.raw, 0, pixels * 8, u32::MAX);
            dev.cmd_fill_buffer(cmd, self.counters.raw, 0, 32, 0);
        }
        barrier(dev, cmd);
        let bufs = [globals, spheres, vis, &self.jobs, &self.counters];
        let push = RasterPush {
            view_index: view as u32,
            big_area: self.big_area,
            job_capacity: JOB_CAPACITY,
            sphere_count,
        };
        self.args.record(
            ctx,
            cmd,
            (&self.spheres, &push),
            (
                &self.bands,
                &BandsPush {
                    view_index: view as u32,
                },
            ),
            &bufs,
            sphere_count,
            &self.counters,
            &RASTER_COUNTERS,
        )
    }

    /// Convenience: record inside a named timestamp scope, with a trailing barrier.
    #[allow(clippy::too_many_arguments)]
    pub fn record_scoped(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        prof: &mut Profiler,
        name: &'static str,
        globals: &Buffer,
        spheres: &Buffer,
        sphere_count: u32,
        vis: &Buffer,
        pixels: u64,
        view: ViewIndex,
    ) -> Result<()> {
        prof.begin(ctx, cmd, name)?;
        self.record(ctx, cmd, globals, spheres, sphere_count, vis, pixels, view)?;
        prof.end(ctx, cmd)?;
        barrier(&ctx.device, cmd);
        Ok(())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        super::destroy_all(ctx, &[&self.spheres, &self.bands]);
        self.args.destroy(ctx);
        self.jobs.destroy(ctx);
        self.counters.destroy(ctx);
    }
}
