//! Images for publication (DESIGN.md): tiles, supersampling, backgrounds,
//! 16-bit PNG, OpenEXR layers, outlines and depth cueing. Every render runs
//! under validation through the same library path as `render`
//! (`run::render_run`, `run::render_layers`).

mod common;

use common::*;
use sphereshade::output::AovImage;
use sphereshade::run;
use sphereshade::scene::Scene;
use sphereshade::settings::{
    Aov, Axes, Background, Fog, Options, RenderSettings, ShadowMode, SsdoMode,
};

fn resolve(
    scene: &Scene,
    w: u32,
    h: u32,
    shadows: ShadowMode,
    ssdo: SsdoMode,
    edit: impl Fn(&mut Options),
) -> RenderSettings {
    let mut o = Options::default();
    edit(&mut o);
    let axes = Axes {
        width: w,
        height: h,
        shadows,
        ssdo,
        ..Default::default()
    };
    o.resolve(&axes, scene).expect("options")
}

/// The default modes (ISSM soft shadows, semantic SSDO) at w x h.
fn defaults(scene: &Scene, w: u32, h: u32) -> RenderSettings {
    defaults_with(scene, w, h, |_| {})
}

/// The default modes with options edited.
fn defaults_with(scene: &Scene, w: u32, h: u32, edit: impl Fn(&mut Options)) -> RenderSettings {
    resolve(scene, w, h, ShadowMode::IssmSoft, SsdoMode::Semantic, edit)
}

/// One measured frame, no warm-up.
fn request(aov: Aov) -> run::RunRequest<'static> {
    run::RunRequest {
        input: "test",
        aov,
        warmup: 0,
        frames: 1,
        load_ms: 0.0,
    }
}

fn render(scene: &Scene, settings: RenderSettings, aov: Aov) -> AovImage {
    let ctx = validated_context();
    let out =
        run::render_run(&ctx, scene, settings, &request(aov)).unwrap_or_else(|e| panic!("{e}"));
    assert_no_validation_messages(&ctx);
    out.image.expect("render_run keeps the image")
}

fn rgba(img: &AovImage) -> &image::RgbaImage {
    match img {
        AovImage::Rgba8(i) => i,
        _ => panic!("not RGBA8"),
    }
}

