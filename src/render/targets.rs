//! The screen-sized buffers of a frame, allocated for one image size and
//! reallocated (nothing else) when it changes.

use crate::error::Result;
use crate::passes::raster;
use crate::vk::{Buffer, Context};

pub struct Targets {
    pub pixels: u64,
    /// depth|id per pixel (+ guard words).
    pub vis: Buffer,
    /// xyz world position, w depth key (-1 = background).
    pub gpos: Buffer,
    /// xyz normal, w 1 (0 = background).
    pub gnorm: Buffer,
    /// Region ids of the visible sphere per level.
    pub gregion: Buffer,
    /// Key-light visibility (f32).
    pub shadow: Buffer,
    /// x ambient visibility, yzw bounce.
    pub ambient: Buffer,
    /// Blur ping-pong and results: [ambient tmp, shadow tmp, ambient out, shadow out].
    pub blurred: [Buffer; 4],
    /// RGBA8 (or BGRA8) colour.
    pub color: Buffer,
}

impl Targets {
    pub fn new(ctx: &Context, width: u32, height: u32) -> Result<Self> {
        let pixels = width as u64 * height as u64;
        // Each buffer is guarded until all exist: one over the device's
        // limit destroys the others.
        let storage = |name: &str, size: u64| {
            Ok::<_, crate::Error>(ctx.guard(Buffer::storage(ctx, name, size)?))
        };
        let vis = ctx.guard(raster::vis_buffer(ctx, "visibility", pixels)?);
        let gpos = storage("gbuffer position", pixels * 16)?;
        let gnorm = storage("gbuffer normal", pixels * 16)?;
        let gregion = storage("gbuffer regions", pixels * 16)?;
        let shadow = storage("key-light visibility", pixels * 4)?;
        let ambient = storage("ambient visibility+bounce", pixels * 16)?;
        let blurred = [
            storage("ambient blur tmp", pixels * 16)?,
            storage("shadow blur tmp", pixels * 4)?,
            storage("ambient blurred", pixels * 16)?,
            storage("shadow blurred", pixels * 4)?,
        ];
        let color = storage("colour", pixels * 4)?;
        let t = Targets {
            pixels,
            vis: vis.keep(),
            gpos: gpos.keep(),
            gnorm: gnorm.keep(),
            gregion: gregion.keep(),
            shadow: shadow.keep(),
            ambient: ambient.keep(),
            blurred: blurred.map(|b| b.keep()),
            color: color.keep(),
        };
        // Without a shadow pass, key-light visibility is 1 everywhere.
        t.clear_shadow(ctx)?;
        Ok(t)
    }

    /// Key-light visibility 1 everywhere (no technique writes it).
    pub fn clear_shadow(&self, ctx: &Context) -> Result<()> {
        ctx.one_shot_passes("init shadow", |rec| {
            rec.pass("init shadow", |p| {
                p.fill(&self.shadow, self.pixels * 4, 1.0f32.to_bits());
                Ok(())
            })
        })
    }

    /// Bytes by memory class: (visibility, gbuffer).
    pub fn memory(&self) -> (u64, u64) {
        let g = [
            &self.gpos,
            &self.gnorm,
            &self.gregion,
            &self.shadow,
            &self.ambient,
            &self.color,
        ]
        .iter()
        .map(|b| b.size)
        .sum::<u64>()
            + self.blurred.iter().map(|b| b.size).sum::<u64>();
        (self.vis.size, g)
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.vis,
            &mut self.gpos,
            &mut self.gnorm,
            &mut self.gregion,
            &mut self.shadow,
            &mut self.ambient,
            &mut self.color,
        ] {
            b.destroy(ctx);
        }
        for b in &mut self.blurred {
            b.destroy(ctx);
        }
    }
}

crate::impl_destroy!(Targets);
