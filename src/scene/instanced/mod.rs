//! Instanced scenes (mesoscale models): each molecule type's atoms stored
//! once in its own frame, each copy a rigid (or, as stored, affine)
//! transform, and a hierarchy tree whose levels separate regions for
//! semantic SSDO. A scene is never expanded to load or draw it; the
//! expanded order (DESIGN.md "Instanced scenes") is what ids name:
//! instances in order, each its molecule's atoms in order.
//!
//! The world position of an atom is computed by [`apply_rigid`] or
//! [`apply_affine`], in f32 with a fixed order of operations, and the GPU
//! (glsl/scene.glsl) computes the very same bits (`precise`): an instanced
//! render equals the render of [`Scene::expand`] byte for byte.

use super::{MAX_LEVELS, Scene, SceneError, Sphere};
use bytemuck::{Pod, Zeroable};
use glam::{DMat3, DQuat, DVec3, Vec3};

/// A molecule type: a run of `Scene::spheres` (its atoms, in its own frame;
/// `region[0]` is the atom's chain index within the molecule).
#[derive(Clone, Debug, PartialEq)]
pub struct Molecule {
    pub label: String,
    /// First atom and count in `Scene::spheres`.
    pub first: u32,
    pub atoms: u32,
    /// Its node in the hierarchy tree (a leaf, usually).
    pub node: u32,
    /// Distinct chains among its atoms (chain indices 0..chains).
    pub chains: u32,
    /// A nested scene's proxy ([`nested`]): per atom, the expanded index
    /// within its placement of the atom it stands for (what ids name at
    /// every level of detail). None: atom a names atom a.
    pub origin: Option<Vec<u32>>,
}

/// A node of the hierarchy tree (node 0 is the root).
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    pub label: String,
    pub parent: Option<u32>,
    pub depth: u32,
}

/// A rigid transform as the GPU holds it (32 bytes): a unit quaternion
/// (x, y, z, w) and a translation (w unused, 0).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct Rigid {
    pub q: [f32; 4],
    pub t: [f32; 4],
}

/// An affine transform as stored (3 rows: m00 m01 m02 v0, ...), for
/// operators that are not rigid (cellPACK bead exports, 3 decimals).
pub type Affine = [[f32; 4]; 3];

#[derive(Clone, Debug, PartialEq)]
pub enum Transforms {
    Rigid(Vec<Rigid>),
    Affine(Vec<Affine>),
}

