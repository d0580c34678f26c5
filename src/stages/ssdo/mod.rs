//! The SSDO stage (after the semantic SSDO paper): `ssdo_prep`, `ssdo` (per
//! pixel, per 2x2 block or per visible sphere) and the separable bilateral
//! blur. It owns its pipelines, its screen targets ([`SsdoTargets`]), the
//! tap tables and the semantic levels, and computes its parameters once
//! per frame ([`SsdoStage::params`]) from the camera and the scene's scale.

pub mod blur;
pub mod passes;
pub mod record;

use crate::camera::Camera;
use crate::error::Result;
use crate::passes::screen::ScreenInputs;
use crate::passes::tiles::Tiles;
use crate::semantic::{self, LevelChoice};
use crate::stages::shadows::{Lookup, ShadowParams};
use crate::vk::guard::Destroy;
use crate::vk::{Buffer, Context, Recorder};
use blur::{Axis, BlurIo, BlurPass, BlurPush, BlurShape};
use glam::DVec3;
use passes::{
    PrepIo, PrepPush, Receivers, Shape, SphereBuffers, SphereIo, SsdoIo, SsdoPass, SsdoPush, Taps,
};

/// SSDO taps when spheres are large on screen: per 2x2 block (the AO is
/// smooth over a block there), 8 directions x (1 near + 5 far steps),
/// blurred 2 blocks each side and upsampled. Spearman with the ray-traced
/// AO (tests/ao.rs scene at 1280x960, radius ~30 px): 12 x (1+4) 0.937,
/// 8 x (1+4) 0.935, 8 x (1+5) 0.938; per pixel (before) 0.936.
pub const SSDO_TAPS_LARGE: (Taps, i32) = (
    Taps {
        dirs: 8,
        steps: 5,
        receivers: Receivers::Block,
        perspective: false,
    },
    2,
);
/// ... and when they are small (typical radius under
/// [`SSDO_SMALL_RADIUS_PX`] pixels): per pixel, 8 directions x (1 + 5
/// steps), blurred 2 px each side.
pub const SSDO_TAPS_SMALL: (Taps, i32) = (
    Taps {
        dirs: 8,
        steps: 5,
        receivers: Receivers::Pixel,
        perspective: false,
    },
    2,
);
/// ... and when they are a few pixels wide (typical radius under
/// [`SSDO_SPHERE_RADIUS_PX`]): per visible sphere, SSDO_SPHERE_DIRS
/// directions (8 azimuths x 4 elevations) from the surface point facing
/// each, the 4 elevations of an azimuth sharing its 12 taps along one
/// screen line; weighted per pixel by its normal in shade; no blur (no
/// per-pixel noise). Spearman with the ray-traced AO (tests/ao.rs scene x
/// 27 at radius ~1.4 / ~0.7 / ~2.8 px), and the capsid's `ssdo` ms at
/// 1080p: 8 taps per line 0.851 / 0.834 / 0.843, 88 ms; 12: 0.874 /
/// 0.860 / 0.867, 111 ms; 16: 0.881 / 0.864 / 0.875, 133 ms; 32 spiral
/// directions x 5 taps each (unshared) 0.858 / 0.847 / 0.853, 151 ms.
pub const SSDO_TAPS_SPHERE: (Taps, i32) = (
    Taps {
        dirs: crate::gpu::consts::SSDO_SPHERE_DIRS,
        steps: 12,
        receivers: Receivers::Sphere,
        perspective: false,
    },
    0,
);
/// Below this typical sphere radius on screen (pixels) SSDO runs per
/// visible sphere. Spearman per sphere vs per pixel: ~1.4 px 0.874 vs
/// 0.827, ~1.7 px 0.862 vs 0.850, ~2.1 px 0.863 vs 0.867, ~2.8 px 0.867
/// vs 0.884: the per-pixel path ranks a little better from about 2 px, at
/// 2.5x the cost (the 1M capsid at 1080p, 2.8 px, is below this).
pub const SSDO_SPHERE_RADIUS_PX: f64 = 3.0;
/// Below this typical sphere radius on screen (pixels) the small set: per
/// block the AO loses the pixel-to-pixel creases of small spheres.
/// Spearman of the ao AOV with the ray-traced reference (tests/ao.rs
/// scene), per block vs per pixel: radius ~8 px 0.865 vs 0.929, ~16 px
/// 0.922 vs 0.938, ~30 px 0.937 vs 0.936; 9x the atoms at ~3 px 0.623 vs
/// 0.871.
pub const SSDO_SMALL_RADIUS_PX: f64 = 16.0;

