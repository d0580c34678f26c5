//! The frame graph: every frame, in every mode, records a barrier for each
//! hazard between its steps (derived from the pipelines' declared bindings),
//! judged by an independent replay of the recorder's log; removing any one
//! of those barriers is caught. The pass list is the README's table.

mod common;

use common::*;
use sphereshade::render::{Renderer, graph};
use sphereshade::settings::{RasterMode, ShadowMode, SsdoMode};
use sphereshade::vk::barrier::{Event, check_hazards};

#[test]
fn every_mode_records_a_barrier_for_every_hazard() {
    let ctx = validated_context();
    let scene = load_data("1tii.pdb");
    let cam = camera(&scene, 64, 48, None);
    let mut checked = 0;
    for raster in [RasterMode::Compute, RasterMode::Graphics] {
        let mut s = settings(cam, ShadowMode::None);
        s.raster = raster;
        let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
        for shadows in [
            ShadowMode::None,
            ShadowMode::Issm,
            ShadowMode::IssmSoft,
            ShadowMode::Deep,
            ShadowMode::SmPcf,
            ShadowMode::Osm,
        ] {
            for ssdo in [SsdoMode::Off, SsdoMode::Plain, SsdoMode::Semantic] {
                for blur in [false, true] {
                    if raster == RasterMode::Graphics && (ssdo != SsdoMode::Off || blur) {
                        continue;
                    }
                    r.update(|set| set.shadows = shadows).unwrap();
                    r.update(|set| set.ssdo = ssdo).unwrap();
                    r.update(|set| set.ssdo_knobs.blur = blur).expect("blur");
                    let log = r.frame_log().expect("log");
                    let what = format!("{raster:?} {shadows:?} {ssdo:?} blur {blur}");
                    let problems = check_hazards(&log);
                    assert!(problems.is_empty(), "{what}: {problems:#?}");
                    let barriers: Vec<usize> = log
                        .iter()
                        .enumerate()
                        .filter(|(_, e)| matches!(e, Event::Barrier(_)))
                        .map(|(i, _)| i)
                        .collect();
                    assert!(!barriers.is_empty(), "{what}: no barriers at all");
                    for &k in &barriers {
                        let mut broken = log.clone();
                        broken.remove(k);
                        assert!(
                            !check_hazards(&broken).is_empty(),
                            "{what}: barrier {k} of {} is not needed by any hazard:\n{:#?}",
                            barriers.len(),
                            &log[k.saturating_sub(4)..(k + 3).min(log.len())]
                        );
                    }
                    // And the frame runs, with the same validation verdict.
                    r.render_frame().expect("frame");
                    checked += 1;
                }
            }
        }
        drop(r);
        if raster == RasterMode::Compute {
            // the graphics run below needs a device of its own on lavapipe
            // for timings only; correctness is the same
        }
    }
    eprintln!("{checked} mode combinations: every hazard covered, every barrier needed");
    assert_no_validation_messages(&ctx);
}

#[test]
fn passes_outside_the_list_are_refused() {
    let ctx = validated_context();
    let buf = sphereshade::vk::Buffer::storage(&ctx, "x", 64).unwrap();
    let err = ctx
        .one_shot_passes("unlisted", |rec| {
            rec.restrict_to(graph::pass_names());
            rec.pass("not_a_pass", |p| {
                p.fill(&buf, 64, 0);
                Ok(())
            })
        })
        .expect_err("an unlisted pass name");
    assert!(err.to_string().contains("not_a_pass"), "{err}");
    let mut buf = buf;
    buf.destroy(&ctx);
}

/// The README's "How it works" table is the pass list.
#[test]
fn readme_pass_table_is_the_pass_list() {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let table = graph::markdown_table();
    assert!(
        readme.contains(&table),
        "README.md's pass table differs from src/render/graph.rs PASSES; it should read:\n{table}"
    );
    let names = graph::pass_names();
    let mut sorted = names.to_vec();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), names.len(), "duplicate pass names");
}

/// `Renderer::update` refuses what a live renderer cannot change and what
/// is out of range, and leaves the settings as they were then; what it
/// accepts is what the next frame uses.
#[test]
fn update_refuses_fixed_and_bad_settings_and_keeps_the_old_ones() {
    let ctx = validated_context();
    let scene = load_data("1tii.pdb");
    let cam = camera(&scene, 64, 48, None);
    let mut r = Renderer::new(&ctx, &scene, settings(cam, ShadowMode::Issm)).expect("renderer");
    let before = r.settings().clone();
    for (edit, frag) in [
        (
            Box::new(|s: &mut sphereshade::settings::RenderSettings| {
                s.raster = RasterMode::Graphics
            }) as Box<dyn Fn(&mut sphereshade::settings::RenderSettings)>,
            "--raster cannot change on a live renderer",
        ),
        (
            Box::new(|s| s.issm.size = 1024),
            "the ISSM parameters cannot change",
        ),
        (
            Box::new(|s| s.opacity = 1.5),
            "--opacity must be between 0 and 1",
        ),
        (
            Box::new(|s| s.light = glam::DVec3::ZERO),
            "--light must be a finite",
        ),
    ] {
        let e = r.update(|s| edit(s)).expect_err(frag).to_string();
        assert!(e.contains(frag), "{e}");
        assert_eq!(r.settings(), &before, "{frag}: settings changed");
    }
    r.update(|s| {
        s.shadows = ShadowMode::Deep;
        s.opacity = 0.5;
    })
    .expect("update");
    assert_eq!(
        (r.settings().shadows, r.settings().opacity),
        (ShadowMode::Deep, 0.5)
    );
    r.render_frame().expect("frame");
    assert!(r.inspect().deep_stats().is_some(), "the deep lists ran");
    drop(r);
    assert_no_validation_messages(&ctx);
}
