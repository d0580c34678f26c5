//! A seeded mutation fuzzer over every structure format: thousands of byte
//! flips, insertions, deletions, truncations, line splices and hostile
//! tokens per format, parsed in process. Each case must return within a
//! time bound without panicking, and either fail cleanly or give a scene
//! that passes the sanity checks; the process's peak memory stays bounded.
//! (Deterministic: the same seed gives the same cases; FUZZ_CASES=N
//! changes the count per format.)

use sphereshade::scene::{
    Format, LoadOptions, MAX_COORDINATE, MAX_LEVELS, MAX_SPHERES, ModelSelect, Scene, parse_bytes,
};
use std::time::{Duration, Instant};

/// xorshift64*: small, deterministic.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

const TOKENS: &[&[u8]] = &[
    b"nan",
    b"-inf",
    b"1e39",
    b"3e38",
    b"-0",
    b"99999999999999999999",
    b"4294967296",
    b"-1",
    b"\xEF\xBB\xBF",
    b"\0",
    b"\r",
    b"\x1b[2J",
    b"'",
    b"\"",
    b";",
    b"loop_",
    b"data_x",
    b"MODEL",
    b"ENDMDL",
    b"_atom_site.id",
    b"(1-9999)",
    b"\xff\xfe",
    b"       ",
    b"\n\n\n",
];

fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        let n = v.len().max(1);
        match rng.below(8) {
            0 => {
                // flip a byte
                let i = rng.below(n);
                if let Some(b) = v.get_mut(i) {
                    *b ^= 1 << rng.below(8);
                }
            }
            1 => {
                let i = rng.below(n);
                v.insert(i.min(v.len()), rng.next() as u8);
            }
            2 => {
                if !v.is_empty() {
                    let i = rng.below(v.len());
                    let len = rng.below(64).min(v.len() - i);
                    v.drain(i..i + len);
                }
            }
            3 => {
                // truncate anywhere (including inside a record)
                let i = rng.below(n);
                v.truncate(i);
            }
            4 | 5 => {
                // splice lines: duplicate, delete or swap whole lines
                let mut lines: Vec<Vec<u8>> =
                    v.split(|&b| b == b'\n').map(|l| l.to_vec()).collect();
                if lines.len() > 1 {
                    let (a, b) = (rng.below(lines.len()), rng.below(lines.len()));
                    match rng.below(3) {
                        0 => {
                            let l = lines[a].clone();
                            lines.insert(b, l);
                        }
                        1 => {
                            lines.remove(a);
                        }
                        _ => lines.swap(a, b),
                    }
                }
                v = lines.join(&b'\n');
            }
            _ => {
                let t = TOKENS[rng.below(TOKENS.len())];
                let i = rng.below(n).min(v.len());
                // replace a field-sized window or insert
                if rng.below(2) == 0 {
                    let end = (i + t.len()).min(v.len());
                    v.splice(i..end, t.iter().copied());
                } else {
                    v.splice(i..i, t.iter().copied());
                }
            }
        }
    }
    v
}

fn sane(s: &Scene, input_len: usize) -> Result<(), String> {
    if s.spheres.is_empty() || s.spheres.len() > MAX_SPHERES {
        return Err(format!("{} spheres", s.spheres.len()));
    }
    // Streaming parsers keep at most one sphere per input line (assemblies
    // aside, which these seeds do not select).
    if s.spheres.len() > input_len {
        return Err(format!(
            "{} spheres from {input_len} bytes",
            s.spheres.len()
        ));
    }
    if s.level_names.len() > MAX_LEVELS {
        return Err(format!("{} levels", s.level_names.len()));
    }
    for sp in &s.spheres {
        if !sp
            .center
            .iter()
            .all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE)
        {
            return Err(format!("centre {:?}", sp.center));
        }
        if !(sp.radius > 0.0 && sp.radius <= MAX_COORDINATE) {
            return Err(format!("radius {}", sp.radius));
        }
    }
    Ok(())
}

fn peak_rss_kib() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

