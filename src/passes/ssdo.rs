//! Semantic SSDO with one bounce (`ssdo`) and screen-space key-light
//! shadows (`key_shadow`), seed 001. See glsl/ssdo.comp for the method.

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context};
use ash::vk;
use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SsdoPush {
    pub r_near: f32,
    pub r_far: f32,
    pub dirs: u32,
    pub steps: u32,
    pub semantic: u32,
    pub level_a: u32,
    pub level_b: u32,
    pub blend: f32,
    pub bounce: f32,
    pub pad: [f32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct KeyShadowPush {
    pub march: f32,
    pub thickness: f32,
    pub steps: u32,
    pub pad: f32,
}

/// G-buffer inputs shared by the screen-space passes.
pub struct GBuffer<'a> {
    pub attrs: &'a Buffer,
    pub vis: &'a Buffer,
    pub gpos: &'a Buffer,
    pub gnorm: &'a Buffer,
    pub gregion: &'a Buffer,
}

pub struct SsdoPass {
    ssdo: ComputePipeline,
    key_shadow: ComputePipeline,
}

impl SsdoPass {
    pub const NAME: &'static str = "ssdo";
    pub const KEY_SHADOW: &'static str = "key_shadow";

    pub fn new(ctx: &Context) -> Result<Self> {
        let ssdo = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                spirv: spirv::SSDO_COMP,
                bindings: &[
                    UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE,
                ],
                push_size: std::mem::size_of::<SsdoPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        let key_shadow = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::KEY_SHADOW,
                spirv: spirv::KEY_SHADOW_COMP,
                bindings: &[UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE],
                push_size: std::mem::size_of::<KeyShadowPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        Ok(SsdoPass { ssdo, key_shadow })
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record_ssdo(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        globals: &Buffer,
        gb: &GBuffer,
        shadow: &Buffer,
        ambient: &Buffer,
        push: &SsdoPush,
        pixels: u64,
    ) -> Result<()> {
        let bufs = [
            globals, gb.attrs, gb.vis, gb.gpos, gb.gnorm, gb.gregion, shadow, ambient,
        ];
        self.ssdo.dispatch(ctx, cmd, &bufs, push, pixels)
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record_key_shadow(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        globals: &Buffer,
        gb: &GBuffer,
        shadow: &Buffer,
        push: &KeyShadowPush,
        pixels: u64,
    ) -> Result<()> {
        self.key_shadow.dispatch(
            ctx,
            cmd,
            &[globals, gb.vis, gb.gpos, gb.gnorm, shadow],
            push,
            pixels,
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        super::destroy_all(ctx, &[&self.ssdo, &self.key_shadow]);
    }
}
