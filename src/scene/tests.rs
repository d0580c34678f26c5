use super::*;

fn sphere(c: [f32; 3], r: f32, region: [u32; MAX_LEVELS]) -> Sphere {
    Sphere {
        center: c,
        radius: r,
        color: [255; 4],
        region,
    }
}

fn two() -> Scene {
    Scene {
        spheres: vec![
            sphere([0.0, 0.0, 0.0], 1.0, [0, 0, 0, 0]),
            sphere([4.0, 2.0, 0.0], 2.0, [0, 1, 1, 1]),
        ],
        level_names: vec![
            "model".into(),
            "chain".into(),
            "residue".into(),
            "atom".into(),
        ],
        source: "test".into(),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    }
}

#[test]
fn bounds() {
    let s = two();
    let (lo, hi) = s.center_bounds().unwrap();
    assert_eq!(lo, Vec3::ZERO);
    assert_eq!(hi, Vec3::new(4.0, 2.0, 0.0));
    let (c, r) = s.bounding_sphere();
    assert_eq!(c, Vec3::new(2.0, 1.0, 0.0));
    assert!((r - (5.0f32.sqrt() + 2.0)).abs() < 1e-6);
    assert_eq!(s.max_radius(), 2.0);
    let mut t = s.clone();
    t.scale_radii(0.5);
    assert_eq!(t.max_radius(), 1.0);
    let empty = Scene {
        spheres: vec![],
        level_names: vec![],
        source: String::new(),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    };
    assert_eq!(empty.center_bounds(), None);
    assert_eq!(empty.bounding_sphere(), (Vec3::ZERO, 0.0));
    assert_eq!(empty.max_radius(), 0.0);
}

#[test]
fn replicate_counts_and_regions() {
    let s = two();
    let r = s.replicate([2, 3, 4]);
    assert_eq!(r.spheres.len(), 2 * 24);
    let mut level0: Vec<u32> = r.spheres.iter().map(|s| s.region[0]).collect();
    level0.sort_unstable();
    level0.dedup();
    assert_eq!(level0.len(), 24);
    // Atom-level ids stay unique across copies.
    let mut atoms: Vec<u32> = r.spheres.iter().map(|s| s.region[3]).collect();
    atoms.sort_unstable();
    atoms.dedup();
    assert_eq!(atoms.len(), 48);
    // Copies do not overlap: spacing is extent + 2 * max radius.
    let (lo, hi) = r.center_bounds().unwrap();
    assert_eq!(lo, Vec3::ZERO);
    assert_eq!(hi, Vec3::new(4.0 + 8.0, 2.0 + 2.0 * 6.0, 3.0 * 4.0));
    // Degenerate counts and scenes without levels.
    let mut bare = two();
    bare.level_names.clear();
    for sp in &mut bare.spheres {
        sp.region = [0; MAX_LEVELS];
    }
    let r = bare.replicate([0, 2, 1]);
    assert_eq!(r.spheres.len(), 4);
    assert_eq!(r.level_names, vec!["copy".to_string()]);
    assert_ne!(r.spheres[0].region[0], r.spheres[2].region[0]);
}

#[test]
fn formats_by_name() {
    let f = |p: &str| format_of(Path::new(p));
    assert_eq!(f("a.pdb"), Some((Format::Pdb, false)));
    assert_eq!(f("a.ENT"), Some((Format::Pdb, false)));
    assert_eq!(f("dir.x/a.cif.gz"), Some((Format::Cif, true)));
    assert_eq!(f("a.mmcif"), Some((Format::Cif, false)));
    assert_eq!(f("a.gro"), Some((Format::Gro, false)));
    assert_eq!(f("a.xyz.GZ"), Some((Format::Xyz, true)));
    assert_eq!(f("a.xyzr"), Some((Format::Xyzr, false)));
    assert_eq!(f("a.txt"), None);
    assert_eq!(f("a.gz"), None);
    assert_eq!(f("noext"), None);
}

fn temp_path(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("sphereshade-{}-{name}", std::process::id()))
}

