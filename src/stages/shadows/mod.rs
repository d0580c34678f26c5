//! Key-light shadow techniques, one shape for all: a technique builds its
//! light-space structure in `record_light` and tells, in `lookup`, how
//! `shade` (and `ssdo_prep`) read key-light visibility from it: a lookup
//! compiled into those shaders (glsl/lookup_*.glsl, the fast path of the
//! built-in techniques: no per-pixel visibility buffer is written and read
//! back), or a per-pixel buffer its own pass fills (`LookupKind::Buffer`,
//! the generic way in). Adding a technique = its file here, its shader(s),
//! a `ShadowMode` value and one arm in [`create`] (see constant.rs).

#[cfg(test)]
pub mod constant;
pub mod deep;
pub mod issm;
pub mod osm;
pub mod shadow_map;
pub mod stage;

pub use stage::ShadowStage;

use crate::camera::Camera;
use crate::error::Result;
use crate::passes::scene::{SceneBuffers, SceneGeom};
use crate::settings::{RenderSettings, ShadowMode};
use crate::vk::pipeline::Binding;
use crate::vk::{Buffer, Context, Recorder};
use glam::DVec3;
use std::any::Any;

/// What a shadow technique's light-space passes read in a frame: the
/// scene, the camera's visibility buffer (for per-pixel passes of its own).
pub struct ShadowInputs<'a> {
    pub globals: &'a Buffer,
    pub scene: &'a SceneBuffers,
    pub vis: &'a Buffer,
    /// Sphere opacity for the translucent techniques (1 = opaque).
    pub opacity: f32,
    pub pixels: u64,
    /// The compute rasterizer (light-space maps are rasterized with it).
    pub raster: &'a crate::stages::raster::compute::RasterPass,
    /// The LOD cull, when it ran this frame: the light's lists are drawn
    /// in place of its order.
    pub lod: Option<&'a crate::stages::raster::lod::LodCull>,
}

impl<'a> ShadowInputs<'a> {
    /// The pass `name`: the spheres rasterized from the light into `map`
    /// (`size` texels); with the LOD cull, then `light_occlusion` and
    /// `light_raster_late` (the instances not drawn first and not hidden
    /// behind what was).
    pub fn record_light_map(
        &self,
        rec: &mut crate::vk::Recorder,
        name: &'static str,
        map: &'a Buffer,
        (w, h): (u32, u32),
    ) -> Result<()> {
        use crate::stages::raster::compute::{RasterIo, ViewIndex};
        use crate::stages::raster::lod::{Image, LodCull};
        let io = |lod, clear| RasterIo {
            globals: self.globals,
            scene: self.scene,
            target: map,
            texels: w as u64 * h as u64,
            lod,
            clear,
            tested: None,
        };
        let light = ViewIndex::Light;
        self.raster
            .record_light_map(rec, name, &io(self.lod.map(|l| l.view(light)), true))?;
        let Some(l) = self.lod else {
            return Ok(());
        };
        rec.pass(LodCull::LIGHT_OCCLUSION, |p| {
            l.occlusion_steps(p, self.globals, self.scene, map, light, false, (w, h))
        })?;
        rec.pass(LodCull::LIGHT_LATE, |p| {
            self.raster
                .steps(p, &io(Some(l.late(light)), false), light, false, false)?;
            // (the final map's depth tiles: next frame's early batches)
            l.tiles_of(p, self.globals, map, (light, Image::Final), (w, h));
            Ok(())
        })
    }
}

/// What a technique needs to (re)fit itself: the spheres (CPU copy) and
/// the scene's SCENE_SPEC (its pipelines' kind and batch shift), the key-light direction
/// and the settings.
pub struct ShadowSetup<'a> {
    pub ctx: &'a Context,
    pub geom: &'a SceneGeom,
    pub scene: u32,
    pub light_dir: DVec3,
    pub settings: &'a RenderSettings,
}

impl ShadowSetup<'_> {
    /// The orthographic light view fitted to the spheres at `size`² texels.
    pub fn fit(&self, size: u32) -> Result<Camera> {
        let axes = crate::camera::light_axes(self.light_dir)?;
        crate::camera::light_view_of(self.geom.extent_along(axes), axes, size)
    }

    /// Every represented sphere's radius.
    pub fn radii(&self) -> impl Iterator<Item = f32> + '_ {
        self.geom.radii()
    }
}

/// After a frame: is it good, or must it be rendered again?
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameCheck {
    Done,
    /// The technique grew a structure that overflowed: render again.
    Retry,
}

