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
    BATCH_COARSE, BATCH_TYPE_MASK, MAX_BATCH_SHIFT, MAX_LOD_LEVELS, MIN_BATCH_SHIFT, NO_LEVEL,
    SCENE_AFFINE, SCENE_PLAIN, SCENE_RIGID,
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
pub const SCENE_GEOMETRY: [Binding; 4] = [
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("batchTex", Format::R32G32B32A32_UINT),
    texel("instanceTex", Format::R32G32B32A32_SFLOAT),
    texel("originTex", Format::R32_UINT),
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
    /// Instanced: the batches (16 B per 2^shift slots).
    pub batches: Buffer,
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
pub struct LodBuffers {
    /// Per (molecule type, level < MAX_LOD_LEVELS), RGBA32UI: first batch
    /// of the level within an instance's coarse batches (level 0: the
    /// number of levels), its batches, its switch size (f32 bits: most
    /// pixels per world unit it is drawn at), its spheres.
    pub levels: Buffer,
    /// Per molecule type, RGBA32F: bounding sphere in its frame.
    pub bounds: Buffer,
    /// Per instance, RGBA32UI: molecule type, first level-0 batch, first
    /// coarse batch, 0.
    pub instances: Buffer,
    pub instance_count: u32,
    /// The batch with no atoms (what unused list entries name).
    pub empty_batch: u32,
    /// Level-0 batches: the most a view lists (an instance draws one
    /// level).
    pub base_batches: u32,
}

impl SceneBuffers {
    /// The geometry buffers, by the names of [`SCENE_GEOMETRY`].
    pub fn geometry(&self) -> [(&'static str, &Buffer); 4] {
        [
            ("sphereTex", &self.spheres),
            ("batchTex", &self.batches),
            ("instanceTex", &self.instances),
            ("originTex", &self.origins),
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
        let (lod_mol, lod_inst) = self.lod.as_ref().map_or((0, 0), |l| {
            (
                l.levels.size + l.bounds.size + self.origins.size,
                l.instances.size,
            )
        });
        vec![
            ("molecules", atoms + self.molecules.size + lod_mol),
            ("instances", self.instances.size + lod_inst),
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
        let mut geom: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let mut colors: Vec<u32> = scene
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
            // (batches, instances and molecules: bound, never read)
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
                ],
            )?;
            buffers.base_slots = buffers.slots;
            buffers.base_atoms = geom.len() as u32;
            return Ok((buffers, SceneGeom::Plain(geom)));
        };
        let shift = batch_shift(scene);
        let mut batches = batches_of(scene, shift)?;
        let base_batches = batches.len() as u32;
        let base_atoms = geom.len() as u32;
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
            let per = 1u32 << shift;
            // per molecule type: per level >= 1, its first stored atom
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
            // the level table: per (type, level) first batch within the
            // instance's coarse batches, batches, switch size, spheres
            let mut levels = vec![[0u32; 4]; inst.molecules.len() * MAX_LOD_LEVELS as usize];
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
                    let nb = ml.counts[l].div_ceil(per);
                    let first = if l == 0 { ml.levels() as u32 } else { off };
                    levels[m * MAX_LOD_LEVELS as usize + l] =
                        [first, nb, switch[l].to_bits(), ml.counts[l]];
                    if l > 0 {
                        off += nb;
                    }
                }
                coarse_batches[m] = off;
            }
            // (reserved exactly: at 10^9 atoms the table is ~330 MiB, and a
            // doubling growth would hold twice that for a moment)
            let coarse_total: u64 = inst
                .instance_molecule
                .iter()
                .map(|&m| coarse_batches[m as usize] as u64)
                .sum();
            batches.reserve_exact(coarse_total as usize + 1);
            let mut inst_rows = Vec::with_capacity(inst.instances());
            let mut first0 = 0u32;
            for (k, &m) in inst.instance_molecule.iter().enumerate() {
                let mu = m as usize;
                inst_rows.push([m, first0, batches.len() as u32, 0]);
                first0 += inst.molecules[mu].atoms.div_ceil(per);
                for (&n, &at) in lod[mu].levels.counts.iter().zip(&level_first[mu]).skip(1) {
                    let mut a = 0;
                    while a < n {
                        let c = (n - a).min(per);
                        batches.push([
                            k as u32,
                            at + a,
                            inst.first[k] as u32,
                            c | (m << 8) | BATCH_COARSE,
                        ]);
                        a += c;
                    }
                }
                debug_assert_eq!(batches.len() as u32, inst_rows[k][2] + coarse_batches[mu]);
            }
            let empty_batch = batches.len() as u32;
            batches.push([0, 0, 0, 0]);
            if (batches.len() as u64) << shift > MAX_SLOTS {
                return Err(Error::Input(format!(
                    "{}: the levels of detail need more than the 2^32 sphere ids sphereshade has \
                     (--lod off draws without them)",
                    scene.source
                )));
            }
            let bounds: Vec<[f32; 4]> = lod.iter().map(|l| l.bound).collect();
            lod_tables = Some((levels, bounds, inst_rows, empty_batch));
        }
        let tree: Vec<u32> = inst.tree_regions.iter().flatten().copied().collect();
        let (kind, transform_bytes): (u32, &[u8]) = match &inst.transforms {
            Transforms::Rigid(v) => (SCENE_RIGID, bytemuck::cast_slice(v)),
            Transforms::Affine(v) => (SCENE_AFFINE, bytemuck::cast_slice(v)),
        };
        let mut buffers = Self::upload(
            ctx,
            kind | (shift << 8),
            (batches.len() as u64) << shift,
            [
                ("molecule atoms", bytemuck::cast_slice(&geom)),
                ("atom chains", bytemuck::cast_slice(&chains)),
                ("atom colours", bytemuck::cast_slice(&colors)),
                ("scene batches", bytemuck::cast_slice(&batches)),
                ("instances", transform_bytes),
                ("molecule regions", bytemuck::cast_slice(&tree)),
                ("atom origins", bytemuck::cast_slice(&origins)),
            ],
        )?;
        buffers.base_slots = base_batches << shift;
        buffers.base_atoms = base_atoms;
        buffers.coarse_source = coarse_source;
        if let Some((levels, bounds, rows, empty_batch)) = lod_tables {
            let mut made = ctx.guard(Vec::new());
            for (name, bytes) in [
                ("LOD levels", bytemuck::cast_slice::<[u32; 4], u8>(&levels)),
                ("LOD bounds", bytemuck::cast_slice(&bounds)),
                ("LOD instances", bytemuck::cast_slice(&rows)),
            ] {
                let b = ctx.guard(Buffer::table(ctx, name, bytes.len().max(16) as u64)?);
                b.upload(ctx, 0, bytes)?;
                made.push(b.keep());
            }
            let [levels, bounds, instances]: [Buffer; 3] = made
                .keep()
                .try_into()
                .map_err(|_| Error::Internal("LOD buffers".into()))?;
            buffers.lod = Some(LodBuffers {
                levels,
                bounds,
                instances,
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
            batches,
            base_batches: base_batches as usize,
            origins,
            shift,
        }));
        Ok((buffers, geom))
    }

    /// The seven buffers (named, with their bytes) in field order; an
    /// error part way destroys what was made. An instanced scene's are
    /// read-only texel tables (not bound by the storage range: its batch
    /// table passes 128 MiB near 10^9 atoms); a plain scene's spheres are
    /// also the graphics rasterizer's storage buffer.
    fn upload(ctx: &Context, spec: u32, slots: u64, data: [(&str, &[u8]); 7]) -> Result<Self> {
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
        ]: [Buffer; 7] = made
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
        ] {
            b.destroy(ctx);
        }
        if let Some(l) = &mut self.lod {
            l.levels.destroy(ctx);
            l.bounds.destroy(ctx);
            l.instances.destroy(ctx);
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
/// lanes (slots) plus four per batch (its 16-byte record and its view
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

/// The batches of an instanced scene: each instance's atoms in runs of
/// 2^shift, in expanded order (slot order is expanded order).
fn batches_of(scene: &Scene, shift: u32) -> Result<Vec<GpuBatch>> {
    let Some(inst) = &scene.instancing else {
        return Ok(Vec::new());
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
    let mut out = Vec::with_capacity(count as usize);
    for (k, &m) in inst.instance_molecule.iter().enumerate() {
        let mol = &inst.molecules[m as usize];
        let mut a = 0u32;
        while a < mol.atoms {
            let n = (mol.atoms - a).min(per as u32);
            out.push([
                k as u32,
                mol.first + a,
                (inst.first[k] + a as u64) as u32,
                n | (m << 8),
            ]);
            a += n;
        }
    }
    Ok(out)
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
    pub batches: Vec<GpuBatch>,
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
                let b = i.batches.get((id >> i.shift) as usize)?;
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
                i.batches[..i.base_batches]
                    .iter()
                    .enumerate()
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
    /// Bounding sphere in the molecule's frame.
    bound: [f32; 4],
}

/// Every molecule type's levels (`pixels`: `--lod-pixels`).
fn lod_of(scene: &Scene, geom: &[GpuSphere], pixels: f32) -> Result<Vec<Lod>> {
    let Some(inst) = &scene.instancing else {
        return Ok(Vec::new());
    };
    let one = |mol: &crate::scene::instanced::Molecule| -> Result<Lod> {
        let atoms = &geom[mol.first as usize..(mol.first + mol.atoms) as usize];
        let ml = MoleculeLod::new(atoms);
        if ml.levels() > MAX_LOD_LEVELS as usize {
            return Err(Error::Internal(format!(
                "{}: {} levels of detail",
                mol.label,
                ml.levels()
            )));
        }
        let switch = ml.switch_ppu(atoms, pixels);
        // (grown a little against the f32 rounding of the transforms)
        let (c, r) = box_sphere(|| atoms.iter().map(|a| ([a[0], a[1], a[2]], a[3])))
            .unwrap_or((glam::Vec3::ZERO, 0.0));
        Ok(Lod {
            levels: ml,
            switch,
            bound: [c.x, c.y, c.z, r * 1.001 + 1e-3],
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