/// A tiled render writes the untiled bytes, in every mode family: the
/// screen-space passes see their neighbours through the tile margin, and
/// rays, noise and patterns use image coordinates. Tiles of 40 px (forced;
/// rounded to 40) on a 256x200 image: 7 x 5 tiles.
#[test]
fn tiled_renders_equal_untiled_bytes() {
    let scene = load_data("1tii.pdb");
    type Edit = fn(&mut Options);
    let cases: [(&str, ShadowMode, SsdoMode, Edit); 10] = [
        ("default", ShadowMode::IssmSoft, SsdoMode::Semantic, |_| {}),
        ("perspective", ShadowMode::Issm, SsdoMode::Plain, |o| {
            o.fov = Some(35.0)
        }),
        ("sm-pcf noise", ShadowMode::SmPcf, SsdoMode::Plain, |_| {}),
        (
            "screen shadows",
            ShadowMode::None,
            SsdoMode::Semantic,
            |_| {},
        ),
        ("deep", ShadowMode::Deep, SsdoMode::Off, |_| {}),
        ("osm", ShadowMode::Osm, SsdoMode::Off, |_| {}),
        (
            "outline + fog",
            ShadowMode::IssmSoft,
            SsdoMode::Semantic,
            |o| {
                o.look.outline = 2.0;
                o.look.fog = Some(Fog([-10.0, 25.0]));
            },
        ),
        (
            // spheres ~19 px in radius: SSDO per 2x2 block
            "close-up ssaa 2 transparent",
            ShadowMode::IssmSoft,
            SsdoMode::Semantic,
            |o| {
                o.view_height = Some(18.0);
                o.ssaa = 2;
                o.look.background = Background::Transparent;
            },
        ),
        (
            // spheres ~2 px in radius: SSDO per visible sphere
            "far view",
            ShadowMode::IssmSoft,
            SsdoMode::Semantic,
            |o| o.view_height = Some(170.0),
        ),
        (
            "far view perspective screen shadows",
            ShadowMode::None,
            SsdoMode::Plain,
            |o| {
                o.view_height = Some(170.0);
                o.fov = Some(35.0);
            },
        ),
    ];
    for (name, shadows, ssdo, edit) in cases {
        let whole = resolve(&scene, 256, 200, shadows, ssdo, edit);
        let mut tiled = whole.clone();
        tiled.tile_size = Some(40);
        let a = render(&scene, whole, Aov::Color);
        let b = render(&scene, tiled, Aov::Color);
        if a.sha256() != b.sha256() {
            let (a, b) = (rgba(&a), rgba(&b));
            let diff = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
            panic!("{name}: tiled differs from untiled on {diff} pixels");
        }
        // and the other AOVs (two mode families: validation is slow), and
        // the close-up's per-block SSDO
        let aovs: &[Aov] = match name {
            "default" | "perspective" => &[Aov::Id, Aov::Depth, Aov::Ao],
            "close-up ssaa 2 transparent" | "far view" => &[Aov::Ao],
            _ => &[],
        };
        for &aov in aovs {
            let whole = resolve(&scene, 256, 200, shadows, ssdo, edit);
            let mut tiled = whole.clone();
            tiled.tile_size = Some(40);
            assert_eq!(
                render(&scene, whole, aov).sha256(),
                render(&scene, tiled, aov).sha256(),
                "{name}: {aov:?}"
            );
        }
    }
}

/// The failure side of the margin: without it (a renderer's raw window of
/// the image, no neighbours beyond the tile) SSDO differs near the tile's
/// edge, so the test above can fail.
#[test]
fn a_window_without_margin_differs() {
    let ctx = validated_context();
    let scene = load_data("1tii.pdb");
    let whole = defaults(&scene, 256, 200);
    let mut r = sphereshade::render::Renderer::new(&ctx, &scene, whole).unwrap();
    r.render_frame().unwrap();
    let full = r.inspect().read_color().unwrap();
    let win = sphereshade::camera::Window {
        x: 96,
        y: 64,
        width: 64,
        height: 64,
    };
    r.update(|set| set.window = Some(win)).unwrap();
    r.render_frame().unwrap();
    let part = r.inspect().read_color().unwrap();
    drop(r);
    assert_no_validation_messages(&ctx);
    let mut diff = 0;
    for y in 0..64 {
        for x in 0..64 {
            diff += (part[y * 64 + x] != full[(64 + y) * 256 + 96 + x]) as usize;
        }
    }
    assert!(
        diff > 50,
        "only {diff} of 4096 pixels differ without a margin"
    );
}

