//! Independent CPU references in f64: exact primary-ray casting on the
//! DESIGN.md camera and exact shadow rays toward the key light. Spheres are
//! binned into screen tiles only to skip impossible pairs; every candidate is
//! tested with the full 3D ray-sphere intersection.

use crate::camera::Camera;
use crate::scene::Sphere;
use glam::DVec3;

const TILE: u32 = 16;

/// Screen-tile bins of sphere indices for one view.
pub struct Bins {
    cam: Camera,
    tiles_x: u32,
    tiles_y: u32,
    bins: Vec<Vec<u32>>,
}

fn c64(s: &Sphere) -> DVec3 {
    DVec3::new(s.center[0] as f64, s.center[1] as f64, s.center[2] as f64)
}

/// The point pixel (x, y) of `cam` sees on the sphere (c, r) it shows (the
/// visibility buffer's id): the near hit of its ray in f64 (the ray's
/// origin for a miss, which f32 rounding can give at a silhouette).
pub fn visible_point(cam: &crate::camera::Camera, x: u32, y: u32, c: DVec3, r: f64) -> DVec3 {
    let (o, d) = cam.ray(x, y);
    let (t, _) = ray_sphere(o, d, c, r).unwrap_or((0.0, 0.0));
    o + t * d
}

/// Ray-sphere intersection in a cancellation-free form. Returns the near hit
/// distance and the squared gap to the silhouette (r^2 - miss distance^2).
pub fn ray_sphere(o: DVec3, d: DVec3, c: DVec3, r: f64) -> Option<(f64, f64)> {
    let oc = o - c;
    let b = oc.dot(d);
    let q = oc - b * d; // closest approach, relative to the centre
    let disc = r * r - q.length_squared();
    if disc < 0.0 {
        return None;
    }
    Some((-b - disc.sqrt(), disc))
}

/// Angular extent along one plane axis for a perspective view (tangents).
fn persp_extent(a: f64, z: f64, r: f64, dist: f64) -> (f64, f64) {
    let l = (a * a + z * z).sqrt();
    if l <= r {
        return (f64::NEG_INFINITY, f64::INFINITY);
    }
    let ang = a.atan2(z);
    let del = (r / l).asin();
    let hp = std::f64::consts::FRAC_PI_2;
    let lo = if ang - del <= -hp {
        f64::NEG_INFINITY
    } else {
        dist * (ang - del).tan()
    };
    let hi = if ang + del >= hp {
        f64::INFINITY
    } else {
        dist * (ang + del).tan()
    };
    (lo, hi)
}

