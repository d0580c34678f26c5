//! Nested instancing (src/scene/instanced/nested.rs): a scene of
//! placements of one instanced block. On the CPU its represented spheres
//! are the block's placed by composed transforms; on the GPU (under
//! validation) a view with every placement opened renders the same bytes
//! as the scene expanded, closed placements draw through their proxies the
//! very coarsest spheres their instances would draw, with ids naming the
//! atoms those stand for, and a view opens what it shows nearest first.

mod common;

use common::*;
use glam::{DQuat, DVec3};
use sphereshade::render::Renderer;
use sphereshade::render::nesting::{opening, opening_within};
use sphereshade::scene::Scene;
use sphereshade::scene::instanced::nested::{Proxies, nest};
use sphereshade::scene::instanced::{Rigid, rigid_from};
use sphereshade::settings::{ShadowMode, SsdoMode};

/// The HIV-1 cellPACK model (11,681 instances of 26 types, rigid).
fn block() -> Scene {
    load_data("meso/HIV-1_0.1.6-8_mixed_radii_pdb.json")
}

/// `n`^3 placements of `block` on a lattice of touching bounding spheres
/// (z fastest last: layer by layer along z), each in its own turn.
fn lattice(block: &Scene, n: u32) -> Vec<Rigid> {
    let (c, r) = block.bounding_sphere();
    let s = 2.0 * r as f64;
    let mid = (n - 1) as f64 * 0.5;
    (0..n * n * n)
        .map(|i| {
            let cell = DVec3::new(
                (i % n) as f64 - mid,
                (i / n % n) as f64 - mid,
                (i / (n * n)) as f64 - mid,
            );
            let q = DQuat::from_axis_angle(
                DVec3::new(1.0, 2.0, 3.0 + i as f64).normalize(),
                0.3 * i as f64,
            );
            rigid_from(q, (cell * s - q * c.as_dvec3()).into())
        })
        .collect()
}

fn nested(n: u32) -> Scene {
    let b = block();
    let p = lattice(&b, n);
    nest(b, p).expect("nest")
}

/// Represented spheres: placements x block, in expanded order, each the
/// block's atom placed by the composed transform (as `expand` stores it).
#[test]
fn a_nested_scene_represents_its_placed_blocks() {
    let b = block();
    let per = b.represented();
    let s = nested(2);
    assert_eq!(s.represented(), 8 * per);
    let inst = s.instancing.as_ref().unwrap();
    assert_eq!(inst.represented_instances(), 8 * inst.instances() as u64);
    let e = s.expand().unwrap();
    assert_eq!(e.spheres.len() as u64, 8 * per);
    for i in (0..8 * per).step_by(9973) {
        let a = s.sphere(i).unwrap();
        assert_eq!(a, e.spheres[i as usize], "sphere {i}");
        let (k, atom) = inst.locate(i).unwrap();
        assert_eq!(k / inst.instances(), (i / per) as usize, "placement of {i}");
        // the block's own atom, placed
        let (kb, ab) = b.instancing.as_ref().unwrap().locate(i % per).unwrap();
        assert_eq!((k % inst.instances(), atom), (kb, ab));
        let own = b.sphere(i % per).unwrap();
        let d = DVec3::from(own.center.map(|x| x as f64));
        let p = &s.nesting().unwrap().placements[(i / per) as usize];
        let q = DQuat::from_xyzw(p.q[0] as f64, p.q[1] as f64, p.q[2] as f64, p.q[3] as f64);
        let want = q * d + DVec3::new(p.t[0] as f64, p.t[1] as f64, p.t[2] as f64);
        let got = DVec3::from(a.center.map(|x| x as f64));
        assert!((got - want).length() < 1e-2, "sphere {i}: {got} vs {want}");
    }
    assert!(s.sphere(8 * per).is_none());
    // the bounds hold every placed sphere
    let (c, r) = s.bounding_sphere();
    let far = e
        .spheres
        .iter()
        .map(|x| glam::Vec3::from(x.center).distance(c) + x.radius)
        .fold(0.0f32, f32::max);
    assert!(far <= r, "bounding sphere {r} < {far}");
}