/// Random spheres, 4 x 4 supersampling, transparent background: on edge
/// pixels alpha follows the coverage of an 8 x 8 exact ray cast of the
/// pixel (an independent, denser grid). Tolerance: mean |alpha - coverage|
/// <= 0.05 and 95 % of edge pixels within 0.15 (4 x 4 samples estimate a
/// coverage to about 1/16; rounding to 8 bits adds 1/510). One sample per
/// pixel (alpha 0 or 1) must fail it.
#[test]
fn supersampled_alpha_follows_exact_coverage() {
    let scene = sphereshade::scene::procedural("random", 400, 7).unwrap();
    let (w, h) = (120, 90);
    let errors = |ssaa: u32| -> (f64, f64, usize) {
        let s = resolve(&scene, w, h, ShadowMode::None, SsdoMode::Off, |o| {
            o.ssaa = ssaa;
            o.look.background = Background::Transparent;
        });
        let reference_cam = {
            let mut c = s.camera;
            c.width *= 8;
            c.height *= 8;
            c
        };
        let img = render(&scene, s, Aov::Color);
        let img = rgba(&img).clone();
        let refi = sphereshade::reference::cast(&scene.spheres, &reference_cam, 0.0);
        let mut errs = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let mut hits = 0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        let k = ((y * 8 + sy) * w * 8 + x * 8 + sx) as usize;
                        hits += (refi.ids[k] != u32::MAX) as u32;
                    }
                }
                if hits == 0 || hits == 64 {
                    continue;
                }
                let cov = hits as f64 / 64.0;
                let alpha = img.get_pixel(x, y).0[3] as f64 / 255.0;
                errs.push((alpha - cov).abs());
            }
        }
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        errs.sort_by(f64::total_cmp);
        (mean, errs[errs.len() * 95 / 100], errs.len())
    };
    let (mean4, p95_4, n) = errors(4);
    eprintln!(
        "ssaa 4: {n} edge pixels, mean |alpha - coverage| {mean4:.4}, 95th percentile {p95_4:.3}"
    );
    assert!(n > 500, "{n} edge pixels");
    assert!(
        mean4 <= 0.05 && p95_4 <= 0.15,
        "ssaa 4: mean {mean4:.4}, p95 {p95_4:.3}"
    );
    let (mean1, p95_1, _) = errors(1);
    eprintln!("ssaa 1: mean {mean1:.4}, 95th percentile {p95_1:.3}");
    assert!(
        mean1 > 0.05 || p95_1 > 0.15,
        "one sample per pixel passed: {mean1:.4} {p95_1:.3}"
    );
}

/// Without supersampling, a transparent background has alpha exactly 0 and
/// black colour on every background pixel and 255 on every covered one.
#[test]
fn transparent_background_alpha_is_exact() {
    let scene = load_data("1tii.pdb");
    let s = defaults_with(&scene, 200, 150, |o| {
        o.look.background = Background::Transparent;
    });
    let img = render(&scene, s.clone(), Aov::Color);
    let ids = render(&scene, s, Aov::Id);
    let (img, ids) = (rgba(&img), rgba(&ids));
    let (mut bg, mut fg) = (0, 0);
    for (p, id) in img.pixels().zip(ids.pixels()) {
        let covered = id.0[..3] != [0, 0, 0];
        if covered {
            assert_eq!(p.0[3], 255);
            fg += 1;
        } else {
            assert_eq!(p.0, [0, 0, 0, 0]);
            bg += 1;
        }
    }
    assert!(bg > 1000 && fg > 1000, "{bg} background, {fg} covered");
}

/// A flat background colour is written exactly; fog whose far distance is
/// in front of every sphere turns every covered pixel into it.
#[test]
fn background_colour_and_fog() {
    let scene = load_data("1tii.pdb");
    let s = defaults_with(&scene, 160, 120, |o| {
        o.look.background = Background::Color([10, 200, 30]);
    });
    let plain = render(&scene, s.clone(), Aov::Color);
    let ids = render(&scene, s, Aov::Id);
    let mut bg = 0;
    for (p, id) in rgba(&plain).pixels().zip(rgba(&ids).pixels()) {
        if id.0[..3] == [0, 0, 0] {
            assert_eq!(p.0, [10, 200, 30, 255]);
            bg += 1;
        }
    }
    assert!(bg > 1000);
    let fogged = defaults_with(&scene, 160, 120, |o| {
        o.look.background = Background::Color([10, 200, 30]);
        o.look.fog = Some(Fog([-1e6, -1e5]));
    });
    let fogged = render(&scene, fogged, Aov::Color);
    for p in rgba(&fogged).pixels() {
        let d: i32 = p.0[..3]
            .iter()
            .zip([10, 200, 30])
            .map(|(&a, b)| (a as i32 - b).abs())
            .max()
            .unwrap();
        assert!(d <= 1, "{:?}", p.0);
    }
    // and fog between the front and the back darkens nothing toward black:
    // the far half of the molecule moves toward the background
    let half = defaults_with(&scene, 160, 120, |o| {
        o.look.background = Background::Color([255, 255, 255]);
        o.look.fog = Some(Fog([-5.0, 30.0]));
    });
    let half = render(&scene, half, Aov::Color);
    let plain_l: f64 = rgba(&plain).pixels().map(|p| p.0[1] as f64).sum();
    let half_l: f64 = rgba(&half).pixels().map(|p| p.0[1] as f64).sum();
    assert!(
        half_l > plain_l,
        "fog toward white did not brighten the image"
    );
}

