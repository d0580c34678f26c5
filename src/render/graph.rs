//! THE frame: every stage of a frame, in order, in one function. Each pass
//! names its steps and the recorder derives the barriers, so adding a pass
//! is its shader, its stage's module (crate::stages), and one call here
//! (plus its row in [`PASSES`], which the README's "How it works" table is
//! checked against).

use super::Resources;
use crate::error::Result;
use crate::passes::screen::ScreenInputs;
use crate::settings::{RasterMode, RenderSettings};
use crate::stages::raster::compute::ViewIndex;
use crate::stages::raster::lod::LightReads;
use crate::stages::raster::{RasterInputs, RasterStage};
use crate::stages::see_through::{SeeThrough, SeeThroughInputs};
use crate::stages::shading::{ShadeInputs, ShadePass};
use crate::stages::shadows::{ShadowInputs, ShadowStage};
use crate::stages::ssdo::{SsdoInputs, SsdoOutputs, SsdoStage};
use crate::vk::{Buffer, Context, Recorder};

/// Every pass a frame may record: its name (= debug label = timestamp
/// scope = JSON name) and what it does.
pub const PASSES: &[(&str, &str)] = &[
    (
        "lod_cull",
        "instanced scenes with levels of detail (`--lod auto`): one invocation per instance (visited by molecule type, and within a type along a Morton curve through the instances, walked backwards where the view looks down it: a SIMD group's batch loops alike, neighbours kept or culled together, and the lists near to far) places its molecule's bounds and chooses the coarsest level whose switch size the instance is within (a prefix of the molecule's atoms in a spatial order, radii grown; kept only where its outline keeps 95 % of the molecule's, or what half a pixel of motion keeps; a coarser one than last frame's only a band below its switch size) and keeps the level for the light, then tests that level's bounds (a sphere, and a box turned with the instance) against the camera's pixel window; of those that passed the occlusion test last frame (after a moving camera's small move: that its last image showed; where the camera has no last tiles to test against, the first frame or a large move: the front instances, the nearest per cell of about a typical instance's radius on screen, `glsl/lod_front.comp`) and that last frame's final depth tiles do not hide whole, each batch of 64 atoms (its bounding sphere, placed with the instance) not hidden behind the depth tiles of last frame's final image is listed with an `atomicAdd` (entry: instance, level, batch), and those hidden behind them are deferred to the late phase, as are the other instances in the window (a batch past the deferral room defers its instance from that batch on), and the rasterizer visits the list, dispatched indirectly, instead of the view's order: a sphere's id is its slot in the lists, so ids stay 32-bit past 2^32 atoms",
    ),
    (
        "raster",
        "one invocation per sphere, the spheres visited in runs of 64, the dispatch's two halves on the two sides of the view and each sorted front to back (sorted again when the camera turns more than 30° or the spheres move): exact ray-sphere test per pixel of the footprint's rectangle (one flat loop; orthographic/perspective a specialization constant), the stored depth read first (a 4-byte texel gather through an R32UI view of the buffer) and the 64-bit `atomicMin(depth<<32 \\| id)` only where nearer; footprints above 1024 px (CPU) / 256 px (GPU) are split into 8-row bands that whole workgroups process (indirect dispatch); an instanced scene's camera list (still or moved a little, a typical atom at most 5 px in radius) is drawn per batch (32 slots an invocation): each atom projected by the instance's linear map (a perspective camera: its tangents from the eye) and tested against last frame's final depth tiles where last frame's view saw it (2x2 tiles of 2, 4 or 32 px), only those not hidden drawn as above; `--raster graphics`: the vertex/fragment impostor baseline, same output",
    ),
    (
        "lod_occlusion",
        "instanced scenes with levels of detail: (a camera moved a little: first the early list's atoms last frame's tiles hid that this frame's early image does not, drawn, since a hole where a pixel changed hands would let every batch over its tile through) the farthest depth of each 2x2 (for atoms), 4x4 and 32x32 pixels (coarser past 4096x4096) of the early camera image (the instances that passed last frame's test), then, dispatched indirectly over what the early phase deferred, one invocation per deferred batch (listed unless hidden behind every tile its rectangle touches: exact, it could not win a pixel) and one per deferred instance (the same test of its level's bounds, then of its batches not drawn early); the instances' results are the next frame's history (two-phase occlusion culling of instances and of batches, as niagara does it for meshlets)",
    ),
    (
        "raster_late",
        "where the camera's early list was tested per atom, the camera still, and this frame's early depth tiles differ from last frame's, that list again: the atoms last frame's tiles hid that this frame's do not; then the rasterizer over the late list (per batch, its atoms tested against this frame's early tiles), into the same visibility buffer; then the final image's depth tiles, the next frame's early test of batches and atoms, and (a moved camera) the instances it shows, the next frame's early list after a small move",
    ),
    (
        "issm_raster",
        "the same rasterizer from the key light into the ISSM (nearest sphere id per light texel), light view fitted to the spheres; like `raster` it visits the spheres in runs of 64, each half of the dispatch on one side of its view and front to back, so the early-depth test rejects more visits before their atomics and lavapipe's two threads get alike halves on different cache lines; an instanced scene's light lists are drawn per batch (32 slots an invocation): the batch's record and transform read once, each atom projected by the transform's linear map, and only the atoms whose disc may hold a texel centre (most are smaller than a texel) placed, keyed and visited as the per-slot raster does, so the same map",
    ),
    (
        "light_cull",
        "instanced scenes with levels of detail, after the camera's raster: the light-map rectangle of the points the camera sees and a bit per light depth tile one of them projects to (per 16x16 pixels, each hit unprojected; one atomic per rectangle word per tile, one per change of depth tile), then one invocation per instance in the light's view with the camera's level, kept if over that rectangle grown by the farthest its shadow lookup reads (ISSM t texels, at least 1, PCF its radius + 1, from the point's texel kept one inside the map: nothing else can shadow a visible point), it passed the light's occlusion test last frame and last frame's light-map tiles do not hide it whole; its batches (also over the rectangle) tested against those tiles as the camera's are, but per tile against the bound's own front over its texel centres (the sphere's depth at its least distance from the tile, tiles its disc misses skipped): one-texel tiles at an atom's scale hide a bound at its rim that its nearest point would not; in see-through frames it runs after `oit_count`, which adds the spheres that made fragments to the points (their points are not in the visibility buffer)",
    ),
    (
        "light_occlusion",
        "the same two-phase occlusion culling in the key light's view (instanced scenes with levels of detail): depth tiles of its early map (one texel each on maps up to 1024², where spheres are smaller than a texel and leave holes; a tile with no marked tile within the lookup's reach hides everything: no visible point reads it), the deferred batches and instances not hidden listed",
    ),
    (
        "light_raster_late",
        "the rasterizer over the light's late list (per batch, as `issm_raster`), into the same light map; then its depth tiles for the next frame",
    ),
    (
        "issm_resolve",
        "per light texel, its sphere's light-space centre and radius (16 bytes): the lookup reads one texel per patch texel instead of an id and the sphere it names",
    ),
    (
        "deep_count",
        "deep shadow lists (after deep shadow maps on the GPU), 8x8-texel tiles, one 64-invocation workgroup each: count the entries per texel (every sphere whose light-space disk overlaps the texel square), the spheres visited in the light's order (front to back), so each texel's entries arrive nearly sorted",
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
        "baseline (after the Metal protein viewer paper): depth shadow map from the same compute rasterizer (sphere surface depth)",
    ),
    (
        "osm_raster",
        "baseline (after the WebGL particle paper): opacity shadow maps, 64 depth slices of fixed-point optical depth -ln(1-α)",
    ),
    (
        "osm_prefix",
        "prefix sum of the optical depth across the slices",
    ),
    (
        "oit_count",
        "see-through spheres (alpha below 1; the camera raster draws the opaque ones only; on an instanced scene with levels of detail, first the batches of the camera's early and late LOD lists that hold see-through atoms are picked, `glsl/oit_pick.comp`, and only those visited; with an orthographic camera per batch, each atom tested against the final opaque image's depth tiles, the candidates kept as a bit mask per 32 slots for the fill): the band skeleton of the raster over them, an exact ray-sphere test per pixel, and a per-pixel `atomicAdd` where the front hit lies in front of the opaque surface",
    ),
    (
        "oit_alloc",
        "per 8x8-pixel tile (one invocation each: a loop, not a barrier-bound 64-lane scan, a tenth of the time on lavapipe), a running sum of the counts and one pool `atomicAdd`: each pixel's fragments contiguous from its head; overflow detected, the pool grown and the frame re-run (the deep lists' count → allocate → fill in the camera view)",
    ),
    (
        "oit_fill",
        "the same enumeration as the count, writing (depth key, sphere id) at head + an atomic per-pixel cursor; `shade` takes each pixel's fragments in depth order (selection scans of its run, each keeping the least 8 after the last taken, stopping once the transmittance is below 1/1024) and composites them, lit, front to back over the opaque surface",
    ),
    (
        "coverage",
        "which 16x16-pixel regions show a sphere (256 id fetches per region): two lists with their indirect dispatch arguments; `ssdo_prep`, `ssdo`, `blur_*` and `shade` run their full shader on the covered regions and a variant compiled to the background path alone on the others (lavapipe runs a branch no lane takes), so background costs about a buffer write",
    ),
    (
        "ssdo_prep",
        "half resolution: per 2x2 block one representative covered pixel (found from the ids), its surface rebuilt from (pixel ray, sphere id), key-light visibility by the technique's lookup, packed into a 16-byte record (view depth, octahedral normal, region hashes, reflected key light); with per-sphere SSDO it also flags every sphere seen",
    ),
    (
        "ssdo",
        "receivers rebuilt exactly from (pixel ray, sphere id): every covered pixel when spheres are under 16 px on screen, else one per 2x2 block (its representative); 8 directions from a sample table in a uniform buffer (Halton + Malley), rotated per receiver; a near sample and a far 5-step search per direction (visibilities multiplied); a tap reads the 4-byte depth word of the visibility key (exact occluder depth) and only the first occluder's block record (regions, normal, reflected light for the bounce); occluder = closer to the viewer and (semantic) in another region at the active hierarchy level, blended between two levels by zoom; per pixel it also writes the blur's edge key; counts and the size thresholds measured against a ray-traced AO. Spheres under 3 px on screen: per visible sphere instead (the spheres `ssdo_prep` flagged (one bit each), listed with one atomic per 32-sphere flag word, an indirect dispatch): 32 directions (8 azimuths x 4 elevations over the viewer-facing sphere of directions) searched from the surface point facing each, the 4 elevations of an azimuth sharing its 12 taps along one screen line, the line's first occluder's record for regions and bounce; the directions' occluder weights as band-2 spherical harmonics of their cosine-lobe sum (9 fixed-point coefficients) and the bounce in 16 bytes per sphere, no blur",
    ),
    (
        "blur_h",
        "separable bilateral blur (2 taps each side) of the packed 4-byte SSDO result (near/far visibility, bounce, screen-space shadow): per pixel with weights from 4-byte edge keys `ssdo` writes (view distance, region hash), or per block from the blocks' records (depth, normal, region); horizontal, into the colour buffer (free until `shade`)",
    ),
    ("blur_v", "the same, vertical, back into the SSDO result"),
    (
        "shade",
        "full resolution, covered pixels: surface from (pixel ray, sphere id); key-light lookup compiled in per technique (ISSM: exact light-ray tests against the spheres of the 3x3 patch (t = 1) or (2t+1)², soft `(1 - s'/s_eff)^x`; deep: exact transmittance walk of the texel's list; sm-pcf: biased PCF; osm: interpolated optical depth; none+SSDO: screen-space march); the pixel's SSDO result (per block: upsampled from the 4 nearest blocks, bilinear × depth, normal and region agreement; per sphere: its directions' cosine-lobe sum at the pixel's normal, 9 spherical-harmonic terms over the same with every weight 1); key (5 % of its diffuse kept in full shadow), sky light × ambient visibility, occluded fill and rim, half the bounce, a filmic curve on the luminance (hue kept) into the colour buffer; the shadow and ao AOVs (unorm16) only when asked for",
    ),
    (
        "readback",
        "the words the host checks after a frame (the raster's band-job overflow flag; the deep lists', see-through fragments' and LOD lists' counters; the opacity maps' band flag) copied into the frame slot's host-visible buffer: read once its fence signals, with no transfer of its own, so the viewer's pipelined frames are checked too",
    ),
];