impl Transforms {
    pub fn len(&self) -> usize {
        match self {
            Transforms::Rigid(v) => v.len(),
            Transforms::Affine(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Instance `k`'s transform applied to a point of its molecule.
    #[inline]
    pub fn apply(&self, k: usize, x: [f32; 3]) -> [f32; 3] {
        match self {
            Transforms::Rigid(v) => apply_rigid(&v[k], x),
            Transforms::Affine(v) => apply_affine(&v[k], x),
        }
    }

    /// Instance `k`'s transform as stored, bit for bit (rigid: the last
    /// four words 0): equal keys place a molecule's atoms at equal bits.
    pub fn key(&self, k: usize) -> [u32; 12] {
        let mut key = [0u32; 12];
        match self {
            Transforms::Rigid(v) => {
                for (w, x) in key.iter_mut().zip(v[k].q.iter().chain(&v[k].t)) {
                    *w = x.to_bits();
                }
            }
            Transforms::Affine(v) => {
                for (w, x) in key.iter_mut().zip(v[k].iter().flatten()) {
                    *w = x.to_bits();
                }
            }
        }
        key
    }

    /// GPU bytes per instance.
    pub fn bytes_per_instance(&self) -> usize {
        match self {
            Transforms::Rigid(_) => std::mem::size_of::<Rigid>(),
            Transforms::Affine(_) => std::mem::size_of::<Affine>(),
        }
    }
}

/// x' = R(q) x + t as glsl/scene.glsl computes it: u = 2 (q.xyz × x),
/// x' = ((x + w u) + q.xyz × u) + t, each operation rounded to f32 (no
/// fused multiply-add on either side).
#[inline]
pub fn apply_rigid(r: &Rigid, x: [f32; 3]) -> [f32; 3] {
    let [qx, qy, qz, qw] = r.q;
    let c = [
        qy * x[2] - qz * x[1],
        qz * x[0] - qx * x[2],
        qx * x[1] - qy * x[0],
    ];
    let u = [2.0 * c[0], 2.0 * c[1], 2.0 * c[2]];
    let d = [
        qy * u[2] - qz * u[1],
        qz * u[0] - qx * u[2],
        qx * u[1] - qy * u[0],
    ];
    [
        ((x[0] + qw * u[0]) + d[0]) + r.t[0],
        ((x[1] + qw * u[1]) + d[1]) + r.t[1],
        ((x[2] + qw * u[2]) + d[2]) + r.t[2],
    ]
}

/// x' = M x + v as glsl/scene.glsl computes it: ((m0 x + m1 y) + m2 z) + v
/// per row, each operation rounded to f32.
#[inline]
pub fn apply_affine(m: &Affine, x: [f32; 3]) -> [f32; 3] {
    let row = |r: &[f32; 4]| ((r[0] * x[0] + r[1] * x[1]) + r[2] * x[2]) + r[3];
    [row(&m[0]), row(&m[1]), row(&m[2])]
}

/// Largest deviation of an operator's 3x3 part from a rotation for it to
/// be stored as a quaternion (PetWorld operators are rigid to 2e-6;
/// 3-decimal cellPACK bead operators are not, and stay affine).
pub const RIGID_TOLERANCE: f64 = 1e-5;

/// The rigid transform of a 3x4 operator, or None if its 3x3 part is no
/// rotation within [`RIGID_TOLERANCE`].
pub fn rigid_of(m: &[[f64; 4]; 3]) -> Option<Rigid> {
    let rot = DMat3::from_cols(
        DVec3::new(m[0][0], m[1][0], m[2][0]),
        DVec3::new(m[0][1], m[1][1], m[2][1]),
        DVec3::new(m[0][2], m[1][2], m[2][2]),
    );
    if !rot.is_finite() {
        return None;
    }
    let q = DQuat::from_mat3(&rot).normalize();
    let back = DMat3::from_quat(q);
    let dev = (0..3)
        .flat_map(|c| (0..3).map(move |r| (c, r)))
        .map(|(c, r)| (back.col(c)[r] - rot.col(c)[r]).abs())
        .fold(0.0, f64::max);
    (dev <= RIGID_TOLERANCE).then(|| rigid_from(q, [m[0][3], m[1][3], m[2][3]]))
}

/// A rigid transform from a quaternion (any norm but zero) and a translation.
pub fn rigid_from(q: DQuat, t: [f64; 3]) -> Rigid {
    let q = q.normalize();
    Rigid {
        q: [q.x as f32, q.y as f32, q.z as f32, q.w as f32],
        t: [t[0] as f32, t[1] as f32, t[2] as f32, 0.0],
    }
}

/// What a hierarchy level separates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelKind {
    /// Nodes of the tree at this depth (1 = the root's children).
    Tree(u32),
    /// Each instance its own region.
    Molecule,
    /// Each (instance, chain) its own region.
    Chain,
}

/// The instancing of a scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Instancing {
    pub molecules: Vec<Molecule>,
    /// Per instance: its molecule type.
    pub instance_molecule: Vec<u32>,
    pub transforms: Transforms,
    pub nodes: Vec<Node>,
    /// The region levels (as `Scene::level_names`), outermost first: tree
    /// levels, then molecule, then chain.
    pub levels: Vec<LevelKind>,
    /// Per molecule type: its region ids at the tree levels (by level
    /// index; other entries 0). The GPU's molecule table.
    pub tree_regions: Vec<[u32; MAX_LEVELS]>,
    /// Chain regions are `instance * chain_stride + chain`.
    pub chain_stride: u32,
    /// Expanded index of each instance's first atom; one more entry, the
    /// represented count (nested: of one block).
    pub first: Vec<u64>,
    /// Nested: the placements of this block ([`nested`]); instances,
    /// `first` and the other tables are the block's.
    pub nesting: Option<nested::Nesting>,
}

impl Instancing {
    pub fn instances(&self) -> usize {
        self.instance_molecule.len()
    }

