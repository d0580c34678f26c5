//! `--scene meso --atoms N`: the semantic SSDO paper's kind of scene, an
//! HIV-like virion in blood plasma, built deterministically from real
//! structures compiled into the binary (tests/data, provenance in its
//! README): the HIV-1 cellPACK model (tests/data/meso, 91,956 beads in
//! 11,681 instances of 26 types: envelope, matrix, capsid, interior) as the
//! virion at the centre, and around it plasma proteins (1TII and 3P3W, all
//! atoms, waters dropped) in the cells of a lattice (turned off the axes)
//! at about 20 % volume fraction, each anywhere in its cell in a random
//! turn where its covering spheres miss its neighbours' (atoms never
//! overlap; bounding spheres may), filling the cells nearest the
//! virion first (a shell that thickens with N), as many as bring the scene to N atoms
//! represented. Hierarchy: plasma | virion, then the model's own tree (or
//! the plasma protein), molecule, chain. Every copy is an instance: the
//! scene stores 91,956 + 16,953 atoms whatever N is.

use super::instanced::{InstancedBuilder, Transforms};
use super::procedural::Rng;
use super::{Format, LoadOptions, Scene, SceneError, Sphere, parse_bytes};
use glam::{DQuat, DVec3};

const VIRION: &[u8] = include_bytes!("../../tests/data/meso/HIV-1_0.1.6-8_mixed_radii_pdb.json");
const PLASMA: [(&str, &[u8]); 2] = [
    ("1TII", include_bytes!("../../tests/data/1tii.pdb")),
    ("3P3W", include_bytes!("../../tests/data/pdb3p3w.pdb")),
];

/// Plasma protein volume fraction of the lattice cells (blood plasma is
/// ~7 % protein by weight; the paper's scene packs it denser to show
/// clutter): 90 Å cells, about 99 % of them filled (3 * 10^6 atoms: 343
/// proteins in 347 cells).
pub const VOLUME_FRACTION: f64 = 0.2;
/// The most atoms `--scene meso` builds (2^40, the most an instanced
/// scene represents).
pub const MAX_ATOMS: u64 = super::instanced::MAX_REPRESENTED;
/// Above this many atoms the scene is nested (src/scene/instanced/nested.rs):
/// placements of one [`BLOCK_ATOMS`] block, a scene of whole virions each
/// in its plasma. A flat scene keeps an instance record per protein copy,
/// so memory and build time grow with N (10^11 flat: 13.4 M instances,
/// built in 5.7 min, 5.2 GB RSS and 1.04 GB GPU on lavapipe).
pub const NEST_ABOVE: u64 = 10_000_000_000;
/// Atoms of the block a nested meso scene places.
pub const BLOCK_ATOMS: u64 = 1_000_000_000;
/// Covering spheres per plasma protein type (the collision test's shape).
const COVER: usize = 16;
/// Placements tried per lattice cell before it is left empty.
const TRIES: usize = 4;
/// Protein volume per heavy atom, Å^3 (~1.35 g/cm^3, 14 Da per atom).
const ATOM_VOLUME: f64 = 17.0;

/// The scene with about `atoms` atoms represented (at least the virion's).
pub fn meso(atoms: u64, seed: u64) -> Result<Scene, SceneError> {
    meso_with_progress(atoms, seed, &mut |_, _| {})
}

/// [`meso`], reporting (atoms placed, atoms wanted) as the plasma grows.
/// Past [`NEST_ABOVE`] atoms: [`nested`] placements of the [`BLOCK_ATOMS`]
/// scene.
pub fn meso_with_progress(
    atoms: u64,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    if atoms <= NEST_ABOVE {
        return flat(atoms, seed, progress);
    }
    nested(BLOCK_ATOMS, atoms, seed, progress)
}

/// A nested meso scene of about `atoms` atoms: the `block`-atom scene
/// placed on a cubic lattice (x fastest, then y, then z) of touching
/// bounding spheres, each placement in a random turn, as many times as
/// bring it nearest to `atoms`.
pub fn nested(
    block: u64,
    atoms: u64,
    seed: u64,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    let block = flat(block, seed, progress)?;
    let per = block.represented().max(1);
    let count = ((atoms as f64 / per as f64).round() as u64).max(1);
    let side = (count as f64).cbrt().ceil() as u64;
    let (c, r) = block.bounding_sphere();
    let spacing = 2.0 * r as f64;
    let mut rng = Rng::new(seed ^ 0x6E65_7374);
    let mid = (side - 1) as f64 * 0.5;
    let placements = (0..count)
        .map(|i| {
            let cell = DVec3::new(
                (i % side) as f64 - mid,
                (i / side % side) as f64 - mid,
                (i / (side * side)) as f64 - mid,
            );
            let q = random_rotation(&mut rng);
            // (the block's centre at the cell's: t = cell - q c)
            let t = cell * spacing - q * c.as_dvec3();
            super::instanced::rigid_from(q, t.into())
        })
        .collect();
    super::instanced::nested::nest(block, placements)
}

