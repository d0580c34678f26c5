//! Implicit Sphere Shadow Maps (seed 000): the key light's view is
//! rasterized by the compute sphere rasterizer into an id map (`issm_raster`,
//! see raster.rs), then `issm_shadow` tests each visible point's light ray
//! against the spheres of a (2t+1)^2 texel patch.

use super::{LOCAL_SIZE, ShadowInputs, spirv};
use crate::error::Result;
use crate::settings::IssmParams;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context};
use ash::vk;
use bytemuck::{Pod, Zeroable};

/// Largest automatic patch half-size in texels.
pub const MAX_AUTO_T: u32 = 64;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct IssmPush {
    pub t: i32,
    /// Texel step outside the dense 3x3 core.
    pub stride: i32,
    pub soft_s: f32,
    pub soft_x: f32,
    pub soft_b: f32,
}

/// Automatic t: an occluder of P's light ray has its centre within r_max
/// (plus the soft enlargement s) of P across the light, so its own texel is
/// within ceil((r_max + s) / texel + 0.5) texels of P's; the sphere covering
/// its centre texel is stored there unless something nearer the light covers
/// it, which then shadows P as well (up to silhouettes).
pub fn auto_t(max_radius: f32, soft_s: f32, texel: f64) -> u32 {
    let reach = (max_radius + soft_s) as f64 / texel.max(1e-9) + 0.5;
    (reach.ceil() as u32).clamp(1, MAX_AUTO_T)
}

/// Patch sampling step for automatic t: the smallest sphere radius in texels
/// (at least 1), so a sphere's light-space disk always holds a sample.
pub fn auto_stride(min_radius: f32, texel: f64) -> u32 {
    ((min_radius as f64 / texel.max(1e-9)).floor() as u32).max(1)
}

pub struct IssmShadowPass {
    pipeline: ComputePipeline,
}

impl IssmShadowPass {
    pub const RASTER_NAME: &'static str = "issm_raster";
    pub const NAME: &'static str = "issm_shadow";

    pub fn new(ctx: &Context) -> Result<Self> {
        let pipeline = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                spirv: spirv::ISSM_SHADOW_COMP,
                bindings: &[UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE],
                push_size: std::mem::size_of::<IssmPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        Ok(IssmShadowPass { pipeline })
    }

    /// `stride` 1 walks every texel of the patch (the paper's method; used
    /// when the user sets t); automatic t uses `auto_stride`.
    pub fn push(params: &IssmParams, soft: bool, t: u32, stride: u32) -> IssmPush {
        IssmPush {
            t: t as i32,
            stride: stride.max(1) as i32,
            soft_s: if soft { params.soft_s } else { 0.0 },
            soft_x: params.soft_x,
            soft_b: params.soft_b,
        }
    }

    pub fn record(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        f: &ShadowInputs,
        issm: &Buffer,
        push: &IssmPush,
    ) -> Result<()> {
        self.pipeline.dispatch(
            ctx,
            cmd,
            &[f.globals, f.spheres, f.vis, f.gpos, issm, f.shadow],
            push,
            f.pixels,
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
    }
}
