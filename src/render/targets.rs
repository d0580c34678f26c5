//! The screen-sized buffers of a frame, allocated for one image size and
//! reallocated (nothing else) when it changes. Full resolution: the
//! visibility buffer (8 B/px), colour (4 B/px, also the blur's scratch:
//! SSDO and blur run before shade writes colour), the SSDO result (4 B/px;
//! per pixel when spheres are small on screen, else only its first quarter
//! is used, per 2x2 block) and the per-pixel blur's edge keys (4 B/px; with
//! per-sphere SSDO, which has no blur, the taps' depth words in 2x2-block
//! order instead); the SSDO records at half resolution (16 B per 2x2 block
//! = 4 B/px): 24 B/px;
//! the shadow|ao AOVs when asked for (4 B/px more).

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
    /// bits), unorm, per pixel: the shadow and ao AOVs; one word (never
    /// written) when they are off.
    pub aov: Buffer,
    pub aovs: bool,
    /// The colour buffer holds RGBA16 (two words per pixel).
    pub wide: bool,
    /// SSDO records (half resolution) and result (full, or half).
    pub records: Buffer,
    pub ao: Buffer,
    /// Per pixel: the blur's edge keys (view distance and region); with
    /// per-sphere SSDO the depth words the taps read, four per 2x2 block
    /// (ssdo_prep.comp writes them).
    pub keys: Buffer,
    /// The coverage pass's tile lists (passes/coverage.rs).
    pub tiles: Buffer,
}

/// Half-resolution size (one block per 2x2 pixels).
pub fn half(w: u32, h: u32) -> (u32, u32) {
    let b = crate::gpu::consts::SSDO_BLOCK;
    (w.div_ceil(b), h.div_ceil(b))
}

impl Targets {
    pub fn new(ctx: &Context, width: u32, height: u32, aovs: bool, wide: bool) -> Result<Self> {
        let pixels = width as u64 * height as u64;
        let (hw, hh) = half(width, height);
        let blocks = hw as u64 * hh as u64;
        // Each buffer is guarded until all exist: one over the device's
        // limit destroys the others.
        let storage = |name: &str, size: u64| {
            Ok::<_, crate::Error>(ctx.guard(Buffer::storage(ctx, name, size)?))
        };
        let vis = ctx.guard(raster::vis_buffer(ctx, "visibility", pixels)?);
        // RGBA8, or RGBA16 in two words (--png-depth 16)
        let color = storage("colour", pixels * if wide { 8 } else { 4 })?;
        let aov = storage("shadow and ao", if aovs { pixels * 4 } else { 4 })?;
        let records = storage("ssdo records", blocks * 16)?;
        let ao = storage("ssdo ao", pixels * 4)?;
        // (block-linear depth words cover whole blocks: odd sizes need more)
        let keys = storage("ssdo blur keys", pixels.max(4 * blocks) * 4)?;
        let tiles = ctx.guard(crate::passes::coverage::lists_buffer(ctx, width, height)?);
        Ok(Targets {
            width,
            height,
            pixels,
            vis: vis.keep(),
            color: color.keep(),
            aov: aov.keep(),
            aovs,
            wide,
            records: records.keep(),
            ao: ao.keep(),
            keys: keys.keep(),
            tiles: tiles.keep(),
        })
    }

    pub fn half(&self) -> (u32, u32) {
        half(self.width, self.height)
    }

    /// Bytes by memory class: (visibility with its tile lists, gbuffer =
    /// colour + AOVs, ssdo).
    pub fn memory(&self) -> (u64, u64, u64) {
        (
            self.vis.size + self.tiles.size,
            self.color.size + self.aov.size,
            self.records.size + self.ao.size + self.keys.size,
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.vis,
            &mut self.color,
            &mut self.aov,
            &mut self.records,
            &mut self.ao,
            &mut self.keys,
            &mut self.tiles,
        ] {
            b.destroy(ctx);
        }
    }
}

crate::impl_destroy!(Targets);
