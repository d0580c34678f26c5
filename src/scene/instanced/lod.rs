//! Levels of detail of a molecule type (Mol*'s scheme): its atoms put in
//! one order in which every coarser level is a prefix. The order is a
//! spatial (Morton) order started at the atom nearest the centroid, and
//! level L takes every k-th atom of it (k a product of steps of 4, then
//! of 2 from 1024 atoms down: [`strides`]); its spheres keep the molecule's
//! volume (radius grown by (n / n_L)^(1/3)), down to one sphere at the
//! centroid's atom. Level 0 is every atom in the molecule's own order (what
//! an instance draws with `--lod off`, byte for byte). A level is drawn
//! below a switch size under which, at every size checked, its silhouette
//! is as close to level 0's as level 0's is to itself moved half a pixel
//! (or IoU 0.95: [`needed_iou`]); its radius factor is the one that makes
//! that switch size largest.

use std::collections::HashMap;

/// Atoms of level L per atom of level L+1 at the coarse end (levels of at
/// most [`LOD_HALVING_BELOW`] atoms): 2, so that an instance small on
/// screen, where most of a large scene's instances are, draws at most
/// about twice the spheres its size needs (with 4 throughout, a 10^9-atom
/// overview drew 3P3W at 718 spheres where 359 passed its silhouette test:
/// 7.45 spheres a pixel; 3.17 with 2). Finer levels step by
/// [`LOD_MAX_STRIDE`]: they are drawn only large on screen, by few
/// instances, and each level costs every instance batch words (stride 2
/// throughout made the 10^8 scene's batch table 22 % larger).
pub const LOD_STRIDE: u32 = 2;
/// The largest step between two levels.
pub const LOD_MAX_STRIDE: u32 = 4;
/// Levels of more atoms than this step by LOD_MAX_STRIDE.
pub const LOD_HALVING_BELOW: usize = 1024;

/// The step from each level to the next for a molecule of `n` atoms:
/// LOD_MAX_STRIDE down to LOD_HALVING_BELOW atoms, then LOD_STRIDE to one
/// sphere; more steps of LOD_MAX_STRIDE where that would take more than
/// MAX_LOD_LEVELS levels (a molecule of more than 2^30 atoms stops there,
/// above one sphere).
pub fn strides(n: usize) -> Vec<usize> {
    let max_steps = crate::gpu::consts::MAX_LOD_LEVELS as usize - 1;
    // ceil(log2 n): the doublings from one atom to n
    let log2 = |n: usize| (usize::BITS - n.saturating_sub(1).leading_zeros()) as usize;
    let bits = log2(n);
    let to_halving = bits.saturating_sub(log2(LOD_HALVING_BELOW)).div_ceil(2);
    let big = to_halving
        .max(bits.saturating_sub(max_steps))
        .min(max_steps);
    let small = bits.saturating_sub(2 * big).min(max_steps - big);
    let mut s = vec![LOD_MAX_STRIDE as usize; big];
    s.extend(std::iter::repeat_n(LOD_STRIDE as usize, small));
    s
}

/// The Morton (Z-order) code of a point on a 1024^3 grid: its coordinates'
/// bits interleaved, x lowest (coordinates above 1023 are cut to 10 bits).
pub fn morton3(q: [u32; 3]) -> u32 {
    let mut code = 0u32;
    for (i, q) in q.iter().enumerate() {
        for b in 0..10 {
            code |= ((q >> b) & 1) << (3 * b + i);
        }
    }
    code
}

/// Each point's Morton code on a 1024^3 grid over the box of the finite
/// points (NaN and a flat axis: cell 0 along it): what orders instances for
/// the cull and a nested scene's proxies.
pub fn morton_cells(points: &[[f32; 3]]) -> Vec<u32> {
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for p in points.iter().filter(|p| p.iter().all(|c| c.is_finite())) {
        for i in 0..3 {
            lo[i] = lo[i].min(p[i]);
            hi[i] = hi[i].max(p[i]);
        }
    }
    points
        .iter()
        .map(|p| {
            morton3(std::array::from_fn(|i| {
                let e = hi[i] - lo[i];
                if e > 0.0 {
                    ((p[i] - lo[i]) / e * 1023.0).clamp(0.0, 1023.0) as u32
                } else {
                    0
                }
            }))
        })
        .collect()
}