    /// Represented (expanded) sphere count.
    pub fn represented(&self) -> u64 {
        let block = self.first.last().copied().unwrap_or(0);
        self.nesting
            .as_ref()
            .map_or(block, |n| block * n.placements.len() as u64)
    }

    /// The labels a `molecule` or `node` selection may name, for a note
    /// when one names none: up to `most` of each, then how many in all
    /// (as read: the caller makes it printable).
    pub fn names_hint(&self, most: usize) -> String {
        fn list<'a>(labels: impl Iterator<Item = &'a str>, most: usize) -> String {
            let mut seen: Vec<&str> = Vec::new();
            for l in labels {
                if !seen.contains(&l) {
                    seen.push(l);
                }
            }
            let shown: Vec<&str> = seen.iter().take(most).copied().collect();
            let rest = if seen.len() > most {
                format!(", ... ({} in all)", seen.len())
            } else {
                String::new()
            };
            format!("{}{rest}", shown.join(", "))
        }
        format!(
            "molecule types: {}; nodes: {}",
            list(self.molecules.iter().map(|m| m.label.as_str()), most),
            list(self.nodes.iter().map(|n| n.label.as_str()), most)
        )
    }

    /// The number of tree levels among `levels` (they come first).
    pub fn tree_levels(&self) -> u32 {
        self.levels
            .iter()
            .filter(|l| matches!(l, LevelKind::Tree(_)))
            .count() as u32
    }

    /// Level index of the molecule and chain levels (None if absent).
    pub fn level_of(&self, kind: LevelKind) -> Option<u32> {
        self.levels
            .iter()
            .position(|&l| l == kind)
            .map(|i| i as u32)
    }

    /// Instance and atom (index within its molecule) of expanded index `i`
    /// (nested: instance `p * K + k`, [`nested`]).
    pub fn locate(&self, i: u64) -> Option<(usize, u32)> {
        if i >= self.represented() {
            return None;
        }
        let block = self.first.last().copied().unwrap_or(0);
        let (p, i) = (i / block.max(1), i % block.max(1));
        // the last instance whose first atom is at or before i
        let k = self.first.partition_point(|&f| f <= i) - 1;
        let a = (i - self.first[k]) as u32;
        let m = &self.molecules[self.instance_molecule[k] as usize];
        // (a proxy's range is its placement's: its atoms are not those)
        if a >= m.atoms || m.origin.is_some() {
            return None;
        }
        Some((p as usize * self.instances() + k, a))
    }

    /// Region ids of an atom of chain `chain` of instance `k` (nested:
    /// `p * K + k`).
    pub fn regions(&self, k: usize, chain: u32) -> [u32; MAX_LEVELS] {
        let m = self.instance_molecule[k % self.instances().max(1)] as usize;
        let mut r = self.tree_regions[m];
        for (l, kind) in self.levels.iter().enumerate() {
            match kind {
                LevelKind::Tree(_) => {}
                LevelKind::Molecule => r[l] = k as u32,
                LevelKind::Chain => {
                    r[l] = (k as u32)
                        .wrapping_mul(self.chain_stride)
                        .wrapping_add(chain)
                }
            }
        }
        r
    }
}

impl Scene {
    /// Spheres the scene represents (instanced: expanded, never stored).
    pub fn represented(&self) -> u64 {
        match &self.instancing {
            Some(inst) => inst.represented(),
            None => self.spheres.len() as u64,
        }
    }

    /// Every represented sphere, in expanded order, with its world centre
    /// and region ids (the order and bits `expand` stores).
    pub fn for_each_sphere(&self, mut f: impl FnMut(Sphere)) {
        let Some(inst) = &self.instancing else {
            self.spheres.iter().copied().for_each(f);
            return;
        };
        for k in 0..inst.represented_instances() {
            let Some((b, t)) = inst.instance_at(k) else {
                return;
            };
            let mol = &inst.molecules[inst.instance_molecule[b] as usize];
            let atoms = &self.spheres[mol.first as usize..(mol.first + mol.atoms) as usize];
            for a in atoms {
                f(Sphere {
                    center: place(inst, b, t.as_ref(), a.center),
                    radius: a.radius,
                    color: a.color,
                    region: inst.regions(k as usize, a.region[0]),
                });
            }
        }
    }

