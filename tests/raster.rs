//! The compute rasterizer's id AOV against the exact CPU ray caster (f64),
//! orthographic and perspective, on random, procedural and real scenes, with
//! border-crossing, larger-than-screen and sub-pixel spheres. All under
//! GPU-assisted + synchronization validation.

mod common;

use common::*;
use sphereshade::output::ids_from_vis;
use sphereshade::reference;
use sphereshade::render::Renderer;
use sphereshade::scene::{self, Scene};
use sphereshade::settings::{RasterMode, ShadowMode};
use sphereshade::stages::raster::compute::{GUARD_PATTERN, VIS_GUARD_WORDS};

/// Renders `scene` with `cam`, compares with the reference, checks guards.
fn check_against_reference(
    ctx: &sphereshade::vk::Context,
    name: &str,
    scene: &Scene,
    cam: sphereshade::camera::Camera,
) -> f64 {
    let mut r = Renderer::new(ctx, scene, settings(cam, ShadowMode::None)).expect("renderer");
    r.render_frame().expect("frame");
    let vis = r.inspect().read_vis().expect("read vis");
    let guard = r.inspect().read_vis_guard().expect("read guard");
    assert_eq!(guard.len() as u64, VIS_GUARD_WORDS);
    assert!(
        guard.iter().all(|&g| g == GUARD_PATTERN),
        "{name}: visibility guard words overwritten"
    );

    let (_, radius) = scene.bounding_sphere();
    let tolerance = 2e-5 * (radius as f64).max(1.0);
    let reference = reference::cast(&scene.spheres, &cam, tolerance);
    let m = compare_ids(name, &ids_from_vis(&vis), &reference);
    let hit = reference.ids.iter().filter(|&&i| i != u32::MAX).count();
    eprintln!(
        "{name}: {:.4}% of {} pixels match ({} covered), {} mismatches, {} outside float tolerance",
        m.percent(),
        m.pixels,
        hit,
        m.mismatches,
        m.hard_mismatches
    );
    assert!(
        hit > 0,
        "{name}: the reference sees no sphere; the test would prove nothing"
    );
    assert_ids_agree(name, &m);
    m.percent()
}

/// At least 99.9 % of the ids agree, and the mismatches are explainable by
/// float rounding (ties or silhouettes).
fn assert_ids_agree(name: &str, m: &IdMatch) {
    assert!(
        m.percent() >= 99.9,
        "{name}: only {:.3}% match",
        m.percent()
    );
    assert!(
        m.hard_mismatches as f64 <= 1e-4 * m.pixels as f64,
        "{name}: {} mismatches outside float tolerance",
        m.hard_mismatches
    );
}

/// Moves every sphere by up to `amp` across x and z (a trajectory frame)
/// and hands the renderer the new positions.
fn move_all(r: &mut Renderer, spheres: &mut [sphereshade::scene::Sphere], amp: f32) {
    for (i, sp) in spheres.iter_mut().enumerate() {
        let w = i as f32 * 0.37;
        sp.center[0] += amp * w.sin();
        sp.center[2] += amp * w.cos();
    }
    let pos: Vec<[f32; 3]> = spheres.iter().map(|sp| sp.center).collect();
    r.set_positions(&pos).expect("positions");
}

/// A view's visibility buffer against the exact caster through the same
/// view (ties within `tolerance`): at least `min_hit` covered pixels, ids agreeing as
/// `assert_ids_agree` requires.
fn assert_view_matches(
    name: &str,
    vis: &[u64],
    spheres: &[sphereshade::scene::Sphere],
    cam: &sphereshade::camera::Camera,
    tolerance: f64,
    min_hit: usize,
) {
    let reference = reference::cast(spheres, cam, tolerance);
    let m = compare_ids(name, &ids_from_vis(vis), &reference);
    let hit = reference.ids.iter().filter(|&&i| i != u32::MAX).count();
    eprintln!(
        "{name}: {:.4}% of {} pixels match ({hit} covered)",
        m.percent(),
        m.pixels
    );
    assert!(
        hit >= min_hit,
        "{name}: the view sees too little to prove anything"
    );
    assert_ids_agree(name, &m);
}

#[test]
fn random_scene_matches_reference_ortho_and_perspective() {
    let ctx = validated_context();
    let s = scene::procedural("random", 3000, 7).expect("scene");
    check_against_reference(&ctx, "random-ortho", &s, camera(&s, 320, 200, None));
    check_against_reference(&ctx, "random-persp", &s, camera(&s, 320, 200, Some(50.0)));
    assert_no_validation_messages(&ctx);
}