#[test]
fn nesting_refuses_what_it_cannot_hold() {
    let e = nest(block(), Vec::new()).unwrap_err().to_string();
    assert!(e.contains("0 placements"), "{e}");
    let twice = nest(nested(1), vec![Rigid::default()])
        .unwrap_err()
        .to_string();
    assert!(twice.contains("cannot be nested again"), "{twice}");
    let far = Rigid {
        q: [0.0, 0.0, 0.0, 1.0],
        t: [1e30, 0.0, 0.0, 0.0],
    };
    let out = nest(block(), vec![Rigid::default(), far])
        .unwrap_err()
        .to_string();
    assert!(out.contains("placements reach"), "{out}");
    let plain = load_data("1tii.pdb");
    let flat = nest(plain, vec![Rigid::default()]).unwrap_err().to_string();
    assert!(flat.contains("only an instanced scene"), "{flat}");
    // rules cannot tell one placement's copy from another's: one line
    let paint = sphereshade::scene::paint::Paint {
        scheme: None,
        colormap: Default::default(),
        rules: vec![sphereshade::scene::paint::Rule::hide("all").unwrap()],
    };
    let err = sphereshade::scene::paint::apply(nested(1), &paint)
        .expect_err("rules on a nested scene")
        .to_string();
    assert!(err.contains("nested scene") && !err.contains('\n'), "{err}");
}

/// Every placement opened (`--lod-pixels 0`: full detail; `--lod off`):
/// the same ids, colours, shadow and ambient AOVs as the scene expanded,
/// in the default modes and with deep shadows.
#[test]
fn a_nested_scene_with_every_placement_open_renders_as_its_expansion() {
    let ctx = validated_context();
    let s = nested(2);
    let e = s.expand().unwrap();
    let cam = camera(&s, 96, 72, None);
    for (shadows, ssdo, lod_off) in [
        (ShadowMode::IssmSoft, SsdoMode::Semantic, false),
        (ShadowMode::Deep, SsdoMode::Off, true),
    ] {
        let mut st = settings(cam, shadows);
        st.ssdo = ssdo;
        st.ssdo_knobs.blur = true;
        st.lod.lod_pixels = 0.0;
        if lod_off {
            st.lod.lod = sphereshade::settings::LodMode::Off;
        }
        let mut a = Renderer::new(&ctx, &s, st.clone()).unwrap();
        a.render_frame().unwrap();
        let mut b = Renderer::new(&ctx, &e, st).unwrap();
        b.render_frame().unwrap();
        let (a, b) = (a.inspect(), b.inspect());
        let what = format!("{shadows:?} {ssdo:?} lod off {lod_off}");
        assert_eq!(a.instancing().unwrap().placements, Some(8), "{what}");
        let vis = a.read_vis().unwrap();
        let covered = vis
            .iter()
            .filter(|&&k| k != sphereshade::gpu::VIS_EMPTY)
            .count();
        assert!(covered > vis.len() / 10, "{what}: {covered} covered");
        // (ids only: a depth word holds the view depth plus an offset from
        // the scene's bounding sphere, which for a nested scene is the
        // placed block's, a little larger than the expanded scene's)
        let ids = |v: &[u64]| v.iter().map(|k| k & 0xFFFF_FFFF).collect::<Vec<_>>();
        assert!(
            ids(&vis) == ids(&b.read_vis().unwrap()),
            "{what}: ids differ"
        );
        assert!(
            a.read_color().unwrap() == b.read_color().unwrap(),
            "{what}: colours differ"
        );
        assert!(
            a.read_shadow().unwrap() == b.read_shadow().unwrap(),
            "{what}: shadows differ"
        );
        assert!(
            a.read_ambient().unwrap() == b.read_ambient().unwrap(),
            "{what}: ambient differs"
        );
        assert_no_validation_messages(&ctx);
    }
}

