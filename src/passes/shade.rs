//! `shade`: the one full-resolution pass after the rasterizer (see
//! glsl/shade.comp): visible surface from (pixel ray, sphere id), the active
//! technique's key-light lookup, the SSDO result upsampled, three-point
//! lighting into the colour buffer, shadow and ao AOVs. One shader compiled
//! per technique (the lookup's bindings differ), mode switches as
//! specialization constants; pipelines are made the first time a
//! combination is used and kept.

use super::coverage::{TILE_BINDING, Tiles};
use super::shadows::{Lookup, LookupKind};
use super::{LOCAL_SIZE, spirv};
use crate::error::Result;
use crate::vk::pipeline::{Binding, PipelineDesc, Shader, texel, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder, Recorder};
use ash::vk::Format;
use bytemuck::{Pod, Zeroable};
use std::collections::HashMap;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ShadePush {
    /// Fraction of the key light's diffuse term kept in full shadow.
    pub shadow_diffuse: f32,
    /// Silhouette line width in pixels (with ShadeMode::outline).
    pub outline_px: f32,
    /// Depth cue from view_z fog_near to fog_far (used with ShadeMode::fog).
    pub fog_near: f32,
    pub fog_far: f32,
    /// A neighbour nearer by more than this (world units) makes a line.
    pub edge_dz: f32,
    /// Hierarchy level whose region changes make lines.
    pub level: u32,
    /// Depth tolerance (world units) of the SSDO upsample.
    pub ao_sigma_z: f32,
    /// 1: the upsample compares regions at the records' level b, 0: level a.
    pub ao_level_b: u32,
}

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

/// Which compiled variant of a per-technique shader.
pub fn variant(kind: LookupKind, shade: bool) -> Shader {
    use LookupKind::*;
    match (kind, shade) {
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

/// Groups for an image in 8x8 tiles (glsl/tiles.glsl), folded into y.
pub fn tile_grid(w: u32, h: u32) -> Grid<'static> {
    Grid::Invocations(w.div_ceil(8) as u64 * h.div_ceil(8) as u64 * LOCAL_SIZE as u64)
}

/// Pipelines made on first use, by (variant, constants).
#[derive(Default)]
pub struct Variants {
    made: HashMap<(usize, Vec<u32>), ComputePipeline>,
}

/// A variant is keyed by the address of its embedded SPIR-V: build.rs
/// makes each shader a `static`, whose bytes have one address (a `const`'s
/// may be copied per codegen unit, and then the key misses).
fn key(shader: Shader, constants: &[u32]) -> (usize, Vec<u32>) {
    (shader.spirv.as_ptr() as usize, constants.to_vec())
}

impl Variants {
    /// The pipeline for `shader` with these bindings, push size and
    /// specialization constants (ids 1, 2, ...), made if new.
    pub fn ensure(
        &mut self,
        ctx: &Context,
        name: &'static str,
        shader: Shader,
        bindings: &[Binding],
        push_size: u32,
        constants: &[u32],
    ) -> Result<()> {
        let key = key(shader, constants);
        if self.made.contains_key(&key) {
            return Ok(());
        }
        let pipe = ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name,
                shader,
                bindings,
                push_size,
                local_size: LOCAL_SIZE,
                constants,
            },
        )?;
        self.made.insert(key, pipe);
        Ok(())
    }

    pub fn get(&self, shader: Shader, constants: &[u32]) -> Option<&ComputePipeline> {
        self.made.get(&key(shader, constants))
    }

    /// [`Variants::ensure`] for a tiled shader (glsl/tiles.glsl): the
    /// pipelines with its TILE_LIST constant appended (the last id), for
    /// the covered and background lists or for every tile.
    #[allow(clippy::too_many_arguments)]
    pub fn ensure_tiled(
        &mut self,
        ctx: &Context,
        name: &'static str,
        shader: Shader,
        bindings: &[Binding],
        push_size: u32,
        constants: &[u32],
        lists: bool,
    ) -> Result<()> {
        for &t in Tiles::constants(lists) {
            let mut c = constants.to_vec();
            c.push(t);
            self.ensure(ctx, name, shader, bindings, push_size, &c)?;
        }
        Ok(())
    }

    /// A tiled shader's dispatches on a w x h grid (`half`: of blocks):
    /// one per tile list, `TileLists` bound to the lists (or, for every
    /// tile, to the first storage buffer given: unread).
    #[allow(clippy::too_many_arguments)]
    pub fn dispatch_tiled<'b, P: Pod>(
        &'b self,
        p: &mut PassBuilder<'b>,
        name: &str,
        shader: Shader,
        constants: &[u32],
        push: &P,
        tiles: Tiles<'b>,
        (size, half): ((u32, u32), bool),
        bufs: &[(&'static str, &'b Buffer)],
    ) -> Result<()> {
        // (for every tile the lists are unread: any storage buffer given)
        let fallback = bufs
            .iter()
            .map(|b| b.1)
            .find(|b| b.is_storage())
            .ok_or_else(|| crate::Error::Internal(format!("{name}: no storage buffer bound")))?;
        let mut all = bufs.to_vec();
        all.push(("TileLists", tiles.buffer(fallback)));
        for (t, grid) in tiles.dispatches(size, half) {
            let mut c = constants.to_vec();
            c.push(t);
            let pipe = self
                .get(shader, &c)
                .ok_or_else(|| crate::Error::Internal(format!("{name}: pipeline not prepared")))?;
            p.dispatch(pipe, push, grid, &all);
        }
        Ok(())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for (_, mut p) in self.made.drain() {
            p.destroy(ctx);
        }
    }
}

