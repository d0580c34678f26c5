//! Levels of detail of a molecule type (Mol*'s scheme): its atoms put in
//! one order in which every coarser level is a prefix. The order is a
//! spatial (Morton) order started at the atom nearest the centroid, and
//! level L takes every 4^L-th atom of it; its spheres keep the molecule's
//! volume (radius grown by (n / n_L)^(1/3)), down to one sphere at the
//! centroid's atom. Level 0 is every atom in the molecule's own order (what
//! an instance draws with `--lod off`, byte for byte). A level is drawn
//! below a switch size where its silhouette is as close to level 0's as
//! level 0's is to itself moved half a pixel (or IoU 0.95: [`needed_iou`]).

/// Atoms of level L+1 per atom of level L.
pub const LOD_STRIDE: u32 = 4;

/// The levels of one molecule type.
#[derive(Clone, Debug, PartialEq)]
pub struct MoleculeLod {
    /// Indices of the molecule's atoms in LOD order: level L is the first
    /// `counts[L]`.
    pub order: Vec<u32>,
    /// Atoms per level: `counts[0]` is every atom, decreasing to 1.
    pub counts: Vec<u32>,
    /// Radius factor per level (1 at level 0): the one of a few around
    /// the volume-keeping (n / n_L)^(1/3) whose silhouette best matches
    /// level 0's (the volume-keeping factor overshoots the outline).
    pub radius: Vec<f32>,
}

impl MoleculeLod {
    /// The levels of a molecule of `atoms` (centre, radius in its frame).
    pub fn new(atoms: &[[f32; 4]]) -> MoleculeLod {
        let n = atoms.len();
        if n == 0 {
            return MoleculeLod {
                order: Vec::new(),
                counts: vec![0],
                radius: vec![1.0],
            };
        }
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        let mut sum = [0.0f64; 3];
        for a in atoms {
            for i in 0..3 {
                lo[i] = lo[i].min(a[i]);
                hi[i] = hi[i].max(a[i]);
                sum[i] += a[i] as f64;
            }
        }
        let centroid = sum.map(|s| (s / n as f64) as f32);
        let scale: [f32; 3] = std::array::from_fn(|i| {
            let e = hi[i] - lo[i];
            if e > 0.0 { 1023.0 / e } else { 0.0 }
        });
        let morton = |a: &[f32; 4]| -> u32 {
            let mut code = 0u32;
            for i in 0..3 {
                let q = ((a[i] - lo[i]) * scale[i]).clamp(0.0, 1023.0) as u32;
                for b in 0..10 {
                    code |= ((q >> b) & 1) << (3 * b + i);
                }
            }
            code
        };
        let mut sorted: Vec<u32> = (0..n as u32).collect();
        sorted.sort_by_key(|&i| (morton(&atoms[i as usize]), i));
        let d2 = |i: u32| {
            let a = atoms[i as usize];
            (0..3).map(|k| (a[k] - centroid[k]).powi(2)).sum::<f32>()
        };
        let start = (0..n)
            .min_by(|&x, &y| d2(sorted[x]).total_cmp(&d2(sorted[y])))
            .unwrap_or(0);
        // position j of the cyclic order from `start` belongs to the levels
        // whose stride divides j: the coarsest first
        let rank = |j: usize| -> u32 {
            if j == 0 {
                return u32::MAX;
            }
            let mut r = 0;
            let mut j = j;
            while j.is_multiple_of(LOD_STRIDE as usize) {
                j /= LOD_STRIDE as usize;
                r += 1;
            }
            r
        };
        let mut js: Vec<usize> = (0..n).collect();
        js.sort_by_key(|&j| (std::cmp::Reverse(rank(j)), j));
        let order = js.iter().map(|&j| sorted[(start + j) % n]).collect();
        let mut counts = vec![n as u32];
        let mut stride = 1usize;
        while *counts.last().unwrap_or(&1) > 1 {
            stride *= LOD_STRIDE as usize;
            counts.push(n.div_ceil(stride) as u32);
        }
        let radius = vec![1.0; counts.len()];
        let mut lod = MoleculeLod {
            order,
            counts,
            radius,
        };
        lod.fit_radii(atoms);
        lod
    }