/// The stage's screen-sized buffers. Full resolution: the SSDO result
/// (4 B/px; per pixel when spheres are small on screen, else only its
/// first quarter is used, per 2x2 block), the per-pixel blur's edge keys
/// (4 B/px) and the taps' depth words in 2x2-block order (4 B/px); the
/// records at half resolution (16 B per 2x2 block = 4 B/px).
pub struct SsdoTargets {
    /// Records (half resolution).
    pub records: Buffer,
    /// The result: near/far visibility, bounce, screen-space shadow.
    pub ao: Buffer,
    keys: Buffer,
    taps: Buffer,
}

impl SsdoTargets {
    pub fn new(ctx: &Context, width: u32, height: u32) -> Result<Self> {
        let pixels = width as u64 * height as u64;
        let (hw, hh) = half(width, height);
        let blocks = hw as u64 * hh as u64;
        let records = ctx.guard(Buffer::storage(ctx, "ssdo records", blocks * 16)?);
        let ao = ctx.guard(Buffer::storage(ctx, "ssdo ao", pixels * 4)?);
        let keys = ctx.guard(Buffer::storage(ctx, "ssdo blur keys", pixels * 4)?);
        // (block-linear depth words cover whole blocks: odd sizes need more)
        let taps = Buffer::storage(ctx, "ssdo tap depth", 4 * blocks * 4)?;
        Ok(SsdoTargets {
            records: records.keep(),
            ao: ao.keep(),
            keys: keys.keep(),
            taps,
        })
    }

    /// Per pixel: the blur's edge keys (view distance and region), which
    /// `ssdo` writes.
    pub fn edge_keys(&self) -> &Buffer {
        &self.keys
    }

    /// The depth words the taps read, four per 2x2 block (`ssdo_prep`
    /// writes them).
    pub fn tap_depth(&self) -> &Buffer {
        &self.taps
    }

    pub fn bytes(&self) -> u64 {
        self.records.size + self.ao.size + self.keys.size + self.taps.size
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.records,
            &mut self.ao,
            &mut self.keys,
            &mut self.taps,
        ] {
            b.destroy(ctx);
        }
    }
}

crate::impl_destroy!(SsdoTargets);

/// Half-resolution size (one block per 2x2 pixels).
pub fn half(w: u32, h: u32) -> (u32, u32) {
    let b = crate::gpu::consts::SSDO_BLOCK;
    (w.div_ceil(b), h.div_ceil(b))
}

/// Parameters of the screen-space passes for one frame, computed in one
/// place ([`SsdoStage::params`]).
pub struct SsdoParams {
    pub prep: PrepPush,
    pub ssdo: SsdoPush,
    pub taps: Taps,
    /// Blur taps on each side (one of [`blur::BLUR_RADII`]).
    pub blur_radius: i32,
    pub blur: BlurPush,
    /// The screen-space key-light march (`--shadows none` with SSDO).
    pub screen: ShadowParams,
    /// The semantic level choice for this camera.
    pub choice: LevelChoice,
}

impl SsdoParams {
    /// How far (pixels) a pixel's SSDO value reaches back through the blur
    /// and the upsample: each blur axis reads `blur_radius` pixels, or
    /// blocks, then the upsample the blocks next to the pixel's own.
    pub fn blur_reach_px(&self) -> u32 {
        let r = self.blur_radius.max(0) as u32;
        if self.taps.per_block() {
            crate::gpu::consts::SSDO_BLOCK * (r + 2)
        } else {
            r
        }
    }

    /// The hierarchy level weighted more (the blur's, the upsample's and
    /// the outlines' region level).
    pub fn main_level(&self) -> u32 {
        if self.choice.blend >= 0.5 {
            self.choice.level_b
        } else {
            self.choice.level_a
        }
    }
}

