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
