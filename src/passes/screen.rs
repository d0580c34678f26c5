//! What the screen-space passes (`ssdo_prep`, `shade`) start from: the
//! visible surface, rebuilt per pixel from (pixel ray, sphere id).

use crate::vk::Buffer;
use crate::vk::pipeline::{Binding, texel, uniform};
use ash::vk::Format;

/// The frame's screen-space inputs of `shade` and `ssdo_prep`.
pub struct ScreenInputs<'a> {
    pub globals: &'a Buffer,
    pub vis: &'a Buffer,
    pub spheres: &'a Buffer,
    pub attrs: &'a Buffer,
    /// One RGBA8 word per sphere (albedo_of): a 64-byte line holds 16
    /// spheres' colours, where the attribute texels hold 2.
    pub colors: &'a Buffer,
}

impl<'a> ScreenInputs<'a> {
    /// The buffers of [`SURFACE_BINDINGS`], by the same names.
    pub fn surface_buffers(&self) -> Vec<(&'static str, &'a Buffer)> {
        vec![
            ("GlobalsBlock", self.globals),
            ("visTex", self.vis),
            ("sphereTex", self.spheres),
            ("attrTex", self.attrs),
            ("colorTex", self.colors),
        ]
    }
}

/// The bindings every variant of shade.comp and ssdo_prep.comp starts with.
pub const SURFACE_BINDINGS: [Binding; 5] = [
    uniform("GlobalsBlock"),
    texel("visTex", Format::R32G32_UINT),
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("attrTex", Format::R32_UINT),
    texel("colorTex", Format::R32_UINT),
];
