//! Extremes over every represented atom of an instanced scene (the box and
//! bounding sphere of the centres, a light view's extent, the sphere
//! nearest the eye) without visiting every atom: an instance's atoms lie
//! in the hull of its molecule's centre box placed by the instance's
//! transform, so an instance whose hull cannot beat the best value found
//! so far is skipped (the largest bounds are visited first). The results
//! are the full scan's, bit for bit: the same values of the same atoms,
//! and a maximum does not depend on the order. At 10^9 atoms a full scan
//! took seconds per call (the light fit, the tile margin of each image).
//! Copies with the same molecule and transform bits are visited once.

use super::Transforms;
use glam::{DVec3, Vec3};
use std::borrow::Cow;

/// An instanced scene's atoms as placed copies, with each instance's hull.
pub struct Extremes<'a> {
    transforms: &'a Transforms,
    instance_molecule: &'a [u32],
    /// Per molecule type: first atom, atom count.
    molecules: Vec<(u32, u32)>,
    /// The stored atoms (centre, radius in their molecule's frame).
    atoms: Cow<'a, [[f32; 4]]>,
    /// Per instance: its molecule's centre box corners placed, its
    /// molecule's largest radius, and a margin for f32 rounding.
    hulls: Vec<Hull>,
}

/// A molecule's centre box (least, largest corner) and largest radius.
type CentreBox = ([f32; 3], [f32; 3], f32);

struct Hull {
    corners: [DVec3; 8],
    radius: f64,
    margin: f64,
    /// Its molecule's atoms are all finite.
    finite: bool,
}

impl<'a> Extremes<'a> {
    pub fn new(
        transforms: &'a Transforms,
        instance_molecule: &'a [u32],
        molecules: Vec<(u32, u32)>,
        atoms: Cow<'a, [[f32; 4]]>,
    ) -> Self {
        // per molecule: the box of its centres and its largest radius
        let boxes: Vec<Option<CentreBox>> = molecules
            .iter()
            .map(|&(f, n)| {
                let own = &atoms[f as usize..(f + n) as usize];
                own.iter()
                    .fold(None, |b: Option<([f32; 3], [f32; 3], f32)>, a| {
                        let c = [a[0], a[1], a[2]];
                        Some(match b {
                            None => (c, c, a[3]),
                            Some((lo, hi, r)) => (
                                std::array::from_fn(|i| f32::min(lo[i], c[i])),
                                std::array::from_fn(|i| f32::max(hi[i], c[i])),
                                f32::max(r, a[3]),
                            ),
                        })
                    })
            })
            .collect();
        let finite: Vec<bool> = molecules
            .iter()
            .map(|&(f, n)| {
                atoms[f as usize..(f + n) as usize]
                    .iter()
                    .all(|a| a.iter().all(|v| v.is_finite()))
            })
            .collect();
        let hulls = instance_molecule
            .iter()
            .enumerate()
            .map(|(k, &m)| {
                let Some((lo, hi, r)) = boxes[m as usize] else {
                    return Hull {
                        corners: [DVec3::ZERO; 8],
                        radius: f64::NEG_INFINITY,
                        margin: 0.0,
                        finite: true,
                    };
                };
                let corners: [DVec3; 8] = std::array::from_fn(|c| {
                    let x = [
                        if c & 1 == 0 { lo[0] } else { hi[0] },
                        if c & 2 == 0 { lo[1] } else { hi[1] },
                        if c & 4 == 0 { lo[2] } else { hi[2] },
                    ];
                    Vec3::from(transforms.apply(k, x)).as_dvec3()
                });
                // (each placed coordinate is rounded to f32 a few times:
                // a generous relative bound on how far a computed atom
                // may lie outside the exact hull)
                let scale = corners
                    .iter()
                    .map(|p| p.abs().max_element())
                    .fold(0.0, f64::max)
                    + DVec3::from(hi.map(f64::from)).distance(DVec3::from(lo.map(f64::from)));
                Hull {
                    corners,
                    radius: r as f64,
                    margin: 1e-4 * (scale + 1.0),
                    finite: finite[m as usize],
                }
            })
            .collect();
        Extremes {
            transforms,
            instance_molecule,
            molecules,
            atoms,
            hulls,
        }
    }

