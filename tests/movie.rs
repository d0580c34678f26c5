//! `render TOPOLOGY --trajectory TRAJ`: frames to files through the real
//! binary under validation. Frame k renders the id AOV an XYZR file of
//! frame k's coordinates renders; `--frames` slices (negative, empty);
//! disjoint ranges write exactly the files of one full run; JSON Lines;
//! a cut trajectory renders the frames before the cut and names it;
//! mismatched atom counts and a missing ffmpeg are refused before any work.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn data(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/traj")
        .join(name)
        .display()
        .to_string()
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sphereshade-movie-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str], path_env: Option<&str>) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sphereshade"));
    c.env("XDG_RUNTIME_DIR", std::env::temp_dir()).args(args);
    if let Some(p) = path_env {
        c.env("PATH", p);
    }
    c.output().expect("run sphereshade")
}

fn ok(o: &Output) {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The error: exit 1, and the last stderr line (progress lines may come
/// before it when frames were rendered) is the one error line.
fn err(o: &Output) -> String {
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    let last = e.lines().last().unwrap_or("").to_string();
    assert!(last.starts_with("sphereshade: error: "), "{e}");
    assert_eq!(e.matches("sphereshade: error").count(), 1, "{e}");
    last
}

fn files(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

const SMALL: [&str; 6] = ["--width", "96", "--height", "72", "--validate", "--ssdo"];

/// Writes frame `k` of `traj` (the atoms `keep` keeps, the topology's
/// radii) as an .xyzr in `d`, renders it with `extra` and the camera, and
/// returns the PNG's bytes.
fn render_frame_as_xyzr(
    d: &Path,
    top: &str,
    traj: &str,
    k: usize,
    keep: &dyn Fn(usize) -> bool,
    extra: &[&str],
    cam: &[&str],
) -> Vec<u8> {
    let scene =
        sphereshade::scene::load(Path::new(top), &Default::default(), &mut |_, _| {}).unwrap();
    let mut r = sphereshade::traj::open(Path::new(traj)).unwrap();
    let mut f = sphereshade::traj::Frame::default();
    r.read(k, &mut f).unwrap();
    assert_eq!(f.positions.len(), scene.spheres.len());
    let text: String = f
        .positions
        .iter()
        .zip(&scene.spheres)
        .enumerate()
        .filter(|(i, _)| keep(*i))
        .map(|(_, (p, s))| format!("{} {} {} {}\n", p[0], p[1], p[2], s.radius))
        .collect();
    let xyzr = d.join(format!("frame{k}.xyzr"));
    std::fs::write(&xyzr, text).unwrap();
    let single = d.join("single.png");
    let mut a = vec!["render", xyzr.to_str().unwrap()];
    a.extend(SMALL);
    a.push("plain");
    a.extend(extra);
    a.extend(["--out", single.to_str().unwrap()]);
    a.extend(cam);
    ok(&run(&a, None));
    std::fs::read(&single).unwrap()
}

fn traj_args<'a>(top: &'a str, traj: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = vec!["render", top, "--trajectory", traj];
    a.extend(SMALL);
    a.push("plain");
    a.extend(extra);
    a
}

#[test]
fn frame_k_renders_like_an_xyzr_of_its_coordinates() {
    let d = dir("xyzr");
    let (top, traj) = (data("adk_open.pdb"), data("adk_dims.dcd"));
    let pattern = d.join("id_%02d.png");
    // (one explicit camera for both: a trajectory's camera is fitted to
    // its frame 0, the XYZR's to itself)
    let cam = ["--view-center", "0,0,0", "--view-height", "90"];
    let mut a = traj_args(
        &top,
        &traj,
        &[
            "--frames",
            "40",
            "--aov",
            "id",
            "--out",
            pattern.to_str().unwrap(),
        ],
    );
    a.extend(cam);
    ok(&run(&a, None));
    // frame 40's coordinates with the topology's radii, as .xyzr
    let from_file = render_frame_as_xyzr(&d, &top, &traj, 40, &|_| true, &["--aov", "id"], &cam);
    let from_traj = std::fs::read(d.join("id_40.png")).unwrap();
    assert!(
        from_traj == from_file,
        "frame 40 of the DCD and its XYZR give different id images"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn ranges_split_across_runs_write_the_files_of_one_run() {
    let (top, traj) = (data("adk_oplsaa.gro"), data("adk_oplsaa.xtc"));
    let full = dir("full");
    let split = dir("split");
    let out = |d: &Path| d.join("f_%05d.png").display().to_string();
    let fo = out(&full);
    let json = full.join("stats.jsonl").display().to_string();
    ok(&run(
        &traj_args(&top, &traj, &["--out", &fo, "--json", &json]),
        None,
    ));
    let so = out(&split);
    for range in ["0:4", "4:"] {
        ok(&run(
            &traj_args(&top, &traj, &["--frames", range, "--out", &so]),
            None,
        ));
    }
    let names: Vec<String> = (0..10).map(|k| format!("f_{k:05}.png")).collect();
    let mut want = names.clone();
    want.push("stats.jsonl".into());
    want.sort();
    assert_eq!(files(&full), want);
    assert_eq!(files(&split), names);
    for n in &names {
        assert!(
            std::fs::read(full.join(n)).unwrap() == std::fs::read(split.join(n)).unwrap(),
            "{n} differs between one run and two"
        );
    }
    // JSON Lines: one render object per frame, with frame and time
    let text = std::fs::read_to_string(full.join("stats.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 10);
    for (k, v) in lines.iter().enumerate() {
        assert_eq!(v["frame"], k);
        let t = v["time_ps"].as_f64().unwrap();
        assert!((t - 100.0 * k as f64).abs() < 1e-3, "frame {k}: time {t}");
        assert_eq!(v["spheres"], 47681);
        assert_eq!(v["validation_messages"], 0);
        assert!(v["passes"].as_array().is_some_and(|p| !p.is_empty()));
    }
    // negative and stepped slices name the files by frame index
    let neg = dir("neg");
    ok(&run(
        &traj_args(&top, &traj, &["--frames", "-3::2", "--out", &out(&neg)]),
        None,
    ));
    assert_eq!(files(&neg), vec!["f_00007.png", "f_00009.png"]);
    // an empty selection is refused
    let e = err(&run(
        &traj_args(&top, &traj, &["--frames", "5:2", "--out", &out(&neg)]),
        None,
    ));
    assert!(
        e.contains("selects no frame") && e.contains("10 frame"),
        "{e}"
    );
    let e = err(&run(
        &traj_args(&top, &traj, &["--frames", "1:2:0", "--out", &out(&neg)]),
        None,
    ));
    assert!(e.contains("step must be at least 1"), "{e}");
    for d in [full, split, neg] {
        let _ = std::fs::remove_dir_all(&d);
    }
}

#[test]
fn refusals_before_any_work_and_a_cut_trajectory() {
    let d = dir("refuse");
    let out = d.join("f_%d.png").display().to_string();
    // atom counts differ: both files and counts named
    let e = err(&run(
        &traj_args(
            &data("adk_open.pdb"),
            &data("adk_oplsaa.xtc"),
            &["--out", &out],
        ),
        None,
    ));
    assert!(
        e.contains("3341") && e.contains("47681") && e.contains("adk_oplsaa.xtc"),
        "{e}"
    );
    // --movie without ffmpeg on PATH
    let movie = d.join("m.mp4").display().to_string();
    let e = err(&run(
        &traj_args(
            &data("adk_oplsaa.gro"),
            &data("adk_oplsaa.xtc"),
            &["--movie", &movie],
        ),
        Some("/nonexistent"),
    ));
    assert!(e.contains("--movie needs ffmpeg"), "{e}");
    // an output name without the frame index
    let e = err(&run(
        &traj_args(
            &data("adk_oplsaa.gro"),
            &data("adk_oplsaa.xtc"),
            &["--out", d.join("x.png").to_str().unwrap()],
        ),
        None,
    ));
    assert!(e.contains("%d"), "{e}");
    assert!(files(&d).is_empty(), "{:?}", files(&d));
    // cut inside frame 6: frames 0-5 are rendered, then one line naming
    // the file, the frame and its byte offset, exit 1
    let bytes = std::fs::read(data("adk_oplsaa.xtc")).unwrap();
    let cut = d.join("cut.xtc");
    std::fs::write(&cut, &bytes[..bytes.len() * 65 / 100]).unwrap();
    let e = err(&run(
        &traj_args(
            &data("adk_oplsaa.gro"),
            cut.to_str().unwrap(),
            &["--out", &out],
        ),
        None,
    ));
    assert!(
        e.contains("cut.xtc: frame 6 at byte") && e.contains("6 frames before it"),
        "{e}"
    );
    let pngs: Vec<String> = files(&d)
        .into_iter()
        .filter(|f| f.ends_with(".png"))
        .collect();
    assert_eq!(
        pngs,
        (0..6).map(|k| format!("f_{k}.png")).collect::<Vec<_>>()
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_movie_through_ffmpeg() {
    if Command::new("ffmpeg").arg("-version").output().is_err() {
        panic!("ffmpeg is missing: run tools/setup.sh");
    }
    let d = dir("mp4");
    let movie = d.join("adk.mp4");
    ok(&run(
        &traj_args(
            &data("adk_oplsaa.gro"),
            &data("adk_oplsaa.xtc"),
            &[
                "--frames",
                "::3",
                "--movie",
                movie.to_str().unwrap(),
                "--fps",
                "10",
                "--orbit",
                "5",
            ],
        ),
        None,
    ));
    let probe = Command::new("ffprobe")
        .args([
            "-v",
            "error",
            "-count_frames",
            "-show_entries",
            "stream=width,height,nb_read_frames,codec_name",
            "-of",
            "csv=p=0",
        ])
        .arg(&movie)
        .output()
        .expect("ffprobe");
    let info = String::from_utf8_lossy(&probe.stdout).trim().to_string();
    assert_eq!(info, "h264,96,72,4", "{info}");
    assert_eq!(files(&d), vec!["adk.mp4"]);
    let _ = std::fs::remove_dir_all(&d);
}

/// A movie is written whole or not at all: a trajectory cut in the middle
/// leaves no MP4 (and no temporary file), and SIGINT during the run
/// removes the temporary file; each says in one line how many frames had
/// been rendered.
#[test]
fn a_movie_is_whole_or_absent() {
    if Command::new("ffmpeg").arg("-version").output().is_err() {
        panic!("ffmpeg is missing: run tools/setup.sh");
    }
    let d = dir("whole");
    let bytes = std::fs::read(data("adk_oplsaa.xtc")).unwrap();
    let cut = d.join("cut.xtc");
    std::fs::write(&cut, &bytes[..bytes.len() * 65 / 100]).unwrap();
    let movie = d.join("m.mp4");
    let e = err(&run(
        &traj_args(
            &data("adk_oplsaa.gro"),
            cut.to_str().unwrap(),
            &["--movie", movie.to_str().unwrap()],
        ),
        None,
    ));
    assert!(
        e.contains("cut.xtc: frame 6 at byte")
            && e.contains("6 frame(s) had been rendered; no movie written"),
        "{e}"
    );
    assert_eq!(files(&d), vec!["cut.xtc"]);

    // SIGINT once the temporary movie exists
    let (top, traj) = (data("adk_oplsaa.gro"), data("adk_oplsaa.xtc"));
    let args = traj_args(&top, &traj, &["--movie", movie.to_str().unwrap()]);
    let child = Command::new(env!("CARGO_BIN_EXE_sphereshade"))
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .args(&args)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("spawn");
    let started = std::time::Instant::now();
    while !files(&d).iter().any(|f| f.contains(".tmp.")) {
        assert!(
            started.elapsed().as_secs() < 60,
            "no temporary movie appeared"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let killed = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill");
    assert!(killed.success());
    let o = child.wait_with_output().expect("wait");
    let e = err(&o);
    assert!(
        e.contains("interrupted by a signal") && e.contains("no movie written"),
        "{e}"
    );
    assert_eq!(files(&d), vec!["cut.xtc"]);
    let _ = std::fs::remove_dir_all(&d);
}

/// A LAMMPS dump whose second `ITEM: TIMESTEP` line is damaged renders
/// frame 0, then stops with one line naming frame 1 and its byte offset
/// (it lost frame 1 and renumbered the rest before); a dump whose last
/// line has no newline renders every frame, as a trajectory and as a
/// structure.
/// A multi-frame XYZ with a `nan` in frame 1: frame 0 rendered, one line.
#[test]
fn text_trajectories_stop_at_a_nan() {
    let d = dir("xyznan");
    let frames = [
        "3\nf0\nC 0 0 0\nO 1.5 0 0\nN 0 1.5 0\n",
        "3\nf1\nC 0 0 0\nO nan 0 0\nN 0 1.5 0\n",
        "3\nf2\nC 0 0 0\nO 1.5 0 0\nN 0 1.5 0\n",
    ];
    let p = d.join("t.xyz");
    std::fs::write(&p, frames.concat()).unwrap();
    let top = d.join("top.xyz");
    std::fs::write(&top, frames[0]).unwrap();
    let out = d.join("x_%d.png").display().to_string();
    let e = err(&run(
        &traj_args(top.to_str().unwrap(), p.to_str().unwrap(), &["--out", &out]),
        None,
    ));
    let at = frames[0].len();
    assert!(
        e.contains(&format!("t.xyz: frame 1 at byte {at}"))
            && e.contains("the 1 frames before it were rendered and written"),
        "{e}"
    );
    let pngs: Vec<String> = files(&d)
        .into_iter()
        .filter(|f| f.ends_with(".png"))
        .collect();
    assert_eq!(pngs, vec!["x_0.png"]);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn lammps_frames_are_read_whole_or_named() {
    let d = dir("lammps");
    let src = std::fs::read(data("image_vf.lammpstrj")).unwrap();
    let starts: Vec<usize> = (0..src.len())
        .filter(|&k| src[k..].starts_with(b"ITEM: TIMESTEP"))
        .collect();
    assert_eq!(starts.len(), 3);
    let mut bad = src.clone();
    bad[starts[1] + 13] = b'X'; // ITEM: TIMESTEX
    let bad_path = d.join("bad.lammpstrj");
    std::fs::write(&bad_path, &bad).unwrap();
    let out = d.join("f_%d.png").display().to_string();
    let top = data("image_vf.lammpstrj");
    let e = err(&run(
        &traj_args(&top, bad_path.to_str().unwrap(), &["--out", &out]),
        None,
    ));
    assert!(
        e.contains(&format!("bad.lammpstrj: frame 1 at byte {}", starts[1]))
            && e.contains("'ITEM: TIMESTEX'")
            && e.matches("bad.lammpstrj").count() == 1,
        "{e}"
    );
    let pngs: Vec<String> = files(&d)
        .into_iter()
        .filter(|f| f.ends_with(".png"))
        .collect();
    assert_eq!(pngs, vec!["f_0.png"]);

    // a `nan` coordinate in frame 1: stopped there, frame 0 kept
    let mut nan = src.clone();
    let line = starts[1]
        + nan[starts[1]..]
            .windows(11)
            .position(|w| w == b"ITEM: ATOMS")
            .unwrap();
    let row = line + nan[line..].iter().position(|&b| b == b'\n').unwrap() + 1;
    // the first number after the atom's id and type
    let mut k = row;
    for _ in 0..2 {
        k += nan[k..].iter().position(|&b| b == b' ').unwrap() + 1;
    }
    let end = k + nan[k..].iter().position(|&b| b == b' ').unwrap();
    nan.splice(k..end, b"nan".iter().copied());
    let nan_path = d.join("nan.lammpstrj");
    std::fs::write(&nan_path, &nan).unwrap();
    let out3 = d.join("q_%d.png").display().to_string();
    let e = err(&run(
        &traj_args(&top, nan_path.to_str().unwrap(), &["--out", &out3]),
        None,
    ));
    assert!(
        e.contains(&format!("nan.lammpstrj: frame 1 at byte {}", starts[1]))
            && e.contains("the 1 frames before it were rendered and written"),
        "{e}"
    );
    let q: Vec<String> = files(&d)
        .into_iter()
        .filter(|f| f.starts_with("q_"))
        .collect();
    assert_eq!(q, vec!["q_0.png"]);

    let nonl = d.join("nonl.lammpstrj");
    std::fs::write(&nonl, src.strip_suffix(b"\n").unwrap()).unwrap();
    let out2 = d.join("n_%d.png").display().to_string();
    ok(&run(
        &traj_args(&top, nonl.to_str().unwrap(), &["--out", &out2]),
        None,
    ));
    let n: Vec<String> = files(&d)
        .into_iter()
        .filter(|f| f.starts_with("n_"))
        .collect();
    assert_eq!(n, vec!["n_0.png", "n_1.png", "n_2.png"]);
    let s = d.join("s.png");
    ok(&run(
        &[
            "render",
            nonl.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--validate",
            "--out",
            s.to_str().unwrap(),
        ],
        None,
    ));
    let _ = std::fs::remove_dir_all(&d);
}

/// The binary readers stop at a damaged frame (cut, bad magic, a bad
/// record marker, a NaN coordinate or precision) with one line naming the
/// file, the frame and its byte offset, after rendering exactly the frames
/// before it (numbered by their index; none skipped).
#[test]
fn binary_trajectories_stop_at_the_damage() {
    let d = dir("damage");
    let gro = data("adk_oplsaa.gro");
    let pdb = data("adk_open.pdb");
    let mut cases: Vec<(String, PathBuf, &str, usize)> = Vec::new();
    for ext in ["xtc", "trr"] {
        let bytes = std::fs::read(data(&format!("adk_oplsaa.{ext}"))).unwrap();
        let cut = d.join(format!("cut.{ext}"));
        std::fs::write(&cut, &bytes[..bytes.len() * 65 / 100]).unwrap();
        cases.push((gro.clone(), cut, "frame 6 at byte", 6));
        // the third frame's magic number damaged
        let magic = &bytes[..4];
        let second = 4 + bytes[4..].windows(4).position(|w| w == magic).unwrap();
        let third = second
            + 4
            + bytes[second + 4..]
                .windows(4)
                .position(|w| w == magic)
                .unwrap();
        let mut bad = bytes.clone();
        bad[third..third + 4].copy_from_slice(&[0xde, 0xad, 0xbe, 0xef]);
        let p = d.join(format!("magic.{ext}"));
        std::fs::write(&p, &bad).unwrap();
        cases.push((gro.clone(), p, "frame 2 at byte", 2));
    }
    let dcd = std::fs::read(data("adk_dims.dcd")).unwrap();
    let cut = d.join("cut.dcd");
    std::fs::write(&cut, &dcd[..dcd.len() * 65 / 100]).unwrap();
    cases.push((pdb.clone(), cut, "frame 63 at byte", 63));
    // frame 2 located by the reader itself (the index of frame starts)
    let start = |file: &str, k: usize| {
        let r = sphereshade::traj::open(Path::new(&data(file))).unwrap();
        r.offset(k) as usize
    };
    let write = |name: &str, bytes: &[u8]| {
        let p = d.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    };
    // DCD: frame 2's first record marker damaged
    let mut bad = dcd.clone();
    let f2 = start("adk_dims.dcd", 2);
    bad[f2..f2 + 4].copy_from_slice(&7u32.to_le_bytes());
    let at = format!("frame 2 at byte {f2}:");
    cases.push((pdb.clone(), write("marker.dcd", &bad), &at, 2));
    // non-finite values: a NaN coordinate in frame 2 (DCD, TRR) and a NaN
    // XTC precision (its coordinates decode to NaN)
    let mut bad = dcd.clone();
    let x = f2 + 4 + 4 * 100;
    bad[x..x + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let nan_dcd = format!("frame 2 at byte {f2}: atom 100 is at [NaN");
    cases.push((pdb, write("nan.dcd", &bad), &nan_dcd, 2));
    let xtc = std::fs::read(data("adk_oplsaa.xtc")).unwrap();
    let x2 = start("adk_oplsaa.xtc", 2);
    let mut bad = xtc.clone();
    // magic, atoms, step, time, box (9 floats), atoms again, precision
    bad[x2 + 56..x2 + 60].copy_from_slice(&f32::NAN.to_be_bytes());
    let nan_xtc = format!("frame 2 at byte {x2}: atom 0 is at [NaN");
    cases.push((gro.clone(), write("nan.xtc", &bad), &nan_xtc, 2));
    let trr = std::fs::read(data("adk_oplsaa.trr")).unwrap();
    let t2 = start("adk_oplsaa.trr", 2);
    let be = |at: usize| i32::from_be_bytes(trr[at..at + 4].try_into().unwrap()) as usize;
    // header: magic, 2 string lengths, the string, 13 sizes and counts,
    // then t and lambda (doubles when the box is)
    let text = be(t2 + 8).div_ceil(4) * 4;
    let sizes = t2 + 12 + text;
    let (box_size, vir, pres) = (be(sizes + 8), be(sizes + 12), be(sizes + 16));
    let real = if box_size == 72 { 8 } else { 4 };
    let x_at = sizes + 13 * 4 + 2 * real + box_size + vir + pres;
    let mut bad = trr.clone();
    bad[x_at + 30 * real..x_at + 31 * real].copy_from_slice(&if real == 8 {
        f64::NAN.to_be_bytes().to_vec()
    } else {
        f32::NAN.to_be_bytes().to_vec()
    });
    let nan_trr = format!("frame 2 at byte {t2}: atom 10 is at [NaN");
    cases.push((gro, write("nan.trr", &bad), &nan_trr, 2));
    for (top, traj, frag, frames) in cases {
        let name = traj
            .file_name()
            .unwrap()
            .to_string_lossy()
            .replace('.', "_");
        let out = d.join(format!("{name}_%d.png")).display().to_string();
        let e = err(&run(
            &traj_args(&top, traj.to_str().unwrap(), &["--out", &out]),
            None,
        ));
        let shown = traj.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            e.contains(&format!("{shown}: {frag}"))
                && e.contains(&format!(
                    "the {frames} frames before it were rendered and written"
                )),
            "{shown}: {e}"
        );
        let mut pngs: Vec<String> = files(&d)
            .into_iter()
            .filter(|f| f.starts_with(&format!("{name}_")))
            .collect();
        pngs.sort_by_key(|f| f.len());
        assert_eq!(
            pngs,
            (0..frames)
                .map(|k| format!("{name}_{k}.png"))
                .collect::<Vec<_>>(),
            "{shown}"
        );
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// `--hide` on a trajectory: every frame keeps the subset (the hidden
/// atoms' coordinates are read and dropped); frame 40 renders as an XYZR
/// of its kept coordinates, and its id image (input order) never shows a
/// hidden atom.
#[test]
fn hidden_atoms_stay_hidden_in_every_frame() {
    let d = dir("hide");
    let (top, traj) = (data("adk_open.pdb"), data("adk_dims.dcd"));
    let cam = ["--view-center", "0,0,0", "--view-height", "90"];
    let rule = ["--hide", "resid 1-60 or name CA", "--color", "200,180,90"];
    let frame = |aov: &str| {
        let pattern = d.join(format!("{aov}_%02d.png"));
        let mut a = traj_args(
            &top,
            &traj,
            &[
                "--frames",
                "38:41",
                "--aov",
                aov,
                "--out",
                pattern.to_str().unwrap(),
            ],
        );
        a.extend(cam);
        a.extend(rule);
        ok(&run(&a, None));
        std::fs::read(d.join(format!("{aov}_40.png"))).unwrap()
    };
    let (color, ids) = (frame("color"), frame("id"));
    // which atoms the rule hides, from the PDB's own columns
    let text = std::fs::read_to_string(&top).unwrap();
    let hidden: Vec<bool> = text
        .lines()
        .filter(|l| l.starts_with("ATOM  ") || l.starts_with("HETATM"))
        .map(|l| {
            let resid: i64 = l[22..26].trim().parse().unwrap();
            (1..=60).contains(&resid) || l[12..16].trim() == "CA"
        })
        .collect();
    let n_hidden = hidden.iter().filter(|&&h| h).count();
    assert!(n_hidden > 500 && n_hidden < hidden.len());
    let img = image::load_from_memory(&ids).unwrap().to_rgba8();
    let mut seen = 0;
    for p in img.pixels() {
        let v = p[0] as usize | (p[1] as usize) << 8 | (p[2] as usize) << 16;
        if v > 0 {
            assert!(!hidden[v - 1], "hidden atom {} in frame 40's ids", v - 1);
            seen += 1;
        }
    }
    assert!(seen > 500);
    // frame 40's kept coordinates with the topology's radii, as .xyzr
    let keep = |i: usize| !hidden[i];
    let single = render_frame_as_xyzr(&d, &top, &traj, 40, &keep, &rule[2..], &cam);
    assert!(
        color == single,
        "frame 40 with --hide differs from its kept coordinates"
    );
    let _ = std::fs::remove_dir_all(&d);
}