/// Seeds: the first lines of the shared files, and small files of the
/// formats tests/data has no sample of, made from 1TII's atoms.
fn seeds() -> Vec<(Format, &'static str, Vec<u8>)> {
    let data = |f: &str| {
        std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/").to_string() + f).unwrap()
    };
    let head = |b: Vec<u8>, lines: usize| -> Vec<u8> {
        let mut out = Vec::new();
        for l in b.split_inclusive(|&c| c == b'\n').take(lines) {
            out.extend_from_slice(l);
        }
        out
    };
    // A PDB seed: the first header records, then the first atoms.
    let pdb_seed = |b: Vec<u8>| -> Vec<u8> {
        let lines: Vec<&[u8]> = b.split_inclusive(|&c| c == b'\n').collect();
        let first_atom = lines
            .iter()
            .position(|l| l.starts_with(b"ATOM"))
            .unwrap_or(0);
        let mut out: Vec<u8> = lines[..20.min(lines.len())].concat();
        out.extend(
            lines[first_atom..]
                .iter()
                .take(300)
                .flat_map(|l| l.iter().copied()),
        );
        out.extend_from_slice(b"END\n");
        out
    };
    let pdb = pdb_seed(data("1tii.pdb"));
    let atoms: Vec<[f32; 3]> = String::from_utf8_lossy(&pdb)
        .lines()
        .filter(|l| l.starts_with("ATOM") && l.len() >= 54)
        .take(120)
        .map(|l| {
            let f = |a: usize| l[a..a + 8].trim().parse::<f32>().unwrap();
            [f(30), f(38), f(46)]
        })
        .collect();
    let mut xyz = format!("{}\ncomment\n", atoms.len());
    let mut xyzr = String::from("# x y z r chain residue\n");
    let mut gro = format!("1TII\n{:5}\n", atoms.len());
    for (i, a) in atoms.iter().enumerate() {
        xyz += &format!("C {} {} {}\n", a[0], a[1], a[2]);
        xyzr += &format!("{} {} {} 1.7 {} {}\n", a[0], a[1], a[2], i / 40, i / 8);
        gro += &format!(
            "{:5}{:<5}{:>5}{:5}{:8.3}{:8.3}{:8.3}\n",
            i / 8 + 1,
            "GLY",
            "CA",
            i + 1,
            a[0] / 10.0,
            a[1] / 10.0,
            a[2] / 10.0
        );
    }
    gro += "   5.00000   5.00000   5.00000\n";
    let xyz2 = format!("{xyz}{xyz}");
    vec![
        (Format::Pdb, "pdb", pdb),
        (
            Format::Pdb,
            "pdb (hybrid-36)",
            pdb_seed(data("pdb4v8r_h36.pdb")),
        ),
        (Format::Cif, "cif", head(data("mmcif_6yfy.cif"), 900)),
        (Format::Gro, "gro", gro.into_bytes()),
        (Format::Xyz, "xyz (two frames)", xyz2.into_bytes()),
        (Format::Xyzr, "xyzr", xyzr.into_bytes()),
    ]
}

#[test]
fn mutated_inputs_never_panic_hang_or_load_garbage() {
    let per_format: usize = std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000);
    let started = Instant::now();
    let rss0 = peak_rss_kib();
    let mut rng = Rng(0x5EED_5EED_1234_5678);
    let (mut total, mut loaded, mut refused) = (0usize, 0usize, 0usize);
    let mut slowest = Duration::ZERO;
    for (format, label, seed) in seeds() {
        // the unmutated seed loads
        let s = parse_bytes(&seed, format, label, &LoadOptions::default())
            .unwrap_or_else(|e| panic!("{label} seed: {e}"));
        sane(&s, seed.len()).unwrap_or_else(|e| panic!("{label} seed: {e}"));
        for case in 0..per_format {
            let input = mutate(&seed, &mut rng);
            let opts = LoadOptions {
                model: [ModelSelect::First, ModelSelect::All, ModelSelect::Index(2)][case % 3],
                ..LoadOptions::default()
            };
            let t = Instant::now();
            let result = std::panic::catch_unwind(|| parse_bytes(&input, format, "f", &opts));
            let took = t.elapsed();
            slowest = slowest.max(took);
            total += 1;
            let dump = || {
                let p = std::env::temp_dir().join(format!("fuzz-{label}-{case}.bin"));
                std::fs::write(&p, &input).unwrap();
                p.display().to_string()
            };
            match result {
                Err(_) => panic!("{label} case {case}: panic (input saved to {})", dump()),
                Ok(Ok(scene)) => {
                    if let Err(e) = sane(&scene, input.len()) {
                        panic!(
                            "{label} case {case}: loaded an insane scene: {e} ({})",
                            dump()
                        );
                    }
                    loaded += 1;
                }
                Ok(Err(e)) => {
                    let msg = e.to_string();
                    assert!(
                        !msg.is_empty() && !msg.contains("panicked"),
                        "{label} {case}: {msg}"
                    );
                    refused += 1;
                }
            }
            assert!(
                took < Duration::from_secs(2),
                "{label} case {case}: {took:?} ({})",
                dump()
            );
        }
    }
    let rss = peak_rss_kib();
    eprintln!(
        "fuzz: {total} cases in {:.1} s ({loaded} loaded, {refused} refused cleanly), slowest {:.1} ms, \
         peak RSS {} MiB (from {} MiB)",
        started.elapsed().as_secs_f64(),
        slowest.as_secs_f64() * 1e3,
        rss / 1024,
        rss0 / 1024
    );
    assert!(
        loaded > total / 20 && refused > total / 20,
        "mutations too weak or too strong"
    );
    assert!(rss < 512 * 1024, "peak RSS {} MiB", rss / 1024);
}

