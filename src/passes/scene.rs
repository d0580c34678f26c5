//! The scene on the GPU (glsl/scene.glsl): plain spheres, or an instanced
//! scene's molecule atoms (stored once), instance transforms and the
//! batches that name a sphere by slot; and the CPU copy of its geometry
//! that light views and view orders are fitted to ([`SceneGeom`]).
//!
//! Every pipeline whose shader includes scene.glsl gets the scene's
//! [`SceneBuffers::spec`] as its specialization constant SCENE_SPEC (kind
//! and batch shift) and its buffers by name ([`SCENE_GEOMETRY`],
//! [`SCENE_ATTRIBUTES`]).

use crate::error::{Error, Result};
use crate::gpu::consts::{
    BATCH_COARSE, BATCH_EMPTY, BATCH_INSTANCE_BITS, BATCH_INSTANCE_MASK, BATCH_TYPE_MASK,
    CULL_CHUNK_BATCHES, LEVEL_MAPPED, MAX_BATCH_SHIFT, MAX_LOD_LEVELS, MIN_BATCH_SHIFT, NO_LEVEL,
    SCENE_AFFINE, SCENE_PLAIN, SCENE_RIGID,
};
use crate::gpu::{GpuBatch, GpuSphere, SphereAttr};
use crate::scene::Scene;
use crate::scene::instanced::extremes::Extremes;
use crate::scene::instanced::lod::{LodFit, MoleculeLod, level_alpha, morton_cells, on_every_core};
use crate::scene::instanced::{LevelKind, Transforms};
use crate::vk::pipeline::{Binding, texel};
use crate::vk::{Buffer, Context};
use ash::vk::Format;
use glam::DVec3;

/// What scene.glsl reads for geometry: `scene_sphere`, `scene_index`.
pub const SCENE_GEOMETRY: [Binding; 6] = [
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("batchTex", Format::R32G32_UINT),
    texel("instanceTex", Format::R32G32B32A32_SFLOAT),
    texel("originTex", Format::R32_UINT),
    texel("instanceRowTex", Format::R32G32_UINT),
    texel("levelTex", Format::R32G32B32A32_UINT),
];

/// What scene.glsl reads for colours and regions (SCENE_ATTRIBUTES).
pub const SCENE_ATTRIBUTES: [Binding; 3] = [
    texel("attrTex", Format::R32_UINT),
    texel("colorTex", Format::R32_UINT),
    texel("moleculeTex", Format::R32_UINT),
];

/// Most slots a batch table may have: ids are 32-bit and ~0 means "no
/// sphere". The static table (every atom of every instance) is bound by
/// it; the LOD lists, whose slots are list positions, are not.
pub const MAX_SLOTS: u64 = u32::MAX as u64 - (1 << MAX_BATCH_SHIFT);

/// The scene's buffers on the device.
pub struct SceneBuffers {
    /// SCENE_PLAIN, SCENE_RIGID or SCENE_AFFINE in the low byte, the batch
    /// shift in the next (the SCENE_SPEC constant of the scene's pipelines).
    pub spec: u32,
    /// Plain: centre and radius per sphere. Instanced: the molecule atoms.
    pub spheres: Buffer,
    /// Plain: 4 region words per sphere. Instanced: the chain of each atom.
    pub attrs: Buffer,
    /// One RGBA8 word per sphere / atom.
    pub colors: Buffer,
    /// Instanced: the static batch table (8 B per 2^shift slots: every
    /// instance's full detail, [`static_entries`]); with levels of detail
    /// made for the first frame that draws full detail
    /// ([`SceneBuffers::ensure_static`]), 16 unread bytes until then.
    pub batches: Buffer,
    /// The static table is made (`batches` holds it).
    pub static_made: bool,
    /// Instanced: [`BatchTables::rows`] (8 B per instance).
    pub rows: Buffer,
    /// Instanced: [`BatchTables::levels`] (16 B per molecule type and level).
    pub levels: Buffer,
    /// Instanced: the transforms (32 B rigid, 48 B affine per instance).
    pub instances: Buffer,
    /// Instanced: the tree regions of each molecule type (16 B each).
    pub molecules: Buffer,
    /// Instanced with levels of detail: the origin of each coarse atom
    /// (4 B per stored atom; 16 B unread otherwise).
    pub origins: Buffer,
    /// Ids a per-sphere dispatch over the static table covers: the
    /// spheres, or every slot of its batches (0 before it is made).
    pub slots: u32,
    /// Slots of every level of every instance (saturated at u32::MAX):
    /// what SSDO's per-sphere receivers are sized by (src/render/mod.rs).
    pub all_level_slots: u32,
    /// The levels of detail (instanced scenes, `--lod auto`).
    pub lod: Option<LodBuffers>,
    /// This frame draws the LOD lists: they are the batch table
    /// (`geometry`), and ids are their slots (set by the renderer for
    /// each frame).
    pub listed: std::cell::Cell<bool>,
    /// Atoms of the scene's own (`Scene::spheres`); the colour buffer holds
    /// them, then the coarse copies (`coarse_source`).
    base_atoms: u32,
    /// Per coarse stored atom: what it copies and stands for.
    coarse_source: CoarseSources,
}

/// The coarse copies' sources: their colours follow the atoms' ones
/// ([`CoarseSources::colour`]).
#[derive(Default)]
struct CoarseSources {
    /// Per coarse stored atom: the stored atom it copies, its level's
    /// alpha exponent ([`MoleculeLod::alpha_exponent`]) and the run of
    /// `runs` it stands for (start, length: [`MoleculeLod::stands_for`]).
    copies: Vec<(u32, f32, [u32; 2])>,
    /// Stored atoms: each molecule type's in its spatial order.
    runs: Vec<u32>,
}