pub struct ShadePass {
    variants: Variants,
}

/// Everything that picks a shade pipeline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeMode {
    pub kind: LookupKind,
    pub soft: bool,
    pub ao: bool,
    /// The SSDO result is per 2x2 block: upsample it.
    pub ao_half: bool,
    /// The SSDO result is per sphere: weight it by the pixel's normal.
    pub ao_sphere: bool,
    pub swap_rb: bool,
    /// Write the shadow and ao AOVs.
    pub aovs: bool,
    /// ISSM reads only its 3x3 core ([`Lookup::core_only`]).
    pub core_only: bool,
    /// ISSM reads only the 2x2 texels around the point ([`Lookup::quad`]).
    pub quad: bool,
    /// Silhouette lines.
    pub outline: bool,
    /// RGBA16 colour.
    pub wide: bool,
    /// Depth cue: the push constants' fog range is not empty (the one place
    /// that decides; the shader reads the range only then).
    pub fog: bool,
    /// Perspective camera.
    pub perspective: bool,
    /// Run on the tile lists (not with silhouette lines, which reach from
    /// covered pixels into background regions).
    pub lists: bool,
}

impl ShadeMode {
    fn constants(&self) -> [u32; 13] {
        let use_shadow = !matches!(self.kind, LookupKind::None | LookupKind::Screen);
        [
            self.soft as u32,
            self.ao as u32,
            self.swap_rb as u32,
            use_shadow as u32,
            self.aovs as u32,
            self.core_only as u32,
            self.outline as u32,
            self.wide as u32,
            self.ao_half as u32,
            self.ao_sphere as u32,
            self.fog as u32,
            self.perspective as u32,
            self.quad as u32,
        ]
    }
}

const SHADE_OUTPUTS: [Binding; 5] = [
    texel("aoTex", Format::R32_UINT),
    texel("recordTex", Format::R32G32B32A32_UINT),
    wo("Color"),
    wo("Aov"),
    texel("sphereAoTex", Format::R32G32B32A32_UINT),
];

impl ShadePass {
    pub const NAME: &'static str = "shade";

    pub fn new() -> Self {
        ShadePass {
            variants: Variants::default(),
        }
    }

    fn bindings(lookup: &Lookup) -> Vec<Binding> {
        let mut b: Vec<Binding> = SURFACE_BINDINGS.to_vec();
        b.extend_from_slice(&SHADE_OUTPUTS);
        b.push(TILE_BINDING);
        b.extend_from_slice(lookup.bindings);
        b
    }

    /// Makes the pipelines of `mode` if this is their first use.
    pub fn prepare(&mut self, ctx: &Context, mode: ShadeMode, lookup: &Lookup) -> Result<()> {
        self.variants.ensure_tiled(
            ctx,
            Self::NAME,
            variant(mode.kind, true),
            &Self::bindings(lookup),
            std::mem::size_of::<ShadePush>() as u32,
            &mode.constants(),
            mode.lists,
        )
    }

    /// `shade` into `color` and `aov`, upsampling the half-resolution SSDO
    /// result `ao` with its `records` (bound even without SSDO; unread then),
    /// or weighting the per-sphere result `sphere_ao` (any buffer when
    /// unused).
    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        rec: &mut Recorder,
        io: &ScreenInputs,
        lookup: &Lookup,
        mode: ShadeMode,
        (ao, records, sphere_ao): (&Buffer, &Buffer, &Buffer),
        (color, aov): (&Buffer, &Buffer),
        push: &ShadePush,
        (w, h): (u32, u32),
        tiles: Tiles,
    ) -> Result<()> {
        let tiles = if mode.lists { tiles } else { Tiles::All };
        let mut bufs = io.surface_buffers();
        bufs.extend([
            ("aoTex", ao),
            ("recordTex", records),
            ("Color", color),
            ("Aov", aov),
            ("sphereAoTex", sphere_ao),
        ]);
        bufs.extend(lookup.buffers.iter().copied());
        rec.pass(Self::NAME, |p| {
            self.variants.dispatch_tiled(
                p,
                Self::NAME,
                variant(mode.kind, true),
                &mode.constants(),
                push,
                tiles,
                ((w, h), false),
                &bufs,
            )
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.variants.destroy(ctx);
    }
}

impl Default for ShadePass {
    fn default() -> Self {
        Self::new()
    }
}