#[test]
fn capsid_scene_matches_reference() {
    let ctx = validated_context();
    let s = scene::procedural("capsid", 6000, 3).expect("scene");
    check_against_reference(&ctx, "capsid-ortho", &s, camera(&s, 256, 256, None));
    check_against_reference(&ctx, "capsid-persp", &s, camera(&s, 256, 256, Some(35.0)));
    assert_no_validation_messages(&ctx);
}

#[test]
fn pdb_1tii_matches_reference() {
    let ctx = validated_context();
    let s = load_data("1tii.pdb");
    assert_eq!(s.spheres.len(), 5684);
    check_against_reference(&ctx, "1tii-ortho", &s, camera(&s, 300, 240, None));
    check_against_reference(&ctx, "1tii-persp", &s, camera(&s, 300, 240, Some(40.0)));
    assert_no_validation_messages(&ctx);
}

/// The light view visits the spheres in a sorted order (runs front to back
/// along the light, src/stages/raster/compute.rs `view_order`): the ISSM's id map
/// must still hold each texel's nearest sphere, as the exact caster finds it
/// through the light view, before and after the light turns far enough for
/// the order to be sorted again, and after every sphere moves (a trajectory
/// frame: sorted again, by the next frame). Techniques that neither draw
/// the light view nor splat the deep lists never sort it.
#[test]
fn ordered_light_raster_matches_reference() {
    let ctx = validated_context();
    let s = scene::procedural("capsid", 6000, 3).expect("scene");
    let mut r = Renderer::new(
        &ctx,
        &s,
        settings(camera(&s, 96, 96, None), ShadowMode::Osm),
    )
    .expect("renderer");
    r.render_frame().expect("frame");
    assert!(
        !r.inspect().light_order_ready(),
        "opacity shadow maps sorted the light order"
    );
    r.update(|set| set.shadows = ShadowMode::Deep)
        .expect("deep");
    r.render_frame().expect("frame");
    assert!(
        r.inspect().light_order_ready(),
        "the deep lists' splat visits the light order"
    );
    r.update(|set| set.shadows = ShadowMode::Issm)
        .expect("issm");
    let (_, radius) = s.bounding_sphere();
    let tolerance = 2e-5 * (radius as f64).max(1.0);
    let mut spheres = s.spheres.clone();
    for (k, light) in [
        glam::DVec3::new(-1.0, -1.0, -1.0),
        glam::DVec3::new(1.0, 0.3, 0.8),
        glam::DVec3::new(1.0, 0.3, 0.8),
    ]
    .into_iter()
    .enumerate()
    {
        if k == 2 {
            // Every sphere moves, by up to 2.5 of the mean radius.
            move_all(&mut r, &mut spheres, 2.0);
            assert!(
                !r.inspect().light_order_ready(),
                "the order survived a move"
            );
        }
        r.update(|set| set.light = light).expect("light");
        r.render_frame().expect("frame");
        assert!(
            r.inspect().light_order_ready(),
            "issm drew a frame without its order"
        );
        let (light_cam, _) = r.inspect().issm_info().expect("issm active");
        let map = r
            .inspect()
            .read_issm()
            .expect("read map")
            .expect("issm map");
        assert_view_matches(
            &format!("issm-light-{k}"),
            &map,
            &spheres,
            &light_cam,
            tolerance,
            1000,
        );
    }
    // Moved while a technique without the light view is active: sorted
    // when ISSM is chosen again.
    r.update(|set| set.shadows = ShadowMode::None)
        .expect("none");
    let pos: Vec<[f32; 3]> = s.spheres.iter().map(|sp| sp.center).collect();
    r.set_positions(&pos).expect("positions");
    r.render_frame().expect("frame");
    assert!(
        !r.inspect().light_order_ready(),
        "sorted for a technique without it"
    );
    r.update(|set| set.shadows = ShadowMode::IssmSoft)
        .expect("issm soft");
    r.render_frame().expect("frame");
    assert!(r.inspect().light_order_ready());
    drop(r);
    assert_no_validation_messages(&ctx);
}

