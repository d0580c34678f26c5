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
    MAX_BATCH_SHIFT, MAX_LOD_LEVELS, MIN_BATCH_SHIFT, NO_LEVEL, SCENE_AFFINE, SCENE_PLAIN,
    SCENE_RIGID,
};
use crate::gpu::{GpuBatch, GpuSphere, SphereAttr};
use crate::scene::Scene;
use crate::scene::instanced::extremes::Extremes;
use crate::scene::instanced::lod::MoleculeLod;
use crate::scene::instanced::{LevelKind, Transforms};
use crate::vk::pipeline::{Binding, texel};
use crate::vk::{Buffer, Context};
use ash::vk::Format;
use glam::DVec3;

/// What scene.glsl reads for geometry: `scene_sphere`, `scene_index`.
pub const SCENE_GEOMETRY: [Binding; 6] = [
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("batchTex", Format::R32_UINT),
    texel("instanceTex", Format::R32G32B32A32_SFLOAT),
    texel("originTex", Format::R32_UINT),
    texel("instanceRowTex", Format::R32G32B32A32_UINT),
    texel("levelTex", Format::R32G32B32A32_UINT),
];

/// What scene.glsl reads for colours and regions (SCENE_ATTRIBUTES).
pub const SCENE_ATTRIBUTES: [Binding; 3] = [
    texel("attrTex", Format::R32_UINT),
    texel("colorTex", Format::R32_UINT),
    texel("moleculeTex", Format::R32_UINT),
];

/// Most slots an instanced scene may have: ids are 32-bit and ~0 means
/// "no sphere".
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
    /// Instanced: the batches (4 B per 2^shift slots: [`BatchTables::words`]).
    pub batches: Buffer,
    /// Instanced: [`BatchTables::rows`] (16 B per instance).
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
    /// Ids a per-sphere dispatch covers: the spheres, or every slot of the
    /// batches.
    pub slots: u32,
    /// The slots of level 0 (every atom of every instance, expanded
    /// order): what a pass that draws full detail covers. `slots` less the
    /// coarse levels' batches.
    pub base_slots: u32,
    /// The levels of detail (instanced scenes, `--lod auto`).
    pub lod: Option<LodBuffers>,
    /// Atoms of the scene's own (`Scene::spheres`); the colour buffer holds
    /// them, then the coarse copies (`coarse_source`).
    base_atoms: u32,
    /// Per coarse stored atom: the stored atom it copies.
    coarse_source: Vec<u32>,
}

/// The tables of the LOD cull (glsl/lod_cull.comp).
/// (The levels and each instance's first batches are the scene's
/// [`SceneBuffers::levels`] and [`SceneBuffers::rows`].)
pub struct LodBuffers {
    /// Per molecule type, RGBA32F: bounding sphere in its frame.
    pub bounds: Buffer,
    pub instance_count: u32,
    /// The batch with no atoms (what unused list entries name).
    pub empty_batch: u32,
    /// Level-0 batches: the most a view lists (an instance draws one
    /// level).
    pub base_batches: u32,
}

