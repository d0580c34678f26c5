//! The binary's contract: exit codes, one clear error line naming the
//! file/line/option/feature, no partial output files, JSON schema, stable
//! image hashes, and the bench JSON. Runs the real `sphereshade` binary.

use std::path::PathBuf;
use std::process::{Command, Output};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sphereshade"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir());
    c
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sphereshade-cli-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&d);
    d.join(name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run sphereshade")
}

/// A small procedural bench matrix: scene, sphere counts, sizes, shadow
/// modes, `frames` measured after `warmup` (SSDO off).
struct Matrix<'a> {
    scene: &'a str,
    atoms: &'a str,
    size: &'a str,
    shadows: &'a str,
    frames: &'a str,
    warmup: &'a str,
}

/// `bench` on matrix `m` into `json`, then `extra`.
fn bench(m: &Matrix, json: &std::path::Path, extra: &[&str]) -> Output {
    let Matrix {
        scene,
        atoms,
        size,
        shadows,
        frames,
        warmup,
    } = *m;
    let mut a = vec![
        "bench",
        "--scene",
        scene,
        "--atoms",
        atoms,
        "--size",
        size,
        "--shadows",
        shadows,
        "--ssdo",
        "off",
        "--frames",
        frames,
        "--warmup",
        warmup,
        "--json",
    ];
    a.push(json.to_str().unwrap());
    a.extend(extra);
    run(&a)
}

const SMALL: [&str; 6] = ["--width", "96", "--height", "64", "--scene", "random"];