/// The scene's scale as the stage sees it: the typical sphere radius and
/// the centre zoom distances are measured from (both world units).
#[derive(Clone, Copy, Debug)]
pub struct SceneScale {
    pub typical_radius: f64,
    pub center: DVec3,
    /// Per-sphere receivers are possible ([`sphere_flags_fit`]); else
    /// spheres of a few pixels take the small per-pixel taps.
    pub sphere_receivers: bool,
}

/// Whether the per-sphere receivers' flags (a bit per id of `slots`) fit
/// one storage buffer of `range` bytes.
pub fn sphere_flags_fit(slots: u32, range: u32) -> bool {
    (slots as u64).div_ceil(32) * 4 <= range as u64
}

/// The stage's switches for a frame (from the render settings).
#[derive(Clone, Copy, Debug)]
pub struct SsdoModes {
    /// Semantic region test (else plain SSDO).
    pub semantic: bool,
    pub blur: bool,
    /// Run on the tile lists (else on every tile).
    pub lists: bool,
}

/// What the stage reads in a frame.
pub struct SsdoInputs<'a> {
    pub screen: &'a ScreenInputs<'a>,
    /// Key-light visibility for the records' reflected light.
    pub lookup: &'a Lookup<'a>,
    pub tiles: Tiles<'a>,
    /// Full-resolution size.
    pub size: (u32, u32),
    /// A full-resolution 4 B/px buffer the blur may use between its two
    /// axes: nothing may read it before the blur writes it (the frame
    /// passes the colour buffer, which shade writes afterwards).
    pub scratch: &'a Buffer,
}

/// What the stage leaves for shade.
pub struct SsdoOutputs<'a> {
    /// Per receiver (pixel or block) result, blurred.
    pub ao: &'a Buffer,
    pub records: &'a Buffer,
    /// Per visible sphere results (with the flags and word bases that
    /// find a sphere's entry), with per-sphere receivers.
    pub sphere_ao: Option<&'a SphereBuffers>,
}

/// Pipelines (made when SSDO is first chosen) and the per-sphere
/// receivers' buffers once a frame has used them.
struct SsdoState {
    pass: SsdoPass,
    blur: BlurPass,
    spheres: Option<SphereBuffers>,
}

impl Destroy for SsdoState {
    fn destroy_with(&mut self, ctx: &Context) {
        self.pass.destroy(ctx);
        self.blur.destroy(ctx);
        self.spheres.destroy_with(ctx);
    }
}

pub struct SsdoStage {
    state: Option<SsdoState>,
    /// Useful hierarchy levels, outermost first (empty: every sphere is
    /// its own region), and the zoom thresholds between them.
    levels: Vec<u32>,
    thresholds: Vec<f64>,
    /// The scene's SCENE_SPEC (kind and batch shift) for the pipelines reading it.
    scene: u32,
}

impl SsdoStage {
    pub fn new(levels: Vec<u32>, thresholds: Vec<f64>, scene: u32) -> Self {
        SsdoStage {
            state: None,
            levels,
            thresholds,
            scene,
        }
    }

    /// Makes the stage's pipelines the first time SSDO is chosen.
    pub fn enable(&mut self, ctx: &Context) -> Result<()> {
        if self.state.is_none() {
            self.state = Some(SsdoState {
                pass: SsdoPass::new(ctx, self.scene)?,
                blur: BlurPass::new(),
                spheres: None,
            });
        }
        Ok(())
    }

    pub fn levels(&self) -> &[u32] {
        &self.levels
    }

    pub fn level_choice(&self, cam: &Camera, scale: SceneScale) -> LevelChoice {
        semantic::choose(
            semantic::zoom_distance(cam, scale.center),
            &self.thresholds,
            &self.levels,
        )
    }