/// Outlines: on two overlapping spheres far apart in depth (a step of more
/// than a sphere radius is an edge), the far sphere's pixels next to the
/// near one's silhouette and the background pixels next to any
/// silhouette turn black, W pixels wide; the spheres' insides do not.
#[test]
fn outlines_follow_silhouettes() {
    let scene = scene_of(
        vec![sphere([0.0, 0.0, 0.0], 3.0), sphere([2.5, 0.0, -10.0], 3.0)],
        "two",
    );
    let s = |w: f32| {
        resolve(
            &scene,
            160,
            120,
            ShadowMode::None,
            SsdoMode::Off,
            move |o| {
                o.look.outline = w;
                o.view_height = Some(12.0);
                o.look.background = Background::Color([255, 255, 255]);
            },
        )
    };
    let ids = render(&scene, s(0.0), Aov::Id);
    let ids = rgba(&ids);
    let id_at = |x: u32, y: u32| ids.get_pixel(x, y).0[0];
    for w in [1.0, 3.0] {
        let img = render(&scene, s(w), Aov::Color);
        let img = rgba(&img);
        let black = |x: u32, y: u32| img.get_pixel(x, y).0[..3] == [0, 0, 0];
        let mut lines = 0;
        for y in 0..120 {
            for x in 0..160 {
                // distance (cross/diagonal steps) to a pixel of a nearer surface
                let me = id_at(x, y);
                let mut near = false;
                for k in 1..=(w as i32) {
                    for (dx, dy) in [(k, 0), (-k, 0), (0, k), (0, -k)] {
                        let (qx, qy) = (x as i32 + dx, y as i32 + dy);
                        if qx < 0 || qy < 0 || qx >= 160 || qy >= 120 {
                            continue;
                        }
                        let q = id_at(qx as u32, qy as u32);
                        // id 1 is the near sphere, 2 the far one, 0 background
                        near |= q != 0 && (me == 0 || (q == 1 && me == 2));
                    }
                }
                if near {
                    assert!(
                        black(x, y),
                        "w {w}: ({x}, {y}) next to a nearer surface is not black"
                    );
                    lines += 1;
                }
                // inside a sphere, far from any edge: never a line
                let far_from_edge = (-(w as i32) - 1..=w as i32 + 1).all(|d| {
                    let (qx, qy) = (
                        (x as i32 + d).clamp(0, 159) as u32,
                        (y as i32 + d).clamp(0, 119) as u32,
                    );
                    id_at(qx, y) == me && id_at(x, qy) == me
                });
                if me != 0 && far_from_edge && !near {
                    assert!(!black(x, y), "w {w}: ({x}, {y}) inside a sphere is black");
                }
            }
        }
        assert!(lines > 100, "w {w}: {lines} line pixels");
    }
}

/// The colour PNG at 16 bits: the same image as the 8-bit one to within
/// the 8-bit rounding (and finer: values between the 8-bit steps occur).
#[test]
fn sixteen_bit_colour_matches_eight_bit() {
    let scene = load_data("1tii.pdb");
    let s8 = defaults(&scene, 160, 120);
    let mut s16 = s8.clone();
    s16.look.color16 = true;
    let a = render(&scene, s8, Aov::Color);
    let b = render(&scene, s16, Aov::Color);
    let AovImage::Rgba16(b) = b else {
        panic!("not RGBA16")
    };
    let mut between = 0;
    for (p, q) in rgba(&a).pixels().zip(b.pixels()) {
        for k in 0..4 {
            let v = q.0[k] as f64 / 257.0;
            assert!((v - p.0[k] as f64).abs() <= 0.51, "{:?} vs {:?}", p.0, q.0);
            between += (q.0[k] % 257 != 0) as usize;
        }
    }
    assert!(between > 1000, "{between} values between the 8-bit steps");
}