    /// The scene's instances as [`extremes::Extremes`] (None: plain).
    /// (Nested scenes: the block's, unplaced.)
    pub fn extremes(&self) -> Option<extremes::Extremes<'_>> {
        let inst = self.instancing.as_ref()?;
        let atoms: Vec<[f32; 4]> = self
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        Some(extremes::Extremes::new(
            &inst.transforms,
            &inst.instance_molecule,
            inst.molecules.iter().map(|m| (m.first, m.atoms)).collect(),
            std::borrow::Cow::Owned(atoms),
        ))
    }

    /// Centre and radius of every represented sphere (faster than
    /// `for_each_sphere`: no regions).
    pub fn for_each_geometry(&self, mut f: impl FnMut([f32; 3], f32)) {
        let Some(inst) = &self.instancing else {
            self.spheres.iter().for_each(|s| f(s.center, s.radius));
            return;
        };
        for k in 0..inst.represented_instances() {
            let Some((b, t)) = inst.instance_at(k) else {
                return;
            };
            let mol = &inst.molecules[inst.instance_molecule[b] as usize];
            let atoms = &self.spheres[mol.first as usize..(mol.first + mol.atoms) as usize];
            for a in atoms {
                f(place(inst, b, t.as_ref(), a.center), a.radius);
            }
        }
    }

    /// The represented sphere of expanded index `i`.
    pub fn sphere(&self, i: u64) -> Option<Sphere> {
        let Some(inst) = &self.instancing else {
            return self.spheres.get(usize::try_from(i).ok()?).copied();
        };
        let (k, a) = inst.locate(i)?;
        let (b, t) = inst.instance_at(k as u64)?;
        let mol = &inst.molecules[inst.instance_molecule[b] as usize];
        let s = self.spheres[(mol.first + a) as usize];
        Some(Sphere {
            center: place(inst, b, t.as_ref(), s.center),
            radius: s.radius,
            color: s.color,
            region: inst.regions(k, s.region[0]),
        })
    }

    /// The scene with every instance expanded into its own spheres (what
    /// sphereshade drew before instancing; tests compare the two).
    pub fn expand(&self) -> Result<Scene, SceneError> {
        let n = self.represented();
        if n > super::MAX_SPHERES as u64 {
            return Err(SceneError::Invalid(format!(
                "{}: {n} spheres expanded, more than {}, the most an expanded scene holds",
                self.source,
                super::MAX_SPHERES
            )));
        }
        let mut spheres = Vec::with_capacity(n as usize);
        self.for_each_sphere(|s| spheres.push(s));
        // (rules hid atoms: each sphere keeps its input index)
        let origin = self.id_map().map(|m| super::Origin::Plain {
            index: (0..n).map(|i| m.input(i) as u32).collect(),
            total: m.total().unwrap_or(n),
        });
        Ok(Scene {
            spheres,
            level_names: self.level_names.clone(),
            source: self.source.clone(),
            instancing: None,
            expanded: true,
            atoms: None,
            origin,
        })
    }
}

/// An atom of block instance `b` placed: by the block's transform, or
/// (nested) by the composed one `t`.
#[inline]
fn place(inst: &Instancing, b: usize, t: Option<&Transforms>, x: [f32; 3]) -> [f32; 3] {
    match t {
        Some(t) => t.apply(0, x),
        None => inst.transforms.apply(b, x),
    }
}

/// Collects molecule types, their atoms, instances and the tree, then
/// works out the levels ([`InstancedBuilder::finish`]).
pub struct InstancedBuilder {
    pub spheres: Vec<Sphere>,
    pub molecules: Vec<Molecule>,
    pub instance_molecule: Vec<u32>,
    /// Operators as read (3x4, f64), turned into rigid or affine
    /// transforms at the end.
    ops: Vec<Op>,
    pub nodes: Vec<Node>,
    /// Names of tree depths 1, 2, ... (fewer: "level N").
    pub depth_names: Vec<String>,
    /// Spheres the instances so far represent.
    represented: u64,
}