impl Bins {
    pub fn new(spheres: &[Sphere], cam: &Camera) -> Self {
        let tiles_x = cam.width.div_ceil(TILE);
        let tiles_y = cam.height.div_ceil(TILE);
        let mut bins = vec![Vec::new(); (tiles_x * tiles_y) as usize];
        let ppu = cam.pixels_per_unit();
        let (w, h) = (cam.width as f64, cam.height as f64);
        let dist = cam.eye_distance();
        for (i, s) in spheres.iter().enumerate() {
            let r = s.radius as f64;
            let q = c64(s)
                - if cam.fov_deg.is_some() {
                    cam.eye()
                } else {
                    cam.center
                };
            let (cx, cy, cz) = (q.dot(cam.right), q.dot(cam.up), q.dot(cam.dir));
            let (xr, yr) = if cam.fov_deg.is_none() {
                ((cx - r, cx + r), (cy - r, cy + r))
            } else {
                if cz + r <= 0.0 {
                    continue;
                }
                (persp_extent(cx, cz, r, dist), persp_extent(cy, cz, r, dist))
            };
            // One pixel of margin: culling must never lose a candidate.
            let px0 = (xr.0 * ppu + 0.5 * w - 1.5).max(0.0);
            let px1 = (xr.1 * ppu + 0.5 * w + 0.5).min(w - 1.0);
            let py0 = (0.5 * h - yr.1 * ppu - 1.5).max(0.0);
            let py1 = (0.5 * h - yr.0 * ppu + 0.5).min(h - 1.0);
            if !(px0 <= px1 && py0 <= py1) {
                continue;
            }
            let (tx0, tx1) = (px0 as u32 / TILE, px1 as u32 / TILE);
            let (ty0, ty1) = (py0 as u32 / TILE, py1 as u32 / TILE);
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    bins[(ty * tiles_x + tx) as usize].push(i as u32);
                }
            }
        }
        Bins {
            cam: *cam,
            tiles_x,
            tiles_y,
            bins,
        }
    }

    /// Candidates for the ray through pixel (px, py).
    pub fn at_pixel(&self, px: u32, py: u32) -> &[u32] {
        let (tx, ty) = (px / TILE, py / TILE);
        if tx >= self.tiles_x || ty >= self.tiles_y {
            return &[];
        }
        &self.bins[(ty * self.tiles_x + tx) as usize]
    }

    /// Candidates for a ray parallel to an orthographic view's direction
    /// through world point `p` (used for shadow rays along the light).
    pub fn along_dir(&self, p: DVec3) -> &[u32] {
        let q = p - self.cam.center;
        let ppu = self.cam.pixels_per_unit();
        let px = q.dot(self.cam.right) * ppu + 0.5 * self.cam.width as f64 - 0.5;
        let py = 0.5 * self.cam.height as f64 - q.dot(self.cam.up) * ppu - 0.5;
        let (px, py) = (px.round(), py.round());
        if px < 0.0 || py < 0.0 || px >= self.cam.width as f64 || py >= self.cam.height as f64 {
            return &[];
        }
        self.at_pixel(px as u32, py as u32)
    }
}

/// Result of the reference primary-ray cast.
pub struct RefImage {
    pub width: u32,
    pub height: u32,
    /// Sphere index per pixel, u32::MAX for background.
    pub ids: Vec<u32>,
    /// Hit distance along the ray per pixel (NaN for background).
    pub t: Vec<f64>,
    /// Pixels where f32 rounding may legitimately pick another answer: two
    /// surfaces within `tolerance` in depth, or the ray grazing a silhouette.
    pub ambiguous: Vec<bool>,
}

pub fn cast(spheres: &[Sphere], cam: &Camera, tolerance: f64) -> RefImage {
    let bins = Bins::new(spheres, cam);
    let n = (cam.width * cam.height) as usize;
    let mut img = RefImage {
        width: cam.width,
        height: cam.height,
        ids: vec![u32::MAX; n],
        t: vec![f64::NAN; n],
        ambiguous: vec![false; n],
    };
    for py in 0..cam.height {
        for px in 0..cam.width {
            let (o, d) = cam.ray(px, py);
            let (mut best, mut second, mut id, mut graze) =
                (f64::INFINITY, f64::INFINITY, u32::MAX, false);
            for &i in bins.at_pixel(px, py) {
                let s = &spheres[i as usize];
                let r = s.radius as f64;
                // Near-silhouette misses are ambiguous too.
                let oc = o - c64(s);
                let q = oc - oc.dot(d) * d;
                let gap = r * r - q.length_squared();
                if gap.abs() <= tolerance * r.max(1.0) * 2.0 {
                    graze = true;
                }
                // Hits behind the eye (perspective, eye inside a sphere) do not count.
                if let Some((t, _)) = ray_sphere(o, d, c64(s), r).filter(|(t, _)| *t > 0.0) {
                    if t < best {
                        second = best;
                        best = t;
                        id = i;
                    } else if t < second {
                        second = t;
                    }
                }
            }
            let k = (py * cam.width + px) as usize;
            img.ids[k] = id;
            img.t[k] = if id == u32::MAX { f64::NAN } else { best };
            img.ambiguous[k] = graze || (second - best) <= tolerance;
        }
    }
    img
}

