//! Render settings shared by `render`, `bench`, `view` and the library:
//! [`Options`] and [`Axes`] are what a user sets (their `Default` impls are
//! the one source of every default: clap, bench, the viewer and the tests
//! read them), [`RenderSettings`] is what the renderer runs with, resolved
//! against a scene (camera fit) and validated by [`Options::resolve`].

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::gpu::default_from_args;
use crate::scene::Scene;
use glam::DVec3;
use serde::Serialize;
use std::fmt;
use std::str::FromStr;

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShadowMode {
    None,
    Issm,
    IssmSoft,
    Deep,
    /// Baseline (after the Metal protein viewer paper): depth shadow map + slope-scaled bias + Vogel PCF.
    SmPcf,
    /// Baseline (after the WebGL particle paper): opacity shadow maps (depth slices, prefix sum).
    Osm,
    /// Unit tests only: a trivial technique (constant half shadow) showing
    /// what adding one takes.
    #[cfg(test)]
    TestConstant,
}

impl ShadowMode {
    /// Whether the technique rasterizes the key light's view with the
    /// sphere rasterizer (ISSM's id map, the baseline's depth map).
    pub fn draws_light_view(self) -> bool {
        matches!(
            self,
            ShadowMode::Issm | ShadowMode::IssmSoft | ShadowMode::SmPcf
        )
    }

    /// Whether the technique visits the spheres in the key light's sphere
    /// order: the rasterized light views, and the deep lists' splat.
    pub fn orders_light_view(self) -> bool {
        self.draws_light_view() || self == ShadowMode::Deep
    }
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
        impl fmt::Display for $t {
            fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(&self.name())
            }
        }
    };
}
value_name!(ShadowMode);
value_name!(SsdoMode);
value_name!(RasterMode);
value_name!(Aov);

/// Implicit Sphere Shadow Map parameters: the ISSM stage's knobs, flattened
/// into the command line (and bench, Python) as `--issm-size`, `--issm-t`,
/// `--soft-s`, `--soft-x`, `--soft-b`; defaults in `Default`, ranges in
/// [`IssmParams::validate`].
#[derive(Clone, Copy, Debug, PartialEq, clap::Args)]
pub struct IssmParams {
    /// ISSM (and deep-list) light map side in texels.
    #[arg(
        id = "issm_size",
        long = "issm-size",
        value_name = "ISSM_SIZE",
        default_value_t = 512
    )]
    pub size: u32,
    /// ISSM patch half-size t (0..32), or `auto`: 1 is the paper's 3x3
    /// patch; 0 reads only the 2x2 texels around the point (faster, slightly
    /// less exact where a light texel is nearly a sphere radius).
    // (The default, 1: on the 1M capsid (tests/agreement_1m.rs) the hard
    // mask agrees with exact shadow rays on 98.84 % of pixels with t = 1
    // and 98.96 % with the automatic t (4 there), at a third of the
    // lookup's cost.)
    #[arg(id = "issm_t", long = "issm-t", value_name = "ISSM_T", default_value_t = IssmT(Some(1)))]
    pub t: IssmT,
    /// Soft shadows: radius enlargement s in world units.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub soft_s: f32,
    /// Soft shadows: falloff exponent x of (1 - s'/s)^x.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub soft_x: f32,
    /// Soft shadows: distance b over which the penumbra reaches full width.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    pub soft_b: f32,
}

impl IssmParams {
    pub fn validate(&self) -> Result<()> {
        if !(16..=8192).contains(&self.size) {
            return Err(Error::Input(
                "--issm-size must be between 16 and 8192".into(),
            ));
        }
        for (x, name) in [
            (self.soft_s, "--soft-s"),
            (self.soft_x, "--soft-x"),
            (self.soft_b, "--soft-b"),
        ] {
            if !(x > 0.0 && x.is_finite()) {
                return Err(Error::Input(format!("{name} must be positive")));
            }
        }
        Ok(())
    }
}

