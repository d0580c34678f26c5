//! Shared test helpers: a validated Vulkan context, scene builders, and image
//! comparison against CPU references that writes a difference image on
//! failure (target/test-output/NAME-diff.png).
#![allow(dead_code)]

use glam::DVec3;
use sphereshade::camera::Camera;
use sphereshade::camera::{CameraFit, default_camera};
use sphereshade::reference::RefImage;
use sphereshade::scene::{Scene, Sphere};
use sphereshade::settings::{
    IssmParams, RasterMode, RenderSettings, ShadowMapParams, ShadowMode, SsdoMode,
};
use sphereshade::vk::{Context, ContextOptions};
use std::path::PathBuf;

/// A context with the validation layer, GPU-assisted and synchronization
/// validation on: every GPU test runs under it.
pub fn validated_context() -> Context {
    Context::new(&ContextOptions {
        validate: true,
        ..Default::default()
    })
    .unwrap_or_else(|e| {
        panic!("cannot create a validated Vulkan context: {e} (run tools/setup.sh)")
    })
}

/// Fails the test if the validation layer reported anything.
pub fn assert_no_validation_messages(ctx: &Context) {
    let n = ctx.validation_messages();
    assert_eq!(
        n,
        0,
        "validation reported {n} message(s):\n{}",
        ctx.messages.messages().join("\n---\n")
    );
}

/// A file of tests/data (the shared structures, copied with provenance).
pub fn data_file(name: &str) -> PathBuf {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/")).join(name);
    assert!(p.exists(), "{} is missing from the checkout", p.display());
    p
}

/// Loads a file of tests/data with the default options.
pub fn load_data(name: &str) -> Scene {
    sphereshade::scene::load(&data_file(name), &Default::default(), &mut |_, _| {})
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

pub fn out_dir() -> PathBuf {
    let p = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/target/test-output"));
    let _ = std::fs::create_dir_all(&p);
    p
}

pub fn sphere(c: [f32; 3], r: f32) -> Sphere {
    Sphere {
        center: c,
        radius: r,
        color: [200, 200, 200, 255],
        region: [0; 4],
    }
}

/// Four spheres of radius ~400 about the origin: each covers a view or a
/// light map fitted to them (footprints past lavapipe's 65,535-step loops:
/// the band job tests).
pub fn screen_filling_spheres() -> Vec<Sphere> {
    vec![
        sphere([0.0, 0.0, -50.0], 400.0),
        sphere([5.0, 3.0, -20.0], 380.0),
        sphere([-4.0, 2.0, 0.0], 390.0),
        sphere([2.0, -6.0, 10.0], 385.0),
    ]
}

/// One checked frame (`render_frame`), or four through the viewer's path
/// (`render_frame_pipelined`: a finished frame's checks read from its
/// slot, two frames in flight), waited for.
pub fn checked_or_pipelined(r: &mut sphereshade::render::Renderer, pipelined: bool) {
    if pipelined {
        for _ in 0..4 {
            r.render_frame_pipelined().expect("frame");
        }
        r.wait_idle().expect("idle");
    } else {
        r.render_frame().expect("frame");
    }
}

/// A 512x384 orthographic camera 60 units high on the origin, looking
/// down -z: [`screen_filling_spheres`] each cover its image (48 bands).
pub fn screen_filling_camera() -> Camera {
    Camera::new(
        DVec3::ZERO,
        DVec3::new(0.0, 0.0, -1.0),
        DVec3::Y,
        60.0,
        None,
        512,
        384,
    )
    .unwrap()
}

pub fn scene_of(spheres: Vec<Sphere>, name: &str) -> Scene {
    Scene {
        spheres,
        level_names: vec![],
        source: name.to_string(),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    }
}

pub fn settings(camera: Camera, shadows: ShadowMode) -> RenderSettings {
    RenderSettings {
        camera,
        light: DVec3::new(-1.0, -1.0, -1.0),
        shadows,
        issm: IssmParams::default(),
        shadow_maps: ShadowMapParams::default(),
        opacity: 1.0,
        ssdo: SsdoMode::Off,
        ssdo_knobs: sphereshade::settings::SsdoKnobs {
            blur: false,
            semantic_levels: None,
        },
        raster: RasterMode::Compute,
        deep: Default::default(),
        lod: Default::default(),
        aovs: true,
        window: None,
        look: Default::default(),
        ssaa: 1,
        tile_size: None,
        tile_lists: true,
        opaque_view: false,
        band_jobs: None,
    }
}

/// Default DESIGN camera for a scene (view along -z) at a test resolution.
pub fn camera(scene: &Scene, w: u32, h: u32, fov: Option<f64>) -> Camera {
    default_camera(
        scene,
        w,
        h,
        &CameraFit {
            view_dir: DVec3::new(0.0, 0.0, -1.0),
            fov,
            ..Default::default()
        },
    )
    .expect("camera")
}

/// Result of comparing GPU ids with the reference.
pub struct IdMatch {
    pub pixels: usize,
    pub mismatches: usize,
    /// Mismatches on pixels the reference does not mark ambiguous.
    pub hard_mismatches: usize,
}

impl IdMatch {
    pub fn percent(&self) -> f64 {
        100.0 * (self.pixels - self.mismatches) as f64 / self.pixels as f64
    }
}

/// Compares GPU sphere ids with the reference; on any non-ambiguous mismatch
/// writes NAME-diff.png (red = mismatch, yellow = ambiguous mismatch).
pub fn compare_ids(name: &str, gpu: &[Option<u32>], reference: &RefImage) -> IdMatch {
    let mut m = IdMatch {
        pixels: gpu.len(),
        mismatches: 0,
        hard_mismatches: 0,
    };
    let mut diff = image::RgbImage::new(reference.width, reference.height);
    for (i, (g, &r)) in gpu.iter().zip(&reference.ids).enumerate() {
        let r = (r != u32::MAX).then_some(r);
        let px = diff.get_pixel_mut(i as u32 % reference.width, i as u32 / reference.width);
        if *g != r {
            m.mismatches += 1;
            if reference.ambiguous[i] {
                *px = image::Rgb([255, 255, 0]);
            } else {
                m.hard_mismatches += 1;
                *px = image::Rgb([255, 0, 0]);
            }
        } else if r.is_some() {
            *px = image::Rgb([40, 40, 40]);
        }
    }
    if m.hard_mismatches > 0 {
        let p = out_dir().join(format!("{name}-diff.png"));
        let _ = diff.save(&p);
        eprintln!("{name}: wrote difference image {}", p.display());
    }
    m
}

/// Loads `file` as the CLI does with rules (kind "hide", "paint" or
/// "alpha", and the text after the flag), applied in the order given.
pub fn load_with_rules(file: &std::path::Path, rules: &[(&str, &str)], expand: bool) -> Scene {
    let mut a = sphereshade::run::SceneArgs {
        input: Some(file.to_path_buf()),
        expand,
        ..Default::default()
    };
    for (kind, text) in rules {
        a.add_rule(kind, text).unwrap();
    }
    sphereshade::run::load_scene(&a)
        .unwrap_or_else(|e| panic!("{} {rules:?}: {e}", file.display()))
        .0
}