impl CoarseSources {
    /// Coarse copy `i`'s colour word from the scene's atoms' `words`: its
    /// source atom's with the level's alpha; a see-through copy takes the
    /// mean (alpha-weighted, in linear light) of the atoms it stands for,
    /// as full detail blends their layers into one tone (the source's
    /// alone would show a see-through molecule's element colours as
    /// speckle through its levels). Opaque copies keep their source's.
    fn colour(&self, words: &[u32], i: usize) -> u32 {
        let (src, e, [start, len]) = self.copies[i];
        let own = level_alpha(words[src as usize], e);
        if own >> 24 == 255 {
            return own;
        }
        let to_linear = |b: u32| {
            let c = b as f32 / 255.0;
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        let to_byte = |l: f32| {
            let c = if l <= 0.003_130_8 {
                l * 12.92
            } else {
                1.055 * l.powf(1.0 / 2.4) - 0.055
            };
            (c * 255.0).round().clamp(0.0, 255.0) as u32
        };
        let (mut sum, mut weight) = ([0.0f32; 3], 0.0f32);
        for &a in &self.runs[start as usize..(start + len) as usize] {
            let w = words[a as usize];
            let alpha = (w >> 24) as f32;
            for (k, s) in sum.iter_mut().enumerate() {
                *s += alpha * to_linear((w >> (8 * k)) & 0xFF);
            }
            weight += alpha;
        }
        if weight <= 0.0 {
            return own;
        }
        let rgb = (0..3).fold(0u32, |acc, k| acc | to_byte(sum[k] / weight) << (8 * k));
        (own & 0xFF00_0000) | rgb
    }
}

/// The tables of the LOD cull (glsl/lod_cull.comp) and its lists.
/// (The levels and each instance's molecule type are the scene's
/// [`SceneBuffers::levels`] and [`SceneBuffers::rows`].)
pub struct LodBuffers {
    /// Per molecule type and level, RGBA32F: bounding sphere and box in
    /// its frame ([`lod_bounds`]; the box's w: its first batch bound).
    pub bounds: Buffer,
    /// Per batch of each (molecule type, level), RGBA32F: its bounding
    /// sphere in the molecule's frame ([`batch_bound`]).
    pub batch_bounds: Buffer,
    /// The instances in the order the cull visits them: by molecule type
    /// (stable), so the lanes of a SIMD group loop over alike batch counts
    /// ([`cull_order`]), then the further chunks of the large ones
    /// ([`cull_chunks`]: `chunk_count` pairs of words).
    pub cull_order: Buffer,
    pub instance_count: u32,
    /// The median of the instances' bounding radii (full detail, world
    /// units): the size the cull's front cells follow.
    pub instance_radius: f32,
    pub chunk_count: u32,
    /// Level-0 batches (saturated at u32::MAX): the most a view lists (an
    /// instance draws one level).
    pub base_batches: u32,
    /// The four lists of the LOD cull, one after the other (8 B entries:
    /// src/stages/raster/lod.rs makes, fills and grows them); in a frame
    /// that draws them, the batch table.
    pub lists: Buffer,
    /// Entries `lists` holds (4 lists and their tails).
    pub list_entries: u32,
}

/// The median over instances of their molecule type's `radius` (0 for none).
fn median_radius(instance_molecule: &[u32], radius: impl Fn(u32) -> f32) -> f32 {
    let mut per_type: Vec<(f32, u64)> = Vec::new();
    for &m in instance_molecule {
        let m = m as usize;
        if per_type.len() <= m {
            per_type.resize(m + 1, (0.0, 0));
        }
        per_type[m].1 += 1;
    }
    for (m, t) in per_type.iter_mut().enumerate() {
        t.0 = radius(m as u32);
    }
    per_type.sort_by(|a, b| a.0.total_cmp(&b.0));
    let half = instance_molecule.len() as u64 / 2;
    let mut seen = 0;
    for (r, n) in per_type {
        seen += n;
        if seen > half {
            return r;
        }
    }
    0.0
}

/// The order the LOD cull visits instances in: by molecule type, and
/// within a type along a Morton curve through their placed centres
/// (`place`). The cull's per-instance loop over its level's batches runs
/// as long as the longest of a SIMD group's lanes (lavapipe: 8): a scene's
/// types range from one batch to thousands, and neighbours in space are
/// kept or culled together (meso 10^9 at 2,025 A: the four cull passes 321
/// -> 172 ms). The cull walks it backwards for views looking down the
/// curve (glsl/lod_cull.comp), so the lists it fills run near to far.
pub fn cull_order(instance_molecule: &[u32], place: impl Fn(usize) -> [f32; 3]) -> Vec<u32> {
    let places: Vec<[f32; 3]> = (0..instance_molecule.len()).map(place).collect();
    let cells = morton_cells(&places);
    let mut order: Vec<u32> = (0..instance_molecule.len() as u32).collect();
    order.sort_by_key(|&k| (instance_molecule[k as usize], cells[k as usize]));
    order
}

/// The further chunks the LOD cull takes instances of more than
/// CULL_CHUNK_BATCHES level-0 batches in (`batches(k)`), in `order`: per
/// chunk the instance and its first batch (each invocation then stays
/// within lavapipe's loop limit, gpu_consts CULL_CHUNK_BATCHES).
pub fn cull_chunks(order: &[u32], batches: impl Fn(usize) -> u64) -> Vec<[u32; 2]> {
    let chunk = CULL_CHUNK_BATCHES as u64;
    let mut out = Vec::new();
    for &k in order {
        let n = batches(k as usize);
        out.extend((1..n.div_ceil(chunk)).map(|c| [k, (c * chunk) as u32]));
    }
    out
}

impl SceneBuffers {
    /// The geometry buffers, by the names of [`SCENE_GEOMETRY`] (the
    /// batch table: the LOD lists in a frame that draws them).
    pub fn geometry(&self) -> [(&'static str, &Buffer); 6] {
        let batches = match &self.lod {
            Some(l) if self.listed.get() => &l.lists,
            _ => &self.batches,
        };
        [
            ("sphereTex", &self.spheres),
            ("batchTex", batches),
            ("instanceTex", &self.instances),
            ("originTex", &self.origins),
            ("instanceRowTex", &self.rows),
            ("levelTex", &self.levels),
        ]
    }

    /// The attribute buffers, by the names of [`SCENE_ATTRIBUTES`].
    pub fn attributes(&self) -> [(&'static str, &Buffer); 3] {
        [
            ("attrTex", &self.attrs),
            ("colorTex", &self.colors),
            ("moleculeTex", &self.molecules),
        ]
    }

    /// SCENE_PLAIN, SCENE_RIGID or SCENE_AFFINE.
    pub fn kind(&self) -> u32 {
        self.spec & 0xFF
    }

    /// Ids this frame's passes may name: the LOD lists' slots when the
    /// frame draws them, else the static table's.
    pub fn frame_slots(&self) -> u32 {
        self.slots_when(self.listed.get())
    }

    /// Ids a frame may name that draws the LOD lists (`listed`) or not.
    pub fn slots_when(&self, listed: bool) -> u32 {
        match &self.lod {
            Some(l) if listed => l.list_entries << (self.spec >> 8),
            _ => self.slots,
        }
    }

    /// Makes the static batch table of an instanced scene with levels of
    /// detail (every atom of every instance: what a frame that draws full
    /// detail names) the first time one needs it. The GPU must be idle.
    pub fn ensure_static(&mut self, ctx: &Context, geom: &SceneGeom) -> Result<()> {
        let SceneGeom::Instanced(i) = geom else {
            return Ok(());
        };
        if self.static_made {
            return Ok(());
        }
        let entries = static_entries(&i.batch_first, i.shift, &i.source)?;
        let b = ctx.guard(Buffer::table(
            ctx,
            "scene batches",
            entries.len() as u64 * 8,
        )?);
        b.upload(ctx, 0, bytemuck::cast_slice(&entries))?;
        let mut old = std::mem::replace(&mut self.batches, b.keep());
        old.destroy(ctx);
        self.slots = ((entries.len() as u64 - 1) << i.shift) as u32;
        self.static_made = true;
        Ok(())
    }

    /// Device memory by class: plain `scene`; instanced `molecules` (the
    /// atoms and their attributes), `instances`, and `scene` (batches, the
    /// LOD lists and the cull's order).
    pub fn memory(&self) -> Vec<(&'static str, u64)> {
        let atoms = self.spheres.size + self.attrs.size + self.colors.size;
        if self.kind() == SCENE_PLAIN {
            return vec![("scene", atoms)];
        }
        let lod_mol = self.lod.as_ref().map_or(0, |l| {
            l.bounds.size + l.batch_bounds.size + self.origins.size
        });
        vec![
            (
                "molecules",
                atoms + self.molecules.size + self.levels.size + lod_mol,
            ),
            ("instances", self.instances.size + self.rows.size),
            (
                "scene",
                self.batches.size
                    + self
                        .lod
                        .as_ref()
                        .map_or(0, |l| l.lists.size + l.cull_order.size),
            ),
        ]
    }

    /// The colour buffer's words for the scene's atom colours (`colors`,
    /// one per `Scene::spheres` record): those, then the coarse copies'.
    pub fn colour_words(&self, colors: &[[u8; 4]]) -> Result<Vec<u32>> {
        if colors.len() as u64 != self.base_atoms as u64 {
            return Err(Error::Input(format!(
                "{} colours for {} sphere records",
                colors.len(),
                self.base_atoms
            )));
        }
        let mut out: Vec<u32> = colors.iter().map(|c| u32::from_le_bytes(*c)).collect();
        let coarse: Vec<u32> = (0..self.coarse_source.copies.len())
            .map(|i| self.coarse_source.colour(&out, i))
            .collect();
        out.extend(coarse);
        Ok(out)
    }

    /// Uploads `scene`: its buffers and the CPU copy of its geometry;
    /// with `lod_pixels` (`--lod auto`) an instanced scene's levels of
    /// detail too (each molecule type's taken from `fitted` where it holds
    /// that type's fit at `lod_pixels`).
    pub fn new(
        ctx: &Context,
        scene: &Scene,
        lod_pixels: Option<f32>,
        fitted: Option<&[LodFit]>,
    ) -> Result<(Self, SceneGeom)> {
        let geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let colors: Vec<u32> = scene
            .spheres
            .iter()
            .map(|s| u32::from_le_bytes(s.color))
            .collect();
        let Some(inst) = &scene.instancing else {
            let attrs: Vec<SphereAttr> = scene
                .spheres
                .iter()
                .map(|s| SphereAttr { region: s.region })
                .collect();
            // (batches, instances, molecules and their rows: bound, never
            // read)
            let mut buffers = Self::upload(
                ctx,
                SCENE_PLAIN,
                geom.len() as u64,
                [
                    ("spheres", bytemuck::cast_slice(&geom)),
                    ("sphere attributes", bytemuck::cast_slice(&attrs)),
                    ("sphere colours", bytemuck::cast_slice(&colors)),
                    ("scene batches (unused)", &[]),
                    ("scene instances (unused)", &[]),
                    ("scene molecules (unused)", &[]),
                    ("atom origins (unused)", &[]),
                    ("instance rows (unused)", &[]),
                    ("molecule levels (unused)", &[]),
                ],
            )?;
            buffers.static_made = true;
            buffers.base_atoms = geom.len() as u32;
            return Ok((buffers, SceneGeom::Plain(geom)));
        };
        let Built {
            geom,
            chains,
            colors,
            origins,
            coarse_source,
            tables,
            batch_first,
            all_level_batches,
            entries,
            lod: lod_tables,
        } = build_instanced(scene, geom, colors, lod_pixels, fitted)?;
        let shift = tables.shift;
        let tree: Vec<u32> = inst.tree_regions.iter().flatten().copied().collect();
        let (kind, transform_bytes): (u32, &[u8]) = match &inst.transforms {
            Transforms::Rigid(v) => (SCENE_RIGID, bytemuck::cast_slice(v)),
            Transforms::Affine(v) => (SCENE_AFFINE, bytemuck::cast_slice(v)),
        };
        let static_slots = entries
            .as_ref()
            .map_or(0, |e| (e.len() as u64 - 1) << shift);
        let mut buffers = Self::upload(
            ctx,
            kind | (shift << 8),
            static_slots,
            [
                ("molecule atoms", bytemuck::cast_slice(&geom)),
                ("atom chains", bytemuck::cast_slice(&chains)),
                ("atom colours", bytemuck::cast_slice(&colors)),
                (
                    "scene batches",
                    entries.as_deref().map_or(&[], bytemuck::cast_slice),
                ),
                ("instances", transform_bytes),
                ("molecule regions", bytemuck::cast_slice(&tree)),
                ("atom origins", bytemuck::cast_slice(&origins)),
                ("instance rows", bytemuck::cast_slice(&tables.rows)),
                ("molecule levels", bytemuck::cast_slice(&tables.levels)),
            ],
        )?;
        buffers.static_made = entries.is_some();
        buffers.all_level_slots = (all_level_batches << shift).min(u32::MAX as u64) as u32;
        // (the scene's own atoms: the coarse copies follow them)
        buffers.base_atoms = scene.spheres.len() as u32;
        buffers.coarse_source = coarse_source;
        let base_batches = batch_first.last().copied().unwrap_or(0);
        if let Some((bounds, batch_bounds)) = lod_tables {
            let table = |name: &str, texels: &[[f32; 4]]| -> Result<Buffer> {
                let t = ctx.guard(Buffer::table(
                    ctx,
                    name,
                    (texels.len() as u64 * 16).max(16),
                )?);
                t.upload(ctx, 0, bytemuck::cast_slice(texels))?;
                Ok(t.keep())
            };
            let b = ctx.guard(table("LOD bounds", &bounds)?);
            let bb = ctx.guard(table("LOD batch bounds", &batch_bounds)?);
            let mut words = cull_order(&inst.instance_molecule, |k| {
                let c = bounds[2 * inst.instance_molecule[k] as usize * MAX_LOD_LEVELS as usize];
                inst.transforms.apply(k, [c[0], c[1], c[2]])
            });
            let chunks = cull_chunks(&words, |k| batch_first[k + 1] - batch_first[k]);
            words.extend(chunks.iter().flatten());
            let order = ctx.guard(Buffer::table(
                ctx,
                "LOD cull order",
                (words.len() as u64 * 4).max(16),
            )?);
            order.upload(ctx, 0, bytemuck::cast_slice(&words))?;
            // (src/stages/raster/lod.rs sizes them)
            let lists = Buffer::storage(ctx, "LOD lists", 16)?;
            buffers.lod = Some(LodBuffers {
                bounds: b.keep(),
                batch_bounds: bb.keep(),
                cull_order: order.keep(),
                instance_count: inst.instances() as u32,
                instance_radius: median_radius(&inst.instance_molecule, |m| {
                    bounds[2 * m as usize * MAX_LOD_LEVELS as usize][3]
                }),
                chunk_count: chunks.len() as u32,
                base_batches: base_batches.min(u32::MAX as u64) as u32,
                lists,
                list_entries: 0,
            });
        }
        let geom = SceneGeom::Instanced(Box::new(InstancedGeom {
            atoms: geom,
            transforms: inst.transforms.clone(),
            instance_molecule: inst.instance_molecule.clone(),
            molecules: inst.molecules.iter().map(|m| (m.first, m.atoms)).collect(),
            proxies: inst.molecules.iter().map(|m| m.origin.is_some()).collect(),
            first: inst.first.clone(),
            tables,
            batch_first,
            origins,
            shift,
            source: scene.source.clone(),
        }));
        Ok((buffers, geom))
    }

    /// The nine buffers (named, with their bytes) in field order; an
    /// error part way destroys what was made. An instanced scene's are
    /// read-only texel tables (not bound by the storage range: its batch
    /// table passes 128 MiB near 10^9 atoms); a plain scene's spheres are
    /// also the graphics rasterizer's storage buffer.
    fn upload(ctx: &Context, spec: u32, slots: u64, data: [(&str, &[u8]); 9]) -> Result<Self> {
        let mut made = ctx.guard(Vec::new());
        let make = if spec & 0xFF == SCENE_PLAIN {
            Buffer::storage
        } else {
            Buffer::table
        };
        for (name, bytes) in data {
            let b = ctx.guard(make(ctx, name, bytes.len().max(16) as u64)?);
            if !bytes.is_empty() {
                b.upload(ctx, 0, bytes)?;
            }
            made.push(b.keep());
        }
        let [
            spheres,
            attrs,
            colors,
            batches,
            instances,
            molecules,
            origins,
            rows,
            levels,
        ]: [Buffer; 9] = made
            .keep()
            .try_into()
            .map_err(|_| Error::Internal("scene buffers".into()))?;
        Ok(SceneBuffers {
            spec,
            spheres,
            attrs,
            colors,
            batches,
            instances,
            molecules,
            origins,
            rows,
            levels,
            slots: slots.min(MAX_SLOTS) as u32,
            all_level_slots: slots.min(MAX_SLOTS) as u32,
            static_made: false,
            lod: None,
            listed: std::cell::Cell::new(false),
            base_atoms: 0,
            coarse_source: CoarseSources::default(),
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.spheres,
            &mut self.attrs,
            &mut self.colors,
            &mut self.batches,
            &mut self.instances,
            &mut self.molecules,
            &mut self.origins,
            &mut self.rows,
            &mut self.levels,
        ] {
            b.destroy(ctx);
        }
        if let Some(l) = &mut self.lod {
            l.bounds.destroy(ctx);
            l.batch_bounds.destroy(ctx);
            l.cull_order.destroy(ctx);
            l.lists.destroy(ctx);
        }
    }
}

crate::impl_destroy!(SceneBuffers);

/// The scene's `Globals.scene` word: tree levels, chain stride, the
/// molecule and chain levels' indices.
pub fn levels_word(scene: &Scene) -> [u32; 4] {
    let Some(inst) = &scene.instancing else {
        return [0, 0, NO_LEVEL, NO_LEVEL];
    };
    [
        inst.tree_levels(),
        inst.chain_stride,
        inst.level_of(LevelKind::Molecule).unwrap_or(NO_LEVEL),
        inst.level_of(LevelKind::Chain).unwrap_or(NO_LEVEL),
    ]
}

/// The batch shift for an instanced scene: the one that makes the fewest
/// lanes (slots) plus four per batch (its record's fetches and its view
/// orders' words weigh about as much as four idle lanes): 64-slot batches
/// for molecules of thousands of atoms, 8-slot ones for beads (the
/// Mycoplasma model's 19 beads an instance would leave 70 % of 64-slot
/// batches idle).
pub fn batch_shift(scene: &Scene) -> u32 {
    let Some(inst) = &scene.instancing else {
        return MAX_BATCH_SHIFT;
    };
    let cost = |shift: u32| -> u64 {
        let per = 1u64 << shift;
        inst.instance_molecule
            .iter()
            .map(|&m| {
                let batches = (inst.molecules[m as usize].atoms as u64).div_ceil(per);
                batches * per + 4 * batches
            })
            .sum()
    };
    (MIN_BATCH_SHIFT..=MAX_BATCH_SHIFT)
        .min_by_key(|&s| (cost(s), std::cmp::Reverse(s)))
        .unwrap_or(MAX_BATCH_SHIFT)
}

/// An instanced scene's tables as [`SceneBuffers::new`] uploads them.
struct Built {
    /// The molecule atoms, then the coarse levels' (`geom`, `colors` as
    /// given extended by them).
    geom: Vec<GpuSphere>,
    chains: Vec<u32>,
    colors: Vec<u32>,
    origins: Vec<u32>,
    coarse_source: CoarseSources,
    tables: BatchTables,
    /// Per instance its first batch in the static table (+ the total).
    batch_first: Vec<u64>,
    /// Batches of every level of every instance.
    all_level_batches: u64,
    /// Without levels of detail the static table ([`static_entries`]),
    /// made up front; with them, made when a frame draws full detail.
    entries: Option<Vec<[u32; 2]>>,
    /// With levels of detail: per (molecule type, level) its bounds
    /// ([`lod_bounds`]), then per batch of each its bounding sphere
    /// ([`batch_bound`]).
    lod: Option<LodTables>,
}

/// Per (molecule type, level) its bounds, then per batch of each its
/// bounding sphere (RGBA32F texels).
type LodTables = (Vec<[f32; 4]>, Vec<[f32; 4]>);

/// The tables of instanced `scene` (its atoms `geom` and colour words
/// `colors`); with `lod_pixels` its levels of detail too (from `fitted`
/// where it holds them: [`lod_of`]).
fn build_instanced(
    scene: &Scene,
    mut geom: Vec<GpuSphere>,
    mut colors: Vec<u32>,
    lod_pixels: Option<f32>,
    fitted: Option<&[LodFit]>,
) -> Result<Built> {
    let Some(inst) = &scene.instancing else {
        return Err(Error::Internal("instanced tables of a plain scene".into()));
    };
    let shift = batch_shift(scene);
    let mut tables = base_tables(scene, shift)?;
    let batch_first = batch_firsts(
        inst.instance_molecule
            .iter()
            .map(|&m| inst.molecules[m as usize].atoms),
        shift,
    );
    let mut chains: Vec<u32> = scene.spheres.iter().map(|s| s.region[0]).collect();
    let lod = match lod_pixels {
        Some(p) => Some(lod_of(scene, &geom, p, fitted)?),
        None => None,
    };
    // The coarse levels' atoms after the scene's own.
    let mut origins: Vec<u32> = Vec::new();
    let mut coarse_source = CoarseSources::default();
    let mut lod_tables = None;
    if let Some(lod) = &lod {
        origins = vec![0; geom.len()];
        for (m, mol) in inst.molecules.iter().enumerate() {
            let Lod {
                levels: ml, switch, ..
            } = &lod[m];
            let own = mol.first as usize..(mol.first + mol.atoms) as usize;
            // (the molecule's atoms in their spatial order: its copies'
            // runs)
            let runs = coarse_source.runs.len() as u32;
            if ml.levels() > 1 {
                let spatial = ml.spatial.iter().map(|&a| mol.first + a);
                coarse_source.runs.extend(spatial);
            }
            for (l, sw) in switch.iter().enumerate().take(ml.levels()) {
                let first = if l == 0 { mol.first } else { geom.len() as u32 };
                // (level 0's row holds the number of levels; a proxy's
                // rows are marked: its level 0 names atoms through origins)
                let x = if l == 0 { ml.levels() as u32 } else { 0 }
                    | if mol.origin.is_some() {
                        LEVEL_MAPPED
                    } else {
                        0
                    };
                tables.levels[m * MAX_LOD_LEVELS as usize + l] =
                    [x, first, sw.to_bits(), ml.counts[l]];
                let origin = |a: u32| mol.origin.as_ref().map_or(a, |o| o[a as usize]);
                if l == 0 {
                    if mol.origin.is_some() {
                        for a in 0..mol.atoms {
                            origins[(mol.first + a) as usize] = origin(a);
                        }
                    }
                    continue;
                }
                let spheres = ml.level_spheres(&geom[own.clone()], l);
                geom.extend(spheres);
                // (a see-through atom's copy is as opaque as the atoms it
                // stands for along a ray)
                let e = ml.alpha_exponent(l);
                for (&a, run) in ml.order.iter().zip(ml.stands_for(l)) {
                    let src = mol.first + a;
                    chains.push(chains[src as usize]);
                    let run = [runs + run.start as u32, run.len() as u32];
                    coarse_source.copies.push((src, e, run));
                    colors.push(coarse_source.colour(&colors, coarse_source.copies.len() - 1));
                    origins.push(origin(a));
                }
            }
        }
        // (MAX_LOD_LEVELS rows per type, as levelTex; the box's w: the
        // level's first batch bound)
        let mut bounds = vec![[0.0f32; 4]; 2 * lod.len() * MAX_LOD_LEVELS as usize];
        let mut batch_bounds: Vec<[f32; 4]> = Vec::new();
        for (m, l) in lod.iter().enumerate() {
            for (i, b) in l.bound.iter().enumerate() {
                let row = m * MAX_LOD_LEVELS as usize + i;
                let at = 2 * row;
                bounds[at..at + 2].copy_from_slice(b);
                bounds[at + 1][3] = batch_bounds.len() as f32;
                let [_, first, _, n] = tables.levels[row];
                let stored = &geom[first as usize..(first + n) as usize];
                batch_bounds.extend(stored.chunks(1 << shift).map(batch_bound));
            }
        }
        if batch_bounds.len() >= 1 << 24 {
            return Err(Error::Input(format!(
                "{}: {} batches in the molecules' levels, more than 2^24",
                scene.source,
                batch_bounds.len()
            )));
        }
        lod_tables = Some((bounds, batch_bounds));
    }
    if lod.is_none() && inst.molecules.iter().any(|m| m.origin.is_some()) {
        return Err(Error::Internal(
            "a nested scene's proxies drawn without levels of detail".into(),
        ));
    }
    let entries = match lod {
        None => Some(static_entries(&batch_first, shift, &scene.source)?),
        Some(_) => None,
    };
    let level_batches: Vec<u64> = match &lod {
        None => Vec::new(),
        Some(lod) => lod
            .iter()
            .map(|l| {
                let c = &l.levels.counts;
                c.iter().map(|&n| n.div_ceil(1 << shift) as u64).sum()
            })
            .collect(),
    };
    let all_level_batches = match lod {
        None => batch_first.last().copied().unwrap_or(0),
        Some(_) => inst
            .instance_molecule
            .iter()
            .map(|&m| level_batches[m as usize])
            .sum(),
    };
    Ok(Built {
        geom,
        chains,
        colors,
        origins,
        coarse_source,
        tables,
        batch_first,
        all_level_batches,
        entries,
        lod: lod_tables,
    })
}

/// The sphere about the box of a batch's centres that holds its spheres
/// (in the molecule's frame), grown a little against the f32 rounding of
/// the transforms: what glsl/lod_cull.comp tests a batch by.
fn batch_bound(spheres: &[GpuSphere]) -> [f32; 4] {
    let Some((c, _)) = box_sphere(|| spheres.iter().map(|a| ([a[0], a[1], a[2]], a[3]))) else {
        return [0.0; 4];
    };
    let r = spheres
        .iter()
        .map(|a| glam::Vec3::new(a[0], a[1], a[2]).distance(c) + a[3])
        .fold(0.0f32, f32::max);
    [c.x, c.y, c.z, r * 1.001 + 1e-3]
}

/// Per instance (of `atoms` each) its first batch of 2^shift slots in the
/// static table, then the total.
fn batch_firsts(atoms: impl Iterator<Item = u32>, shift: u32) -> Vec<u64> {
    let mut firsts = vec![0u64];
    let mut at = 0u64;
    for n in atoms {
        at += n.div_ceil(1 << shift) as u64;
        firsts.push(at);
    }
    firsts
}

/// Whether the static table's slots fit the 32-bit ids (else the one
/// line that says what can draw the scene).
fn static_fits(batch_first: &[u64], shift: u32, source: &str) -> Result<()> {
    let total = batch_first.last().copied().unwrap_or(0);
    let needed = (total + 1) << shift;
    if needed > MAX_SLOTS {
        return Err(Error::Input(format!(
            "{source}: drawing every atom needs {needed} sphere ids, more than the {MAX_SLOTS} \
             sphereshade has: only levels of detail (--lod auto) with the compute rasterizer \
             and --shadows issm|sm|pcf|none draw a scene this large"
        )));
    }
    Ok(())
}

/// The static batch table: every instance's batches at full detail in
/// expanded order (entry: instance, batch index within its level 0),
/// then the empty batch; `batch_first` per instance and the total. Its
/// slots must fit the 32-bit ids: past them only the LOD lists can draw
/// the scene, and the error says so.
pub fn static_entries(batch_first: &[u64], shift: u32, source: &str) -> Result<Vec<[u32; 2]>> {
    static_fits(batch_first, shift, source)?;
    let total = batch_first.last().copied().unwrap_or(0);
    let mut entries = Vec::with_capacity(total as usize + 1);
    for (k, w) in batch_first.windows(2).enumerate() {
        entries.extend((0..(w[1] - w[0]) as u32).map(|j| [k as u32, j]));
    }
    entries.push([BATCH_EMPTY, 0]);
    Ok(entries)
}

/// An instanced scene's instances and levels as the GPU stores them; a
/// batch table's entries (the static one, or the LOD lists) name an
/// instance, a level and a batch of it, and [`BatchTables::record`] makes
/// that batch's record from them as glsl/scene.glsl `scene_batch` does.
pub struct BatchTables {
    /// Per instance: molecule type, the low 32 bits of the expanded index
    /// of its first atom.
    pub rows: Vec<[u32; 2]>,
    /// Per (molecule type, level < MAX_LOD_LEVELS): level 0's holds the
    /// number of levels, the level's first stored atom, its switch size
    /// (f32 bits: most pixels per world unit it is drawn at), its atoms.
    pub levels: Vec<[u32; 4]>,
    /// Slots a batch: 2^shift.
    pub shift: u32,
}

impl BatchTables {
    /// The record of the batch entry `e` names: instance, first stored
    /// atom, the expanded index of that atom (a coarse batch: of its
    /// instance's first; low 32 bits), atom count | molecule type << 8 |
    /// BATCH_COARSE; zeros for the empty batch. None: an entry past the
    /// tables.
    pub fn record(&self, e: [u32; 2]) -> Option<GpuBatch> {
        if e[0] == BATCH_EMPTY {
            return Some([0; 4]);
        }
        let (k, l) = (e[0] & BATCH_INSTANCE_MASK, e[0] >> BATCH_INSTANCE_BITS);
        let row = self.rows.get(k as usize)?;
        let lv = self
            .levels
            .get((row[0] * MAX_LOD_LEVELS + l.min(MAX_LOD_LEVELS - 1)) as usize)?;
        let coarse = l != 0 || lv[0] & LEVEL_MAPPED != 0;
        let a = e[1].checked_mul(1 << self.shift)?;
        Some([
            k,
            lv[1] + a,
            row[1].wrapping_add(if coarse { 0 } else { a }),
            lv[3].checked_sub(a)?.min(1 << self.shift)
                | (row[0] << 8)
                | if coarse { BATCH_COARSE } else { 0 },
        ])
    }
}

/// The instance and level tables of an instanced scene at full detail
/// (one level per molecule type; `build_instanced` adds the coarse ones).
fn base_tables(scene: &Scene, shift: u32) -> Result<BatchTables> {
    let Some(inst) = &scene.instancing else {
        return Err(Error::Internal("batches of a plain scene".into()));
    };
    if inst.molecules.len() > BATCH_TYPE_MASK as usize {
        return Err(Error::Input(format!(
            "{}: {} molecule types, more than 2^23",
            scene.source,
            inst.molecules.len()
        )));
    }
    let mut levels = vec![[0u32; 4]; inst.molecules.len() * MAX_LOD_LEVELS as usize];
    for (m, mol) in inst.molecules.iter().enumerate() {
        levels[m * MAX_LOD_LEVELS as usize] = [1, mol.first, f32::INFINITY.to_bits(), mol.atoms];
    }
    let rows = inst
        .instance_molecule
        .iter()
        .enumerate()
        .map(|(k, &m)| [m, inst.first[k] as u32])
        .collect();
    Ok(BatchTables {
        rows,
        levels,
        shift,
    })
}

/// The CPU copy of the scene's geometry.
pub enum SceneGeom {
    Plain(Vec<GpuSphere>),
    Instanced(Box<InstancedGeom>),
}

pub struct InstancedGeom {
    /// The molecule atoms (their frames).
    pub atoms: Vec<GpuSphere>,
    pub transforms: Transforms,
    pub instance_molecule: Vec<u32>,
    /// Per molecule type: first atom, atom count.
    pub molecules: Vec<(u32, u32)>,
    /// Per molecule type: a nested scene's proxy.
    pub proxies: Vec<bool>,
    /// Expanded index of each instance's first atom (+ the total).
    pub first: Vec<u64>,
    pub tables: BatchTables,
    /// Per instance its first batch in the static table, then the total.
    pub batch_first: Vec<u64>,
    /// Per stored atom of a coarse level: the atom it stands for (index
    /// within its molecule); empty without levels of detail.
    pub origins: Vec<u32>,
    /// Slots a batch: 2^shift.
    pub shift: u32,
    /// The scene's name (for errors).
    pub source: String,
}

impl InstancedGeom {
    /// The expanded index of atom `lane` of the batch entry `e` names
    /// (None: no such atom).
    fn expanded_of(&self, e: [u32; 2], lane: u32) -> Option<u64> {
        let b = self.tables.record(e)?;
        if lane >= (b[3] & 0xFF) {
            return None;
        }
        let atom = if b[3] & BATCH_COARSE != 0 {
            *self.origins.get((b[1] + lane) as usize)?
        } else {
            (e[1] << self.shift) + lane
        };
        Some(self.first.get(b[0] as usize)? + atom as u64)
    }

    fn instance_atoms(&self, k: usize) -> &[GpuSphere] {
        let (f, n) = self.molecules[self.instance_molecule[k] as usize];
        &self.atoms[f as usize..(f + n) as usize]
    }
}

impl SceneGeom {
    /// Represented spheres.
    pub fn len(&self) -> u64 {
        match self {
            SceneGeom::Plain(g) => g.len() as u64,
            SceneGeom::Instanced(i) => i.first.last().copied().unwrap_or(0),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Ids a per-sphere dispatch of every atom at full detail covers (as
    /// `SceneBuffers::base_slots`: the coarse levels' batches follow).
    pub fn slots(&self) -> u32 {
        match self {
            SceneGeom::Plain(g) => g.len() as u32,
            SceneGeom::Instanced(i) => {
                let total = i.batch_first.last().copied().unwrap_or(0);
                (total << i.shift).min(MAX_SLOTS) as u32
            }
        }
    }

    /// Whether a frame may draw every atom (the static table's ids fit 32
    /// bits), else the one line that says what can draw the scene.
    pub fn check_full_detail(&self) -> Result<()> {
        match self {
            SceneGeom::Plain(_) => Ok(()),
            SceneGeom::Instanced(i) => static_fits(&i.batch_first, i.shift, &i.source),
        }
    }

    /// Every represented sphere: world centre and radius (instanced: the
    /// transform applied as the GPU applies it).
    pub fn spheres(&self) -> Box<dyn Iterator<Item = ([f32; 3], f32)> + '_> {
        match self {
            SceneGeom::Plain(g) => Box::new(g.iter().map(|s| ([s[0], s[1], s[2]], s[3]))),
            SceneGeom::Instanced(i) => {
                Box::new((0..i.instance_molecule.len()).flat_map(move |k| {
                    i.instance_atoms(k)
                        .iter()
                        .map(move |a| (i.transforms.apply(k, [a[0], a[1], a[2]]), a[3]))
                }))
            }
        }
    }

    /// Every represented sphere's radius.
    pub fn radii(&self) -> Box<dyn Iterator<Item = f32> + '_> {
        match self {
            SceneGeom::Plain(g) => Box::new(g.iter().map(|s| s[3])),
            SceneGeom::Instanced(i) => Box::new(
                (0..i.instance_molecule.len())
                    .flat_map(move |k| i.instance_atoms(k).iter().map(|a| a[3])),
            ),
        }
    }

    /// The represented sphere of expanded index `e` (centre, radius).
    pub fn sphere(&self, e: u64) -> Option<GpuSphere> {
        match self {
            SceneGeom::Plain(g) => g.get(usize::try_from(e).ok()?).copied(),
            SceneGeom::Instanced(i) => {
                if e >= *i.first.last()? {
                    return None;
                }
                let k = i.first.partition_point(|&f| f <= e) - 1;
                let a = i.instance_atoms(k)[(e - i.first[k]) as usize];
                let c = i.transforms.apply(k, [a[0], a[1], a[2]]);
                Some([c[0], c[1], c[2], a[3]])
            }
        }
    }

    /// The expanded index of sphere id `id` (a slot of an instanced
    /// scene's static table).
    pub fn expanded_id(&self, id: u32) -> Option<u64> {
        match self {
            SceneGeom::Plain(g) => ((id as usize) < g.len()).then_some(id as u64),
            SceneGeom::Instanced(i) => {
                let b = (id >> i.shift) as u64;
                let k = i.batch_first.partition_point(|&f| f <= b).checked_sub(1)?;
                if k >= i.instance_molecule.len() {
                    return None;
                }
                let entry = [k as u32, (b - i.batch_first[k]) as u32];
                i.expanded_of(entry, id & ((1 << i.shift) - 1))
            }
        }
    }

    /// The expanded index of sphere id `id` of a frame that drew the LOD
    /// lists (`lists`: their entries as the GPU held them).
    pub fn listed_id(&self, lists: &[[u32; 2]], id: u32) -> Option<u64> {
        match self {
            SceneGeom::Plain(_) => None,
            SceneGeom::Instanced(i) => {
                let e = *lists.get((id >> i.shift) as usize)?;
                i.expanded_of(e, id & ((1 << i.shift) - 1))
            }
        }
    }

    /// Centres of the runs a view order permutes (runs of `plain_run`
    /// plain spheres, or the batches) and each run's ids.
    pub fn runs(&self, plain_run: usize) -> Vec<(DVec3, std::ops::Range<u32>)> {
        let mean = |it: &mut dyn Iterator<Item = [f32; 3]>| {
            let (mut s, mut n) = (DVec3::ZERO, 0.0);
            for c in it {
                s += DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
                n += 1.0;
            }
            s / f64::max(n, 1.0)
        };
        match self {
            SceneGeom::Plain(g) => g
                .chunks(plain_run)
                .enumerate()
                .map(|(k, run)| {
                    let first = (k * plain_run) as u32;
                    (
                        mean(&mut run.iter().map(|s| [s[0], s[1], s[2]])),
                        first..first + run.len() as u32,
                    )
                })
                .collect(),
            SceneGeom::Instanced(i) => {
                // the runs' centres in their molecules' frames, then placed
                let per = 1usize << i.shift;
                let mut local: Vec<Vec<[f32; 3]>> = Vec::with_capacity(i.molecules.len());
                for &(f, n) in &i.molecules {
                    let atoms = &i.atoms[f as usize..(f + n) as usize];
                    local.push(
                        atoms
                            .chunks(per)
                            .map(|run| {
                                let c = mean(&mut run.iter().map(|s| [s[0], s[1], s[2]]));
                                [c.x as f32, c.y as f32, c.z as f32]
                            })
                            .collect(),
                    );
                }
                // (the static table's batches, level 0: the coarse ones are
                // listed by the LOD cull, never by a view order)
                let mut runs = Vec::with_capacity(self.slots() as usize >> i.shift);
                for (k, &m) in i.instance_molecule.iter().enumerate() {
                    let first = i.batch_first[k];
                    for (j, &c) in local[m as usize].iter().enumerate() {
                        let slot = ((first + j as u64) << i.shift).min(MAX_SLOTS) as u32;
                        let c = i.transforms.apply(k, c);
                        runs.push((
                            DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64),
                            slot..slot + per as u32,
                        ));
                    }
                }
                runs
            }
        }
    }

    /// Whether view orders hold batches (instanced) rather than spheres.
    pub fn orders_batches(&self) -> bool {
        matches!(self, SceneGeom::Instanced(_))
    }

    /// Bounding sphere of the sphere centres' box centre and the farthest
    /// surface (as `Scene::bounding_sphere`).
    pub fn bounding_sphere(&self) -> (DVec3, f64) {
        let sphere = match self.extremes() {
            Some(e) => e.bounding_sphere(),
            None => box_sphere(|| self.spheres()),
        };
        sphere.map_or((DVec3::ZERO, 0.0), |(c, r)| (c.as_dvec3(), r as f64))
    }

    /// An instanced scene's instances as [`Extremes`] (None: plain).
    fn extremes(&self) -> Option<Extremes<'_>> {
        self.extremes_of(false)
    }

    /// [`Self::extremes`], with `opened_only` over the instances that are
    /// no nested scene's proxies (a proxy type as a molecule of no atoms:
    /// the scans skip it).
    fn extremes_of(&self, opened_only: bool) -> Option<Extremes<'_>> {
        match self {
            SceneGeom::Plain(_) => None,
            SceneGeom::Instanced(i) => Some(Extremes::new(
                &i.transforms,
                &i.instance_molecule,
                i.molecules
                    .iter()
                    .zip(&i.proxies)
                    .map(|(&m, &p)| if p && opened_only { (m.0, 0) } else { m })
                    .collect(),
                std::borrow::Cow::Borrowed(&i.atoms),
            )),
        }
    }

    /// Along each of `axes`, the least `centre . axis - radius` and the
    /// largest `centre . axis + radius` over every represented sphere
    /// (None: no spheres): what a light view is fitted to. A nested scene
    /// with placements opened: over theirs only, so the light's texels
    /// stay as fine as the block's (fitted to a 10^12 scene, ~240 A
    /// wide, and a zoomed view lost its shadows); closed placements then
    /// cast no shadow on them.
    pub fn extent_along(&self, axes: [DVec3; 3]) -> Option<(DVec3, DVec3)> {
        let opened_only = matches!(self, SceneGeom::Instanced(i)
            if i.instance_molecule.iter().any(|&m| !i.proxies[m as usize])
                && i.instance_molecule.iter().any(|&m| i.proxies[m as usize]));
        if let Some(e) = self.extremes_of(opened_only) {
            return e.extent_along(axes);
        }
        crate::camera::extent_along(self.spheres(), axes)
    }

    /// The least `(centre - eye) . dir - radius` over every represented
    /// sphere (None: no spheres).
    pub fn nearest_along(&self, eye: DVec3, dir: DVec3) -> Option<f64> {
        if let Some(e) = self.extremes() {
            return e.nearest_along(eye, dir);
        }
        self.spheres()
            .map(|(g, r)| {
                (DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64) - eye).dot(dir) - r as f64
            })
            .reduce(f64::min)
    }

