//! Baseline hard shadows (seed 003): a depth shadow map of the key light,
//! rendered by the compute sphere rasterizer into its own visibility buffer
//! (`sm_raster`, sphere surface depth, tight orthographic fit from
//! [`crate::camera::light_view`]), then `sm_shadow` compares each visible
//! point's light depth with the map under a slope-scaled depth bias and
//! percentage-closer filtering on a per-pixel rotated Vogel disk.
//!
//! Bias (in map texels, so it keeps its meaning across map sizes):
//! `bias = texel * (sm_bias + sm_slope_bias * reach * min(tan(theta), TAN_MAX))`
//! with theta the angle between the receiver normal and the light and
//! `reach` = half a texel diagonal (nearest-texel lookup) plus the PCF radius.
//! A plane receiver's depth changes by `reach * texel * tan(theta)` between P
//! and the farthest texel centre a tap reads, and a sphere is convex toward
//! the light (its depth only rises faster), so `sm_slope_bias = 1` is the
//! smallest slope factor free of first-order acne. The constant 0.5 texel
//! absorbs float rounding and the raster's footprint slack. Larger biases
//! detach shadows from contacts (peter-panning): bonded atoms interpenetrate,
//! so an occluder's surface can lie less than the bias in front of P.
//! tests/baselines.rs measures that trade-off against exact shadow rays.
//!
//! Receivers facing away from the light, or grazing it beyond the slope
//! clamp [`TAN_MAX`], cannot be told from their own sphere's lit cap by depth
//! alone (no finite bias helps), while the shadow AOV counts occlusion by
//! other spheres only. For those, a tap whose texel holds the receiver's own
//! sphere (the id the rasterizer stores beside the depth) counts as
//! unoccluded; everything else is the plain biased depth test.

use super::{LOCAL_SIZE, ShadowInputs, spirv};
use crate::camera::Camera;
use crate::error::Result;
use crate::settings::ShadowMapParams;
use crate::vk::pipeline::{PipelineDesc, STORAGE, UNIFORM};
use crate::vk::{Buffer, ComputePipeline, Context, Profiler, barrier};
use ash::vk;
use bytemuck::{Pod, Zeroable};

use super::raster::{self, RasterPass, ViewIndex};

/// Clamp of tan(theta) in the slope term (theta about 84 degrees): closer to
/// the terminator no finite bias avoids acne, so those grazing receivers
/// (like those facing away from the light) skip texels holding their own
/// sphere instead (see glsl/sm_shadow.comp); N . L shading is nearly zero
/// there anyway.
pub const TAN_MAX: f32 = 10.0;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SmPush {
    pub bias_const: f32,
    pub bias_slope: f32,
    pub tan_max: f32,
    pub radius: f32,
    pub samples: u32,
}

/// The key light's depth map and the lookup that reads it.
pub struct ShadowMap {
    pub light: Camera,
    map: Buffer,
    pipeline: ComputePipeline,
    pub push: SmPush,
}

impl ShadowMap {
    pub const RASTER_NAME: &'static str = "sm_raster";
    pub const NAME: &'static str = "sm_shadow";

    /// `light` must be the orthographic light view the renderer puts in
    /// `Globals.light` (size `params.sm_size`).
    pub fn new(ctx: &Context, light: Camera, params: &ShadowMapParams) -> Result<Self> {
        let texels = light.width as u64 * light.height as u64;
        let range = ctx.props.limits.max_storage_buffer_range as u64;
        if (texels + raster::VIS_GUARD_WORDS) * 8 > range {
            return Err(crate::Error::Invalid(format!(
                "--sm-size {}: the depth map needs {} MiB, more than the device's maxStorageBufferRange ({} MiB)",
                light.width,
                (texels * 8) >> 20,
                range >> 20
            )));
        }
        let pipeline = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                spirv: spirv::SM_SHADOW_COMP,
                bindings: &[UNIFORM, STORAGE, STORAGE, STORAGE, STORAGE, STORAGE],
                push_size: std::mem::size_of::<SmPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
            },
        )?;
        let map = match raster::vis_buffer(ctx, "shadow map", texels) {
            Ok(m) => m,
            Err(e) => {
                pipeline.destroy(ctx);
                return Err(e);
            }
        };
        let push = Self::push(&light, params);
        log::info!(
            "sm-pcf: map {}², texel {:.4}, bias {:.4} + {:.4} tan, {} taps radius {}",
            light.width,
            light.view_height / light.width as f64,
            push.bias_const,
            push.bias_slope,
            push.samples,
            push.radius
        );
        Ok(ShadowMap {
            light,
            map,
            pipeline,
            push,
        })
    }

    /// World-unit biases and PCF settings for a light view.
    pub fn push(light: &Camera, p: &ShadowMapParams) -> SmPush {
        let texel = (light.view_height / light.width.max(1) as f64) as f32;
        let pcf = p.pcf_samples > 1;
        let radius = if pcf { p.pcf_radius } else { 0.0 };
        let reach = std::f32::consts::FRAC_1_SQRT_2 + radius;
        SmPush {
            bias_const: p.sm_bias * texel,
            bias_slope: p.sm_slope_bias * reach * texel,
            tan_max: TAN_MAX,
            radius,
            samples: p.pcf_samples.max(1),
        }
    }

    pub fn texels(&self) -> u64 {
        self.light.width as u64 * self.light.height as u64
    }

    pub fn memory_bytes(&self) -> u64 {
        self.map.size
    }

    /// `sm_raster`: the light view's depth|id map (own timestamp scope).
    #[allow(clippy::too_many_arguments)]
    pub fn record_raster(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        prof: &mut Profiler,
        raster: &RasterPass,
        globals: &Buffer,
        spheres: &Buffer,
        sphere_count: u32,
    ) -> Result<()> {
        raster.record_scoped(
            ctx,
            cmd,
            prof,
            Self::RASTER_NAME,
            globals,
            spheres,
            sphere_count,
            &self.map,
            self.texels(),
            ViewIndex::Light,
        )
    }

    /// `sm_shadow`: key-light visibility per visible pixel into `shadow`.
    pub fn record_shadow(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        prof: &mut Profiler,
        f: &ShadowInputs,
    ) -> Result<()> {
        prof.begin(ctx, cmd, Self::NAME)?;
        self.pipeline.dispatch(
            ctx,
            cmd,
            &[f.globals, f.vis, f.gpos, f.gnorm, &self.map, f.shadow],
            &self.push,
            f.pixels,
        )?;
        prof.end(ctx, cmd)?;
        barrier(&ctx.device, cmd);
        Ok(())
    }

    /// The depth|id map (without guard words).
    pub fn read_map(&self, ctx: &Context) -> Result<Vec<u64>> {
        self.map.download_pod(ctx, 0, self.texels())
    }

    /// True when the guard words after the map are intact.
    pub fn guard_ok(&self, ctx: &Context) -> Result<bool> {
        let g: Vec<u64> = self
            .map
            .download_pod(ctx, self.texels(), raster::VIS_GUARD_WORDS)?;
        Ok(g.iter().all(|&w| w == raster::GUARD_PATTERN))
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipeline.destroy(ctx);
        self.map.destroy(ctx);
    }
}