enum Op {
    Matrix([[f64; 4]; 3]),
    Quat(DQuat, [f64; 3]),
}

impl Default for InstancedBuilder {
    fn default() -> Self {
        InstancedBuilder {
            spheres: Vec::new(),
            molecules: Vec::new(),
            instance_molecule: Vec::new(),
            ops: Vec::new(),
            nodes: vec![Node {
                label: "root".into(),
                parent: None,
                depth: 0,
            }],
            depth_names: Vec::new(),
            represented: 0,
        }
    }
}

/// Most instances a scene may hold (a 16-byte record each while loading;
/// a stored batch names its instance in BATCH_INSTANCE_BITS bits).
pub const MAX_INSTANCES: usize = 1 << crate::gpu::consts::BATCH_INSTANCE_BITS;

/// Most spheres an instanced scene may represent (2^40): ids are 32-bit
/// slots of a frame's LOD lists, expanded indices 64-bit on the CPU and
/// 48 in the id AOV. Drawing every atom of a frame (--lod off, deep
/// shadows, ...) needs a static table of 32-bit slots: past ~4.2 * 10^9
/// atoms that is refused when asked (src/passes/scene.rs
/// `static_entries`).
pub const MAX_REPRESENTED: u64 = 1 << 40;

impl InstancedBuilder {
    /// The node of a path below the root (made if new), e.g.
    /// `["mge", "interior", "RIBOSOME"]`.
    pub fn node(&mut self, path: &[&str]) -> u32 {
        let mut at = 0u32;
        for (d, label) in path.iter().enumerate() {
            let found = self
                .nodes
                .iter()
                .position(|n| n.parent == Some(at) && n.label == *label);
            at = match found {
                Some(i) => i as u32,
                None => {
                    self.nodes.push(Node {
                        label: label.to_string(),
                        parent: Some(at),
                        depth: d as u32 + 1,
                    });
                    self.nodes.len() as u32 - 1
                }
            };
        }
        at
    }

    /// Adds a molecule type from its atoms (`region[0]` = chain index);
    /// returns its index.
    pub fn molecule(&mut self, label: &str, node: u32, atoms: Vec<Sphere>) -> u32 {
        let chains = atoms.iter().map(|s| s.region[0] + 1).max().unwrap_or(0);
        self.molecules.push(Molecule {
            label: label.to_string(),
            first: self.spheres.len() as u32,
            atoms: atoms.len() as u32,
            node,
            chains,
            origin: None,
        });
        self.spheres.extend(atoms);
        self.molecules.len() as u32 - 1
    }

    /// Refuses the instance of molecule `m` that would exceed a limit
    /// (before anything more is allocated for it).
    fn check_instance(&mut self, name: &str, m: u32) -> Result<(), SceneError> {
        if self.instance_molecule.len() >= MAX_INSTANCES {
            return Err(SceneError::Invalid(format!(
                "{name}: more than {MAX_INSTANCES} instances, the most sphereshade holds"
            )));
        }
        let atoms = self.molecules.get(m as usize).map_or(0, |m| m.atoms as u64);
        self.represented += atoms;
        if self.represented > MAX_REPRESENTED {
            return Err(SceneError::Invalid(format!(
                "{name}: more than {MAX_REPRESENTED} spheres represented, the most sphereshade \
                 renders"
            )));
        }
        Ok(())
    }

    /// An instance of molecule `m` by a 3x4 operator (row i: m_i0 m_i1 m_i2 v_i).
    pub fn instance_matrix(
        &mut self,
        name: &str,
        m: u32,
        op: [[f64; 4]; 3],
    ) -> Result<(), SceneError> {
        self.check_instance(name, m)?;
        self.instance_molecule.push(m);
        self.ops.push(Op::Matrix(op));
        Ok(())
    }

    /// An instance of molecule `m` by a rotation and a translation.
    pub fn instance_quat(
        &mut self,
        name: &str,
        m: u32,
        q: DQuat,
        t: [f64; 3],
    ) -> Result<(), SceneError> {
        self.check_instance(name, m)?;
        if !(q.is_finite() && q.length() > 1e-12) {
            return Err(SceneError::Invalid(format!(
                "{name}: instance {} has a zero or non-finite rotation",
                self.instance_molecule.len()
            )));
        }
        self.instance_molecule.push(m);
        self.ops.push(Op::Quat(q, t));
        Ok(())
    }