const MINI_PDB: &str = "\
ATOM      1  N   GLY A   1      42.053  -9.336  17.867  1.00 43.86           N
ATOM      2  CA  GLY A   1      42.704 -10.253  18.851  1.00 41.67           C
HETATM    3  O   HOH     2      19.099   9.698 -13.097  1.00 32.87           O
";

#[test]
fn gzip_load_and_sniff() {
    use std::io::Write;
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(MINI_PDB.as_bytes()).unwrap();
    let gz = enc.finish().unwrap();

    let p = temp_path("mini.pdb.gz");
    std::fs::write(&p, &gz).unwrap();
    let mut calls = 0;
    let s = load(&p, &LoadOptions::default(), &mut |_, _| calls += 1).unwrap();
    assert_eq!(s.spheres.len(), 3);
    assert!(calls > 0);
    assert_eq!(format_of(&p), Some((Format::Pdb, true)));

    // Compressed content behind a plain extension is sniffed.
    let p2 = temp_path("sniffed.pdb");
    std::fs::write(&p2, &gz).unwrap();
    assert_eq!(format_of(&p2), Some((Format::Pdb, true)));
    assert_eq!(
        load(&p2, &LoadOptions::default(), &mut |_, _| {})
            .unwrap()
            .spheres
            .len(),
        3
    );

    // Corrupt stream: an I/O error naming the file, no panic.
    let mut bad = gz.clone();
    let mid = bad.len() / 2;
    for b in &mut bad[12..mid] {
        *b ^= 0x5a;
    }
    let p3 = temp_path("corrupt.pdb.gz");
    std::fs::write(&p3, &bad).unwrap();
    let err = load(&p3, &LoadOptions::default(), &mut |_, _| {}).unwrap_err();
    assert!(
        matches!(err, SceneError::Io { .. } | SceneError::Invalid(_)),
        "{err}"
    );
    assert!(err.to_string().contains("corrupt.pdb.gz"), "{err}");

    // Truncated stream.
    std::fs::write(&p3, &gz[..gz.len() / 2]).unwrap();
    let err = load(&p3, &LoadOptions::default(), &mut |_, _| {}).unwrap_err();
    assert!(err.to_string().contains("gzip"), "{err}");

    for p in [p, p2, p3] {
        let _ = std::fs::remove_file(p);
    }
}

#[test]
fn load_errors() {
    let opts = LoadOptions::default();
    let err = load(Path::new("x.txt"), &opts, &mut |_, _| {}).unwrap_err();
    assert!(matches!(err, SceneError::UnknownFormat { .. }));
    let err = load(Path::new("/nonexistent/x.pdb"), &opts, &mut |_, _| {}).unwrap_err();
    assert!(matches!(err, SceneError::Io { .. }));
    assert!(err.to_string().starts_with("/nonexistent/x.pdb: "));

    let p = temp_path("empty.xyzr");
    std::fs::write(&p, b"").unwrap();
    let err = load(&p, &opts, &mut |_, _| {}).unwrap_err();
    assert!(matches!(err, SceneError::Empty { .. }), "{err}");

    std::fs::write(&p, b"1 2 3 1\n\x00\x01\x02garbage\xff\xfe").unwrap();
    let err = load(&p, &opts, &mut |_, _| {}).unwrap_err();
    assert!(matches!(err, SceneError::Invalid(_)), "{err}");
    assert!(err.to_string().contains(":2:"), "{err}");
    let _ = std::fs::remove_file(p);
}

#[test]
fn invalid_utf8_is_a_parse_error() {
    let opts = LoadOptions::default();
    for (fmt, text) in [
        (Format::Xyzr, &b"1 2 3 1\n1 \xff 3 1\n"[..]),
        (Format::Xyz, &b"1\nc\nC 1 \xc3\x28 3\n"[..]),
        (
            Format::Pdb,
            &b"ATOM      1  N   GLY A   1      4\xff.053  -9.336  17.867  1.00\n"[..],
        ),
    ] {
        let err = parse_bytes(text, fmt, "bin", &opts).unwrap_err();
        assert!(matches!(err, SceneError::Parse { .. }), "{err}");
    }
}