/// Which key-light lookup shade.comp and ssdo_prep.comp are compiled with
/// (their `SHADOW_*` variants, glsl/lookup.glsl).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LookupKind {
    /// No shadows.
    None,
    Issm,
    Deep,
    ShadowMap,
    Opacity,
    /// Screen-space march (`--shadows none` with SSDO).
    Screen,
    /// A per-pixel visibility buffer a technique's own pass wrote.
    Buffer,
}

impl LookupKind {
    /// The variant of shade.comp (`shade`) or ssdo_prep.comp compiled with
    /// this lookup.
    pub fn shader(self, shade: bool) -> crate::vk::pipeline::Shader {
        use crate::passes::spirv;
        use LookupKind::*;
        match (self, shade) {
            (None, true) => spirv::SHADE_COMP_SHADOW_NONE,
            (Issm, true) => spirv::SHADE_COMP_SHADOW_ISSM,
            (Deep, true) => spirv::SHADE_COMP_SHADOW_DEEP,
            (ShadowMap, true) => spirv::SHADE_COMP_SHADOW_SM,
            (Opacity, true) => spirv::SHADE_COMP_SHADOW_OSM,
            (Screen, true) => spirv::SHADE_COMP_SHADOW_SCREEN,
            (Buffer, true) => spirv::SHADE_COMP_SHADOW_BUFFER,
            (None, false) => spirv::SSDO_PREP_COMP_SHADOW_NONE,
            (Issm, false) => spirv::SSDO_PREP_COMP_SHADOW_ISSM,
            (Deep, false) => spirv::SSDO_PREP_COMP_SHADOW_DEEP,
            (ShadowMap, false) => spirv::SSDO_PREP_COMP_SHADOW_SM,
            (Opacity, false) => spirv::SSDO_PREP_COMP_SHADOW_OSM,
            (Screen, false) => spirv::SSDO_PREP_COMP_SHADOW_SCREEN,
            (Buffer, false) => spirv::SSDO_PREP_COMP_SHADOW_BUFFER,
        }
    }
}

/// Parameters of a lookup, carried in `Globals.shadow_*` (each lookup
/// header documents its fields).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShadowParams {
    pub f0: [f32; 4],
    pub f1: [f32; 4],
    pub u: [u32; 4],
}

/// How shade reads a technique's key-light visibility.
pub struct Lookup<'a> {
    pub kind: LookupKind,
    /// ISSM soft shadows (a specialization constant of the lookup).
    pub soft: bool,
    /// The lookup's own bindings (from binding 16 on in GLSL).
    pub bindings: &'static [Binding],
    pub buffers: Vec<(&'static str, &'a Buffer)>,
    pub params: ShadowParams,
}

impl Lookup<'_> {
    /// The farthest (texels, Chebyshev) a lookup reads from the texel
    /// whose centre is nearest its point, that texel kept one texel inside
    /// the map (as ISSM's 3x3 core is; glsl/lod_bounds.comp): ISSM the
    /// (2t+1)^2 patch (at least the core); PCF its disk's radius rounded
    /// up, one more for the rounding of each tap. The light's cull keeps
    /// only instances over the camera's visible points' texels grown by
    /// this (every texel for a lookup of another kind).
    pub fn reach(&self) -> i32 {
        match self.kind {
            LookupKind::Issm => self.params.u[0].clamp(1, 1 << 20) as i32,
            LookupKind::ShadowMap => self.params.f0[3].clamp(0.0, 1e6).ceil() as i32 + 1,
            _ => 1 << 29,
        }
    }

    /// How far (world units) a caster may lie behind a point, from the
    /// light, and still darken it: a lookup that counts only casters
    /// nearer the light than the point (ISSM: the occluder's centre ahead
    /// of it, or the point inside it) needs none; the depth map's test
    /// point moves back by a negative bias. The light's cull hides what
    /// lies farther than every point reading a texel by more than this
    /// (glsl/lod_hiz.comp).
    pub fn depth_slack(&self) -> f32 {
        match self.kind {
            LookupKind::ShadowMap => {
                let [bias, slope, tan_max, _] = self.params.f0;
                let back = -bias.min(bias + slope * tan_max);
                // (NaN: none)
                if back > 0.0 { back.min(1e30) } else { 0.0 }
            }
            _ => 0.0,
        }
    }

    /// ISSM with t <= 1: only the dense 3x3 core is read (a
    /// specialization constant of the lookup, `ISSM_CORE_ONLY`).
    pub fn core_only(&self) -> bool {
        self.kind == LookupKind::Issm && self.params.u[0] <= 1
    }

    /// ISSM with t = 0: only the 2x2 texels around the point are read (a
    /// specialization constant of the lookup, `ISSM_QUAD`).
    pub fn quad(&self) -> bool {
        self.kind == LookupKind::Issm && self.params.u[0] == 0
    }
}

