//! THE frame: every pass of a frame, in order, in one function. Each pass
//! names its steps and the recorder derives the barriers, so adding a pass
//! is its file in passes/, its shader, and one call here (plus its row in
//! [`PASSES`], which the README's "How it works" table is checked against).

use super::Resources;
use crate::error::Result;
use crate::passes::ShadowInputs;
use crate::passes::blur::{Axis, BlurIo};
use crate::passes::composite::{CompositeInputs, CompositePush};
use crate::passes::raster::{RasterPass, ViewIndex};
use crate::passes::resolve::ResolveIo;
use crate::passes::ssdo::GBuffer;
use crate::settings::RenderSettings;
use crate::vk::{Buffer, Recorder};

/// Fraction of the key light's diffuse term kept in full shadow.
pub const SHADOW_DIFFUSE: f32 = 0.12;

/// Every pass a frame may record: its name (= debug label = timestamp
/// scope = JSON name) and what it does.
pub const PASSES: &[(&str, &str)] = &[
    (
        "raster",
        "one invocation per sphere: exact ray-sphere test per covered pixel, 64-bit `atomicMin(depth<<32 \\| id)`; footprints above 1024 px (CPU) / 256 px (GPU) are split into 8-row bands that whole workgroups process (indirect dispatch); `--raster graphics`: the vertex/fragment impostor baseline, same output",
    ),
    (
        "issm_raster",
        "the same rasterizer from the key light into the ISSM (nearest sphere id per light texel), light view fitted to the spheres",
    ),
    (
        "deep_count",
        "deep shadow lists (seed 002), 8x8-texel tiles, one 64-invocation workgroup each: count the entries per texel (every sphere whose light-space disk overlaps the texel square)",
    ),
    (
        "deep_alloc",
        "per tile, a prefix sum of texel counts and one pool `atomicAdd` for its chunks of 64 entries (SoA: depth, alpha, id, next); overflow detected, the pool grown and the frame re-run",
    ),
    (
        "deep_fill",
        "the same enumeration as the count, writing the entries",
    ),
    (
        "deep_sort",
        "per texel: sort by depth, write links, transmittance and the epsilon-compressed visibility nodes",
    ),
    (
        "sm_raster",
        "baseline (seed 003): depth shadow map from the same compute rasterizer (sphere surface depth)",
    ),
    (
        "osm_raster",
        "baseline (seed 004): opacity shadow maps, 64 depth slices of fixed-point optical depth -ln(1-α)",
    ),
    (
        "osm_prefix",
        "prefix sum of the optical depth across the slices",
    ),
    (
        "resolve",
        "visibility → G-buffer (position, normal, regions buffer)",
    ),
    (
        "issm_shadow",
        "per visible point: exact light-ray tests against the spheres of the (2t+1)² ISSM patch (dense 3x3 core, then every `stride` texels where stride ≤ the smallest sphere radius in texels); identity check; soft: `(1 - s'/s_eff)^x` with `s_eff = s (1 - exp(-k²/2b²))`, minimum over the patch",
    ),
    (
        "deep_shadow",
        "per visible point: exact transmittance walk of its light texel's list (no spinning on other invocations)",
    ),
    (
        "sm_shadow",
        "slope-scaled bias, PCF over a per-pixel rotated Vogel disk",
    ),
    (
        "osm_shadow",
        "lookup interpolated between slices and texels, the receiver's own deposit subtracted",
    ),
    (
        "key_shadow",
        "screen-space march toward the key light (only with `--shadows none`: the light-space techniques are used as they are)",
    ),
    (
        "ssdo",
        "Halton + Malley cosine-weighted directions, near sample × far fixed-step search (visibilities multiplied), occluder = closer to the viewer and (semantic) in another region at the active hierarchy level, blended between two levels by zoom; one bounce (Ritschel et al.)",
    ),
    (
        "blur_h",
        "separable bilateral blur (depth, normal and region aware) of occlusion + bounce (and screen-space shadows), horizontal",
    ),
    ("blur_v", "the same, vertical"),
    (
        "composite",
        "key (shadowed: ambient + fill + rim only), fill and rim lights, ambient × occlusion + bounce, tone map",
    ),
];

/// The pass names, in [`PASSES`] order.
pub fn pass_names() -> &'static [&'static str] {
    static NAMES: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    NAMES.get_or_init(|| {
        #[allow(unused_mut)]
        let mut names: Vec<_> = PASSES.iter().map(|p| p.0).collect();
        #[cfg(test)]
        names.push(crate::passes::shadows::constant::NAME);
        names
    })
}