/// Placements small enough on screen that every instance draws its
/// coarsest level are drawn by the proxies: the same spheres as the
/// placements opened (placed in two roundings instead of one: a few edge
/// pixels may differ), with ids naming the atoms the coarsest spheres
/// stand for.
#[test]
fn closed_placements_draw_the_coarsest_spheres_of_their_instances() {
    let ctx = validated_context();
    let s = nested(2);
    let inst = s.instancing.as_ref().unwrap();
    let pixels = 2.0;
    let proxies = Proxies::new(&s, pixels).unwrap();
    assert!(
        proxies.groups() > 1,
        "the HIV model's compartments make several groups"
    );
    let mut cam = camera(&s, 160, 120, None);
    // the whole lattice in view, every placement just below its opening size
    let fit = cam.view_height;
    cam.view_height = (cam.height as f64 / (0.9 * proxies.open_ppu as f64)).max(fit);
    let o = opening(&s, Some(&proxies), &cam).unwrap();
    assert_eq!(
        o.open,
        vec![false; 8],
        "at {} px/unit",
        cam.pixels_per_unit()
    );
    let st = settings(cam, ShadowMode::IssmSoft);
    let mut a = Renderer::new(&ctx, &s, st.clone()).unwrap();
    a.render_frame().unwrap();
    let opened = inst.resolve(&s, &proxies, &[true; 8]).unwrap();
    let mut b = Renderer::new(&ctx, &opened, st).unwrap();
    b.render_frame().unwrap();
    let (ia, ib) = (
        a.inspect().read_ids().unwrap(),
        b.inspect().read_ids().unwrap(),
    );
    let covered = ia.iter().filter(|i| i.is_some()).count();
    assert!(covered > 500, "{covered} pixels covered");
    let same = ia.iter().zip(&ib).filter(|(x, y)| x == y).count();
    assert!(
        same as f64 >= 0.97 * ia.len() as f64,
        "{} of {} pixels name other atoms",
        ia.len() - same,
        ia.len()
    );
    // a sphere per instance at most (the proxies' level 0)
    let drawn = a.inspect().spheres_drawn().unwrap();
    assert!(drawn <= 8 * inst.instances() as u64, "{drawn} drawn");
    for id in ia.iter().flatten() {
        assert!(s.sphere(*id).is_some(), "id {id} names no atom");
    }
    assert_no_validation_messages(&ctx);
}

/// A view close to the front placement of a column opens it and not the
/// one behind it (its disc is held by the front one's); a far view opens
/// none; `--lod off` opens all.
#[test]
fn a_view_opens_what_it_shows_nearest_first() {
    let s = nested(2);
    let proxies = Proxies::new(&s, 2.0).unwrap();
    let p = &s.nesting().unwrap().placements;
    let (bc, _) = block().bounding_sphere();
    let centre = |i: usize| {
        glam::Vec3::from(sphereshade::scene::instanced::apply_rigid(&p[i], bc.into())).as_dvec3()
    };
    // camera along -z: placements 4..8 (z > 0) are the front layer
    let mut cam = camera(&s, 320, 240, None);
    cam.center = centre(4);
    cam.view_height = 200.0;
    let o = opening(&s, Some(&proxies), &cam).unwrap();
    assert_eq!(o.wanted, 2, "the front placement and the one behind it");
    assert!(o.open[4] && !o.open[0], "{:?}", o.open);
    // full detail asked for (no coarse levels): both, the budget allowing
    let full = Proxies::new(&s, 0.0).unwrap();
    let o = opening(&s, Some(&full), &cam).unwrap();
    assert!(o.open[4] && o.open[0], "{:?}", o.open);
    let o = opening_within(&s, Some(&full), &cam, 1).unwrap();
    assert!(o.open[4] && !o.open[0], "{:?}", o.open);
    cam.view_height = 1e7;
    cam.center = DVec3::ZERO;
    let o = opening(&s, Some(&proxies), &cam).unwrap();
    assert_eq!(o.open, vec![false; 8]);
    let o = opening(&s, None, &cam).unwrap();
    assert_eq!(o.open, vec![true; 8]);
}

