//! Hostile inputs and careless options (issue "Hardening"): every class is
//! refused with one line and exit status 1, within a time limit and under a
//! 4 GB address-space limit, leaving no file behind; the README's table of
//! refusals is exactly what these cases produce. Runs the real binary.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("sphereshade-hard-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The binary under `ulimit -v` (KiB), with a wall-clock limit.
fn run_limited(args: &[&str], mem_kib: u64, env: &[(&str, &str)]) -> (Output, Duration) {
    let mut c = Command::new("bash");
    c.arg("-c")
        .arg(format!(
            "ulimit -v {mem_kib}; exec timeout 60 \"$0\" \"$@\""
        ))
        .arg(env!("CARGO_BIN_EXE_sphereshade"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    for (k, v) in env {
        c.env(k, v);
    }
    let t = Instant::now();
    let o = c.output().expect("run sphereshade");
    (o, t.elapsed())
}

fn write(path: &Path, bytes: &[u8]) -> String {
    std::fs::write(path, bytes).unwrap();
    path.to_str().unwrap().to_string()
}

/// A small mmCIF with 5,000 atoms of chain A, ten translation operators,
/// assembly 1 = (1-10) ten times over (10^10 operators), assembly 2 =
/// (1-10) four times (10^4 operators x 5,000 atoms = 5e7 spheres),
/// assembly 3 = (1-10) six times (10^6 instances, 5e9 spheres: past the
/// 2^32 ids of a frame that draws every atom).
fn assembly_bomb(path: &Path) -> String {
    let mut t = String::from(
        "data_bomb\nloop_\n_atom_site.group_PDB\n_atom_site.id\n_atom_site.type_symbol\n\
         _atom_site.label_atom_id\n_atom_site.label_comp_id\n_atom_site.label_asym_id\n\
         _atom_site.label_seq_id\n_atom_site.Cartn_x\n_atom_site.Cartn_y\n_atom_site.Cartn_z\n",
    );
    for i in 0..5000 {
        t += &format!(
            "ATOM {} C CA GLY A 1 {:.3} 0.000 0.000\n",
            i + 1,
            i as f64 * 0.1
        );
    }
    t += "#\nloop_\n_pdbx_struct_assembly_gen.assembly_id\n\
          _pdbx_struct_assembly_gen.oper_expression\n_pdbx_struct_assembly_gen.asym_id_list\n";
    t += &format!(
        "1 '{}' A\n2 '{}' A\n3 '{}' A\n#\nloop_\n",
        "(1-10)".repeat(10),
        "(1-10)".repeat(4),
        "(1-10)".repeat(6)
    );
    t += "_pdbx_struct_oper_list.id\n_pdbx_struct_oper_list.type\n";
    for i in 1..=3 {
        for j in 1..=3 {
            t += &format!("_pdbx_struct_oper_list.matrix[{i}][{j}]\n");
        }
        t += &format!("_pdbx_struct_oper_list.vector[{i}]\n");
    }
    for i in 1..=10 {
        // (translations along every axis: the bounds' search has no ties
        // to scan through)
        t += &format!(
            "{i} 'op' 1 0 0 {} 0 1 0 {} 0 0 1 {}\n",
            i * 300,
            i * 170,
            i * 90
        );
    }
    t += "#\n";
    write(path, t.as_bytes())
}

fn gzip(path: &Path, chunk: &[u8], times: usize) -> String {
    let f = std::fs::File::create(path).unwrap();
    let mut e = flate2::write::GzEncoder::new(f, flate2::Compression::best());
    for _ in 0..times {
        e.write_all(chunk).unwrap();
    }
    e.finish().unwrap();
    path.to_str().unwrap().to_string()
}

struct Case {
    name: &'static str,
    args: Vec<String>,
    expect: &'static str,
    env: Vec<(&'static str, &'static str)>,
}

fn cases(d: &Path) -> Vec<Case> {
    let out = d.join("out.png").to_str().unwrap().to_string();
    let small = ["--width", "32", "--height", "24"];
    let file = |name: &str, body: &[u8]| write(&d.join(name), body);
    let render = |input: Vec<String>, extra: &[&str]| -> Vec<String> {
        let mut a = vec!["render".to_string()];
        a.extend(input);
        a.extend(small.iter().map(|s| s.to_string()));
        a.extend(extra.iter().map(|s| s.to_string()));
        a.extend(["--out".to_string(), out.clone()]);
        a
    };
    let one = |s: String| vec![s];
    let procedural = vec![
        "--scene".to_string(),
        "random".into(),
        "--atoms".into(),
        "50".into(),
    ];
    let zero_link = d.join("zero.xyz");
    let _ = std::fs::remove_file(&zero_link);
    std::os::unix::fs::symlink("/dev/zero", &zero_link).unwrap();
    let cif = assembly_bomb(&d.join("bomb.cif"));
    let tii = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/1tii.pdb").to_string();
    let c = |name, args, expect| Case {
        name,
        args,
        expect,
        env: vec![],
    };
    vec![
        c(
            "xyzr.gz bomb: 210 KB of gzip, 18M spheres",
            render(one(gzip(&d.join("bomb.xyzr.gz"), &b"0 0 0 1\n".repeat(100_000), 180)), &[]),
            "more than 16777215 spheres",
        ),
        c(
            "--atoms 1e9",
            render(vec!["--scene".into(), "random".into(), "--atoms".into(), "1000000000".into()], &[]),
            "must be between 1 and 16777215",
        ),
        c(
            "--replicate 100x100x100",
            render(vec![tii.clone(), "--replicate".into(), "100x100x100".into()], &[]),
            "more than 16777215, the most",
        ),
        c(
            "assembly of 5e9 spheres (instanced) at full detail",
            render(
                vec![cif.clone(), "--assembly".into(), "3".into(), "--lod".into(), "off".into()],
                &[],
            ),
            "drawing every atom needs",
        ),
        c(
            "assembly of 5e7 spheres expanded",
            render(vec![cif.clone(), "--assembly".into(), "2".into(), "--expand".into()], &[]),
            "more than 16777215, the most an expanded scene holds",
        ),
        c(
            "oper_expression of 1e10 operators",
            render(vec![cif.clone(), "--assembly".into(), "1".into()], &[]),
            "operators (each at least one sphere",
        ),
        c(
            "100 MB of gzipped zeros",
            render(one(gzip(&d.join("zeros.xyz.gz"), &[0u8; 1 << 20], 100)), &[]),
            "line longer than 1048576 bytes",
        ),
        c(
            "/dev/zero as .xyz",
            render(one(zero_link.to_str().unwrap().into()), &[]),
            "line longer than 1048576 bytes",
        ),
        c(
            "NUL inside a PDB",
            render(one(file("nul.pdb", b"REMARK x\nATOM  \0\n")), &[]),
            "binary data (NUL byte)",
        ),
        c(
            "coordinate 3e38",
            render(one(file("far.xyzr", b"0 0 3e38 1\n")), &[]),
            "the range sphereshade renders in f32",
        ),
        c(
            "radius 1e19",
            render(one(file("huge.xyzr", b"0 0 0 1e19\n")), &[]),
            "the range sphereshade renders in f32",
        ),
        c(
            "XYZ count smaller than its atom lines",
            render(one(file("count.xyz", b"2\nc\nC 0 0 0\nO 1 0 0\nN 2 0 0\n")), &[]),
            "the count on line",
        ),
        c(
            "GRO count smaller than its atom lines",
            render(
                one(file(
                    "count.gro",
                    b"t\n 1\n    1SOL     OW    1   0.126   1.624   1.679\n    1SOL    HW1    2   0.190   1.661   1.747\n   1 1 1\n",
                )),
                &[],
            ),
            "the count on line",
        ),
        c(
            "XYZR cut inside the radius",
            render(one(file("cut.xyzr", b"0 0 0 1.5\n1 0 0 1")), &[]),
            "the file ends inside this record",
        ),
        c(
            "PDB cut after the coordinates",
            render(
                one(file(
                    "cut.pdb",
                    b"ATOM      1  N   MET A   1      27.340  24.430   2.614  1.00  9.67           N\nATOM      2  CA  MET A   1      26.266  25.413   2.842",
                )),
                &[],
            ),
            "the file ends inside this record",
        ),
        c(
            "--json in a missing directory",
            render(
                procedural.clone(),
                &["--json", d.join("missing/x.json").to_str().unwrap()],
            ),
            "does not exist",
        ),
        c(
            "view --screenshot x.jpg",
            vec!["view".into(), "--screenshot".into(), d.join("x.jpg").to_str().unwrap().into()],
            "expected a .png file name",
        ),
        c(
            "--out in an unwritable directory",
            {
                let mut a = render(procedural.clone(), &[]);
                let n = a.len();
                a[n - 1] = "/proc/out.png".into();
                a
            },
            "cannot write in",
        ),
        c("--frames 0", render(procedural.clone(), &["--frames", "0"]), "--frames must be at least 1"),
        c(
            "--opacity -0.1",
            render(procedural.clone(), &["--opacity", "-0.1"]),
            "--opacity must be between 0 and 1",
        ),
        c(
            "--lod-pixels -1",
            render(procedural.clone(), &["--lod-pixels", "-1"]),
            "--lod-pixels must be between 0 and 1000",
        ),
        c(
            "--lod-list-batches 0",
            render(procedural.clone(), &["--lod-list-batches", "0"]),
            "--lod-list-batches must be at least 1",
        ),
        c(
            "--scene meso --atoms 2e12",
            render(
                vec!["--scene".into(), "meso".into(), "--atoms".into(), "2000000000000".into()],
                &[],
            ),
            // (past 2^40: 10^12 is a nested scene now)
            "the meso scene holds between 1 and 1099511627776 atoms",
        ),
        c(
            "--deep-pool-chunks 4e9",
            render(
                procedural.clone(),
                &["--shadows", "deep", "--deep-pool-chunks", "4000000000"],
            ),
            "--deep-pool-chunks",
        ),
        Case {
            name: "view without a display",
            args: vec!["view".into(), "--frames".into(), "1".into()],
            expect: "view needs a display",
            env: vec![("DISPLAY", ""), ("WAYLAND_DISPLAY", "")],
        },
        c(
            "view --width 0",
            vec!["view".into(), "--width".into(), "0".into()],
            "--width/--height must be between",
        ),
        Case {
            name: "a device lacking two features",
            args: render(procedural.clone(), &[]),
            expect: "lacks required Vulkan feature(s):",
            env: vec![("SPHERESHADE_DENY_FEATURE", "shaderInt64,synchronization2")],
        },
        c(
            "ESC and BEL in a count line",
            render(one(file("esc.xyz", b"3\x1b[31mRED\x07\nc\nC 0 0 0\n")), &[]),
            "bad atom count",
        ),
        c(
            "a file name with a newline",
            render(one(file("new\nline.xyzr", b"0 0 0 1\n1 0 0")), &[]),
            "new\\nline.xyzr",
        ),
        c("an unknown option", vec!["render".into(), "--bogus".into()], "--bogus"),
        c(
            "a missing required option",
            vec!["bench".into(), "--quick".into()],
            "not provided: --json <JSON>",
        ),
        c(
            "--fov -40",
            render(procedural.clone(), &["--fov", "-40"]),
            "--fov must be above 0 and below 179",
        ),
        c(
            "--issm-size -1",
            render(procedural.clone(), &["--issm-size", "-1"]),
            "for '--issm-size <ISSM_SIZE>'",
        ),
        c(
            "--view-height 1e-300",
            render(one(tii.clone()), &["--view-height", "1e-300"]),
            "below the f32 precision of the scene",
        ),
        c(
            "--fov 1e-9",
            render(one(tii.clone()), &["--fov", "1e-9"]),
            "beyond the f32 precision of the scene",
        ),
        c(
            "a misspelt selection keyword",
            render(one(tii.clone()), &["--hide", "chian A"]),
            "'chian' at column 1: unknown keyword",
        ),
        c(
            "an unclosed parenthesis in a selection",
            render(one(tii.clone()), &["--alpha", "(chain A or water=0.5"]),
            "'(' at column 1: is never closed",
        ),
        c(
            "--alpha out of 0..1",
            render(one(tii.clone()), &["--alpha", "chain A=1.5"]),
            "between 0 and 1",
        ),
        c(
            "--paint with no colour",
            render(one(tii.clone()), &["--paint", "chain A"]),
            "SEL=COLOR",
        ),
        c(
            "--color bfactor on a file without B-factors",
            render(procedural.clone(), &["--color", "bfactor"]),
            "--color",
        ),
        c(
            "see-through spheres with the graphics raster",
            render(one(tii.clone()), &["--alpha", "chain A=0.5", "--raster", "graphics"]),
            "need --raster compute",
        ),
        c(
            "--hide with --replicate",
            render(one(tii.clone()), &["--hide", "water", "--replicate", "2x1x1"]),
            "does not combine with --hide",
        ),
        c(
            "--png-depth 16 with an EXR",
            {
                let mut a = render(procedural.clone(), &["--png-depth", "16"]);
                let n = a.len();
                a[n - 1] = d.join("out.exr").to_str().unwrap().into();
                a
            },
            "--png-depth applies to PNG",
        ),
        c(
            "a LAMMPS dump whose first frame header is damaged",
            {
                let traj = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/traj/image_vf.lammpstrj");
                let body = std::fs::read_to_string(traj).unwrap();
                let damaged = file("damaged.lammpstrj", body.replacen("ITEM: TIMESTEP", "ITEM: TIMESTEX", 1).as_bytes());
                let mut a = render(vec![traj.to_string(), "--trajectory".into(), damaged], &[]);
                let n = a.len();
                a[n - 1] = d.join("out_%d.png").to_str().unwrap().into();
                a
            },
            "damaged.lammpstrj: frame 0 at byte 0",
        ),
    ]
}

#[test]
fn hostile_inputs_get_one_line_and_leave_nothing_behind() {
    let d = dir();
    let mut produced = Vec::new();
    for case in cases(&d) {
        let env: Vec<(&str, &str)> = case.env.to_vec();
        let args: Vec<&str> = case.args.iter().map(String::as_str).collect();
        // Device-feature cases start Vulkan (lavapipe reserves a lot of
        // address space); loading cases never get that far.
        let mem = if case.name.contains("device") || case.name.contains("deep") {
            16 << 20
        } else {
            4 << 20
        };
        let (o, took) = run_limited(&args, mem, &env);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        eprintln!(
            "{:<45} {:>6.2} s  {}",
            case.name,
            took.as_secs_f64(),
            err.trim_end()
        );
        assert_eq!(o.status.code(), Some(1), "{}: {err}", case.name);
        assert_eq!(
            err.lines().count(),
            1,
            "{}: not one line: {err:?}",
            case.name
        );
        assert!(err.starts_with("sphereshade: "), "{}: {err}", case.name);
        assert!(
            err.contains(case.expect),
            "{}: expected '{}' in {err}",
            case.name,
            case.expect
        );
        assert!(
            !o.stderr.iter().any(|&b| b == 0x1b || b == 0x07),
            "{}: control characters reached the terminal",
            case.name
        );
        assert!(
            took < Duration::from_secs(30),
            "{}: took {took:?}",
            case.name
        );
        produced.push(err);
    }
    // Nothing written: no output, no temporary or probe file.
    let left: Vec<String> = std::fs::read_dir(&d)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| {
            n.starts_with('.') || n.ends_with(".png") || n.ends_with(".json") || n.contains("tmp")
        })
        .collect();
    assert!(left.is_empty(), "files left behind: {left:?}");

    // The README's table of refusals is what the cases produce: every
    // fragment it quotes appears in some case's message.
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let start = readme
        .find("Refused, each with one line containing:")
        .expect("README table");
    let table = &readme[start..];
    let table = &table[..table.find("\n\n#").unwrap_or(table.len())];
    let mut checked = 0;
    for row in table
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| what"))
    {
        let cell = row.rsplit('|').nth(1).unwrap_or("");
        for frag in cell.split('`').skip(1).step_by(2) {
            let frag = frag.trim_start_matches("e.g. ");
            assert!(
                produced.iter().any(|e| e.contains(frag)),
                "README promises '{frag}' ({row}) but no case produced it"
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 15,
        "README table not found or too short ({checked} fragments)"
    );
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn careful_edge_values_are_accepted() {
    let d = dir().join("ok");
    std::fs::create_dir_all(&d).unwrap();
    let out = d.join("o.png");
    let o = out.to_str().unwrap();
    for extra in [
        vec!["--view-dir", "-0.2,0,-1"],
        vec!["--light", "1e300,1e300,0"],
        vec!["--up", "0,1e300,0"],
    ] {
        let mut a = vec![
            "render", "--scene", "random", "--atoms", "50", "--width", "32", "--height", "24",
            "--out", o,
        ];
        a.extend(extra.iter());
        let (r, _) = run_limited(&a, 16 << 20, &[]);
        assert_eq!(
            r.status.code(),
            Some(0),
            "{extra:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        assert!(out.exists());
    }
    // A BOM at the start of every text format loads every record.
    for (name, body, n) in [
        ("bom.pdb", &b"\xEF\xBB\xBFATOM      1  N   MET A   1      27.340  24.430   2.614  1.00  9.67           N\nATOM      2  CA  MET A   1      26.266  25.413   2.842  1.00 10.38           C\nEND\n"[..], 2),
        ("bom.xyz", b"\xEF\xBB\xBF2\nc\nC 0 0 0\nO 1 0 0\n", 2),
        ("bom.xyzr", b"\xEF\xBB\xBF0 0 0 1\n1 0 0 1\n", 2),
        ("bom.gro", b"\xEF\xBB\xBFt\n 1\n    1SOL     OW    1   0.126   1.624   1.679\n   1 1 1\n", 1),
    ] {
        let p = d.join(name);
        std::fs::write(&p, body).unwrap();
        let s = sphereshade::scene::load(&p, &Default::default(), &mut |_, _| {})
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(s.spheres.len(), n, "{name}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// A 16384x16384 render under a 4 GB address-space limit (issue 39: the
/// read-back was one image-sized buffer, 4.65 GB peak). Takes about six
/// minutes on lavapipe: `cargo test --release --test hardening -- --ignored`.
#[test]
#[ignore]
fn a_16k_render_fits_in_4_gb() {
    let d = dir().join("16k");
    std::fs::create_dir_all(&d).unwrap();
    let out = d.join("16k.png");
    let mut c = Command::new("bash");
    c.arg("-c")
        .arg("ulimit -v 4000000; exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_sphereshade"))
        .args(["render", "--width", "16384", "--height", "16384", "--out"])
        .arg(&out)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir());
    let o = c.output().expect("run sphereshade");
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let (w, h) = image::image_dimensions(&out).unwrap();
    assert_eq!((w, h), (16384, 16384));
    // Decoded row by row (the test keeps to the limit's spirit too): the
    // capsid covers the centre, the background the corner.
    let file = std::io::BufReader::new(std::fs::File::open(&out).unwrap());
    let mut r = png::Decoder::new(file).read_info().unwrap();
    let (mut y, mut centre, mut corner) = (0, Vec::new(), Vec::new());
    while let Some(row) = r.next_row().unwrap() {
        if y == 0 {
            corner = row.data()[..4].to_vec();
        }
        if y == 8192 {
            centre = row.data()[4 * 8192..4 * 8192 + 4].to_vec();
        }
        y += 1;
    }
    assert_eq!(y, 16384);
    assert_ne!(centre, corner, "centre {centre:?} is background");
    let _ = std::fs::remove_dir_all(&d);
}
