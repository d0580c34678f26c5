//! Separable bilateral blur (`blur_h`, `blur_v`): one shader, the axis is
//! specialization constant 1.

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, ro, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
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

/// What one blur dispatch reads and writes.
pub struct BlurIo<'a> {
    pub globals: &'a Buffer,
    /// [gpos, gnorm, gregion]
    pub geometry: [&'a Buffer; 3],
    /// (ambient, shadow) in
    pub input: [&'a Buffer; 2],
    /// (ambient, shadow) out
    pub output: [&'a Buffer; 2],
}

impl BlurPass {
    pub fn new(ctx: &Context) -> Result<Self> {
        let make = |axis: Axis| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name: axis.name(),
                    shader: spirv::BLUR_COMP,
                    bindings: &[
                        uniform("GlobalsBlock"),
                        ro("GPos"),
                        ro("GNorm"),
                        ro("GRegion"),
                        ro("InA"),
                        ro("InS"),
                        wo("OutA"),
                        wo("OutS"),
                    ],
                    push_size: std::mem::size_of::<BlurPush>() as u32,
                    local_size: LOCAL_SIZE,
                    constants: &[(axis == Axis::Vertical) as u32],
                },
            )
        };
        let h = ctx.guard(make(Axis::Horizontal)?);
        let v = make(Axis::Vertical)?;
        Ok(BlurPass { h: h.keep(), v })
    }

    /// Blurs (ambient, shadow) into (out ambient, out shadow) along `axis`,
    /// as the pass `axis.name()`.
    pub fn record(
        &self,
        rec: &mut Recorder,
        axis: Axis,
        io: &BlurIo,
        push: &BlurPush,
        pixels: u64,
    ) -> Result<()> {
        let pipe = if axis == Axis::Horizontal {
            &self.h
        } else {
            &self.v
        };
        rec.pass(axis.name(), |p| {
            p.dispatch(
                pipe,
                push,
                Grid::Invocations(pixels),
                &[
                    ("GlobalsBlock", io.globals),
                    ("GPos", io.geometry[0]),
                    ("GNorm", io.geometry[1]),
                    ("GRegion", io.geometry[2]),
                    ("InA", io.input[0]),
                    ("InS", io.input[1]),
                    ("OutA", io.output[0]),
                    ("OutS", io.output[1]),
                ],
            );
            Ok(())
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.h.destroy(ctx);
        self.v.destroy(ctx);
    }
}