default_from_args!(IssmParams);

/// Parameters of the two baseline techniques: the depth shadow map with PCF
/// (`--shadows sm-pcf`, after the Metal protein viewer paper) and opacity
/// shadow maps (`--shadows osm`, after the WebGL particle paper), flattened
/// into the command line as `--sm-size` ... `--osm-slices`. Biases and PCF
/// radii are in shadow-map texels, so they keep their meaning when the map
/// size changes.
#[derive(Clone, Copy, Debug, PartialEq, clap::Args)]
pub struct ShadowMapParams {
    /// Depth shadow map side in texels (`--shadows sm-pcf`).
    #[arg(long, default_value_t = 2048)]
    pub sm_size: u32,
    /// Constant depth bias of the shadow map, in map texels.
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub sm_bias: f32,
    /// Slope-scaled bias factor: times tan(N, light) times the lookup reach
    /// (half a texel diagonal + PCF radius), in texels: the depth change of
    /// a plane receiver over that reach, so 1 is exactly that first-order
    /// bound.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub sm_slope_bias: f32,
    /// PCF taps on a Vogel disk rotated per pixel (0 or 1 = single tap).
    #[arg(long, default_value_t = 16)]
    pub pcf_samples: u32,
    /// PCF disk radius in shadow-map texels.
    #[arg(long, default_value_t = 1.5, allow_negative_numbers = true)]
    pub pcf_radius: f32,
    /// Opacity shadow map side in texels (`--shadows osm`).
    #[arg(long, default_value_t = 512)]
    pub osm_size: u32,
    /// Depth slices of the opacity shadow map.
    #[arg(long, default_value_t = 64)]
    pub osm_slices: u32,
}

impl ShadowMapParams {
    pub fn validate(&self) -> Result<()> {
        let input = |m: String| Err(Error::Input(m));
        if !(16..=8192).contains(&self.sm_size) {
            return input("--sm-size must be between 16 and 8192".into());
        }
        for (x, name) in [
            (self.sm_bias, "--sm-bias"),
            (self.sm_slope_bias, "--sm-slope-bias"),
            (self.pcf_radius, "--pcf-radius"),
        ] {
            if !(0.0..=1e4).contains(&x) {
                return input(format!("{name} must be between 0 and 10000 (texels)"));
            }
        }
        if self.pcf_samples > 256 {
            return input("--pcf-samples must be between 0 and 256".into());
        }
        if !(16..=4096).contains(&self.osm_size) {
            return input("--osm-size must be between 16 and 4096".into());
        }
        if !(1..=1024).contains(&self.osm_slices) {
            return input("--osm-slices must be between 1 and 1024".into());
        }
        Ok(())
    }
}

default_from_args!(ShadowMapParams);

#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub camera: Camera,
    pub light: DVec3,
    pub shadows: ShadowMode,
    pub issm: IssmParams,
    /// Baseline shadow map / opacity shadow map parameters.
    pub shadow_maps: ShadowMapParams,
    pub opacity: f32,
    pub ssdo: SsdoMode,
    /// The SSDO stage's knobs (blur, semantic levels).
    pub ssdo_knobs: SsdoKnobs,
    pub raster: RasterMode,
    /// The deep lists' knobs.
    pub deep: DeepParams,
    /// Levels of detail and culling of instanced scenes.
    pub lod: LodParams,
    /// Keep the shadow and ao AOVs (4 B/px more) for `read_shadow` and
    /// `read_ambient`; off, frames write colour only.
    pub aovs: bool,
    /// The part of the camera's image the frame's buffers hold (a tile and
    /// its margin); None = all of it. Pixels are the untiled image's bits.
    pub window: Option<crate::camera::Window>,
    pub look: Look,
    /// Supersampling asked for (`--ssaa`): `run::render_run` renders the
    /// colour AOV n x n times with the camera moved to each sub-pixel
    /// sample position (`shifted`) and averages them.
    pub ssaa: u32,
    /// Tile side asked for (`--tile-size`); None = tiles only when needed.
    pub tile_size: Option<u32>,
    /// The per-pixel passes run on the `coverage` pass's tile lists (the
    /// default; off runs every tile, for comparisons and tests: the images
    /// are the same bytes).
    pub tile_lists: bool,
    /// Draws every sphere opaque in the camera view while the shadows keep
    /// each sphere's alpha (off by default: alpha below 1 is see-through).
    /// For tests and comparisons of translucent shadows alone: their
    /// receivers must be visible surfaces.
    pub opaque_view: bool,
    /// The rasterizers' band job list's first length (None: 2^20,
    /// src/stages/raster/compute.rs JOB_CAPACITY); a frame that asks more
    /// is drawn again with a longer one (tests force that with less).
    pub band_jobs: Option<u32>,
}

