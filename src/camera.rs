//! The DESIGN.md camera: orthographic by default, perspective with `--fov`.
//! The same struct describes the key light's orthographic view. f64 here (the
//! CPU references use it directly); `to_gpu` rounds to f32 for the shaders.

use crate::error::{Error, Result};
use crate::gpu::GpuView;
use crate::scene::Scene;
use glam::DVec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub center: DVec3,
    /// Unit view direction d.
    pub dir: DVec3,
    /// r = normalize(cross(d, up)).
    pub right: DVec3,
    /// u = cross(r, d).
    pub up: DVec3,
    /// View height h in world units (at the view centre for perspective).
    pub view_height: f64,
    /// Vertical field of view in degrees; None = orthographic.
    pub fov_deg: Option<f64>,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    pub fn new(
        center: DVec3,
        view_dir: DVec3,
        up_hint: DVec3,
        view_height: f64,
        fov_deg: Option<f64>,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        let dir = unit(view_dir)
            .ok_or_else(|| Error::Input("--view-dir must be a finite non-zero vector".into()))?;
        let up_hint = unit(up_hint)
            .ok_or_else(|| Error::Input("--up must be a finite non-zero vector".into()))?;
        let r = dir.cross(up_hint);
        if !(r.length() > 1e-9) {
            return Err(Error::Input(
                "--up must not be parallel to --view-dir".into(),
            ));
        }
        if !(view_height > 0.0) || !view_height.is_finite() {
            return Err(Error::Input("--view-height must be positive".into()));
        }
        if let Some(f) = fov_deg
            && !(f > 0.0 && f < 179.0)
        {
            return Err(Error::Input(
                "--fov must be above 0 and below 179 degrees".into(),
            ));
        }
        if width == 0 || height == 0 || width > 16384 || height > 16384 {
            return Err(Error::Input(
                "--width/--height must be between 1 and 16384".into(),
            ));
        }
        let right = r.normalize();
        let up = right.cross(dir);
        Ok(Camera {
            center,
            dir,
            right,
            up,
            view_height,
            fov_deg,
            width,
            height,
        })
    }

    /// Eye distance from the view centre (0 for orthographic).
    pub fn eye_distance(&self) -> f64 {
        self.fov_deg.map_or(0.0, |f| {
            0.5 * self.view_height / (0.5 * f.to_radians()).tan()
        })
    }

    pub fn eye(&self) -> DVec3 {
        self.center - self.eye_distance() * self.dir
    }

    /// View-plane coordinates of a pixel centre (row 0 at the top).
    pub fn plane(&self, px: f64, py: f64) -> (f64, f64) {
        let (w, h) = (self.width as f64, self.height as f64);
        let x = ((px + 0.5) / w - 0.5) * self.view_height * w / h;
        let y = (0.5 - (py + 0.5) / h) * self.view_height;
        (x, y)
    }

    /// Primary ray of a pixel: (origin, unit direction). Orthographic rays
    /// start 1e6 units behind the view centre, as DESIGN.md specifies.
    pub fn ray(&self, px: u32, py: u32) -> (DVec3, DVec3) {
        let (x, y) = self.plane(px as f64, py as f64);
        match self.fov_deg {
            None => (
                self.center + x * self.right + y * self.up - 1e6 * self.dir,
                self.dir,
            ),
            Some(_) => {
                let dist = self.eye_distance();
                (
                    self.eye(),
                    (dist * self.dir + x * self.right + y * self.up).normalize(),
                )
            }
        }
    }

    /// Pixels per world unit on the view plane.
    pub fn pixels_per_unit(&self) -> f64 {
        self.height as f64 / self.view_height
    }

    pub fn to_gpu(&self, depth_offset: f64) -> GpuView {
        self.to_gpu_window(depth_offset, None)
    }

    /// The view for a frame whose buffers hold `window` of the image (None:
    /// the whole image): rays keep the image's coordinates.
    pub fn to_gpu_window(&self, depth_offset: f64, window: Option<Window>) -> GpuView {
        let win = window.unwrap_or(Window::whole(self));
        let f = |v: DVec3, w: f64| [v.x as f32, v.y as f32, v.z as f32, w as f32];
        GpuView {
            center: f(self.center, self.pixels_per_unit()),
            right: f(self.right, self.width as f64),
            up: f(self.up, self.height as f64),
            dir: f(self.dir, self.eye_distance()),
            depth: [depth_offset as f32, 0.0, 0.0, 0.0],
            dims: [win.width, win.height, win.x, win.y],
        }
    }
}

/// A rectangle of an image's pixels: what a tile's buffers hold (the tile
/// and its margin).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

impl Window {
    pub fn whole(cam: &Camera) -> Window {
        Window {
            x: 0,
            y: 0,
            width: cam.width,
            height: cam.height,
        }
    }

