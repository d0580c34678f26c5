//! The windowed viewer's smoke mode under Xvfb (lavapipe, validation on): N
//! frames in a real window with a scripted resize, then a screenshot whose
//! pixels must match `render` of the same scene and camera at the final size.

use std::path::Path;
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sphereshade"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

/// `sphereshade view ARGS --screenshot SHOT` in a virtual X server.
fn view(args: &[&str], shot: &Path) -> Output {
    Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1024x768x24"])
        .arg(env!("CARGO_BIN_EXE_sphereshade"))
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .arg("view")
        .args(args)
        .arg("--screenshot")
        .arg(shot)
        .output()
        .expect("run xvfb-run")
}

/// `sphereshade render ARGS --out OUT` (which must succeed), read back.
fn render(args: &[&str], out: &Path) -> image::RgbaImage {
    let o = bin()
        .arg("render")
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .expect("render");
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    image::open(out).expect("render png").to_rgba8()
}

/// Percentage of pixels whose channels all agree within 2 levels.
fn percent_close(a: &image::RgbaImage, b: &image::RgbaImage) -> f64 {
    assert_eq!(a.dimensions(), b.dimensions());
    let close = a
        .pixels()
        .zip(b.pixels())
        .filter(|(a, b)| a.0.iter().zip(b.0.iter()).all(|(x, y)| x.abs_diff(*y) <= 2))
        .count();
    100.0 * close as f64 / (a.width() as f64 * a.height() as f64)
}

