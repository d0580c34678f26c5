//! Nested instancing: a scene of placements of one instanced block (a
//! scene of whole virions, each itself an instanced model), so that 10^12
//! atoms are represented by one 10^9-atom block and a thousand rigid
//! placements. Expanded order: placements in order, each the block's
//! expanded order; instance `p * K + k` (K the block's instances) is block
//! instance k placed by placement p, its transform the two composed in f64
//! and rounded once ([`compose`]), which is what an opened placement draws.
//!
//! A frame never holds every instance: [`Instancing::resolve`] makes the
//! scene a view draws, where a placement is either opened (its K instances
//! with composed transforms) or closed, drawn as instances of proxy
//! molecule types: per group of block instances with the same tree
//! regions, one sphere per instance, its molecule's coarsest level of
//! detail placed in the block's frame (what that instance draws whenever
//! its size on screen is within its coarsest level's switch size), whose
//! id names the atom that coarsest sphere stands for. The proxies have
//! levels of detail of their own like any molecule type.

use super::lod::{LodFit, on_every_core};
use super::{Affine, Instancing, Molecule, Rigid, Transforms, rigid_from};
use crate::scene::{Scene, SceneError, Sphere};
use glam::{DMat3, DQuat, DVec3};

/// The placements of a nested scene's block (its instances).
#[derive(Clone, Debug, PartialEq)]
pub struct Nesting {
    /// Rigid placements of the block, in expanded order.
    pub placements: Vec<Rigid>,
}

impl Nesting {
    fn placed(&self, x: glam::Vec3) -> impl Iterator<Item = glam::Vec3> + '_ {
        self.placements
            .iter()
            .map(move |p| glam::Vec3::from(super::apply_rigid(p, x.into())))
    }

    /// The box of a block box's corners placed by every placement.
    pub fn placed_box(&self, lo: glam::Vec3, hi: glam::Vec3) -> Option<(glam::Vec3, glam::Vec3)> {
        let corners = (0..8).map(|i| {
            glam::Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        });
        corners
            .flat_map(|c| self.placed(c).collect::<Vec<_>>())
            .fold(None, |b, c| {
                Some(b.map_or((c, c), |(l, h): (glam::Vec3, glam::Vec3)| {
                    (l.min(c), h.max(c))
                }))
            })
    }

    /// A sphere holding the block's bounding sphere (c, r) placed by every
    /// placement: about the box of the placed centres.
    pub fn placed_sphere(&self, c: glam::Vec3, r: f32) -> (glam::Vec3, f32) {
        let Some((lo, hi)) = self.placed(c).fold(None, |b, p| {
            Some(b.map_or((p, p), |(l, h): (glam::Vec3, glam::Vec3)| {
                (l.min(p), h.max(p))
            }))
        }) else {
            return (glam::Vec3::ZERO, 0.0);
        };
        let m = (lo + hi) * 0.5;
        let reach = self.placed(c).map(|p| p.distance(m)).fold(0.0f32, f32::max);
        // (grown for the f32 rounding of the placed centres)
        (m, (reach + r) * (1.0 + 1e-5))
    }
}

/// The most placements a nested scene may have (instance ids `p * K + k`
/// are 64-bit on the CPU; a resolved scene holds a proxy per group and
/// closed placement).
pub const MAX_PLACEMENTS: usize = 1 << 20;

fn quat(r: &Rigid) -> DQuat {
    DQuat::from_xyzw(r.q[0] as f64, r.q[1] as f64, r.q[2] as f64, r.q[3] as f64)
}

fn dvec(t: &[f32; 4]) -> DVec3 {
    DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64)
}

/// Placement `p` composed with the block's transform `k` (x' = P(T_k x)),
/// in f64, rounded once: rigid stays rigid, affine stays affine.
pub fn compose_rigid(p: &Rigid, t: &Rigid) -> Rigid {
    let (qp, tp) = (quat(p), dvec(&p.t));
    let q = qp * quat(t);
    rigid_from(q, (qp * dvec(&t.t) + tp).into())
}