    /// Each coarse level's radius factor: among 0.5..1.25 x the
    /// volume-keeping one, the best mean silhouette IoU along
    /// [`CHECK_DIRS`] with the molecule 64 px across.
    fn fit_radii(&mut self, atoms: &[[f32; 4]]) {
        let ppu = 64.0 / extent(atoms).max(1e-6);
        for l in 1..self.levels() {
            let vol = (self.counts[0] as f32 / self.counts[l].max(1) as f32).cbrt();
            let mut best = (f64::MIN, vol);
            for k in 4..=10 {
                self.radius[l] = vol * k as f32 / 8.0;
                let coarse = self.level_spheres(atoms, l);
                let iou: f64 = CHECK_DIRS
                    .iter()
                    .map(|&d| silhouette_iou(atoms, &coarse, d, ppu))
                    .sum();
                if iou > best.0 {
                    best = (iou, self.radius[l]);
                }
            }
            self.radius[l] = best.1;
        }
    }

    /// Levels (1 for a single atom).
    pub fn levels(&self) -> usize {
        self.counts.len()
    }

    /// The radius factor of level `l`.
    pub fn radius_scale(&self, l: usize) -> f32 {
        self.radius[l]
    }

    /// Level `l`'s spheres (level 0: the atoms as given).
    pub fn level_spheres(&self, atoms: &[[f32; 4]], l: usize) -> Vec<[f32; 4]> {
        if l == 0 {
            return atoms.to_vec();
        }
        let s = self.radius_scale(l);
        self.order[..self.counts[l] as usize]
            .iter()
            .map(|&i| {
                let a = atoms[i as usize];
                [a[0], a[1], a[2], a[3] * s]
            })
            .collect()
    }
}

/// Largest extent of the spheres' box.
fn extent(atoms: &[[f32; 4]]) -> f32 {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for a in atoms {
        for k in 0..3 {
            lo[k] = lo[k].min(a[k] - a[3]);
            hi[k] = hi[k].max(a[k] + a[3]);
        }
    }
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max)
}

/// Silhouette IoU against level 0 that always suffices for a level to be
/// drawn (where level 0 keeps more than this under half a pixel of motion,
/// [`needed_iou`]).
pub const MIN_IOU: f64 = 0.95;

/// The silhouette IoU a coarse level must keep against level 0 seen along
/// `dir` at `ppu`: [`MIN_IOU`], or less where level 0's own silhouette
/// changes more than that when the molecule moves half a pixel
/// ([`shift_iou`]): a level is then no further from full detail than the
/// next frame of a slow pan. (0.95 alone is more than full detail keeps
/// below ~100 px across: 1TII moved half a pixel keeps 0.70 at 8 px, 0.81
/// at 16, 0.90 at 32, 0.94 at 64; the coarse levels of every k-th atom keep
/// about the same IoU at every size, so with 0.95 alone only level 1
/// switched in, at a few px, and a 10^9-atom overview drew every atom.)
pub fn needed_iou(atoms: &[[f32; 4]], dir: [f32; 3], ppu: f32) -> f64 {
    MIN_IOU.min(shift_iou(atoms, dir, ppu))
}

/// Pixels covered by `spheres` seen along `dir` at `ppu` pixels per unit
/// (pixel centres on a grid whose corner is `lo`, `w` x `h`).
pub fn silhouette(
    spheres: &[[f32; 4]],
    dir: [f32; 3],
    ppu: f32,
    lo: [f32; 2],
    w: usize,
    h: usize,
) -> Vec<bool> {
    let (u, v) = plane_axes(dir);
    let mut m = vec![false; w * h];
    for s in spheres {
        let (pu, pv) = (dot3(s, u), dot3(s, v));
        let (cx, cy, r) = ((pu - lo[0]) * ppu, (pv - lo[1]) * ppu, s[3] * ppu);
        let x0 = (cx - r - 0.5).floor().max(0.0) as usize;
        let y0 = (cy - r - 0.5).floor().max(0.0) as usize;
        let x1 = ((cx + r + 0.5).ceil().max(0.0) as usize).min(w);
        let y1 = ((cy + r + 0.5).ceil().max(0.0) as usize).min(h);
        for y in y0..y1 {
            for x in x0..x1 {
                let (dx, dy) = (x as f32 + 0.5 - cx, y as f32 + 0.5 - cy);
                if dx * dx + dy * dy <= r * r {
                    m[y * w + x] = true;
                }
            }
        }
    }
    m
}

