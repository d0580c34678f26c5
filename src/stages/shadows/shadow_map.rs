//! Baseline hard shadows (after the Metal protein viewer paper): a depth shadow map of the key light,
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

use super::ShadowInputs;
use super::{Lookup, LookupKind, ShadowParams, ShadowSetup, ShadowTechnique};
use crate::camera::Camera;
use crate::error::Result;
use crate::settings::{ShadowMapParams, ShadowMode};
use crate::stages::raster::compute as raster;
use crate::vk::pipeline::{Binding, texel};
use crate::vk::{Buffer, Context, Recorder};
use bytemuck::{Pod, Zeroable};
use std::any::Any;

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
    pub push: SmPush,
}

/// The lookup's binding (glsl/lookup_sm.glsl): the depth|id map as pairs of
/// 32-bit words (id, depth bits).
const LOOKUP: [Binding; 1] = [texel("mapTex", ash::vk::Format::R32G32_UINT)];

impl ShadowMap {
    pub const RASTER_NAME: &'static str = "sm_raster";

    pub fn new(setup: &ShadowSetup) -> Result<Self> {
        let ctx = setup.ctx;
        let params = &setup.settings.shadow_maps;
        let light = setup.fit(params.sm_size)?;
        let texels = light.width as u64 * light.height as u64;
        let range = ctx.props.limits.max_storage_buffer_range as u64;
        if (texels + raster::VIS_GUARD_WORDS) * 8 > range {
            return Err(crate::Error::DeviceLimit(format!(
                "--sm-size {}: the depth map needs {} MiB, more than the device's maxStorageBufferRange ({} MiB)",
                light.width,
                (texels * 8) >> 20,
                range >> 20
            )));
        }
        let map = raster::vis_buffer(ctx, "shadow map", texels)?;
        let push = Self::push(&light, params);
        Self::log(&light, &push);
        Ok(ShadowMap { light, map, push })
    }

    fn log(light: &Camera, push: &SmPush) {
        log::info!(
            "sm-pcf: map {}², texel {:.4}, bias {:.4} + {:.4} tan, {} taps radius {}",
            light.width,
            light.view_height / light.width as f64,
            push.bias_const,
            push.bias_slope,
            push.samples,
            push.radius
        );
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

    /// Bytes of the depth map.
    pub fn memory_bytes(&self) -> u64 {
        self.map.size
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
}

impl ShadowTechnique for ShadowMap {
    fn mode(&self) -> ShadowMode {
        ShadowMode::SmPcf
    }

    fn light(&self) -> &Camera {
        &self.light
    }

    /// `sm_raster`: the light view's depth|id map.
    fn record_light<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        f.record_light_map(
            rec,
            Self::RASTER_NAME,
            &self.map,
            (self.light.width, self.light.height),
        )
    }

    fn lookup(&self, _opacity: f32) -> Lookup<'_> {
        let p = &self.push;
        Lookup {
            kind: LookupKind::ShadowMap,
            soft: false,
            bindings: &LOOKUP,
            buffers: vec![("mapTex", &self.map)],
            params: ShadowParams {
                f0: [p.bias_const, p.bias_slope, p.tan_max, p.radius],
                u: [p.samples, 0, 0, 0],
                ..Default::default()
            },
        }
    }

    fn refit(&mut self, setup: &ShadowSetup) -> Result<()> {
        self.light = setup.fit(self.light.width)?;
        self.push = Self::push(&self.light, &setup.settings.shadow_maps);
        Self::log(&self.light, &self.push);
        Ok(())
    }

    fn memory(&self) -> Vec<(&'static str, u64)> {
        vec![("shadow_map", self.map.size)]
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }

    fn destroy(&mut self, ctx: &Context) {
        self.map.destroy(ctx);
    }
}
