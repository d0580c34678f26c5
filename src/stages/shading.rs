//! `shade`: the one full-resolution pass after the rasterizer (see
//! glsl/shade.comp): visible surface from (pixel ray, sphere id), the active
//! technique's key-light lookup, the SSDO result upsampled, three-point
//! lighting into the colour buffer, shadow and ao AOVs. One shader compiled
//! per technique (the lookup's bindings differ), mode switches as
//! specialization constants; pipelines are made the first time a
//! combination is used and kept.

use super::shadows::{Lookup, LookupKind};
use super::ssdo::{SsdoOutputs, SsdoParams};
use crate::error::Result;
pub use crate::gpu::blocks::ShadePush;
use crate::gpu::blocks::ShadeSpec;
use crate::passes::LOCAL_SIZE;
use crate::passes::screen::{ScreenInputs, surface_bindings};
use crate::passes::tiles::{TILE_BINDING, Tiles};
use crate::passes::variants::{TiledDispatch, Variants};
use crate::settings::RenderSettings;
use crate::vk::pipeline::{Binding, PipelineDesc, rw, texel, wo};
use crate::vk::{Buffer, Context, Recorder};
use ash::vk::Format;

pub struct ShadePass {
    variants: Variants,
    /// The scene's SCENE_SPEC (kind and batch shift) for the pipelines.
    scene: u32,
}

/// The stage's screen targets: colour (RGBA8 or BGRA8; RGBA16 in two
/// words when `wide`) and the shadow|ao AOVs (one unorm16 each per pixel;
/// one word, never written, when they are off).
pub struct ShadeTargets {
    pub color: Buffer,
    pub aov: Buffer,
    pub aovs: bool,
    pub wide: bool,
}

impl ShadeTargets {
    pub fn new(ctx: &Context, pixels: u64, aovs: bool, wide: bool) -> Result<Self> {
        let color = ctx.guard(Buffer::storage(
            ctx,
            "colour",
            pixels * if wide { 8 } else { 4 },
        )?);
        let aov = Buffer::storage(ctx, "shadow and ao", if aovs { pixels * 4 } else { 4 })?;
        Ok(ShadeTargets {
            color: color.keep(),
            aov,
            aovs,
            wide,
        })
    }

    pub fn bytes(&self) -> u64 {
        self.color.size + self.aov.size
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.color.destroy(ctx);
        self.aov.destroy(ctx);
    }
}

crate::impl_destroy!(ShadeTargets);

/// What `shade` reads in a frame.
pub struct ShadeInputs<'a> {
    pub screen: &'a ScreenInputs<'a>,
    pub lookup: &'a Lookup<'a>,
    /// The SSDO stage's outputs (its targets, unread, without SSDO).
    pub ssdo: &'a SsdoOutputs<'a>,
    pub tiles: Tiles<'a>,
    /// The see-through fragment lists, when the frame has some.
    pub see_through: Option<crate::stages::see_through::SeeThroughOutputs<'a>>,
}

/// The stage's pipeline choice and push constants for one frame, computed
/// in one place ([`ShadeFrame::new`]).
#[derive(Clone, Copy, Debug)]
pub struct ShadeFrame {
    pub mode: ShadeMode,
    pub push: ShadePush,
}

impl ShadeFrame {
    /// From the settings, the frame's key-light lookup and SSDO parameters
    /// (whether SSDO runs or not: the upsample's tolerances and the
    /// outlines' level come from them), the swapchain's channel order and
    /// the typical sphere radius (world units).
    pub fn new(
        settings: &RenderSettings,
        lookup: &Lookup,
        ssdo: &SsdoParams,
        bgra: bool,
        typical_radius: f64,
        see_through: bool,
    ) -> Self {
        let on = settings.ssdo_on();
        let outline_px = outline_px(settings);
        let fog = settings.look.fog;
        ShadeFrame {
            mode: ShadeMode {
                kind: lookup.kind,
                lists: settings.tile_lists && outline_px == 0,
                spec: ShadeSpec {
                    soft: lookup.soft,
                    ao: on,
                    swap_rb: bgra,
                    use_shadow: !matches!(lookup.kind, LookupKind::None | LookupKind::Screen),
                    aovs: settings.aovs,
                    core_only: lookup.core_only(),
                    outline: outline_px > 0,
                    wide: settings.look.color16,
                    ao_half: on && ssdo.taps.per_block(),
                    ao_sphere: on && ssdo.taps.per_sphere(),
                    // the one place that decides; the shader reads the
                    // fog range only then
                    fog: fog.is_some_and(|f| f.0[1] > f.0[0]),
                    perspective: settings.camera.fov_deg.is_some(),
                    quad: lookup.quad(),
                    see_through,
                },
            },
            push: ShadePush {
                knobs: settings.look.knobs,
                outline_px: outline_px as f32,
                fog_near: fog.map_or(0.0, |f| f.0[0] as f32),
                fog_far: fog.map_or(0.0, |f| f.0[1] as f32),
                // a step of a sphere radius between neighbours is an edge
                edge_dz: typical_radius as f32,
                level: ssdo.main_level(),
                ao_sigma_z: ssdo.blur.sigma_z,
                ao_level_b: ssdo.blur.level_b,
            },
        }
    }
}

