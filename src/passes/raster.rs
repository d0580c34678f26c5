//! Compute rasterization of sphere impostors into a 64-bit depth|id
//! visibility buffer (camera view or key-light view, same code).

use super::bands::{BandArgs, BandCounters, BandPipelines};
use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::gpu::consts::{R_ARGS, R_BANDS_REQ, R_BANDS_RUN};
use crate::vk::pipeline::{PipelineDesc, ro, rw, texel, uniform};
use crate::vk::{Buffer, Context, PassBuilder};
use bytemuck::{Pod, Zeroable};

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
/// Counter words (src/gpu_consts.rs R_*): bands requested, bands run,
/// indirect dispatch arguments.
pub const RASTER_COUNTERS: BandCounters = BandCounters {
    job_capacity: JOB_CAPACITY,
    requested: R_BANDS_REQ,
    run: R_BANDS_RUN,
    args: R_ARGS,
};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct RasterPush {
    view_index: u32,
    big_area: u32,
    job_capacity: u32,
    sphere_count: u32,
}

/// Which view a raster pass draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewIndex {
    Camera = 0,
    Light = 1,
}

pub struct RasterPass {
    /// Orthographic and perspective views (specialization constant 2).
    pipes: [BandPipelines; 2],
    args: BandArgs,
    jobs: Buffer,
    big_area: u32,
    counters: Buffer,
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

    pub fn new(ctx: &Context) -> Result<Self> {
        let desc = PipelineDesc {
            name: "raster spheres",
            shader: spirv::RASTER_COMP,
            bindings: &[
                uniform("GlobalsBlock"),
                ro("Spheres"),
                rw("Vis"),
                rw("Jobs"),
                rw("Counters"),
                texel("visWordTex", ash::vk::Format::R32_UINT),
            ],
            push_size: std::mem::size_of::<RasterPush>() as u32,
            local_size: LOCAL_SIZE,
            constants: &[],
        };
        let ortho = ctx.guard(BandPipelines::new(ctx, &desc, &[0])?);
        let persp = ctx.guard(BandPipelines::new(ctx, &desc, &[1])?);
        let args = ctx.guard(BandArgs::new(ctx, "raster band args")?);
        let jobs = ctx.guard(Buffer::storage(
            ctx,
            "raster band jobs",
            JOB_CAPACITY as u64 * 8,
        )?);
        let counters = super::bands::counters_buffer(ctx, "raster counters", 32)?;
        Ok(RasterPass {
            pipes: [ortho.keep(), persp.keep()],
            args: args.keep(),
            jobs: jobs.keep(),
            big_area: big_area(ctx),
            counters,
        })
    }

    pub fn memory_bytes(&self) -> u64 {
        self.jobs.size + self.counters.size
    }

    /// Clears `vis` (its first `pixels` words) and rasterizes every sphere
    /// (steps of the caller's pass).
    #[allow(clippy::too_many_arguments)]
    pub fn steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        spheres: &'b Buffer,
        sphere_count: u32,
        vis: &'b Buffer,
        pixels: u64,
        view: ViewIndex,
        perspective: bool,
    ) {
        p.fill(vis, pixels * 8, u32::MAX);
        p.fill(&self.counters, 32, 0);
        let push = RasterPush {
            view_index: view as u32,
            big_area: self.big_area,
            job_capacity: JOB_CAPACITY,
            sphere_count,
        };
        self.args.steps(
            p,
            &self.pipes[perspective as usize],
            &push,
            &[
                ("GlobalsBlock", globals),
                ("Spheres", spheres),
                ("Vis", vis),
                ("Jobs", &self.jobs),
                ("Counters", &self.counters),
                ("visWordTex", vis),
            ],
            sphere_count,
            &self.counters,
            &RASTER_COUNTERS,
        );
    }

    /// The pass `name`: the key light's view rasterized into `map` (the
    /// ISSM's id map, the baseline's depth map).
    pub fn record_light_map<'b>(
        &'b self,
        rec: &mut crate::vk::Recorder,
        name: &'static str,
        f: &super::ShadowInputs<'b>,
        map: &'b Buffer,
        texels: u64,
    ) -> Result<()> {
        rec.pass(name, |p| {
            self.steps(
                p,
                f.globals,
                f.spheres,
                f.sphere_count,
                map,
                texels,
                ViewIndex::Light,
                false,
            );
            Ok(())
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for p in &mut self.pipes {
            p.destroy(ctx);
        }
        self.args.destroy(ctx);
        self.jobs.destroy(ctx);
        self.counters.destroy(ctx);
    }
}
