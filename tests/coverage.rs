//! The `coverage` pass's tile lists: they partition the 16x16-pixel regions
//! exactly by what the visibility buffer shows (a CPU model from the read
//! back buffer), and running the per-pixel passes on them (full shader on
//! covered regions, the background variant on the rest) changes no byte of
//! the colour and AOVs against running every tile with the full shader.

mod common;

use common::*;
use glam::DVec3;
use sphereshade::gpu::consts::{TL_ARGS, TL_BACKGROUND, TL_COVERED, TL_LIST, TL_REGION};
use sphereshade::render::Renderer;
use sphereshade::settings::{RenderSettings, ShadowMode, SsdoMode};
use sphereshade::stages::ssdo::passes::Receivers;
use std::collections::BTreeSet;

#[test]
fn tile_lists_partition_the_regions_by_the_visibility_buffer() {
    let ctx = validated_context();
    let scene = load_data("1tii.pdb");
    // A wide image: background regions on both sides, some partly covered.
    let (w, h) = (200u32, 72u32);
    let mut s = settings(camera(&scene, w, h, None), ShadowMode::Issm);
    s.ssdo = SsdoMode::Semantic;
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let vis = r.inspect().read_vis().expect("vis");
    let words = r.inspect().read_tile_lists().expect("lists");
    let (rx, ry) = (w.div_ceil(TL_REGION), h.div_ceil(TL_REGION));
    let regions = (rx * ry) as usize;
    let mut want = BTreeSet::new();
    for y in 0..h {
        for x in 0..w {
            if vis[(y * w + x) as usize] as u32 != u32::MAX {
                want.insert((x / TL_REGION, y / TL_REGION));
            }
        }
    }
    let (nc, nb) = (
        words[TL_COVERED as usize] as usize,
        words[TL_BACKGROUND as usize] as usize,
    );
    eprintln!(
        "{regions} regions: {nc} covered, {nb} background (CPU: {} covered)",
        want.len()
    );
    assert_eq!(nc + nb, regions, "the lists do not hold every region once");
    assert!(
        nc > 0 && nb > 0,
        "the test image needs both kinds of region"
    );
    let list = &words[TL_LIST as usize..TL_LIST as usize + regions];
    let unpack = |e: u32| (e & 0xFFFF, e >> 16);
    let covered: BTreeSet<_> = list[..nc].iter().map(|&e| unpack(e)).collect();
    let background: BTreeSet<_> = list[nc..].iter().map(|&e| unpack(e)).collect();
    assert_eq!(covered.len(), nc, "a covered region is listed twice");
    assert_eq!(background.len(), nb, "a background region is listed twice");
    assert_eq!(
        covered, want,
        "covered regions differ from the visibility buffer's"
    );
    assert!(
        background
            .iter()
            .all(|&(x, y)| x < rx && y < ry && !want.contains(&(x, y)))
    );
    // indirect arguments: 4 full-resolution tiles or 1 block tile per region
    let args = |k: u32| &words[(TL_ARGS + 3 * k) as usize..(TL_ARGS + 3 * k + 3) as usize];
    for (k, groups) in [(0, 4 * nc), (1, 4 * nb), (2, nc), (3, nb)] {
        assert_eq!(args(k), [groups as u32, 1, 1], "dispatch arguments {k}");
    }
    assert_no_validation_messages(&ctx);
}

type Images = (Receivers, Vec<u32>, Vec<f32>, Vec<[f32; 4]>, Vec<u32>);

fn images(s: &RenderSettings, scene: &sphereshade::scene::Scene) -> Images {
    let ctx = validated_context();
    let mut r = Renderer::new(&ctx, scene, s.clone()).expect("renderer");
    r.render_frame().expect("frame");
    let out = (
        r.inspect().ssdo_receivers(),
        r.inspect().read_color().expect("colour"),
        r.inspect().read_shadow().expect("shadow"),
        r.inspect().read_ambient().expect("ambient"),
        r.inspect().read_tile_lists().expect("lists"),
    );
    drop(r);
    assert_no_validation_messages(&ctx);
    out
}

#[test]
fn tile_lists_change_no_byte_of_the_image() {
    let scene = load_data("1tii.pdb");
    let mut seen = BTreeSet::new();
    // sizes that give per-sphere, per-pixel and per-block receivers
    // (zoom: the view height divided by it, so spheres grow on screen)
    for (w, h, fov, zoom, shadows) in [
        (96, 40, None, 1.0, ShadowMode::IssmSoft),
        (600, 250, None, 1.0, ShadowMode::None),
        (400, 170, Some(40.0), 8.0, ShadowMode::Issm),
        (400, 170, None, 8.0, ShadowMode::IssmSoft),
    ] {
        let mut cam = camera(&scene, w, h, fov);
        cam.view_height /= zoom;
        if zoom > 1.0 {
            // the molecule's edge through the image centre: background to its right
            cam.center += cam.right * scene.bounding_sphere().1 as f64;
        }
        let mut s = settings(cam, shadows);
        s.ssdo = SsdoMode::Semantic;
        s.ssdo_knobs.blur = true;
        s.light = DVec3::new(-1.0, -0.5, -1.0);
        let with = images(&s, &scene);
        s.tile_lists = false;
        let without = images(&s, &scene);
        let what = format!("{w}x{h} fov {fov:?} zoom {zoom} {shadows:?} {:?}", with.0);
        let differ = with
            .1
            .iter()
            .zip(&without.1)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(
            differ, 0,
            "{what}: {differ} colour pixels differ with the tile lists"
        );
        assert!(with.2 == without.2, "{what}: the shadow AOV differs");
        assert!(with.3 == without.3, "{what}: the ambient AOV differs");
        let (nc, nb) = (with.4[TL_COVERED as usize], with.4[TL_BACKGROUND as usize]);
        eprintln!("{what}: identical ({nc} covered regions, {nb} background)");
        assert!(
            nc > 0 && nb > 0,
            "{what}: the image needs both kinds of region"
        );
        seen.insert(format!("{:?}", with.0));
    }
    assert_eq!(
        seen.len(),
        3,
        "not every SSDO receiver kind was compared: {seen:?}"
    );
}
