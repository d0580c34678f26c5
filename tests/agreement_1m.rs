//! Measurement, not a regular test (ignored: minutes on lavapipe): hard-mask
//! agreement of every shadow technique with exact CPU shadow rays on a
//! 1M-sphere capsid at 256x200. Run with
//! `cargo test --release --test agreement_1m -- --ignored --nocapture`.

mod common;

use common::*;
use sphereshade::output::ids_from_vis;
use sphereshade::reference;
use sphereshade::render::Renderer;
use sphereshade::scene;
use sphereshade::settings::ShadowMode;

#[test]
#[ignore]
fn agreement_of_every_technique_at_one_million_spheres() {
    let ctx = validated_context();
    let s = scene::procedural("capsid", 1_000_000, 1).expect("scene");
    let cam = camera(&s, 256, 200, None);
    let light = settings(cam, ShadowMode::None).light;
    let (refs, img) = reference::shadow_image(&s.spheres, &cam, light, 1.0);
    for (mode, t) in [
        (ShadowMode::Issm, Some(1)),
        (ShadowMode::Issm, None),
        (ShadowMode::IssmSoft, Some(1)),
        (ShadowMode::IssmSoft, None),
        (ShadowMode::Deep, None),
        (ShadowMode::SmPcf, None),
        (ShadowMode::Osm, None),
    ] {
        let mut st = settings(cam, mode);
        st.issm.t = sphereshade::settings::IssmT(t);
        let mut r = Renderer::new(&ctx, &s, st).expect("renderer");
        r.render_frame().expect("frame");
        let ids = ids_from_vis(&r.inspect().read_vis().expect("vis"));
        let shadow = r.inspect().read_shadow().expect("shadow");
        let (mut n, mut agree) = (0usize, 0usize);
        for i in 0..ids.len() {
            let Some(rv) = refs[i] else { continue };
            if ids[i] != Some(img.ids[i]) {
                continue;
            }
            n += 1;
            agree += ((shadow[i] < 0.5) == (rv < 0.5)) as usize;
        }
        eprintln!(
            "1M capsid {:<10} t {:<4} hard-mask agreement {:.3}% of {n} pixels",
            mode.name(),
            t.map_or("auto".to_string(), |t| t.to_string()),
            100.0 * agree as f64 / n as f64
        );
        assert!(n > 10_000);
    }
    assert_no_validation_messages(&ctx);
}