/// Exact key-light visibility of point `p` on sphere `self_id`: the product
/// of (1 - opacity) over every other sphere the ray toward the light crosses
/// (opacity 1 = hard shadow). `light_bins` must come from `light_view`.
pub fn shadow_ray(
    spheres: &[Sphere],
    light_bins: &Bins,
    light_dir: DVec3,
    p: DVec3,
    self_id: u32,
    opacity: f64,
) -> f64 {
    let d = -light_dir.normalize();
    let mut vis = 1.0;
    for &i in light_bins.along_dir(p) {
        if i == self_id {
            continue;
        }
        let s = &spheres[i as usize];
        if let Some((_, disc)) = ray_sphere(p, d, c64(s), s.radius as f64) {
            // Only occluders toward the light (far intersection ahead of p).
            let far = (c64(s) - p).dot(d) + disc.sqrt();
            if far > 0.0 {
                vis *= 1.0 - opacity;
                if vis == 0.0 {
                    break;
                }
            }
        }
    }
    vis
}

/// The seed's soft key-light visibility of point `p` on sphere `self_id`
/// (glsl/lookup_issm.glsl, parameters s, x, b), evaluated in f64 against
/// every other sphere, one occluder at a time: 0 where the ray toward the
/// light crosses a sphere, else the minimum over occluders ahead of p of
/// 1 - (1 - gap / s_eff)^x with s_eff = s (1 - exp(-k^2 / 2b^2)).
pub fn soft_shadow_ray(
    spheres: &[Sphere],
    light_dir: DVec3,
    p: DVec3,
    self_id: u32,
    (s, x, b): (f64, f64, f64),
) -> f64 {
    let d = -light_dir.normalize();
    let mut vis = 1.0f64;
    for (i, sp) in spheres.iter().enumerate() {
        if i as u32 == self_id {
            continue;
        }
        let r = sp.radius as f64;
        let oc = c64(sp) - p;
        let k = oc.dot(d);
        let d2 = (oc.length_squared() - k * k).max(0.0);
        if d2 < r * r {
            if k + (r * r - d2).sqrt() > 0.0 {
                return 0.0;
            }
            continue;
        }
        if s <= 0.0 || k <= 0.0 {
            continue;
        }
        let se = s * (1.0 - (-k * k / (2.0 * b * b)).exp());
        let gap = d2.sqrt() - r;
        if gap < se {
            vis = vis.min(1.0 - (1.0 - gap / se).powf(x));
        }
    }
    vis
}

/// Exact key-light visibility per pixel of `cam` at the reference's visible
/// points (None for background and ambiguous pixels), with the reference
/// cast itself (ids). `opacity` 1 gives hard shadows.
pub fn shadow_image(
    spheres: &[Sphere],
    cam: &Camera,
    light: DVec3,
    opacity: f64,
) -> (Vec<Option<f64>>, RefImage) {
    // Tolerance relative to the scene size, as the id comparisons use.
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for s in spheres {
        lo = lo.min(c64(s) - s.radius as f64);
        hi = hi.max(c64(s) + s.radius as f64);
    }
    let radius = (0.5 * (hi - lo).length()).max(1.0);
    let img = cast(spheres, cam, 2e-5 * radius);
    let bins = match crate::camera::light_view(
        spheres.iter().map(|s| (s.center, s.radius)),
        light,
        1024,
    ) {
        Ok(lv) => Bins::new(spheres, &lv),
        Err(_) => return (vec![None; img.ids.len()], img),
    };
    let out = (0..img.ids.len())
        .map(|i| {
            if img.ids[i] == u32::MAX || img.ambiguous[i] {
                return None;
            }
            let (orig, dir) = cam.ray(i as u32 % cam.width, i as u32 / cam.width);
            let p = orig + img.t[i] * dir;
            Some(shadow_ray(spheres, &bins, light, p, img.ids[i], opacity))
        })
        .collect();
    (out, img)
}