    /// Instance `k`'s atoms as the full scan places them: centre, radius.
    pub fn atoms_of(&self, k: usize) -> impl Iterator<Item = ([f32; 3], f32)> + '_ {
        let (f, n) = self.molecules[self.instance_molecule[k] as usize];
        self.atoms[f as usize..(f + n) as usize]
            .iter()
            .map(move |a| (self.transforms.apply(k, [a[0], a[1], a[2]]), a[3]))
    }

    /// Whether every centre of instance `k` is finite and within `limit`
    /// of 0 in each coordinate, shown from its hull (false: it may not be;
    /// scan its atoms).
    pub fn inside(&self, k: usize, limit: f64) -> bool {
        let h = &self.hulls[k];
        h.finite
            && h.corners
                .iter()
                .all(|p| p.is_finite() && p.abs().max_element() + h.margin <= limit)
    }

    /// Atoms of instance `k`.
    pub fn atom_count(&self, k: usize) -> u32 {
        self.molecules[self.instance_molecule[k] as usize].1
    }

    /// The largest `f` over every atom (None: no atoms). `bound(corners,
    /// radius)` must be at least `f` of any centre in the corners' hull
    /// with any radius up to `radius`, and move by at most the distance a
    /// centre moves (1-Lipschitz in the centre).
    pub fn max_by(
        &self,
        bound: impl Fn(&[DVec3; 8], f64) -> f64,
        f: impl Fn([f32; 3], f32) -> f64,
    ) -> Option<f64> {
        let mut order: Vec<(f64, usize)> = self
            .hulls
            .iter()
            .enumerate()
            .filter(|(_, h)| h.radius >= 0.0)
            .map(|(k, h)| (bound(&h.corners, h.radius) + h.margin, k))
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0));
        let mut best: Option<f64> = None;
        // (copies placed by the same transform bits give the same values:
        // an assembly whose operators compose to equal sums put 10^6
        // instances of 5,000 atoms on ~50 places, and every bound tied)
        let mut seen = std::collections::HashSet::new();
        for (ub, k) in order {
            if best.is_some_and(|b| ub <= b) {
                break;
            }
            if !seen.insert((self.instance_molecule[k], self.transforms.key(k))) {
                continue;
            }
            for (c, r) in self.atoms_of(k) {
                let v = f(c, r);
                best = Some(best.map_or(v, |b| b.max(v)));
            }
        }
        best
    }

    /// The box of every centre (as a scan of `min`/`max` would find).
    pub fn center_bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = [0.0f32; 3];
        let mut hi = [0.0f32; 3];
        for i in 0..3 {
            let axis = DVec3::AXES[i];
            hi[i] = self.max_by(|h, _| corner_max(h, axis), |c, _| c[i] as f64)? as f32;
            lo[i] = -self.max_by(|h, _| corner_max(h, -axis), |c, _| -c[i] as f64)? as f32;
        }
        Some((Vec3::from(lo), Vec3::from(hi)))
    }

    /// The sphere centred on the box of the centres that reaches the
    /// farthest surface (as `Scene::bounding_sphere`; None without atoms).
    pub fn bounding_sphere(&self) -> Option<(Vec3, f32)> {
        let (lo, hi) = self.center_bounds()?;
        let c = (lo + hi) * 0.5;
        Some((c, self.reach_from(c)))
    }

    /// The farthest surface from `c`: the largest `|centre - c| + radius`
    /// in f32, at least 0.
    pub fn reach_from(&self, c: Vec3) -> f32 {
        let cd = c.as_dvec3();
        let far = |h: &[DVec3; 8], r: f64| h.iter().map(|p| p.distance(cd)).fold(0.0, f64::max) + r;
        self.max_by(far, |p, r| (Vec3::from(p).distance(c) + r) as f64)
            .map_or(0.0, |v| (v as f32).max(0.0))
    }

    /// Along each of `axes`, the least `centre . axis - radius` and the
    /// largest `centre . axis + radius` (centres in f64), as a light
    /// view's fit scans them; None without atoms.
    pub fn extent_along(&self, axes: [DVec3; 3]) -> Option<(DVec3, DVec3)> {
        let mut lo = [0.0; 3];
        let mut hi = [0.0; 3];
        for i in 0..3 {
            let a = axes[i];
            let c64 = |c: [f32; 3]| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
            hi[i] = self.max_by(|h, r| corner_max(h, a) + r, |c, r| c64(c).dot(a) + r as f64)?;
            lo[i] = -self.max_by(
                |h, r| corner_max(h, -a) + r,
                |c, r| -(c64(c).dot(a) - r as f64),
            )?;
        }
        Some((DVec3::from(lo), DVec3::from(hi)))
    }

    /// The least `(centre - eye) . dir - radius` (centres in f64): how
    /// near the nearest sphere comes along `dir`; None without atoms.
    pub fn nearest_along(&self, eye: DVec3, dir: DVec3) -> Option<f64> {
        let c64 = |c: [f32; 3]| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
        self.max_by(
            |h, r| corner_max(h, -dir) + eye.dot(dir) + r,
            |c, r| -((c64(c) - eye).dot(dir) - r as f64),
        )
        .map(|v| -v)
    }
}

