//! Which placements of a nested scene a view opens
//! (src/scene/instanced/nested.rs): those in the view, large enough on
//! screen that some block instance would draw finer than its coarsest
//! level, nearest first, as many as [`OPEN_INSTANCES`] instances allow;
//! every other placement is drawn by its proxies, which draw exactly the
//! coarsest spheres its instances would draw (placed in two steps, so to
//! f32 rounding) until it is that large.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::scene::Scene;
use crate::scene::instanced::nested::Proxies;

/// The most block instances a view opens: two placements of the 10^9 meso
/// block (145,372 instances each). The cull visits an instance in ~170-190
/// ns on lavapipe, and an opened placement's visible instances draw as in
/// the 10^9 scene: the 10^12 scene at 8,094 A, with two opened, 723 ms and
/// 186 MB.
pub const OPEN_INSTANCES: usize = 300_000;

/// The placements a view opens and what the choice saw.
#[derive(Clone, Debug, PartialEq)]
pub struct Opening {
    pub open: Vec<bool>,
    /// Placements in the view large enough to want opening.
    pub wanted: usize,
    /// Most pixels per world unit at which a placement stays closed.
    pub open_ppu: f32,
}

/// The placements `cam` opens in nested `scene` (`proxies`: None =
/// `--lod off`, every placement opened).
pub fn opening(scene: &Scene, proxies: Option<&Proxies>, cam: &Camera) -> Result<Opening> {
    let k = scene
        .instancing
        .as_ref()
        .map_or(1, |i| i.instances().max(1));
    opening_within(scene, proxies, cam, (OPEN_INSTANCES / k).max(1))
}

/// [`opening`] with room for `budget` placements.
pub fn opening_within(
    scene: &Scene,
    proxies: Option<&Proxies>,
    cam: &Camera,
    budget: usize,
) -> Result<Opening> {
    let Some(nest) = scene.nesting() else {
        return Err(Error::Internal(
            "opening placements of a scene that is not nested".into(),
        ));
    };
    let n = nest.placements.len();
    let Some(proxies) = proxies else {
        return Ok(Opening {
            open: vec![true; n],
            wanted: n,
            open_ppu: 0.0,
        });
    };
    let (bc, br) = scene
        .extremes()
        .and_then(|e| e.bounding_sphere())
        .unwrap_or((glam::Vec3::ZERO, 0.0));
    let (bc, br) = (bc.as_dvec3(), br as f64 * 1.001);
    let eye = cam.eye();
    let half_h = 0.5 * cam.view_height;
    let half_w = half_h * cam.width as f64 / cam.height as f64;
    let ppu0 = cam.pixels_per_unit();
    let d0 = cam.eye_distance();
    // those in the view that want opening: (placement, priority, disc in
    // the view plane at the view centre: centre and radius)
    let mut want: Vec<(usize, f64, [f64; 3])> = Vec::new();
    for (p, place) in nest.placements.iter().enumerate() {
        let c = glam::Vec3::from(crate::scene::instanced::apply_rigid(
            place,
            [bc.x as f32, bc.y as f32, bc.z as f32],
        ))
        .as_dvec3();
        let q = c - eye;
        let (x, y, z) = (q.dot(cam.right), q.dot(cam.up), q.dot(cam.dir));
        let (inside, ppu) = match cam.fov_deg {
            None => (x.abs() <= half_w + br && y.abs() <= half_h + br, ppu0),
            Some(_) => {
                // the sphere against the four side planes (slopes
                // half_w / d0, half_h / d0), and in front of the eye
                let side = |a: f64, s: f64| (a.abs() - s * z) / (1.0 + s * s).sqrt() <= br;
                let near = z - br;
                (
                    z > -br && side(x, half_w / d0) && side(y, half_h / d0),
                    if near > 1e-6 * d0 {
                        ppu0 * d0 / near
                    } else {
                        f64::INFINITY
                    },
                )
            }
        };
        if inside && ppu > proxies.open_ppu as f64 {
            // nearest first, a placement that fills more of the view as if
            // up to one placement nearer (a lattice's front layer ties)
            let (dx, dy, dr) = match cam.fov_deg {
                None => (x, y, br),
                Some(_) => {
                    let zz = z.max(1e-6 * d0);
                    (x * d0 / zz, y * d0 / zz, br * d0 / zz)
                }
            };
            let ox = (dx + dr).min(half_w) - (dx - dr).max(-half_w);
            let oy = (dy + dr).min(half_h) - (dy - dr).max(-half_h);
            let fill = (ox.max(0.0) * oy.max(0.0)) / (4.0 * half_w * half_h);
            want.push((p, z - br - 2.0 * br * fill, [dx, dy, dr]));
        }
    }
    want.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let mut open = vec![false; n];
    // (one whose disc an opened nearer one's holds is behind it: its
    // proxies draw what of it shows through; opened only if the budget is
    // left after the others and the view asks for full detail,
    // `--lod-pixels 0`, where proxies are a level of detail too coarse)
    let mut opened: Vec<[f64; 3]> = Vec::new();
    let mut held: Vec<usize> = Vec::new();
    for &(p, _, d) in &want {
        if opened.len() == budget {
            break;
        }
        let behind = opened.iter().any(|o| {
            ((d[0] - o[0]).powi(2) + (d[1] - o[1]).powi(2)).sqrt() + d[2] <= o[2] * 1.0001
        });
        if behind {
            held.push(p);
        } else {
            open[p] = true;
            opened.push(d);
        }
    }
    if proxies.open_ppu <= 0.0 {
        for p in held.into_iter().take(budget - opened.len()) {
            open[p] = true;
        }
    }
    Ok(Opening {
        open,
        wanted: want.len(),
        open_ppu: proxies.open_ppu,
    })
}

/// A nested scene's proxies for `--lod-pixels` (None: `--lod off`, or
/// not nested).
pub fn proxies_of(scene: &Scene, lod_pixels: Option<f32>) -> Result<Option<Proxies>> {
    match (scene.nesting(), lod_pixels) {
        (Some(_), Some(p)) => Ok(Some(Proxies::new(scene, p)?)),
        _ => Ok(None),
    }
}

/// The scene `cam` draws of `scene`: None when it is not nested (draw it as
/// it is), else its placements opened or drawn by `proxies` ([`opening`];
/// made once by [`proxies_of`]: a viewer that reopens placements as its
/// camera moves keeps them).
pub fn resolved(scene: &Scene, cam: &Camera, proxies: Option<&Proxies>) -> Result<Option<Scene>> {
    let Some(inst) = scene.instancing.as_ref().filter(|i| i.nesting.is_some()) else {
        return Ok(None);
    };
    let o = opening(scene, proxies, cam)?;
    let opened = o.open.iter().filter(|&&x| x).count();
    log::info!(
        "nested: {opened} of {} placements opened ({} in view want it; closed below {:.4} px/unit)",
        o.open.len(),
        o.wanted,
        o.open_ppu
    );
    let empty;
    let proxies = match proxies {
        Some(p) => p,
        None => {
            empty = Proxies::none();
            &empty
        }
    };
    Ok(Some(inst.resolve(scene, proxies, &o.open)?))
}
