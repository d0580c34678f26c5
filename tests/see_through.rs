//! See-through spheres under GPU-assisted + synchronization validation: the
//! composited colour of overlapping translucent spheres against a CPU
//! reference that sorts every ray-sphere intersection of the pixel's ray
//! (f64), each sphere's colour taken from its own opaque render; the id AOV
//! keeps the nearest opaque sphere; the fragment pool's overflow path
//! (forced 1-fragment pool: detected, grown, same image, guards intact).

mod common;

use common::*;
use sphereshade::camera::Camera;
use sphereshade::output::ids_from_vis;
use sphereshade::reference::ray_sphere;
use sphereshade::render::Renderer;
use sphereshade::scene::{Scene, Sphere};
use sphereshade::settings::{Background, RenderSettings, ShadowMode};
use sphereshade::vk::Context;

const W: u32 = 128;
const H: u32 = 96;

fn ball(c: [f32; 3], r: f32, rgb: [u8; 3], alpha: u8) -> Sphere {
    Sphere {
        center: c,
        radius: r,
        color: [rgb[0], rgb[1], rgb[2], alpha],
        region: [0; 4],
    }
}

/// Four translucent spheres overlapping in front of an opaque one, which
/// covers only part of the frame (the rest composites over nothing).
fn stack() -> Vec<Sphere> {
    vec![
        ball([0.0, 0.0, 0.0], 1.0, [230, 40, 40], 128),
        ball([0.6, 0.2, -0.8], 0.9, [40, 220, 60], 90),
        ball([-0.4, -0.3, -1.6], 1.1, [50, 80, 240], 200),
        ball([-0.5, 0.5, 0.9], 0.7, [240, 220, 30], 60),
        ball([0.9, 0.6, -3.0], 1.2, [200, 200, 200], 255),
    ]
}

fn flat(cam: Camera) -> RenderSettings {
    let mut s = settings(cam, ShadowMode::None);
    s.look.background = Background::Transparent;
    s.look.color16 = true;
    s
}

fn rgba16(words: &[u32]) -> Vec<[f64; 4]> {
    let u = |w: u32| (w & 0xFFFF) as f64 / 65535.0;
    words
        .chunks(2)
        .map(|w| [u(w[0]), u(w[0] >> 16), u(w[1]), u(w[1] >> 16)])
        .collect()
}

struct Frame {
    color: Vec<[f64; 4]>,
    ids: Vec<Option<u32>>,
    stats: Option<sphereshade::stages::see_through::SeeThroughStats>,
}