/// With a placement opened, the key light is fitted to the opened ones
/// (its texels as fine as the block's own: fitted to the whole 10^12
/// scene, ~240 A, and a zoomed view lost its shadows); with none,
/// to the whole scene.
#[test]
fn the_light_is_fitted_to_the_opened_placements() {
    let ctx = validated_context();
    let s = nested(2);
    let (_, block_r) = block().bounding_sphere();
    let (_, all_r) = s.bounding_sphere();
    let p = &s.nesting().unwrap().placements;
    let (bc, _) = block().bounding_sphere();
    let front = glam::Vec3::from(sphereshade::scene::instanced::apply_rigid(&p[4], bc.into()));
    let mut cam = camera(&s, 96, 72, None);
    let whole = cam;
    cam.center = front.as_dvec3();
    cam.view_height = 200.0;
    for (c, opened, reach) in [(cam, true, block_r), (whole, false, all_r)] {
        let mut r = Renderer::new(&ctx, &s, settings(c, ShadowMode::IssmSoft)).unwrap();
        r.render_frame().unwrap();
        let light = r.inspect().light_view().expect("a light view");
        let h = light.view_height;
        eprintln!(
            "opened {opened}: light view {h:.0} (block radius {block_r:.0}, scene {all_r:.0})"
        );
        assert!(
            h <= 2.0 * reach as f64 * 1.01 && h >= 0.5 * reach as f64,
            "opened {opened}: {h}"
        );
    }
    assert_no_validation_messages(&ctx);
}

/// `--scene meso` past 10^10 atoms is nested; here the same builder with a
/// 10^6-atom block: the count nearest N, the same scene twice, the
/// placements' bounding spheres touching at most, each turn a rotation.
#[test]
fn the_nested_meso_scene_places_whole_blocks() {
    let build =
        || sphereshade::scene::meso::nested(1_000_000, 27_000_000, 1, &mut |_, _| {}).unwrap();
    let s = build();
    let per = sphereshade::scene::meso::meso(1_000_000, 1)
        .unwrap()
        .represented();
    let n = s.nesting().unwrap().placements.len() as u64;
    assert_eq!(n, (27_000_000f64 / per as f64).round() as u64);
    assert_eq!(s.represented(), n * per);
    assert!(s.represented().abs_diff(27_000_000) <= per / 2);
    let again = build();
    assert!(
        s.spheres == again.spheres && s.instancing == again.instancing,
        "deterministic"
    );
    let b = s.instancing.as_ref().unwrap();
    let (bc, br) = {
        let mut flat = s.clone();
        flat.instancing.as_mut().unwrap().nesting = None;
        flat.bounding_sphere()
    };
    let p = &s.nesting().unwrap().placements;
    let centres: Vec<glam::Vec3> = p
        .iter()
        .map(|q| glam::Vec3::from(sphereshade::scene::instanced::apply_rigid(q, bc.into())))
        .collect();
    for (i, a) in centres.iter().enumerate() {
        let q = glam::Vec4::from(p[i].q);
        assert!(
            (q.length() - 1.0).abs() < 1e-5,
            "placement {i}: not a rotation"
        );
        for c in &centres[i + 1..] {
            assert!(
                a.distance(*c) >= 2.0 * br * (1.0 - 1e-5),
                "placements overlap"
            );
        }
    }
    assert!(b.represented_instances() == n * b.instances() as u64);
}