/// The trajectory readers under the same mutations (written to files:
/// they seek): no panic escapes (molly's decoder panics are guarded), no
/// case hangs, every error is one line.
#[test]
fn mutated_trajectories_never_panic() {
    let per_format: usize = std::env::var("FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .map_or(400, |n: usize| n / 10)
        .max(50);
    let dir = std::env::temp_dir().join(format!("sphereshade-fuzz-traj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let data = |f: &str| {
        std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/traj/").to_string() + f)
            .unwrap()
    };
    // Two frames of each binary format (small), the whole LAMMPS dump.
    let xtc = data("adk_oplsaa.xtc");
    let trr = data("adk_oplsaa.trr");
    let dcd = data("adk_dims.dcd");
    let seeds: Vec<(&str, Vec<u8>)> = vec![
        ("xtc", xtc[..xtc.len() / 5].to_vec()),
        ("trr", trr[..trr.len() / 5].to_vec()),
        ("dcd", dcd[..dcd.len() / 40].to_vec()),
        ("lammpstrj", data("image_vf.lammpstrj")),
    ];
    let mut rng = Rng(0xD1CE_0F5E_ED00_0001);
    let started = Instant::now();
    let (mut total, mut opened, mut frames_read) = (0usize, 0usize, 0usize);
    for (ext, seed) in seeds {
        let path = dir.join(format!("m.{ext}"));
        for case in 0..per_format {
            // byte-level mutations only for binary formats (line splices
            // would mostly make them unreadable at frame 0)
            let input = mutate(&seed, &mut rng);
            std::fs::write(&path, &input).unwrap();
            let t = Instant::now();
            let r = std::panic::catch_unwind(|| -> (bool, usize, Vec<String>) {
                let mut errors = Vec::new();
                let mut n = 0;
                match sphereshade::traj::open(&path) {
                    Err(e) => {
                        errors.push(e.to_string());
                        (false, 0, errors)
                    }
                    Ok(mut r) => {
                        let mut f = sphereshade::traj::Frame::default();
                        for k in 0..r.frames() {
                            match r.read(k, &mut f) {
                                Ok(()) => n += 1,
                                Err(e) => errors.push(e.to_string()),
                            }
                        }
                        (true, n, errors)
                    }
                }
            });
            total += 1;
            let (ok, n, errors) = r.unwrap_or_else(|_| {
                let keep = dir.join(format!("panic-{case}.{ext}"));
                std::fs::write(&keep, &input).unwrap();
                panic!(
                    "{ext} case {case}: panic (input kept at {})",
                    keep.display()
                )
            });
            opened += ok as usize;
            frames_read += n;
            for e in errors {
                assert!(
                    !e.is_empty() && e.lines().count() == 1,
                    "{ext} {case}: {e:?}"
                );
            }
            assert!(
                t.elapsed() < Duration::from_secs(5),
                "{ext} case {case}: {:?}",
                t.elapsed()
            );
        }
    }
    eprintln!(
        "trajectory fuzz: {total} cases in {:.1} s, {opened} opened, {frames_read} frames read",
        started.elapsed().as_secs_f64()
    );
    let _ = std::fs::remove_dir_all(&dir);
}
