//! Debian's `tachyon` ray tracer as an independent reference for the look:
//! a scene written as a Tachyon model with sphereshade's camera, key light
//! and colours, and Tachyon's PPM output read back. Used by
//! `examples/tachyon_scene.rs`, `tests/look.rs` and tools/look-vs-tachyon.sh.
//!
//! Tachyon's orthographic view spans 1 / ZOOM world units vertically
//! (checked with one sphere); its frame is left-handed, so the whole world
//! is written mirrored in x (spheres, camera, light), which gives the image
//! sphereshade renders. DIRECTIONAL_LIGHT DIRECTION points from the light
//! toward the scene, like `--light`. Its rays go through pixel corners,
//! ours through pixel centres: the camera is shifted by half a pixel.

use crate::camera::Camera;
use crate::scene::Scene;
use glam::DVec3;
use std::io::Write;
use std::path::Path;

/// How the reference is lit.
#[derive(Clone, Copy, Debug)]
pub struct TachyonLight {
    /// Sky-light ambient occlusion samples (None: no AO).
    pub ao_samples: Option<u32>,
    /// Every sphere white (luminance comparisons), else the scene colours.
    pub white: bool,
}

/// Writes `scene` seen by `cam` with the key light `light` as a Tachyon
/// model: hard shadows from a directional light, optionally sky-light AO.
pub fn write_scene(
    w: &mut impl Write,
    scene: &Scene,
    cam: &Camera,
    light: DVec3,
    how: TachyonLight,
) -> std::io::Result<()> {
    if cam.fov_deg.is_some() {
        return Err(std::io::Error::other(
            "only orthographic cameras are written",
        ));
    }
    let m = |v: DVec3| DVec3::new(-v.x, v.y, v.z);
    let (bc, br) = scene.bounding_sphere();
    let right = cam.dir.cross(cam.up).normalize();
    let upv = right.cross(cam.dir);
    let pxs = 1.0 / cam.pixels_per_unit();
    // Tachyon's ray of pixel (x, y) passes through the pixel's corner, ours
    // through its centre: move its camera half a pixel left and down (found
    // by the correlation of N.L with Tachyon's direct light on lit pixels:
    // 0.93 unshifted, 1.000 shifted).
    let eye = m(cam.center
        - (right + upv) * (0.5 * pxs)
        - cam.dir * (cam.center.distance(bc.as_dvec3()) + 4.0 * br as f64 + 1.0));
    let (dir, up) = (m(cam.dir), m(cam.up));
    writeln!(w, "BEGIN_SCENE\nRESOLUTION {} {}", cam.width, cam.height)?;
    writeln!(
        w,
        "CAMERA\n  PROJECTION ORTHOGRAPHIC\n  ZOOM {}\n  ASPECTRATIO 1.0\n  ANTIALIASING 0\n  RAYDEPTH 4\n  \
         CENTER {} {} {}\n  VIEWDIR {} {} {}\n  UPDIR {} {} {}\nEND_CAMERA",
        1.0 / cam.view_height,
        eye.x,
        eye.y,
        eye.z,
        dir.x,
        dir.y,
        dir.z,
        up.x,
        up.y,
        up.z
    )?;
    let l = m(crate::camera::unit(light).unwrap_or(DVec3::NEG_ONE.normalize()));
    writeln!(
        w,
        "DIRECTIONAL_LIGHT DIRECTION {} {} {} COLOR 1 1 1\nBACKGROUND 0 0 0",
        l.x, l.y, l.z
    )?;
    if let Some(n) = how.ao_samples {
        // (VMD's export: sky colour, direct light rescaled, samples)
        writeln!(
            w,
            "SHADER_MODE FULL\n  AMBIENT_OCCLUSION\n    AMBIENT_COLOR 0.8 0.8 0.8\n    RESCALE_DIRECT 0.6\n    \
             SAMPLES {n}\nEND_SHADER_MODE"
        )?;
    }
    for sp in &scene.spheres {
        let [r, g, b] = if how.white {
            [1.0; 3]
        } else {
            let [r, g, b, _] = sp.color.map(|v| v as f32 / 255.0);
            [r, g, b]
        };
        writeln!(
            w,
            "SPHERE CENTER {} {} {} RAD {} TEXTURE AMBIENT 0.1 DIFFUSE 0.8 SPECULAR 0.0 OPACITY 1.0 \
             COLOR {r:.3} {g:.3} {b:.3} TEXFUNC 0",
            -sp.center[0], sp.center[1], sp.center[2], sp.radius
        )?;
    }
    writeln!(w, "END_SCENE")
}

