//! Visibility buffer -> G-buffer (world position + depth key, normal).

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context};
use ash::vk;

pub struct ResolvePass {
    pipeline: ComputePipeline,
}

impl ResolvePass {
    pub const NAME: &'static str = "resolve";

    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                spirv: spirv::RESOLVE_COMP,
                bindings: &[
                    UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE,
                ],
                push_size: 0,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        Ok(ResolvePass { pipeline })
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        globals: &Buffer,
        spheres: &Buffer,
        vis: &Buffer,
        gpos: &Buffer,
        gnorm: &Buffer,
        attrs: &Buffer,
        gregion: &Buffer,
        pixels: u64,
    ) -> Result<()> {
        self.pipeline.dispatch(
            ctx,
            cmd,
            &[globals, spheres, vis, gpos, gnorm, attrs, gregion],
            &(),
            pixels,
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
    }
}