    /// The scene: instances of empty molecules dropped, transforms rigid
    /// where every one is, the useful levels (see [`levels`]).
    pub fn finish(mut self, source: &str) -> Result<Scene, SceneError> {
        // Instances of molecules without atoms add nothing.
        let keep: Vec<bool> = self
            .instance_molecule
            .iter()
            .map(|&m| self.molecules[m as usize].atoms > 0)
            .collect();
        let mut k = 0;
        self.instance_molecule.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        let mut k = 0;
        self.ops.retain(|_| {
            k += 1;
            keep[k - 1]
        });
        if self.instance_molecule.is_empty() {
            return Err(SceneError::Empty {
                path: source.to_string(),
            });
        }
        for (k, op) in self.ops.iter().enumerate() {
            let finite = match op {
                Op::Matrix(m) => m.iter().flatten().all(|v| v.is_finite()),
                Op::Quat(q, t) => q.is_finite() && t.iter().all(|v| v.is_finite()),
            };
            if !finite {
                return Err(SceneError::Invalid(format!(
                    "{source}: instance {k} has a non-finite transform"
                )));
            }
        }
        let rigid: Option<Vec<Rigid>> = self
            .ops
            .iter()
            .map(|op| match op {
                Op::Matrix(m) => rigid_of(m),
                Op::Quat(q, t) => Some(rigid_from(*q, *t)),
            })
            .collect();
        let transforms = match rigid {
            Some(r) => Transforms::Rigid(r),
            None => Transforms::Affine(
                self.ops
                    .iter()
                    .map(|op| {
                        let m = match op {
                            Op::Matrix(m) => *m,
                            Op::Quat(q, t) => {
                                let r = DMat3::from_quat(q.normalize());
                                [0, 1, 2].map(|i| [r.col(0)[i], r.col(1)[i], r.col(2)[i], t[i]])
                            }
                        };
                        m.map(|row| row.map(|v| v as f32))
                    })
                    .collect(),
            ),
        };
        let mut first = Vec::with_capacity(self.instance_molecule.len() + 1);
        let mut total = 0u64;
        for &m in &self.instance_molecule {
            first.push(total);
            total += self.molecules[m as usize].atoms as u64;
        }
        first.push(total);
        let chain_stride = self
            .molecules
            .iter()
            .map(|m| m.chains)
            .max()
            .unwrap_or(1)
            .max(1);
        let (levels, tree_regions) = levels(&self.molecules, &self.instance_molecule, &self.nodes);
        let level_names = levels
            .iter()
            .map(|l| match l {
                LevelKind::Tree(d) => self
                    .depth_names
                    .get(*d as usize - 1)
                    .cloned()
                    .unwrap_or_else(|| format!("level {d}")),
                LevelKind::Molecule => "molecule".into(),
                LevelKind::Chain => "chain".into(),
            })
            .collect();
        let inst = Instancing {
            molecules: self.molecules,
            instance_molecule: self.instance_molecule,
            transforms,
            nodes: self.nodes,
            levels,
            tree_regions,
            chain_stride,
            first,
            nesting: None,
        };
        let scene = Scene {
            spheres: self.spheres,
            level_names,
            source: source.to_string(),
            instancing: Some(inst),
            expanded: false,
            atoms: None,
            origin: None,
        };
        check_extent(&scene)?;
        Ok(scene)
    }
}