/// Runs `tachyon` on `model` (2 threads) writing a PPM; returns its RGB
/// pixels, row 0 at the top.
pub fn render(model: &Path, out_ppm: &Path) -> std::io::Result<(u32, u32, Vec<[u8; 3]>)> {
    let o = std::process::Command::new("tachyon")
        .arg(model)
        .args(["-numthreads", "2", "-format", "PPM", "-o"])
        .arg(out_ppm)
        .output()
        .map_err(|e| {
            std::io::Error::other(format!("cannot run tachyon ({e}): run tools/setup.sh"))
        })?;
    if !o.status.success() {
        return Err(std::io::Error::other(format!(
            "tachyon failed: {}",
            String::from_utf8_lossy(&o.stderr)
                .lines()
                .next()
                .unwrap_or("")
        )));
    }
    read_ppm(out_ppm)
}

/// A binary PPM (P6, 8-bit) as RGB pixels.
pub fn read_ppm(path: &Path) -> std::io::Result<(u32, u32, Vec<[u8; 3]>)> {
    let d = std::fs::read(path)?;
    let bad = || std::io::Error::other("not a P6 PPM");
    let mut fields = Vec::new();
    let mut i = 0;
    while fields.len() < 4 {
        while i < d.len() && d[i].is_ascii_whitespace() {
            i += 1;
        }
        if i < d.len() && d[i] == b'#' {
            while i < d.len() && d[i] != b'\n' {
                i += 1;
            }
            continue;
        }
        let s = i;
        while i < d.len() && !d[i].is_ascii_whitespace() {
            i += 1;
        }
        if s == i {
            return Err(bad());
        }
        fields.push(String::from_utf8_lossy(&d[s..i]).to_string());
    }
    i += 1; // the single whitespace after maxval
    if fields[0] != "P6" || fields[3] != "255" {
        return Err(bad());
    }
    let (w, h): (u32, u32) = (
        fields[1].parse().map_err(|_| bad())?,
        fields[2].parse().map_err(|_| bad())?,
    );
    let px = d.get(i..i + (w * h * 3) as usize).ok_or_else(bad)?;
    Ok((
        w,
        h,
        px.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    ))
}

/// Rec. 709 luma of sRGB-encoded 8-bit values (0..255), as image viewers
/// compute "grey level".
pub fn luma(rgb: [u8; 3]) -> f64 {
    0.2126 * rgb[0] as f64 + 0.7152 * rgb[1] as f64 + 0.0722 * rgb[2] as f64
}

/// The look of one image against Tachyon's, over the pixels both cover.
#[derive(Clone, Copy, Debug)]
pub struct LookStats {
    /// Spearman rank correlation of the luminances.
    pub rho: f64,
    /// Standard deviation and mean of the grey level (0..255).
    pub ours_sd: f64,
    pub ref_sd: f64,
    pub ours_mean: f64,
    pub ref_mean: f64,
    pub pixels: usize,
}

impl std::fmt::Display for LookStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "rank correlation {:.3} over {} px; luminance spread {:.1} vs Tachyon {:.1} ({:.2}x); mean {:.0} vs {:.0}",
            self.rho,
            self.pixels,
            self.ours_sd,
            self.ref_sd,
            self.ours_sd / self.ref_sd,
            self.ours_mean,
            self.ref_mean
        )
    }
}

/// The scene as `.xyzr` white spheres: same centres and radii, no
/// hierarchy (semantic SSDO then treats every sphere as its own region),
/// every sphere white. The protocol of the issue "Images people publish".
pub fn white_spheres(scene: &Scene) -> Scene {
    let spheres = scene
        .spheres
        .iter()
        .map(|s| crate::scene::Sphere {
            color: [255; 4],
            region: Default::default(),
            ..*s
        })
        .collect();
    Scene {
        spheres,
        level_names: Vec::new(),
        source: scene.source.clone(),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    }
}