    /// Screen-space radii in world units (at least a few pixels so far
    /// views still sample), the tap set for the spheres' size on screen,
    /// and the semantic level for this camera.
    pub fn params(&self, cam: &Camera, scale: SceneScale) -> SsdoParams {
        let r = scale.typical_radius;
        let px = 1.0 / cam.pixels_per_unit();
        let choice = self.level_choice(cam, scale);
        // the blur's (and the upsample's) region level: the one weighted more
        let level_b = choice.blend >= 0.5;
        let taps = if r / px < SSDO_SPHERE_RADIUS_PX && scale.sphere_receivers {
            SSDO_TAPS_SPHERE
        } else if r / px < SSDO_SMALL_RADIUS_PX {
            SSDO_TAPS_SMALL
        } else {
            SSDO_TAPS_LARGE
        };
        SsdoParams {
            prep: PrepPush {
                level_a: choice.level_a,
                level_b: choice.level_b,
                pad: [0; 2],
            },
            ssdo: SsdoPush {
                r_near: (2.0 * r).max(2.0 * px) as f32,
                // 12 radii: the rank correlation of the ambient visibility
                // with Tachyon's unbounded sky-light AO (tests/look.rs) is
                // 0.90/0.84 at 8 radii, 0.94/0.90 at 12, 0.95/0.93 at 16
                // (1TII / 3P3W): the same taps, so the same cost.
                r_far: (12.0 * r).max(8.0 * px) as f32,
                blend: choice.blend,
                bounce: 1.0,
                level_a: choice.level_a,
                level_b: choice.level_b,
                blur_level_b: level_b as u32,
                pad: 0,
            },
            taps: Taps {
                perspective: cam.fov_deg.is_some(),
                ..taps.0
            },
            blur_radius: taps.1,
            blur: BlurPush {
                sigma_z: (0.5 * r).max(px) as f32,
                level_b: level_b as u32,
                pad: [0; 2],
            },
            screen: ShadowParams {
                f0: [
                    (6.0 * r).max(6.0 * px) as f32,
                    (2.0 * r).max(px) as f32,
                    0.0,
                    0.0,
                ],
                u: [12, 0, 0, 0],
                ..Default::default()
            },
            choice,
        }
    }

    /// Makes the pipelines this frame's modes need (the first time) and,
    /// with per-sphere receivers, buffers for `sphere_count` spheres (ids)
    /// seen in at most `pixels`.
    pub fn prepare(
        &mut self,
        ctx: &Context,
        p: &SsdoParams,
        modes: SsdoModes,
        lookup: &Lookup,
        (sphere_count, pixels): (u32, u64),
    ) -> Result<()> {
        let Some(st) = &mut self.state else {
            return Ok(());
        };
        st.pass
            .prepare(ctx, lookup, modes.semantic, p.taps, modes.lists)?;
        let capacity = (sphere_count.max(1) as u64).min(pixels.max(1)) as u32;
        let fits = |b: &SphereBuffers| b.spheres == sphere_count && b.capacity == capacity;
        // (remade for other counts, or freed if this frame takes other
        // receivers: the LOD lists grew past the renderer's budget for
        // them. The renderer waits for frames in flight when the ids a
        // frame may name change; a frame that only takes other receivers
        // keeps them)
        if !st.spheres.as_ref().is_some_and(fits)
            && let Some(mut old) = st.spheres.take()
        {
            old.destroy(ctx);
        }
        if p.taps.per_sphere() && st.spheres.is_none() {
            st.spheres = Some(SphereBuffers::new(ctx, sphere_count, pixels)?);
        }
        st.blur.prepare(ctx, modes.semantic, modes.lists)
    }

    /// The per-sphere receivers' buffers (tests read their list).
    pub fn sphere_buffers(&self) -> Option<&SphereBuffers> {
        self.state.as_ref().and_then(|s| s.spheres.as_ref())
    }

