//! SSDO against a ray-traced ambient-occlusion reference (f64, 256
//! cosine-weighted rays per pixel within the SSDO's far radius, every
//! sphere tested): the rank correlation (Spearman) of the `ao` AOV with the
//! reference over covered pixels, on the first 2,500 atoms of 1TII at 320x240.

mod common;

use common::*;
use sphereshade::reference::{ambient_occlusion, spearman};
use sphereshade::render::Renderer;
use sphereshade::settings::{ShadowMode, SsdoMode};
use sphereshade::stages::ssdo::passes::Receivers;

/// The first 2,500 atoms of 1TII, replicated `copies` x `copies` x
/// `copies` (1: as they are).
fn ao_scene(copies: u32) -> sphereshade::scene::Scene {
    let mut scene = load_data("1tii.pdb");
    scene.spheres.truncate(2500);
    if copies > 1 {
        scene = scene.replicate([copies; 3]);
    }
    scene
}

/// At image size `(w, h)`, the reference on every `stride`-th pixel
/// (`path`: the SSDO receivers this size must take).
fn correlation_at(
    mode: SsdoMode,
    fov: Option<f64>,
    (w, h): (u32, u32),
    stride: u32,
    (copies, path): (u32, Receivers),
) -> (f64, usize) {
    let ctx = validated_context();
    let scene = ao_scene(copies);
    let cam = camera(&scene, w, h, fov);
    let mut s = settings(cam, ShadowMode::None);
    s.ssdo = mode;
    s.ssdo_knobs.blur = true;
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    assert_eq!(
        r.inspect().ssdo_receivers(),
        path,
        "SSDO receivers at {w}x{h}"
    );
    r.render_frame().expect("frame");
    let radius = r.inspect().ssdo_far_radius();
    let ao: Vec<f32> = r
        .inspect()
        .read_ambient()
        .expect("ao")
        .iter()
        .map(|a| a[0])
        .collect();
    drop(r);
    assert_no_validation_messages(&ctx);
    let reference = ambient_occlusion(&scene.spheres, &cam, radius, 256, stride);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (i, v) in reference.iter().enumerate() {
        if let Some(v) = v {
            a.push(*v);
            b.push(ao[i] as f64);
        }
    }
    (spearman(&a, &b), a.len())
}

/// Runs `correlation_at` and asserts enough covered pixels and a rank
/// correlation of at least `min`.
fn assert_ranks(
    what: &str,
    fov: Option<f64>,
    size: (u32, u32),
    stride: u32,
    scene: (u32, Receivers),
    min: f64,
) {
    let (rho, n) = correlation_at(SsdoMode::Plain, fov, size, stride, scene);
    eprintln!("{what} vs ray-traced AO: Spearman {rho:.3} over {n} pixels");
    assert!(n > 2000, "too few covered pixels: {n}");
    assert!(rho >= min, "{what} rank correlation {rho:.3} < {min}");
}

#[test]
fn plain_ssdo_ranks_like_ray_traced_ao() {
    // Measured on lavapipe: 0.929; a0b2d65's full-resolution SSDO: 0.915.
    // The goal is >= 0.85 and no lower than before (0.91 leaves room for
    // other drivers' rounding).
    assert_ranks(
        "plain SSDO",
        None,
        (320, 240),
        2,
        (1, Receivers::Pixel),
        0.91,
    );
}

/// Spheres large on screen (~30 px radius at 1280x960): SSDO per 2x2
/// block, blurred per block and upsampled, must rank like the reference
/// too. Measured 0.938 (the per-pixel path before it, at this size: 0.936).
#[test]
fn per_block_ssdo_ranks_like_ray_traced_ao() {
    assert_ranks(
        "per-block SSDO",
        None,
        (1280, 960),
        8,
        (1, Receivers::Block),
        0.91,
    );
}

/// The same per block through the perspective (world-space) tap path.
#[test]
fn per_block_ssdo_ranks_like_ray_traced_ao_in_perspective() {
    assert_ranks(
        "per-block SSDO (perspective)",
        Some(40.0),
        (1280, 960),
        8,
        (1, Receivers::Block),
        0.9,
    );
}

