//! Implicit Sphere Shadow Maps (after the ISSM paper): the key light's view is
//! rasterized by the compute sphere rasterizer into an id map
//! (`issm_raster`), resolved to a light-space sphere record per texel
//! (`issm_resolve`); the lookup (in `shade`) tests each visible point's
//! light ray against the spheres of a (2t+1)^2 texel patch.

use super::ShadowInputs;
use super::{Lookup, LookupKind, ShadowParams, ShadowSetup, ShadowTechnique};
use crate::camera::Camera;
use crate::error::Result;
use crate::gpu::blocks::ResolvePush;
use crate::passes::scene::SCENE_GEOMETRY;
use crate::passes::{LOCAL_SIZE, spirv};
use crate::settings::{IssmParams, ShadowMode};
use crate::stages::raster::compute as raster;
use crate::vk::pipeline::{Binding, PipelineDesc, texel, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
use ash::vk::Format;
use bytemuck::{Pod, Zeroable};
use std::any::Any;

/// Largest automatic patch half-size in texels.
pub const MAX_AUTO_T: u32 = 64;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct IssmPush {
    pub t: i32,
    /// Texel step outside the dense 3x3 core.
    pub stride: i32,
    pub soft_s: f32,
    pub soft_x: f32,
    pub soft_b: f32,
}

/// Automatic t: an occluder of P's light ray has its centre within r_max
/// (plus the soft enlargement s) of P across the light, so its own texel is
/// within ceil((r_max + s) / texel + 0.5) texels of P's; the sphere covering
/// its centre texel is stored there unless something nearer the light covers
/// it, which then shadows P as well (up to silhouettes).
pub fn auto_t(max_radius: f32, soft_s: f32, texel: f64) -> u32 {
    let reach = (max_radius + soft_s) as f64 / texel.max(1e-9) + 0.5;
    (reach.ceil() as u32).clamp(1, MAX_AUTO_T)
}

/// Patch sampling step for automatic t: the smallest sphere radius in texels
/// (at least 1), so a sphere's light-space disk always holds a sample.
pub fn auto_stride(min_radius: f32, texel: f64) -> u32 {
    ((min_radius as f64 / texel.max(1e-9)).floor() as u32).max(1)
}

/// The key light's sphere id map and its resolved copy (read by
/// glsl/lookup_issm.glsl).
pub struct Issm {
    soft: bool,
    pub light: Camera,
    map: Buffer,
    /// Per texel its sphere's light-space centre and radius (RGBA32F,
    /// glsl/issm_resolve.comp).
    resolved: Buffer,
    resolve: ComputePipeline,
    pub push: IssmPush,
}

/// Bytes per texel of the resolved map.
const RESOLVED_TEXEL: u64 = 16;

/// The lookup's binding: the resolved map.
const LOOKUP: [Binding; 1] = [texel("issmResolvedTex", Format::R32G32B32A32_SFLOAT)];

const RESOLVE_BINDINGS: [Binding; 3] = [
    uniform("GlobalsBlock"),
    texel("issmTex", Format::R32_UINT),
    wo("Resolved"),
];

impl Issm {
    pub const RASTER_NAME: &'static str = "issm_raster";
    pub const RESOLVE_NAME: &'static str = "issm_resolve";

    pub fn new(setup: &ShadowSetup, soft: bool) -> Result<Self> {
        let ctx = setup.ctx;
        let p = &setup.settings.issm;
        let light = setup.fit(p.size)?;
        let texels = p.size as u64 * p.size as u64;
        let map = ctx.guard(raster::vis_buffer(ctx, "issm", texels)?);
        let resolved = ctx.guard(Buffer::storage(
            ctx,
            "issm resolved",
            texels * RESOLVED_TEXEL,
        )?);
        let resolve = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "issm resolve",
                shader: spirv::ISSM_RESOLVE_COMP,
                bindings: &[&RESOLVE_BINDINGS[..], &SCENE_GEOMETRY].concat(),
                push_size: std::mem::size_of::<ResolvePush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &[],
                scene: setup.scene,
            },
        )?);
        let mut issm = Issm {
            soft,
            light,
            map: map.keep(),
            resolved: resolved.keep(),
            resolve: resolve.keep(),
            push: IssmPush::zeroed(),
        };
        issm.fit_push(setup, light);
        Ok(issm)
    }

    /// Patch size and stride for a light view (auto t follows the texel).
    fn fit_push(&mut self, setup: &ShadowSetup, light: Camera) {
        let p = &setup.settings.issm;
        let texel = light.view_height / p.size as f64;
        let (t, stride) = match p.t.0 {
            Some(t) => (t, 1),
            None => {
                let (min_r, max_r) = setup.geom.radius_range();
                let t = auto_t(max_r, if self.soft { p.soft_s } else { 0.0 }, texel);
                (t, auto_stride(min_r, texel))
            }
        };
        log::info!(
            "issm: map {}², texel {texel:.3}, t {t}, stride {stride}",
            p.size
        );
        self.light = light;
        self.push = Self::push(p, self.soft, t, stride);
    }

    /// `stride` 1 walks every texel of the patch (the paper's method; used
    /// when the user sets t); automatic t uses `auto_stride`.
    pub fn push(params: &IssmParams, soft: bool, t: u32, stride: u32) -> IssmPush {
        IssmPush {
            t: t as i32,
            stride: stride.max(1) as i32,
            soft_s: if soft { params.soft_s } else { 0.0 },
            soft_x: params.soft_x,
            soft_b: params.soft_b,
        }
    }

    fn texels(&self) -> u64 {
        self.light.width as u64 * self.light.height as u64
    }

    /// The light-space id map (depth|id per texel, without guard words).
    pub fn read_map(&self, ctx: &Context) -> Result<Vec<u64>> {
        self.map.download_pod(ctx, 0, self.texels())
    }
}