/// The largest `p . axis` over the corners (a linear function's maximum
/// over their hull).
fn corner_max(corners: &[DVec3; 8], axis: DVec3) -> f64 {
    corners.iter().map(|p| p.dot(axis)).fold(f64::MIN, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::instanced::Rigid;

    /// Random molecules in random rigid placements: every extreme equals
    /// the full scan's bits, and most instances are skipped.
    #[test]
    fn extremes_equal_the_full_scan() {
        let mut rng = crate::scene::procedural::Rng::new(7);
        let mut atoms = Vec::new();
        let mut molecules = Vec::new();
        for m in 0..3 {
            let first = atoms.len() as u32;
            let n = 50 + 40 * m;
            for _ in 0..n {
                let p = [rng.f64(), rng.f64(), rng.f64()].map(|x| (x * 30.0 - 15.0) as f32);
                atoms.push([p[0], p[1], p[2], 1.0 + rng.f64() as f32]);
            }
            molecules.push((first, n));
        }
        let mut rigid = Vec::new();
        let mut inst = Vec::new();
        for k in 0..500 {
            let q = glam::DQuat::from_axis_angle(
                DVec3::new(rng.f64() - 0.5, rng.f64() - 0.5, rng.f64() - 0.5).normalize(),
                rng.f64() * 6.0,
            );
            let t = [rng.f64(), rng.f64(), rng.f64()].map(|x| (x * 2000.0 - 1000.0) as f32);
            rigid.push(Rigid {
                q: [q.x as f32, q.y as f32, q.z as f32, q.w as f32],
                t: [t[0], t[1], t[2], 0.0],
            });
            inst.push((k % 3) as u32);
        }
        let tr = Transforms::Rigid(rigid);
        let e = Extremes::new(&tr, &inst, molecules.clone(), Cow::Borrowed(&atoms));
        let all: Vec<([f32; 3], f32)> = (0..inst.len()).flat_map(|k| e.atoms_of(k)).collect();
        // the box
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        for (c, _) in &all {
            lo = lo.min(Vec3::from(*c));
            hi = hi.max(Vec3::from(*c));
        }
        assert_eq!(e.center_bounds(), Some((lo, hi)));
        let c = (lo + hi) * 0.5;
        let reach = all
            .iter()
            .map(|&(p, r)| Vec3::from(p).distance(c) + r)
            .fold(0.0f32, f32::max);
        assert_eq!(e.reach_from(c).to_bits(), reach.to_bits());
        // a light's axes
        let d = DVec3::new(-1.0, -0.7, -0.3).normalize();
        let right = d.cross(DVec3::Y).normalize();
        let axes = [right, right.cross(d), d];
        let (mut l, mut h) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
        for &(c, r) in &all {
            let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
            let p = DVec3::new(c.dot(axes[0]), c.dot(axes[1]), c.dot(axes[2]));
            l = l.min(p - r as f64);
            h = h.max(p + r as f64);
        }
        assert_eq!(e.extent_along(axes), Some((l, h)));
        // the nearest sphere from an eye inside the scene
        let eye = DVec3::new(100.0, -50.0, 20.0);
        let near = all
            .iter()
            .map(|&(c, r)| {
                (DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) - eye).dot(d) - r as f64
            })
            .fold(f64::MAX, f64::min);
        assert_eq!(e.nearest_along(eye, d), Some(near));
        // and the pruning works: the box needs few instances
        let visited = std::cell::Cell::new(0usize);
        e.max_by(
            |h, _| corner_max(h, DVec3::X),
            |c, _| {
                visited.set(visited.get() + 1);
                c[0] as f64
            },
        );
        assert!(
            visited.get() < all.len() / 10,
            "{} of {}",
            visited.get(),
            all.len()
        );
    }

    /// 10^5 copies of a 1,000-atom rod on 5 places (translations along x
    /// composed to equal sums): every bound ties, and each place's atoms
    /// are visited once, with the full scan's results.
    #[test]
    fn copies_on_one_place_are_visited_once() {
        let atoms: Vec<[f32; 4]> = (0..1000).map(|i| [i as f32 * 0.1, 0.0, 0.0, 1.5]).collect();
        let rigid: Vec<Rigid> = (0..100_000)
            .map(|k| Rigid {
                q: [0.0, 0.0, 0.0, 1.0],
                t: [(k % 5) as f32 * 300.0, 0.0, 0.0, 0.0],
            })
            .collect();
        let inst = vec![0u32; rigid.len()];
        let tr = Transforms::Rigid(rigid);
        let e = Extremes::new(&tr, &inst, vec![(0, 1000)], Cow::Borrowed(&atoms));
        let visited = std::cell::Cell::new(0usize);
        let count = |v: f64| {
            visited.set(visited.get() + 1);
            v
        };
        let hi = e.max_by(|h, _| corner_max(h, DVec3::Y), |c, _| count(c[1] as f64));
        assert_eq!(hi, Some(0.0));
        assert!(visited.get() <= 5 * 1000, "{} atoms visited", visited.get());
        assert_eq!(
            e.center_bounds(),
            Some((Vec3::ZERO, Vec3::new(1200.0 + 99.9, 0.0, 0.0)))
        );
    }
}