impl RenderSettings {
    /// Refuses see-through spheres (`per_sphere_alpha`, or `--opacity`
    /// below 1) where they cannot be drawn: the graphics raster draws
    /// opaque spheres only.
    pub fn check_see_through(&self, per_sphere_alpha: bool) -> crate::error::Result<()> {
        if self.raster == RasterMode::Graphics
            && !self.opaque_view
            && (per_sphere_alpha || self.opacity < 1.0)
        {
            return Err(crate::error::Error::Input(
                "--raster graphics draws opaque spheres only: see-through spheres (--alpha, \
                 --opacity below 1) need --raster compute"
                    .into(),
            ));
        }
        Ok(())
    }

    /// A one-line note when the key-light technique does not give
    /// see-through spheres (`per_sphere_alpha`: a colour's alpha below 1)
    /// the translucent shadow `--alpha` asks for; only deep lists do.
    pub fn see_through_note(&self, per_sphere_alpha: bool) -> Option<String> {
        let name = clap::ValueEnum::to_possible_value(&self.shadows)?
            .get_name()
            .to_string();
        match self.shadows {
            ShadowMode::Issm | ShadowMode::IssmSoft | ShadowMode::SmPcf
                if per_sphere_alpha || self.opacity < 1.0 =>
            {
                Some(format!(
                    "--shadows {name} casts opaque shadows from see-through spheres \
                     (translucent shadows: --shadows deep)"
                ))
            }
            ShadowMode::Osm if per_sphere_alpha => Some(
                "--shadows osm gives every sphere the --opacity shadow, not its --alpha \
                 (per-sphere shadows: --shadows deep)"
                    .into(),
            ),
            _ => None,
        }
    }

    /// The camera moved by (dx, dy) pixels in the image plane (x right, y
    /// down): the sub-pixel sample positions of `--ssaa`.
    pub fn shifted(&self, dx: f64, dy: f64) -> RenderSettings {
        let mut s = self.clone();
        let c = &mut s.camera;
        let ppu = c.pixels_per_unit();
        c.center += c.right * (dx / ppu) - c.up * (dy / ppu);
        s
    }

    /// Sub-pixel samples per axis for `aov`: `ssaa` for the colour, 1 for
    /// the others (they keep one sample per pixel centre, DESIGN.md).
    pub fn ssaa_for(&self, aov: Aov) -> u32 {
        if aov == Aov::Color {
            self.ssaa.max(1)
        } else {
            1
        }
    }

    /// The pixels a frame's buffers hold.
    pub fn window(&self) -> crate::camera::Window {
        self.window
            .unwrap_or(crate::camera::Window::whole(&self.camera))
    }

    /// Whether SSDO runs.
    pub fn ssdo_on(&self) -> bool {
        self.ssdo != SsdoMode::Off
    }
}

/// A 3-vector option (`X,Y,Z`); Display writes what FromStr reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct V3(pub DVec3);