/// [`compose_rigid`] for an affine block transform.
pub fn compose_affine(p: &Rigid, a: &Affine) -> Affine {
    let r = DMat3::from_quat(quat(p).normalize());
    let tp = dvec(&p.t);
    let m = DMat3::from_cols(
        DVec3::new(a[0][0] as f64, a[1][0] as f64, a[2][0] as f64),
        DVec3::new(a[0][1] as f64, a[1][1] as f64, a[2][1] as f64),
        DVec3::new(a[0][2] as f64, a[1][2] as f64, a[2][2] as f64),
    );
    let v = DVec3::new(a[0][3] as f64, a[1][3] as f64, a[2][3] as f64);
    let rm = r * m;
    let rv = r * v + tp;
    [0, 1, 2].map(|i| {
        [
            rm.col(0)[i] as f32,
            rm.col(1)[i] as f32,
            rm.col(2)[i] as f32,
            rv[i] as f32,
        ]
    })
}

/// A placement as an affine transform (the proxies of an affine block):
/// composed with the identity (exact: r * I = r, r * 0 + t = t).
fn affine_of(p: &Rigid) -> Affine {
    const IDENTITY: Affine = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    compose_affine(p, &IDENTITY)
}

/// Instance `k` of the block placed by `p`, as a transform of the block's kind.
pub fn compose(p: &Rigid, block: &Transforms, k: usize) -> Transforms {
    match block {
        Transforms::Rigid(v) => Transforms::Rigid(vec![compose_rigid(p, &v[k])]),
        Transforms::Affine(v) => Transforms::Affine(vec![compose_affine(p, &v[k])]),
    }
}

/// What every resolved view of a nested scene shares: per block molecule
/// type its coarsest level's one sphere (in its frame) and the atom it
/// stands for, and the groups of block instances the proxies gather.
#[derive(Clone, Debug)]
pub struct Proxies {
    /// Per group (block instances whose molecule types share their tree
    /// regions, in order of first appearance): the proxy molecule (its
    /// atoms stored after the block's) and those tree regions.
    groups: Vec<(Molecule, [u32; crate::scene::MAX_LEVELS])>,
    /// The proxy atoms, after the block's stored atoms (placed in the
    /// block's frame), group after group.
    atoms: Vec<Sphere>,
    /// Most pixels per world unit at which every block instance draws its
    /// coarsest level (the least coarsest switch size of the types with
    /// more than one level).
    pub open_ppu: f32,
    /// The levels of detail of the block's molecule types, then of the
    /// groups' proxies (a resolved scene's types, in its order), fitted
    /// once for every renderer of the scene (a viewer reopening placements
    /// made them again each time: ~1 s on the 10^12 scene).
    pub fits: Vec<LodFit>,
}