fn dot3(a: &[f32; 4], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Two unit vectors across `dir`.
fn plane_axes(dir: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    let d = glam::Vec3::from(dir).normalize_or(glam::Vec3::Z);
    let u = d.any_orthonormal_vector();
    (u.into(), d.cross(u).into())
}

/// Silhouette IoU of `coarse` against `fine` seen along `dir` at `ppu`.
pub fn silhouette_iou(fine: &[[f32; 4]], coarse: &[[f32; 4]], dir: [f32; 3], ppu: f32) -> f64 {
    let (u, v) = plane_axes(dir);
    let mut lo = [f32::MAX; 2];
    let mut hi = [f32::MIN; 2];
    for s in fine.iter().chain(coarse) {
        let (pu, pv) = (dot3(s, u), dot3(s, v));
        lo = [lo[0].min(pu - s[3]), lo[1].min(pv - s[3])];
        hi = [hi[0].max(pu + s[3]), hi[1].max(pv + s[3])];
    }
    let w = ((hi[0] - lo[0]) * ppu).ceil() as usize + 1;
    let h = ((hi[1] - lo[1]) * ppu).ceil() as usize + 1;
    let a = silhouette(fine, dir, ppu, lo, w, h);
    let b = silhouette(coarse, dir, ppu, lo, w, h);
    let inter = a.iter().zip(&b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(&b).filter(|(x, y)| **x || **y).count();
    if union == 0 {
        1.0
    } else {
        inter as f64 / union as f64
    }
}

/// Level 0's silhouette IoU against itself moved half a pixel along both
/// axes of the view (seen along `dir` at `ppu`).
pub fn shift_iou(atoms: &[[f32; 4]], dir: [f32; 3], ppu: f32) -> f64 {
    let (u, v) = plane_axes(dir);
    let h = 0.5 / ppu;
    let moved: Vec<[f32; 4]> = atoms
        .iter()
        .map(|a| {
            [
                a[0] + h * (u[0] + v[0]),
                a[1] + h * (u[1] + v[1]),
                a[2] + h * (u[2] + v[2]),
                a[3],
            ]
        })
        .collect();
    silhouette_iou(atoms, &moved, dir, ppu)
}

/// The directions a level's silhouette is checked along (the molecule's
/// axes; instances turn it every way).
pub const CHECK_DIRS: [[f32; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

impl MoleculeLod {
    /// Per level, the most pixels per unit (world length) at which an
    /// instance may draw it: where its spheres project at most `pixels` in
    /// radius and its silhouette keeps [`needed_iou`] of level 0's along
    /// [`CHECK_DIRS`] (searched down in steps of sqrt 2 from the size
    /// bound; below a molecule of 2 pixels any level will do). Level 0:
    /// infinity. Non-increasing with the level.
    pub fn switch_ppu(&self, atoms: &[[f32; 4]], pixels: f32) -> Vec<f32> {
        let mut out = vec![f32::INFINITY];
        if atoms.is_empty() {
            return out;
        }
        let mean_r = atoms.iter().map(|a| a[3]).sum::<f32>() / atoms.len() as f32;
        for l in 1..self.levels() {
            let coarse = self.level_spheres(atoms, l);
            let mut ppu = (pixels / (mean_r * self.radius_scale(l))).min(out[l - 1]);
            // (ends: far enough below a pixel both silhouettes are empty)
            while !CHECK_DIRS.iter().all(|&d| {
                // (>= needed_iou; level 0's moved silhouette only if needed)
                let iou = silhouette_iou(atoms, &coarse, d, ppu);
                iou >= MIN_IOU || iou >= shift_iou(atoms, d, ppu)
            }) {
                ppu /= std::f32::consts::SQRT_2;
            }
            out.push(ppu);
        }
        out
    }
}

/// The level an instance draws at `ppu` pixels per unit: the coarsest
/// whose switch size (`MoleculeLod::switch_ppu`) it is within.
pub fn level_for(switch: &[f32], ppu: f32) -> usize {
    switch.iter().rposition(|&s| ppu <= s).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A blob of `n` atoms on a jittered grid (a protein-like packing:
    /// radius 1.7, spacing 1.5).
    fn blob(n: usize, seed: u32) -> Vec<[f32; 4]> {
        let mut out = Vec::new();
        let mut h = seed.wrapping_mul(2654435761);
        let mut rnd = || {
            h ^= h << 13;
            h ^= h >> 17;
            h ^= h << 5;
            (h as f32 / u32::MAX as f32) - 0.5
        };
        let side = (n as f32).cbrt().ceil() as i32 + 2;
        'outer: for x in -side..=side {
            for y in -side..=side {
                for z in -side..=side {
                    let p = [x as f32 * 1.5, y as f32 * 0.9 * 1.5, z as f32 * 1.2 * 1.5];
                    let r2 = (p[0] / 1.3).powi(2) + p[1].powi(2) + p[2].powi(2);
                    if r2 <= (side as f32 * 1.5 * 0.5).powi(2) {
                        out.push([
                            p[0] + 0.3 * rnd(),
                            p[1] + 0.3 * rnd(),
                            p[2] + 0.3 * rnd(),
                            1.7,
                        ]);
                        if out.len() == n {
                            break 'outer;
                        }
                    }
                }
            }
        }
        out
    }

    #[test]
    fn levels_are_nested_prefixes_of_a_permutation() {
        for n in [1usize, 2, 5, 64, 1000, 4097] {
            let atoms = blob(n, n as u32);
            let n = atoms.len();
            let lod = MoleculeLod::new(&atoms);
            let mut seen = lod.order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..n as u32).collect::<Vec<_>>(), "not a permutation");
            assert_eq!(lod.counts[0] as usize, n);
            assert_eq!(*lod.counts.last().unwrap(), 1);
            assert!(
                lod.counts.windows(2).all(|w| w[1] < w[0]),
                "{:?}",
                lod.counts
            );
            for l in 1..lod.levels() {
                assert_eq!(lod.counts[l] as usize, n.div_ceil(4usize.pow(l as u32)));
            }
            // one sphere: the atom nearest the centroid
            let c: [f32; 3] = std::array::from_fn(|k| {
                atoms.iter().map(|a| a[k] as f64).sum::<f64>() as f32 / n as f32
            });
            let d = |a: &[f32; 4]| (0..3).map(|k| (a[k] - c[k]).powi(2)).sum::<f32>();
            let best = atoms.iter().map(d).fold(f32::MAX, f32::min);
            assert_eq!(d(&atoms[lod.order[0] as usize]), best);
        }
    }

    #[test]
    fn the_level_follows_the_projected_size() {
        let atoms = blob(1000, 3);
        let lod = MoleculeLod::new(&atoms);
        let sw = lod.switch_ppu(&atoms, 2.0);
        assert!(sw.windows(2).all(|w| w[1] <= w[0]), "{sw:?}");
        assert_eq!(level_for(&sw, 1e9), 0);
        assert_eq!(level_for(&sw, 1e-9), lod.levels() - 1);
        for l in 1..lod.levels() {
            // the level's spheres are at most 2 px at its switch size
            assert!(1.7 * lod.radius_scale(l) * sw[l] <= 2.0 + 1e-4);
            assert!(level_for(&sw, sw[l]) >= l);
            // just above its switch size the instance draws a finer level
            if sw[l] < sw[l - 1] {
                assert!(level_for(&sw, sw[l] * 1.001) < l);
            }
        }
    }
}

#[cfg(test)]
mod coverage {
    use super::*;
    use crate::scene::{LoadOptions, load};

    /// Full detail's own silhouette under half a pixel of motion: far
    /// below 0.95 at the sizes a mesoscale overview shows a protein (so
    /// 0.95 alone would keep every atom there), 0.95 or more only when the
    /// molecule is hundreds of pixels across; and with the rule, 1TII at
    /// 8 px across (a 10^9-atom overview) draws a level of 1/64 of its
    /// atoms or coarser.
    #[test]
    fn half_a_pixel_of_motion_sets_the_floor() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb");
        let scene = load(
            std::path::Path::new(path),
            &LoadOptions::default(),
            &mut |_, _| {},
        )
        .expect("load");
        let atoms: Vec<[f32; 4]> = scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect();
        let ext = super::extent(&atoms);
        for d in CHECK_DIRS {
            let small = shift_iou(&atoms, d, 8.0 / ext);
            let large = shift_iou(&atoms, d, 256.0 / ext);
            assert!(small < 0.8, "{d:?}: {small:.3} at 8 px");
            assert!(large >= MIN_IOU, "{d:?}: {large:.3} at 256 px");
            assert_eq!(needed_iou(&atoms, d, 256.0 / ext), MIN_IOU);
            assert!((needed_iou(&atoms, d, 8.0 / ext) - small).abs() < 1e-12);
        }
        let lod = MoleculeLod::new(&atoms);
        let level = level_for(&lod.switch_ppu(&atoms, 2.0), 8.0 / ext);
        assert!(level >= 3, "level {level} at 8 px across");
    }

    /// Every molecule type of the SARS-CoV-2 and HIV-1 models: every level
    /// keeps [`needed_iou`] of level 0's silhouette at its switch size
    /// (0.95, or what level 0 keeps moved half a pixel where that is
    /// less), along the axes the switch was searched on; along six oblique
    /// directions it never saw, the worst is printed.
    #[test]
    fn coarse_levels_cover_their_molecules_at_the_switch_size() {
        let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/meso/");
        let oblique: [[f32; 3]; 6] = [
            [1.0, 1.0, 1.0],
            [1.0, -1.0, 0.5],
            [-0.3, 1.0, 1.0],
            [0.2, 0.1, 1.0],
            [1.0, 0.3, -0.7],
            [0.5, -1.0, -1.0],
        ];
        for file in [
            "sarscov2_2-no_bonds.bcif",
            "HIV-1_0.1.6-8_mixed_radii_pdb.json",
        ] {
            let path = format!("{dir}{file}");
            let scene = load(
                std::path::Path::new(&path),
                &LoadOptions::default(),
                &mut |_, _| {},
            )
            .expect("load");
            let inst = scene.instancing.as_ref().expect("instanced");
            for m in &inst.molecules {
                let atoms: Vec<[f32; 4]> = scene.spheres
                    [m.first as usize..(m.first + m.atoms) as usize]
                    .iter()
                    .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
                    .collect();
                let lod = MoleculeLod::new(&atoms);
                let sw = lod.switch_ppu(&atoms, 2.0);
                for (l, &at) in sw.iter().enumerate().skip(1) {
                    let coarse = lod.level_spheres(&atoms, l);
                    for d in CHECK_DIRS {
                        let iou = silhouette_iou(&atoms, &coarse, d, at);
                        let need = needed_iou(&atoms, d, at);
                        assert!(
                            need <= MIN_IOU && iou >= need,
                            "{file} {} level {l}: IoU {iou:.3} < {need:.3}",
                            m.label
                        );
                    }
                    let worst = oblique
                        .iter()
                        .map(|&d| silhouette_iou(&atoms, &coarse, d, at))
                        .fold(1.0f64, f64::min);
                    eprintln!(
                        "{file} {} ({} atoms) level {l} ({} spheres): radius x{:.2}, switch {:.4} px/A ({:.0} px across), oblique IoU {worst:.3}",
                        m.label,
                        m.atoms,
                        lod.counts[l],
                        lod.radius[l],
                        at,
                        at * super::extent(&atoms)
                    );
                }
            }
        }
    }
}
