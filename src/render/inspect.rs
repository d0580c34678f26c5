//! Read-backs and state of a renderer (tests, debugging, the JSON
//! record): [`super::Renderer::inspect`].

use super::Renderer;
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::passes::scene::SceneGeom;
use crate::semantic::LevelChoice;
use crate::stages::raster::compute::ViewIndex;
use crate::stages::shadows::deep::{DeepShadows, DeepStats};
use crate::stages::shadows::issm::Issm;
use crate::stages::shadows::osm::OpacityShadows;
use crate::stages::shadows::shadow_map::ShadowMap;
use crate::stages::ssdo::passes::Receivers;
use std::collections::BTreeMap;

/// What an instanced scene holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstancingCounts {
    pub instances: u64,
    pub molecules: u64,
    pub unique_atoms: u64,
    /// A nested scene's placements.
    pub placements: Option<u64>,
}

/// A renderer seen from outside, borrowed.
pub struct Inspect<'r, 'c> {
    pub(super) r: &'r Renderer<'c>,
}

impl<'r> Inspect<'r, '_> {
    /// Sphere ids a per-sphere pass covers (instanced scenes: every slot
    /// of the batches).
    pub fn sphere_count(&self) -> u32 {
        self.r.res.scene.slots
    }

    /// Represented spheres (instanced: expanded).
    pub fn represented(&self) -> u64 {
        self.r.res.geom.len()
    }

    /// Spheres the last frame's camera drew: after culling and level of
    /// detail when its LOD cull ran (a tiled image: summed over its tiles,
    /// a margin's spheres in each tile that draws them), else every
    /// represented sphere.
    pub fn spheres_drawn(&self) -> Result<u64> {
        let tiled = self.r.settings.window.and(self.r.tiles_drawn);
        Ok(self.lod_counts()?.map_or(self.represented(), |c| {
            tiled.unwrap_or(c.camera_spheres as u64)
        }))
    }

    /// What the last frame's LOD cull kept (None: it did not run).
    pub fn lod_counts(&self) -> Result<Option<crate::stages::raster::lod::LodCounts>> {
        let cull = self.r.res.stages.raster.last_cull();
        cull.map(|l| l.counts(self.r.ctx)).transpose()
    }

    /// Whether the last frame drew the camera's LOD lists per batch, each
    /// atom tested against depth tiles (else per slot).
    pub fn camera_per_batch(&self) -> bool {
        self.r.res.stages.raster.camera_per_batch()
    }

    /// Batches each LOD list holds now (None: the last frame drew none).
    pub fn lod_list_capacity(&self) -> Option<u32> {
        self.r.res.stages.raster.last_cull().map(|l| l.capacity())
    }

    /// Each instance's level of detail in the last frame (None: the cull
    /// did not run).
    pub fn lod_levels(&self) -> Result<Option<Vec<u32>>> {
        let cull = self.r.res.stages.raster.last_cull();
        cull.map(|l| l.levels(self.r.ctx)).transpose()
    }

    /// The instances of the last frame's camera early list, one per batch
    /// listed (None: the cull did not run).
    pub fn lod_camera_early_instances(&self) -> Result<Option<Vec<u32>>> {
        let (Some(cull), Some(lod)) = (self.r.res.stages.raster.last_cull(), &self.r.res.scene.lod)
        else {
            return Ok(None);
        };
        cull.camera_early_instances(self.r.ctx, lod).map(Some)
    }

    /// Entries of the rasterizers' band job list (grown where a frame
    /// asked more).
    pub fn band_job_capacity(&self) -> u32 {
        self.r.res.stages.raster.compute.job_capacity()
    }

    /// Each instance's camera flags of the last frame (VISIBLE_PASSED,
    /// VISIBLE_SHOWN: src/gpu_consts.rs; None: the cull did not run).
    pub fn lod_camera_flags(&self) -> Result<Option<Vec<u32>>> {
        let cull = self.r.res.stages.raster.last_cull();
        cull.map(|l| l.camera_flags(self.r.ctx)).transpose()
    }

    /// Scene ids to input indices (None: the same; rules hid nothing).
    pub fn id_map(&self) -> Option<std::sync::Arc<crate::scene::paint::IdMap>> {
        self.r.res.ids.clone()
    }

    /// Whether the scene is an instanced model drawn expanded.
    pub fn expanded(&self) -> bool {
        self.r.res.expanded
    }

    /// An instanced scene's counts (None for plain scenes).
    pub fn instancing(&self) -> Option<InstancingCounts> {
        match &self.r.res.geom {
            SceneGeom::Plain(_) => None,
            SceneGeom::Instanced(i) => Some(InstancingCounts {
                instances: i.instance_molecule.len() as u64,
                molecules: i.molecules.len() as u64,
                // (the scene's own atoms, not the coarse levels' copies)
                unique_atoms: i.molecules.iter().map(|m| m.1 as u64).sum(),
                placements: self.r.res.placements,
            }),
        }
    }

    /// The key light's view the shadows last fitted (None: no technique
    /// with a light view).
    pub fn light_view(&self) -> Option<crate::camera::Camera> {
        self.r.res.stages.shadows.light()
    }

    /// Whether the key light's view has its sphere order for the current
    /// spheres (sorted by the first frame that draws that view).
    pub fn light_order_ready(&self) -> bool {
        self.r
            .res
            .stages
            .raster
            .compute
            .order_ready(ViewIndex::Light)
    }

    pub fn is_bgra(&self) -> bool {
        self.r.res.bgra
    }

    /// Whether the light cache is on.
    pub fn light_cache(&self) -> bool {
        self.r.res.stages.shadows.cache()
    }

    /// Whether the next frame reuses the light-space structure.
    pub fn light_cached(&self) -> bool {
        self.r.res.stages.shadows.cached()
    }

    pub fn pixels(&self) -> u64 {
        self.r.res.targets.pixels
    }

    /// Device memory of this renderer's buffers by class (bytes requested,
    /// before allocator alignment): what a user sizing a data set needs to
    /// know is which part grows with spheres, pixels or the light map.
    pub fn memory_by_class(&self) -> BTreeMap<String, u64> {
        let mut m = BTreeMap::new();
        let mut add = |class: &str, bytes: u64| {
            if bytes > 0 {
                *m.entry(class.to_string()).or_insert(0) += bytes;
            }
        };
        let (order, bands, light_cull) = self.r.res.stages.raster.memory();
        for (class, bytes) in self.r.res.scene.memory() {
            add(class, bytes);
        }
        add("scene", order);
        add("light_cull", light_cull);
        add(
            "uniforms",
            self.r.slots.iter().map(|f| f.globals.size).sum::<u64>(),
        );
        let (vis, gbuffer, ssdo) = self.r.res.targets.memory();
        add("visibility", vis + bands);
        add("gbuffer", gbuffer);
        add("ssdo", ssdo);
        if let Some(b) = self.r.res.stages.ssdo.sphere_buffers() {
            add("ssdo_spheres", b.bytes());
        }
        for (class, bytes) in self.r.res.stages.shadows.memory() {
            add(class, bytes);
        }
        if let Some(s) = &self.r.res.stages.see_through {
            add("see_through", s.memory_bytes());
        }
        m
    }

    /// The see-through stage (made the first frame that had see-through
    /// spheres).
    pub fn see_through(&self) -> Option<&'r crate::stages::see_through::SeeThrough> {
        self.r.res.stages.see_through.as_ref()
    }

    /// The last image's see-through fragment lists: its tiles' summed when
    /// tiled (None: no see-through spheres this frame).
    pub fn see_through_stats(&self) -> Option<crate::stages::see_through::SeeThroughStats> {
        let on = self.r.res.see_through(&self.r.settings);
        self.see_through()
            .filter(|_| on)
            .and_then(|s| s.image_stats())
    }

    /// Visibility buffer (depth|id per pixel), without the guard words;
    /// ids are indices in input (expanded) order, as the id AOV names them
    /// (below 2^32 atoms: [`Inspect::read_ids`] names any).
    pub fn read_vis(&self) -> Result<Vec<u64>> {
        if !self.ids_fit() {
            return Err(Error::Input(format!(
                "{} atoms: visibility keys name visible atoms by a 32-bit index, so they stop \
                 at 2^32 atoms (read_keys and read_ids name them past)",
                self.represented()
            )));
        }
        let mut v = self.read_vis_slots()?;
        if let SceneGeom::Instanced(_) = &self.r.res.geom {
            // the depth word, then the expanded index below it
            let ids = self.expanded_of(&v)?;
            for (k, e) in v.iter_mut().zip(ids) {
                if let Some(e) = e {
                    *k = (*k & !0xFFFF_FFFF) | e;
                }
            }
        }
        Ok(v)
    }

    /// The visibility keys for an image: `read_vis`'s, or past 2^32 atoms
    /// the GPU's keys (depth word, slot) with each pixel's expanded index +
    /// 1 (0: background) beside them (`Image::wide_ids`).
    pub fn read_keys(&self) -> Result<(Vec<u64>, Option<Vec<u64>>)> {
        if self.ids_fit() {
            return Ok((self.read_vis()?, None));
        }
        let slots = self.read_vis_slots()?;
        let ids = self.expanded_of(&slots)?;
        let wide = ids.into_iter().map(|e| e.map_or(0, |e| e + 1)).collect();
        Ok((slots, Some(wide)))
    }

    /// The expanded index of each pixel's visible sphere (None:
    /// background), past 2^32 atoms too.
    pub fn read_ids(&self) -> Result<Vec<Option<u64>>> {
        self.expanded_of(&self.read_vis_slots()?)
    }

    /// The expanded indices the keys `vis` (as the GPU holds them) name.
    fn expanded_of(&self, vis: &[u64]) -> Result<Vec<Option<u64>>> {
        let geom = &self.r.res.geom;
        // (ids are the LOD lists' slots in a frame that drew them)
        let scene = &self.r.res.scene;
        let lists: Option<Vec<[u32; 2]>> = match &scene.lod {
            Some(l) if scene.listed.get() => {
                Some(l.lists.download_pod(self.r.ctx, 0, l.list_entries as u64)?)
            }
            _ => None,
        };
        vis.iter()
            .map(|&k| {
                if k == crate::gpu::VIS_EMPTY {
                    return Ok(None);
                }
                let slot = k as u32;
                match &lists {
                    Some(l) => geom.listed_id(l, slot),
                    None => geom.expanded_id(slot),
                }
                .map(Some)
                .ok_or_else(|| Error::Internal(format!("slot {slot} names no sphere")))
            })
            .collect()
    }

    /// Whether every represented sphere's expanded index fits the 32 bits
    /// below a visibility key's depth ([`Inspect::read_vis`]).
    pub fn ids_fit(&self) -> bool {
        self.represented() <= u32::MAX as u64
    }

    /// The visibility buffer as the GPU holds it (instanced scenes: slot ids).
    pub fn read_vis_slots(&self) -> Result<Vec<u64>> {
        self.r
            .res
            .targets
            .raster
            .vis
            .download_pod(self.r.ctx, 0, self.pixels())
    }

    /// The guard words after the visibility buffer (must stay GUARD_PATTERN).
    pub fn read_vis_guard(&self) -> Result<Vec<u64>> {
        self.r.res.targets.raster.vis.download_pod(
            self.r.ctx,
            self.pixels(),
            crate::stages::raster::compute::VIS_GUARD_WORDS,
        )
    }

    /// The colour buffer: one RGBA8 word per pixel, or two (RGBA16) with
    /// `look.color16`.
    pub fn read_color(&self) -> Result<Vec<u32>> {
        let words = if self.r.res.targets.shade.wide { 2 } else { 1 };
        self.r
            .res
            .targets
            .shade
            .color
            .download_pod(self.r.ctx, 0, self.pixels() * words)
    }

    /// Visible positions: xyz world (the shader's reconstruction from the
    /// pixel ray and the sphere, redone on the CPU in f32), w the depth key
    /// (-1 = background).
    pub fn read_gpos(&self) -> Result<Vec<[f32; 4]>> {
        let cam = &self.r.settings.camera;
        let vis = self.read_vis()?;
        Ok(vis
            .iter()
            .enumerate()
            .map(|(i, &k)| {
                if k == crate::gpu::VIS_EMPTY {
                    return [0.0, 0.0, 0.0, -1.0];
                }
                let Some(s) = self.r.res.geom.sphere(k & 0xFFFF_FFFF) else {
                    return [0.0, 0.0, 0.0, -1.0];
                };
                let win = self.r.settings.window();
                let (x, y) = (i as u32 % win.width + win.x, i as u32 / win.width + win.y);
                let c = glam::DVec3::new(s[0] as f64, s[1] as f64, s[2] as f64);
                let p = crate::reference::visible_point(cam, x, y, c, s[3] as f64);
                [
                    p.x as f32,
                    p.y as f32,
                    p.z as f32,
                    f32::from_bits((k >> 32) as u32),
                ]
            })
            .collect())
    }

    /// The shadow and ao AOVs as shade wrote them (unorm16 each).
    pub(crate) fn read_aov(&self) -> Result<Vec<u32>> {
        if !self.r.res.targets.shade.aovs {
            return Err(Error::Input(
                "the shadow and ao AOVs are off: set RenderSettings::aovs or call set_aovs(true) \
                 before rendering"
                    .into(),
            ));
        }
        self.r
            .res
            .targets
            .shade
            .aov
            .download_pod(self.r.ctx, 0, self.pixels())
    }

    /// Key-light visibility per pixel (1 on background), 16-bit precision.
    pub fn read_shadow(&self) -> Result<Vec<f32>> {
        Ok(self
            .read_aov()?
            .into_iter()
            .map(|a| (a & 0xFFFF) as f32 / 65535.0)
            .collect())
    }

    /// Ambient visibility per pixel as shade used it (x: after the blur
    /// and the upsample; the bounce, yzw, is not kept at full resolution
    /// and reads 0), 16-bit precision; 1 without SSDO.
    pub fn read_ambient(&self) -> Result<Vec<[f32; 4]>> {
        Ok(self
            .read_aov()?
            .into_iter()
            .map(|a| [(a >> 16) as f32 / 65535.0, 0.0, 0.0, 0.0])
            .collect())
    }

    /// The last frame's tile lists (stages/raster/coverage.rs, TL_* words), whole.
    pub fn read_tile_lists(&self) -> Result<Vec<u32>> {
        let b = &self.r.res.targets.raster.tiles;
        b.download_pod(self.r.ctx, 0, b.size / 4)
    }

    /// The last frame's per-sphere SSDO list (the spheres `ssdo_prep`
    /// flagged, in list order) and the workgroups counted for it; `None`
    /// without per-sphere buffers (tests).
    pub fn read_sphere_list(&self) -> Result<Option<(Vec<u32>, u32)>> {
        let Some(sb) = self.r.res.stages.ssdo.sphere_buffers() else {
            return Ok(None);
        };
        let counters: Vec<u32> = sb.counters.download_pod(self.r.ctx, 0, 4)?;
        let n = counters[crate::gpu::consts::S_LISTED as usize];
        if n > sb.spheres {
            return Err(Error::Internal(format!(
                "per-sphere list: {n} entries for {} spheres",
                sb.spheres
            )));
        }
        let list = sb.list.download_pod(self.r.ctx, 0, n as u64)?;
        Ok(Some((
            list,
            counters[crate::gpu::consts::S_GROUPS as usize],
        )))
    }

    /// The half-resolution SSDO records of the last frame (tests).
    pub fn read_records(&self) -> Result<Vec<crate::stages::ssdo::record::Record>> {
        let (hw, hh) = self.r.res.targets.half();
        let raw: Vec<[u32; 4]> =
            self.r
                .res
                .targets
                .ssdo
                .records
                .download_pod(self.r.ctx, 0, hw as u64 * hh as u64)?;
        Ok(raw
            .into_iter()
            .map(crate::stages::ssdo::record::Record::unpack)
            .collect())
    }

    /// The ISSM light view and patch half-size t, when ISSM is active.
    pub fn issm_info(&self) -> Option<(Camera, u32)> {
        self.r
            .res
            .stages
            .shadows
            .technique::<Issm>()
            .map(|s| (s.light, s.push.t as u32))
    }

    pub fn read_issm(&self) -> Result<Option<Vec<u64>>> {
        self.r
            .res
            .stages
            .shadows
            .technique::<Issm>()
            .map(|s| s.read_map(self.r.ctx))
            .transpose()
    }

    /// The baseline depth shadow map, when `--shadows sm-pcf` is active.
    pub fn shadow_map(&self) -> Option<&'r ShadowMap> {
        self.r.res.stages.shadows.technique::<ShadowMap>()
    }

    /// The baseline opacity shadow maps, when `--shadows osm` is active.
    pub fn opacity_shadows(&self) -> Option<&'r OpacityShadows> {
        self.r.res.stages.shadows.technique::<OpacityShadows>()
    }

    /// The deep shadow lists, when `--shadows deep` is active.
    pub fn deep(&self) -> Option<&'r DeepShadows> {
        self.r.res.stages.shadows.technique::<DeepShadows>()
    }

    /// Stats of the last frame's deep lists (after any pool growth).
    pub fn deep_stats(&self) -> Option<DeepStats> {
        self.deep().and_then(|d| d.stats.clone())
    }

    /// SSDO's far search radius for the current camera (world units): the
    /// reach of its occlusion (the AO reference uses the same).
    pub fn ssdo_far_radius(&self) -> f64 {
        self.r.res.ssdo_params(&self.r.settings).ssdo.r_far as f64
    }

    /// Who receives SSDO for the current camera: per 2x2 block (spheres
    /// large on screen), per pixel, or per visible sphere (a few pixels
    /// wide).
    pub fn ssdo_receivers(&self) -> Receivers {
        self.r.res.ssdo_params(&self.r.settings).taps.receivers
    }

    /// The semantic level choice of this frame, when SSDO runs.
    pub fn level_choice(&self) -> Option<LevelChoice> {
        self.r
            .settings
            .ssdo_on()
            .then(|| self.r.res.ssdo_params(&self.r.settings).choice)
    }
}