impl FromStr for V3 {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() != 3 {
            return Err(format!("'{s}': expected X,Y,Z"));
        }
        let mut v = [0.0; 3];
        for (o, p) in v.iter_mut().zip(&parts) {
            *o = p
                .trim()
                .parse::<f64>()
                .map_err(|_| format!("'{s}': '{p}' is not a number"))?;
            if !o.is_finite() {
                return Err(format!("'{s}': components must be finite"));
            }
        }
        Ok(V3(DVec3::from_array(v)))
    }
}

impl fmt::Display for V3 {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{},{},{}", self.0.x, self.0.y, self.0.z)
    }
}

/// `--issm-t T|auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct IssmT(pub Option<u32>);

impl FromStr for IssmT {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "auto" {
            return Ok(IssmT(None));
        }
        s.parse::<u32>()
            .ok()
            .filter(|t| *t <= 32)
            .map(|t| IssmT(Some(t)))
            .ok_or_else(|| format!("'{s}': expected 0..32 or `auto`"))
    }
}

impl fmt::Display for IssmT {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self.0 {
            None => f.write_str("auto"),
            Some(t) => write!(f, "{t}"),
        }
    }
}

/// `on|off` switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OnOff {
    On,
    Off,
}
value_name!(OnOff);

impl OnOff {
    pub fn on(self) -> bool {
        self == OnOff::On
    }
}

/// `--background gradient|R,G,B|transparent` (R,G,B: 0..255 each, or
/// `white`, `black`, `#RRGGBB`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// The default: a dark vertical gradient.
    Gradient,
    /// One colour (sRGB bytes).
    Color([u8; 3]),
    /// Alpha 0 on background pixels (RGBA PNG).
    Transparent,
}

impl FromStr for Background {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let bad = || {
            format!(
                "'{s}': expected gradient, transparent, R,G,B (0..255), #RRGGBB, white or black"
            )
        };
        match s.trim() {
            "gradient" => return Ok(Background::Gradient),
            "transparent" => return Ok(Background::Transparent),
            "white" => return Ok(Background::Color([255; 3])),
            "black" => return Ok(Background::Color([0; 3])),
            _ => {}
        }
        if let Some(hex) = s.trim().strip_prefix('#') {
            if hex.len() != 6 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
                return Err(bad());
            }
            let v = u32::from_str_radix(hex, 16).map_err(|_| bad())?;
            return Ok(Background::Color([
                (v >> 16) as u8,
                (v >> 8) as u8,
                v as u8,
            ]));
        }
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() != 3 {
            return Err(bad());
        }
        let mut c = [0u8; 3];
        for (o, p) in c.iter_mut().zip(&parts) {
            *o = p.trim().parse::<u8>().map_err(|_| bad())?;
        }
        Ok(Background::Color(c))
    }
}

impl fmt::Display for Background {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            Background::Gradient => f.write_str("gradient"),
            Background::Transparent => f.write_str("transparent"),
            Background::Color([r, g, b]) => write!(f, "{r},{g},{b}"),
        }
    }
}

/// `--fog NEAR,FAR`: view distances (world units, as `view_z`: along the
/// view direction from the eye, or for orthographic views from the plane
/// through the view centre, negative toward the viewer), NEAR < FAR.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fog(pub [f64; 2]);

impl FromStr for Fog {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let parts: Vec<&str> = s.split(',').collect();
        let bad = || format!("'{s}': expected NEAR,FAR (view distances, NEAR < FAR)");
        if parts.len() != 2 {
            return Err(bad());
        }
        let n: f64 = parts[0].trim().parse().map_err(|_| bad())?;
        let f: f64 = parts[1].trim().parse().map_err(|_| bad())?;
        if !(n.is_finite() && f.is_finite() && n < f && n.abs() <= 1e15 && f.abs() <= 1e15) {
            return Err(bad());
        }
        Ok(Fog([n, f]))
    }
}

