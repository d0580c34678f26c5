//! Final shading: three-point lighting with key-light shadows, ambient
//! visibility and bounce, into an RGBA8 colour buffer.

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, ro, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct CompositePush {
    pub use_shadow: u32,
    pub use_ambient: u32,
    /// Fraction of the key light's diffuse term kept in full shadow.
    pub shadow_diffuse: f32,
    /// 1 = write BGRA instead of RGBA.
    pub swap_rb: u32,
}

/// Inputs of the composite pass.
pub struct CompositeInputs<'a> {
    pub globals: &'a Buffer,
    pub attrs: &'a Buffer,
    pub vis: &'a Buffer,
    pub gpos: &'a Buffer,
    pub gnorm: &'a Buffer,
    pub shadow: &'a Buffer,
    pub ambient: &'a Buffer,
    pub color: &'a Buffer,
}

pub struct CompositePass {
    pipeline: ComputePipeline,
}

impl CompositePass {
    pub const NAME: &'static str = "composite";

    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                shader: spirv::COMPOSITE_COMP,
                bindings: &[
                    uniform("GlobalsBlock"),
                    ro("Attrs"),
                    ro("Vis"),
                    ro("GPos"),
                    ro("GNorm"),
                    ro("Shadow"),
                    ro("Ambient"),
                    wo("Color"),
                ],
                push_size: std::mem::size_of::<CompositePush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        Ok(CompositePass { pipeline })
    }

    pub fn record(
        &self,
        rec: &mut Recorder,
        io: &CompositeInputs,
        push: &CompositePush,
        pixels: u64,
    ) -> Result<()> {
        rec.pass(Self::NAME, |p| {
            p.dispatch(
                &self.pipeline,
                push,
                Grid::Invocations(pixels),
                &[
                    ("GlobalsBlock", io.globals),
                    ("Attrs", io.attrs),
                    ("Vis", io.vis),
                    ("GPos", io.gpos),
                    ("GNorm", io.gnorm),
                    ("Shadow", io.shadow),
                    ("Ambient", io.ambient),
                    ("Color", io.color),
                ],
            );
            Ok(())
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
    }
}