/// Perspective cameras take the world-space tap path (orthographic ones
/// step in view space): both must rank like the reference.
#[test]
fn plain_ssdo_ranks_like_ray_traced_ao_in_perspective() {
    assert_ranks(
        "plain SSDO (perspective)",
        Some(40.0),
        (320, 240),
        2,
        (1, Receivers::Pixel),
        0.9,
    );
}

/// Spheres a few pixels wide (27 copies at 320x240: radius ~1.4 px): SSDO
/// per visible sphere, weighted per pixel by its normal. Measured 0.874;
/// the per-pixel path at this size 0.827, a0b2d65's 0.823.
#[test]
fn per_sphere_ssdo_ranks_like_ray_traced_ao() {
    assert_ranks(
        "per-sphere SSDO",
        None,
        (320, 240),
        2,
        (3, Receivers::Sphere),
        0.85,
    );
}

/// The same through the perspective (world-space) tap path. Measured
/// 0.817; the per-pixel path on this scene 0.806, a0b2d65's 0.793.
#[test]
fn per_sphere_ssdo_ranks_like_ray_traced_ao_in_perspective() {
    assert_ranks(
        "per-sphere SSDO (perspective)",
        Some(40.0),
        (320, 240),
        2,
        (3, Receivers::Sphere),
        0.78,
    );
}