/// The OpenEXR layers read back (the `exr` crate) equal the PNG AOVs: id
/// exactly, shadow and ao to the 8-bit rounding, colour after encoding,
/// depth after the PNG's normalisation; normals are unit on covered pixels.
#[test]
fn exr_layers_equal_the_png_aovs() {
    use exr::prelude::*;
    let scene = load_data("1tii.pdb");
    let s = defaults(&scene, 160, 120);
    let ctx = validated_context();
    let (layers, _) = run::render_layers(&ctx, &scene, "test", s.clone(), 0.0).unwrap();
    assert_no_validation_messages(&ctx);
    let path = out_dir().join("layers.exr");
    sphereshade::output::write_exr(&path, 160, 120, layers).unwrap();
    let img = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(&path)
        .unwrap();
    let layer = &img.layer_data[0];
    let ch = |name: &str| -> Vec<f32> {
        layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .unwrap_or_else(|| panic!("no channel {name}"))
            .sample_data
            .values_as_f32()
            .collect()
    };
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for n in [
        "R", "G", "B", "A", "depth", "id", "shadow", "ao", "normal.X", "normal.Y", "normal.Z",
    ] {
        assert!(names.iter().any(|x| x == n), "{n} missing from {names:?}");
    }
    let id_png = render(&scene, s.clone(), Aov::Id);
    let id_png = rgba(&id_png);
    let id = ch("id");
    for (i, p) in id_png.pixels().enumerate() {
        let v = p.0[0] as u32 | (p.0[1] as u32) << 8 | (p.0[2] as u32) << 16;
        assert_eq!(id[i] as u32, v, "id at {i}");
    }
    for (aov, name) in [(Aov::Shadow, "shadow"), (Aov::Ao, "ao")] {
        let AovImage::Gray8(png) = render(&scene, s.clone(), aov) else {
            panic!("not gray8")
        };
        for (i, (p, v)) in png.pixels().zip(ch(name)).enumerate() {
            assert!(
                (p.0[0] as f32 - v * 255.0).abs() <= 0.51,
                "{name} at {i}: {} vs {v}",
                p.0[0]
            );
        }
    }
    let color = render(&scene, s.clone(), Aov::Color);
    let (r, a) = (ch("R"), ch("A"));
    for (i, p) in rgba(&color).pixels().enumerate() {
        let enc = r[i].powf(1.0 / 2.2) * 255.0;
        assert!(
            (enc - p.0[0] as f32).abs() <= 0.6,
            "R at {i}: {enc} vs {}",
            p.0[0]
        );
        assert_eq!(a[i], 1.0);
    }
    let AovImage::Gray16(dpng) = render(&scene, s, Aov::Depth) else {
        panic!("not gray16")
    };
    let depth = ch("depth");
    let finite: Vec<f32> = depth.iter().copied().filter(|d| d.is_finite()).collect();
    let (lo, hi) = finite
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &d| (a.min(d), b.max(d)));
    let (nx, ny, nz) = (ch("normal.X"), ch("normal.Y"), ch("normal.Z"));
    for (i, p) in dpng.pixels().enumerate() {
        if p.0[0] == 65535 {
            assert!(depth[i].is_infinite() && id[i] == 0.0);
            continue;
        }
        let v = (depth[i] - lo) / (hi - lo) * 65534.0;
        assert!(
            (v - p.0[0] as f32).abs() <= 2.0,
            "depth at {i}: {v} vs {}",
            p.0[0]
        );
        let len = (nx[i] * nx[i] + ny[i] * ny[i] + nz[i] * nz[i]).sqrt();
        assert!((len - 1.0).abs() < 1e-4, "normal at {i}");
    }
}