    /// The least and the largest radius of a represented sphere
    /// (`(f32::MAX, 0)` for none): an instanced scene's from the atoms of
    /// the molecule types that have instances.
    pub fn radius_range(&self) -> (f32, f32) {
        let fold = |it: &mut dyn Iterator<Item = f32>| {
            it.fold((f32::MAX, 0.0f32), |(lo, hi), r| (lo.min(r), hi.max(r)))
        };
        match self {
            SceneGeom::Plain(g) => fold(&mut g.iter().map(|s| s[3])),
            SceneGeom::Instanced(i) => {
                let mut used = vec![false; i.molecules.len()];
                for &m in &i.instance_molecule {
                    used[m as usize] = true;
                }
                fold(
                    &mut i.molecules.iter().zip(&used).filter(|(_, u)| **u).flat_map(
                        |(&(f, n), _)| i.atoms[f as usize..(f + n) as usize].iter().map(|a| a[3]),
                    ),
                )
            }
        }
    }
}

/// The sphere centred on the box of `spheres()`' centres that reaches the
/// farthest surface (as `Scene::bounding_sphere`); None for none.
fn box_sphere<I: Iterator<Item = ([f32; 3], f32)>>(
    spheres: impl Fn() -> I,
) -> Option<(glam::Vec3, f32)> {
    let mut b: Option<(glam::Vec3, glam::Vec3)> = None;
    for (c, _) in spheres() {
        let c = glam::Vec3::from(c);
        b = Some(b.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
    }
    let (lo, hi) = b?;
    let c = (lo + hi) * 0.5;
    let r = spheres()
        .map(|(p, r)| glam::Vec3::from(p).distance(c) + r)
        .fold(0.0f32, f32::max);
    Some((c, r))
}

/// A molecule type's levels of detail as the cull reads them.
struct Lod {
    levels: MoleculeLod,
    /// Per level: most pixels per world unit it is drawn at.
    switch: Vec<f32>,
    /// Per level: its bounds in the molecule's frame ([`lod_bounds`]).
    bound: Vec<[[f32; 4]; 2]>,
}

/// What bounds each level's spheres (a coarse level's, grown to keep the
/// volume, reach past the atoms' own box), in the molecule's frame, per
/// level: the sphere (centre: level 0's centres' box's, the same for every
/// level; radius), then the half-extents of the box about that centre
/// (w = 0), which glsl/lod_cull.comp turns with the instance: tighter than
/// the sphere for a long or flat molecule. Grown a little against the f32
/// rounding of the transforms.
fn lod_bounds(atoms: &[[f32; 4]], ml: &MoleculeLod) -> Vec<[[f32; 4]; 2]> {
    let Some((c, _)) = box_sphere(|| atoms.iter().map(|a| ([a[0], a[1], a[2]], a[3]))) else {
        return vec![[[0.0; 4]; 2]];
    };
    let grow = |x: f32| x * 1.001 + 1e-3;
    (0..ml.levels())
        .map(|l| {
            let (mut r, mut e) = (0.0f32, glam::Vec3::ZERO);
            for s in ml.level_spheres(atoms, l) {
                let d = glam::Vec3::new(s[0], s[1], s[2]) - c;
                r = r.max(d.length() + s[3]);
                e = e.max(d.abs() + glam::Vec3::splat(s[3]));
            }
            [
                [c.x, c.y, c.z, grow(r)],
                [grow(e.x), grow(e.y), grow(e.z), 0.0],
            ]
        })
        .collect()
}

/// Every molecule type's levels (`pixels`: `--lod-pixels`).
fn lod_of(
    scene: &Scene,
    geom: &[GpuSphere],
    pixels: f32,
    fitted: Option<&[LodFit]>,
) -> Result<Vec<Lod>> {
    let Some(inst) = &scene.instancing else {
        return Ok(Vec::new());
    };
    // (fits made before, a nested scene's proxies' for its resolved scenes:
    // the block's types, then the proxies, as `resolve` lists them)
    let fitted = fitted.filter(|f| f.len() == inst.molecules.len());
    let one = |m: usize| -> Result<Lod> {
        let mol = &inst.molecules[m];
        let atoms = &geom[mol.first as usize..(mol.first + mol.atoms) as usize];
        let fit = match fitted.map(|f| &f[m]) {
            Some(f) if f.fits(mol.atoms, pixels) => f.clone(),
            _ => LodFit::new(atoms, pixels),
        };
        if fit.levels.levels() > MAX_LOD_LEVELS as usize {
            return Err(Error::Internal(format!(
                "{}: {} levels of detail",
                mol.label,
                fit.levels.levels()
            )));
        }
        let bound = lod_bounds(atoms, &fit.levels);
        Ok(Lod {
            levels: fit.levels,
            switch: fit.switch,
            bound,
        })
    };
    // The molecule types on every core (their silhouette fits are the
    // renderer's start-up: SARS-CoV-2's 2.4 s on one).
    on_every_core(inst.molecules.len(), one)
        .ok_or_else(|| Error::Internal("a level-of-detail worker failed".into()))?
        .into_iter()
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Sphere;
    use crate::scene::instanced::InstancedBuilder;
    use crate::scene::instanced::lod::morton3;

    /// The median radius weighs each molecule type by its instances.
    #[test]
    fn the_median_radius_counts_instances() {
        let radius = |m: u32| [10.0, 1.0, 5.0][m as usize];
        assert_eq!(median_radius(&[0, 1, 1, 1, 2], radius), 1.0);
        assert_eq!(median_radius(&[0, 0, 0, 1, 2], radius), 10.0);
        assert_eq!(median_radius(&[2, 0, 1], radius), 5.0);
        assert_eq!(median_radius(&[], radius), 0.0);
    }

    /// The cull's order visits every instance once, by molecule type, and
    /// within a type along the Morton curve of their places (x bits below
    /// y's below z's); places it cannot grid (NaN, one point) keep their
    /// order.
    #[test]
    fn the_cull_visits_instances_by_type_then_place() {
        let types = [2, 0, 1, 0, 2, 2, 1, 0];
        let places = [
            [0.0, 0.0, 9.0],
            [9.0, 0.0, 0.0],
            [0.0, 0.0, 0.0],
            [0.0, 9.0, 0.0],
            [0.0, 0.0, 0.0],
            [9.0, 9.0, 9.0],
            [f32::NAN, 0.0, 0.0],
            [0.0, 0.0, 0.0],
        ];
        assert_eq!(cull_order(&types, |k| places[k]), [7, 1, 3, 2, 6, 4, 0, 5]);
        assert_eq!(cull_order(&types, |_| [1.0; 3]), [1, 3, 7, 2, 6, 0, 4, 5]);
        assert!(cull_order(&[], |_| [0.0; 3]).is_empty());
        // (the further chunks of the instances past one chunk, in order)
        let n = CULL_CHUNK_BATCHES as u64;
        let batches = [10, 2 * n + 88, n];
        let chunks = cull_chunks(&[2, 1, 0], |k| batches[k]);
        assert_eq!(chunks, [[1, n as u32], [1, 2 * n as u32]]);
        assert_eq!(morton3([1, 0, 0]), 1);
        assert_eq!(morton3([0, 1, 0]), 2);
        assert_eq!(morton3([0, 0, 1]), 4);
        assert_eq!(morton3([1023, 1023, 1023]), (1 << 30) - 1);
    }

    /// A scene of a 300-atom molecule, a 5-atom one and an empty one,
    /// instanced 9 times in mixed order.
    fn scene() -> Scene {
        let mut b = InstancedBuilder::default();
        let node = b.node(&["cell", "proteins"]);
        let blob = |n: usize, seed: u32| -> Vec<Sphere> {
            let mut x = seed;
            let mut next = move || {
                x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (x >> 8) as f32 / (1u32 << 24) as f32 * 20.0 - 10.0
            };
            (0..n)
                .map(|i| Sphere {
                    center: [next(), next(), next()],
                    radius: 1.5,
                    color: [200, 100, 50, 255],
                    region: [(i % 3) as u32, 0, 0, 0],
                })
                .collect()
        };
        let big = b.molecule("big", node, blob(300, 7));
        let small = b.molecule("small", node, blob(5, 11));
        let empty = b.molecule("empty", node, vec![]);
        for (k, m) in [big, small, big, empty, small, big, big, small, big]
            .into_iter()
            .enumerate()
        {
            let op = [
                [1.0, 0.0, 0.0, 40.0 * k as f64],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
            ];
            b.instance_matrix("test", m, op).unwrap();
        }
        b.finish("test").unwrap()
    }

    /// The scene's sphere records as the GPU stores them.
    fn geom_of(scene: &Scene) -> Vec<GpuSphere> {
        scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect()
    }

    /// The 8-byte batch entries give the records a batch table of whole
    /// records would hold, built here the plain way: the static table is
    /// every instance's atoms in runs of 2^shift in expanded order, then
    /// the empty batch; an entry (instance, level, j) of the LOD lists
    /// names run j of that instance's level (its atoms stored after the
    /// scene's own, per type and level).
    #[test]
    fn batch_entries_make_the_records_of_a_full_table() {
        let scene = scene();
        let inst = scene.instancing.as_ref().unwrap();
        let geom = geom_of(&scene);
        for lod in [None, Some(4.0)] {
            let built =
                build_instanced(&scene, geom.clone(), vec![0; geom.len()], lod, None).unwrap();
            let t = &built.tables;
            let per = 1u32 << t.shift;
            let mut want: Vec<GpuBatch> = Vec::new();
            for (k, &m) in inst.instance_molecule.iter().enumerate() {
                let mol = &inst.molecules[m as usize];
                for a in (0..mol.atoms).step_by(per as usize) {
                    let n = (mol.atoms - a).min(per);
                    let e = inst.first[k] as u32 + a;
                    want.push([k as u32, mol.first + a, e, n | (m << 8)]);
                }
            }
            want.push([0; 4]);
            let entries = static_entries(&built.batch_first, t.shift, "test").unwrap();
            assert_eq!(entries.len(), want.len(), "lod {lod:?}");
            assert_eq!(built.entries.is_some(), lod.is_none());
            for (b, (e, w)) in entries.iter().zip(&want).enumerate() {
                assert_eq!(t.record(*e).as_ref(), Some(w), "batch {b}, lod {lod:?}");
            }
            if lod.is_none() {
                assert_eq!(built.entries.as_ref(), Some(&entries));
                continue;
            }
            // per type and level >= 1: first stored atom, atoms
            let mut at = geom.len() as u32;
            let mut coarse: Vec<Vec<(u32, u32)>> = Vec::new();
            for mol in &inst.molecules {
                let atoms = &geom[mol.first as usize..(mol.first + mol.atoms) as usize];
                let counts = MoleculeLod::new(atoms).counts;
                let mut levels = Vec::new();
                for &n in counts.iter().skip(1) {
                    levels.push((at, n));
                    at += n;
                }
                coarse.push(levels);
            }
            assert_eq!(built.geom.len() as u32, at);
            assert!(coarse[0].len() >= 3, "the big molecule has levels");
            for (k, &m) in inst.instance_molecule.iter().enumerate() {
                for (l, &(first, n)) in coarse[m as usize].iter().enumerate() {
                    let word = k as u32 | ((l as u32 + 1) << BATCH_INSTANCE_BITS);
                    for (j, a) in (0..n).step_by(per as usize).enumerate() {
                        let c = (n - a).min(per) | (m << 8) | BATCH_COARSE;
                        let w = [k as u32, first + a, inst.first[k] as u32, c];
                        assert_eq!(t.record([word, j as u32]), Some(w), "{k} {l} {j}");
                    }
                }
            }
        }
    }

    /// Each batch of each (type, level) has a bounding sphere that holds
    /// every sphere of that batch (what the cull tests batches by), found
    /// from the level's row (lodBoundTex's box w) and the batch's index.
    #[test]
    fn batch_bounds_hold_their_spheres() {
        let scene = scene();
        let inst = scene.instancing.as_ref().unwrap();
        let geom = geom_of(&scene);
        let built =
            build_instanced(&scene, geom.clone(), vec![0; geom.len()], Some(4.0), None).unwrap();
        let (bounds, batch) = built.lod.as_ref().unwrap();
        let per = 1usize << built.tables.shift;
        let mut checked = 0;
        for m in 0..inst.molecules.len() {
            let levels = (built.tables.levels[m * MAX_LOD_LEVELS as usize][0]
                & crate::gpu::consts::LEVEL_COUNT_MASK) as usize;
            for l in 0..levels {
                let row = m * MAX_LOD_LEVELS as usize + l;
                let [_, first, _, n] = built.tables.levels[row];
                let at = bounds[2 * row + 1][3] as usize;
                let stored = &built.geom[first as usize..(first + n) as usize];
                for (j, chunk) in stored.chunks(per).enumerate() {
                    let b = batch[at + j];
                    let c = glam::Vec3::new(b[0], b[1], b[2]);
                    for a in chunk {
                        let d = glam::Vec3::new(a[0], a[1], a[2]).distance(c) + a[3];
                        assert!(d <= b[3], "type {m} level {l} batch {j}: {d} > {}", b[3]);
                    }
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, batch.len());
        assert!(checked > 10, "{checked}");
    }

    /// An entry naming an instance the tables lack gives no record, one
    /// naming a level its molecule lacks or a batch past the level's
    /// atoms a batch of no atoms or none (no panic).
    #[test]
    fn a_broken_batch_entry_gives_no_record() {
        let scene = scene();
        let geom = geom_of(&scene);
        let t = build_instanced(&scene, geom.clone(), vec![0; geom.len()], None, None)
            .unwrap()
            .tables;
        assert_eq!(t.record([1000, 0]), None);
        // a level instance 2 lacks
        assert!(
            t.record([2 | 3 << BATCH_INSTANCE_BITS, 0])
                .is_none_or(|r| r[3] & 0xFF == 0)
        );
        assert_eq!(t.record([0, 1000]), None);
        assert_eq!(t.record([0, u32::MAX]), None);
    }

    /// Each level's bounds hold every sphere of that level, its grown
    /// radii included (a coarse sphere reaches past the atoms' box), and
    /// the box is no looser than the sphere on any axis.
    #[test]
    fn a_levels_bounds_hold_its_spheres() {
        let mut x = 5u32;
        let mut next = move || {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (x >> 8) as f32 / (1u32 << 24) as f32
        };
        // a rod: 60 x 12 x 12
        let atoms: Vec<[f32; 4]> = (0..2000)
            .map(|_| {
                [
                    next() * 60.0 + 100.0,
                    next() * 12.0,
                    next() * 12.0 - 50.0,
                    1.7,
                ]
            })
            .collect();
        let mut ml = MoleculeLod::new(&atoms);
        ml.switch_ppu(&atoms, 2.0);
        let bounds = lod_bounds(&atoms, &ml);
        assert_eq!(bounds.len(), ml.levels());
        let level0 = bounds[0][0][3];
        for (l, [s, e]) in bounds.iter().enumerate() {
            let c = glam::Vec3::new(s[0], s[1], s[2]);
            assert_eq!(
                c,
                glam::Vec3::new(bounds[0][0][0], bounds[0][0][1], bounds[0][0][2])
            );
            let mut reach = 0.0f32;
            for a in ml.level_spheres(&atoms, l) {
                let d = glam::Vec3::new(a[0], a[1], a[2]) - c;
                reach = reach.max(d.length() + a[3]);
                assert!(d.length() + a[3] <= s[3], "level {l}: sphere");
                for k in 0..3 {
                    assert!(d[k].abs() + a[3] <= e[k], "level {l}: box axis {k}");
                }
            }
            // tight: grown only for rounding
            assert!(s[3] <= reach * 1.001 + 1e-3 + 1e-5, "level {l}");
            assert!(
                e.iter().take(3).all(|&x| x <= s[3]),
                "level {l}: {e:?} {s:?}"
            );
        }
        // the rod's box is thinner than its sphere across it
        assert!(bounds[0][1][1] < 0.5 * bounds[0][0][3], "{:?}", bounds[0]);
        // a coarse level's grown spheres reach past level 0's
        assert!(bounds.iter().any(|b| b[0][3] > level0), "{bounds:?}");
    }

    /// Past the 2^32 sphere ids a scene with levels of detail builds
    /// (the LOD lists' slots are its ids, no static table is made), and
    /// drawing every atom (--lod off, or a mode that draws full detail)
    /// is refused in one line naming the ids needed.
    #[test]
    fn past_2_32_ids_only_the_levels_draw() {
        let mut b = InstancedBuilder::default();
        let node = b.node(&["cell"]);
        let atoms: Vec<Sphere> = (0..4096)
            .map(|i| Sphere {
                center: [
                    (i % 16) as f32 * 1.5,
                    (i / 16 % 16) as f32 * 1.5,
                    (i / 256) as f32 * 1.5,
                ],
                radius: 1.7,
                color: [200, 100, 50, 255],
                region: [0; 4],
            })
            .collect();
        let m = b.molecule("cube", node, atoms);
        // 4.5 * 10^9 atoms: past the static table's 2^32 slots
        for k in 0..1_100_000u32 {
            let t = [k as f64 * 30.0, 0.0, 0.0];
            b.instance_quat("test", m, glam::DQuat::IDENTITY, t)
                .unwrap();
        }
        let scene = b.finish("big").unwrap();
        let geom = geom_of(&scene);
        let built = build_instanced(&scene, geom.clone(), vec![0; 4096], Some(2.0), None).unwrap();
        assert!(built.entries.is_none());
        assert_eq!(*built.batch_first.last().unwrap(), 1_100_000 * 64);
        let Err(e) = static_entries(&built.batch_first, built.tables.shift, "big") else {
            panic!("a static table past 2^32 slots");
        };
        let msg = e.to_string();
        assert!(!msg.contains('\n'), "{msg}");
        assert!(
            msg.starts_with("big: drawing every atom needs 4505600064 sphere ids"),
            "{msg}"
        );
        let Err(e) = build_instanced(&scene, geom, vec![0; 4096], None, None) else {
            panic!("built --lod off past 2^32 slots");
        };
        assert_eq!(e.to_string(), msg);
    }

    /// A see-through copy takes the alpha-weighted mean colour (linear
    /// light) of the atoms it stands for; an opaque copy its source's.
    #[test]
    fn see_through_copies_take_their_atoms_mean_colour() {
        // RGBA8 words, red lowest; alpha above
        let word = |r: u32, g: u32, b: u32, a: u32| r | g << 8 | b << 16 | a << 24;
        let words = [
            word(255, 0, 0, 128),
            word(0, 0, 255, 128),
            word(0, 255, 0, 255),
            word(255, 255, 255, 0),
            word(188, 188, 188, 128),
        ];
        let sources = CoarseSources {
            copies: vec![
                (0, 1.0, [0, 2]),
                (2, 1.0, [0, 3]),
                (1, 1.0, [1, 3]),
                (0, 2.0, [0, 2]),
                (4, 1.0, [3, 1]),
            ],
            runs: vec![0, 1, 2, 3],
        };
        // red and blue at equal weight: each half its linear value, 188
        assert_eq!(sources.colour(&words, 0), word(188, 0, 188, 128));
        // an opaque copy keeps its source's colour
        assert_eq!(sources.colour(&words, 1), words[2]);
        // blue at 128, green at 255, white at alpha 0 (no weight): linear
        // blue 128/383 -> 156, green 255/383 -> 213
        assert_eq!(sources.colour(&words, 2), word(0, 213, 156, 128));
        // the level's alpha exponent raises the copy's alpha
        assert_eq!(sources.colour(&words, 3), word(188, 0, 188, 192));
        // nothing but an invisible atom to average: the source's colour
        assert_eq!(sources.colour(&words, 4), words[4]);
    }
}
