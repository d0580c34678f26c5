//! The screen-sized buffers of a frame, allocated for one image size and
//! reallocated (nothing else) when it changes. Full resolution: the
//! visibility buffer (8 B/px), colour (4 B/px), the SSDO result and the
//! blur's ping-pong (4 + 4 B/px), the shadow|ao AOVs (4 B/px); the SSDO
//! records at half resolution (16 B per 2x2 block = 4 B/px): 28 B/px.

use crate::error::Result;
use crate::passes::raster;
use crate::vk::{Buffer, Context};

pub struct Targets {
    pub width: u32,
    pub height: u32,
    pub pixels: u64,
    /// depth|id per pixel (+ guard words).
    pub vis: Buffer,
    /// RGBA8 (or BGRA8) colour.
    pub color: Buffer,
    /// Key-light visibility (low 16 bits) and ambient visibility (high 16
    /// bits), unorm, per pixel: the shadow and ao AOVs.
    pub aov: Buffer,
    /// SSDO records (half resolution), result and blur ping-pong (full).
    pub records: Buffer,
    pub ao: Buffer,
    pub ao_tmp: Buffer,
}

/// Half-resolution size (one block per 2x2 pixels).
pub fn half(w: u32, h: u32) -> (u32, u32) {
    let b = crate::gpu::consts::SSDO_BLOCK;
    (w.div_ceil(b), h.div_ceil(b))
}

impl Targets {
    pub fn new(ctx: &Context, width: u32, height: u32) -> Result<Self> {
        let pixels = width as u64 * height as u64;
        let (hw, hh) = half(width, height);
        let blocks = hw as u64 * hh as u64;
        // Each buffer is guarded until all exist: one over the device's
        // limit destroys the others.
        let storage = |name: &str, size: u64| {
            Ok::<_, crate::Error>(ctx.guard(Buffer::storage(ctx, name, size)?))
        };
        let vis = ctx.guard(raster::vis_buffer(ctx, "visibility", pixels)?);
        let color = storage("colour", pixels * 4)?;
        let aov = storage("shadow and ao", pixels * 4)?;
        let records = storage("ssdo records", blocks * 16)?;
        let ao = storage("ssdo ao", pixels * 4)?;
        let ao_tmp = storage("ssdo ao blur", pixels * 4)?;
        Ok(Targets {
            width,
            height,
            pixels,
            vis: vis.keep(),
            color: color.keep(),
            aov: aov.keep(),
            records: records.keep(),
            ao: ao.keep(),
            ao_tmp: ao_tmp.keep(),
        })
    }

    pub fn half(&self) -> (u32, u32) {
        half(self.width, self.height)
    }

    /// Bytes by memory class: (visibility, gbuffer = colour + AOVs, ssdo).
    pub fn memory(&self) -> (u64, u64, u64) {
        (
            self.vis.size,
            self.color.size + self.aov.size,
            self.records.size + self.ao.size + self.ao_tmp.size,
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.vis,
            &mut self.color,
            &mut self.aov,
            &mut self.records,
            &mut self.ao,
            &mut self.ao_tmp,
        ] {
            b.destroy(ctx);
        }
    }
}

crate::impl_destroy!(Targets);