/// How the image looks beyond the lighting: background, lines, depth cue
/// and colour precision (DESIGN.md "Images for publication").
#[derive(Clone, Copy, Debug, PartialEq, clap::Args)]
pub struct Look {
    /// Background: gradient, R,G,B (0..255), #RRGGBB, white, black, or
    /// transparent (RGBA with alpha 0 there).
    #[arg(long, default_value_t = Background::Gradient)]
    pub background: Background,
    /// Silhouette lines this many pixels wide where depth or region changes.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub outline: f32,
    /// Depth cue toward the background between view distances NEAR,FAR.
    #[arg(long, allow_hyphen_values = true)]
    pub fog: Option<Fog>,
    /// The knobs `shade` reads as they are (src/gpu_blocks.rs).
    #[command(flatten)]
    pub knobs: crate::gpu::blocks::ShadeKnobs,
    /// Colour written as RGBA16 (`--png-depth 16`, an output option).
    #[arg(skip)]
    pub color16: bool,
}

impl Look {
    pub fn validate(&self) -> Result<()> {
        if !(self.outline >= 0.0 && self.outline <= 64.0) {
            return Err(Error::Input(
                "--outline must be between 0 and 64 pixels".into(),
            ));
        }
        Ok(())
    }
}

default_from_args!(Look);

/// The SSDO stage's knobs, flattened into the command line (the mode itself
/// is `--ssdo`, a bench axis).
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct SsdoKnobs {
    /// Bilateral blur of ambient occlusion.
    #[arg(
        long,
        default_value = "on",
        value_name = "BLUR",
        action = clap::ArgAction::Set,
        value_parser = clap::builder::TypedValueParser::map(
            clap::builder::PossibleValuesParser::new(["on", "off"]),
            |s: String| s == "on"
        )
    )]
    pub blur: bool,
    /// Zoom thresholds for semantic SSDO levels: comma list of visible
    /// heights (world units, descending) where the next finer level takes over
    /// (default: relative to the scene size).
    #[arg(long)]
    pub semantic_levels: Option<Levels>,
}

default_from_args!(SsdoKnobs);

/// The deep lists' knobs.
#[derive(Clone, Copy, Debug, PartialEq, clap::Args)]
pub struct DeepParams {
    /// Initial deep-list pool size in chunks of 64 entries (grown on overflow;
    /// default: estimated from the scene).
    #[arg(
        id = "deep_pool_chunks",
        long = "deep-pool-chunks",
        value_name = "DEEP_POOL_CHUNKS"
    )]
    pub pool_chunks: Option<u32>,
    /// Initial see-through fragment pool in fragments (grown on overflow;
    /// default: 2 per pixel).
    #[arg(long, value_name = "FRAGMENTS")]
    pub see_through_fragments: Option<u32>,
}

default_from_args!(DeepParams);

/// Levels of detail (instanced scenes): `auto` or every atom.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LodMode {
    Auto,
    Off,
}

/// The LOD stage's knobs (src/stages/lod.rs): how much detail an instance
/// of an instanced scene draws for its size on screen, and which are
/// culled.
#[derive(Clone, Copy, Debug, PartialEq, clap::Args)]
pub struct LodParams {
    /// Level of detail per instance of an instanced scene, chosen from its
    /// size on screen, with the instances outside the view culled
    /// (`auto`); `off` draws every atom of every instance.
    #[arg(long, value_enum, default_value_t = LodMode::Auto)]
    pub lod: LodMode,
    /// Largest radius in pixels a coarse level's spheres are drawn at (a
    /// level is also kept only where its outline matches the molecule's);
    /// 0: full detail everywhere, culling only.
    #[arg(long, default_value_t = 2.0, allow_negative_numbers = true)]
    pub lod_pixels: f32,
    /// Initial length of each view's LOD list in batches (grown when a
    /// frame lists more, and the frame drawn again; default: an eighth of
    /// the scene's full-detail batches, at least 65,536).
    #[arg(long, value_name = "BATCHES")]
    pub lod_list_batches: Option<u32>,
    /// Batches the cull's early phases may defer to the late ones (default:
    /// a quarter of a list's; tests force the overflow path with less).
    #[arg(skip)]
    pub lod_deferred_batches: Option<u32>,
    /// Draw the key light's LOD lists per slot, as the camera's, instead
    /// of per batch (glsl/raster.comp LIGHT_BATCHES; tests compare the
    /// two).
    #[arg(skip)]
    pub lod_light_per_slot: bool,
    /// Draw the camera's LOD lists per slot, untested, instead of per
    /// batch with each atom tested against depth tiles (glsl/raster.comp
    /// CAM_BATCHES; tests compare the two).
    #[arg(skip)]
    pub lod_camera_per_slot: bool,
    /// Leave the camera's history as it is where its early phase has no
    /// tiles to test against (the first frame, a large move) instead of
    /// seeding it with the front instances (glsl/lod_front.comp): such a
    /// first frame draws every instance in the window, the reference the
    /// tests cull against.
    #[arg(skip)]
    pub lod_no_front: bool,
}