/// Measurement helper (ignored): Spearman of an `--aov ao` PNG rendered by
/// any build (AO_PNG=path, the scene written to AO_XYZR first) against the
/// reference, at the PNG's size. Used to compare builds in the notes.
#[test]
#[ignore]
fn ao_png_correlation() {
    let mut scene = load_data("1tii.pdb");
    let atoms: usize = std::env::var("AO_ATOMS").map_or(2500, |s| s.parse().unwrap());
    scene.spheres.truncate(atoms);
    if let Ok(r) = std::env::var("AO_REPLICATE") {
        let n: u32 = r.parse().unwrap();
        scene = scene.replicate([n, n, n]);
    }
    if let Ok(path) = std::env::var("AO_XYZR") {
        let text: String = scene
            .spheres
            .iter()
            .map(|s| {
                format!(
                    "{} {} {} {}\n",
                    s.center[0], s.center[1], s.center[2], s.radius
                )
            })
            .collect();
        std::fs::write(&path, text).unwrap();
        eprintln!("wrote {path}");
        return;
    }
    let path = std::env::var("AO_PNG").expect("AO_PNG");
    let img = image::open(&path).expect("png").to_luma8();
    let fov = std::env::var("AO_FOV").ok().map(|s| s.parse().unwrap());
    let cam = camera(&scene, img.width(), img.height(), fov);
    let typical = 1.7f64; // median vdW radius of 1TII's first 2,500 atoms (C)
    let px = 1.0 / cam.pixels_per_unit();
    let radius = (12.0 * typical).max(8.0 * px);
    let stride: u32 = std::env::var("AO_STRIDE").map_or(2, |s| s.parse().unwrap());
    let reference = ambient_occlusion(&scene.spheres, &cam, radius, 256, stride);
    if let Ok(out) = std::env::var("AO_REF_OUT") {
        // the reference as a PNG (white where not traced), to look at
        let px: Vec<u8> = reference
            .iter()
            .map(|v| v.map_or(255, |v| (v * 255.0).round() as u8))
            .collect();
        image::GrayImage::from_raw(img.width(), img.height(), px)
            .expect("size")
            .save(&out)
            .expect("write");
    }
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (i, v) in reference.iter().enumerate() {
        if let Some(v) = v {
            a.push(*v);
            b.push(img.as_raw()[i] as f64);
        }
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    eprintln!(
        "{path}: Spearman {:.3} over {} pixels; mean {:.3} (reference {:.3})",
        spearman(&a, &b),
        a.len(),
        mean(&b) / 255.0,
        mean(&a)
    );
}

/// Without a hierarchy every sphere is its own region, so semantic SSDO
/// must equal plain on the per-sphere path too (up to collisions of the
/// 15-bit region hashes), and occlude (not a uniform 1).
#[test]
fn per_sphere_semantic_without_hierarchy_equals_plain() {
    let ctx = validated_context();
    let mut scene = ao_scene(3);
    scene.level_names.clear();
    for s in &mut scene.spheres {
        s.region = Default::default();
    }
    let cam = camera(&scene, 320, 240, None);
    let ambient = |mode: SsdoMode| {
        let mut s = settings(cam, ShadowMode::None);
        s.ssdo = mode;
        let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
        assert_eq!(r.inspect().ssdo_receivers(), Receivers::Sphere);
        r.render_frame().expect("frame");
        let ao: Vec<f32> = r
            .inspect()
            .read_ambient()
            .expect("ao")
            .iter()
            .map(|a| a[0])
            .collect();
        ao
    };
    let (plain, semantic) = (ambient(SsdoMode::Plain), ambient(SsdoMode::Semantic));
    assert_no_validation_messages(&ctx);
    let differ = plain
        .iter()
        .zip(&semantic)
        .filter(|(a, b)| (*a - *b).abs() > 1.0 / 255.0)
        .count();
    let occluded = plain.iter().filter(|a| **a < 0.9).count();
    eprintln!(
        "{differ} of {} pixels differ; {occluded} below 0.9",
        plain.len()
    );
    assert!(differ * 200 <= plain.len(), "{differ} pixels differ");
    assert!(occluded > 1000, "too little occlusion: {occluded}");
}

/// The per-sphere list (flag bits set by `ssdo_prep`, compacted by
/// `ssdo_list` with one atomic per flag word) holds every sphere the
/// visibility buffer shows, each once, and nothing else; the workgroup
/// count is the list's length in groups of the dispatch's size. A CPU
/// model of the atomics' result: GPU-AV does not check atomics.
#[test]
fn per_sphere_list_is_exactly_the_visible_spheres() {
    let ctx = validated_context();
    let scene = ao_scene(3);
    for (w, h, fov) in [(320, 240, None), (301, 217, Some(30.0))] {
        let cam = camera(&scene, w, h, fov);
        let mut s = settings(cam, ShadowMode::None);
        s.ssdo = SsdoMode::Semantic;
        let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
        assert_eq!(r.inspect().ssdo_receivers(), Receivers::Sphere);
        r.render_frame().expect("frame");
        let (mut list, groups) = r
            .inspect()
            .read_sphere_list()
            .expect("list")
            .expect("per-sphere buffers");
        let mut seen: Vec<u32> = r
            .inspect()
            .read_vis()
            .expect("vis")
            .iter()
            .map(|k| *k as u32)
            .filter(|id| *id != u32::MAX)
            .collect();
        seen.sort_unstable();
        seen.dedup();
        list.sort_unstable();
        eprintln!("{w}x{h}: {} spheres listed, {groups} groups", list.len());
        assert!(seen.len() > 100, "too few spheres seen: {}", seen.len());
        let twice = list.windows(2).filter(|p| p[0] == p[1]).count();
        let missing = seen
            .iter()
            .filter(|id| list.binary_search(id).is_err())
            .count();
        let extra = list
            .iter()
            .filter(|id| seen.binary_search(id).is_err())
            .count();
        assert_eq!(
            (missing, extra, twice),
            (0, 0, 0),
            "{w}x{h}: spheres seen but not listed, listed but not seen, listed twice"
        );
        let g = sphereshade::passes::LOCAL_SIZE as usize;
        assert_eq!(groups as usize, list.len().div_ceil(g));
        // (what the renderer's memory budget for these buffers counts)
        let bytes = r.inspect().memory_by_class();
        let want = sphereshade::stages::ssdo::passes::SphereBuffers::bytes_for(
            r.inspect().sphere_count(),
            w as u64 * h as u64,
        );
        assert_eq!(bytes.get("ssdo_spheres").copied(), Some(want), "{w}x{h}");
    }
    assert_no_validation_messages(&ctx);
}
