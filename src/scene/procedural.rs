//! Deterministic procedural scenes for tests and benchmarks.
//!
//! * `capsid`: a virus-like particle. An outer shell of up to 60 copies of
//!   one bead-chain protein (placed with icosahedral symmetry when there are
//!   60) around a core of compact "genome" strands. Levels: compartment
//!   (shell / core), protein, domain, residue.
//! * `random`: uniform spheres in a cube. Levels: 4x4x4 grid cell, sphere.
//! * `lattice`: a simple cubic lattice. Levels: z layer, row.

use glam::{Mat3, Quat, Vec3};

use super::{MAX_LEVELS, Scene, SceneError, Sphere};

/// Largest sphere count accepted (region ids are u32 and memory is finite).
use super::MAX_SPHERES as MAX_ATOMS;

/// Generates the named scene with exactly `atoms` spheres.
pub fn procedural(name: &str, atoms: usize, seed: u64) -> Result<Scene, SceneError> {
    if atoms == 0 || atoms > MAX_ATOMS {
        return Err(SceneError::Invalid(format!(
            "procedural scene '{name}': sphere count must be between 1 and {MAX_ATOMS}, got {atoms}"
        )));
    }
    let (spheres, levels): (Vec<Sphere>, &[&str]) = match name.to_ascii_lowercase().as_str() {
        "capsid" => (
            capsid(atoms, seed),
            &["compartment", "protein", "domain", "residue"],
        ),
        "random" => (random(atoms, seed), &["cell", "sphere"]),
        "lattice" => (lattice(atoms), &["layer", "row"]),
        _ => return Err(SceneError::UnknownScene(name.to_string())),
    };
    debug_assert!(levels.len() <= MAX_LEVELS);
    Ok(Scene {
        spheres,
        level_names: levels.iter().map(|s| s.to_string()).collect(),
        source: format!("scene:{}", name.to_ascii_lowercase()),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    })
}

/// SplitMix64: tiny, fast, and good enough for scene generation (the
/// meso scene's too).
pub(crate) struct Rng(u64);

impl Rng {
    pub(crate) fn new(seed: u64) -> Self {
        Rng(seed ^ 0x5DEE_CE66_D1CE_4E5B)
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1), 53 bits.
    pub(crate) fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [0, 1).
    fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }

    /// Uniform direction on the unit sphere.
    fn unit(&mut self) -> Vec3 {
        let z = 2.0 * self.f32() - 1.0;
        let phi = std::f32::consts::TAU * self.f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform point in the unit ball.
    fn in_ball(&mut self) -> Vec3 {
        self.unit() * self.f32().cbrt()
    }
}