default_from_args!(LodParams);

impl LodParams {
    /// `--lod-pixels` with `--lod auto`; None with `--lod off`.
    pub fn pixels(&self) -> Option<f32> {
        (self.lod == LodMode::Auto).then_some(self.lod_pixels)
    }

    pub fn validate(&self) -> Result<()> {
        if !(0.0..=1000.0).contains(&self.lod_pixels) {
            return Err(Error::Input(
                "--lod-pixels must be between 0 and 1000".into(),
            ));
        }
        if self.lod_list_batches == Some(0) || self.lod_deferred_batches == Some(0) {
            return Err(Error::Input("--lod-list-batches must be at least 1".into()));
        }
        Ok(())
    }
}

/// `--semantic-levels T0,T1,...`: positive, descending.
#[derive(Clone, Debug, PartialEq)]
pub struct Levels(pub Vec<f64>);

impl FromStr for Levels {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let t: Vec<f64> = s
            .split(',')
            .map(|p| {
                p.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| *x > 0.0 && x.is_finite())
            })
            .collect::<Option<_>>()
            .ok_or_else(|| format!("'{s}': expected positive numbers"))?;
        if t.windows(2).any(|w| w[1] >= w[0]) {
            return Err(format!("'{s}': thresholds must descend"));
        }
        Ok(Levels(t))
    }
}

/// The axes a benchmark crosses (`bench` takes lists of them); single
/// values for `render` and `view`.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Axes {
    /// Image width in pixels.
    #[arg(long, default_value_t = Axes::default().width)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = Axes::default().height)]
    pub height: u32,
    /// Key-light shadow technique.
    #[arg(long, value_enum, default_value_t = Axes::default().shadows)]
    pub shadows: ShadowMode,
    /// Ambient occlusion + bounce.
    #[arg(long, value_enum, default_value_t = Axes::default().ssdo)]
    pub ssdo: SsdoMode,
    /// Compute rasterizer or the vertex/fragment impostor baseline.
    #[arg(long, value_enum, default_value_t = Axes::default().raster)]
    pub raster: RasterMode,
    /// Opacity of every sphere (0..1): translucent shadows (deep, osm).
    #[arg(long, default_value_t = Axes::default().opacity, allow_negative_numbers = true)]
    pub opacity: f32,
}

impl Default for Axes {
    fn default() -> Self {
        Axes {
            width: 1920,
            height: 1080,
            shadows: ShadowMode::IssmSoft,
            ssdo: SsdoMode::Semantic,
            raster: RasterMode::Compute,
            opacity: 1.0,
        }
    }
}