/// The pass names, in [`PASSES`] order.
pub fn pass_names() -> &'static [&'static str] {
    static NAMES: std::sync::OnceLock<Vec<&'static str>> = std::sync::OnceLock::new();
    NAMES.get_or_init(|| {
        #[allow(unused_mut)]
        let mut names: Vec<_> = PASSES.iter().map(|p| p.0).collect();
        #[cfg(test)]
        names.push(crate::stages::shadows::constant::NAME);
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

/// The stages a frame runs, made with the renderer and destroyed with it.
/// A new stage is its field here, its line in `new` and `destroy`, and its
/// call in [`Resources::record_frame`] below.
pub(crate) struct Stages {
    pub raster: RasterStage,
    /// Made the first time a frame has see-through spheres.
    pub see_through: Option<SeeThrough>,
    pub shadows: ShadowStage,
    pub ssdo: SsdoStage,
    pub shade: ShadePass,
}

impl Stages {
    /// `levels` and `thresholds`: the semantic SSDO levels of the scene;
    /// `scene`: its kind (passes::scene), every scene pipeline's SCENE_KIND;
    /// `typical_radius`: its typical sphere radius.
    pub fn new(
        ctx: &Context,
        settings: &RenderSettings,
        levels: Vec<u32>,
        thresholds: Vec<f64>,
        scene_buffers: &mut crate::passes::scene::SceneBuffers,
        typical_radius: f32,
    ) -> Result<Self> {
        let scene = scene_buffers.spec;
        Ok(Stages {
            raster: RasterStage::new(
                ctx,
                settings.raster == RasterMode::Graphics,
                scene_buffers,
                &settings.lod,
                typical_radius,
                settings.band_jobs,
            )?,
            see_through: None,
            shadows: ShadowStage::new(),
            ssdo: SsdoStage::new(levels, thresholds, scene),
            shade: ShadePass::new(scene),
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.raster.destroy(ctx);
        if let Some(s) = &mut self.see_through {
            s.destroy(ctx);
        }
        self.shade.destroy(ctx);
        self.shadows.destroy(ctx);
        self.ssdo.destroy(ctx);
    }
}

crate::impl_destroy!(Stages);

impl Resources {
    /// Records one frame: the stages in order, each one's outputs wired to
    /// the next ones' inputs.
    pub(super) fn record_frame(
        &self,
        settings: &RenderSettings,
        params: &super::FrameParams,
        globals: &Buffer,
        readback: &Buffer,
        rec: &mut Recorder,
    ) -> Result<()> {
        let t = &self.targets;
        let cam = &settings.camera;
        let size = (t.width, t.height);
        let see = self
            .stages
            .see_through
            .as_ref()
            .filter(|_| params.see_through);

        // How shade (and the light's cull) read the key light's visibility.
        let lookup = self.lookup(settings, &params.ssdo);

        // Levels of detail and culling (`lod_lists`).
        self.stages.raster.no_cull();
        let lod = self.lod_lists(settings)
            && self.stages.raster.record_cull(
                rec,
                globals,
                &self.scene,
                cam.fov_deg.is_some(),
                [&self.globals.cam, &self.globals.light],
            )?;

        let raster_in = RasterInputs {
            globals,
            scene: &self.scene,
            perspective: cam.fov_deg.is_some(),
            image: (cam.width, cam.height),
            size,
            see_through: see.is_some(),
            lod,
            pixels_per_unit: cam.height as f64 / cam.view_height,
        };
        self.stages.raster.record(rec, &raster_in, &t.raster)?;
        // The key light's cull (after the camera's and, in see-through
        // frames, after the fragments' count, which adds the light's
        // receivers of its fragments: their points are not in the
        // visibility buffer).
        let light_reads = match (
            lod,
            settings.shadows.draws_light_view(),
            self.stages.shadows.light(),
        ) {
            (true, true, Some(light)) => Some(LightReads {
                reach: lookup.reach(),
                slack: lookup.depth_slack(),
                map: (light.width, light.height),
                preset: false,
            }),
            _ => None,
        };
        if lod {
            self.stages.raster.record_late(rec, &raster_in, &t.raster)?;
        }

        let mut preset = false;
        let see_out = match see {
            Some(s) => {
                preset = s.record(
                    rec,
                    &SeeThroughInputs {
                        globals,
                        scene: &self.scene,
                        vis: &t.raster.vis,
                        order: self.stages.raster.compute.order(ViewIndex::Camera),
                        perspective: cam.fov_deg.is_some(),
                        lod: if lod {
                            self.stages.raster.camera_lists()
                        } else {
                            None
                        },
                        tiles: if lod {
                            self.stages.raster.final_camera_tiles(size)
                        } else {
                            None
                        },
                        receivers: light_reads.and_then(|r| {
                            self.stages
                                .raster
                                .lod
                                .as_ref()
                                .map(|l| l.light_region(r.map, r.slack))
                        }),
                    },
                    size,
                )?;
                Some(s.outputs()?)
            }
            None => None,
        };
        if let Some(reads) = light_reads {
            let reads = LightReads { preset, ..reads };
            self.stages
                .raster
                .record_light_cull(rec, &raster_in, &t.raster, reads)?;
        }

        self.stages.shadows.record(
            rec,
            &ShadowInputs {
                globals,
                scene: &self.scene,
                vis: &t.raster.vis,
                opacity: settings.opacity,
                pixels: t.pixels,
                raster: &self.stages.raster.compute,
                lod: if lod {
                    self.stages.raster.lod.as_ref()
                } else {
                    None
                },
            },
        )?;

        let tiles = self.stages.raster.record_tiles(
            rec,
            globals,
            &t.raster,
            see_out.map(|o| o.counts),
            size,
            settings.tile_lists,
        )?;

        let ssdo_params = &params.ssdo;
        let screen = ScreenInputs {
            globals,
            vis: &t.raster.vis,
            scene: &self.scene,
        };
        let ssdo = if settings.ssdo_on() {
            self.stages.ssdo.record(
                rec,
                &SsdoInputs {
                    screen: &screen,
                    lookup: &lookup,
                    tiles,
                    size,
                    // shade writes colour after the blur is done with it
                    scratch: &t.shade.color,
                },
                &t.ssdo,
                ssdo_params,
                super::ssdo_modes(settings),
            )?
        } else {
            // (bound, unread)
            SsdoOutputs {
                ao: &t.ssdo.ao,
                records: &t.ssdo.records,
                sphere_ao: None,
            }
        };

        self.stages.shade.record(
            rec,
            &ShadeInputs {
                screen: &screen,
                lookup: &lookup,
                ssdo: &ssdo,
                tiles,
                see_through: see_out,
            },
            &t.shade,
            &params.shade,
            size,
        )?;

        rec.pass("readback", |p| {
            use super::frame::readback as w;
            let (buf, at) = self.stages.raster.compute.bands_flag();
            p.copy_to_host(buf, at, readback, w::RASTER_BANDS as u64 * 4, 4);
            if let Some((buf, at, words)) = self.stages.shadows.readback() {
                let n = words.min(w::LIGHT_COUNT as u64) * 4;
                p.copy_to_host(buf, at, readback, w::LIGHT as u64 * 4, n);
            }
            if let Some((buf, words)) = see.map(|s| s.readback()) {
                let n = words.min(w::SEE_THROUGH_COUNT as u64) * 4;
                p.copy_to_host(buf, 0, readback, w::SEE_THROUGH as u64 * 4, n);
            }
            if let Some(buf) = self.stages.raster.lod_counters() {
                p.copy_to_host(buf, 0, readback, w::LOD as u64 * 4, w::LOD_COUNT as u64 * 4);
            }
            Ok(())
        })
    }
}