impl ShadowTechnique for Issm {
    fn mode(&self) -> ShadowMode {
        if self.soft {
            ShadowMode::IssmSoft
        } else {
            ShadowMode::Issm
        }
    }

    fn light(&self) -> &Camera {
        &self.light
    }

    /// `issm_raster`, then `issm_resolve`.
    fn record_light<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        f.record_light_map(
            rec,
            Self::RASTER_NAME,
            &self.map,
            (self.light.width, self.light.height),
        )?;
        let mut bindings = vec![
            ("GlobalsBlock", f.globals),
            ("issmTex", &self.map),
            ("Resolved", &self.resolved),
        ];
        bindings.extend(f.scene.geometry());
        rec.pass(Self::RESOLVE_NAME, |p| {
            p.dispatch(
                &self.resolve,
                &ResolvePush {
                    texels: self.texels() as u32,
                },
                Grid::Invocations(self.texels()),
                &bindings,
            );
            Ok(())
        })
    }

    fn lookup(&self, _opacity: f32) -> Lookup<'_> {
        let p = &self.push;
        Lookup {
            kind: LookupKind::Issm,
            soft: self.soft,
            bindings: &LOOKUP,
            buffers: vec![("issmResolvedTex", &self.resolved)],
            params: ShadowParams {
                f0: [p.soft_s, p.soft_x, p.soft_b, 0.0],
                u: [p.t as u32, p.stride as u32, 0, 0],
                ..Default::default()
            },
        }
    }

    fn refit(&mut self, setup: &ShadowSetup) -> Result<()> {
        let light = setup.fit(setup.settings.issm.size)?;
        self.fit_push(setup, light);
        Ok(())
    }

    fn memory(&self) -> Vec<(&'static str, u64)> {
        vec![("issm_map", self.map.size + self.resolved.size)]
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }

    fn destroy(&mut self, ctx: &Context) {
        self.resolve.destroy(ctx);
        self.resolved.destroy(ctx);
        self.map.destroy(ctx);
    }
}