/// Every other render option of DESIGN.md: camera, light and technique
/// parameters, and the device. Shared by render, bench and view.
#[derive(Clone, Debug, PartialEq, clap::Args)]
pub struct Options {
    /// Key-light direction, from the light toward the scene.
    #[arg(long, default_value_t = Options::default().light, allow_hyphen_values = true)]
    pub light: V3,
    /// Camera view direction.
    #[arg(long, default_value_t = Options::default().view_dir, allow_hyphen_values = true)]
    pub view_dir: V3,
    /// Camera up hint.
    #[arg(long, default_value_t = Options::default().up, allow_hyphen_values = true)]
    pub up: V3,
    /// View centre (default: centre of the bounding box of the sphere centres).
    #[arg(long, allow_hyphen_values = true)]
    pub view_center: Option<V3>,
    /// Orthographic view height in world units (default: the bounding-sphere
    /// diameter times 1.05).
    #[arg(long, allow_negative_numbers = true)]
    pub view_height: Option<f64>,
    /// Perspective vertical field of view in degrees (default: orthographic).
    #[arg(long, allow_negative_numbers = true)]
    pub fov: Option<f64>,
    #[command(flatten)]
    pub issm: IssmParams,
    #[command(flatten)]
    pub shadow_maps: ShadowMapParams,
    #[command(flatten)]
    pub ssdo_knobs: SsdoKnobs,
    #[command(flatten)]
    pub deep: DeepParams,
    #[command(flatten)]
    pub lod: LodParams,
    /// Enable validation (GPU-assisted + synchronization); exit 3 on any message.
    #[arg(long)]
    pub validate: bool,
    /// Physical device index (see `sphereshade info`).
    #[arg(long)]
    pub device: Option<usize>,
    /// Supersampling: N x N samples per pixel (1-4), averaged in linear
    /// colour (the colour AOV only).
    #[arg(long, default_value_t = Options::default().ssaa)]
    pub ssaa: u32,
    #[command(flatten)]
    pub look: Look,
    /// Render in tiles of this many pixels per side (multiple of 8), as an
    /// image too large for one device allocation is (tests, memory limits).
    #[arg(long)]
    pub tile_size: Option<u32>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            light: V3(DVec3::new(-1.0, -1.0, -1.0)),
            view_dir: V3(DVec3::new(0.0, 0.0, -1.0)),
            up: V3(DVec3::Y),
            view_center: None,
            view_height: None,
            fov: None,
            issm: IssmParams::default(),
            shadow_maps: ShadowMapParams::default(),
            ssdo_knobs: SsdoKnobs::default(),
            deep: DeepParams::default(),
            lod: LodParams::default(),
            validate: false,
            device: None,
            ssaa: 1,
            look: Look::default(),
            tile_size: None,
        }
    }
}

impl Options {
    /// Validates the options and resolves them against a scene: the camera
    /// defaults are fitted to its spheres.
    pub fn resolve(&self, axes: &Axes, scene: &Scene) -> Result<RenderSettings> {
        let input = |m: String| Err(Error::Input(m));
        // (one pass over the spheres serves the camera and its check)
        let bounds = scene.bounding_sphere();
        let camera = crate::camera::fitted_camera(
            bounds,
            axes.width,
            axes.height,
            &crate::camera::CameraFit {
                view_dir: self.view_dir.0,
                up: self.up.0,
                center: self.view_center.map(|v| v.0),
                view_height: self.view_height,
                fov: self.fov,
            },
        )?;
        resolvable(&camera, bounds)?;
        if !(0.0..=1.0).contains(&axes.opacity) {
            return input("--opacity must be between 0 and 1".into());
        }
        if crate::camera::unit(self.light.0).is_none() {
            return input("--light must be a finite non-zero direction".into());
        }
        self.issm.validate()?;
        self.shadow_maps.validate()?;
        self.lod.validate()?;
        if !(1..=4).contains(&self.ssaa) {
            return input("--ssaa must be between 1 and 4".into());
        }
        self.look.validate()?;
        if let Some(t) = self.tile_size
            && !(8..=16384).contains(&t)
        {
            return input("--tile-size must be between 8 and 16384".into());
        }
        Ok(RenderSettings {
            camera,
            light: self.light.0,
            shadows: axes.shadows,
            issm: self.issm,
            shadow_maps: self.shadow_maps,
            opacity: axes.opacity,
            ssdo: axes.ssdo,
            ssdo_knobs: self.ssdo_knobs.clone(),
            raster: axes.raster,
            deep: self.deep,
            lod: self.lod,
            aovs: false,
            window: None,
            ssaa: self.ssaa,
            tile_size: self.tile_size,
            tile_lists: true,
            opaque_view: false,
            look: self.look,
            band_jobs: None,
        })
    }
}