impl Lookup<'static> {
    /// No technique (or the screen-space march, which needs nothing bound).
    pub fn plain(kind: LookupKind, params: ShadowParams) -> Self {
        Lookup {
            kind,
            soft: false,
            bindings: &[],
            buffers: Vec::new(),
            params,
        }
    }
}

pub trait ShadowTechnique {
    fn mode(&self) -> ShadowMode;
    /// The light view the technique's map uses (in `Globals.light`).
    fn light(&self) -> &Camera;
    /// Light-space passes: maps or lists of the key light's view (and, for
    /// `LookupKind::Buffer` techniques, their per-pixel pass).
    fn record_light<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()>;
    /// How shade reads the visibility (opacity of every sphere given).
    fn lookup(&self, opacity: f32) -> Lookup<'_>;
    /// The light direction, the spheres or the settings changed: refit the
    /// light view and everything derived from it (maps keep their size).
    fn refit(&mut self, setup: &ShadowSetup) -> Result<()>;
    /// Device memory by class (bytes), for `gpu_memory`.
    fn memory(&self) -> Vec<(&'static str, u64)>;
    /// Called after each frame finished; `Retry` renders it again.
    /// `words`: the frame's copy of [`Self::readback`]'s words (zeros past
    /// them).
    fn after_frame(&mut self, _ctx: &Context, _words: &[u32]) -> Result<FrameCheck> {
        Ok(FrameCheck::Done)
    }
    /// Words (buffer, byte offset, count: at most 32) copied at the end
    /// of every frame for [`Self::after_frame`], with no round trip. A
    /// technique that does not check every frame (pipelined frames are read
    /// later) copies only flags whose non-zero value asks for a check.
    fn readback(&self) -> Option<(&Buffer, u64, u64)> {
        None
    }
    /// Whether the frame must be checked before the next one is recorded
    /// (so a pipelined viewer waits for it).
    fn checks_frames(&self) -> bool {
        false
    }
    fn as_any(&self) -> &dyn Any;
    fn as_any_mut(&mut self) -> &mut dyn Any;
    fn destroy(&mut self, ctx: &Context);
}

/// The technique of `mode` (None for `--shadows none`).
pub fn create(mode: ShadowMode, setup: &ShadowSetup) -> Result<Option<Box<dyn ShadowTechnique>>> {
    Ok(match mode {
        ShadowMode::None => None,
        ShadowMode::Issm | ShadowMode::IssmSoft => Some(Box::new(issm::Issm::new(
            setup,
            mode == ShadowMode::IssmSoft,
        )?)),
        ShadowMode::Deep => Some(Box::new(deep::DeepShadows::new(setup)?)),
        ShadowMode::SmPcf => Some(Box::new(shadow_map::ShadowMap::new(setup)?)),
        ShadowMode::Osm => Some(Box::new(osm::OpacityShadows::new(setup)?)),
        #[cfg(test)]
        ShadowMode::TestConstant => Some(Box::new(constant::Constant::new(setup)?)),
    })
}

/// Boxed techniques are destroyed through the trait.
impl crate::vk::guard::Destroy for Box<dyn ShadowTechnique> {
    fn destroy_with(&mut self, ctx: &Context) {
        self.destroy(ctx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A depth map's test point moves back from the light by a negative
    /// bias (at the steepest slope the lookup takes): the light's cull
    /// must keep casters that far behind a point; ISSM needs no slack.
    #[test]
    fn the_depth_slack_is_the_farthest_a_bias_moves_a_point_back() {
        let sm = |f0: [f32; 4]| {
            let p = ShadowParams {
                f0,
                ..Default::default()
            };
            Lookup::plain(LookupKind::ShadowMap, p).depth_slack()
        };
        assert_eq!(sm([0.5, 0.25, 4.0, 2.0]), 0.0);
        assert_eq!(sm([-2.0, 0.25, 4.0, 2.0]), 2.0);
        assert_eq!(sm([0.5, -0.5, 4.0, 2.0]), 1.5);
        assert_eq!(sm([f32::NAN, 0.0, 4.0, 2.0]), 0.0);
        let issm = Lookup::plain(LookupKind::Issm, ShadowParams::default());
        assert_eq!(issm.depth_slack(), 0.0);
    }
}