/// Supersampling keeps the look: the screen-space passes work in output
/// pixels, so 2 x 2 samples give the 1-sample image's shading away from
/// silhouettes (mean grey level within 2 and mean |difference| under 6 on
/// pixels whose 5x5 neighbourhood shows one sphere, spheres ~10 px wide);
/// without the
/// scaling (radii and blur in buffer pixels) the AO radius would halve.
#[test]
fn supersampling_keeps_the_look() {
    let scene = load_data("pdb3p3w.pdb");
    let s1 = defaults_with(&scene, 200, 150, |o| o.view_height = Some(40.0));
    let mut s2 = s1.clone();
    s2.ssaa = 2;
    let a = render(&scene, s1.clone(), Aov::Color);
    let b = render(&scene, s2, Aov::Color);
    let ids = render(&scene, s1, Aov::Id);
    let (a, b, ids) = (rgba(&a), rgba(&b), rgba(&ids));
    let (mut da, mut sa, mut sb, mut n) = (0.0, 0.0, 0.0, 0.0);
    for y in 2..148 {
        for x in 2..198 {
            let me = ids.get_pixel(x, y).0;
            if me[..3] == [0, 0, 0] {
                continue;
            }
            let flat = (0..25).all(|k| ids.get_pixel(x + k % 5 - 2, y + k / 5 - 2).0 == me);
            if !flat {
                continue;
            }
            let l = |p: &image::Rgba<u8>| sphereshade::tachyon::luma([p.0[0], p.0[1], p.0[2]]);
            let (la, lb) = (l(a.get_pixel(x, y)), l(b.get_pixel(x, y)));
            da += (la - lb).abs();
            sa += la;
            sb += lb;
            n += 1.0;
        }
    }
    let (mean_a, mean_b, mad) = (sa / n, sb / n, da / n);
    eprintln!("{n} px: mean grey {mean_a:.1} (1x1) vs {mean_b:.1} (2x2), mean |diff| {mad:.2}");
    assert!(n > 1000.0);
    assert!(
        (mean_a - mean_b).abs() <= 2.0 && mad < 6.0,
        "{mean_a:.1} {mean_b:.1} {mad:.2}"
    );
}