/// The overview of `--scene meso --atoms 10^11` (100 placements of the
/// 10^9 block, none opened): the goal of at most 5 spheres drawn a
/// pixel. The proxies (a sphere per protein over a ball of plasma) need
/// coarse spheres that keep the projected area, not the volume: with the
/// radius factors of a protein only (at most 1.25x the volume-keeping
/// one) this view drew 21 spheres a pixel at 480x270 (2.7 M: the back
/// placements through the front ones' holes) and covered 22,804 pixels;
/// now 3.2 and 23,982, of 23,689 in the blocks' discs.
#[test]
fn a_lattice_overview_draws_at_most_five_spheres_a_pixel() {
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(100_000_000_000, 1).unwrap();
    let placements = s.nesting().unwrap().placements.len();
    assert_eq!(placements, 100);
    let cam = camera(&s, 480, 270, None);
    let mut r = Renderer::new(&ctx, &s, settings(cam, ShadowMode::None)).unwrap();
    for _ in 0..2 {
        r.render_frame().unwrap();
    }
    let drawn = r.inspect().spheres_drawn().unwrap();
    let pixels = 480 * 270;
    // the placed blocks' discs (each block's bounding ball, seen along z:
    // the lattice's columns overlap exactly)
    let mut block = s.clone();
    block.instancing.as_mut().unwrap().nesting = None;
    let (bc, br) = block.bounding_sphere();
    let disc = std::f64::consts::PI * (br as f64 * cam.pixels_per_unit()).powi(2);
    let columns = s
        .nesting()
        .unwrap()
        .placements
        .iter()
        .map(|p| {
            let c = sphereshade::scene::instanced::apply_rigid(p, bc.into());
            ((c[0] / br).round() as i64, (c[1] / br).round() as i64)
        })
        .collect::<std::collections::BTreeSet<_>>()
        .len() as f64;
    assert_eq!(columns, 25.0, "a 5 x 5 x 4 lattice");
    let covered = r.inspect().read_ids().unwrap().iter().flatten().count();
    eprintln!(
        "{drawn} spheres drawn, {:.2} a pixel; {covered} pixels covered of {:.0} in the discs",
        drawn as f64 / pixels as f64,
        columns * disc
    );
    assert!(drawn <= 5 * pixels, "{drawn} spheres drawn");
    assert!(
        covered as f64 >= 0.9 * columns * disc && covered as f64 <= 1.05 * columns * disc,
        "{covered} pixels covered"
    );
    drop(r);
    assert_no_validation_messages(&ctx);
}

/// The proxies fit the levels of detail of every molecule type a resolved
/// scene holds (the block's, then the proxies'), once: each is the fit
/// the renderer would make of that type's atoms (it takes them instead of
/// fitting again: a viewer reopening placements, 1.4 -> 0.4 s on the
/// 10^12 scene).
#[test]
fn the_proxies_hold_the_fits_of_the_types_they_resolve_to() {
    use sphereshade::scene::instanced::lod::LodFit;
    let s = nested(2);
    let proxies = Proxies::new(&s, 2.0).unwrap();
    let mut open = vec![false; 8];
    open[3] = true;
    let r = s
        .instancing
        .as_ref()
        .unwrap()
        .resolve(&s, &proxies, &open)
        .unwrap();
    let molecules = &r.instancing.as_ref().unwrap().molecules;
    assert_eq!(proxies.fits.len(), molecules.len());
    assert!(molecules.len() > s.instancing.as_ref().unwrap().molecules.len());
    for (m, fit) in molecules.iter().zip(&proxies.fits) {
        let atoms: Vec<[f32; 4]> = r.spheres[m.first as usize..(m.first + m.atoms) as usize]
            .iter()
            .map(|a| [a.center[0], a.center[1], a.center[2], a.radius])
            .collect();
        assert!(fit.fits(m.atoms, 2.0), "{}", m.label);
        assert!(!fit.fits(m.atoms, 3.0), "{}", m.label);
        assert_eq!(*fit, LodFit::new(&atoms, 2.0), "{}", m.label);
    }
}