/// The camera view visits the spheres front to back along the view
/// (src/stages/raster/compute.rs `view_order`), sorted again when the camera turns
/// far or the spheres move: each frame's ids must match the exact caster,
/// orthographic and perspective, from the front, after a quarter turn (the
/// old order then runs back to front until sorted again) and after every
/// sphere moved.
#[test]
fn ordered_camera_raster_follows_the_view() {
    let ctx = validated_context();
    let s = scene::procedural("lattice", 4000, 1).expect("scene");
    let (_, radius) = s.bounding_sphere();
    let tolerance = 2e-5 * (radius as f64).max(1.0);
    for fov in [None, Some(40.0)] {
        let front = camera(&s, 160, 120, fov);
        let mut r = Renderer::new(&ctx, &s, settings(front, ShadowMode::None)).expect("renderer");
        let side = sphereshade::camera::default_camera(
            &s,
            160,
            120,
            &sphereshade::camera::CameraFit {
                view_dir: glam::DVec3::new(-1.0, 0.0, 0.0),
                fov,
                ..Default::default()
            },
        )
        .expect("camera");
        let mut spheres = s.spheres.clone();
        for (k, cam) in [front, side, side].into_iter().enumerate() {
            if k == 2 {
                move_all(&mut r, &mut spheres, 0.3);
            }
            r.update(|set| set.camera = cam).expect("camera");
            r.render_frame().expect("frame");
            let vis = r.inspect().read_vis().expect("read vis");
            let view = if fov.is_some() { "persp" } else { "ortho" };
            assert_view_matches(
                &format!("camera-order-{view}-{k}"),
                &vis,
                &spheres,
                &cam,
                tolerance,
                2000,
            );
        }
        drop(r);
    }
    assert_no_validation_messages(&ctx);
}

/// Spheres crossing the border, one larger than the whole screen (banded
/// path), sub-pixel spheres, and perspective with a sphere around the view.
#[test]
fn edge_cases_match_reference() {
    let ctx = validated_context();
    let mut spheres = vec![
        sphere([0.0, 0.0, -50.0], 400.0), // far bigger than the view: covers everything behind
        sphere([-48.0, 10.0, 5.0], 9.0),  // crosses the left border
        sphere([30.0, -26.0, 8.0], 7.0),  // crosses the bottom border
        sphere([0.0, 0.0, 10.0], 14.0),   // large: banded path
    ];
    for i in 0..400 {
        // sub-pixel spheres (pixel = 0.5 units here)
        let (x, y) = ((i % 20) as f32 * 4.0 - 40.0, (i / 20) as f32 * 2.5 - 25.0);
        spheres.push(sphere(
            [x + 0.37, y + 0.11, 30.0],
            0.08 + 0.001 * (i % 7) as f32,
        ));
    }
    let s = scene_of(spheres, "edge cases");
    let cam = |fov| {
        sphereshade::camera::Camera::new(
            glam::DVec3::new(0.0, 0.0, 0.0),
            glam::DVec3::new(0.0, 0.0, -1.0),
            glam::DVec3::Y,
            60.0,
            fov,
            160,
            120,
        )
        .unwrap()
    };
    check_against_reference(&ctx, "edges-ortho", &s, cam(None));
    check_against_reference(&ctx, "edges-persp", &s, cam(Some(60.0)));
    assert_no_validation_messages(&ctx);
}

/// Band jobs that do not fit the job list: the sphere's own invocation
/// draws it, where lavapipe ends its loops after 65,535 back-edges (a
/// larger footprint loses its last rows); the frame is then drawn again
/// with a list twice as long. Four spheres over a 512x384 image (48
/// bands each) and a list of 64 jobs: the same ids and depths as with the
/// default list, the list grown to 256. (With no second drawing the ids
/// differ.) The same through the viewer's pipelined frames
/// (`render_frame_pipelined`, which waits for no frame it just submitted:
/// each finished frame's flag is read from its slot), four frames.
#[test]
fn band_jobs_past_the_list_are_drawn_again_longer() {
    let ctx = validated_context();
    let s = scene_of(screen_filling_spheres(), "screen-filling spheres");
    let st = settings(screen_filling_camera(), ShadowMode::None);
    let mut tight = st.clone();
    tight.band_jobs = Some(64);
    let mut a = Renderer::new(&ctx, &s, st).expect("renderer");
    a.render_frame().expect("frame");
    assert_eq!(a.inspect().band_job_capacity(), 1 << 20);
    let va = a.inspect().read_vis().unwrap();
    for pipelined in [false, true] {
        let mut b = Renderer::new(&ctx, &s, tight.clone()).expect("renderer");
        checked_or_pipelined(&mut b, pipelined);
        let vb = b.inspect().read_vis().unwrap();
        let differ = va.iter().zip(&vb).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "pipelined {pipelined}: {differ} pixels differ");
        assert_eq!(
            b.inspect().band_job_capacity(),
            256,
            "pipelined {pipelined}"
        );
    }
    assert_no_validation_messages(&ctx);
}

