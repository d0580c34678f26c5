//! `coverage`: which 16x16-pixel regions of the visibility buffer show a
//! sphere (glsl/coverage.comp), as two lists with their indirect dispatch
//! arguments. The per-pixel passes after it ([`crate::passes::tiles::Tiles`]) run their full
//! shader on the covered regions and a variant compiled to the background
//! path alone on the rest: on lavapipe a branch no lane takes still runs
//! its straight-line code (docs/LAVAPIPE.md), so a background pixel cost
//! the full shader before.

use crate::error::Result;
use crate::passes::tiles::regions;
use crate::passes::{LOCAL_SIZE, spirv};
use crate::vk::pipeline::{Binding, PipelineDesc, rw, texel, uniform};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder};
use ash::vk::Format;

pub struct CoveragePass {
    regions: ComputePipeline,
    /// The same with SEE_THROUGH: pixels with see-through fragments are
    /// covered too (made the first time a frame has see-through spheres).
    see_through: Option<ComputePipeline>,
    args: ComputePipeline,
}

const BINDINGS: [Binding; 4] = [
    uniform("GlobalsBlock"),
    texel("visTex", Format::R32G32_UINT),
    rw("TileLists"),
    texel("oitCountTex", Format::R32_UINT),
];

impl CoveragePass {
    pub const NAME: &'static str = "coverage";

    fn pipeline(
        ctx: &Context,
        name: &str,
        args: u32,
        see: u32,
        local_size: u32,
    ) -> Result<ComputePipeline> {
        ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name,
                shader: spirv::COVERAGE_COMP,
                bindings: &BINDINGS,
                push_size: 0,
                local_size,
                constants: &[args, see],
                scene: 0,
            },
        )
    }

    pub fn new(ctx: &Context) -> Result<Self> {
        let regions = ctx.guard(Self::pipeline(ctx, "coverage", 0, 0, LOCAL_SIZE)?);
        let args = Self::pipeline(ctx, "coverage args", 1, 0, 1)?;
        Ok(CoveragePass {
            regions: regions.keep(),
            see_through: None,
            args,
        })
    }

    /// Makes the SEE_THROUGH pipeline (the first frame with see-through
    /// spheres).
    pub fn enable_see_through(&mut self, ctx: &Context) -> Result<()> {
        if self.see_through.is_none() {
            let p = Self::pipeline(ctx, "coverage see-through", 0, 1, LOCAL_SIZE)?;
            self.see_through = Some(p);
        }
        Ok(())
    }

    /// The steps of the pass: lists of the w x h visibility buffer `vis`
    /// (and, with see-through spheres, the fragment counts) into `lists`.
    pub fn steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        vis: &'b Buffer,
        counts: Option<&'b Buffer>,
        lists: &'b Buffer,
        (w, h): (u32, u32),
    ) -> Result<()> {
        let bufs = [
            ("GlobalsBlock", globals),
            ("visTex", vis),
            ("TileLists", lists),
            // (bound and unread without see-through spheres)
            ("oitCountTex", counts.unwrap_or(vis)),
        ];
        p.fill(lists, 8, 0);
        let pipe = match (counts, &self.see_through) {
            (None, _) => &self.regions,
            (Some(_), Some(p)) => p,
            (Some(_), None) => {
                return Err(crate::error::Error::Internal(
                    "see-through coverage pipeline was not made".into(),
                ));
            }
        };
        p.dispatch(pipe, &(), Grid::Invocations(regions(w, h)), &bufs);
        p.dispatch(&self.args, &(), Grid::Groups([1, 1, 1]), &bufs);
        Ok(())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.regions.destroy(ctx);
        if let Some(p) = &mut self.see_through {
            p.destroy(ctx);
        }
        self.args.destroy(ctx);
    }
}

crate::impl_destroy!(CoveragePass);
