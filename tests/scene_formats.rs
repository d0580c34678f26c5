//! Loads every real structure file in tests/data (copied from ../shared/data,
//! provenance in tests/data/README.md) and checks the counts
//! and quirks documented in its README (atom, chain and model counts,
//! assemblies, element guessing).

use std::collections::HashSet;
use std::path::PathBuf;
use std::time::Instant;

use sphereshade::scene::elements::Element;
use sphereshade::scene::{LoadOptions, ModelSelect, Scene, SceneError, load};

fn data_dir() -> PathBuf {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/"));
    assert!(
        dir.is_dir(),
        "test data directory {} is missing: these tests need the shared structure files \
         described in tests/data/README.md",
        dir.display()
    );
    dir
}

fn load_with(file: &str, opts: &LoadOptions) -> Result<Scene, SceneError> {
    load(&data_dir().join(file), opts, &mut |_, _| {})
}

fn load_default(file: &str) -> Scene {
    let t = Instant::now();
    let s = load_with(file, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{file}: {} spheres in {:?}", s.spheres.len(), t.elapsed());
    s
}

fn distinct(s: &Scene, level: usize) -> usize {
    s.spheres
        .iter()
        .map(|s| s.region[level])
        .collect::<HashSet<_>>()
        .len()
}

fn check_sane(s: &Scene) {
    for (i, sp) in s.spheres.iter().enumerate() {
        assert!(
            sp.center.iter().all(|c| c.is_finite()),
            "{}: sphere {i}",
            s.source
        );
        assert!(
            sp.radius > 0.0 && sp.radius.is_finite(),
            "{}: sphere {i}",
            s.source
        );
        assert_eq!(sp.color[3], 255);
        assert_eq!(sp.region[3], i as u32, "atom level is the atom index");
    }
    assert_eq!(s.level_names, vec!["model", "chain", "residue", "atom"]);
}

/// ATOM/HETATM lines of a PDB file, in order.
fn atom_lines(file: &str) -> Vec<String> {
    let text = std::fs::read_to_string(data_dir().join(file)).unwrap();
    text.lines()
        .filter(|l| l.starts_with("ATOM") || l.starts_with("HETATM"))
        .map(str::to_string)
        .collect()
}

#[test]
fn default_sphere_counts() {
    for (file, count) in [
        ("1tii.pdb", 5_684),
        ("pdb3p3w.pdb", 11_484),
        ("rho.pdb", 51_983),
        ("pdb1tw7_step3_charmm2namd_doubled_h36.pdb", 100_586),
        ("pdb7pbl.pdb", 31_396),
        ("pdb4v8r_h36.pdb", 128_780),
        ("mmcif_6yfy.cif", 1_460),
    ] {
        let s = load_default(file);
        assert_eq!(s.spheres.len(), count, "{file}");
        check_sane(&s);
        assert_eq!(distinct(&s, 0), 1, "{file}: one model");
    }
}

#[test]
fn every_file_in_the_directory_loads() {
    let mut n = 0;
    for entry in std::fs::read_dir(data_dir()).unwrap() {
        let path = entry.unwrap().path();
        // (traj/ holds the trajectories, tested in tests/traj.rs)
        if path.is_dir() || path.extension().is_some_and(|e| e == "md") {
            continue;
        }
        let s =
            load(&path, &LoadOptions::default(), &mut |_, _| {}).unwrap_or_else(|e| panic!("{e}"));
        assert!(!s.spheres.is_empty());
        n += 1;
    }
    assert!(n >= 7, "expected the 7 structure files, found {n}");
}

#[test]
fn chain_counts() {
    // 1tii: 7 protein chains + the blank-chain waters.
    for (file, chains) in [
        ("1tii.pdb", 8),
        ("pdb3p3w.pdb", 4),
        ("pdb7pbl.pdb", 9),
        ("pdb4v8r_h36.pdb", 32),
        ("rho.pdb", 1),
        // Blank chains: segment ids PROA PROB SOLV CLA tell them apart.
        ("pdb1tw7_step3_charmm2namd_doubled_h36.pdb", 4),
        ("mmcif_6yfy.cif", 12),
    ] {
        assert_eq!(distinct(&load_default(file), 1), chains, "{file}");
    }
}

#[test]
fn mmcif_models() {
    let all = LoadOptions {
        model: ModelSelect::All,
        ..LoadOptions::default()
    };
    let s = load_with("mmcif_6yfy.cif", &all).unwrap();
    assert_eq!(s.spheres.len(), 37_960);
    assert_eq!(distinct(&s, 0), 26);
    assert_eq!(distinct(&s, 1), 26 * 12);
    check_sane(&s);

    let last = LoadOptions {
        model: ModelSelect::Index(26),
        ..LoadOptions::default()
    };
    let s26 = load_with("mmcif_6yfy.cif", &last).unwrap();
    assert_eq!(s26.spheres.len(), 1_460);
    let first = load_default("mmcif_6yfy.cif");
    assert_ne!(s26.spheres[0].center, first.spheres[0].center);

    let missing = LoadOptions {
        model: ModelSelect::Index(27),
        ..LoadOptions::default()
    };
    assert!(matches!(
        load_with("mmcif_6yfy.cif", &missing),
        Err(SceneError::Invalid(_))
    ));

    // The one assembly (identity operator) reproduces model 1.
    let asm = LoadOptions {
        assembly: Some(1),
        ..LoadOptions::default()
    };
    let s = load_with("mmcif_6yfy.cif", &asm).unwrap();
    assert_eq!(s.spheres.len(), 1_460);
    for (a, b) in s.spheres.iter().zip(&first.spheres) {
        assert!((0..3).all(|k| (a.center[k] - b.center[k]).abs() < 1e-4));
    }
}

#[test]
fn pdb_without_models_is_model_one() {
    let one = LoadOptions {
        model: ModelSelect::Index(1),
        ..LoadOptions::default()
    };
    assert_eq!(load_with("1tii.pdb", &one).unwrap().spheres.len(), 5_684);
    let all = LoadOptions {
        model: ModelSelect::All,
        ..LoadOptions::default()
    };
    assert_eq!(load_with("1tii.pdb", &all).unwrap().spheres.len(), 5_684);
}

#[test]
fn pdb3p3w_assemblies() {
    let plain = load_default("pdb3p3w.pdb");
    let chains: Vec<u8> = atom_lines("pdb3p3w.pdb")
        .iter()
        .map(|l| l.as_bytes()[21])
        .collect();
    assert_eq!(chains.len(), plain.spheres.len());

    for (id, wanted) in [(1, [b'A', b'C']), (2, [b'B', b'D'])] {
        let opts = LoadOptions {
            assembly: Some(id),
            ..LoadOptions::default()
        };
        let s = load_with("pdb3p3w.pdb", &opts).unwrap();
        check_sane(&s);
        let expected: Vec<[f32; 3]> = plain
            .spheres
            .iter()
            .zip(&chains)
            .filter(|(_, c)| wanted.contains(c))
            .map(|(s, _)| s.center)
            .collect();
        let got: Vec<[f32; 3]> = s.spheres.iter().map(|s| s.center).collect();
        // Identity operator: the same atoms at the same places.
        assert_eq!(got.len(), expected.len(), "assembly {id}");
        for (g, e) in got.iter().zip(&expected) {
            assert!((0..3).all(|k| (g[k] - e[k]).abs() < 1e-4), "assembly {id}");
        }
        assert_eq!(distinct(&s, 1), 2, "assembly {id}: two chains");
        assert_eq!(distinct(&s, 0), 1, "assembly {id}: one operator");
    }

    let opts = LoadOptions {
        assembly: Some(3),
        ..LoadOptions::default()
    };
    let err = load_with("pdb3p3w.pdb", &opts).unwrap_err();
    assert!(matches!(err, SceneError::Invalid(_)), "{err}");
    assert!(err.to_string().contains("assembly 3"), "{err}");

    // 7pbl: one identity assembly over all nine chains.
    let opts = LoadOptions {
        assembly: Some(1),
        ..LoadOptions::default()
    };
    let s = load_with("pdb7pbl.pdb", &opts).unwrap();
    assert_eq!(s.spheres.len(), 31_396);
    assert_eq!(distinct(&s, 1), 9);
    // 1tii has no REMARK 350.
    assert!(matches!(
        load_with("1tii.pdb", &opts),
        Err(SceneError::Invalid(_))
    ));
}

/// Count of spheres with exactly this element's radius at the given atoms.
fn radii_at(s: &Scene, lines: &[String], pred: impl Fn(&str) -> bool) -> Vec<f32> {
    assert_eq!(lines.len(), s.spheres.len());
    lines
        .iter()
        .zip(&s.spheres)
        .filter(|(l, _)| pred(l))
        .map(|(_, sp)| sp.radius)
        .collect()
}

#[test]
fn charmm_names_without_element_columns() {
    let file = "pdb1tw7_step3_charmm2namd_doubled_h36.pdb";
    let s = load_default(file);
    let lines = atom_lines(file);
    // Chloride ions are ` CLA`: chlorine, not carbon.
    let cla = radii_at(&s, &lines, |l| &l[12..16] == " CLA");
    assert!(!cla.is_empty());
    assert!(cla.iter().all(|&r| r == Element::CL.radius()));
    // TIP3 oxygens `OH2` are oxygen; hydrogens named HG21 etc. are hydrogen.
    let oh2 = radii_at(&s, &lines, |l| &l[12..16] == " OH2");
    assert_eq!(oh2.len(), 31_450);
    assert!(oh2.iter().all(|&r| r == Element::O.radius()));
    let h4 = radii_at(&s, &lines, |l| l.as_bytes()[12] == b'H');
    assert!(!h4.is_empty());
    assert!(h4.iter().all(|&r| r == Element::H.radius()));
    // Only protein/water/ion elements appear.
    let allowed: Vec<f32> = [
        Element::H,
        Element::C,
        Element::N,
        Element::O,
        Element::S,
        Element::CL,
    ]
    .iter()
    .map(|e| e.radius())
    .collect();
    assert!(s.spheres.iter().all(|sp| allowed.contains(&sp.radius)));
}

#[test]
fn two_letter_chains_and_metal_columns() {
    let file = "pdb4v8r_h36.pdb";
    let s = load_default(file);
    let lines = atom_lines(file);
    let be = radii_at(&s, &lines, |l| &l[12..16] == " BE ");
    let mg = radii_at(&s, &lines, |l| &l[12..16] == " MG ");
    assert_eq!(be.len(), 32);
    assert_eq!(mg.len(), 32);
    assert!(be.iter().all(|&r| r == Element::BE.radius()));
    assert!(mg.iter().all(|&r| r == Element::MG.radius()));
    assert!(!s.spheres.iter().any(|sp| sp.radius == Element::B.radius()));
    // `Aa` and `AA` are different chains of 4,092 atoms each.
    let chain_of = |c: &str| {
        let i = lines.iter().position(|l| &l[20..22] == c).unwrap();
        s.spheres[i].region[1]
    };
    let (aa, a_lower) = (chain_of("AA"), chain_of("Aa"));
    assert_ne!(aa, a_lower);
    assert_eq!(
        s.spheres
            .iter()
            .filter(|sp| sp.region[1] == a_lower)
            .count(),
        4_092
    );
}

#[test]
fn rho_quirks() {
    let file = "rho.pdb";
    let s = load_default(file);
    let lines = atom_lines(file);
    // ` CL ` with element C stays carbon (the file's own statement).
    let cl = radii_at(&s, &lines, |l| &l[12..16] == " CL ");
    assert_eq!(cl.len(), 57);
    assert!(cl.iter().all(|&r| r == Element::C.radius()));
    let na = radii_at(&s, &lines, |l| &l[76..78] == "NA");
    assert_eq!(na.len(), 57);
    assert!(na.iter().all(|&r| r == Element::NA.radius()));
    // Residue numbers wrap 9999 -> 0 inside the water: 12,650 SOL molecules
    // stay distinct residues.
    let sol: HashSet<u32> = lines
        .iter()
        .zip(&s.spheres)
        .filter(|(l, _)| &l[17..20] == "SOL")
        .map(|(_, sp)| sp.region[2])
        .collect();
    assert_eq!(sol.len(), 12_650);
}

#[test]
fn elements_from_columns() {
    // 7pbl: 15,517 H atoms by element column, 3 Mg ions.
    let file = "pdb7pbl.pdb";
    let s = load_default(file);
    let h = s
        .spheres
        .iter()
        .filter(|sp| sp.radius == Element::H.radius())
        .count();
    assert_eq!(h, 15_517);
    let mg = s
        .spheres
        .iter()
        .filter(|sp| sp.radius == Element::MG.radius())
        .count();
    assert_eq!(mg, 3);
    // 6yfy: 52 % hydrogens from type_symbol (19,656 over all 26 models).
    let all = LoadOptions {
        model: ModelSelect::All,
        ..LoadOptions::default()
    };
    let s = load_with("mmcif_6yfy.cif", &all).unwrap();
    let h = s
        .spheres
        .iter()
        .filter(|sp| sp.radius == Element::H.radius())
        .count();
    assert_eq!(h, 19_656);
}

#[test]
fn progress_is_reported() {
    let mut calls = Vec::new();
    let s = load(
        &data_dir().join("pdb4v8r_h36.pdb"),
        &LoadOptions::default(),
        &mut |d, t| calls.push((d, t)),
    )
    .unwrap();
    assert_eq!(s.spheres.len(), 128_780);
    assert!(calls.len() >= 50 && calls.len() <= 120, "{}", calls.len());
    assert!(calls.windows(2).all(|w| w[0].0 <= w[1].0));
    assert_eq!(calls.last(), Some(&(10_506_328, 10_506_328)));
}

#[test]
fn load_timing_4v8r() {
    let path = data_dir().join("pdb4v8r_h36.pdb");
    let mut best = f64::MAX;
    for _ in 0..3 {
        let t = Instant::now();
        let s = load(&path, &LoadOptions::default(), &mut |_, _| {}).unwrap();
        best = best.min(t.elapsed().as_secs_f64());
        assert_eq!(s.spheres.len(), 128_780);
    }
    eprintln!(
        "pdb4v8r_h36.pdb (10.5 MB, 128,780 atoms): best of 3 {:.1} ms ({:.0} MB/s)",
        best * 1e3,
        10.506 / best
    );
}
