//! Separable bilateral blur (`blur_h`, `blur_v`) of the SSDO result, per
//! pixel (weights from the edge keys `ssdo` writes) or per 2x2 block
//! (weights from the blocks' records): one shader, the axis, the
//! resolution and the semantic region test are specialization constants.
//! See glsl/blur.comp.

use super::coverage::{TILE_BINDING, Tiles};
use super::shade::Variants;
use super::spirv;
use crate::error::Result;
use crate::vk::pipeline::{Binding, texel, uniform, wo};
use crate::vk::{Buffer, Context, Recorder};
use ash::vk::Format;
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct BlurPush {
    /// Depth tolerance (world units).
    pub sigma_z: f32,
    /// Half resolution: 1 = the region test compares the records' level-b
    /// regions, 0 = level a (per pixel, the keys hold the right one).
    pub level_b: u32,
    pub pad: [u32; 2],
}

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

    fn constants(axis: Axis, semantic: bool, radius: i32, half: bool) -> [u32; 4] {
        [
            (axis == Axis::Vertical) as u32,
            semantic as u32,
            radius as u32,
            half as u32,
        ]
    }

    /// `lists`: the pipelines for the tile lists (else for every tile).
    pub fn prepare(&mut self, ctx: &Context, semantic: bool, lists: bool) -> Result<()> {
        for radius in BLUR_RADII {
            for half in [false, true] {
                for axis in [Axis::Horizontal, Axis::Vertical] {
                    self.variants.ensure_tiled(
                        ctx,
                        axis.name(),
                        spirv::BLUR_COMP,
                        &BINDINGS,
                        std::mem::size_of::<BlurPush>() as u32,
                        &Self::constants(axis, semantic, radius, half),
                        lists,
                    )?;
                }
            }
        }
        Ok(())
    }

    /// Blurs `input` into `output` along `axis`, as the pass `axis.name()`:
    /// per 2x2 block when `half` (`size` is then the half-resolution grid),
    /// else per pixel.
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        rec: &mut Recorder,
        axis: Axis,
        semantic: bool,
        (radius, half): (i32, bool),
        io: &BlurIo,
        push: &BlurPush,
        size: (u32, u32),
        tiles: Tiles,
    ) -> Result<()> {
        rec.pass(axis.name(), |p| {
            self.variants.dispatch_tiled(
                p,
                axis.name(),
                spirv::BLUR_COMP,
                &Self::constants(axis, semantic, radius, half),
                push,
                tiles,
                (size, half),
                &[
                    ("GlobalsBlock", io.globals),
                    ("recordTex", io.records),
                    ("inTex", io.input),
                    ("Out", io.output),
                    ("keyTex", io.keys),
                ],
            )
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.variants.destroy(ctx);
    }
}