fn render(ctx: &Context, scene: &Scene, s: RenderSettings) -> Frame {
    let mut r = Renderer::new(ctx, scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let i = r.inspect();
    if let Some(st) = i.see_through() {
        let bad = st.damaged_guards(ctx).expect("guards");
        assert!(bad.is_empty(), "guard words overwritten in {bad:?}");
    }
    Frame {
        color: rgba16(&i.read_color().expect("colour")),
        ids: ids_from_vis(&i.read_vis().expect("vis")),
        stats: i.see_through_stats(),
    }
}

/// Every sphere the ray of pixel (px, py) hits, as (front hit distance,
/// sphere), nearest first (f64); None where f32 rounding may decide: a
/// ray grazing a silhouette, or two front hits within 1e-4.
fn sorted_hits(spheres: &[Sphere], cam: &Camera, px: u32, py: u32) -> Option<Vec<(f64, usize)>> {
    let (o, d) = cam.ray(px, py);
    let mut hits = Vec::new();
    for (i, s) in spheres.iter().enumerate() {
        let c = glam::DVec3::new(s.center[0] as f64, s.center[1] as f64, s.center[2] as f64);
        let r = s.radius as f64;
        let oc = o - c;
        let q = oc - oc.dot(d) * d;
        if (r * r - q.length_squared()).abs() <= 2e-2 * r {
            return None;
        }
        if let Some((t, _)) = ray_sphere(o, d, c, r) {
            hits.push((t, i));
        }
    }
    hits.sort_by(|a, b| a.0.total_cmp(&b.0));
    if hits.windows(2).any(|w| w[1].0 - w[0].0 < 1e-4) {
        return None;
    }
    Some(hits)
}

/// Twelve faint translucent spheres one behind the other in front of an
/// opaque one: more layers than one of shade's selection scans keeps (8).
fn deep_stack() -> Vec<Sphere> {
    let mut v: Vec<Sphere> = (0..12)
        .map(|k| {
            let f = k as f32;
            let rgb = [
                (40 + 17 * k) as u8,
                (230 - 15 * k) as u8,
                (60 + 13 * k) as u8,
            ];
            ball([0.07 * f - 0.4, 0.05 * f - 0.3, -0.45 * f], 1.0, rgb, 40)
        })
        .collect();
    v.push(ball([0.3, 0.2, -6.5], 1.3, [200, 200, 200], 255));
    v
}

/// Checks one camera on `spheres`, with at least 20 pixels behind
/// `layers` translucent spheres; returns the pixels compared.
fn composite_matches(
    ctx: &Context,
    name: &str,
    fov: Option<f64>,
    spheres: Vec<Sphere>,
    layers_seen: usize,
) -> usize {
    let scene = scene_of(spheres.clone(), name);
    let cam = camera(&scene, W, H, fov);
    let all = render(ctx, &scene, flat(cam));
    let st = all.stats.expect("see-through stats");
    assert!(st.fragments > 0 && st.max_per_pixel >= 3, "{name}: {st:?}");
    // each sphere alone and opaque: its display colour at every pixel
    let alone: Vec<Vec<[f64; 4]>> = spheres
        .iter()
        .map(|s| {
            let mut one = *s;
            one.color[3] = 255;
            let f = render(ctx, &scene_of(vec![one], name), flat(cam));
            assert!(f.stats.is_none(), "an opaque sphere made fragments");
            f.color
        })
        .collect();
    let (mut compared, mut worst, mut deep) = (0, 0.0f64, 0);
    let mut diff = image::RgbaImage::new(W, H);
    for py in 0..H {
        for px in 0..W {
            let k = (py * W + px) as usize;
            let Some(hits) = sorted_hits(&spheres, &cam, px, py) else {
                continue;
            };
            // front to back until the first opaque sphere, which is the base
            let (mut acc, mut acc_a, mut t) = ([0.0f64; 3], 0.0, 1.0);
            let mut base = [0.0f64; 4];
            let mut layers = 0;
            for &(_, i) in &hits {
                let c = alone[i][k];
                assert!(
                    c[3] > 0.999,
                    "{name}: sphere {i} alone misses pixel {px},{py}"
                );
                let a = spheres[i].color[3] as f64 / 255.0;
                if spheres[i].color[3] == 255 {
                    base = c;
                    break;
                }
                layers += 1;
                let w = t * a;
                (0..3).for_each(|j| acc[j] += w * c[j]);
                acc_a += w;
                t -= w;
            }
            let out_a = acc_a + t * base[3];
            let want: Vec<f64> = (0..3)
                .map(|j| (acc[j] + t * base[3] * base[j]) / out_a.max(1e-30))
                .chain([out_a])
                .collect();
            let got = all.color[k];
            let e = if out_a < 0.05 {
                (got[3] - out_a).abs()
            } else {
                (0..4).map(|j| (got[j] - want[j]).abs()).fold(0.0, f64::max)
            };
            worst = worst.max(e);
            compared += 1;
            if layers >= layers_seen {
                deep += 1;
            }
            let v = (e * 255.0 * 64.0).min(255.0) as u8;
            diff.put_pixel(px, py, image::Rgba([v, 0, 0, 255]));
            // the id AOV keeps the nearest opaque sphere (or none)
            let opaque = hits
                .iter()
                .find(|h| spheres[h.1].color[3] == 255)
                .map(|h| h.1 as u32);
            assert_eq!(all.ids[k], opaque, "{name}: id at {px},{py}");
        }
    }
    if worst > 1.0 / 255.0 {
        let p = out_dir().join(format!("{name}-diff.png"));
        diff.save(&p).unwrap();
        panic!(
            "{name}: worst difference {:.2}/255 (see {})",
            worst * 255.0,
            p.display()
        );
    }
    eprintln!(
        "{name}: {compared} px, worst {:.3}/255, {deep} px behind {layers_seen} layers",
        worst * 255.0
    );
    assert!(
        deep > 20,
        "{name}: too few pixels behind {layers_seen} translucent spheres"
    );
    compared
}

#[test]
fn overlapping_translucent_spheres_composite_like_sorted_ray_hits() {
    let ctx = validated_context();
    let n = composite_matches(&ctx, "see-through-ortho", None, stack(), 4);
    assert!(n > (W * H / 4) as usize);
    let n = composite_matches(&ctx, "see-through-persp", Some(35.0), stack(), 4);
    assert!(n > (W * H / 4) as usize);
    // more layers than one selection scan takes (shade keeps 8 a scan)
    let n = composite_matches(&ctx, "see-through-deep", None, deep_stack(), 12);
    assert!(n > (W * H / 8) as usize);
    assert_no_validation_messages(&ctx);
}

/// The lists against a CPU model (GPU-AV does not check atomics): each
/// pixel holds exactly the see-through spheres whose exact front hit lies
/// in front of the nearest opaque hit, once each, with their depth order;
/// the runs are disjoint and inside the pool.
#[test]
fn fragment_lists_match_a_cpu_model() {
    let ctx = validated_context();
    let spheres = stack();
    let scene = scene_of(spheres.clone(), "lists");
    let cam = camera(&scene, W, H, Some(35.0));
    let mut r = Renderer::new(&ctx, &scene, flat(cam)).expect("renderer");
    r.render_frame().expect("frame");
    let st = r.inspect().see_through().expect("see-through stage");
    let l = st.read_lists(&ctx).expect("lists");
    let mut runs: Vec<(u32, u32)> = Vec::new();
    let (mut checked, mut total) = (0, 0u64);
    for py in 0..H {
        for px in 0..W {
            let k = (py * W + px) as usize;
            let (n, head) = (l.counts[k], l.heads[k]);
            total += n as u64;
            if n > 0 {
                assert_ne!(head, sphereshade::gpu::consts::F_NONE, "pixel {k}: no head");
                runs.push((head, n));
            }
            let Some(hits) = sorted_hits(&spheres, &cam, px, py) else {
                continue;
            };
            let opaque = hits
                .iter()
                .find(|h| spheres[h.1].color[3] == 255)
                .map_or(f64::INFINITY, |h| h.0);
            let want: Vec<u32> = hits
                .iter()
                .filter(|h| h.0 < opaque && spheres[h.1].color[3] < 255)
                .map(|h| h.1 as u32)
                .collect();
            let mut got: Vec<[u32; 2]> = if n == 0 {
                Vec::new()
            } else {
                l.frags[head as usize..(head + n) as usize].to_vec()
            };
            got.sort();
            let ids: Vec<u32> = got.iter().map(|f| f[1]).collect();
            assert_eq!(ids, want, "pixel {px},{py}: fragments");
            checked += 1;
        }
    }
    // runs disjoint, inside the pool, and the pool counter their sum
    runs.sort();
    for w in runs.windows(2) {
        assert!(w[0].0 + w[0].1 <= w[1].0, "runs overlap: {w:?}");
    }
    assert_eq!(l.frags.len() as u64, total);
    assert_eq!(st.damaged_guards(&ctx).unwrap(), Vec::<String>::new());
    eprintln!("lists: {checked} px checked, {total} fragments");
    assert!(checked > (W * H / 2) as usize && total > 1000);
    drop(r);
    assert_no_validation_messages(&ctx);
}

#[test]
fn a_one_fragment_pool_overflows_grows_and_renders_the_same() {
    let ctx = validated_context();
    let scene = scene_of(stack(), "overflow");
    let cam = camera(&scene, W, H, None);
    let big = render(&ctx, &scene, flat(cam));
    let mut s = flat(cam);
    s.deep.see_through_fragments = Some(1);
    let small = render(&ctx, &scene, s);
    let (a, b) = (big.stats.unwrap(), small.stats.unwrap());
    eprintln!("default pool {a:?}\none-fragment pool {b:?}");
    assert!(!a.overflowed && b.overflowed, "overflow not detected");
    assert!(
        b.capacity >= b.fragments && b.capacity > 1,
        "pool not grown"
    );
    assert_eq!(a.fragments, b.fragments);
    assert!(big.color == small.color, "the image differs after growing");
    assert!(big.ids == small.ids);
    assert_no_validation_messages(&ctx);
}

/// Band jobs past the list: the sphere's own invocation counts and fills
/// its fragments, where lavapipe ends a loop after 65,535 back-edges (a
/// larger footprint loses rows); the frame is then drawn again with a list
/// twice as long. Four see-through spheres over a 512x384 image (48
/// bands each) and a list of 64 jobs: the same colours, ids and fragments
/// as with the default list, the list grown to 256.
#[test]
fn see_through_band_jobs_past_the_list_are_drawn_again_longer() {
    let ctx = validated_context();
    let mut spheres = screen_filling_spheres();
    for (s, color) in spheres.iter_mut().zip([
        [230, 40, 40, 128],
        [40, 220, 60, 90],
        [50, 80, 240, 200],
        [240, 220, 30, 60],
    ]) {
        s.color = color;
    }
    let scene = scene_of(spheres, "screen-filling see-through spheres");
    let cam = screen_filling_camera();
    let a = render(&ctx, &scene, flat(cam));
    let mut s = flat(cam);
    s.band_jobs = Some(64);
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let i = r.inspect();
    let st = i.see_through().expect("see-through spheres");
    assert_eq!(st.job_capacity(), 256);
    assert_eq!(st.damaged_guards(&ctx).unwrap(), Vec::<String>::new());
    let b = rgba16(&i.read_color().unwrap());
    let differ = a.color.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{differ} pixels differ");
    assert_eq!(a.ids, ids_from_vis(&i.read_vis().unwrap()));
    assert_eq!(
        a.stats.unwrap().fragments,
        i.see_through_stats().unwrap().fragments
    );
    drop(r);
    assert_no_validation_messages(&ctx);
}

/// A frame whose band jobs did not all fit (a smaller limit: spheres of
/// 1,000-4,000 pixels counted and filled by their own invocations, their
/// inline bits set, no second draw) leaves bits the next frame must clear
/// before its count: that frame, with the whole list, queues those
/// spheres' bands, and a stale bit would have its fill visit them again
/// (fragments outside their runs). Both frames equal a fresh renderer's.
#[test]
fn inline_bits_of_a_frame_are_cleared_for_the_next() {
    let ctx = validated_context();
    let mut spheres = Vec::new();
    for j in 0..7 {
        for i in 0..9 {
            let c = [
                -60.0 + 15.0 * i as f32,
                -45.0 + 15.0 * j as f32,
                -100.0 - (i + j) as f32,
            ];
            let rgb = [(30 * i) as u8, (40 * j) as u8, 200];
            spheres.push(ball(c, 6.0, rgb, 128));
        }
    }
    let scene = scene_of(spheres, "a grid of see-through spheres");
    let cam = screen_filling_camera();
    let fresh = render(&ctx, &scene, flat(cam));
    let mut r = Renderer::new(&ctx, &scene, flat(cam)).expect("renderer");
    let st = r.inspect().see_through().map(|s| s.job_capacity());
    assert!(st.is_none(), "made with the first frame");
    for (f, limit) in [(0, 64), (1, 0), (2, 64), (3, 0)] {
        if let Some(s) = r.inspect().see_through() {
            s.set_job_limit(limit);
        }
        r.render_frame()
            .unwrap_or_else(|e| panic!("frame {f}: {e}"));
        let i = r.inspect();
        let st = i.see_through().expect("see-through spheres");
        assert_eq!(st.damaged_guards(&ctx).unwrap(), Vec::<String>::new());
        let inlined = st.read_counters(&ctx).unwrap()[sphereshade::gpu::consts::F_INLINED as usize];
        // (frame 0 is made with the whole list: the limit applies from
        // frame 1 on, set before it)
        assert_eq!(inlined != 0, f == 2, "frame {f}: inline visits {inlined}");
        let c = rgba16(&i.read_color().unwrap());
        let differ = fresh.color.iter().zip(&c).filter(|(x, y)| x != y).count();
        assert_eq!(differ, 0, "frame {f}: {differ} pixels differ");
        assert_eq!(
            fresh.stats.as_ref().unwrap().fragments,
            i.see_through_stats().unwrap().fragments,
            "frame {f}"
        );
    }
    drop(r);
    assert_no_validation_messages(&ctx);
}

/// With deep shadows, translucent spheres are lit with their translucent
/// shadow and cast 1 - alpha; a fully opaque alpha rule changes nothing.
#[test]
fn see_through_with_deep_shadows_and_ssdo_validates() {
    let ctx = validated_context();
    let mut spheres = stack();
    spheres.push(ball([0.0, 0.0, -6.0], 4.0, [180, 180, 180], 255));
    let scene = scene_of(spheres.clone(), "deep");
    let cam = camera(&scene, W, H, None);
    let mut s = settings(cam, ShadowMode::Deep);
    s.ssdo = sphereshade::settings::SsdoMode::Semantic;
    let f = render(&ctx, &scene, s.clone());
    assert!(f.stats.unwrap().fragments > 0);
    // the same scene with every alpha 255: no see-through pass at all
    for s in &mut spheres {
        s.color[3] = 255;
    }
    let opaque = render(&ctx, &scene_of(spheres, "deep-opaque"), s);
    assert!(opaque.stats.is_none());
    assert!(f.color != opaque.color, "translucency changed nothing");
    assert_no_validation_messages(&ctx);
}

/// 1tii.pdb's records whose chain column (22) is `chain`.
fn in_chain(chain: &str) -> Vec<bool> {
    let text = std::fs::read_to_string(data_file("1tii.pdb")).unwrap();
    text.lines()
        .take_while(|l| !l.starts_with("ENDMDL"))
        .filter(|l| l.starts_with("ATOM  ") || l.starts_with("HETATM"))
        .map(|l| l.get(21..22) == Some(chain))
        .collect()
}

fn load_1tii(rules: &[(&str, &str)]) -> Scene {
    load_with_rules(&data_file("1tii.pdb"), rules, false)
}

/// `--hide`: the hidden chain is not uploaded, never appears in the id AOV
/// (ids mapped back to input order), and casts no shadow: the deep
/// shadows match exact shadow rays through the kept spheres only.
#[test]
fn hidden_spheres_leave_the_ids_and_cast_no_shadow() {
    let ctx = validated_context();
    let full = load_1tii(&[]);
    let hidden = in_chain("A");
    let n_hidden = hidden.iter().filter(|&&h| h).count();
    assert!(n_hidden > 100 && hidden.len() == full.spheres.len());
    let scene = load_1tii(&[("hide", "chain A")]);
    let kept: Vec<Sphere> = full
        .spheres
        .iter()
        .zip(&hidden)
        .filter(|(_, h)| !**h)
        .map(|(s, _)| *s)
        .collect();
    assert_eq!(scene.spheres.len(), kept.len());
    assert!(
        scene
            .spheres
            .iter()
            .zip(&kept)
            .all(|(a, b)| a.center == b.center)
    );
    let cam = camera(&full, 160, 120, None);
    let mut s = settings(cam, ShadowMode::Deep);
    // the light from behind chain A toward the others' centre (and a bit
    // toward the viewer, so what A shadowed faces the camera)
    let centre = |inside: bool| {
        let v: Vec<glam::DVec3> = full
            .spheres
            .iter()
            .zip(&hidden)
            .filter(|(_, h)| **h == inside)
            .map(|(s, _)| s.center.map(f64::from).into())
            .collect();
        v.iter().sum::<glam::DVec3>() / v.len() as f64
    };
    s.light = (centre(false) - centre(true)).normalize() + glam::DVec3::new(0.0, 0.0, -0.5);
    let light = s.light;
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let map = r.inspect().id_map().expect("an id map");
    let ids = ids_from_vis(&r.inspect().read_vis().unwrap());
    let shadow = r.inspect().read_shadow().unwrap();
    let mut seen = 0;
    for id in ids.iter().flatten() {
        let input = map.input(*id as u64) as usize;
        assert!(!hidden[input], "hidden atom {input} in the id AOV");
        seen += 1;
    }
    assert!(seen > 1000);
    let (vis_kept, img) = sphereshade::reference::shadow_image(&kept, &cam, light, 1.0);
    let (vis_full, _) = sphereshade::reference::shadow_image(&full.spheres, &cam, light, 1.0);
    let (mut compared, mut agree, mut freed) = (0, 0, 0);
    for i in 0..ids.len() {
        let Some(v) = vis_kept[i] else { continue };
        if ids[i] != Some(img.ids[i]) {
            continue;
        }
        compared += 1;
        let g = shadow[i] < 0.5;
        if g == (v < 0.5) {
            agree += 1;
        }
        // where chain A's shadow fell on a kept sphere, it is gone
        if vis_full[i].is_some_and(|f| f < 0.5) && v >= 0.5 {
            freed += 1;
            assert!(!g, "pixel {i} still in chain A's shadow");
        }
    }
    let pct = 100.0 * agree as f64 / compared as f64;
    eprintln!(
        "hide: {pct:.3}% of {compared} px agree with kept-only shadow rays; {freed} px freed of chain A's shadow"
    );
    assert!(pct >= 99.9 && freed > 50, "{pct} {freed}");
    assert_no_validation_messages(&ctx);
}

/// `--alpha SEL=0` renders as `--hide SEL` (deep shadows, a fixed
/// camera): the same image exactly without SSDO; with semantic SSDO the
/// per-sphere sample rotation hashes the sphere's index, which hiding
/// renumbers, so only that noise differs. `--alpha SEL=1` renders as no
/// rule at all.
#[test]
fn alpha_zero_is_hide_and_alpha_one_is_no_rule() {
    let ctx = validated_context();
    let full = load_1tii(&[]);
    let cam = camera(&full, 160, 120, None);
    let mut s = settings(cam, ShadowMode::Deep);
    s.ssdo = sphereshade::settings::SsdoMode::Semantic;
    // the full scene's zoom thresholds (by default they scale with the
    // scene's size, which hiding changes)
    let (_, radius) = full.bounding_sphere();
    let levels = sphereshade::semantic::useful_levels(&full).len();
    s.ssdo_knobs.semantic_levels = Some(sphereshade::settings::Levels(
        sphereshade::semantic::default_thresholds(levels, 2.0 * radius as f64 * 1.05),
    ));
    let color = |scene: &Scene, s: &RenderSettings| {
        let mut r = Renderer::new(&ctx, scene, s.clone()).expect("renderer");
        r.render_frame().expect("frame");
        r.inspect().read_color().unwrap()
    };
    let none = color(&full, &s);
    let one = color(&load_1tii(&[("alpha", "chain A=1")]), &s);
    assert!(none == one, "--alpha SEL=1 changed the image");
    let (hidden, zeroed) = (
        load_1tii(&[("hide", "chain A")]),
        load_1tii(&[("alpha", "chain A=0")]),
    );
    let mut off = s.clone();
    off.ssdo = sphereshade::settings::SsdoMode::Off;
    let (a, b) = (color(&hidden, &off), color(&zeroed, &off));
    assert!(a != color(&full, &off), "hiding chain A changed nothing");
    let n = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(n, 0, "without SSDO, --alpha 0 and --hide differ on {n} px");
    let (hide, zero) = (color(&hidden, &s), color(&zeroed, &s));
    let ch = |w: u32, k: u32| ((w >> (8 * k)) & 0xFF) as i32;
    let (mut sum, mut off1) = (0i64, 0);
    for (a, b) in hide.iter().zip(&zero) {
        let d = (0..3).map(|k| (ch(*a, k) - ch(*b, k)).abs()).max().unwrap();
        sum += d as i64;
        if d > 1 {
            off1 += 1;
        }
    }
    let mean = sum as f64 / hide.len() as f64;
    eprintln!(
        "alpha 0 vs hide with semantic SSDO: mean {mean:.3}/255, {off1} px off by more than 1/255"
    );
    assert!(mean < 2.0 && off1 * 10 < hide.len(), "{mean} {off1}");
    assert_no_validation_messages(&ctx);
}

/// A column of `n` faint see-through spheres along the view (alpha 10/255)
/// in front of an opaque one, seen end-on: the pixels near its axis hold
/// `n` fragments and need ~180 of them composited.
fn faint_column(n: usize, alpha: u8) -> (Scene, Camera) {
    let mut v: Vec<Sphere> = (0..n)
        .map(|k| ball([0.0, 0.0, -0.25 * k as f32], 1.0, [200, 120, 60], alpha))
        .collect();
    v.push(ball(
        [0.0, 0.0, -0.25 * n as f32 - 2.0],
        1.5,
        [90, 90, 220],
        255,
    ));
    let scene = scene_of(v, "faint column");
    let cam = sphereshade::camera::default_camera(
        &scene,
        32,
        32,
        &sphereshade::camera::CameraFit {
            view_height: Some(4.0),
            center: Some(glam::DVec3::new(0.0, 0.0, -0.125 * n as f64)),
            ..Default::default()
        },
    )
    .expect("camera");
    (scene, cam)
}

/// lavapipe ends a shader invocation's loops after 65,535 back-edges:
/// shade's composite of a pixel with thousands of faint fragments (a scan
/// of them per 8 layers) passes it. Such a frame is refused with one line
/// naming the fragments, not drawn with layers left out; the same column
/// with opaque-enough layers (few scans) or short (few fragments) is drawn
/// and counts no cut pixel, so the count is the walk's, not a constant. On
/// a device without that limit every frame is drawn.
#[test]
fn a_composite_longer_than_the_device_walks_is_refused() {
    let ctx = validated_context();
    let cpu = ctx.props.device_type == ash::vk::PhysicalDeviceType::CPU;
    let run = |n: usize, alpha: u8| {
        let (scene, cam) = faint_column(n, alpha);
        let mut r = Renderer::new(&ctx, &scene, flat(cam)).expect("renderer");
        let got = r.render_frame().map(|_| ());
        let c = r
            .inspect()
            .see_through()
            .expect("see-through stage")
            .read_counters(&ctx)
            .expect("counters");
        use sphereshade::gpu::consts::{F_COMPOSITE_CUT, F_MAX, F_PIXELS};
        let word = |w: u32| c[w as usize];
        (got, word(F_COMPOSITE_CUT), word(F_MAX), word(F_PIXELS))
    };
    // 6,000 fragments at alpha 0.04: 22 scans of 6,000
    let (got, cut, most, pixels) = run(6_000, 10);
    assert!(most >= 6_000, "fragments of the axis pixel: {most}");
    if cpu {
        let msg = got
            .expect_err("a 6,000-fragment composite on lavapipe")
            .to_string();
        assert!(!msg.contains('\n'), "{msg}");
        assert!(msg.starts_with("see-through pixels of up to 6"), "{msg}");
        assert!(cut > 0 && cut <= pixels, "cut {cut} of {pixels} pixels");
    } else {
        got.expect("frame");
        assert_eq!(cut, 0);
    }
    // the same fragments, layers opaque enough to end after one scan
    let (got, cut, ..) = run(6_000, 128);
    got.expect("an opaque-enough column");
    assert_eq!(cut, 0);
    // faint layers, few of them
    let (got, cut, ..) = run(200, 10);
    got.expect("a short faint column");
    assert_eq!(cut, 0);
    assert_no_validation_messages(&ctx);
}

/// A tiled image's fragment stats are its tiles' together (they were the
/// last tile's): the same most fragments of a pixel, at least the untiled
/// counts (a tile's margin is counted in each), and the same colours.
#[test]
fn a_tiled_image_reports_every_tiles_fragments() {
    let ctx = validated_context();
    let scene = scene_of(stack(), "stack");
    let cam = camera(&scene, W, H, None);
    let mut r = Renderer::new(&ctx, &scene, flat(cam)).expect("renderer");
    let (whole, _) = r.render_image(None).expect("untiled");
    let one = r.inspect().see_through_stats().expect("stats");
    let (tiled, _) = r.render_image(Some(32)).expect("tiled");
    assert!(tiled.tiles >= 4, "{} tiles", tiled.tiles);
    let all = r.inspect().see_through_stats().expect("stats");
    assert_eq!(all.max_per_pixel, one.max_per_pixel);
    assert!(
        all.fragments >= one.fragments && all.pixels >= one.pixels,
        "{all:?} vs {one:?}"
    );
    assert_eq!(tiled.color, whole.color);
    // back to one tile: that frame's own
    r.render_image(None).expect("untiled again");
    assert_eq!(r.inspect().see_through_stats().expect("stats"), one);
    drop(r);
    assert_no_validation_messages(&ctx);
}