/// A meso scene of `atoms` atoms with an instance record per protein copy.
fn flat(atoms: u64, seed: u64, progress: &mut dyn FnMut(u64, u64)) -> Result<Scene, SceneError> {
    let opts = LoadOptions::default();
    let virion = parse_bytes(VIRION, Format::Json, "HIV-1 cellPACK model", &opts)?;
    let inst = virion
        .instancing
        .as_ref()
        .ok_or_else(|| SceneError::Invalid("the virion model is not instanced".into()))?;
    let mut b = InstancedBuilder::default();
    b.depth_names = vec!["compartment".into()];
    // The virion: its tree under "virion", its molecules and instances.
    let path_of = |mut n: u32| {
        let mut p = Vec::new();
        while let Some(parent) = inst.nodes[n as usize].parent {
            p.push(inst.nodes[n as usize].label.clone());
            n = parent;
        }
        p.push("virion".to_string());
        p.reverse();
        p
    };
    let mut mol_map = Vec::with_capacity(inst.molecules.len());
    for m in &inst.molecules {
        let path = path_of(m.node);
        let refs: Vec<&str> = path.iter().map(String::as_str).collect();
        let node = b.node(&refs);
        let atoms = virion.spheres[m.first as usize..(m.first + m.atoms) as usize].to_vec();
        mol_map.push(b.molecule(&m.label, node, atoms));
    }
    let (vc, vr) = virion.bounding_sphere();
    let center = vc.as_dvec3();
    const NAME: &str = "scene:meso";
    for (k, &m) in inst.instance_molecule.iter().enumerate() {
        let mm = mol_map[m as usize];
        match &inst.transforms {
            Transforms::Rigid(v) => {
                let r = v[k];
                let q =
                    DQuat::from_xyzw(r.q[0] as f64, r.q[1] as f64, r.q[2] as f64, r.q[3] as f64);
                let t = DVec3::new(r.t[0] as f64, r.t[1] as f64, r.t[2] as f64) - center;
                b.instance_quat(NAME, mm, q, t.into())?;
            }
            Transforms::Affine(v) => {
                let mut op = v[k].map(|row| row.map(|x| x as f64));
                for (i, c) in center.to_array().iter().enumerate() {
                    op[i][3] -= c;
                }
                b.instance_matrix(NAME, mm, op)?;
            }
        }
    }
    let virion_atoms = inst.represented();
    // The plasma proteins, centred, waters dropped, chains renumbered.
    let mut types = Vec::new();
    let mut covers: Vec<Vec<(DVec3, f64)>> = Vec::new();
    for (label, bytes) in PLASMA {
        let s = parse_bytes(bytes, Format::Pdb, label, &opts)?;
        let atoms = plasma_atoms(&s);
        let radius = atoms
            .iter()
            .map(|a| DVec3::from(a.center.map(|x| x as f64)).length() + a.radius as f64)
            .fold(0.0f64, f64::max);
        let node = b.node(&["plasma", label]);
        let n = atoms.len() as u64;
        covers.push(covering_spheres(&atoms));
        types.push((b.molecule(label, node, atoms), n, radius));
    }
    let want = atoms.saturating_sub(virion_atoms);
    let mean = types.iter().map(|t| t.1).sum::<u64>() as f64 / types.len() as f64;
    // (cells for the expected copies and a margin: the type of each copy
    // is drawn at random, the last one placed brings the total nearest
    // to `atoms`)
    let copies = (want as f64 / mean * 1.1).ceil() as u64 + 8;
    if want as f64 > mean / 2.0 {
        // Cells of a grid at the aimed volume fraction, one protein each at
        // most, placed anywhere in its cell in a random turn, and only where
        // its covering spheres (COVER per type, each holding its share of
        // the atoms whole) meet none of those of the proteins placed around
        // it: no two proteins' atoms overlap, and they pack closer than
        // their bounding spheres would let them. A cell where TRIES
        // placements all collide stays empty.
        let cell = (mean * ATOM_VOLUME / VOLUME_FRACTION).cbrt();
        let largest = types.iter().map(|t| t.2).fold(0.0f64, f64::max);
        // (a centre lies at most half a cell's diagonal from its cell's)
        let keep_out = vr as f64 + largest + cell * 0.87;
        // The cells of a lattice through the centre outside the keep-out
        // sphere, nearest first (ties in lattice order), room for every
        // copy with most cells left empty: the plasma is a shell around the
        // virion, thicker as N grows.
        let outer = (3.0 * 4.0 * copies as f64 * cell.powi(3) / (4.0 * std::f64::consts::PI)
            + keep_out.powi(3))
        .cbrt()
            + 2.0 * cell;
        let reach = (outer / cell).ceil() as i64;
        let mut cells: Vec<(f64, [i64; 3])> = Vec::new();
        for z in -reach..=reach {
            for y in -reach..=reach {
                for x in -reach..=reach {
                    let d = (DVec3::new(x as f64, y as f64, z as f64) * cell).length();
                    if d >= keep_out && d <= outer {
                        cells.push((d, [x, y, z]));
                    }
                }
            }
        }
        cells.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // The lattice turned off the axes about the virion's centre: seen
        // along an axis (the default camera, --view-dir 1,0,0 ...) an
        // axis-aligned lattice shows straight channels between its columns.
        let turn = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.0);
        // placed proteins by cell (dense: the cube of cells), and how many
        // cells around a cell can hold one that reaches it
        let side = (2 * reach + 1) as usize;
        let mut grid: Vec<u32> = vec![u32::MAX; side * side * side];
        let at = |[x, y, z]: [i64; 3]| -> Option<usize> {
            let r = -reach..=reach;
            (r.contains(&x) && r.contains(&y) && r.contains(&z)).then(|| {
                (((z + reach) as usize * side) + (y + reach) as usize) * side + (x + reach) as usize
            })
        };
        let near = ((2.0 * largest) / cell + 1.0).ceil() as i64;
        let mut placed: Vec<(usize, DVec3, DQuat)> = Vec::new();
        let mut rng = Rng::new(seed ^ 0x6D65_736F);
        let mut total = 0u64;
        let mut visited = 0usize;
        let every = (cells.len() / 100).max(1024);
        for (_, key) in cells {
            visited += 1;
            if visited.is_multiple_of(every) {
                progress(total, want);
            }
            let c = DVec3::new(key[0] as f64, key[1] as f64, key[2] as f64) * cell;
            let t = (rng.next_u64() % types.len() as u64) as usize;
            let (m, n, _) = types[t];
            if 2 * (total + n) > 2 * want + n {
                break;
            }
            let fits = |p: DVec3, q: DQuat| -> bool {
                for dz in -near..=near {
                    for dy in -near..=near {
                        for dx in -near..=near {
                            let Some(i) = at([key[0] + dx, key[1] + dy, key[2] + dz]) else {
                                continue;
                            };
                            let Some(&(u, pu, qu)) = placed.get(grid[i] as usize) else {
                                continue;
                            };
                            if p.distance(pu) >= types[t].2 + types[u].2 {
                                continue;
                            }
                            for &(ca, ra) in &covers[t] {
                                let wa = p + q * ca;
                                for &(cb, rb) in &covers[u] {
                                    if wa.distance(pu + qu * cb) < ra + rb {
                                        return false;
                                    }
                                }
                            }
                        }
                    }
                }
                true
            };
            for _ in 0..TRIES {
                let jitter = DVec3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5);
                let q = random_rotation(&mut rng);
                let p = turn * (c + jitter * cell);
                if fits(p, q) {
                    if let Some(i) = at(key) {
                        grid[i] = placed.len() as u32;
                    }
                    placed.push((t, p, q));
                    total += n;
                    b.instance_quat(NAME, m, q, p.into())?;
                    break;
                }
            }
        }
        log::debug!("meso: {} proteins placed in {visited} cells", placed.len());
    }
    progress(want, want);
    b.finish(NAME)
}

