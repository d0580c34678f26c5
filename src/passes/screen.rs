//! What the screen-space passes (`ssdo_prep`, `shade`) start from: the
//! visible surface, rebuilt per pixel from (pixel ray, sphere id).

use super::scene::{SCENE_ATTRIBUTES, SCENE_GEOMETRY, SceneBuffers};
use crate::vk::Buffer;
use crate::vk::pipeline::{Binding, texel, uniform};
use ash::vk::Format;

/// The frame's screen-space inputs of `shade` and `ssdo_prep`.
pub struct ScreenInputs<'a> {
    pub globals: &'a Buffer,
    pub vis: &'a Buffer,
    /// The spheres, their colours (one RGBA8 word per sphere, albedo_of: a
    /// 64-byte line holds 16 spheres' colours, where the attribute texels
    /// hold 2) and regions (glsl/scene.glsl).
    pub scene: &'a SceneBuffers,
}

impl<'a> ScreenInputs<'a> {
    /// The buffers of [`surface_bindings`], by the same names.
    pub fn surface_buffers(&self) -> Vec<(&'static str, &'a Buffer)> {
        let mut v = vec![("GlobalsBlock", self.globals), ("visTex", self.vis)];
        v.extend(self.scene.geometry());
        v.extend(self.scene.attributes());
        v
    }
}

/// The bindings every variant of shade.comp and ssdo_prep.comp starts with.
pub fn surface_bindings() -> Vec<Binding> {
    let mut v = vec![
        uniform("GlobalsBlock"),
        texel("visTex", Format::R32G32_UINT),
    ];
    v.extend(SCENE_GEOMETRY);
    v.extend(SCENE_ATTRIBUTES);
    v
}
