//! Separable bilateral blur (`blur_h`, `blur_v`): one shader, the axis is
//! specialization constant 1.

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context};
use ash::vk;
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BlurPush {
    pub radius: i32,
    pub sigma_z: f32,
    pub semantic: u32,
    pub level: u32,
    pub blur_shadow: u32,
    pub pad: [f32; 3],
}

/// Which axis a blur dispatch runs along.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    Horizontal,
    Vertical,
}

impl Axis {
    pub fn name(self) -> &'static str {
        match self {
            Axis::Horizontal => "blur_h",
            Axis::Vertical => "blur_v",
        }
    }
}

pub struct BlurPass {
    h: ComputePipeline,
    v: ComputePipeline,
}

impl BlurPass {
    pub fn new(ctx: &Context) -> Result<Self> {
        let make = |axis: Axis| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name: axis.name(),
                    spirv: spirv::BLUR_COMP,
                    bindings: &[
                        UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE,
                    ],
                    push_size: std::mem::size_of::<BlurPush>() as u32,
                    local_size: LOCAL_SIZE,
                    constants: &[(axis == Axis::Vertical) as u32],
                },
            )
        };
        Ok(BlurPass {
            h: make(Axis::Horizontal)?,
            v: make(Axis::Vertical)?,
        })
    }

    /// Blurs (ambient, shadow) into (out_ambient, out_shadow) along `axis`;
    /// `geometry` = [gpos, gnorm, gregion].
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        axis: Axis,
        globals: &Buffer,
        geometry: [&Buffer; 3],
        input: [&Buffer; 2],
        output: [&Buffer; 2],
        push: &BlurPush,
        pixels: u64,
    ) -> Result<()> {
        let p = if axis == Axis::Horizontal {
            &self.h
        } else {
            &self.v
        };
        let bufs = [
            globals,
            geometry[0],
            geometry[1],
            geometry[2],
            input[0],
            input[1],
            output[0],
            output[1],
        ];
        p.dispatch(ctx, cmd, &bufs, push, pixels)
    }

    pub fn destroy(&mut self, ctx: &Context) {
        super::destroy_all(ctx, &[&self.h, &self.v]);
    }
}