#[test]
fn timestamps_report_every_pass() {
    let ctx = validated_context();
    let s = scene::procedural("capsid", 2000, 1).expect("scene");
    let mut r = Renderer::new(
        &ctx,
        &s,
        settings(camera(&s, 128, 96, None), ShadowMode::None),
    )
    .expect("renderer");
    let times = r.render_frame().expect("frame");
    let names: Vec<&str> = times.iter().map(|(n, _)| *n).collect();
    assert!(
        names.contains(&"raster") && names.contains(&"shade"),
        "{names:?}"
    );
    let mut unique = names.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), names.len(), "pass names repeat: {names:?}");
    for (n, ms) in &times {
        assert!(*ms > 0.0 && ms.is_finite(), "pass {n} reported {ms} ms");
    }
    drop(r);
    assert_no_validation_messages(&ctx);
}

/// The vertex/fragment baseline produces the same visibility as the compute
/// rasterizer and matches the reference.
#[test]
fn graphics_raster_matches_compute_and_reference() {
    let ctx = validated_context();
    let s = scene::procedural("capsid", 5000, 9).expect("scene");
    for fov in [None, Some(45.0)] {
        let cam = camera(&s, 256, 192, fov);
        let run = |mode| {
            let mut st = settings(cam, ShadowMode::None);
            st.raster = mode;
            let mut r = Renderer::new(&ctx, &s, st).expect("renderer");
            r.render_frame().expect("frame");
            let guard = r.inspect().read_vis_guard().expect("guard");
            assert!(
                guard.iter().all(|&g| g == GUARD_PATTERN),
                "guard words overwritten"
            );
            ids_from_vis(&r.inspect().read_vis().expect("vis"))
        };
        let (compute, graphics) = (run(RasterMode::Compute), run(RasterMode::Graphics));
        let same = compute
            .iter()
            .zip(&graphics)
            .filter(|(a, b)| a == b)
            .count();
        let pct = 100.0 * same as f64 / compute.len() as f64;
        eprintln!("graphics vs compute ({fov:?}): {pct:.4}% identical ids");
        assert!(
            pct >= 99.99,
            "graphics raster differs from compute on {:.4}% of pixels",
            100.0 - pct
        );
        let (_, radius) = s.bounding_sphere();
        let reference = reference::cast(&s.spheres, &cam, 2e-5 * (radius as f64).max(1.0));
        let m = compare_ids("graphics", &graphics, &reference);
        assert!(
            m.percent() >= 99.9,
            "graphics raster matches the reference on only {:.3}%",
            m.percent()
        );
    }
    assert_no_validation_messages(&ctx);
}

/// Two frames in flight (the viewer's path): timings arrive for the frame
/// submitted earlier, camera changes between frames are honoured, the final
/// image equals a synchronous render, and validation stays silent.
#[test]
fn pipelined_frames_match_synchronous_rendering() {
    let ctx = validated_context();
    let s = scene::procedural("capsid", 3000, 6).expect("scene");
    let mut st = settings(camera(&s, 96, 72, None), ShadowMode::Issm);
    st.ssdo = sphereshade::settings::SsdoMode::Semantic;
    st.ssdo_knobs.blur = true;
    let cams: Vec<_> = (0..4)
        .map(|k| sphereshade::bench::orbit_camera(&st.camera, k, 4).unwrap())
        .collect();
    let mut r = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
    let mut got = Vec::new();
    for c in &cams {
        r.update(|set| set.camera = *c).expect("camera");
        got.push(r.render_frame_pipelined().expect("frame"));
    }
    assert!(
        got[0].is_none() && got[1].is_none(),
        "no frame can be finished before the slots are used once"
    );
    assert!(
        got[2]
            .as_ref()
            .is_some_and(|t| t.iter().all(|(_, ms)| *ms > 0.0))
    );
    let pipelined = r.inspect().read_color().expect("colour");
    drop(r);
    let mut sync = st;
    sync.camera = cams[3];
    let mut r = Renderer::new(&ctx, &s, sync).expect("renderer");
    r.render_frame().expect("frame");
    assert_eq!(
        pipelined,
        r.inspect().read_color().expect("colour"),
        "pipelined and synchronous frames differ"
    );
    drop(r);
    assert_no_validation_messages(&ctx);
}
