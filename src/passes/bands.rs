//! Band jobs, shared by the camera raster, the deep lists and the opacity
//! maps: a per-sphere pass handles small footprints itself and queues
//! 8-row bands of big ones; one invocation turns the band count into
//! indirect dispatch arguments; the band pipeline then runs every band.

use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, STORAGE};
use crate::vk::{Buffer, ComputePipeline, Context, barrier};
use ash::vk;
use bytemuck::{Pod, Zeroable};

/// Where the sequence's words live in the pass's counter buffer.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BandCounters {
    /// Most band jobs the job buffer holds.
    pub job_capacity: u32,
    /// Word the per-sphere pass counts requested bands in.
    pub requested: u32,
    /// Word that receives the number of bands that run.
    pub run: u32,
    /// First of the three indirect dispatch words.
    pub args: u32,
}

impl BandCounters {
    /// Byte offset of the indirect dispatch arguments.
    pub fn args_offset(&self) -> u64 {
        self.args as u64 * 4
    }
}

/// The args pipeline (one per owning pass, named after it).
pub struct BandArgs {
    pipe: ComputePipeline,
}

impl BandArgs {
    pub fn new(ctx: &Context, name: &str) -> Result<Self> {
        Ok(BandArgs {
            pipe: ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    spirv: super::spirv::BAND_ARGS_COMP,
                    bindings: &[STORAGE],
                    push_size: std::mem::size_of::<BandCounters>() as u32,
                    local_size: 1,
                    constants: &[],
                },
            )?,
        })
    }

    /// Per-sphere pass, args, indirect band pass, with barriers between
    /// (none after: the caller decides what follows).
    #[allow(clippy::too_many_arguments)]
    pub fn record<P: Pod, Q: Pod>(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        (sphere_pipe, sphere_push): (&ComputePipeline, &P),
        (band_pipe, band_push): (&ComputePipeline, &Q),
        bufs: &[&Buffer],
        sphere_count: u32,
        counters: &Buffer,
        layout: &BandCounters,
    ) -> Result<()> {
        let dev = &ctx.device;
        sphere_pipe.dispatch(ctx, cmd, bufs, sphere_push, sphere_count as u64)?;
        barrier(dev, cmd);
        self.pipe
            .dispatch_groups(ctx, cmd, &[counters], layout, [1, 1, 1])?;
        barrier(dev, cmd);
        band_pipe.dispatch_indirect(ctx, cmd, bufs, band_push, counters, layout.args_offset())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipe.destroy(ctx);
    }
}
