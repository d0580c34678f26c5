//! Light-space caching (`Renderer::set_light_cache`): while only the camera
//! moves, every technique's frames skip its light passes and give exactly
//! the image a fresh renderer gives; a new light rebuilds the structure.

mod common;

use common::*;
use glam::DVec3;
use sphereshade::camera::Camera;
use sphereshade::render::Renderer;
use sphereshade::scene::Scene;
use sphereshade::settings::{RenderSettings, ShadowMode, SsdoMode};
use sphereshade::vk::Context;

fn names(times: &[(&'static str, f64)]) -> Vec<&'static str> {
    times.iter().map(|(n, _)| *n).collect()
}

fn turned(cam: &Camera, degrees: f64) -> Camera {
    let q = glam::DQuat::from_axis_angle(cam.up, degrees.to_radians());
    Camera::new(
        cam.center,
        q * cam.dir,
        cam.up,
        cam.view_height,
        cam.fov_deg,
        cam.width,
        cam.height,
    )
    .expect("camera")
}

/// The colour a fresh, uncached renderer gives for these settings.
fn fresh(ctx: &Context, scene: &Scene, s: &RenderSettings) -> Vec<u32> {
    let mut r = Renderer::new(ctx, scene, s.clone()).expect("renderer");
    r.render_frame().expect("frame");
    r.inspect().read_color().expect("colour")
}

#[test]
fn cached_light_structures_give_the_rebuilt_image() {
    let ctx = validated_context();
    let mut scene = load_data("1tii.pdb");
    scene.spheres.truncate(1500);
    for mode in [
        ShadowMode::Issm,
        ShadowMode::IssmSoft,
        ShadowMode::Deep,
        ShadowMode::SmPcf,
        ShadowMode::Osm,
    ] {
        let cam = camera(&scene, 96, 72, None);
        let mut s = settings(cam, mode);
        s.ssdo = SsdoMode::Semantic;
        s.ssdo_knobs.blur = true;
        if mode == ShadowMode::Osm {
            s.opacity = 0.6;
        }
        let mut r = Renderer::new(&ctx, &scene, s.clone()).expect("renderer");
        r.set_light_cache(true);
        let built = names(&r.render_frame().expect("frame 1"));
        assert!(r.inspect().light_cached(), "{mode:?}: cache not kept");

        // The camera turns: the light passes are skipped, the image is
        // exactly the one a renderer that builds everything gives.
        s.camera = turned(&cam, 30.0);
        r.update(|set| set.camera = s.camera).expect("camera");
        let cached = names(&r.render_frame().expect("frame 2"));
        assert!(
            cached.len() < built.len() && cached.iter().all(|n| built.contains(n)),
            "{mode:?}: built {built:?}, cached {cached:?}"
        );
        assert!(cached.contains(&"raster") && cached.contains(&"shade"));
        assert!(
            r.inspect().read_color().expect("colour") == fresh(&ctx, &scene, &s),
            "{mode:?}: cached frame differs from a rebuilt one"
        );

        // A new light invalidates: the next frame rebuilds, and matches.
        s.light = DVec3::new(1.0, -1.0, -0.5);
        r.update(|set| set.light = s.light).expect("light");
        assert!(!r.inspect().light_cached());
        let rebuilt = names(&r.render_frame().expect("frame 3"));
        assert_eq!(rebuilt, built, "{mode:?}");
        assert!(
            r.inspect().read_color().expect("colour") == fresh(&ctx, &scene, &s),
            "{mode:?}: frame after the light moved differs from a fresh one"
        );

        // Turning the cache off rebuilds every frame.
        r.set_light_cache(false);
        assert_eq!(names(&r.render_frame().expect("frame 4")), built);
    }
    assert_no_validation_messages(&ctx);
}
