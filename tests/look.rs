//! The look against a ray tracer (issue "Images people publish"): real
//! structures as white `.xyzr` spheres at 640x480 with sphereshade's
//! default modes (ISSM soft shadows + semantic SSDO + blur), against
//! Debian's `tachyon` on the same camera with the same directional key
//! light, hard shadows and a 64-sample sky-light ambient occlusion. Over
//! the pixels both cover:
//! - the luminance rank correlation (Spearman) must be >= 0.93: the same
//!   places are light and dark;
//! - the luminance spread (standard deviation of the grey level, 0..255)
//!   must be >= 0.9 x Tachyon's: shadows and occlusion read as clearly.
//!
//! (The goals were 0.9 and 0.6x; the composite with the sky light
//! going as ao³ measures 0.964 / 0.943 and 0.97x / 0.97x on 1TII / 3P3W,
//! the one before it 0.953 / 0.936 and 0.68x / 0.69x.)
//!
//! A side-by-side image (ours left) is written to
//! target/test-output/look-NAME.png; tools/look-vs-tachyon.sh does the same
//! for any file.

mod common;

use common::*;
use sphereshade::settings::{Axes, Options};
use sphereshade::tachyon;

fn check(name: &str) {
    let ctx = validated_context();
    let scene = tachyon::white_spheres(&load_data(name));
    let axes = Axes {
        width: 640,
        height: 480,
        ..Default::default()
    };
    let settings = Options::default().resolve(&axes, &scene).expect("defaults");
    let dir = out_dir();
    let (l, side) = tachyon::compare_look(&ctx, &scene, settings, &dir, &format!("look-{name}"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_no_validation_messages(&ctx);
    side.save(dir.join(format!("look-{name}.png"))).unwrap();
    eprintln!("{name}: {l}");
    assert!(l.pixels > 20_000, "{name}: {} covered pixels", l.pixels);
    assert!(
        l.rho >= 0.93,
        "{name}: rank correlation {:.3} < 0.93",
        l.rho
    );
    assert!(
        l.ours_sd >= 0.9 * l.ref_sd,
        "{name}: luminance spread {:.1} < 0.9 x Tachyon's {:.1}",
        l.ours_sd,
        l.ref_sd
    );
}

#[test]
fn looks_like_a_ray_tracer_1tii() {
    check("1tii.pdb");
}

#[test]
fn looks_like_a_ray_tracer_3p3w() {
    check("pdb3p3w.pdb");
}

/// The failure side: the composite this replaced (ambient 0.5 + fill,
/// key keeping 12 % in shadow, `1 - exp(-1.5c)`, gamma), applied on the
/// CPU to the same frame's shadow and ao AOVs, fails the spread goal
/// against the same Tachyon render.
#[test]
fn the_old_flat_look_fails_the_goal() {
    let ctx = validated_context();
    let scene = tachyon::white_spheres(&load_data("1tii.pdb"));
    let axes = Axes {
        width: 320,
        height: 240,
        ..Default::default()
    };
    let mut settings = Options::default().resolve(&axes, &scene).expect("defaults");
    let (now, _) = tachyon::compare_look(&ctx, &scene, settings.clone(), &out_dir(), "look-old")
        .unwrap_or_else(|e| panic!("{e}"));
    settings.aovs = true;
    let cam = settings.camera;
    let l_key = -settings.light.normalize();
    let mut r = sphereshade::render::Renderer::new(&ctx, &scene, settings).unwrap();
    r.render_frame().unwrap();
    let gpos = r.inspect().read_gpos().unwrap();
    let vis = r.inspect().read_vis().unwrap();
    let shadow = r.inspect().read_shadow().unwrap();
    let ao = r.inspect().read_ambient().unwrap();
    drop(r);
    assert_no_validation_messages(&ctx);
    let mut old = Vec::new();
    for i in 0..vis.len() {
        if vis[i] == sphereshade::gpu::VIS_EMPTY {
            continue;
        }
        let c = scene.spheres[(vis[i] & 0xFFFF_FFFF) as usize].center;
        let p = glam::DVec3::new(gpos[i][0] as f64, gpos[i][1] as f64, gpos[i][2] as f64);
        let n = (p - glam::DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64)).normalize();
        let nk = n.dot(l_key).max(0.0);
        let key = nk * (0.12 + 0.88 * shadow[i] as f64);
        let c = 0.85 * key + 0.5 * ao[i][0] as f64 + 0.14 * n.dot(-cam.dir).max(0.0);
        let v = (1.0 - (-1.5 * c).exp()).powf(1.0 / 2.2) * 255.0;
        old.push(v);
    }
    let m = old.iter().sum::<f64>() / old.len() as f64;
    let sd = (old.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / old.len() as f64).sqrt();
    eprintln!("old composite: spread {sd:.1}; now: {now}");
    assert!(now.ours_sd >= 0.6 * now.ref_sd, "{now}");
    assert!(
        sd < 0.6 * now.ref_sd,
        "the old composite's spread {sd:.1} vs Tachyon's {:.1}",
        now.ref_sd
    );
}