/// A loaded protein's atoms as a molecule: centred on their centroid,
/// waters dropped, `region[0]` its chain index (chains in order of first
/// appearance).
fn plasma_atoms(s: &Scene) -> Vec<Sphere> {
    let keep: Vec<bool> = match &s.atoms {
        Some(a) => (0..a.len())
            .map(|i| !super::select::WATER.contains(&a.resname_of(i)))
            .collect(),
        None => vec![true; s.spheres.len()],
    };
    let mut chains: Vec<u32> = Vec::new();
    let mut out: Vec<Sphere> = Vec::new();
    for (i, sp) in s.spheres.iter().enumerate() {
        if !keep[i] {
            continue;
        }
        let chain = s.atoms.as_ref().map_or(0, |a| a.chain[i]);
        let c = match chains.iter().position(|&x| x == chain) {
            Some(p) => p,
            None => {
                chains.push(chain);
                chains.len() - 1
            }
        } as u32;
        let mut a = *sp;
        a.region = [c, 0, 0, 0];
        out.push(a);
    }
    let n = out.len().max(1) as f64;
    let mean = out.iter().fold(DVec3::ZERO, |acc, a| {
        acc + DVec3::from(a.center.map(|x| x as f64))
    }) / n;
    for a in &mut out {
        a.center = (DVec3::from(a.center.map(|x| x as f64)) - mean)
            .as_vec3()
            .to_array();
    }
    out
}