impl Proxies {
    /// The proxies of `scene`'s block with levels of detail fitted at
    /// `pixels` (`--lod-pixels`), as the renderer fits them.
    pub fn new(scene: &Scene, pixels: f32) -> Result<Proxies, SceneError> {
        let inst = scene
            .instancing
            .as_ref()
            .ok_or_else(|| SceneError::Invalid("proxies of a plain scene".into()))?;
        let atoms_of = |first: u32, n: u32, spheres: &[Sphere]| -> Vec<[f32; 4]> {
            spheres[first as usize..(first + n) as usize]
                .iter()
                .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
                .collect()
        };
        let worker = || SceneError::Invalid("a level-of-detail worker failed".into());
        // Per molecule type, on every core: its levels, and its coarsest
        // sphere with the atom it stands for.
        let (mut fits, coarsest): (Vec<LodFit>, Vec<([f32; 4], u32)>) =
            on_every_core(inst.molecules.len(), |m| {
                let mol = &inst.molecules[m];
                let atoms = atoms_of(mol.first, mol.atoms, &scene.spheres);
                let fit = LodFit::new(&atoms, pixels);
                let last = fit.levels.levels() - 1;
                let coarsest = match (atoms.first(), last) {
                    (None, _) => ([0.0; 4], 0),
                    (Some(&a), 0) => (a, 0),
                    _ => (
                        fit.levels.level_spheres(&atoms, last)[0],
                        fit.levels.order[0],
                    ),
                };
                (fit, coarsest)
            })
            .ok_or_else(worker)?
            .into_iter()
            .unzip();
        // (the least coarsest switch size of the types with several levels)
        let open_ppu = fits
            .iter()
            .filter(|f| f.levels.levels() > 1)
            .map(|f| f.switch[f.levels.levels() - 1])
            .fold(f32::INFINITY, f32::min);
        let mut groups: Vec<(Molecule, [u32; crate::scene::MAX_LEVELS])> = Vec::new();
        let mut members: Vec<Vec<Sphere>> = Vec::new();
        let block_atoms = inst.first.last().copied().unwrap_or(0);
        if block_atoms > u32::MAX as u64 {
            return Err(SceneError::Invalid(format!(
                "{}: a nested scene's block of {block_atoms} atoms, more than 2^32",
                scene.source
            )));
        }
        let mut origins: Vec<Vec<u32>> = Vec::new();
        for (k, &m) in inst.instance_molecule.iter().enumerate() {
            let mol = &inst.molecules[m as usize];
            if mol.atoms == 0 {
                continue;
            }
            let regions = inst.tree_regions[m as usize];
            let g = match groups.iter().position(|g| g.1 == regions) {
                Some(g) => g,
                None => {
                    groups.push((
                        Molecule {
                            label: format!("proxy of {}", inst.nodes[mol.node as usize].label),
                            first: 0,
                            atoms: 0,
                            node: mol.node,
                            chains: 1,
                            origin: None,
                        },
                        regions,
                    ));
                    members.push(Vec::new());
                    origins.push(Vec::new());
                    groups.len() - 1
                }
            };
            let (s, atom) = coarsest[m as usize];
            let src = &scene.spheres[(mol.first + atom) as usize];
            members[g].push(Sphere {
                center: inst.transforms.apply(k, [s[0], s[1], s[2]]),
                radius: s[3],
                color: src.color,
                region: [0; crate::scene::MAX_LEVELS],
            });
            origins[g].push((inst.first[k] + atom as u64) as u32);
        }
        // Each proxy's atoms in Morton order of their centres: its level 0
        // is its atoms in its own order, and a batch of 64 of them must be
        // compact for the cull (in instance order a meso block's plasma
        // batch spans a shell around the virion).
        for (m, o) in members.iter_mut().zip(origins.iter_mut()) {
            let order = morton_order(m);
            *m = order.iter().map(|&i| m[i]).collect();
            *o = order.iter().map(|&i| o[i]).collect();
        }
        let mut atoms = Vec::new();
        let mut first = scene.spheres.len() as u32;
        for ((g, m), o) in groups.iter_mut().zip(members).zip(origins) {
            g.0.first = first;
            g.0.atoms = m.len() as u32;
            g.0.origin = Some(o);
            first += m.len() as u32;
            atoms.extend(m);
        }
        let base = scene.spheres.len() as u32;
        fits.extend(
            on_every_core(groups.len(), |g| {
                let m = &groups[g].0;
                LodFit::new(&atoms_of(m.first - base, m.atoms, &atoms), pixels)
            })
            .ok_or_else(worker)?,
        );
        Ok(Proxies {
            groups,
            atoms,
            open_ppu,
            fits,
        })
    }

    /// No proxies (every placement opened: `--lod off`).
    pub fn none() -> Proxies {
        Proxies {
            groups: Vec::new(),
            atoms: Vec::new(),
            open_ppu: f32::INFINITY,
            fits: Vec::new(),
        }
    }

    /// Proxy molecule types (one per group).
    pub fn groups(&self) -> usize {
        self.groups.len()
    }
}

/// Indices of `spheres` in Morton order of their centres (ties in order).
fn morton_order(spheres: &[Sphere]) -> Vec<usize> {
    let cells = super::lod::morton_cells(&spheres.iter().map(|s| s.center).collect::<Vec<_>>());
    let mut order: Vec<usize> = (0..spheres.len()).collect();
    order.sort_by_key(|&i| cells[i]);
    order
}

impl Instancing {
    /// Block instances (stored) times placements: the instances represented.
    pub fn represented_instances(&self) -> u64 {
        let k = self.instances() as u64;
        self.nesting
            .as_ref()
            .map_or(k, |n| k * n.placements.len() as u64)
    }

    /// Represented instance `k` (nested: `p * K + k`): its block instance,
    /// and its transform as a one-instance [`Transforms`] when nested.
    pub fn instance_at(&self, k: u64) -> Option<(usize, Option<Transforms>)> {
        let n = self.instances() as u64;
        match &self.nesting {
            None => (k < n).then_some((k as usize, None)),
            Some(nest) => {
                let p = usize::try_from(k / n.max(1)).ok()?;
                let b = (k % n.max(1)) as usize;
                let place = nest.placements.get(p)?;
                Some((b, Some(compose(place, &self.transforms, b))))
            }
        }
    }