    /// Records the stage's passes into `t`; returns what shade reads.
    pub fn record<'a>(
        &'a self,
        rec: &mut Recorder,
        io: &SsdoInputs,
        t: &'a SsdoTargets,
        p: &SsdoParams,
        modes: SsdoModes,
    ) -> Result<SsdoOutputs<'a>> {
        let st = self
            .state
            .as_ref()
            .ok_or_else(|| crate::Error::Internal("ssdo: recorded before it was enabled".into()))?;
        let half = half(io.size.0, io.size.1);
        // the per-sphere receivers' buffers, when this frame uses them
        let spheres = st.spheres.as_ref().filter(|_| p.taps.per_sphere());
        st.pass.record_prep(
            rec,
            io.screen,
            io.lookup,
            &PrepIo {
                records: &t.records,
                // (without per-sphere receivers the flags are not written)
                flags: spheres.map_or(t.tap_depth(), |b| &b.flags),
                tap_depth: t.tap_depth(),
            },
            &p.prep,
            &Shape {
                taps: p.taps,
                semantic: modes.semantic,
                grid: half,
                tiles: io.tiles,
            },
        )?;
        if let Some(sb) = spheres {
            st.pass.record_spheres(
                rec,
                io.screen,
                &SphereIo {
                    records: &t.records,
                    tap_depth: t.tap_depth(),
                    spheres: sb,
                },
                &p.ssdo,
                &Shape {
                    taps: p.taps,
                    semantic: modes.semantic,
                    grid: half,
                    tiles: io.tiles,
                },
            )?;
            return Ok(SsdoOutputs {
                ao: &t.ao,
                records: &t.records,
                sphere_ao: Some(sb),
            });
        }
        // receivers: the blocks, or every pixel
        let grid = if p.taps.per_block() { half } else { io.size };
        st.pass.record_ssdo(
            rec,
            io.screen,
            &SsdoIo {
                records: &t.records,
                tap_depth: t.tap_depth(),
                ao: &t.ao,
                keys: t.edge_keys(),
            },
            &p.ssdo,
            &Shape {
                taps: p.taps,
                semantic: modes.semantic,
                grid,
                tiles: io.tiles,
            },
        )?;
        if modes.blur {
            for (axis, input, output) in [
                (Axis::Horizontal, &t.ao, io.scratch),
                (Axis::Vertical, io.scratch, &t.ao),
            ] {
                let bio = BlurIo {
                    globals: io.screen.globals,
                    records: &t.records,
                    keys: t.edge_keys(),
                    input,
                    output,
                };
                let shape = BlurShape {
                    axis,
                    semantic: modes.semantic,
                    radius: p.blur_radius,
                    half: p.taps.per_block(),
                    size: grid,
                    tiles: io.tiles,
                };
                st.blur.record(rec, &shape, &bio, &p.blur)?;
            }
        }
        Ok(SsdoOutputs {
            ao: &t.ao,
            records: &t.records,
            sphere_ao: None,
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.state.destroy_with(ctx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use blur::BLUR_RADII;

    /// Per-sphere receivers keep a flag bit per id in one storage buffer:
    /// past the range (lavapipe's 128 MiB: 2^30 ids, an instanced scene
    /// near 10^9 atoms) spheres of a few pixels take the per-pixel taps.
    #[test]
    fn sphere_receivers_only_where_their_flags_fit() {
        let range = 128u32 << 20;
        assert!(sphere_flags_fit(1 << 30, range));
        assert!(!sphere_flags_fit((1 << 30) + 1, range));
        assert!(sphere_flags_fit(0, 16));
        let cam = Camera::new(
            DVec3::ZERO,
            DVec3::NEG_Z,
            DVec3::Y,
            1000.0,
            None,
            1920,
            1080,
        )
        .expect("camera");
        // spheres of 1.5 units: under a pixel across at 1000 units high
        let stage = SsdoStage::new(Vec::new(), Vec::new(), 0);
        for (fit, per_sphere) in [(true, true), (false, false)] {
            let p = stage.params(
                &cam,
                SceneScale {
                    typical_radius: 1.5,
                    center: DVec3::ZERO,
                    sphere_receivers: fit,
                },
            );
            assert_eq!(p.taps.per_sphere(), per_sphere);
        }
    }

    /// The blur pipelines are made for a fixed set of radii: every tap
    /// set's radius must be one of them.
    #[test]
    fn tap_sets_blur_with_a_prepared_radius() {
        for (_, radius) in [SSDO_TAPS_LARGE, SSDO_TAPS_SMALL] {
            assert!(BLUR_RADII.contains(&radius), "radius {radius}");
        }
    }
}