/// Refuses a camera whose pixels (or, in perspective, whose eye distance)
/// the GPU's f32 rays cannot resolve against the scene's coordinates: it
/// would render a uniform image and exit 0.
fn resolvable(cam: &crate::camera::Camera, (c, r): (glam::Vec3, f32)) -> Result<()> {
    let scale = (c.as_dvec3().abs().max_element() + r as f64).max(f64::MIN_POSITIVE);
    let px = cam.view_height / cam.height as f64;
    if !(px >= f32::EPSILON as f64 * scale) {
        return Err(Error::Input(format!(
            "--view-height {:e}: a pixel ({px:.2e} world units) is below the f32 precision of the \
             scene's coordinates (up to {scale:.2e}): nothing could be resolved",
            cam.view_height
        )));
    }
    if let Some(fov) = cam.fov_deg {
        let eye = cam.eye_distance();
        if !(eye <= 1e6 * scale) {
            return Err(Error::Input(format!(
                "--fov {fov:e}: the eye would be {eye:.2e} world units away, beyond the f32 \
                 precision of the scene's coordinates (up to {scale:.2e})"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The knob structs' defaults come from their clap attributes: they
    /// parse, and they are DESIGN.md's.
    #[test]
    fn knob_defaults_are_the_documented_ones() {
        let l = Look::default();
        assert_eq!(
            (l.background, l.outline, l.fog, l.color16),
            (Background::Gradient, 0.0, None, false)
        );
        assert_eq!(l.knobs.shadow_diffuse, 0.05);
        let (s, d) = (SsdoKnobs::default(), DeepParams::default());
        assert_eq!(
            (
                s.blur,
                s.semantic_levels,
                d.pool_chunks,
                d.see_through_fragments
            ),
            (true, None, None, None)
        );
        let i = IssmParams::default();
        assert_eq!(
            (i.size, i.t, i.soft_s, i.soft_x, i.soft_b),
            (512, IssmT(Some(1)), 2.0, 2.0, 20.0)
        );
        let m = ShadowMapParams::default();
        assert_eq!(
            (m.sm_size, m.sm_bias, m.sm_slope_bias, m.pcf_samples),
            (2048, 0.5, 1.0, 16)
        );
        assert_eq!((m.pcf_radius, m.osm_size, m.osm_slices), (1.5, 512, 64));
        for v in [i.validate(), m.validate(), l.validate()] {
            v.expect("defaults are valid");
        }
        // and a flag still overrides one of them
        #[derive(clap::Parser)]
        struct P {
            #[command(flatten)]
            o: Options,
        }
        let p = <P as clap::Parser>::try_parse_from([
            "x",
            "--issm-t",
            "auto",
            "--outline",
            "2",
            "--blur",
            "off",
            "--deep-pool-chunks",
            "9",
        ])
        .expect("parse");
        assert_eq!((p.o.issm.t, p.o.look.outline), (IssmT(None), 2.0));
        assert_eq!(
            (p.o.ssdo_knobs.blur, p.o.deep.pool_chunks),
            (false, Some(9))
        );
        assert_eq!(p.o.shadow_maps, ShadowMapParams::default());
        // a knob's range lives in its attribute
        let e = <P as clap::Parser>::try_parse_from(["x", "--shadow-diffuse", "2"])
            .err()
            .expect("out of range")
            .to_string();
        assert!(
            e.contains("--shadow-diffuse") && e.contains("between 0 and 1"),
            "{e}"
        );
    }
}