    /// The scene a view draws: placement p opened where `open[p]`, else
    /// drawn by `proxies`. The result is an instanced scene of its own
    /// (no nesting) that represents the same atoms with the same ids.
    pub fn resolve(
        &self,
        scene: &Scene,
        proxies: &Proxies,
        open: &[bool],
    ) -> Result<Scene, SceneError> {
        let Some(nest) = &self.nesting else {
            return Err(SceneError::Invalid(
                "resolving a scene that is not nested".into(),
            ));
        };
        if open.len() != nest.placements.len() {
            return Err(SceneError::Invalid("one flag per placement".into()));
        }
        let k_block = self.instances();
        let opened = open.iter().filter(|&&o| o).count();
        let count = opened * k_block + (open.len() - opened) * proxies.groups.len();
        if count > super::MAX_INSTANCES {
            return Err(SceneError::Invalid(format!(
                "{}: {opened} placements opened make {count} instances, more than {}: \
                 nested scenes draw far placements by proxies (--lod auto)",
                scene.source,
                super::MAX_INSTANCES
            )));
        }
        let block_atoms = self.first.last().copied().unwrap_or(0);
        let mut molecules = self.molecules.clone();
        let proxy_base = molecules.len() as u32;
        molecules.extend(proxies.groups.iter().map(|g| g.0.clone()));
        let mut tree_regions = self.tree_regions.clone();
        tree_regions.extend(proxies.groups.iter().map(|g| g.1));
        let mut instance_molecule = Vec::with_capacity(count);
        let mut first = Vec::with_capacity(count + 1);
        let rigid = matches!(self.transforms, Transforms::Rigid(_));
        let mut rigids: Vec<Rigid> = Vec::new();
        let mut affines: Vec<Affine> = Vec::new();
        for (p, (place, &o)) in nest.placements.iter().zip(open).enumerate() {
            let base = p as u64 * block_atoms;
            if o {
                for k in 0..k_block {
                    instance_molecule.push(self.instance_molecule[k]);
                    first.push(base + self.first[k]);
                    match &self.transforms {
                        Transforms::Rigid(v) => rigids.push(compose_rigid(place, &v[k])),
                        Transforms::Affine(v) => affines.push(compose_affine(place, &v[k])),
                    }
                }
            } else {
                for g in 0..proxies.groups.len() {
                    instance_molecule.push(proxy_base + g as u32);
                    first.push(base);
                    if rigid {
                        rigids.push(*place);
                    } else {
                        affines.push(affine_of(place));
                    }
                }
            }
        }
        first.push(block_atoms * nest.placements.len() as u64);
        let mut spheres = scene.spheres.clone();
        spheres.extend_from_slice(&proxies.atoms);
        let inst = Instancing {
            molecules,
            instance_molecule,
            transforms: if rigid {
                Transforms::Rigid(rigids)
            } else {
                Transforms::Affine(affines)
            },
            nodes: self.nodes.clone(),
            levels: self.levels.clone(),
            tree_regions,
            chain_stride: self.chain_stride,
            first,
            nesting: None,
        };
        Ok(Scene {
            spheres,
            level_names: scene.level_names.clone(),
            source: scene.source.clone(),
            instancing: Some(inst),
            expanded: false,
            atoms: None,
            origin: None,
        })
    }
}

/// A nested scene of `scene` (instanced, not nested) placed by `placements`.
pub fn nest(mut scene: Scene, placements: Vec<Rigid>) -> Result<Scene, SceneError> {
    if placements.is_empty() || placements.len() > MAX_PLACEMENTS {
        return Err(SceneError::Invalid(format!(
            "{}: {} placements (1 to {MAX_PLACEMENTS})",
            scene.source,
            placements.len()
        )));
    }
    let Some(inst) = scene.instancing.as_mut() else {
        return Err(SceneError::Invalid(format!(
            "{}: only an instanced scene can be nested",
            scene.source
        )));
    };
    if inst.nesting.is_some() {
        return Err(SceneError::Invalid(format!(
            "{}: a nested scene cannot be nested again",
            scene.source
        )));
    }
    let block = inst.first.last().copied().unwrap_or(0);
    let total = (block as u128) * placements.len() as u128;
    if total > super::MAX_REPRESENTED as u128 {
        return Err(SceneError::Invalid(format!(
            "{}: {total} atoms represented, more than 2^40",
            scene.source
        )));
    }
    inst.nesting = Some(Nesting { placements });
    // (every placed block within the coordinates sphereshade renders)
    let (c, r) = scene.bounding_sphere();
    let limit = crate::scene::MAX_COORDINATE;
    if !(c.abs().max_element() + r <= limit) {
        return Err(SceneError::Invalid(format!(
            "{}: placements reach {:.3e} from the origin, past {limit:.0e}",
            scene.source,
            c.abs().max_element() + r
        )));
    }
    Ok(scene)
}