fn hsv(h: f32, s: f32, v: f32) -> [u8; 4] {
    let h = h.rem_euclid(1.0) * 6.0;
    let i = h.floor();
    let f = h - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    let (r, g, b) = match i as u32 {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    let c = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [c(r), c(g), c(b), 255]
}

const GOLDEN: f32 = 0.618_034;
/// Volume per atom in a compact protein, Å^3 (gives blob radii).
const ATOM_VOLUME: f32 = 12.0;
const BEADS_PER_RESIDUE: usize = 8;
const BEADS_PER_DOMAIN: usize = 100;
const BEADS_PER_STRAND: usize = 400;
const STEP: f32 = 1.5;

fn blob_radius(beads: usize) -> f32 {
    (3.0 * ATOM_VOLUME * beads as f32 / (4.0 * std::f32::consts::PI)).cbrt()
}

/// One bead of a generated protein (world coordinates of its copy).
#[derive(Clone, Copy)]
struct Bead {
    pos: Vec3,
    radius: f32,
    domain: u32,
    residue: u32,
}

/// A confined random walk of `n` beads around `center` (a polymer curled
/// into a blob of radius `r`): persistent steps of 1.5 Å, pulled back
/// toward the centre near the blob surface.
fn walk(rng: &mut Rng, center: Vec3, r: f32, n: usize, mut emit: impl FnMut(Vec3, f32)) {
    let mut p = center + rng.in_ball() * (0.3 * r);
    let mut dir = rng.unit();
    for _ in 0..n {
        emit(p, rng.range(1.5, 1.9));
        let to_c = center - p;
        let d = to_c.length();
        let inner = 0.6 * r;
        let pull = if d > inner {
            to_c / d * ((d - inner) / (0.4 * r).max(1e-3)).min(3.0)
        } else {
            Vec3::ZERO
        };
        dir = (dir * 0.6 + rng.unit() * 0.8 + pull).normalize_or(Vec3::Z);
        p += dir * STEP;
    }
}

/// One protein: a domain of ~100 beads around each site, residues of 8
/// beads that never span domains.
fn protein(rng: &mut Rng, sites: &[Vec3], beads: usize, rd: f32) -> Vec<Bead> {
    let per = beads / sites.len();
    let extra = beads % sites.len();
    let mut out = Vec::with_capacity(beads);
    let mut residue = 0u32;
    let mut in_residue = 0usize;
    for (d, &site) in sites.iter().enumerate() {
        let n = per + usize::from(d < extra);
        if n == 0 {
            continue;
        }
        if in_residue > 0 {
            residue += 1;
            in_residue = 0;
        }
        walk(rng, site, rd, n, |pos, radius| {
            if in_residue == BEADS_PER_RESIDUE {
                in_residue = 0;
                residue += 1;
            }
            in_residue += 1;
            out.push(Bead {
                pos,
                radius,
                domain: d as u32,
                residue,
            });
        });
    }
    out
}

/// The 60 rotations of the icosahedral group, by closure of a 5-fold and a
/// 3-fold generator (an icosahedron with vertices (0, ±1, ±φ) and cyclic).
/// The identity comes first.
fn icosahedral_rotations() -> Vec<Quat> {
    let gens = [
        Quat::from_axis_angle(five_fold_axis(), std::f32::consts::TAU / 5.0),
        Quat::from_axis_angle(Vec3::ONE.normalize(), std::f32::consts::TAU / 3.0),
    ];
    let mut group = vec![Quat::IDENTITY];
    let mut i = 0;
    while i < group.len() && group.len() < 60 {
        for g in gens {
            let q = (g * group[i]).normalize();
            if !group.iter().any(|h| h.dot(q).abs() > 0.9999) {
                group.push(q);
            }
        }
        i += 1;
    }
    group
}

const PHI: f32 = 1.618_034;

fn five_fold_axis() -> Vec3 {
    Vec3::new(0.0, 1.0, PHI).normalize()
}

/// Unit vectors spread evenly on the sphere (Fibonacci lattice).
fn fibonacci_directions(n: usize) -> Vec<Vec3> {
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let a = i as f32 * std::f32::consts::TAU * GOLDEN;
            Vec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// Index of the direction in `centres` closest to `u`.
fn nearest(u: Vec3, centres: &[Vec3]) -> usize {
    let mut best = (0, f32::MIN);
    for (i, c) in centres.iter().enumerate() {
        let d = u.dot(*c);
        if d > best.1 {
            best = (i, d);
        }
    }
    best.0
}

fn capsid(atoms: usize, seed: u64) -> Vec<Sphere> {
    let mut rng = Rng::new(seed);
    // About 3/4 of the atoms in the shell, at least 8 beads per protein.
    let shell_target = atoms * 3 / 4;
    let copies = (shell_target / 8).clamp(1, 60);
    let per = shell_target / copies;
    let core = atoms - copies * per;
    let mut spheres = Vec::with_capacity(atoms);

    // Copy centres on the unit sphere. With 60 copies they are the orbit of
    // a generic direction (the centroid of an asymmetric unit) under the
    // icosahedral group, as in a T=1 virus capsid.
    let ico = copies == 60;
    let rotations = if ico {
        icosahedral_rotations()
    } else {
        vec![Quat::IDENTITY; copies]
    };
    let centres: Vec<Vec3> = if ico {
        let v = five_fold_axis();
        let f = Vec3::ONE.normalize();
        let e = Vec3::new(0.5, (1.0 + PHI) / 2.0, PHI / 2.0).normalize();
        let d0 = (v + f + e).normalize();
        rotations.iter().map(|g| *g * d0).collect()
    } else {
        fibonacci_directions(copies)
    };

    // Domain sites: an even Fibonacci lattice over the whole sphere, each
    // site owned by the nearest copy centre. These Voronoi cells tile the
    // sphere, so the proteins close the shell without overlapping.
    let domains = per.div_ceil(BEADS_PER_DOMAIN).max(1);
    let lattice = fibonacci_directions(copies * domains);
    let rd = blob_radius((per / domains).max(1));
    let site_spacing = (4.0 * std::f32::consts::PI / lattice.len() as f32).sqrt();
    let shell_r = (1.8 * rd / site_spacing).max(2.0 * rd);
    let sites_of = |copy: usize, rng: &mut Rng| -> Vec<Vec3> {
        let mut sites: Vec<Vec3> = lattice
            .iter()
            .filter(|u| nearest(**u, &centres) == copy)
            .map(|u| *u * (shell_r + rng.range(-0.2, 0.2) * rd))
            .collect();
        if sites.is_empty() {
            sites.push(centres[copy] * shell_r);
        }
        sites
    };
    // Icosahedral copies are rotated images of one protein; otherwise each
    // copy is built in its own cell.
    let template = if ico {
        let sites = sites_of(0, &mut rng);
        protein(&mut rng, &sites, per, rd)
    } else {
        Vec::new()
    };
    // Copy c sits next to the 5-fold axis g_c * v; number the 12 distinct
    // axes to colour by pentamer.
    let mut axes: Vec<Vec3> = Vec::new();
    let pentamer: Vec<usize> = rotations
        .iter()
        .map(|g| {
            let v = *g * five_fold_axis();
            axes.iter()
                .position(|a| a.dot(v) > 0.999)
                .unwrap_or_else(|| {
                    axes.push(v);
                    axes.len() - 1
                })
        })
        .collect();
    let mut domain_base = 0u32;
    let mut residue_base = 0u32;
    for c in 0..copies {
        let own;
        let (beads, rot): (&[Bead], Mat3) = if ico {
            (&template, Mat3::from_quat(rotations[c]))
        } else {
            let sites = sites_of(c, &mut rng);
            own = protein(&mut rng, &sites, per, rd);
            (&own, Mat3::IDENTITY)
        };
        // Colour by pentamer with a lighter or darker shade per protein, so
        // both levels read in images.
        let group = if ico { pentamer[c] } else { c };
        let hue = group as f32 * GOLDEN;
        let member = if ico {
            pentamer[..c].iter().filter(|&&p| p == pentamer[c]).count()
        } else {
            c % 5
        };
        let shade = 0.7 + 0.07 * member as f32;
        for b in beads {
            let v = shade * if b.domain % 2 == 0 { 1.0 } else { 0.93 };
            spheres.push(Sphere {
                center: (rot * b.pos).to_array(),
                radius: b.radius,
                color: hsv(hue, 0.5, v),
                region: [
                    0,
                    c as u32,
                    domain_base + b.domain,
                    residue_base + b.residue,
                ],
            });
        }
        domain_base += beads.last().map_or(0, |b| b.domain + 1);
        residue_base += beads.last().map_or(0, |b| b.residue + 1);
    }

    // Core: a dense ball of compact "genome" strands well inside the shell.
    let strand_r = blob_radius(BEADS_PER_STRAND.min(core.max(1))) * 1.1;
    let ball = (blob_radius(core) * 1.1)
        .min(shell_r - 1.5 * rd - strand_r)
        .max(0.0);
    let mut molecule = copies as u32;
    let mut domain = domain_base;
    let mut residue = residue_base;
    let mut left = core;
    while left > 0 {
        let n = left.min(BEADS_PER_STRAND);
        left -= n;
        let center = rng.in_ball() * (ball - strand_r).max(0.0);
        let hue = 0.05 + 0.08 * rng.f32();
        let mut i = 0usize;
        walk(&mut rng, center, strand_r, n, |pos, radius| {
            if i > 0 && i.is_multiple_of(BEADS_PER_RESIDUE) {
                residue += 1;
            }
            if i > 0 && i.is_multiple_of(BEADS_PER_DOMAIN) {
                domain += 1;
            }
            let v = if (i / BEADS_PER_DOMAIN).is_multiple_of(2) {
                0.95
            } else {
                0.85
            };
            spheres.push(Sphere {
                center: pos.to_array(),
                radius: radius * 0.9,
                color: hsv(hue, 0.65, v),
                region: [1, molecule, domain, residue],
            });
            i += 1;
        });
        molecule += 1;
        domain += 1;
        residue += 1;
    }
    spheres
}

fn random(atoms: usize, seed: u64) -> Vec<Sphere> {
    let mut rng = Rng::new(seed);
    let side = (atoms as f32).cbrt() * 4.0;
    (0..atoms)
        .map(|i| {
            let u = [rng.f32(), rng.f32(), rng.f32()];
            let cell = u.map(|x| ((x * 4.0) as u32).min(3));
            Sphere {
                center: u.map(|x| (x - 0.5) * side),
                radius: rng.range(1.0, 2.0),
                color: hsv(rng.f32(), rng.range(0.4, 0.8), rng.range(0.75, 1.0)),
                region: [cell[0] + 4 * (cell[1] + 4 * cell[2]), i as u32, 0, 0],
            }
        })
        .collect()
}

/// Smallest n with n^3 >= v.
fn ceil_cbrt(v: usize) -> usize {
    let mut n = (v as f64).cbrt().round() as usize;
    while n.pow(3) < v {
        n += 1;
    }
    while n > 1 && (n - 1).pow(3) >= v {
        n -= 1;
    }
    n.max(1)
}

fn lattice(atoms: usize) -> Vec<Sphere> {
    let n = ceil_cbrt(atoms);
    let spacing = 3.0f32;
    let half = (n - 1) as f32 * spacing * 0.5;
    (0..atoms)
        .map(|idx| {
            let (i, j, k) = (idx % n, (idx / n) % n, idx / (n * n));
            Sphere {
                center: [
                    i as f32 * spacing - half,
                    j as f32 * spacing - half,
                    k as f32 * spacing - half,
                ],
                radius: 1.2,
                // A hue ramp through the layers shows depth order.
                color: hsv(0.66 * k as f32 / n as f32, 0.5, 0.7 + 0.3 * (j % 2) as f32),
                region: [k as u32, (k * n + j) as u32, 0, 0],
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn distinct(s: &Scene, level: usize) -> usize {
        let mut v: Vec<u32> = s.spheres.iter().map(|s| s.region[level]).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    }

    fn check(s: &Scene) {
        for sp in &s.spheres {
            assert!(sp.center.iter().all(|c| c.is_finite()));
            assert!(sp.radius > 0.0 && sp.radius.is_finite());
            assert_eq!(sp.color[3], 255);
        }
    }

    #[test]
    fn exact_counts() {
        for name in ["capsid", "random", "lattice"] {
            for n in [1usize, 2, 7, 100, 1000, 12_345, 200_000] {
                let s = procedural(name, n, 1).unwrap();
                assert_eq!(s.spheres.len(), n, "{name} {n}");
                check(&s);
            }
        }
    }

    #[test]
    fn deterministic() {
        for name in ["capsid", "random", "lattice"] {
            let a = procedural(name, 5000, 42).unwrap();
            let b = procedural(name, 5000, 42).unwrap();
            assert_eq!(a.spheres, b.spheres);
        }
        let a = procedural("capsid", 5000, 1).unwrap();
        let b = procedural("capsid", 5000, 2).unwrap();
        assert_ne!(a.spheres, b.spheres);
    }

    #[test]
    fn capsid_hierarchy() {
        let s = procedural("capsid", 200_000, 7).unwrap();
        assert_eq!(
            s.level_names,
            vec!["compartment", "protein", "domain", "residue"]
        );
        assert_eq!(s.source, "scene:capsid");
        assert_eq!(distinct(&s, 0), 2);
        let shell = s.spheres.iter().filter(|s| s.region[0] == 0).count();
        assert_eq!(shell, 150_000);
        let shell_proteins = {
            let mut v: Vec<u32> = s
                .spheres
                .iter()
                .filter(|s| s.region[0] == 0)
                .map(|s| s.region[1])
                .collect();
            v.dedup();
            v.len()
        };
        assert_eq!(shell_proteins, 60);
        // Domains of ~100 beads, residues of ~8.
        let domains = distinct(&s, 2);
        assert!((1800..=2200).contains(&domains), "{domains}");
        let residues = distinct(&s, 3);
        assert!((23_000..=27_000).contains(&residues), "{residues}");
        // The core sits inside the shell.
        let (c, _) = s.bounding_sphere();
        let dist = |sp: &Sphere| Vec3::from(sp.center).distance(c);
        let shell_min = s
            .spheres
            .iter()
            .filter(|s| s.region[0] == 0)
            .map(dist)
            .fold(f32::MAX, f32::min);
        let core_max = s
            .spheres
            .iter()
            .filter(|s| s.region[0] == 1)
            .map(dist)
            .fold(0.0, f32::max);
        assert!(
            core_max < shell_min * 1.05,
            "core {core_max} shell {shell_min}"
        );
    }

    #[test]
    fn icosahedral_group_has_60() {
        assert_eq!(icosahedral_rotations().len(), 60);
    }

    #[test]
    fn lattice_and_random_levels() {
        let s = procedural("lattice", 1000, 0).unwrap();
        assert_eq!(distinct(&s, 0), 10);
        assert_eq!(distinct(&s, 1), 100);
        let (lo, hi) = s.center_bounds().unwrap();
        assert_eq!(hi - lo, Vec3::splat(27.0));
        assert_eq!(ceil_cbrt(1), 1);
        assert_eq!(ceil_cbrt(8), 2);
        assert_eq!(ceil_cbrt(9), 3);
        assert_eq!(ceil_cbrt(1_000_000), 100);
        assert_eq!(ceil_cbrt(1_000_001), 101);

        let s = procedural("random", 10_000, 3).unwrap();
        assert_eq!(distinct(&s, 0), 64);
        assert_eq!(distinct(&s, 1), 10_000);
        let side = 10_000f32.cbrt() * 4.0;
        assert!(
            s.spheres
                .iter()
                .all(|sp| sp.center.iter().all(|c| c.abs() <= side / 2.0))
        );
        assert!(s.spheres.iter().all(|sp| (1.0..=2.0).contains(&sp.radius)));
    }

    #[test]
    fn errors() {
        assert!(matches!(
            procedural("nope", 10, 0),
            Err(SceneError::UnknownScene(_))
        ));
        assert!(matches!(
            procedural("capsid", 0, 0),
            Err(SceneError::Invalid(_))
        ));
        assert_eq!(procedural("Lattice", 8, 0).unwrap().source, "scene:lattice");
    }

    #[test]
    fn large_capsid_is_fast() {
        let t = std::time::Instant::now();
        let s = procedural("capsid", 1_000_000, 1).unwrap();
        assert_eq!(s.spheres.len(), 1_000_000);
        eprintln!("capsid 1M: {:?}", t.elapsed());
    }
}
