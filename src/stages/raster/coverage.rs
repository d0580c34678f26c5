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
    args: ComputePipeline,
}

const BINDINGS: [Binding; 3] = [
    uniform("GlobalsBlock"),
    texel("visTex", Format::R32G32_UINT),
    rw("TileLists"),
];

impl CoveragePass {
    pub const NAME: &'static str = "coverage";

    pub fn new(ctx: &Context) -> Result<Self> {
        let make = |args: u32, local_size: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name: if args == 0 {
                        "coverage"
                    } else {
                        "coverage args"
                    },
                    shader: spirv::COVERAGE_COMP,
                    bindings: &BINDINGS,
                    push_size: 0,
                    local_size,
                    constants: &[args],
                    scene: 0,
                },
            )
        };
        let regions = ctx.guard(make(0, LOCAL_SIZE)?);
        let args = make(1, 1)?;
        Ok(CoveragePass {
            regions: regions.keep(),
            args,
        })
    }

    /// The steps of the pass: lists of the w x h visibility buffer `vis`
    /// into `lists`.
    pub fn steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        vis: &'b Buffer,
        lists: &'b Buffer,
        (w, h): (u32, u32),
    ) {
        let bufs = [
            ("GlobalsBlock", globals),
            ("visTex", vis),
            ("TileLists", lists),
        ];
        p.fill(lists, 8, 0);
        p.dispatch(&self.regions, &(), Grid::Invocations(regions(w, h)), &bufs);
        p.dispatch(&self.args, &(), Grid::Groups([1, 1, 1]), &bufs);
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.regions.destroy(ctx);
        self.args.destroy(ctx);
    }
}

crate::impl_destroy!(CoveragePass);
