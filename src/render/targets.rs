//! The screen-sized buffers of a frame, each declared by the stage that
//! writes it, allocated for one image size and reallocated (nothing else)
//! when it changes: the raster stage's visibility buffer (8 B/px) and tile
//! lists, the SSDO stage's result, edge keys and records (12 B/px), the
//! shading stage's colour (4 B/px, 8 with RGBA16) and, when asked for,
//! its shadow|ao AOVs (4 B/px).

use crate::error::Result;
use crate::stages::raster::RasterTargets;
use crate::stages::shading::ShadeTargets;
use crate::stages::ssdo::SsdoTargets;
use crate::vk::Context;

pub struct Targets {
    pub width: u32,
    pub height: u32,
    pub pixels: u64,
    pub raster: RasterTargets,
    pub ssdo: SsdoTargets,
    pub shade: ShadeTargets,
}

impl Targets {
    pub fn new(ctx: &Context, width: u32, height: u32, aovs: bool, wide: bool) -> Result<Self> {
        let pixels = width as u64 * height as u64;
        // Each stage's buffers are guarded until all exist: one over the
        // device's limit destroys the others.
        let raster = ctx.guard(RasterTargets::new(ctx, width, height)?);
        let shade = ctx.guard(ShadeTargets::new(ctx, pixels, aovs, wide)?);
        let ssdo = SsdoTargets::new(ctx, width, height)?;
        Ok(Targets {
            width,
            height,
            pixels,
            raster: raster.keep(),
            ssdo,
            shade: shade.keep(),
        })
    }

    pub fn half(&self) -> (u32, u32) {
        crate::stages::ssdo::half(self.width, self.height)
    }

    /// Bytes by memory class: (visibility with its tile lists, gbuffer =
    /// colour + AOVs, ssdo).
    pub fn memory(&self) -> (u64, u64, u64) {
        (self.raster.bytes(), self.shade.bytes(), self.ssdo.bytes())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.raster.destroy(ctx);
        self.ssdo.destroy(ctx);
        self.shade.destroy(ctx);
    }
}

crate::impl_destroy!(Targets);