/// The README's "How it works" table (tests compare the two).
pub fn markdown_table() -> String {
    let mut s = String::from("| pass | what |\n|---|---|\n");
    for (name, what) in PASSES {
        s.push_str(&format!("| `{name}` | {what} |\n"));
    }
    s
}

impl Resources {
    /// Records one frame: the whole pass list.
    pub(super) fn record_frame(
        &self,
        settings: &RenderSettings,
        globals: &Buffer,
        rec: &mut Recorder,
    ) -> Result<()> {
        let t = &self.targets;
        let pixels = t.pixels;
        let cam = &settings.camera;

        rec.pass(RasterPass::NAME, |p| {
            match &self.raster_graphics {
                Some(g) => g.steps(
                    p,
                    globals,
                    &self.spheres,
                    self.sphere_count,
                    &t.vis,
                    (cam.width, cam.height),
                ),
                None => self.raster.steps(
                    p,
                    globals,
                    &self.spheres,
                    self.sphere_count,
                    &t.vis,
                    pixels,
                    ViewIndex::Camera,
                ),
            }
            Ok(())
        })?;

        let shadow = self.active_shadow();
        let inputs = ShadowInputs {
            globals,
            spheres: &self.spheres,
            vis: &t.vis,
            gpos: &t.gpos,
            gnorm: &t.gnorm,
            shadow: &t.shadow,
            opacity: settings.opacity,
            pixels,
            sphere_count: self.sphere_count,
            raster: &self.raster,
        };
        if let Some(s) = shadow {
            s.record_light(rec, &inputs)?;
        }

        self.resolve.record(
            rec,
            &ResolveIo {
                globals,
                spheres: &self.spheres,
                attrs: &self.attrs,
                vis: &t.vis,
                gpos: &t.gpos,
                gnorm: &t.gnorm,
                gregion: &t.gregion,
            },
            pixels,
        )?;

        if let Some(s) = shadow {
            s.record_lookup(rec, &inputs)?;
        }

        let mut ambient_final = &t.ambient;
        let mut shadow_final = &t.shadow;
        let ssdo = self.ssdo.as_ref().filter(|_| settings.ssdo_on());
        if let Some(st) = ssdo {
            let params = self.ssdo_params(settings);
            let gb = GBuffer {
                globals,
                attrs: &self.attrs,
                vis: &t.vis,
                gpos: &t.gpos,
                gnorm: &t.gnorm,
                gregion: &t.gregion,
            };
            if shadow.is_none() {
                // Screen-space key shadows stand in for the light-space techniques.
                st.pass
                    .record_key_shadow(rec, &gb, &t.shadow, &params.key_shadow, pixels)?;
            }
            st.pass
                .record_ssdo(rec, &gb, &t.shadow, &t.ambient, &params.ssdo, pixels)?;
            if settings.blur {
                let [a_tmp, s_tmp, a_out, s_out] = &t.blurred;
                let geometry = [&t.gpos, &t.gnorm, &t.gregion];
                for (axis, input, output) in [
                    (Axis::Horizontal, [&t.ambient, &t.shadow], [a_tmp, s_tmp]),
                    (Axis::Vertical, [a_tmp, s_tmp], [a_out, s_out]),
                ] {
                    let io = BlurIo {
                        globals,
                        geometry,
                        input,
                        output,
                    };
                    st.blur.record(rec, axis, &io, &params.blur, pixels)?;
                }
                (ambient_final, shadow_final) = (a_out, s_out);
            }
        }

        let light_space = shadow.is_some();
        self.composite.record(
            rec,
            &CompositeInputs {
                globals,
                attrs: &self.attrs,
                vis: &t.vis,
                gpos: &t.gpos,
                gnorm: &t.gnorm,
                shadow: shadow_final,
                ambient: ambient_final,
                color: &t.color,
            },
            &CompositePush {
                use_shadow: (light_space || ssdo.is_some()) as u32,
                use_ambient: ssdo.is_some() as u32,
                // Lighting rule (issue 4, after the ISSM paper): a fully
                // shadowed point keeps ambient and this fraction of the key's
                // diffuse term, and loses its specular term.
                shadow_diffuse: SHADOW_DIFFUSE,
                swap_rb: self.bgra as u32,
            },
            pixels,
        )?;
        Ok(())
    }
}
