//! Render settings shared by `render`, `bench` and `view`.

use crate::camera::Camera;
use glam::DVec3;
use serde::Serialize;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShadowMode {
    None,
    Issm,
    IssmSoft,
    Deep,
    /// Baseline (seed 003): depth shadow map + slope-scaled bias + Vogel PCF.
    SmPcf,
    /// Baseline (seed 004): opacity shadow maps (depth slices, prefix sum).
    Osm,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SsdoMode {
    Off,
    Plain,
    Semantic,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum RasterMode {
    Compute,
    Graphics,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Aov {
    Color,
    Id,
    Depth,
    Shadow,
    Ao,
}

macro_rules! value_name {
    ($t:ty) => {
        impl $t {
            /// The command-line spelling (also used in JSON).
            pub fn name(self) -> String {
                clap::ValueEnum::to_possible_value(&self)
                    .map(|v| v.get_name().to_string())
                    .unwrap_or_default()
            }
        }
    };
}
value_name!(ShadowMode);
value_name!(SsdoMode);
value_name!(RasterMode);
value_name!(Aov);

/// ISSM parameters (seed 000).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IssmParams {
    pub size: u32,
    /// Patch half-size t; None = automatic.
    pub t: Option<u32>,
    /// Soft-shadow radius enlargement s (world units).
    pub soft_s: f32,
    /// Falloff exponent x of (1 - s'/s)^x.
    pub soft_x: f32,
    /// Distance b over which the penumbra reaches full width.
    pub soft_b: f32,
}

impl Default for IssmParams {
    fn default() -> Self {
        IssmParams {
            size: 512,
            t: None,
            soft_s: 2.0,
            soft_x: 2.0,
            soft_b: 20.0,
        }
    }
}

/// Parameters of the two baseline techniques: the depth shadow map with PCF
/// (`--shadows sm-pcf`, seed 003) and opacity shadow maps (`--shadows osm`,
/// seed 004). Biases and PCF radii are in shadow-map texels, so they keep
/// their meaning when the map size changes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowMapParams {
    /// Depth map side in texels (`--sm-size`).
    pub sm_size: u32,
    /// Constant depth bias in texels (`--sm-bias`).
    pub sm_bias: f32,
    /// Slope factor (`--sm-slope-bias`): the bias grows by this times
    /// tan(angle between N and the light) times the lookup's reach in texels
    /// (half a texel diagonal plus the PCF radius), the depth change of a
    /// plane receiver over that reach. 1 is exactly that first-order bound.
    pub sm_slope_bias: f32,
    /// PCF taps on a Vogel disk (`--pcf-samples`); 0 or 1 = one tap, no PCF.
    pub pcf_samples: u32,
    /// PCF disk radius in texels (`--pcf-radius`).
    pub pcf_radius: f32,
    /// Opacity map side in texels (`--osm-size`).
    pub osm_size: u32,
    /// Depth slices of the opacity map (`--osm-slices`).
    pub osm_slices: u32,
}

impl Default for ShadowMapParams {
    fn default() -> Self {
        ShadowMapParams {
            sm_size: 2048,
            sm_bias: 0.5,
            sm_slope_bias: 1.0,
            pcf_samples: 16,
            pcf_radius: 1.5,
            osm_size: 512,
            osm_slices: 64,
        }
    }
}

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub camera: Camera,
    pub light: DVec3,
    pub shadows: ShadowMode,
    pub issm: IssmParams,
    /// Baseline shadow map / opacity shadow map parameters.
    pub shadow_maps: ShadowMapParams,
    pub opacity: f32,
    pub ssdo: SsdoMode,
    pub blur: bool,
    pub raster: RasterMode,
    /// Initial deep-list pool size in chunks (None = estimate from the scene).
    pub deep_pool_chunks: Option<u32>,
    /// Zoom thresholds (visible height in world units, descending) where the
    /// next finer region level takes over; None = relative to scene size.
    pub semantic_levels: Option<Vec<f64>>,
}