/// Truncating or corrupting input anywhere must give a result or an
/// error, never a panic.
#[test]
fn mangled_input_never_panics() {
    let samples: [(Format, &str); 5] = [
        (
            Format::Pdb,
            "REMARK 350 BIOMOLECULE: 1\n\
             REMARK 350 APPLY THE FOLLOWING TO CHAINS: A\n\
             REMARK 350   BIOMT1   1  1.000000  0.000000  0.000000        0.00000\n\
             REMARK 350   BIOMT2   1  0.000000  1.000000  0.000000        0.00000\n\
             REMARK 350   BIOMT3   1  0.000000  0.000000  1.000000        0.00000\n\
             MODEL        1\n\
             ATOM      1  N   PHEAA   5     131.128  15.297 139.774  1.00150.60         A N\n\
             HETATMA0LGO  BE  BEFAA 602      99.650   2.287 160.398  1.00146.00        HABE\n\
             ATOM   3111  OH2 TIP3    1     -28.430 -30.303 -33.703  1.00  0.00      SOLV\n\
             ENDMDL\nMODEL        2\n\
             ATOM      1  CA AGLY A   1       1.000   1.000   1.000  0.50  1.00           C\n\
             ENDMDL\n",
        ),
        (
            Format::Cif,
            "data_x\nloop_\n_atom_site.id\n_atom_site.type_symbol\n_atom_site.label_alt_id\n\
             _atom_site.label_asym_id\n_atom_site.Cartn_x\n_atom_site.Cartn_y\n_atom_site.Cartn_z\n\
             _atom_site.pdbx_PDB_model_num\n1 C . A 1.0 2.0 3.0 1\n2 'O' A A 1 2 3 1\n\
             3 N . B 1 2 3 2\n#\n_pdbx_struct_oper_list.id 1\n\
             _pdbx_struct_oper_list.matrix[1][1] 1\n_pdbx_struct_assembly_gen.assembly_id 1\n\
             _pdbx_struct_assembly_gen.oper_expression '(1)'\n_pdbx_struct_assembly_gen.asym_id_list A\n",
        ),
        (
            Format::Gro,
            "t\n 2\n    1SOL     OW    1   0.126   1.624   1.679\n    2NA      NA    2   1.000   2.000   3.000\n 1 1 1\n",
        ),
        (Format::Xyz, "2\nc\nO 0 0 0\nH 0.96 0 0\n1\nf2\nC 1 1 1\n"),
        (Format::Xyzr, "# c\n1 2 3 1.5 7 8\n4 5 6 0.5 # t\n"),
    ];
    let opts = [
        LoadOptions::default(),
        LoadOptions {
            model: ModelSelect::All,
            assembly: Some(1),
            color_by: ColorBy::Chain,
        },
        LoadOptions {
            model: ModelSelect::Index(2),
            ..LoadOptions::default()
        },
    ];
    let mut rng = 0x1234_5678_9abc_def0u64;
    let mut next = || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    let alphabet = b" \n\r\t.-+0123456789eE'\";#_ABCXYZnai\xff\xc3";
    for (format, text) in samples {
        let bytes = text.as_bytes();
        for o in &opts {
            for cut in 0..bytes.len() {
                let _ = parse_bytes(&bytes[..cut], format, "f", o);
            }
            for _ in 0..2000 {
                let mut m = bytes.to_vec();
                for _ in 0..1 + next() % 4 {
                    let i = (next() % m.len() as u64) as usize;
                    m[i] = alphabet[(next() % alphabet.len() as u64) as usize];
                }
                let _ = parse_bytes(&m, format, "f", o);
            }
        }
    }
}

#[test]
fn error_messages_name_file_and_line() {
    let err = parse_error("a.pdb", 7, "bad x");
    assert_eq!(err.to_string(), "a.pdb:7: bad x");
    assert_eq!(
        SceneError::UnknownScene("foo".into()).to_string(),
        "unknown procedural scene 'foo' (expected capsid, lattice, random)"
    );
}