/// 7680x4320 does not fit lavapipe's 128 MiB buffers (8 B/px visibility):
/// it renders in tiles, and the ids at 2,000 spread pixels equal the exact
/// f64 ray cast's (outside its ambiguous grazing/tie cases). 3840x2160 with
/// --ssaa 4 renders its 16 samples. (Shadows and SSDO off: the tiling of
/// the screen-space passes is checked above at small sizes; validation
/// makes every pass several times slower.)
#[test]
fn eight_k_in_tiles_and_4k_with_ssaa_4() {
    let scene = load_data("1tii.pdb");
    let ctx = validated_context();
    let s = resolve(&scene, 7680, 4320, ShadowMode::None, SsdoMode::Off, |_| {});
    let cam = s.camera;
    assert!(
        (cam.width as u64 * cam.height as u64)
            > sphereshade::render::tiles::max_window_pixels(&ctx),
        "8K fits one window here: the test would not tile"
    );
    let mut r = sphereshade::render::Renderer::new_windowed(&ctx, &scene, s, None).unwrap();
    let (img, _) = r.render_image(None).unwrap();
    drop(r);
    assert!(img.tiles > 1, "{} tiles", img.tiles);
    let (mut checked, mut ambiguous) = (0, 0);
    for k in 0..2000u64 {
        let i = (k * 16_588_777) % (7680 * 4320);
        let (x, y) = ((i % 7680) as u32, (i / 7680) as u32);
        let (o, d) = cam.ray(x, y);
        let mut hits: Vec<(f64, u32)> = scene
            .spheres
            .iter()
            .enumerate()
            .filter_map(|(j, sp)| {
                let c = glam::DVec3::new(
                    sp.center[0] as f64,
                    sp.center[1] as f64,
                    sp.center[2] as f64,
                );
                sphereshade::reference::ray_sphere(o, d, c, sp.radius as f64)
                    .map(|(t, _)| (t, j as u32))
            })
            .collect();
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        let key = img.vis[i as usize];
        let got = (key != sphereshade::gpu::VIS_EMPTY).then_some((key & 0xFFFF_FFFF) as u32);
        let want = hits.first().map(|h| h.1);
        if got != want {
            // a tie in depth or a grazing ray: f32 may pick the other
            let tie = hits.len() > 1 && hits[1].0 - hits[0].0 < 1e-3;
            let graze = hits.first().is_none_or(|h| {
                let sp = &scene.spheres[h.1 as usize];
                let c = glam::DVec3::new(
                    sp.center[0] as f64,
                    sp.center[1] as f64,
                    sp.center[2] as f64,
                );
                let q = (o - c) - (o - c).dot(d) * d;
                (sp.radius as f64).powi(2) - q.length_squared() < 1e-2
            });
            assert!(tie || graze, "pixel ({x}, {y}): {got:?} vs exact {want:?}");
            ambiguous += 1;
        }
        checked += 1;
    }
    eprintln!(
        "8K: {} tiles, {checked} pixels checked, {ambiguous} ambiguous",
        img.tiles
    );
    let s = resolve(&scene, 3840, 2160, ShadowMode::None, SsdoMode::Off, |o| {
        o.ssaa = 4;
        o.look.background = Background::Transparent;
    });
    let out = run::render_run(&ctx, &scene, s, &request(Aov::Color)).unwrap();
    assert_no_validation_messages(&ctx);
    let img = rgba(out.image.as_ref().expect("image"));
    assert_eq!(img.dimensions(), (3840, 2160));
    // silhouette pixels carry partial coverage: alpha k/16 for every k
    let mut levels = std::collections::BTreeSet::new();
    let mut partial = 0;
    for p in img.pixels() {
        let a = p.0[3];
        if a != 0 && a != 255 {
            partial += 1;
            levels.insert(((a as f64 / 255.0) * 16.0).round() as u32);
        }
    }
    eprintln!(
        "4K ssaa 4: {partial} partly covered pixels, {} alpha levels",
        levels.len()
    );
    assert!(
        partial > 5_000 && levels.len() == 15,
        "{partial} px, levels {levels:?}"
    );
}

/// `--shadow-diffuse` (a knob of src/gpu_blocks.rs) reaches the shader:
/// keeping all of the key's diffuse term in shadow brightens exactly the
/// shadowed pixels; without shadows it changes nothing.
#[test]
fn shadow_diffuse_knob_reaches_shade() {
    let scene = load_data("1tii.pdb");
    let shot = |diffuse: f32, shadows: ShadowMode| {
        let s = resolve(&scene, 160, 120, shadows, SsdoMode::Off, |o| {
            o.look.knobs.shadow_diffuse = diffuse
        });
        rgba(&render(&scene, s, Aov::Color)).clone()
    };
    let (dark, lit) = (shot(0.05, ShadowMode::Issm), shot(1.0, ShadowMode::Issm));
    let sum = |img: &image::RgbaImage| -> u64 {
        img.pixels()
            .map(|p| p.0[0] as u64 + p.0[1] as u64 + p.0[2] as u64)
            .sum()
    };
    let changed = dark
        .pixels()
        .zip(lit.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 100, "only {changed} pixels changed");
    assert!(
        sum(&lit) > sum(&dark),
        "more diffuse light in shadow is brighter"
    );
    assert_eq!(shot(0.05, ShadowMode::None), shot(1.0, ShadowMode::None));
}
