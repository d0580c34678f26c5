//! `coverage`: which 16x16-pixel regions of the visibility buffer show a
//! sphere (glsl/coverage.comp), as two lists with their indirect dispatch
//! arguments. The per-pixel passes after it ([`Tiles`]) run their full
//! shader on the covered regions and a variant compiled to the background
//! path alone on the rest: on lavapipe a branch no lane takes still runs
//! its straight-line code (docs/LAVAPIPE.md), so a background pixel cost
//! the full shader before.

use super::LOCAL_SIZE;
use super::bands::counters_buffer;
use super::spirv;
use crate::error::Result;
use crate::gpu::consts::{TL_ARGS, TL_LIST, TL_REGION};
use crate::vk::pipeline::{Binding, PipelineDesc, ro, rw, texel, uniform};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder};
use ash::vk::Format;

/// Regions of a w x h buffer.
pub fn regions(w: u32, h: u32) -> u64 {
    w.div_ceil(TL_REGION) as u64 * h.div_ceil(TL_REGION) as u64
}

/// The tile-list buffer of a w x h target: counts, dispatch arguments and
/// one word per region (4 B per 256 pixels).
pub fn lists_buffer(ctx: &Context, w: u32, h: u32) -> Result<Buffer> {
    counters_buffer(ctx, "tile lists", (TL_LIST as u64 + regions(w, h)) * 4)
}

/// The binding every tiled shader declares (`TileLists`, tiles.glsl).
pub const TILE_BINDING: Binding = ro("TileLists");

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

/// Which tiles of its grid a per-pixel pass runs.
#[derive(Clone, Copy)]
pub enum Tiles<'a> {
    /// Every tile, one shader (TILE_LIST = 0).
    All,
    /// The covered regions with the full shader (TILE_LIST = 1), the
    /// background ones with its background path (TILE_LIST = 2), from
    /// these lists (this frame's `coverage`).
    Lists(&'a Buffer),
}

impl<'a> Tiles<'a> {
    /// The TILE_LIST constants whose pipelines a pass needs.
    pub fn constants(lists: bool) -> &'static [u32] {
        if lists { &[1, 2] } else { &[0] }
    }

    /// The dispatches of a pass on a w x h grid (half: the half-resolution
    /// blocks, a region is one tile of them): (TILE_LIST, grid).
    pub fn dispatches(self, (w, h): (u32, u32), half: bool) -> Vec<(u32, Grid<'a>)> {
        match self {
            Tiles::All => vec![(0, super::shade::tile_grid(w, h))],
            Tiles::Lists(b) => {
                let at = |k: u32| Grid::Indirect(b, (TL_ARGS + 3 * k) as u64 * 4);
                let first = if half { 2 } else { 0 };
                vec![(1, at(first)), (2, at(first + 1))]
            }
        }
    }

    /// The buffer bound as `TileLists` (any buffer for [`Tiles::All`]:
    /// unread).
    pub fn buffer(self, fallback: &'a Buffer) -> &'a Buffer {
        match self {
            Tiles::All => fallback,
            Tiles::Lists(b) => b,
        }
    }
}

crate::impl_destroy!(CoveragePass);