/// A uniform grid of sphere indices (cells of `cell` world units), for
/// "which spheres can a short ray from here hit".
struct Grid3 {
    lo: DVec3,
    cell: f64,
    dims: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl Grid3 {
    fn new(spheres: &[Sphere], cell: f64) -> Self {
        let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
        for s in spheres {
            lo = lo.min(c64(s) - s.radius as f64);
            hi = hi.max(c64(s) + s.radius as f64);
        }
        let dims = {
            let d = ((hi - lo) / cell).ceil().max(DVec3::ONE);
            [d.x as usize, d.y as usize, d.z as usize]
        };
        let mut cells = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
        let g = Grid3 {
            lo,
            cell,
            dims,
            cells: Vec::new(),
        };
        for (i, s) in spheres.iter().enumerate() {
            let r = s.radius as f64;
            let (a, b) = (g.index(c64(s) - r), g.index(c64(s) + r));
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        cells[(z * dims[1] + y) * dims[0] + x].push(i as u32);
                    }
                }
            }
        }
        Grid3 { cells, ..g }
    }

    fn index(&self, p: DVec3) -> [usize; 3] {
        let q = ((p - self.lo) / self.cell).floor();
        let c = |v: f64, n: usize| (v.max(0.0) as usize).min(n - 1);
        [
            c(q.x, self.dims[0]),
            c(q.y, self.dims[1]),
            c(q.z, self.dims[2]),
        ]
    }

    /// Every sphere with a cell within `reach` of `p` (may repeat ids).
    fn near(&self, p: DVec3, reach: f64, out: &mut Vec<u32>) {
        out.clear();
        let (a, b) = (self.index(p - reach), self.index(p + reach));
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    out.extend_from_slice(&self.cells[(z * self.dims[1] + y) * self.dims[0] + x]);
                }
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// Ray-traced ambient occlusion, the reference for SSDO: at the visible
/// point of every `stride`-th pixel (both axes), the fraction of `rays`
/// cosine-weighted directions (a stratified grid over Malley's mapping,
/// rotated per pixel) that leave a `radius` ball around the point without
/// hitting another sphere. None for background, ambiguous and skipped pixels.
pub fn ambient_occlusion(
    spheres: &[Sphere],
    cam: &Camera,
    radius: f64,
    rays: u32,
    stride: u32,
) -> Vec<Option<f64>> {
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    let mut r_max = 0.0f64;
    for s in spheres {
        lo = lo.min(c64(s) - s.radius as f64);
        hi = hi.max(c64(s) + s.radius as f64);
        r_max = r_max.max(s.radius as f64);
    }
    let size = (0.5 * (hi - lo).length()).max(1.0);
    let img = cast(spheres, cam, 2e-5 * size);
    let grid = Grid3::new(spheres, (radius + r_max).max(1e-3));
    let side = (rays as f64).sqrt().ceil() as u32;
    let n = img.ids.len();
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(8);
    let chunk = n.div_ceil(threads);
    let mut out = vec![None; n];
    std::thread::scope(|scope| {
        for (part, slot) in out.chunks_mut(chunk).enumerate() {
            let (img, grid) = (&img, &grid);
            scope.spawn(move || {
                let mut near = Vec::new();
                for (k, o) in slot.iter_mut().enumerate() {
                    let i = part * chunk + k;
                    let (px, py) = (i as u32 % cam.width, i as u32 / cam.width);
                    if px % stride != 0 || py % stride != 0 {
                        continue;
                    }
                    if img.ids[i] == u32::MAX || img.ambiguous[i] {
                        continue;
                    }
                    let (orig, dir) = cam.ray(px, py);
                    let p = orig + img.t[i] * dir;
                    let own = &spheres[img.ids[i] as usize];
                    let nrm = (p - c64(own)).normalize();
                    let p = p + nrm * 1e-6 * size;
                    grid.near(p, radius, &mut near);
                    // Only spheres that reach into the ball in front of p.
                    near.retain(|&j| {
                        let s = &spheres[j as usize];
                        let c = c64(s);
                        let r = s.radius as f64;
                        j != img.ids[i] && (c - p).length() < radius + r && (c - p).dot(nrm) > -r
                    });
                    // Orthonormal frame around the normal.
                    let t = if nrm.x.abs() < 0.9 {
                        DVec3::X
                    } else {
                        DVec3::Y
                    };
                    let t = nrm.cross(t).normalize();
                    let b = nrm.cross(t);
                    let rot = ((px.wrapping_mul(73_856_093) ^ py.wrapping_mul(19_349_663)) % 1024)
                        as f64
                        / 1024.0;
                    let mut open = 0u32;
                    let mut total = 0u32;
                    for a in 0..side {
                        for c in 0..side {
                            if total == rays {
                                break;
                            }
                            total += 1;
                            let u = ((a as f64 + 0.5) / side as f64 + rot).fract();
                            let v = (c as f64 + 0.5) / side as f64;
                            // cosine-weighted: uniform disk point lifted to the hemisphere
                            let (rr, phi) = (u.sqrt(), std::f64::consts::TAU * v);
                            let (x, y) = (rr * phi.cos(), rr * phi.sin());
                            let z = (1.0 - x * x - y * y).max(0.0).sqrt();
                            let d = (x * t + y * b + z * nrm).normalize();
                            let hit = near.iter().any(|&j| {
                                let s = &spheres[j as usize];
                                ray_sphere(p, d, c64(s), s.radius as f64).is_some_and(
                                    |(th, disc)| {
                                        let far = th + 2.0 * disc.max(0.0).sqrt();
                                        far > 0.0 && th.max(0.0) < radius
                                    },
                                )
                            });
                            if !hit {
                                open += 1;
                            }
                        }
                    }
                    *o = Some(open as f64 / total as f64);
                }
            });
        }
    });
    out
}