/// Every represented centre stays within the f32 range sphereshade renders.
fn check_extent(scene: &Scene) -> Result<(), SceneError> {
    let limit = super::MAX_COORDINATE;
    let ok = |c: &[f32; 3]| c.iter().all(|v| v.is_finite() && v.abs() <= limit);
    let mut bad = None;
    let mut i = 0u64;
    // (instances whose hull lies inside are counted, not scanned: at 10^9
    // atoms a full scan took most of the scene's build)
    match scene.extremes() {
        Some(e) => {
            for k in 0..scene.instancing.as_ref().map_or(0, |x| x.instances()) {
                if e.inside(k, limit as f64) {
                    i += e.atom_count(k) as u64;
                    continue;
                }
                for (c, _) in e.atoms_of(k) {
                    if !ok(&c) {
                        bad = Some((i, c));
                        break;
                    }
                    i += 1;
                }
                if bad.is_some() {
                    break;
                }
            }
        }
        None => scene.for_each_geometry(|c, _| {
            if bad.is_none() && !ok(&c) {
                bad = Some((i, c));
            }
            i += 1;
        }),
    }
    match bad {
        Some((i, c)) => Err(SceneError::Invalid(format!(
            "{}: sphere {i} lands at {c:?}, outside ±{limit:e}, the range sphereshade renders in f32",
            scene.source
        ))),
        None => Ok(()),
    }
}

/// The levels that separate something, outermost first (tree depths, then
/// molecule, then chain), each kept only if it splits its predecessor
/// further (every later level refines the earlier ones, so equal region
/// counts mean equal partitions), at most [`MAX_LEVELS`]: the molecule
/// and chain levels and the outermost tree levels. Returns them with each
/// molecule type's tree regions by level index.
fn levels(
    molecules: &[Molecule],
    instance_molecule: &[u32],
    nodes: &[Node],
) -> (Vec<LevelKind>, Vec<[u32; MAX_LEVELS]>) {
    // Each molecule's path from depth 1 down to its node.
    let path = |m: &Molecule| {
        let mut p = Vec::new();
        let mut at = Some(m.node);
        while let Some(n) = at {
            if nodes[n as usize].depth > 0 {
                p.push(n);
            }
            at = nodes[n as usize].parent;
        }
        p.reverse();
        p
    };
    let paths: Vec<Vec<u32>> = molecules.iter().map(path).collect();
    let max_depth = paths.iter().map(Vec::len).max().unwrap_or(0);
    // (node at depth d: the path's, or its last node where the path is shorter)
    let at_depth = |m: usize, d: usize| {
        paths[m]
            .get(d - 1)
            .or(paths[m].last())
            .copied()
            .unwrap_or(0)
    };
    let mut used: Vec<usize> = instance_molecule.iter().map(|&m| m as usize).collect();
    used.sort_unstable();
    used.dedup();
    let distinct = |d: usize| {
        let mut v: Vec<u32> = used.iter().map(|&m| at_depth(m, d)).collect();
        v.sort_unstable();
        v.dedup();
        v.len() as u64
    };
    let mut kept: Vec<(LevelKind, u64)> = Vec::new();
    let mut last = 1u64;
    for d in 1..=max_depth {
        let n = distinct(d);
        if n > last {
            kept.push((LevelKind::Tree(d as u32), n));
            last = n;
        }
    }
    let instances = instance_molecule.len() as u64;
    let mut tail = Vec::new();
    if instances > last {
        tail.push(LevelKind::Molecule);
        last = instances;
    }
    let chains: u64 = instance_molecule
        .iter()
        .map(|&m| molecules[m as usize].chains.max(1) as u64)
        .sum();
    if chains > last {
        tail.push(LevelKind::Chain);
    }
    let tree_room = MAX_LEVELS - tail.len();
    let mut levels: Vec<LevelKind> = kept.into_iter().map(|(k, _)| k).take(tree_room).collect();
    levels.extend(tail);
    let regions = (0..molecules.len())
        .map(|m| {
            let mut r = [0u32; MAX_LEVELS];
            for (l, kind) in levels.iter().enumerate() {
                if let LevelKind::Tree(d) = kind {
                    r[l] = at_depth(m, *d as usize);
                }
            }
            r
        })
        .collect();
    (levels, regions)
}

/// Centre of the atoms of a molecule's run `[a, b)` (the view orders sort
/// runs of 64 atoms by it).
pub fn run_center(atoms: &[Sphere]) -> Vec3 {
    let n = atoms.len().max(1) as f32;
    atoms.iter().map(|s| Vec3::from(s.center)).sum::<Vec3>() / n
}

pub mod extremes;
pub mod lod;
pub mod nested;

#[cfg(test)]
mod tests;
