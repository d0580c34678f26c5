//! Semantic SSDO with one bounce (`ssdo`) and screen-space key-light
//! shadows (`key_shadow`), seed 001. See glsl/ssdo.comp for the method.

use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, ro, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
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
    pub globals: &'a Buffer,
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
        let ssdo = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                shader: spirv::SSDO_COMP,
                bindings: &[
                    uniform("GlobalsBlock"),
                    ro("Attrs"),
                    ro("Vis"),
                    ro("GPos"),
                    ro("GNorm"),
                    ro("GRegion"),
                    ro("Shadow"),
                    wo("Ambient"),
                ],
                push_size: std::mem::size_of::<SsdoPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?);
        let key_shadow = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::KEY_SHADOW,
                shader: spirv::KEY_SHADOW_COMP,
                bindings: &[
                    uniform("GlobalsBlock"),
                    ro("Vis"),
                    ro("GPos"),
                    ro("GNorm"),
                    wo("Shadow"),
                ],
                push_size: std::mem::size_of::<KeyShadowPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        Ok(SsdoPass {
            ssdo: ssdo.keep(),
            key_shadow,
        })
    }

    /// `ssdo`: ambient visibility and bounce into `ambient`.
    pub fn record_ssdo(
        &self,
        rec: &mut Recorder,
        gb: &GBuffer,
        shadow: &Buffer,
        ambient: &Buffer,
        push: &SsdoPush,
        pixels: u64,
    ) -> Result<()> {
        rec.pass(Self::NAME, |p| {
            p.dispatch(
                &self.ssdo,
                push,
                Grid::Invocations(pixels),
                &[
                    ("GlobalsBlock", gb.globals),
                    ("Attrs", gb.attrs),
                    ("Vis", gb.vis),
                    ("GPos", gb.gpos),
                    ("GNorm", gb.gnorm),
                    ("GRegion", gb.gregion),
                    ("Shadow", shadow),
                    ("Ambient", ambient),
                ],
            );
            Ok(())
        })
    }

    /// `key_shadow`: screen-space key-light visibility into `shadow`.
    pub fn record_key_shadow(
        &self,
        rec: &mut Recorder,
        gb: &GBuffer,
        shadow: &Buffer,
        push: &KeyShadowPush,
        pixels: u64,
    ) -> Result<()> {
        rec.pass(Self::KEY_SHADOW, |p| {
            p.dispatch(
                &self.key_shadow,
                push,
                Grid::Invocations(pixels),
                &[
                    ("GlobalsBlock", gb.globals),
                    ("Vis", gb.vis),
                    ("GPos", gb.gpos),
                    ("GNorm", gb.gnorm),
                    ("Shadow", shadow),
                ],
            );
            Ok(())
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.ssdo.destroy(ctx);
        self.key_shadow.destroy(ctx);
    }
}