/// Spearman rank correlation of paired samples (average ranks for ties).
pub fn spearman(a: &[f64], b: &[f64]) -> f64 {
    fn ranks(v: &[f64]) -> Vec<f64> {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        let mut r = vec![0.0; v.len()];
        let mut k = 0;
        while k < idx.len() {
            let mut e = k;
            while e + 1 < idx.len() && v[idx[e + 1]] == v[idx[k]] {
                e += 1;
            }
            let avg = (k + e) as f64 / 2.0;
            for &i in &idx[k..=e] {
                r[i] = avg;
            }
            k = e + 1;
        }
        r
    }
    let (ra, rb) = (ranks(a), ranks(b));
    let n = a.len() as f64;
    let (ma, mb) = (ra.iter().sum::<f64>() / n, rb.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in ra.iter().zip(&rb) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa == 0.0 || sbb == 0.0 {
        return 0.0;
    }
    sab / (saa * sbb).sqrt()
}

#[cfg(test)]
mod ao_tests {
    use super::*;

    #[test]
    fn spearman_is_one_for_monotone_and_minus_one_for_reversed() {
        let a = [1.0, 2.0, 3.0, 4.0, 10.0];
        let b = [0.1, 0.2, 0.25, 0.9, 1.0];
        assert!((spearman(&a, &b) - 1.0).abs() < 1e-12);
        let c: Vec<f64> = b.iter().map(|x| -x).collect();
        assert!((spearman(&a, &c) + 1.0).abs() < 1e-12);
    }

    #[test]
    fn ao_of_a_lone_sphere_is_open_and_of_a_pit_is_closed() {
        let s = |c: [f32; 3], r: f32| Sphere {
            center: c,
            radius: r,
            color: [255; 4],
            region: [0; 4],
        };
        let cam = |h: f64| {
            Camera::new(
                DVec3::ZERO,
                DVec3::new(0.0, 0.0, -1.0),
                DVec3::Y,
                h,
                None,
                16,
                16,
            )
            .unwrap()
        };
        let lone = ambient_occlusion(&[s([0.0; 3], 1.0)], &cam(3.0), 2.0, 64, 1);
        assert!(lone.iter().flatten().all(|&v| v == 1.0));
        // A small sphere at the bottom of a ring of big ones: mostly occluded.
        let mut ring = vec![s([0.0, 0.0, 0.0], 0.5)];
        for k in 0..12 {
            let a = k as f32 * std::f32::consts::TAU / 12.0;
            ring.push(s([1.6 * a.cos(), 1.6 * a.sin(), 1.0], 1.0));
        }
        let ao = ambient_occlusion(&ring, &cam(0.6), 4.0, 256, 1);
        let centre = ao[8 * 16 + 8].expect("centre pixel sees the small sphere");
        assert!(centre < 0.7, "pit visibility {centre}");
    }
}