/// Silhouette line width in buffer pixels.
pub fn outline_px(settings: &RenderSettings) -> u32 {
    settings.look.outline.round() as u32
}

/// Everything that picks a shade pipeline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadeMode {
    /// The lookup compiled in (the shader variant).
    pub kind: LookupKind,
    /// Run on the tile lists (not with silhouette lines, which reach from
    /// covered pixels into background regions).
    pub lists: bool,
    /// The specialization constants (src/gpu_blocks.rs).
    pub spec: ShadeSpec,
}

impl ShadeMode {
    fn constants(&self) -> Vec<u32> {
        self.spec.constants()
    }
}

const SHADE_OUTPUTS: [Binding; 10] = [
    texel("aoTex", Format::R32_UINT),
    texel("recordTex", Format::R32G32B32A32_UINT),
    wo("Color"),
    wo("Aov"),
    texel("sphereAoTex", Format::R32G32B32A32_UINT),
    texel("flagTex", Format::R32_UINT),
    texel("wordBaseTex", Format::R32_UINT),
    texel("oitHeadTex", Format::R32G32_UINT),
    texel("oitFragTex", Format::R32G32_UINT),
    rw("OitCounters"),
];

impl ShadePass {
    pub const NAME: &'static str = "shade";

    /// The pass for a scene of this SCENE_SPEC (passes::scene).
    pub fn new(scene: u32) -> Self {
        ShadePass {
            variants: Variants::default(),
            scene,
        }
    }

    fn bindings(lookup: &Lookup) -> Vec<Binding> {
        let mut b: Vec<Binding> = surface_bindings();
        b.extend_from_slice(&SHADE_OUTPUTS);
        b.push(TILE_BINDING);
        b.extend_from_slice(lookup.bindings);
        b
    }

    /// Makes the pipelines of `mode` if this is their first use.
    pub fn prepare(&mut self, ctx: &Context, mode: ShadeMode, lookup: &Lookup) -> Result<()> {
        self.variants.ensure_tiled(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                shader: mode.kind.shader(true),
                bindings: &Self::bindings(lookup),
                push_size: std::mem::size_of::<ShadePush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &mode.constants(),
                scene: self.scene,
            },
            mode.lists,
        )
    }

    /// `shade` into the targets, from the SSDO outputs (upsampling the
    /// per-block result with its records, or weighting the per-sphere
    /// result; bound and unread without SSDO).
    pub fn record(
        &self,
        rec: &mut Recorder,
        io: &ShadeInputs,
        targets: &ShadeTargets,
        frame: &ShadeFrame,
        size: (u32, u32),
    ) -> Result<()> {
        let mode = frame.mode;
        let tiles = if mode.lists { io.tiles } else { Tiles::All };
        let mut bufs = io.screen.surface_buffers();
        bufs.extend([
            ("aoTex", io.ssdo.ao),
            ("recordTex", io.ssdo.records),
            ("Color", &targets.color),
            ("Aov", &targets.aov),
        ]);
        // (bound and unread without per-sphere receivers)
        let spheres = io.ssdo.sphere_ao;
        bufs.extend([
            ("sphereAoTex", spheres.map_or(io.ssdo.records, |s| &s.ao)),
            ("flagTex", spheres.map_or(io.ssdo.records, |s| &s.flags)),
            (
                "wordBaseTex",
                spheres.map_or(io.ssdo.records, |s| &s.word_base),
            ),
        ]);
        // (bound and unread without see-through spheres)
        let see = io.see_through;
        bufs.extend([
            ("oitHeadTex", see.map_or(io.ssdo.records, |s| s.heads)),
            ("oitFragTex", see.map_or(io.ssdo.records, |s| s.frags)),
            ("OitCounters", see.map_or(io.ssdo.records, |s| s.counters)),
        ]);
        bufs.extend(io.lookup.buffers.iter().copied());
        rec.pass(Self::NAME, |p| {
            self.variants.dispatch_tiled(
                p,
                &TiledDispatch {
                    name: Self::NAME,
                    shader: mode.kind.shader(true),
                    constants: &mode.constants(),
                    push: &frame.push,
                    tiles,
                    size,
                    half: false,
                    bufs: &bufs,
                },
            )
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.variants.destroy(ctx);
    }
}

crate::impl_destroy!(ShadePass);