/// Renders `scene` with `settings` (orthographic) and the same scene with
/// Tachyon (64-sample sky-light AO, hard shadows from the same key light);
/// returns the statistics and a side-by-side picture (ours left). Tachyon's
/// model and PPM are written to `work_dir` as `NAME.dat` / `NAME.ppm`.
pub fn compare_look(
    ctx: &crate::vk::Context,
    scene: &Scene,
    settings: crate::settings::RenderSettings,
    work_dir: &Path,
    name: &str,
) -> Result<(LookStats, image::RgbImage), String> {
    let cam = settings.camera;
    let light = settings.light;
    let mut r = crate::render::Renderer::new(ctx, scene, settings).map_err(|e| e.to_string())?;
    r.render_frame().map_err(|e| e.to_string())?;
    let color = r.inspect().read_color().map_err(|e| e.to_string())?;
    let vis = r.inspect().read_vis().map_err(|e| e.to_string())?;
    drop(r);
    let reference = reference_image(scene, &cam, light, work_dir, name)?;
    let (w, h) = (cam.width, cam.height);
    let ours: Vec<[u8; 3]> = color
        .iter()
        .map(|c| {
            let c = c.to_le_bytes();
            [c[0], c[1], c[2]]
        })
        .collect();
    let covered: Vec<bool> = vis.iter().map(|&k| k != crate::gpu::VIS_EMPTY).collect();
    Ok(look_stats(w, h, &ours, &covered, &reference))
}

/// Tachyon's image of `scene` seen by `cam` with the key light `light`,
/// hard shadows and 64-sample sky-light AO, in the scene's colours: the
/// reference of the look comparison. The model and the PPM are written to
/// `work_dir` as `NAME.dat` / `NAME.ppm`.
pub fn reference_image(
    scene: &Scene,
    cam: &Camera,
    light: DVec3,
    work_dir: &Path,
    name: &str,
) -> Result<Vec<[u8; 3]>, String> {
    let model = work_dir.join(format!("{name}.dat"));
    let mut buf = Vec::new();
    let how = TachyonLight {
        ao_samples: Some(64),
        white: false,
    };
    write_scene(&mut buf, scene, cam, light, how).map_err(|e| e.to_string())?;
    std::fs::write(&model, buf).map_err(|e| format!("{}: {e}", model.display()))?;
    let (tw, th, reference) =
        render(&model, &work_dir.join(format!("{name}.ppm"))).map_err(|e| e.to_string())?;
    let (w, h) = (cam.width, cam.height);
    if (tw, th) != (w, h) {
        return Err(format!("tachyon wrote {tw}x{th}, not {w}x{h}"));
    }
    Ok(reference)
}

/// The statistics over the pixels covered in `covered` and in the
/// reference (Tachyon's background is black), and a side-by-side picture
/// (ours left).
pub fn look_stats(
    w: u32,
    h: u32,
    ours: &[[u8; 3]],
    covered: &[bool],
    reference: &[[u8; 3]],
) -> (LookStats, image::RgbImage) {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut side = image::RgbImage::new(2 * w, h);
    for i in 0..(w * h) as usize {
        let (x, y) = ((i as u32) % w, (i as u32) / w);
        side.put_pixel(x, y, image::Rgb(ours[i]));
        side.put_pixel(x + w, y, image::Rgb(reference[i]));
        if covered[i] && reference[i] != [0, 0, 0] {
            a.push(luma(ours[i]));
            b.push(luma(reference[i]));
        }
    }
    let mean_sd = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len().max(1) as f64;
        let var = v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / v.len().max(1) as f64;
        (m, var.sqrt())
    };
    let (ours_mean, ours_sd) = mean_sd(&a);
    let (ref_mean, ref_sd) = mean_sd(&b);
    let stats = LookStats {
        rho: crate::reference::spearman(&a, &b),
        ours_sd,
        ref_sd,
        ours_mean,
        ref_mean,
        pixels: a.len(),
    };
    (stats, side)
}