    pub fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// Whether it is a non-empty part of `cam`'s image.
    pub fn fits(&self, cam: &Camera) -> bool {
        self.width > 0
            && self.height > 0
            && self.x as u64 + self.width as u64 <= cam.width as u64
            && self.y as u64 + self.height as u64 <= cam.height as u64
    }
}

/// An orthographic square view along `light_dir`, fitted tightly to the
/// spheres' extent across the light (not to the camera frustum).
pub fn light_view(
    spheres: impl Iterator<Item = ([f32; 3], f32)>,
    light_dir: DVec3,
    size: u32,
) -> Result<Camera> {
    let axes = light_axes(light_dir)?;
    light_view_of(extent_along(spheres, axes), axes, size)
}

/// The light view's axes for `light_dir` (from the light toward the
/// scene): right, up, and the unit direction.
pub fn light_axes(light_dir: DVec3) -> Result<[DVec3; 3]> {
    let d = unit(light_dir)
        .ok_or_else(|| Error::Input("--light must be a finite non-zero direction".into()))?;
    // Any up not parallel to d.
    let hint = if d.y.abs() < 0.9 { DVec3::Y } else { DVec3::X };
    let right = d.cross(hint).normalize();
    Ok([right, right.cross(d), d])
}

/// Along each of `axes`, the least `centre . axis - radius` and the
/// largest `centre . axis + radius` of `spheres` (None: no spheres).
pub fn extent_along(
    spheres: impl Iterator<Item = ([f32; 3], f32)>,
    [right, up, d]: [DVec3; 3],
) -> Option<(DVec3, DVec3)> {
    let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
    for (c, r) in spheres {
        let c = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
        let p = DVec3::new(c.dot(right), c.dot(up), c.dot(d));
        lo = lo.min(p - r as f64);
        hi = hi.max(p + r as f64);
    }
    (lo.x <= hi.x).then_some((lo, hi))
}

/// The orthographic light view along `axes` (from [`light_axes`]) fitted
/// to the spheres' `extent` along them (None: a unit box), `size`² texels.
pub fn light_view_of(
    extent: Option<(DVec3, DVec3)>,
    [right, up, d]: [DVec3; 3],
    size: u32,
) -> Result<Camera> {
    let (lo, hi) = extent.unwrap_or((DVec3::splat(-1.0), DVec3::splat(1.0)));
    let mid = 0.5 * (lo + hi);
    let center = mid.x * right + mid.y * up + mid.z * d;
    // Square texels; a hair of margin keeps border spheres off the edge.
    let extent = (hi.x - lo.x).max(hi.y - lo.y).max(1e-3) * 1.001;
    // (the direction is valid and the extent finite: the scene's
    // coordinates are bounded, so an error here is ours, not an option's)
    Camera::new(center, d, up, extent, None, size, size)
        .map_err(|e| Error::Internal(format!("light view: {e}")))
}

/// The unit vector along v, for any finite non-zero v (scaled first, so
/// 1e300 components do not overflow); None otherwise.
pub fn unit(v: DVec3) -> Option<DVec3> {
    let m = v.abs().max_element();
    if !(m > 0.0 && m.is_finite()) {
        return None;
    }
    Some((v / m).normalize())
}

/// What the caller fixes of a default camera; the rest is fitted to the
/// scene (DESIGN.md: centre and height from its bounding sphere).
#[derive(Clone, Copy, Debug)]
pub struct CameraFit {
    pub view_dir: DVec3,
    pub up: DVec3,
    /// Look-at point (default: the bounding sphere's centre).
    pub center: Option<DVec3>,
    /// World units across the image height (default: the bounding
    /// sphere's diameter + 5 %).
    pub view_height: Option<f64>,
    /// Vertical field of view in degrees (None: orthographic).
    pub fov: Option<f64>,
}

impl Default for CameraFit {
    fn default() -> Self {
        CameraFit {
            view_dir: DVec3::NEG_Z,
            up: DVec3::Y,
            center: None,
            view_height: None,
            fov: None,
        }
    }
}

/// Builds the DESIGN.md default camera for a scene, overridable per field.
pub fn default_camera(scene: &Scene, width: u32, height: u32, fit: &CameraFit) -> Result<Camera> {
    fitted_camera(scene.bounding_sphere(), width, height, fit)
}

/// [`default_camera`] for a scene whose bounding sphere (centre, radius)
/// is known.
pub fn fitted_camera(
    (bs_center, bs_radius): (glam::Vec3, f32),
    width: u32,
    height: u32,
    fit: &CameraFit,
) -> Result<Camera> {
    let center = fit.center.unwrap_or(bs_center.as_dvec3());
    let h = fit
        .view_height
        .unwrap_or((2.0 * bs_radius as f64 * 1.05).max(1e-3));
    Camera::new(center, fit.view_dir, fit.up, h, fit.fov, width, height)
}