/// Covering spheres of a protein in its frame: its atoms split into
/// COVER clusters (k-means from atoms spread along their order), each
/// sphere holding its cluster's atoms whole (centre distance + radius).
fn covering_spheres(atoms: &[Sphere]) -> Vec<(DVec3, f64)> {
    let pos: Vec<DVec3> = atoms
        .iter()
        .map(|a| DVec3::from(a.center.map(|x| x as f64)))
        .collect();
    if pos.is_empty() {
        return Vec::new();
    }
    let k = COVER.min(pos.len());
    let mut centres: Vec<DVec3> = (0..k).map(|i| pos[i * pos.len() / k]).collect();
    let mut owner = vec![0usize; pos.len()];
    for _ in 0..16 {
        for (i, p) in pos.iter().enumerate() {
            owner[i] = (0..k)
                .min_by(|&a, &b| {
                    p.distance_squared(centres[a])
                        .total_cmp(&p.distance_squared(centres[b]))
                })
                .unwrap_or(0);
        }
        let mut sum = vec![(DVec3::ZERO, 0usize); k];
        for (i, p) in pos.iter().enumerate() {
            sum[owner[i]].0 += *p;
            sum[owner[i]].1 += 1;
        }
        for (c, (s, n)) in centres.iter_mut().zip(&sum) {
            if *n > 0 {
                *c = *s / *n as f64;
            }
        }
    }
    let mut radius = vec![0.0f64; k];
    for (i, p) in pos.iter().enumerate() {
        let o = owner[i];
        radius[o] = radius[o].max(p.distance(centres[o]) + atoms[i].radius as f64);
    }
    centres
        .into_iter()
        .zip(radius)
        .filter(|(_, r)| *r > 0.0)
        .collect()
}