/// A colour word (RGBA8) with its alpha `a` (below 1) raised to
/// `1 - (1 - a)^e` ([`MoleculeLod::alpha_exponent`]); opaque and fully
/// clear words unchanged.
pub fn level_alpha(word: u32, e: f32) -> u32 {
    let a = word >> 24;
    if a == 0 || a == 255 {
        return word;
    }
    let t = (1.0 - a as f32 / 255.0).powf(e);
    // (as paint's alpha_byte rounds a rule's alpha)
    let b = ((1.0 - t).clamp(0.0, 1.0) * 255.0).round() as u32;
    (word & 0x00FF_FFFF) | (b << 24)
}

/// The levels of one molecule type.
#[derive(Clone, Debug, PartialEq)]
pub struct MoleculeLod {
    /// Indices of the molecule's atoms in LOD order: level L is the first
    /// `counts[L]`.
    pub order: Vec<u32>,
    /// Atoms per level: `counts[0]` is every atom, decreasing to 1.
    pub counts: Vec<u32>,
    /// Radius factor per level (1 at level 0): the volume-keeping
    /// (n / n_L)^(1/3) until [`MoleculeLod::switch_ppu`] picks, of a few
    /// around it, the one drawn up to the largest size.
    pub radius: Vec<f32>,
    /// The atoms in their spatial order (Morton, cyclic from the atom
    /// nearest the centroid): a level takes every stride-th of it.
    pub spatial: Vec<u32>,
    /// Per entry of `order`: its position in `spatial`.
    pub position: Vec<u32>,
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
                spatial: Vec::new(),
                position: Vec::new(),
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
            morton3(std::array::from_fn(|i| {
                ((a[i] - lo[i]) * scale[i]).clamp(0.0, 1023.0) as u32
            }))
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
        // whose stride (the product of the steps to it) divides j: the
        // coarsest first
        let steps = strides(n);
        let rank = |j: usize| -> u32 {
            if j == 0 {
                return u32::MAX;
            }
            let mut r = 0;
            let mut j = j;
            for &s in &steps {
                if !j.is_multiple_of(s) {
                    break;
                }
                j /= s;
                r += 1;
            }
            r
        };
        let mut js: Vec<usize> = (0..n).collect();
        js.sort_by_key(|&j| (std::cmp::Reverse(rank(j)), j));
        let spatial: Vec<u32> = (0..n).map(|j| sorted[(start + j) % n]).collect();
        let order = js.iter().map(|&j| spatial[j]).collect();
        let position = js.iter().map(|&j| j as u32).collect();
        let mut counts = vec![n as u32];
        let mut stride = 1usize;
        for &s in &steps {
            stride *= s;
            counts.push(n.div_ceil(stride) as u32);
        }
        let radius = counts
            .iter()
            .map(|&c| (n as f32 / c as f32).cbrt())
            .collect();
        MoleculeLod {
            order,
            counts,
            radius,
            spatial,
            position,
        }
    }

    /// Per copy of level `l` (in `order`), the atoms it stands for: a
    /// run of positions in `spatial`, from its own atom to the level's
    /// next copy. The runs of a level partition the molecule.
    pub fn stands_for(&self, l: usize) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
        let n = self.spatial.len();
        let stride: usize = strides(n).iter().take(l).product();
        self.position[..self.counts[l] as usize]
            .iter()
            .map(move |&j| j as usize..(j as usize + stride).min(n))
    }

    /// Levels (1 for a single atom).
    pub fn levels(&self) -> usize {
        self.counts.len()
    }

    /// The radius factor of level `l`.
    pub fn radius_scale(&self, l: usize) -> f32 {
        self.radius[l]
    }

    /// The exponent that makes a see-through atom's level-`l` copy as
    /// opaque as the atoms it stands for: a ray through the molecule meets
    /// spheres in proportion to their number times their cross-section, so
    /// level `l` meets `n_l f_l^2 / n` times as many as level 0 (`f_l` its
    /// radius factor), and each copy's transmittance is the atoms' raised
    /// to the inverse (`1 - a_l = (1 - a)^e`). 1 at level 0.
    pub fn alpha_exponent(&self, l: usize) -> f32 {
        let f = self.radius[l];
        self.counts[0] as f32 / (self.counts[l].max(1) as f32 * f * f)
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

/// Points covered by `spheres` seen along `dir` at `ppu` pixels per unit,
/// on a grid of half pixels `w` x `h`: point (x, y) lies `x / 2 - margin`
/// and `y / 2 - margin` pixels from `anchor` (whole-pixel margins in
/// integers: the same point tests the same numbers whatever the margin).
/// Its four sub-grids of odd and even x and y are the pixel centres of the
/// grid placements [`PHASES`], drawn in one pass.
pub fn silhouette(
    spheres: &[[f32; 4]],
    dir: [f32; 3],
    ppu: f32,
    anchor: [f32; 2],
    margin: i64,
    (w, h): (usize, usize),
) -> Vec<bool> {
    let (u, v) = plane_axes(dir);
    let mut m = vec![false; w * h];
    let m2 = 2 * margin;
    for s in spheres {
        let (pu, pv) = (dot3(s, u), dot3(s, v));
        // (in half pixels)
        let (cx, cy, r) = (
            2.0 * (pu - anchor[0]) * ppu,
            2.0 * (pv - anchor[1]) * ppu,
            2.0 * s[3] * ppu,
        );
        let x0 = ((cx - r).floor() as i64 + m2).max(0) as usize;
        let y0 = ((cy - r).floor() as i64 + m2).max(0) as usize;
        let x1 = (((cx + r).ceil() as i64 + m2 + 1).max(0) as usize).min(w);
        let y1 = (((cy + r).ceil() as i64 + m2 + 1).max(0) as usize).min(h);
        for y in y0..y1 {
            let dy = (y as i64 - m2) as f32 - cy;
            let row = &mut m[y * w..(y + 1) * w];
            for (x, cell) in row.iter_mut().enumerate().take(x1).skip(x0) {
                let dx = (x as i64 - m2) as f32 - cx;
                if dx * dx + dy * dy <= r * r {
                    *cell = true;
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

/// Sub-pixel placements of the pixel grid a silhouette IoU is averaged
/// over: the four of half a pixel along x, y or both (at a few pixels
/// across, one placement's IoU jumps by ~0.05 from one size to the next).
/// [`silhouette`] draws them together on a grid of half pixels.
const PHASES: usize = 4;

/// The grid a silhouette against `fine` is drawn on, seen along `dir` at
/// `ppu`: anchored at `fine`'s lower corner (so its masks are the same
/// whatever else is drawn on it), `margin` units more on every side in
/// whole pixels.
struct Frame {
    dir: [f32; 3],
    ppu: f32,
    /// `fine`'s lower corner.
    anchor: [f32; 2],
    /// Whole pixels before it.
    margin: i64,
    /// In half pixels.
    size: (usize, usize),
}

/// The box (lower, upper corner) of `spheres` seen along `dir`.
fn projected_box(spheres: &[[f32; 4]], dir: [f32; 3]) -> ([f32; 2], [f32; 2]) {
    let (u, v) = plane_axes(dir);
    let mut lo = [f32::MAX; 2];
    let mut hi = [f32::MIN; 2];
    for s in spheres {
        let (pu, pv) = (dot3(s, u), dot3(s, v));
        lo = [lo[0].min(pu - s[3]), lo[1].min(pv - s[3])];
        hi = [hi[0].max(pu + s[3]), hi[1].max(pv + s[3])];
    }
    (lo, hi)
}

impl Frame {
    /// The frame of fine spheres whose [`projected_box`] along `dir` is
    /// `(lo, hi)`.
    fn new((lo, hi): ([f32; 2], [f32; 2]), dir: [f32; 3], ppu: f32, margin: f32) -> Frame {
        let m = (margin * ppu).max(0.0).ceil() as i64 + 1;
        let side = |k: usize| 2 * (((hi[k] - lo[k]) * ppu).ceil() as usize + 2 * m as usize + 2);
        Frame {
            dir,
            ppu,
            anchor: lo,
            margin: m,
            size: (side(0), side(1)),
        }
    }

    /// `spheres`' silhouette on the frame's half-pixel grid.
    fn mask(&self, spheres: &[[f32; 4]]) -> Vec<bool> {
        silhouette(
            spheres,
            self.dir,
            self.ppu,
            self.anchor,
            self.margin,
            self.size,
        )
    }

    /// The mean over the grid placements of two masks' IoU.
    fn mean_iou(&self, a: &[bool], b: &[bool]) -> f64 {
        let w = self.size.0;
        let (mut inter, mut union) = ([0u32; PHASES], [0u32; PHASES]);
        for (y, (ra, rb)) in a.chunks(w).zip(b.chunks(w)).enumerate() {
            for (x, (&p, &q)) in ra.iter().zip(rb).enumerate() {
                let c = (x & 1) | ((y & 1) << 1);
                inter[c] += (p && q) as u32;
                union[c] += (p || q) as u32;
            }
        }
        let sum: f64 = inter
            .iter()
            .zip(&union)
            .map(|(&i, &u)| if u == 0 { 1.0 } else { i as f64 / u as f64 })
            .sum();
        sum / PHASES as f64
    }
}

/// How far (units) `coarse` reaches past a fine box `(lo, hi)` seen along
/// `dir`.
fn reach_past((lo, hi): ([f32; 2], [f32; 2]), coarse: &[[f32; 4]], dir: [f32; 3]) -> f32 {
    let (u, v) = plane_axes(dir);
    coarse.iter().fold(0.0f32, |m, s| {
        let (pu, pv) = (dot3(s, u), dot3(s, v));
        m.max(lo[0] - (pu - s[3]))
            .max(lo[1] - (pv - s[3]))
            .max(pu + s[3] - hi[0])
            .max(pv + s[3] - hi[1])
    })
}

/// Silhouette IoU of `coarse` against `fine` seen along `dir` at `ppu`:
/// the mean over the grid placements [`PHASES`] of a grid anchored at
/// `fine`'s lower corner.
pub fn silhouette_iou(fine: &[[f32; 4]], coarse: &[[f32; 4]], dir: [f32; 3], ppu: f32) -> f64 {
    let fine_box = projected_box(fine, dir);
    let f = Frame::new(fine_box, dir, ppu, reach_past(fine_box, coarse, dir));
    f.mean_iou(&f.mask(fine), &f.mask(coarse))
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

/// The radius factors a level's switch size is searched over, in eighths
/// of the volume-keeping one, in the order tried (the first wins a tie).
/// 0.5..1.25 fit a protein, whose silhouette is a solid blob. 1.5 and 2
/// fit a sparse cloud, where the projected area is kept, not the volume
/// ((n / n_L)^(1/2) = the volume's factor x (n / n_L)^(1/6): 2x at 64
/// atoms a sphere): a nested scene's proxy of one sphere per protein over
/// a ball of plasma. With 1.25 at most, the 10^12 overview's proxies
/// switched to every 4th sphere only (their coarse spheres left holes that
/// full detail covers) and drew 25.3 M spheres (12.2 a pixel, the back
/// layers of the lattice seen through the front's holes), 666 ms; with 1.5
/// and 2 tried, 7.8 M (3.8 a pixel), 285 ms. No molecule of the meso 10^9
/// scene or SARS-CoV-2 changed (the same images).
pub const RADIUS_EIGHTHS: [u32; 9] = [8, 7, 9, 6, 10, 12, 5, 16, 4];

/// Steps per doubling of the sizes a level's silhouette is checked at.
pub const SWITCH_STEPS: i32 = 4;

/// The checked size of step `j`: 2^(j / SWITCH_STEPS) pixels per unit.
pub fn switch_grid(j: i32) -> f32 {
    (j as f32 / SWITCH_STEPS as f32).exp2()
}

impl MoleculeLod {
    /// Per level, the most pixels per unit (world length) at which an
    /// instance may draw it, and its radius factor: sizes are checked on
    /// [`switch_grid`] from a molecule 2 pixels across (below, any level
    /// will do) upward, and a level's switch size is the last one before
    /// its silhouette first misses [`needed_iou`] of level 0's along
    /// [`CHECK_DIRS`] (so it keeps it at every checked size below), at
    /// most where its spheres project `pixels` in radius and at most the
    /// finer level's. Of the radius factors [`RADIUS_EIGHTHS`] x the
    /// volume-keeping one, the level takes the one with the largest switch
    /// size (the first of that list where several tie). Level 0: infinity.
    /// Non-increasing with the level.
    pub fn switch_ppu(&mut self, atoms: &[[f32; 4]], pixels: f32) -> Vec<f32> {
        let mut out = vec![f32::INFINITY];
        if atoms.is_empty() {
            return out;
        }
        let mean_r = atoms.iter().map(|a| a[3]).sum::<f32>() / atoms.len() as f32;
        let ext = extent(atoms).max(1e-6);
        let bottom = ((2.0 / ext).log2() * SWITCH_STEPS as f32).floor() as i32;
        // Per (direction, step): level 0's masks on a grid wide enough for
        // every coarse sphere tried (their centres are atoms'), and its
        // IoU moved half a pixel; shared by every level and radius.
        let grow =
            1.25 * (self.counts[0] as f32).cbrt() * atoms.iter().fold(0.0f32, |m, a| m.max(a[3]));
        let mut fine = HashMap::new();
        for l in 1..self.levels() {
            let vol = (self.counts[0] as f32 / self.counts[l].max(1) as f32).cbrt();
            let mut best = (i32::MIN, vol);
            for k in RADIUS_EIGHTHS {
                let f = vol * k as f32 / 8.0;
                self.radius[l] = f;
                let coarse = self.level_spheres(atoms, l);
                let top = (pixels / (mean_r * f)).min(out[l - 1]);
                let top = (top.log2() * SWITCH_STEPS as f32).floor() as i32;
                let mut j = bottom.min(top);
                // (a radius that misses where the best so far passes cannot
                // beat it: checked first)
                if best.0 != i32::MIN
                    && (best.0 >= top || !keeps(&mut fine, atoms, &coarse, best.0 + 1, grow))
                {
                    continue;
                }
                while j < top && keeps(&mut fine, atoms, &coarse, j + 1, grow) {
                    j += 1;
                }
                if j > best.0 {
                    best = (j, f);
                }
            }
            self.radius[l] = best.1;
            out.push(switch_grid(best.0).min(out[l - 1]));
        }
        out
    }
}

/// Level 0's masks and its IoU moved half a pixel per (direction,
/// [`switch_grid`] step).
type FineMasks = HashMap<(usize, i32), (Frame, Vec<bool>, Option<f64>)>;

/// Whether `coarse` keeps [`needed_iou`] of `atoms`' silhouette along every
/// one of [`CHECK_DIRS`] at grid step `j` (level 0's masks from `fine`,
/// made on a grid `grow` units wider on every side where missing).
fn keeps(fine: &mut FineMasks, atoms: &[[f32; 4]], coarse: &[[f32; 4]], j: i32, grow: f32) -> bool {
    CHECK_DIRS.iter().enumerate().all(|(di, &d)| {
        let ppu = switch_grid(j);
        let (frame, masks, moved) = fine.entry((di, j)).or_insert_with(|| {
            let frame = Frame::new(projected_box(atoms, d), d, ppu, grow);
            let mask = frame.mask(atoms);
            (frame, mask, None)
        });
        let iou = frame.mean_iou(masks, &frame.mask(coarse));
        // (level 0 moved only where 0.95 is missed)
        iou >= MIN_IOU || iou >= *moved.get_or_insert_with(|| shift_iou(atoms, d, ppu))
    })
}

/// A molecule type's levels of detail with their switch sizes, fitted at
/// `pixels` (`--lod-pixels`): the silhouette fits are a renderer's
/// start-up (SARS-CoV-2 1.3 s, the 10^12 scene's proxies 0.9 s), so a
/// nested scene's proxies keep theirs for every renderer of their scene.
#[derive(Clone, Debug, PartialEq)]
pub struct LodFit {
    pub levels: MoleculeLod,
    /// [`MoleculeLod::switch_ppu`].
    pub switch: Vec<f32>,
    /// The `pixels` they were fitted at.
    pub pixels: f32,
}

impl LodFit {
    /// The levels of `atoms` (centre, radius) and their switch sizes.
    pub fn new(atoms: &[[f32; 4]], pixels: f32) -> LodFit {
        let mut levels = MoleculeLod::new(atoms);
        let switch = levels.switch_ppu(atoms, pixels);
        LodFit {
            levels,
            switch,
            pixels,
        }
    }

    /// Whether this is the fit of a molecule of `atoms` atoms at `pixels`.
    pub fn fits(&self, atoms: u32, pixels: f32) -> bool {
        self.pixels == pixels && self.levels.counts.first() == Some(&atoms)
    }
}

/// `f(0..n)` on every core (each thread takes the next index), in index
/// order; None if a worker panicked.
pub fn on_every_core<T: Send>(n: usize, f: impl Fn(usize) -> T + Sync) -> Option<Vec<T>> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut done: Vec<(usize, T)> = std::thread::scope(|sc| {
        let workers: Vec<_> = (0..threads.min(n))
            .map(|_| {
                sc.spawn(|| {
                    let mut got = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if i >= n {
                            return got;
                        }
                        got.push((i, f(i)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_default())
            .collect()
    });
    if done.len() != n {
        return None;
    }
    done.sort_by_key(|d| d.0);
    Some(done.into_iter().map(|d| d.1).collect())
}

/// The level an instance draws at `ppu` pixels per unit: the coarsest
/// whose switch size (`MoleculeLod::switch_ppu`) it is within.
pub fn level_for(switch: &[f32], ppu: f32) -> usize {
    switch.iter().rposition(|&s| ppu <= s).unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::consts::MAX_LOD_LEVELS;

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
        for n in [1usize, 2, 5, 64, 1000, 4097, 40_000] {
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
            assert!(
                lod.levels() <= MAX_LOD_LEVELS as usize,
                "{n}: {:?}",
                lod.counts
            );
            let mut stride = 1;
            for l in 1..lod.levels() {
                stride *= strides(n)[l - 1];
                assert_eq!(lod.counts[l] as usize, n.div_ceil(stride));
            }
            // one sphere: the atom nearest the centroid
            let c: [f32; 3] = std::array::from_fn(|k| {
                atoms.iter().map(|a| a[k] as f64).sum::<f64>() as f32 / n as f32
            });
            let d = |a: &[f32; 4]| (0..3).map(|k| (a[k] - c[k]).powi(2)).sum::<f32>();
            let best = atoms.iter().map(d).fold(f32::MAX, f32::min);
            assert_eq!(d(&atoms[lod.order[0] as usize]), best);
            // each copy stands for a run that starts at its own atom; a
            // level's runs hold every atom once, in spatial neighbourhoods
            for l in 0..lod.levels() {
                let mut all: Vec<u32> = Vec::new();
                for (k, run) in lod.stands_for(l).enumerate() {
                    let run = &lod.spatial[run];
                    assert_eq!(run[0], lod.order[k], "level {l} copy {k}");
                    all.extend_from_slice(run);
                }
                assert_eq!(all.len(), n, "level {l}");
                all.sort_unstable();
                assert_eq!(all, (0..n as u32).collect::<Vec<_>>(), "level {l}");
            }
            assert!(lod.stands_for(0).all(|r| r.len() == 1));
            if let Some(last) = lod.stands_for(lod.levels() - 1).next() {
                assert_eq!(last.len(), n, "the one sphere stands for them all");
            }
        }
    }

    #[test]
    fn coarse_levels_halve() {
        let max = MAX_LOD_LEVELS as usize - 1;
        assert_eq!(strides(1), Vec::<usize>::new());
        assert_eq!(strides(2), vec![2]);
        assert_eq!(strides(1024), vec![2; 10]);
        // 3P3W: 11,484 -> 2,871 -> 718, then halving to one sphere
        assert_eq!(strides(11_484), [&[4, 4][..], &[2; 10][..]].concat());
        for n in [3usize, 1000, 1025, 1 << 15, 100_000, 5_000_000, 1 << 30] {
            let s = strides(n);
            assert!(s.len() <= max, "{n}: {s:?}");
            assert!(s.iter().product::<usize>() >= n, "{n}: {s:?}");
            // 4s first, 2s from LOD_HALVING_BELOW atoms down (or where
            // 2s would take too many levels)
            assert!(s.windows(2).all(|w| w[0] >= w[1]), "{n}: {s:?}");
            let fours = s.iter().filter(|&&x| x == 4).count();
            let left = n.div_ceil(4usize.pow(fours as u32));
            assert!(left <= LOD_HALVING_BELOW || s.len() == max, "{n}: {s:?}");
            // (more 4s only where the levels would not fit)
            let before = n.div_ceil(4usize.pow(fours.saturating_sub(1) as u32));
            assert!(
                fours == 0 || before > LOD_HALVING_BELOW || s.len() == max,
                "{n}: {s:?}"
            );
        }
        // past 2^30 atoms the levels stop above one sphere
        let s = strides((1 << 30) + 1);
        assert_eq!(s, vec![4; max]);
    }

    #[test]
    fn the_level_follows_the_projected_size() {
        let atoms = blob(1000, 3);
        let mut lod = MoleculeLod::new(&atoms);
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

    /// 1TII's atoms (centre, radius).
    fn tii_atoms() -> Vec<[f32; 4]> {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb");
        let scene = load(
            std::path::Path::new(path),
            &LoadOptions::default(),
            &mut |_, _| {},
        )
        .expect("load");
        scene
            .spheres
            .iter()
            .map(|s| [s.center[0], s.center[1], s.center[2], s.radius])
            .collect()
    }

    /// Mean transmittance of rays along each axis through the middle of
    /// `spheres` (a grid of `n` x `n` per axis over the central half of
    /// their box), each sphere passing 1 - `alpha` of the light.
    fn mean_transmittance(spheres: &[[f32; 4]], alpha: f32, n: usize) -> f64 {
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for a in spheres {
            for k in 0..3 {
                lo[k] = lo[k].min(a[k]);
                hi[k] = hi[k].max(a[k]);
            }
        }
        let (mut sum, mut rays) = (0.0f64, 0usize);
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for i in 0..n {
                for j in 0..n {
                    let at = |k: usize, t: usize| {
                        let c = 0.5 * (lo[k] + hi[k]);
                        c + 0.5 * (hi[k] - lo[k]) * ((t as f32 + 0.5) / n as f32 - 0.5)
                    };
                    let (pu, pv) = (at(u, i), at(v, j));
                    let hits = spheres
                        .iter()
                        .filter(|a| (a[u] - pu).powi(2) + (a[v] - pv).powi(2) < a[3] * a[3])
                        .count();
                    sum += (1.0 - alpha as f64).powi(hits as i32);
                    rays += 1;
                }
            }
        }
        sum / rays as f64
    }

    /// A see-through molecule's coarse levels pass about the light its
    /// atoms pass (1TII, alpha 0.15): each coarse copy's alpha raised by
    /// its level's exponent keeps the mean transmittance of rays through
    /// the molecule within 0.03 of full detail's (0.135) at every level
    /// down to 64 spheres (1,421 to 89: 0.121-0.129), where the atoms' own
    /// alpha would let far more through (0.23-0.50). (At 45 spheres, a
    /// few large overlapping ones, it passes 0.07.)
    #[test]
    fn coarse_copies_pass_the_light_their_atoms_pass() {
        let atoms = tii_atoms();
        let lod = MoleculeLod::new(&atoms);
        assert_eq!(lod.alpha_exponent(0), 1.0);
        let a = 0.15f32;
        let full = mean_transmittance(&atoms, a, 24);
        assert!(full > 0.05 && full < 0.9, "full detail passes {full}");
        for l in 1..lod.levels() {
            if lod.counts[l] < 64 {
                break;
            }
            let e = lod.alpha_exponent(l);
            let word = level_alpha(0x2680_4020 | ((a * 255.0).round() as u32) << 24, e);
            assert_eq!(word & 0x00FF_FFFF, 0x0080_4020, "colour kept");
            let al = (word >> 24) as f32 / 255.0;
            let spheres = lod.level_spheres(&atoms, l);
            let coarse = mean_transmittance(&spheres, al, 24);
            let plain = mean_transmittance(&spheres, a, 24);
            eprintln!(
                "level {l}: {} spheres, exponent {e:.3}, alpha {al:.3}: passes {coarse:.3} \
                 (full detail {full:.3}; with the atoms' alpha {plain:.3})",
                lod.counts[l]
            );
            assert!(
                (coarse - full).abs() < 0.03,
                "level {l}: {coarse} vs {full}"
            );
            if lod.counts[l] * 8 <= lod.counts[0] {
                assert!(plain - full > 0.1, "level {l}: {plain} vs {full}");
            }
        }
        // opaque and fully clear words stay as they are
        assert_eq!(level_alpha(0xFF12_3456, 3.0), 0xFF12_3456);
        assert_eq!(level_alpha(0x0012_3456, 3.0), 0x0012_3456);
        assert_eq!(level_alpha(0x8012_3456, 1.0), 0x8012_3456);
    }

    /// Full detail's own silhouette under half a pixel of motion: far
    /// below 0.95 at the sizes a mesoscale overview shows a protein (so
    /// 0.95 alone would keep every atom there), 0.95 or more only when the
    /// molecule is hundreds of pixels across; and with the rule, 1TII at
    /// 8 px across (a 10^9-atom overview) draws a level of 1/64 of its
    /// atoms or coarser.
    #[test]
    fn half_a_pixel_of_motion_sets_the_floor() {
        let atoms = tii_atoms();
        let ext = super::extent(&atoms);
        for d in CHECK_DIRS {
            let small = shift_iou(&atoms, d, 8.0 / ext);
            let large = shift_iou(&atoms, d, 256.0 / ext);
            assert!(small < 0.8, "{d:?}: {small:.3} at 8 px");
            assert!(large >= MIN_IOU, "{d:?}: {large:.3} at 256 px");
            assert_eq!(needed_iou(&atoms, d, 256.0 / ext), MIN_IOU);
            assert!((needed_iou(&atoms, d, 8.0 / ext) - small).abs() < 1e-12);
        }
        let mut lod = MoleculeLod::new(&atoms);
        let level = level_for(&lod.switch_ppu(&atoms, 2.0), 8.0 / ext);
        assert!(level >= 3, "level {level} at 8 px across");
    }

    /// 1TII: every coarse level keeps [`needed_iou`] along the checked
    /// axes at every checked size from 2 px across up to its switch size
    /// (not only at the switch: a single grid placement's IoU is noisy in
    /// the size, and a level that matched at one size could miss below
    /// it); its radius factor is one of those tried, and no other of them
    /// reaches one step further.
    #[test]
    fn a_level_keeps_its_outline_at_every_size_below_its_switch() {
        let atoms = tii_atoms();
        let ext = super::extent(&atoms);
        let mean_r = atoms.iter().map(|a| a[3]).sum::<f32>() / atoms.len() as f32;
        let mut lod = MoleculeLod::new(&atoms);
        let sw = lod.switch_ppu(&atoms, 2.0);
        let step = |ppu: f32| (ppu.log2() * SWITCH_STEPS as f32).round() as i32;
        let bottom = ((2.0 / ext).log2() * SWITCH_STEPS as f32).floor() as i32;
        let keeps = |coarse: &[[f32; 4]], j: i32| {
            CHECK_DIRS.iter().all(|&d| {
                silhouette_iou(&atoms, coarse, d, switch_grid(j))
                    >= needed_iou(&atoms, d, switch_grid(j))
            })
        };
        for l in 1..lod.levels() {
            let coarse = lod.level_spheres(&atoms, l);
            let top = step(sw[l]);
            assert!(
                (switch_grid(top) - sw[l]).abs() <= 1e-6 * sw[l],
                "on the grid"
            );
            for j in bottom + 1..=top {
                assert!(
                    keeps(&coarse, j),
                    "level {l} misses at {:.1} px",
                    switch_grid(j) * ext
                );
            }
            let vol = (lod.counts[0] as f32 / lod.counts[l] as f32).cbrt();
            let chosen = lod.radius_scale(l);
            assert!(
                RADIUS_EIGHTHS
                    .iter()
                    .any(|&k| (vol * k as f32 / 8.0 - chosen).abs() < 1e-6)
            );
            // (no radius reaches past the finer level's switch)
            if switch_grid(top + 1) <= sw[l - 1] {
                let mut other = lod.clone();
                for k in RADIUS_EIGHTHS {
                    other.radius[l] = vol * k as f32 / 8.0;
                    let c = other.level_spheres(&atoms, l);
                    // (its spheres no larger than 2 px in radius there)
                    let bound = (2.0 / (mean_r * other.radius[l])).min(sw[l - 1]);
                    let fits = (bound.log2() * SWITCH_STEPS as f32).floor() as i32 > top;
                    assert!(
                        !(fits && (bottom + 1..=top + 1).all(|j| keeps(&c, j))),
                        "level {l}: radius x{} reaches further",
                        other.radius[l]
                    );
                }
            }
        }
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
                let mut lod = MoleculeLod::new(&atoms);
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
