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

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub camera: Camera,
    pub light: DVec3,
    pub shadows: ShadowMode,
    pub issm: IssmParams,
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