/// A uniformly random rotation (Shoemake).
fn random_rotation(rng: &mut Rng) -> DQuat {
    let (u1, u2, u3) = (rng.f64(), rng.f64(), rng.f64());
    let tau = std::f64::consts::TAU;
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    DQuat::from_xyzw(
        a * (tau * u2).sin(),
        a * (tau * u2).cos(),
        b * (tau * u3).sin(),
        b * (tau * u3).cos(),
    )
    .normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A long build reports the atoms placed, rising, then (want, want).
    #[test]
    fn the_build_reports_its_progress() {
        let mut calls = Vec::new();
        meso_with_progress(20_000_000, 1, &mut |d, t| calls.push((d, t))).expect("meso");
        // (the plasma's share: what the virion's 91,956 beads leave)
        let want = 20_000_000 - 91_956;
        assert!(calls.len() >= 3, "{calls:?}");
        assert!(
            calls
                .windows(2)
                .all(|w| w[0].0 <= w[1].0 && w[0].1 == w[1].1),
            "{calls:?}"
        );
        assert_eq!(calls.last(), Some(&(want, want)));
        assert!(calls[calls.len() - 2].0 < want);
    }

    #[test]
    fn the_scene_is_deterministic_and_near_its_size() {
        for n in [50_000u64, 2_000_000, 20_000_000] {
            let a = meso(n, 1).expect("meso");
            let b = meso(n, 1).expect("meso");
            assert!(
                a.spheres == b.spheres
                    && a.instancing == b.instancing
                    && a.level_names == b.level_names,
                "not deterministic at {n}"
            );
            let inst = a.instancing.as_ref().unwrap();
            let got = inst.represented();
            let virion = 91_956u64;
            if n > virion {
                // within half a protein of the asked count
                assert!(got.abs_diff(n) <= 11_484 / 2, "{n}: {got}");
            } else {
                assert_eq!(got, virion);
            }
            // the hierarchy: plasma | virion at the top
            let top: Vec<&str> = inst
                .nodes
                .iter()
                .filter(|x| x.depth == 1)
                .map(|x| x.label.as_str())
                .collect();
            assert!(top.contains(&"virion"), "{top:?}");
            if n >= 2_000_000 {
                assert!(top.contains(&"plasma"), "{top:?}");
            }
            // stored atoms do not grow with n: the virion's 384 beads and
            // the two proteins' atoms
            assert_eq!(a.spheres.len(), 384 + 5_469 + 11_484, "{n}");
        }
        let (a, b) = (meso(2_000_000, 1).unwrap(), meso(2_000_000, 2).unwrap());
        assert_ne!(a.instancing, b.instancing, "the seed changes nothing");
    }

    #[test]
    fn plasma_proteins_stay_out_of_the_virion_and_apart() {
        let s = meso(3_000_000, 1).unwrap();
        let inst = s.instancing.as_ref().unwrap();
        let Transforms::Rigid(t) = &inst.transforms else {
            panic!("rigid transforms expected")
        };
        let virion = parse_bytes(VIRION, Format::Json, "v", &LoadOptions::default()).unwrap();
        let vr = virion.bounding_sphere().1 as f64;
        // every plasma atom, placed, with its instance
        let mut atoms: Vec<(DVec3, f64, usize)> = Vec::new();
        let mut proteins = 0;
        for (k, tk) in t.iter().enumerate() {
            let m = &inst.molecules[inst.instance_molecule[k] as usize];
            if m.label != "1TII" && m.label != "3P3W" {
                continue;
            }
            proteins += 1;
            let own = &s.spheres[m.first as usize..(m.first + m.atoms) as usize];
            let r = own
                .iter()
                .map(|a| DVec3::from(a.center.map(|x| x as f64)).length() + a.radius as f64)
                .fold(0.0f64, f64::max);
            let c = DVec3::new(tk.t[0] as f64, tk.t[1] as f64, tk.t[2] as f64);
            assert!(c.length() - r >= vr, "protein {k} reaches into the virion");
            for a in own {
                let p = inst.transforms.apply(k, a.center);
                atoms.push((DVec3::from(p.map(|x| x as f64)), a.radius as f64, k));
            }
        }
        assert!(proteins > 100, "{proteins} plasma proteins");
        // no atom of one protein overlaps an atom of another (a grid of
        // 4 Å cells: radii are below 2 Å)
        let key = |p: DVec3| (p / 4.0).floor().as_ivec3();
        let mut grid: std::collections::HashMap<glam::IVec3, Vec<usize>> = Default::default();
        for (i, a) in atoms.iter().enumerate() {
            grid.entry(key(a.0)).or_default().push(i);
        }
        for (i, &(p, r, k)) in atoms.iter().enumerate() {
            let c = key(p);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let Some(v) = grid.get(&(c + glam::IVec3::new(dx, dy, dz))) else {
                            continue;
                        };
                        for &j in v {
                            let (q, rq, kq) = atoms[j];
                            assert!(
                                j <= i || kq == k || p.distance(q) >= r + rq,
                                "atoms of proteins {k} and {kq} overlap: {p} {q}"
                            );
                        }
                    }
                }
            }
        }
        // packed closer than their bounding spheres (a shell several
        // proteins thick: 2 * 10^7 atoms): most proteins have a neighbour
        // whose bounding sphere overlaps theirs, their atoms apart (the
        // covering spheres, as above)
        let s = meso(20_000_000, 1).unwrap();
        let inst = s.instancing.as_ref().unwrap();
        let radius: Vec<f64> = inst
            .molecules
            .iter()
            .map(|m| {
                s.spheres[m.first as usize..(m.first + m.atoms) as usize]
                    .iter()
                    .map(|a| DVec3::from(a.center.map(|x| x as f64)).length() + a.radius as f64)
                    .fold(0.0f64, f64::max)
            })
            .collect();
        let Transforms::Rigid(t) = &inst.transforms else {
            panic!("rigid transforms expected")
        };
        let centres: Vec<(DVec3, f64)> = t
            .iter()
            .enumerate()
            .filter(|&(k, _)| {
                let l = &inst.molecules[inst.instance_molecule[k] as usize].label;
                l == "1TII" || l == "3P3W"
            })
            .map(|(k, tk)| {
                let c = DVec3::new(tk.t[0] as f64, tk.t[1] as f64, tk.t[2] as f64);
                (c, radius[inst.instance_molecule[k] as usize])
            })
            .collect();
        let close = centres
            .iter()
            .enumerate()
            .filter(|&(k, &(c, r))| {
                centres
                    .iter()
                    .enumerate()
                    .any(|(j, &(c2, r2))| j != k && c.distance(c2) < r + r2)
            })
            .count();
        let n = centres.len();
        eprintln!(
            "{close} of {n} plasma proteins closer to a neighbour than their bounding spheres"
        );
        assert!(2 * close > n, "{close} of {n}");
    }
}
