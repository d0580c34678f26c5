//! Visibility buffer -> G-buffer (world position + depth key, normal,
//! regions of the visible sphere).

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, ro, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};

pub struct ResolvePass {
    pipeline: ComputePipeline,
}

/// The buffers resolve reads and writes.
pub struct ResolveIo<'b> {
    pub globals: &'b Buffer,
    pub spheres: &'b Buffer,
    pub attrs: &'b Buffer,
    pub vis: &'b Buffer,
    pub gpos: &'b Buffer,
    pub gnorm: &'b Buffer,
    pub gregion: &'b Buffer,
}

impl ResolvePass {
    pub const NAME: &'static str = "resolve";

    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                shader: spirv::RESOLVE_COMP,
                bindings: &[
                    uniform("GlobalsBlock"),
                    ro("Spheres"),
                    ro("Vis"),
                    wo("GPos"),
                    wo("GNorm"),
                    ro("Attrs"),
                    wo("GRegion"),
                ],
                push_size: 0,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        Ok(ResolvePass { pipeline })
    }

    pub fn record(&self, rec: &mut Recorder, io: &ResolveIo, pixels: u64) -> Result<()> {
        rec.pass(Self::NAME, |p| {
            p.dispatch(
                &self.pipeline,
                &(),
                Grid::Invocations(pixels),
                &[
                    ("GlobalsBlock", io.globals),
                    ("Spheres", io.spheres),
                    ("Vis", io.vis),
                    ("GPos", io.gpos),
                    ("GNorm", io.gnorm),
                    ("Attrs", io.attrs),
                    ("GRegion", io.gregion),
                ],
            );
            Ok(())
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
    }
}