impl SceneBuffers {
    /// The geometry buffers, by the names of [`SCENE_GEOMETRY`].
    pub fn geometry(&self) -> [(&'static str, &Buffer); 6] {
        [
            ("sphereTex", &self.spheres),
            ("batchTex", &self.batches),
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

    /// Device memory by class: plain `scene`; instanced `molecules` (the
    /// atoms and their attributes), `instances`, and `scene` (batches).
    pub fn memory(&self) -> Vec<(&'static str, u64)> {
        let atoms = self.spheres.size + self.attrs.size + self.colors.size;
        if self.kind() == SCENE_PLAIN {
            return vec![("scene", atoms)];
        }
        let lod_mol = self
            .lod
            .as_ref()
            .map_or(0, |l| l.bounds.size + self.origins.size);
        vec![
            (
                "molecules",
                atoms + self.molecules.size + self.levels.size + lod_mol,
            ),
            ("instances", self.instances.size + self.rows.size),
            ("scene", self.batches.size),
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
        let coarse: Vec<u32> = self
            .coarse_source
            .iter()
            .map(|&i| out[i as usize])
            .collect();
        out.extend(coarse);
        Ok(out)
    }

    /// Uploads `scene`: its buffers and the CPU copy of its geometry;
    /// with `lod_pixels` (`--lod auto`) an instanced scene's levels of
    /// detail too.
    pub fn new(ctx: &Context, scene: &Scene, lod_pixels: Option<f32>) -> Result<(Self, SceneGeom)> {
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
            buffers.base_slots = buffers.slots;
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
            base_batches,
            lod: lod_tables,
        } = build_instanced(scene, geom, colors, lod_pixels)?;
        let shift = tables.shift;
        let tree: Vec<u32> = inst.tree_regions.iter().flatten().copied().collect();
        let (kind, transform_bytes): (u32, &[u8]) = match &inst.transforms {
            Transforms::Rigid(v) => (SCENE_RIGID, bytemuck::cast_slice(v)),
            Transforms::Affine(v) => (SCENE_AFFINE, bytemuck::cast_slice(v)),
        };
        let mut buffers = Self::upload(
            ctx,
            kind | (shift << 8),
            (tables.words.len() as u64) << shift,
            [
                ("molecule atoms", bytemuck::cast_slice(&geom)),
                ("atom chains", bytemuck::cast_slice(&chains)),
                ("atom colours", bytemuck::cast_slice(&colors)),
                ("scene batches", bytemuck::cast_slice(&tables.words)),
                ("instances", transform_bytes),
                ("molecule regions", bytemuck::cast_slice(&tree)),
                ("atom origins", bytemuck::cast_slice(&origins)),
                ("instance rows", bytemuck::cast_slice(&tables.rows)),
                ("molecule levels", bytemuck::cast_slice(&tables.levels)),
            ],
        )?;
        buffers.base_slots = base_batches << shift;
        // (the scene's own atoms: the coarse copies follow them)
        buffers.base_atoms = scene.spheres.len() as u32;
        buffers.coarse_source = coarse_source;
        if let Some((bounds, empty_batch)) = lod_tables {
            let b = ctx.guard(Buffer::table(
                ctx,
                "LOD bounds",
                (bounds.len() as u64 * 16).max(16),
            )?);
            b.upload(ctx, 0, bytemuck::cast_slice(&bounds))?;
            buffers.lod = Some(LodBuffers {
                bounds: b.keep(),
                instance_count: inst.instances() as u32,
                empty_batch,
                base_batches,
            });
        }
        let geom = SceneGeom::Instanced(Box::new(InstancedGeom {
            atoms: geom,
            transforms: inst.transforms.clone(),
            instance_molecule: inst.instance_molecule.clone(),
            molecules: inst.molecules.iter().map(|m| (m.first, m.atoms)).collect(),
            first: inst.first.clone(),
            tables,
            base_batches: base_batches as usize,
            origins,
            shift,
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
            slots: slots as u32,
            base_slots: slots as u32,
            lod: None,
            base_atoms: 0,
            coarse_source: Vec::new(),
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
    coarse_source: Vec<u32>,
    tables: BatchTables,
    base_batches: u32,
    /// With levels of detail: the molecule types' bounding spheres, the
    /// empty batch.
    lod: Option<(Vec<[f32; 4]>, u32)>,
}

/// The tables of instanced `scene` (its atoms `geom` and colour words
/// `colors`); with `lod_pixels` its levels of detail too.
fn build_instanced(
    scene: &Scene,
    mut geom: Vec<GpuSphere>,
    mut colors: Vec<u32>,
    lod_pixels: Option<f32>,
) -> Result<Built> {
    let Some(inst) = &scene.instancing else {
        return Err(Error::Internal("instanced tables of a plain scene".into()));
    };
    let shift = batch_shift(scene);
    let per = 1u32 << shift;
    let mut tables = base_tables(scene, shift)?;
    let base_batches = tables.words.len() as u32;
    let mut chains: Vec<u32> = scene.spheres.iter().map(|s| s.region[0]).collect();
    let lod = match lod_pixels {
        Some(p) => Some(lod_of(scene, &geom, p)?),
        None => None,
    };
    // The coarse levels' atoms after the scene's own, their batches
    // after level 0's, then the empty batch.
    let mut origins: Vec<u32> = Vec::new();
    let mut coarse_source: Vec<u32> = Vec::new();
    let mut lod_tables = None;
    if let Some(lod) = &lod {
        origins = vec![0; geom.len()];
        // per molecule type: per level, its first stored atom
        let mut level_first: Vec<Vec<u32>> = Vec::with_capacity(inst.molecules.len());
        for (m, mol) in inst.molecules.iter().enumerate() {
            let ml = &lod[m].levels;
            let own = mol.first as usize..(mol.first + mol.atoms) as usize;
            let mut firsts = vec![mol.first];
            for l in 1..ml.levels() {
                firsts.push(geom.len() as u32);
                let spheres = ml.level_spheres(&geom[own.clone()], l);
                geom.extend(spheres);
                for &a in &ml.order[..ml.counts[l] as usize] {
                    let src = mol.first + a;
                    chains.push(chains[src as usize]);
                    colors.push(colors[src as usize]);
                    origins.push(a);
                    coarse_source.push(src);
                }
            }
            level_first.push(firsts);
        }
        // the level rows, and each type's coarse batches
        let mut coarse_batches = vec![0u32; inst.molecules.len()];
        for (
            m,
            Lod {
                levels: ml, switch, ..
            },
        ) in lod.iter().enumerate()
        {
            let mut off = 0u32;
            for l in 0..ml.levels() {
                let first = if l == 0 { ml.levels() as u32 } else { off };
                tables.levels[m * MAX_LOD_LEVELS as usize + l] =
                    [first, level_first[m][l], switch[l].to_bits(), ml.counts[l]];
                if l > 0 {
                    off += ml.counts[l].div_ceil(per);
                }
            }
            coarse_batches[m] = off;
        }
        let coarse_total: u64 = inst
            .instance_molecule
            .iter()
            .map(|&m| coarse_batches[m as usize] as u64)
            .sum();
        let needed = (base_batches as u64 + coarse_total + 1) << shift;
        if needed > MAX_SLOTS {
            // (the coarse levels' share scales with the atoms)
            let fit = inst.represented() as u128 * MAX_SLOTS as u128 / needed as u128;
            return Err(Error::Input(format!(
                "{}: {} atoms with their levels of detail need {needed} sphere ids, more than \
                 the {MAX_SLOTS} sphereshade has: about {fit} atoms fit (--lod off needs none \
                 for the levels, but draws every atom every frame)",
                scene.source,
                inst.represented()
            )));
        }
        // (reserved exactly: a doubling growth would hold up to twice
        // the table for a moment)
        tables.words.reserve_exact(coarse_total as usize + 1);
        for (k, &m) in inst.instance_molecule.iter().enumerate() {
            let mu = m as usize;
            tables.rows[k][2] = tables.words.len() as u32;
            for (l, &n) in lod[mu].levels.counts.iter().enumerate().skip(1) {
                let word = k as u32 | (l as u32) << BATCH_INSTANCE_BITS;
                let nb = n.div_ceil(per) as usize;
                tables.words.extend(std::iter::repeat_n(word, nb));
            }
        }
        let empty_batch = tables.words.len() as u32;
        tables.words.push(BATCH_EMPTY);
        // (MAX_LOD_LEVELS rows per type, as levelTex)
        let mut bounds = vec![[0.0f32; 4]; 2 * lod.len() * MAX_LOD_LEVELS as usize];
        for (m, l) in lod.iter().enumerate() {
            for (i, b) in l.bound.iter().enumerate() {
                let at = 2 * (m * MAX_LOD_LEVELS as usize + i);
                bounds[at..at + 2].copy_from_slice(b);
            }
        }
        lod_tables = Some((bounds, empty_batch));
    }
    Ok(Built {
        geom,
        chains,
        colors,
        origins,
        coarse_source,
        tables,
        base_batches,
        lod: lod_tables,
    })
}

/// An instanced scene's batches as the GPU stores them: a word per batch
/// (its instance and level), a row per instance, a row per (molecule
/// type, level). [`BatchTables::record`] makes a batch's record from them
/// as glsl/scene.glsl `scene_batch` does (4 bytes a batch, not the 16 of
/// a stored record: 86 MB instead of 344 at 10^9 atoms).
pub struct BatchTables {
    /// Per batch: instance | level << BATCH_INSTANCE_BITS, or BATCH_EMPTY.
    pub words: Vec<u32>,
    /// Per instance: molecule type, first level-0 batch, first coarse
    /// batch (0 without levels of detail), expanded index of its first
    /// atom.
    pub rows: Vec<[u32; 4]>,
    /// Per (molecule type, level < MAX_LOD_LEVELS): the level's first
    /// batch within an instance's coarse batches (level 0: the number of
    /// levels), its first stored atom, its switch size (f32 bits: most
    /// pixels per world unit it is drawn at), its atoms.
    pub levels: Vec<[u32; 4]>,
    /// Slots a batch: 2^shift.
    pub shift: u32,
}

impl BatchTables {
    /// Batch `b`'s record: instance, first stored atom, the expanded index
    /// of that atom (a coarse batch: of its instance's first), atom count
    /// | molecule type << 8 | BATCH_COARSE; zeros for the empty batch.
    pub fn record(&self, b: u32) -> Option<GpuBatch> {
        let w = *self.words.get(b as usize)?;
        if w == BATCH_EMPTY {
            return Some([0; 4]);
        }
        let (k, l) = (w & BATCH_INSTANCE_MASK, w >> BATCH_INSTANCE_BITS);
        let row = self.rows.get(k as usize)?;
        let lv = self
            .levels
            .get((row[0] * MAX_LOD_LEVELS + l.min(MAX_LOD_LEVELS - 1)) as usize)?;
        let coarse = l != 0;
        let first = if coarse { row[2] + lv[0] } else { row[1] };
        let a = b.checked_sub(first)? << self.shift;
        Some([
            k,
            lv[1] + a,
            row[3] + if coarse { 0 } else { a },
            lv[3].checked_sub(a)?.min(1 << self.shift)
                | (row[0] << 8)
                | if coarse { BATCH_COARSE } else { 0 },
        ])
    }
}

/// The batch tables of an instanced scene at full detail: each instance's
/// atoms in runs of 2^shift, in expanded order (slot order is expanded
/// order); one level per molecule type.
fn base_tables(scene: &Scene, shift: u32) -> Result<BatchTables> {
    let Some(inst) = &scene.instancing else {
        return Err(Error::Internal("batches of a plain scene".into()));
    };
    let per = 1u64 << shift;
    let count: u64 = inst
        .instance_molecule
        .iter()
        .map(|&m| (inst.molecules[m as usize].atoms as u64).div_ceil(per))
        .sum();
    if count * per > MAX_SLOTS || inst.represented() > u32::MAX as u64 - 1 {
        return Err(Error::Input(format!(
            "{}: {} spheres in {count} batches of {per}: more than the 2^32 sphere ids \
             sphereshade has",
            scene.source,
            inst.represented()
        )));
    }
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
    let mut words = Vec::with_capacity(count as usize);
    let mut rows = Vec::with_capacity(inst.instances());
    for (k, &m) in inst.instance_molecule.iter().enumerate() {
        rows.push([m, words.len() as u32, 0, inst.first[k] as u32]);
        let nb = (inst.molecules[m as usize].atoms as u64).div_ceil(per);
        words.extend(std::iter::repeat_n(k as u32, nb as usize));
    }
    Ok(BatchTables {
        words,
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
    /// Expanded index of each instance's first atom (+ the total).
    pub first: Vec<u64>,
    pub tables: BatchTables,
    /// Level 0's batches (the coarse levels' follow).
    pub base_batches: usize,
    /// Per stored atom of a coarse level: the atom it stands for (index
    /// within its molecule); empty without levels of detail.
    pub origins: Vec<u32>,
    /// Slots a batch: 2^shift.
    pub shift: u32,
}

impl InstancedGeom {
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
            SceneGeom::Instanced(i) => (i.base_batches as u32) << i.shift,
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

    /// The expanded index of sphere id `id` (a slot of an instanced scene).
    pub fn expanded_id(&self, id: u32) -> Option<u64> {
        match self {
            SceneGeom::Plain(g) => ((id as usize) < g.len()).then_some(id as u64),
            SceneGeom::Instanced(i) => {
                let b = i.tables.record(id >> i.shift)?;
                let lane = id & ((1 << i.shift) - 1);
                if lane >= (b[3] & 0xFF) {
                    return None;
                }
                let atom = if b[3] & BATCH_COARSE != 0 {
                    *i.origins.get((b[1] + lane) as usize)?
                } else {
                    lane
                };
                Some(b[2] as u64 + atom as u64)
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
                // (level 0's batches: the coarse ones are listed by the LOD
                // cull, never by a view order)
                (0..i.base_batches)
                    .filter_map(|b| Some((b, i.tables.record(b as u32)?)))
                    .map(|(b, batch)| {
                        let (k, m) = (
                            batch[0] as usize,
                            ((batch[3] >> 8) & BATCH_TYPE_MASK) as usize,
                        );
                        let run = (batch[1] - i.molecules[m].0) as usize / per;
                        let c = i.transforms.apply(k, local[m][run]);
                        let first = (b << i.shift) as u32;
                        (
                            DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64),
                            first..first + per as u32,
                        )
                    })
                    .collect()
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
        match self {
            SceneGeom::Plain(_) => None,
            SceneGeom::Instanced(i) => Some(Extremes::new(
                &i.transforms,
                &i.instance_molecule,
                i.molecules.clone(),
                std::borrow::Cow::Borrowed(&i.atoms),
            )),
        }
    }

    /// Along each of `axes`, the least `centre . axis - radius` and the
    /// largest `centre . axis + radius` over every represented sphere
    /// (None: no spheres): what a light view is fitted to.
    pub fn extent_along(&self, axes: [DVec3; 3]) -> Option<(DVec3, DVec3)> {
        if let Some(e) = self.extremes() {
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
fn lod_of(scene: &Scene, geom: &[GpuSphere], pixels: f32) -> Result<Vec<Lod>> {
    let Some(inst) = &scene.instancing else {
        return Ok(Vec::new());
    };
    let one = |mol: &crate::scene::instanced::Molecule| -> Result<Lod> {
        let atoms = &geom[mol.first as usize..(mol.first + mol.atoms) as usize];
        let mut ml = MoleculeLod::new(atoms);
        if ml.levels() > MAX_LOD_LEVELS as usize {
            return Err(Error::Internal(format!(
                "{}: {} levels of detail",
                mol.label,
                ml.levels()
            )));
        }
        let switch = ml.switch_ppu(atoms, pixels);
        let bound = lod_bounds(atoms, &ml);
        Ok(Lod {
            levels: ml,
            switch,
            bound,
        })
    };
    // The molecule types on every core (their silhouette fits are the
    // renderer's start-up: SARS-CoV-2's 2.4 s on one): each thread takes
    // the next type, the results land in type order.
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut done: Vec<(usize, Result<Lod>)> = std::thread::scope(|sc| {
        let workers: Vec<_> = (0..threads.min(inst.molecules.len()))
            .map(|_| {
                sc.spawn(|| {
                    let mut got = Vec::new();
                    loop {
                        let m = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(mol) = inst.molecules.get(m) else {
                            return got;
                        };
                        got.push((m, one(mol)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_default())
            .collect()
    });
    if done.len() != inst.molecules.len() {
        return Err(Error::Internal("a level-of-detail worker failed".into()));
    }
    done.sort_by_key(|d| d.0);
    done.into_iter().map(|d| d.1).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Sphere;
    use crate::scene::instanced::InstancedBuilder;

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

    /// The stored 4-byte batches give the records a batch table of whole
    /// records would hold, built here the plain way: every instance's
    /// atoms in runs of 2^shift in expanded order, then every instance's
    /// coarse levels' runs (their atoms stored after the scene's own, per
    /// type and level), then the empty batch.
    #[test]
    fn batch_words_make_the_records_of_a_full_table() {
        let scene = scene();
        let inst = scene.instancing.as_ref().unwrap();
        let geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        for lod in [None, Some(4.0)] {
            let built = build_instanced(&scene, geom.clone(), vec![0; geom.len()], lod).unwrap();
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
            assert_eq!(built.base_batches as usize, want.len());
            if lod.is_some() {
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
                    for &(first, n) in &coarse[m as usize] {
                        for a in (0..n).step_by(per as usize) {
                            let c = (n - a).min(per) | (m << 8) | BATCH_COARSE;
                            want.push([k as u32, first + a, inst.first[k] as u32, c]);
                        }
                    }
                }
                want.push([0; 4]);
            }
            assert_eq!(t.words.len(), want.len(), "lod {lod:?}");
            for (b, w) in want.iter().enumerate() {
                assert_eq!(
                    t.record(b as u32).as_ref(),
                    Some(w),
                    "batch {b}, lod {lod:?}"
                );
            }
            assert_eq!(t.record(want.len() as u32), None);
        }
    }

    /// A word naming an instance the tables lack gives no record, one
    /// naming a level its molecule lacks a batch of no atoms (no panic).
    #[test]
    fn a_broken_batch_word_gives_no_record() {
        let scene = scene();
        let geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let mut t = build_instanced(&scene, geom.clone(), vec![0; geom.len()], None)
            .unwrap()
            .tables;
        t.words[0] = 1000;
        assert_eq!(t.record(0), None);
        t.words[0] = 2 | 3 << BATCH_INSTANCE_BITS; // a level instance 2 lacks
        assert!(t.record(0).is_none_or(|r| r[3] & 0xFF == 0));
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

    /// Levels of detail past the 2^32 sphere ids are refused in one line
    /// that says how many atoms fit (before any table is built).
    #[test]
    fn too_many_slots_for_the_levels_is_one_clear_line() {
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
        // 3.5 * 10^9 atoms: under MAX_REPRESENTED, but with their coarse
        // levels past 2^32 slots
        for k in 0..854_500u32 {
            let t = [k as f64 * 30.0, 0.0, 0.0];
            b.instance_quat("test", m, glam::DQuat::IDENTITY, t)
                .unwrap();
        }
        let scene = b.finish("big").unwrap();
        let geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let Err(e) = build_instanced(&scene, geom, vec![0; 4096], Some(2.0)) else {
            panic!("built past 2^32 slots");
        };
        let msg = e.to_string();
        assert!(!msg.contains('\n'), "{msg}");
        assert!(msg.starts_with("big: 3500032000 atoms"), "{msg}");
        let fit: u64 = msg
            .split("about ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .and_then(|n| n.parse().ok())
            .expect("the atoms that fit");
        assert!((2_500_000_000..3_500_000_000).contains(&fit), "{msg}");
    }
}