#[test]
fn malformed_files_fail_with_file_and_line_and_no_png() {
    let cases: [(&str, &str, &str); 4] = [
        ("bad.xyzr", "1 2 3 1.5\n4 5 nan 1.0\n", ":2:"),
        ("short.xyzr", "1 2 3\n", ":1:"),
        ("empty.pdb", "", "no spheres"),
        (
            "trunc.pdb",
            "ATOM      1  CA  ALA A   1      11.104   6.134\n",
            ":1:",
        ),
    ];
    for (name, text, needle) in cases {
        let input = tmp(name);
        std::fs::write(&input, text).unwrap();
        let out = tmp(&format!("{name}.png"));
        let o = run(&[
            "render",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--width",
            "32",
            "--height",
            "32",
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{name}: {err}");
        assert!(
            err.contains(name) && err.contains(needle),
            "{name}: error does not name file and line: {err}"
        );
        assert_eq!(
            err.trim().lines().count(),
            1,
            "{name}: expected one error line, got: {err}"
        );
        assert!(!out.exists(), "{name}: a PNG was written for a failed run");
    }
    // (-o is --out's short form)
    let o = run(&["render", "x.unknown", "-o", tmp("u.png").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("x.unknown"), "{}", stderr(&o));
    // a missing file: its name and the system's reason, said once
    let missing = tmp("missing.pdb");
    let o = run(&[
        "render",
        missing.to_str().unwrap(),
        "--out",
        tmp("m.png").to_str().unwrap(),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("missing.pdb"), "{err}");
    assert_eq!(err.matches("os error 2").count(), 1, "{err}");
}

#[test]
fn bad_options_are_named() {
    let png = tmp("opt.png");
    for (args, needle) in [
        (vec!["--opacity", "2"], "--opacity"),
        (vec!["--view-dir", "0,0,0"], "--view-dir"),
        (vec!["--issm-t", "lots"], "--issm-t"),
        (vec!["--replicate", "1000x1000x1000"], "--replicate"),
        (vec!["--ssaa", "5"], "--ssaa"),
        (vec!["--outline", "-1"], "--outline"),
        (vec!["--tile-size", "4"], "--tile-size"),
        (vec!["--png-depth", "12"], "--png-depth"),
        (vec!["--aov", "id", "--png-depth", "16"], "--png-depth 16"),
    ] {
        let mut a = vec!["render", "--out", png.to_str().unwrap()];
        a.extend(SMALL);
        a.extend(args.iter());
        let o = run(&a);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
    }
    // clap rejects malformed values with its usage exit code
    for (flag, value) in [
        ("--light", "1,2"),
        ("--background", "1,2"),
        ("--fog", "5,1"),
    ] {
        let o = run(&["render", "--out", png.to_str().unwrap(), flag, value]);
        assert_ne!(o.status.code(), Some(0));
        assert!(stderr(&o).contains(flag), "{flag}: {}", stderr(&o));
    }
    assert!(!png.exists());
    // bench's orbit: a finite step, not with --no-orbit
    let json = tmp("opt.json");
    for args in [vec!["--orbit", "inf"], vec!["--orbit", "2", "--no-orbit"]] {
        let mut a = vec!["bench", "--json", json.to_str().unwrap()];
        a.extend(args.iter());
        let o = run(&a);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("--orbit"), "{args:?}: {}", stderr(&o));
    }
    assert!(!json.exists());
    // an EXR holds every layer; --aov is for PNGs
    let exr = tmp("opt.exr");
    let mut a = vec!["render", "--out", exr.to_str().unwrap(), "--aov", "id"];
    a.extend(SMALL);
    let o = run(&a);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("--aov applies to PNG"),
        "{}",
        stderr(&o)
    );
    assert!(!exr.exists());
    // the window has one sample per pixel
    let o = run(&["view", "--ssaa", "2"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("--ssaa and --tile-size apply to `render`"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn missing_device_feature_is_one_clear_line() {
    let o = bin()
        .env("SPHERESHADE_DENY_FEATURE", "shaderBufferInt64Atomics")
        .args(["render", "--out", tmp("f.png").to_str().unwrap()])
        .args(SMALL)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("lacks required Vulkan feature(s): shaderBufferInt64Atomics"),
        "{err}"
    );
    // every missing feature is named, not only the first
    let o = bin()
        .env(
            "SPHERESHADE_DENY_FEATURE",
            "shaderInt64,shaderBufferInt64Atomics",
        )
        .args(["render", "--out", tmp("f.png").to_str().unwrap()])
        .args(SMALL)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert!(
        err.contains("shaderInt64, shaderBufferInt64Atomics") && err.lines().count() == 1,
        "{err}"
    );
    let o = run(&[
        "render",
        "--device",
        "99",
        "--out",
        tmp("d.png").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--device 99"), "{}", stderr(&o));
}

#[test]
fn validated_render_writes_schema_json_and_stable_hash() {
    let mut hashes = Vec::new();
    for k in 0..2 {
        let png = tmp(&format!("v{k}.png"));
        let json = tmp(&format!("v{k}.json"));
        let mut a = vec![
            "render",
            "--validate",
            "--out",
            png.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ];
        a.extend(SMALL);
        a.extend(["--atoms", "500", "--frames", "2"]);
        let o = run(&a);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        for key in [
            "device",
            "driver",
            "input",
            "spheres",
            "width",
            "height",
            "frames",
            "shadows",
            "ssdo",
            "raster",
            "opacity",
            "passes",
            "total_ms",
            "load_ms",
            "gpu_memory_bytes",
            "validation_messages",
            "deep",
            "image_sha256",
        ] {
            assert!(v.get(key).is_some(), "JSON lacks {key}");
        }
        assert_eq!(v["validation_messages"], 0);
        // Memory by class adds up to the total; the classes this frame needs are there.
        let classes = v["gpu_memory"].as_object().expect("gpu_memory object");
        let sum: u64 = classes.values().map(|b| b.as_u64().unwrap()).sum();
        assert_eq!(sum, v["gpu_memory_bytes"].as_u64().unwrap());
        for class in ["scene", "visibility", "gbuffer", "issm_map"] {
            assert!(classes[class].as_u64().unwrap() > 0, "{class}: {classes:?}");
        }
        assert_eq!(v["spheres"], 500);
        assert_eq!(v["shadows"], "issm-soft");
        assert_eq!(v["ssdo"], "semantic");
        let passes = v["passes"].as_array().unwrap();
        let mut names: Vec<&str> = passes.iter().map(|p| p["name"].as_str().unwrap()).collect();
        for p in passes {
            assert!(p["median_ms"].as_f64().unwrap() > 0.0, "{p}");
            assert!(p["min_ms"].as_f64().unwrap() <= p["max_ms"].as_f64().unwrap());
        }
        for want in [
            "raster",
            "issm_raster",
            "issm_resolve",
            "ssdo_prep",
            "ssdo",
            "shade",
        ] {
            assert!(names.contains(&want), "pass {want} missing from {names:?}");
        }
        // spheres this small on screen take per-sphere SSDO, which has no
        // blur (DESIGN.md: a pass a mode does not run is not listed)
        assert!(
            !names.contains(&"blur_h") && !names.contains(&"blur_v"),
            "{names:?}"
        );
        names.sort();
        names.dedup();
        assert_eq!(names.len(), passes.len(), "duplicate pass names");
        hashes.push(v["image_sha256"].as_str().unwrap().to_string());
        let img = image::open(&png).expect("png");
        assert_eq!((img.width(), img.height()), (96, 64));
    }
    assert_eq!(
        hashes[0], hashes[1],
        "two runs of the same scene produced different images"
    );
}

#[test]
fn aov_encodings_follow_design() {
    let xyzr = tmp("two.xyzr");
    // two spheres side by side; ids 1 and 2
    std::fs::write(&xyzr, "# two\n-3 0 0 2\n3 0 0 2\n").unwrap();
    let base = |aov: &str, out: &PathBuf| {
        let o = run(&[
            "render",
            xyzr.to_str().unwrap(),
            "--aov",
            aov,
            "--out",
            out.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "32",
            "--ssdo",
            "off",
            "--shadows",
            "issm",
        ]);
        assert_eq!(o.status.code(), Some(0), "{aov}: {}", stderr(&o));
        image::open(out).expect("png")
    };
    let id = base("id", &tmp("id.png")).to_rgba8();
    assert_eq!(id.get_pixel(0, 0).0, [0, 0, 0, 255], "background id");
    assert_eq!(
        id.get_pixel(21, 16).0,
        [1, 0, 0, 255],
        "left sphere is index 0 -> 1"
    );
    assert_eq!(
        id.get_pixel(42, 16).0,
        [2, 0, 0, 255],
        "right sphere is index 1 -> 2"
    );
    let depth = base("depth", &tmp("depth.png"));
    let d = depth.as_luma16().expect("16-bit depth");
    assert_eq!(d.get_pixel(0, 0).0[0], 65535, "background depth");
    let centre = d.get_pixel(21, 16).0[0];
    assert!(
        centre < 2000,
        "sphere centre is among the nearest: {centre}"
    );
    let sh = base("shadow", &tmp("shadow.png"));
    let s = sh.as_luma8().expect("8-bit shadow");
    assert_eq!(s.get_pixel(0, 0).0[0], 255, "background shadow");
    let ao = base("ao", &tmp("ao.png"));
    assert!(ao.as_luma8().is_some(), "8-bit ao");
}

#[test]
fn bench_writes_runs_and_ratios() {
    let json = tmp("bench.json");
    let o = bench(
        &Matrix {
            scene: "random",
            atoms: "1500",
            size: "64x48",
            shadows: "none,issm,issm-soft",
            frames: "2",
            warmup: "0",
        },
        &json,
        &[],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let runs = v["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 3);
    assert!(
        v["ratios"]
            .as_object()
            .unwrap()
            .keys()
            .any(|k| k.starts_with("issm_overhead"))
    );
    // The runs were measured together: the local run carries its frames of
    // the cached rounds, and the cached ratio divides by them.
    assert_eq!(runs[0]["shadows"], "none");
    assert_eq!(runs[1]["shadows"], "issm");
    let ratio = v["ratios"]
        .as_object()
        .unwrap()
        .iter()
        .find(|(k, _)| k.starts_with("issm_cached_overhead"))
        .and_then(|(_, r)| r.as_f64())
        .unwrap();
    // (the median of the per-frame ratios of the rounds)
    let frames = |i: usize| -> Vec<f64> {
        runs[i]["light_cached"]["frame_ms"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| t.as_f64().unwrap())
            .collect()
    };
    let (h, l) = (frames(1), frames(0));
    assert_eq!(h.len(), 2);
    assert_eq!(l.len(), 2);
    let want = 0.5 * (h[0] / l[0] + h[1] / l[1]);
    assert!((ratio - want).abs() < 1e-9, "{ratio} vs {want}");
    assert_eq!(runs[2]["frame_ms"].as_array().unwrap().len(), 2);
    assert!(
        stderr(&o).contains("measuring 3 runs together"),
        "{}",
        stderr(&o)
    );
    // --compare against itself: every ratio is exactly 1
    let o = bench(
        &Matrix {
            scene: "random",
            atoms: "1500",
            size: "64x48",
            shadows: "none",
            frames: "1",
            warmup: "0",
        },
        &tmp("bench2.json"),
        &["--compare", json.to_str().unwrap()],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("compare"));
}

/// A run the device cannot make (a G-buffer over the storage-buffer limit)
/// is reported and the matrix goes on; the JSON keeps the good runs and the
/// exit status says something failed.
#[test]
fn bench_keeps_going_past_a_failed_run() {
    let json = tmp("bench-fail.json");
    // (a 16384x16384 image no longer fails: it renders in tiles; an
    // 8192² ISSM map, 512 MiB, does)
    let o = bench(
        &Matrix {
            scene: "random",
            atoms: "300",
            size: "64x48",
            shadows: "none,issm",
            frames: "1",
            warmup: "0",
        },
        &json,
        &["--validate", "--issm-size", "8192"],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 of 2 runs failed"), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["runs"].as_array().unwrap().len(), 1);
    assert_eq!(v["complete"], true);
    // The buffers made before the failing one were destroyed: validation
    // reports no leak at device destruction (charged to the last good run).
    assert_eq!(v["runs"][0]["validation_messages"], 0, "{}", stderr(&o));
    let failed = v["failed"].as_array().unwrap();
    assert_eq!(failed.len(), 1);
    assert!(
        failed[0]["run"].as_str().unwrap().contains("shadows=issm"),
        "{failed:?}"
    );
    assert!(
        failed[0]["error"]
            .as_str()
            .unwrap()
            .contains("maxStorageBufferRange"),
        "{failed:?}"
    );
}

/// Regression: on lavapipe a graphics-raster run used to leave the queue
/// binning timestamps, so every compute run after it read 0 ms for all
/// passes after the first. The passes both modes share must time alike.
#[test]
fn graphics_runs_leave_compute_timings_alone() {
    let json = tmp("bench-graphics.json");
    let o = bench(
        &Matrix {
            scene: "capsid",
            atoms: "3000",
            size: "96x64",
            shadows: "none,issm",
            frames: "2",
            warmup: "1",
        },
        &json,
        &["--raster", "graphics,compute"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let runs = v["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 4);
    // After the raster the two modes run the same passes on the same
    // G-buffer, so those passes must take comparable time (the bug gave the
    // compute runs ~3 % of the graphics runs' time).
    let ms = |shadows: &str, raster: &str, pass: &str| {
        let r = runs
            .iter()
            .find(|r| r["shadows"] == shadows && r["raster"] == raster)
            .expect("run");
        r["passes"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == pass)
            .and_then(|p| p["median_ms"].as_f64())
            .expect("pass")
    };
    for (shadows, pass) in [
        ("none", "shade"),
        ("issm", "issm_raster"),
        ("issm", "shade"),
    ] {
        let (c, g) = (ms(shadows, "compute", pass), ms(shadows, "graphics", pass));
        // Other tests' processes share the 2 cores, so single runs vary by
        // up to ~5x; the bug's ratio was ~0.03.
        assert!(
            c > 0.1 * g && g > 0.1 * c,
            "{shadows} {pass}: compute run {c} ms vs graphics run {g} ms"
        );
    }
}

/// `bench` takes every render option: with the same camera, light and
/// technique parameters it makes exactly the image `render` makes.
#[test]
fn bench_reproduces_a_render_with_the_same_options() {
    let opts = [
        "--view-dir",
        "1,0.2,-1",
        "--up",
        "0,1,0",
        "--fov",
        "35",
        "--light",
        "1,-1,-0.5",
        "--issm-t",
        "1",
        "--soft-s",
        "1.5",
        "--blur",
        "off",
    ];
    // The scene, size and technique, shared by both commands.
    let common = [
        "--scene",
        "random",
        "--atoms",
        "500",
        "--width",
        "80",
        "--height",
        "60",
        "--shadows",
        "issm-soft",
        "--ssdo",
        "plain",
    ];
    let png = tmp("repro.png");
    let json = tmp("repro.json");
    let mut a = vec!["render"];
    a.extend(common);
    a.extend(["--out", png.to_str().unwrap()]);
    a.extend(["--json", json.to_str().unwrap()]);
    a.extend(opts);
    let o = run(&a);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let bjson = tmp("repro-bench.json");
    let mut b = vec!["bench"];
    b.extend(common);
    b.extend(["--frames", "1", "--warmup", "0", "--no-orbit"]);
    b.extend(["--json", bjson.to_str().unwrap()]);
    b.extend(opts);
    let o = run(&b);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&bjson).unwrap()).unwrap();
    assert_eq!(r["runs"][0]["image_sha256"], v["image_sha256"]);
    // and a different option gives a different image (the options arrive)
    let mut c = b.clone();
    let i = c.iter().position(|x| *x == "1.5").unwrap();
    c[i] = "3";
    let o = run(&c);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r2: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&bjson).unwrap()).unwrap();
    assert_ne!(r2["runs"][0]["image_sha256"], v["image_sha256"]);
}

/// A negative value is refused in one line that names its option (clap
/// read `-5` as an unknown flag before).
#[test]
fn negative_values_name_their_option() {
    let out = tmp("negative.png");
    let out = out.to_str().unwrap();
    let json = tmp("negative.json").to_str().unwrap().to_string();
    for (args, option) in [
        (
            &["render", "--scene", "random", "--width", "-5"][..],
            "--width",
        ),
        (
            &["render", "--scene", "random", "--height", "-5"],
            "--height",
        ),
        (&["render", "--scene", "random", "--atoms", "-1"], "--atoms"),
        (
            &["render", "--scene", "random", "--replicate", "-1x1x1"],
            "--replicate",
        ),
        (
            &["render", "--scene", "random", "--semantic-levels", "-1"],
            "--semantic-levels",
        ),
        (&["render", "--scene", "random", "--ssaa", "-1"], "--ssaa"),
        (
            &["render", "--scene", "random", "--background", "-1,0,0"],
            "--background",
        ),
        (
            &["render", "--scene", "random", "--issm-size", "-1"],
            "--issm-size",
        ),
        (&["render", "--scene", "random", "--model", "-1"], "--model"),
        (
            &[
                "render",
                concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb"),
                "--trajectory",
                concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb"),
                "--movie",
                "m.mp4",
                "--fps",
                "-1",
            ],
            "--fps",
        ),
        (
            &[
                "bench", "--scene", "random", "--atoms", "-1", "--json", &json,
            ],
            "--atoms",
        ),
    ] {
        let mut a = args.to_vec();
        a.extend(["--out", out]);
        if args[0] == "bench" || args.contains(&"--movie") {
            a.truncate(a.len() - 2);
        }
        let o = run(&a);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert_eq!(e.trim_end().lines().count(), 1, "{args:?}: {e}");
        assert!(e.contains(option), "{args:?} should name {option}: {e}");
    }
}

/// Degenerate cameras are refused before rendering (they rendered a
/// uniform image and exited 0), and an option a format ignores is refused.
#[test]
fn degenerate_cameras_and_ignored_options_are_refused() {
    let png = tmp("degenerate.png");
    let exr = tmp("degenerate.exr");
    let (png, exr) = (png.to_str().unwrap(), exr.to_str().unwrap());
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb");
    for (extra, out, frag) in [
        (
            &["--view-height", "1e-300"][..],
            png,
            "--view-height 1e-300: a pixel",
        ),
        (&["--fov", "1e-9"], png, "--fov 1e-9: the eye would be"),
        (
            &["--view-dir", "nan,0,1"],
            png,
            "for '--view-dir <VIEW_DIR>': 'nan,0,1': components must be finite",
        ),
        (&["--png-depth", "16"], exr, "--png-depth applies to PNG"),
    ] {
        let mut a = vec![
            "render", data, "--width", "64", "--height", "48", "--out", out,
        ];
        a.extend(extra);
        let o = run(&a);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{extra:?}: {e}");
        assert_eq!(e.trim_end().lines().count(), 1, "{extra:?}: {e}");
        assert!(e.contains(frag), "{extra:?}: {e}");
        assert!(!std::path::Path::new(out).exists(), "{extra:?} wrote {out}");
    }
    // the closest view f32 still resolves renders
    let o = run(&[
        "render",
        data,
        "--width",
        "64",
        "--height",
        "48",
        "--view-height",
        "1e-3",
        "--out",
        png,
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
}

/// Without a Vulkan driver the line says what is missing and how to get
/// it, not the loader's raw result.
#[test]
fn no_vulkan_driver_is_one_clear_line() {
    let out = tmp("nodriver.png");
    let o = bin()
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .args([
            "render", "--scene", "random", "--atoms", "100", "--width", "32", "--height", "32",
            "--out",
        ])
        .arg(&out)
        .output()
        .expect("run");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    assert!(
        e.contains("no Vulkan device found") && e.contains("tools/setup.sh"),
        "{e}"
    );
    assert!(!out.exists());
}

/// A tiled render is encoded row of tiles by row of tiles (streamed PNG,
/// EXR scan-line blocks): the file decodes to the pixels of the untiled
/// render (pixels and file bytes), with sub-pixel samples, for colour (8 and 16 bit), ids, depth
/// and every EXR layer; the JSON's hash is the same too.
#[test]
fn streamed_tiled_files_equal_the_untiled_ones() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb");
    let render = |name: &str, extra: &[&str]| -> (PathBuf, serde_json::Value, String) {
        let out = tmp(name);
        let json = tmp(&format!("{name}.json"));
        let mut a = vec![
            "render",
            data,
            "--width",
            "150",
            "--height",
            "110",
            "--out",
            out.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ];
        a.extend(extra);
        let o = run(&a);
        assert_eq!(o.status.code(), Some(0), "{extra:?}: {}", stderr(&o));
        let v = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        (out, v, stderr(&o))
    };
    let pixels = |p: &PathBuf| image::open(p).unwrap().into_bytes();
    for extra in [
        &["--ssaa", "2"][..],
        &["--png-depth", "16"],
        &["--aov", "id"],
        &["--aov", "depth"],
        &["--aov", "ao", "--shadows", "deep"],
    ] {
        let (whole, a, _) = render("whole.png", extra);
        let mut t = extra.to_vec();
        t.extend(["--tile-size", "40"]);
        let (tiled, b, log) = render("tiled.png", &t);
        assert!(
            log.contains("tiles x samples"),
            "{extra:?} not tiled: {log}"
        );
        assert!(pixels(&whole) == pixels(&tiled), "{extra:?}: pixels differ");
        // one encoder for both: the files themselves are identical
        assert!(
            std::fs::read(&whole).unwrap() == std::fs::read(&tiled).unwrap(),
            "{extra:?}: PNG bytes differ"
        );
        assert_eq!(a["image_sha256"], b["image_sha256"], "{extra:?}");
    }
    let layers = |p: &PathBuf| -> Vec<(String, Vec<u32>)> {
        use exr::prelude::*;
        let img = read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .all_layers()
            .all_attributes()
            .from_file(p)
            .unwrap();
        let l = &img.layer_data[0];
        assert_eq!((l.size.0, l.size.1), (150, 110));
        l.channel_data
            .list
            .iter()
            .map(|c| {
                let v = c.sample_data.values_as_f32().map(f32::to_bits).collect();
                (c.name.to_string(), v)
            })
            .collect()
    };
    let (whole, a, _) = render("whole.exr", &["--ssaa", "2"]);
    let (tiled, b, _) = render("tiled.exr", &["--ssaa", "2", "--tile-size", "40"]);
    let (x, y) = (layers(&whole), layers(&tiled));
    assert_eq!(x.len(), 11);
    for ((n, u), (m, v)) in x.iter().zip(&y) {
        assert_eq!(n, m);
        let differ = u.iter().zip(v).filter(|(p, q)| p != q).count();
        assert_eq!(differ, 0, "EXR layer {n}: {differ} pixels differ");
    }
    assert_eq!(a["image_sha256"], b["image_sha256"]);
}

/// `render --scene meso --atoms ATOMS` with `extra` options, which must
/// succeed; its JSON.
fn meso_json(atoms: &str, extra: &[&str]) -> serde_json::Value {
    let (png, json) = (
        tmp(&format!("meso{atoms}.png")),
        tmp(&format!("meso{atoms}.json")),
    );
    let mut a = vec!["render", "--scene", "meso", "--atoms", atoms];
    a.extend(extra);
    a.extend([
        "--out",
        png.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let o = run(&a);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

/// Memory per instance from the JSON (the bytes-per-instance
/// figure): two meso scenes of 2 and 6 million atoms. The `instances`
/// class is 40 bytes an instance (a rigid transform, 32, and its row:
/// molecule type and first expanded index, 8); the `molecules` class (the atoms stored once, their levels) does
/// not grow with the scene; `spheres_drawn` is at most `spheres`.
#[test]
fn memory_per_instance_is_in_the_json() {
    let small = ["--width", "64", "--height", "48"];
    let (a, b) = (meso_json("2000000", &small), meso_json("6000000", &small));
    let class = |v: &serde_json::Value, c: &str| v["gpu_memory"][c].as_u64().unwrap();
    for v in [&a, &b] {
        let n = v["instances"].as_u64().unwrap();
        assert_eq!(class(v, "instances"), 40 * n, "{v}");
        assert!(v["spheres_drawn"].as_u64().unwrap() <= v["spheres"].as_u64().unwrap());
        assert_eq!(v["unique_atoms"], 17_337);
    }
    // (the virion's 11,681 instances, then the plasma's)
    let plasma = |v: &serde_json::Value| v["instances"].as_u64().unwrap() - 11_681;
    assert!(plasma(&b) > 2 * plasma(&a), "{} {}", plasma(&a), plasma(&b));
    assert_eq!(class(&a, "molecules"), class(&b, "molecules"));
}

/// 10^8 atoms (the meso scene, 24,789 instances) under validation (GPU-AV
/// and synchronization): two frames, zero messages, every atom
/// represented and far fewer drawn; the `scene` class (batches, LOD lists,
/// depth tiles) holds less than 16 bytes per 64 atoms (a 16-byte record
/// per batch alone took 30).
#[test]
fn a_hundred_million_atoms_render_under_validation() {
    let v = meso_json(
        "100000000",
        &[
            "--width",
            "320",
            "--height",
            "180",
            "--frames",
            "2",
            "--validate",
        ],
    );
    assert_eq!(v["validation_messages"], 0);
    let spheres = v["spheres"].as_u64().unwrap();
    assert!(spheres.abs_diff(100_000_000) <= 11_484 / 2, "{spheres}");
    let drawn = v["spheres_drawn"].as_u64().unwrap();
    assert!(drawn > 0 && drawn < spheres / 10, "{drawn} of {spheres}");
    let scene = v["gpu_memory"]["scene"].as_u64().unwrap();
    assert!(
        scene * 64 < 16 * spheres,
        "{scene} bytes for {spheres} atoms"
    );
}
