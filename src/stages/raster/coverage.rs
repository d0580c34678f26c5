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
    /// covered too.
    see_through: ComputePipeline,
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

    pub fn new(ctx: &Context) -> Result<Self> {
        let make = |name: &str, args: u32, see: u32, local_size: u32| {
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
        };
        let regions = ctx.guard(make("coverage", 0, 0, LOCAL_SIZE)?);
        let see_through = ctx.guard(make("coverage see-through", 0, 1, LOCAL_SIZE)?);
        let args = make("coverage args", 1, 0, 1)?;
        Ok(CoveragePass {
            regions: regions.keep(),
            see_through: see_through.keep(),
            args,
        })
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
    ) {
        let bufs = [
            ("GlobalsBlock", globals),
            ("visTex", vis),
            ("TileLists", lists),
            // (bound and unread without see-through spheres)
            ("oitCountTex", counts.unwrap_or(vis)),
        ];
        p.fill(lists, 8, 0);
        let pipe = if counts.is_some() {
            &self.see_through
        } else {
            &self.regions
        };
        p.dispatch(pipe, &(), Grid::Invocations(regions(w, h)), &bufs);
        p.dispatch(&self.args, &(), Grid::Groups([1, 1, 1]), &bufs);
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.regions.destroy(ctx);
        self.see_through.destroy(ctx);
        self.args.destroy(ctx);
    }
}

crate::impl_destroy!(CoveragePass);
