//! Separable bilateral blur (`blur_h`, `blur_v`) of the SSDO result, per
//! pixel (weights from the edge keys `ssdo` writes) or per 2x2 block
//! (weights from the blocks' records): one shader, the axis, the
//! resolution and the semantic region test are specialization constants.
//! See glsl/blur.comp.

use crate::error::Result;
pub use crate::gpu::blocks::BlurPush;
use crate::gpu::blocks::BlurSpec;
use crate::passes::tiles::{TILE_BINDING, Tiles};
use crate::passes::variants::{TiledDispatch, Variants};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::vk::pipeline::{Binding, PipelineDesc, texel, uniform, wo};
use crate::vk::{Buffer, Context, Recorder};
use ash::vk::Format;

/// The blur radii (taps on each side, in pixels or in blocks) the SSDO tap
/// sets use; one pipeline pair per radius and resolution, made up front so
/// zooming never compiles.
pub const BLUR_RADII: [i32; 1] = [2];

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

const BINDINGS: [Binding; 6] = [
    uniform("GlobalsBlock"),
    texel("recordTex", Format::R32G32B32A32_UINT),
    texel("inTex", Format::R32_UINT),
    wo("Out"),
    texel("keyTex", Format::R32_UINT),
    TILE_BINDING,
];

#[derive(Default)]
pub struct BlurPass {
    variants: Variants,
}

/// How one blur dispatch runs: its axis, the region test, the taps each
/// side, per block (`half`) or per pixel, on a `size` grid of them.
#[derive(Clone, Copy)]
pub struct BlurShape<'a> {
    pub axis: Axis,
    pub semantic: bool,
    pub radius: i32,
    pub half: bool,
    pub size: (u32, u32),
    pub tiles: Tiles<'a>,
}

/// What one blur dispatch reads and writes.
pub struct BlurIo<'a> {
    pub globals: &'a Buffer,
    pub records: &'a Buffer,
    /// The per-pixel edge keys (ssdo's `Keys`).
    pub keys: &'a Buffer,
    pub input: &'a Buffer,
    pub output: &'a Buffer,
}

impl BlurPass {
    pub fn new() -> Self {
        Self::default()
    }

    fn constants(axis: Axis, semantic: bool, radius: i32, half: bool) -> Vec<u32> {
        BlurSpec {
            vertical: (axis == Axis::Vertical) as u32,
            semantic,
            radius,
            half,
        }
        .constants()
    }

    /// `lists`: the pipelines for the tile lists (else for every tile).
    pub fn prepare(&mut self, ctx: &Context, semantic: bool, lists: bool) -> Result<()> {
        for radius in BLUR_RADII {
            for half in [false, true] {
                for axis in [Axis::Horizontal, Axis::Vertical] {
                    self.variants.ensure_tiled(
                        ctx,
                        &PipelineDesc {
                            name: axis.name(),
                            shader: spirv::BLUR_COMP,
                            bindings: &BINDINGS,
                            push_size: std::mem::size_of::<BlurPush>() as u32,
                            local_size: LOCAL_SIZE,
                            constants: &Self::constants(axis, semantic, radius, half),
                            scene: 0,
                        },
                        lists,
                    )?;
                }
            }
        }
        Ok(())
    }

    /// Blurs `io.input` into `io.output` along `shape.axis`, as the pass
    /// `shape.axis.name()`: per 2x2 block when `shape.half` (its `size` is
    /// then the half-resolution grid), else per pixel.
    pub fn record(
        &self,
        rec: &mut Recorder,
        shape: &BlurShape,
        io: &BlurIo,
        push: &BlurPush,
    ) -> Result<()> {
        let BlurShape {
            axis,
            semantic,
            radius,
            half,
            size,
            tiles,
        } = *shape;
        rec.pass(axis.name(), |p| {
            self.variants.dispatch_tiled(
                p,
                &TiledDispatch {
                    name: axis.name(),
                    shader: spirv::BLUR_COMP,
                    constants: &Self::constants(axis, semantic, radius, half),
                    push,
                    tiles,
                    size,
                    half,
                    bufs: &[
                        ("GlobalsBlock", io.globals),
                        ("recordTex", io.records),
                        ("inTex", io.input),
                        ("Out", io.output),
                        ("keyTex", io.keys),
                    ],
                },
            )
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.variants.destroy(ctx);
    }
}
crate::impl_destroy!(BlurPass);