#[test]
fn view_smoke_with_resize_matches_render() {
    assert!(
        Command::new("xvfb-run").arg("--help").output().is_ok(),
        "xvfb-run is missing: run tools/setup.sh"
    );
    let dir = std::env::temp_dir().join(format!("sphereshade-view-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("view.png");
    let input = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb");
    let o = view(
        &[
            input,
            "--width",
            "200",
            "--height",
            "150",
            "--frames",
            "6",
            "--resize-test",
            "--validate",
        ],
        &shot,
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "view failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let view = image::open(&shot).expect("screenshot").to_rgba8();
    assert_eq!(
        view.dimensions(),
        (240, 174),
        "the scripted resize did not take effect"
    );

    let render = render(
        &[input, "--width", "240", "--height", "174", "--validate"],
        &dir.join("render.png"),
    );
    let pct = percent_close(&view, &render);
    eprintln!("view screenshot matches render on {pct:.3}% of pixels");
    let sphere_px = view.pixels().filter(|p| p.0[0] > 120).count();
    assert!(sphere_px > 1000, "the screenshot shows no spheres");
    assert!(
        pct >= 99.5,
        "view and render differ on {:.3}% of pixels",
        100.0 - pct
    );
}

/// Every mode key through all its states and eight light-drag steps, under
/// validation: one renderer for the whole session (techniques are created
/// lazily and kept), zero validation messages, and the last frame equals a
/// fresh `render` with the light where the drags left it.
#[test]
fn view_toggles_every_mode_and_drags_the_light_without_rebuilding() {
    let dir = std::env::temp_dir().join(format!("sphereshade-toggle-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("toggle.png");
    let input = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb");
    let o = view(
        &[
            input,
            "--width",
            "160",
            "--height",
            "120",
            "--frames",
            "36",
            "--script",
            "toggle-all",
            "--validate",
        ],
        &shot,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "view failed: {err}");
    let summary = err
        .lines()
        .find(|l| l.contains("mode toggles"))
        .unwrap_or_else(|| panic!("no toggle summary: {err}"));
    eprintln!("{summary}");
    assert!(
        summary.contains("22 mode toggles") && summary.contains("8 light-drag steps"),
        "{summary}"
    );
    assert!(summary.contains("renderers created 1,"), "{summary}");
    let state = err
        .lines()
        .find(|l| l.contains("final state"))
        .unwrap_or_else(|| panic!("no final state: {err}"));
    assert!(
        state.contains("shadows issm-soft ssdo semantic blur on opacity 1"),
        "{state}"
    );
    let light = state.rsplit("light ").next().unwrap().trim();

    let render = render(
        &[input, "--width", "160", "--height", "120", "--light", light],
        &dir.join("render.png"),
    );
    let view = image::open(&shot).expect("screenshot").to_rgba8();
    let pct = percent_close(&view, &render);
    eprintln!("after the toggles the screenshot matches render on {pct:.3}% of pixels");
    assert!(
        pct >= 99.5,
        "view and render differ on {:.3}% of pixels",
        100.0 - pct
    );
}

/// `view TOP --trajectory TRAJ` plays frames from its reader thread under
/// validation: 20 window frames advance through the 10-frame XTC (looping),
/// with no validation message (exit 0 under --validate) and a screenshot.
#[test]
fn view_plays_a_trajectory() {
    let dir = std::env::temp_dir().join(format!("sphereshade-view-traj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("traj.png");
    let traj = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/traj/");
    let (top, xtc) = (
        format!("{traj}adk_oplsaa.gro"),
        format!("{traj}adk_oplsaa.xtc"),
    );
    let o = view(
        &[
            &top,
            "--trajectory",
            &xtc,
            "--width",
            "160",
            "--height",
            "120",
            "--frames",
            "20",
            "--validate",
            "--ssdo",
            "off",
        ],
        &shot,
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(0), "view failed: {err}");
    let played = err
        .lines()
        .find_map(|l| l.strip_prefix("view: played "))
        .unwrap_or_else(|| panic!("no playback report: {err}"));
    let n: u64 = played.split_whitespace().next().unwrap().parse().unwrap();
    assert!(n >= 10, "only {n} trajectory frames shown: {played}");
    assert!(!err.contains("validation message"), "{err}");
    assert!(shot.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// An instanced model (the HIV-1 cellPACK packing, 11,681 instances of 26
/// bead molecules) in the viewer: every mode key and the light drags under
/// validation, one renderer, and the last frame equals `render`'s.
#[test]
fn view_draws_an_instanced_model_in_every_mode() {
    let dir = std::env::temp_dir().join(format!("sphereshade-view-meso-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("meso.png");
    let input = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/meso/HIV-1_0.1.6-8_mixed_radii_pdb.json"
    );
    let o = view(
        &[
            input,
            "--width",
            "128",
            "--height",
            "96",
            "--frames",
            "36",
            "--script",
            "toggle-all",
            "--validate",
        ],
        &shot,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "view failed: {err}");
    assert!(err.contains("91956 spheres"), "{err}");
    let state = err
        .lines()
        .find(|l| l.contains("final state"))
        .unwrap_or_else(|| panic!("no final state: {err}"));
    let light = state.rsplit("light ").next().unwrap().trim();
    let render = render(
        &[input, "--width", "128", "--height", "96", "--light", light],
        &dir.join("render.png"),
    );
    let view = image::open(&shot).expect("screenshot").to_rgba8();
    let pct = percent_close(&view, &render);
    eprintln!("instanced model: the screenshot matches render on {pct:.3}% of pixels");
    assert!(
        pct >= 99.5,
        "view and render differ on {:.3}% of pixels",
        100.0 - pct
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--script fly-in` through the meso scene under validation: 64 wheel
/// notches from the whole scene to 0.9^64 of its height, into one protein
/// (levels of detail switching on the way, the LOD lists growing as they
/// must), the frame intervals reported.
#[test]
fn view_flies_into_the_meso_scene() {
    let dir = std::env::temp_dir().join(format!("sphereshade-view-fly-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shot = dir.join("fly.png");
    let o = view(
        &[
            "--scene",
            "meso",
            "--atoms",
            "2000000",
            "--width",
            "128",
            "--height",
            "96",
            "--view-height",
            "3000",
            "--frames",
            "70",
            "--script",
            "fly-in",
            "--validate",
        ],
        &shot,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "view failed: {err}");
    let line = err
        .lines()
        .find(|l| l.contains("frame intervals"))
        .unwrap_or_else(|| panic!("no intervals: {err}"));
    let height: f64 = line.rsplit(' ').next().unwrap().parse().unwrap();
    let want = 3000.0 * 0.9f64.powi(64);
    assert!((height - want).abs() < 1e-9 * want, "{line}");
    assert!(image::open(&shot).is_ok(), "no screenshot");
    let _ = std::fs::remove_dir_all(&dir);
}
