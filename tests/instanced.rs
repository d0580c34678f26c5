//! Instanced mesoscale scenes (DESIGN.md "Instanced scenes"): BinaryCIF
//! against mmCIF, the real models' true counts (tests/data/meso/README.md),
//! the cellPACK quaternion convention, manifests, and on the GPU (under
//! validation) the instanced render against the render of the same scene
//! expanded into one sphere per atom: the same bytes in every AOV.

mod common;

use common::*;
use glam::{DQuat, DVec3};
use rmpv::Value;
use sphereshade::output::ids_from_vis;
use sphereshade::render::{Inspect, Renderer};
use sphereshade::scene::instanced::{LevelKind, Transforms};
use sphereshade::scene::{self, LoadOptions, ModelSelect, Scene};
use sphereshade::settings::{Aov, Levels, RenderSettings, ShadowMode, SsdoMode};
use sphereshade::stages::ssdo::record::region_hash;
use sphereshade::vk::Context;

fn load_with(name: &str, opts: &LoadOptions) -> Scene {
    scene::load(&data_file(name), opts, &mut |_, _| {}).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn meso(name: &str) -> Scene {
    load_data(&format!("meso/{name}"))
}

/// (molecule types, instances, atoms stored, represented, rigid, levels)
/// of each model, as tests/data/meso/README.md lists them.
#[test]
fn real_models_load_instanced_with_their_counts() {
    type Want = (usize, usize, usize, u64, bool, &'static [&'static str]);
    let want: [(&str, Want); 4] = [
        (
            "flagellarmotor_2-no_bonds.bcif",
            (
                17,
                258,
                38_168,
                736_472,
                true,
                &["type", "molecule", "chain"],
            ),
        ),
        (
            "sarscov2_2-no_bonds.bcif",
            (
                8,
                696,
                232_573,
                13_539_470,
                true,
                &["group", "type", "molecule", "chain"],
            ),
        ),
        (
            "cellpack_instances_149_21.bcif",
            (
                563,
                27_542,
                99_160,
                521_219,
                false,
                &["location", "ingredient", "molecule"],
            ),
        ),
        (
            "HIV-1_0.1.6-8_mixed_radii_pdb.json",
            (
                26,
                11_681,
                384,
                91_956,
                true,
                &["compartment", "location", "ingredient", "molecule"],
            ),
        ),
    ];
    for (file, (mols, insts, atoms, represented, rigid, levels)) in want {
        let t = std::time::Instant::now();
        let s = meso(file);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let inst = s.instancing.as_ref().expect("instanced");
        eprintln!("{file}: loaded in {ms:.0} ms (debug build)");
        assert_eq!(inst.molecules.len(), mols, "{file}: molecule types");
        assert_eq!(inst.instances(), insts, "{file}: instances");
        assert_eq!(s.spheres.len(), atoms, "{file}: atoms stored");
        assert_eq!(s.represented(), represented, "{file}: represented");
        assert_eq!(
            matches!(inst.transforms, Transforms::Rigid(_)),
            rigid,
            "{file}: transforms"
        );
        assert_eq!(s.level_names, levels, "{file}: levels");
        // the expanded order's bookkeeping: each instance's first atom
        assert_eq!(inst.first.len(), insts + 1);
        assert_eq!(*inst.first.last().unwrap(), represented);
        // batches: 64 slots for molecules of thousands of atoms, 8 for beads
        let shift = sphereshade::passes::scene::batch_shift(&s);
        let want = if atoms / mols > 1000 { 6 } else { 3 };
        assert_eq!(shift, want, "{file}: batch shift");
    }
}

/// SARS-CoV-2's 8 PetWorld models by name, its membrane grouped, and its
/// operators rigid to the file's 2e-6 (the quaternions reproduce them).
#[test]
fn petworld_models_and_operators() {
    let s = meso("sarscov2_2-no_bonds.bcif");
    let inst = s.instancing.as_ref().unwrap();
    let labels: Vec<&str> = inst.molecules.iter().map(|m| m.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "E",
            "M",
            "M2",
            "S",
            "membrane_rho",
            "membrane_tri",
            "Nest",
            "Pyramid"
        ]
    );
    let per_type: Vec<usize> = (0..8)
        .map(|m| inst.instance_molecule.iter().filter(|&&k| k == m).count())
        .collect();
    // `_pdbx_model.instances`
    assert_eq!(per_type, [50, 100, 100, 30, 340, 40, 28, 8]);
    let group = |m: usize| {
        let n = &inst.nodes[inst.molecules[m].node as usize];
        inst.nodes[n.parent.unwrap() as usize].label.clone()
    };
    assert_eq!(group(4), "membrane");
    assert_eq!(group(5), "membrane");
    assert_eq!(group(3), "root");
    assert_eq!(inst.levels[0], LevelKind::Tree(1));
}

/// 1F2N's complete icosahedral assembly (`--assembly 1`): 60 copies.
fn capsid_60mer() -> Scene {
    load_with(
        "1f2n.cif",
        &LoadOptions {
            assembly: Some(1),
            ..Default::default()
        },
    )
}

/// The 60-mer of a real capsid (1F2N, `--assembly 1`, 60 operators) stays
/// instanced; its represented spheres are the operators' x' = M x + v of
/// the asymmetric unit's atoms to f32 precision (the rigid operators are
/// held as unit quaternions).
#[test]
fn a_capsid_assembly_stays_instanced() {
    let asu = load_data("1f2n.cif");
    let asm = capsid_60mer();
    let inst = asm.instancing.as_ref().expect("instanced");
    assert_eq!((inst.instances(), inst.molecules.len()), (60, 1));
    assert_eq!(asm.spheres.len(), asu.spheres.len());
    assert_eq!(asm.represented(), 60 * 4730);
    assert!(matches!(inst.transforms, Transforms::Rigid(_)));
    // the file's operators, read independently here
    let text = std::fs::read_to_string(data_file("1f2n.cif")).unwrap();
    let ops = oper_list(&text);
    assert_eq!(ops.len(), 60 + 2, "1F2N lists 62 operators (60 + P and X0)");
    let e = asm.expand().unwrap();
    // the levels the instanced scene chose separate the expanded spheres
    assert_eq!(
        sphereshade::semantic::useful_levels(&e),
        sphereshade::semantic::useful_levels(&asm)
    );
    let mut worst = 0.0f64;
    for k in 0..60 {
        let m = &ops[&(k + 1).to_string()];
        for (a, s) in asu.spheres.iter().enumerate() {
            let x = DVec3::from(s.center.map(f64::from));
            let want = DVec3::new(
                m[0][0] * x.x + m[0][1] * x.y + m[0][2] * x.z + m[0][3],
                m[1][0] * x.x + m[1][1] * x.y + m[1][2] * x.z + m[1][3],
                m[2][0] * x.x + m[2][1] * x.y + m[2][2] * x.z + m[2][3],
            );
            let got = DVec3::from(e.spheres[k * 4730 + a].center.map(f64::from));
            worst = worst.max((got - want).length());
        }
    }
    eprintln!("1F2N 60-mer: largest distance from x' = M x + v: {worst:.2e} Å");
    assert!(worst < 2e-3, "{worst}");
}

/// `_pdbx_struct_oper_list` of a text mmCIF: id -> 3x4 matrix (a reader of
/// its own, independent of the crate's).
fn oper_list(text: &str) -> std::collections::HashMap<String, [[f64; 4]; 3]> {
    let lines: Vec<&str> = text.lines().collect();
    let start = lines
        .iter()
        .position(|l| l.starts_with("_pdbx_struct_oper_list."))
        .unwrap();
    let items: Vec<&str> = lines[start..]
        .iter()
        .take_while(|l| l.starts_with("_pdbx_struct_oper_list."))
        .map(|l| l.trim())
        .collect();
    let col = |n: &str| {
        items
            .iter()
            .position(|i| *i == format!("_pdbx_struct_oper_list.{n}"))
            .unwrap()
    };
    let mut out = std::collections::HashMap::new();
    let mut tokens: Vec<String> = Vec::new();
    for l in &lines[start + items.len()..] {
        if l.starts_with('#') || l.starts_with('_') || l.starts_with("loop_") {
            break;
        }
        // quoted values (names, types) hold blanks: split on quotes first
        for (k, part) in l.split('\'').enumerate() {
            if k % 2 == 1 {
                tokens.push(part.to_string());
            } else {
                tokens.extend(part.split_whitespace().map(str::to_string));
            }
        }
        while tokens.len() >= items.len() {
            let row: Vec<String> = tokens.drain(..items.len()).collect();
            let mut m = [[0.0; 4]; 3];
            for (i, mr) in m.iter_mut().enumerate() {
                for (j, v) in mr.iter_mut().enumerate() {
                    let name = if j < 3 {
                        format!("matrix[{}][{}]", i + 1, j + 1)
                    } else {
                        format!("vector[{}]", i + 1)
                    };
                    *v = row[col(&name)].parse().unwrap();
                }
            }
            out.insert(row[col("id")].clone(), m);
        }
    }
    out
}

/// Every option a text mmCIF is loaded with gives the same spheres (and
/// levels) from its BinaryCIF: the RCSB's encoding of the same entries.
#[test]
fn binary_cif_loads_the_spheres_of_its_mmcif() {
    for stem in ["1f2n", "1l2y"] {
        for opts in [
            LoadOptions::default(),
            LoadOptions {
                model: ModelSelect::All,
                ..Default::default()
            },
            LoadOptions {
                assembly: Some(1),
                ..Default::default()
            },
            LoadOptions {
                color_by: scene::ColorBy::Chain,
                ..Default::default()
            },
        ] {
            let a = load_with(&format!("{stem}.cif"), &opts);
            let b = load_with(&format!("{stem}.bcif"), &opts);
            assert_eq!(a.represented(), b.represented(), "{stem} {opts:?}");
            assert_eq!(a.level_names, b.level_names, "{stem} {opts:?}");
            assert_eq!(
                a.expand().unwrap().spheres,
                b.expand().unwrap().spheres,
                "{stem} {opts:?}"
            );
        }
    }
    let all = LoadOptions {
        model: ModelSelect::All,
        ..Default::default()
    };
    assert_eq!(load_with("1l2y.bcif", &all).spheres.len(), 38 * 304);
}

/// tests/data's NMR mmCIF (6YFY) encoded here (every encoding but
/// IntervalQuantization, which is lossy) loads the same spheres.
#[test]
fn our_encoding_of_an_mmcif_loads_the_same_spheres() {
    let text = std::fs::read_to_string(data_file("mmcif_6yfy.cif")).unwrap();
    let bytes = bcif_writer::encode(&text, None);
    for opts in [
        LoadOptions::default(),
        LoadOptions {
            model: ModelSelect::All,
            ..Default::default()
        },
        LoadOptions {
            model: ModelSelect::Index(3),
            color_by: scene::ColorBy::Chain,
            ..Default::default()
        },
    ] {
        let a = scene::parse_bytes(text.as_bytes(), scene::Format::Cif, "6yfy.cif", &opts).unwrap();
        let b = scene::parse_bytes(&bytes, scene::Format::Bcif, "6yfy.bcif", &opts).unwrap();
        assert_eq!(a.spheres, b.spheres, "{opts:?}");
        assert_eq!(a.level_names, b.level_names);
    }
}

/// A bad container, an unknown encoding and a column of the wrong length
/// are one line each, naming the file (and the column).
#[test]
fn broken_binary_cif_is_one_clear_line() {
    let text = std::fs::read_to_string(data_file("mmcif_6yfy.cif")).unwrap();
    let good = bcif_writer::encode(&text, None);
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("cut", good[..good.len() / 2].to_vec(), "does not decode"),
        ("text", text.as_bytes().to_vec(), "not a BinaryCIF file"),
        (
            "encoding",
            bcif_writer::encode(&text, Some(bcif_writer::Break::UnknownEncoding)),
            "_atom_site.Cartn_x: unknown encoding 'Zigzag'",
        ),
        (
            "length",
            bcif_writer::encode(&text, Some(bcif_writer::Break::ShortColumn)),
            "_atom_site.Cartn_y has",
        ),
    ];
    for (what, bytes, want) in cases {
        let e = scene::parse_bytes(
            &bytes,
            scene::Format::Bcif,
            "x.bcif",
            &LoadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("x.bcif: "), "{what}: {e}");
        assert!(e.contains(want), "{what}: {e}");
        assert!(!e.contains('\n'), "{what}: {e}");
    }
}

/// cellPACK results give quaternions scalar first (w, x, y, z): read so,
/// the matrix protein's beads of neighbouring copies hardly interpenetrate;
/// read in the other order they do, often.
#[test]
fn cellpack_quaternions_are_scalar_first() {
    let path = data_file("meso/HIV-1_0.1.6-8_mixed_radii_pdb.json");
    let s = meso("HIV-1_0.1.6-8_mixed_radii_pdb.json");
    let inst = s.instancing.as_ref().unwrap();
    let m = inst
        .molecules
        .iter()
        .position(|m| m.label == "HIV1_MA_Hyb_0_1_0")
        .unwrap() as u32;
    let mut beads: Vec<(DVec3, f64, usize)> = Vec::new();
    let e = s.expand().unwrap();
    for (k, &im) in inst.instance_molecule.iter().enumerate() {
        if im != m {
            continue;
        }
        for i in inst.first[k]..inst.first[k + 1] {
            let b = &e.spheres[i as usize];
            beads.push((DVec3::from(b.center.map(f64::from)), b.radius as f64, k));
        }
    }
    let right = deep_overlap(&beads);
    // the same results read (x, y, z, w), from the JSON directly
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    let ing = &json["compartments"]["HIV1_envelope_Pack_145_0_2_0"]["surface"]["ingredients"]["HIV1_MA_Hyb_0_1_0"];
    let local: Vec<(DVec3, f64)> = ing["positions"][0]
        .as_array()
        .unwrap()
        .iter()
        .zip(ing["radii"][0].as_array().unwrap())
        .map(|(p, r)| {
            let p: Vec<f64> = p
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            (DVec3::new(p[0], p[1], p[2]), r.as_f64().unwrap())
        })
        .collect();
    let mut wrong_beads = Vec::new();
    for (k, res) in ing["results"].as_array().unwrap().iter().enumerate() {
        let t: Vec<f64> = res[0]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let q: Vec<f64> = res[1]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let wrong = DQuat::from_xyzw(q[0], q[1], q[2], q[3]).normalize();
        for &(p, r) in &local {
            wrong_beads.push((wrong * p + DVec3::new(t[0], t[1], t[2]), r, k));
        }
    }
    let wrong = deep_overlap(&wrong_beads);
    eprintln!(
        "HIV-1 matrix beads interpenetrating another copy by over a quarter of their radii: \
         {:.2} % read (w, x, y, z), {:.2} % read (x, y, z, w)",
        100.0 * right,
        100.0 * wrong
    );
    assert!(right < 0.01, "{right}");
    assert!(wrong > 0.03, "{wrong}");
}

/// Fraction of beads whose centre lies closer than 3/4 of the radii's sum
/// to a bead of another copy (a cell grid).
fn deep_overlap(beads: &[(DVec3, f64, usize)]) -> f64 {
    let rmax = beads.iter().map(|b| b.1).fold(0.0, f64::max);
    let cell = 2.0 * rmax;
    let key = |p: DVec3| (p / cell).floor().as_ivec3();
    let mut grid: std::collections::HashMap<glam::IVec3, Vec<usize>> = Default::default();
    for (i, b) in beads.iter().enumerate() {
        grid.entry(key(b.0)).or_default().push(i);
    }
    let mut bad = 0;
    for (i, b) in beads.iter().enumerate() {
        let c = key(b.0);
        let hit = (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                (-1..=1).any(|dz| {
                    grid.get(&(c + glam::IVec3::new(dx, dy, dz)))
                        .is_some_and(|v| {
                            v.iter().any(|&j| {
                                let o = &beads[j];
                                j != i && o.2 != b.2 && b.0.distance(o.0) < 0.75 * (b.1 + o.1)
                            })
                        })
                })
            })
        });
        bad += hit as usize;
    }
    bad as f64 / beads.len() as f64
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("sphereshade-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// An instanced model written as a manifest (one .xyzr per molecule type,
/// binary instance arrays) loads back to the same represented spheres and
/// levels.
#[test]
fn manifest_round_trip() {
    let s = meso("flagellarmotor_2-no_bonds.bcif");
    let dir = temp_dir("manifest");
    scene::meso_json::write_manifest(&s, &dir).unwrap();
    let back = scene::load(
        &dir.join("manifest.json"),
        &Default::default(),
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(back.represented(), s.represented());
    // (a manifest's tree has no names for its depths)
    let kinds = |s: &Scene| s.instancing.as_ref().unwrap().levels.clone();
    assert_eq!(kinds(&back), kinds(&s));
    let (a, b) = (s.expand().unwrap(), back.expand().unwrap());
    let mut worst = 0.0f32;
    for (x, y) in a.spheres.iter().zip(&b.spheres) {
        let d = glam::Vec3::from(x.center).distance(glam::Vec3::from(y.center));
        worst = worst.max(d);
        assert_eq!(x.radius, y.radius);
        assert_eq!(x.region, y.region);
    }
    // (the .xyzr text rounds nothing: shortest round-trip decimals)
    assert!(worst < 1e-3, "{worst}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A hand-written manifest: inline arrays, a group in the tree, a colour,
/// a size factor, `center: bbox`; and its errors, one line each.
#[test]
fn manifest_by_hand() {
    let dir = temp_dir("manifest-hand");
    std::fs::write(dir.join("pair.xyzr"), "10 0 0 1\n12 0 0 1\n").unwrap();
    let doc = r##"{"roots": [{"id": "cell", "label": "cell", "children": [{"id": "env", "label": "envelope"}]}],
        "entities": [{"label": "pair", "file": "pair.xyzr", "color": "#ff8000", "sizeFactor": 2,
          "center": "bbox", "groups": ["env"],
          "instances": {"positions": [0, 0, 0, 100, 0, 0],
                        "rotations": {"variant": "quaternion", "data": [0, 0, 0, 1, 0, 0, 0.7071068, 0.7071068]}}}]}"##;
    std::fs::write(dir.join("m.json"), doc).unwrap();
    let s = scene::load(&dir.join("m.json"), &Default::default(), &mut |_, _| {}).unwrap();
    let e = s.expand().unwrap();
    let c: Vec<[i32; 3]> = e
        .spheres
        .iter()
        .map(|s| s.center.map(|v| v.round() as i32))
        .collect();
    // centred on the pair's box (x = 11), then placed; the second copy
    // turned 90 degrees about z
    assert_eq!(c, [[-1, 0, 0], [1, 0, 0], [100, -1, 0], [100, 1, 0]]);
    assert!(
        e.spheres
            .iter()
            .all(|s| s.radius == 2.0 && s.color == [255, 128, 0, 255])
    );
    let inst = s.instancing.as_ref().unwrap();
    let leaf = &inst.nodes[inst.molecules[0].node as usize];
    assert_eq!(leaf.label, "envelope");
    for (bad, want) in [
        (
            doc.replace("\"env\"]", "\"nowhere\"]"),
            "group 'nowhere' is not a node",
        ),
        (doc.replace("100, 0, 0]", "100, 0]"), "position values"),
        (doc.replace("quaternion", "matrix"), "only quaternion"),
        (doc.replace("pair.xyzr", "missing.xyzr"), "missing.xyzr"),
        (doc.replace("#ff8000", "orange"), "color"),
        ("{\"foo\": 1}".to_string(), "nor a manifest"),
        ("{\"entities\": [".to_string(), "JSON"),
    ] {
        std::fs::write(dir.join("bad.json"), &bad).unwrap();
        let e = scene::load(&dir.join("bad.json"), &Default::default(), &mut |_, _| {})
            .unwrap_err()
            .to_string();
        assert!(e.contains("bad.json") && e.contains(want), "{want}: {e}");
        assert!(!e.contains('\n'), "{e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------- GPU

/// What one frame leaves: colour, depth|id keys (expanded ids), shadow and
/// ambient AOVs.
struct Frame {
    color: Vec<u32>,
    vis: Vec<u64>,
    shadow: Vec<f32>,
    ambient: Vec<[f32; 4]>,
}

fn frame(ctx: &Context, scene: &Scene, s: RenderSettings) -> Frame {
    let mut r = Renderer::new(ctx, scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let i = r.inspect();
    Frame {
        color: i.read_color().unwrap(),
        vis: i.read_vis().unwrap(),
        shadow: i.read_shadow().unwrap(),
        ambient: i.read_ambient().unwrap(),
    }
}

/// The instanced scene and its expansion render the same bytes (colour,
/// ids, depth, shadow, ambient) in each mode; the instanced one through
/// the LOD cull with every instance at full detail (`--lod-pixels 0`),
/// so culling never drops a visible sphere.
fn same_as_expanded(
    ctx: &Context,
    name: &str,
    s: &Scene,
    modes: &[(ShadowMode, SsdoMode)],
    size: (u32, u32),
) {
    same_as_expanded_from(ctx, name, s, modes, camera(s, size.0, size.1, None));
}

fn same_as_expanded_from(
    ctx: &Context,
    name: &str,
    s: &Scene,
    modes: &[(ShadowMode, SsdoMode)],
    cam: sphereshade::camera::Camera,
) {
    let e = s.expand().unwrap();
    for &(shadows, ssdo) in modes {
        let mut st = settings(cam, shadows);
        st.ssdo = ssdo;
        st.ssdo_knobs.blur = true;
        st.lod.lod_pixels = 0.0;
        let a = frame(ctx, s, st.clone());
        let b = frame(ctx, &e, st);
        let what = format!("{name} {shadows:?} {ssdo:?}");
        let covered = a
            .vis
            .iter()
            .filter(|&&k| k != sphereshade::gpu::VIS_EMPTY)
            .count();
        assert!(
            covered > a.vis.len() / 20,
            "{what}: {covered} pixels covered"
        );
        assert!(a.vis == b.vis, "{what}: ids or depths differ");
        assert!(a.color == b.color, "{what}: colours differ");
        assert!(a.shadow == b.shadow, "{what}: shadow AOVs differ");
        assert!(a.ambient == b.ambient, "{what}: ambient AOVs differ");
        assert_no_validation_messages(ctx);
    }
}

/// The 60-mer of 1F2N (rigid) in every shadow technique and SSDO mode.
#[test]
fn instanced_capsid_renders_as_its_expansion() {
    let ctx = validated_context();
    let s = capsid_60mer();
    let mut modes = Vec::new();
    for shadows in [
        ShadowMode::Issm,
        ShadowMode::IssmSoft,
        ShadowMode::Deep,
        ShadowMode::SmPcf,
        ShadowMode::Osm,
        ShadowMode::None,
    ] {
        modes.push((shadows, SsdoMode::Semantic));
    }
    modes.push((ShadowMode::IssmSoft, SsdoMode::Plain));
    modes.push((ShadowMode::Deep, SsdoMode::Off));
    same_as_expanded(&ctx, "1f2n-60mer", &s, &modes, (96, 72));
    // close up: spheres wide enough for per-pixel SSDO receivers; region
    // outlines (shade reads each neighbour's region)
    let mut st = settings(camera(&s, 96, 72, None), ShadowMode::IssmSoft);
    st.camera.view_height *= 0.08;
    st.ssdo = SsdoMode::Semantic;
    st.look.outline = 1.5;
    let e = s.expand().unwrap();
    let (a, b) = (frame(&ctx, &s, st.clone()), frame(&ctx, &e, st));
    assert!(
        a.color == b.color && a.vis == b.vis && a.ambient == b.ambient,
        "close-up"
    );
    assert_no_validation_messages(&ctx);
}

/// The real models: the flagellar motor (rigid, 736,472 spheres), the
/// Mycoplasma beads (affine, as stored) and the HIV-1 packing (rigid, from
/// JSON), in the default modes and with deep lists.
#[test]
fn real_models_render_as_their_expansion() {
    let ctx = validated_context();
    let default = [(ShadowMode::IssmSoft, SsdoMode::Semantic)];
    same_as_expanded(
        &ctx,
        "motor",
        &meso("flagellarmotor_2-no_bonds.bcif"),
        &default,
        (64, 48),
    );
    let both = [
        (ShadowMode::IssmSoft, SsdoMode::Semantic),
        (ShadowMode::Deep, SsdoMode::Plain),
    ];
    same_as_expanded(
        &ctx,
        "mycoplasma",
        &meso("cellpack_instances_149_21.bcif"),
        &both,
        (64, 48),
    );
    same_as_expanded(
        &ctx,
        "hiv",
        &meso("HIV-1_0.1.6-8_mixed_radii_pdb.json"),
        &both,
        (64, 48),
    );
}

/// Culling: cameras that see a corner of the motor (a quarter of its
/// height, off centre) and look from inside it (perspective) draw a part
/// of the instances through the LOD cull at full detail, frame after
/// frame on one renderer (the later frames draw last frame's visible
/// instances first and test the others against that image: two-phase
/// occlusion culling, in the camera's and the light's views, here with a
/// camera that moved in between), and each frame's image, ids, depths and
/// shadows are the expansion's, byte for byte.
#[test]
fn culled_instances_are_never_visible() {
    let ctx = validated_context();
    let s = meso("flagellarmotor_2-no_bonds.bcif");
    let e = s.expand().unwrap();
    let (c, r) = s.bounding_sphere();
    let (c, r) = (c.as_dvec3(), r as f64);
    let whole = camera(&s, 64, 48, None);
    let corner = |shift: f64| {
        let mut cam = whole;
        cam.view_height = whole.view_height / 4.0;
        cam.center = whole.center + whole.right * (r * (0.4 + shift)) + whole.up * (r * 0.2);
        cam
    };
    // (the eye a third of the scene's radius in front of a point inside it)
    let inside = |shift: f64| {
        let mut cam = camera(&s, 64, 48, Some(50.0));
        cam.view_height = r / 3.0;
        cam.center = c + cam.right * (r * (0.3 + shift));
        cam
    };
    let all = s.represented();
    for (what, cams) in [
        ("corner", [corner(0.0), corner(0.0), corner(0.05), whole]),
        (
            "perspective",
            [inside(0.0), inside(0.0), inside(-0.05), inside(-0.05)],
        ),
    ] {
        let mut st = settings(cams[0], ShadowMode::IssmSoft);
        st.ssdo = SsdoMode::Semantic;
        st.ssdo_knobs.blur = true;
        st.lod.lod_pixels = 0.0;
        let mut rd = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
        let mut late = Vec::new();
        for (f, &cam) in cams.iter().enumerate() {
            rd.update(|x| x.camera = cam).expect("camera");
            rd.render_frame().expect("frame");
            let counts = rd.inspect().lod_counts().unwrap().expect("the cull ran");
            late.push(counts.late_spheres);
            if f < 3 {
                assert!(
                    (counts.camera_spheres as u64) < all * 3 / 4 && counts.camera_spheres > 0,
                    "{what} frame {f}: the camera drew {} of {all} spheres",
                    counts.camera_spheres
                );
            }
            // the light draws what may shadow a visible point: the
            // instances over the light texels the camera's view volume
            // covers (less than the whole motor for the eye inside it),
            // then only the ones not hidden from the light
            assert!(counts.light_spheres as u64 <= all, "{what}");
            if what == "perspective" {
                assert!(
                    (counts.light_spheres as u64) < all,
                    "{what}: the light drew all"
                );
            }
            let mut se = st.clone();
            se.camera = cam;
            let b = frame(&ctx, &e, se);
            assert_frame_is(&rd.inspect(), &b, &format!("{what} frame {f}"));
            assert_no_validation_messages(&ctx);
        }
        // the first frame draws everything late (no history); the second,
        // same camera, nothing late
        assert!(late[0] > 0 && late[1] == 0, "{what}: late spheres {late:?}");
    }
}

/// See-through spheres on an instanced scene draw through the LOD lists:
/// their fragments visit the camera's early and late lists (the opaque
/// raster skips them in both phases), so culling still works, and with
/// every instance at full detail (`--lod-pixels 0`) the frames equal the
/// expanded scene's (no cull, every sphere in the camera's order) bit for
/// bit: colours, ids, depths and shadows, over frames with history (the
/// same camera, a pan, the whole model, then that per slot, then a
/// perspective camera inside the model, its opaque spheres drawn per
/// batch). The fragments visit the picked batches per batch with an
/// orthographic camera, each atom tested against the final opaque image's depth tiles
/// (dropping a part's first atom fails it: "frame 0: colours differ"),
/// and the count adds the key light's receivers of the spheres that made
/// fragments, per batch and per slot (without them: "colours differ",
/// the shadows of see-through spheres wrong).
#[test]
fn see_through_instances_draw_through_the_lod_lists() {
    let ctx = validated_context();
    let file = data_file("meso/flagellarmotor_2-no_bonds.bcif");
    let plain = load_with_rules(&file, &[], false);
    let inst = plain.instancing.as_ref().expect("instanced");
    let node = &inst.nodes[inst.molecules[2].node as usize];
    let rule = format!("not node {}=0.4", label_glob(&node.label));
    let s = load_with_rules(&file, &[("alpha", rule.as_str())], false);
    assert!(s.has_translucent() && s.instancing.is_some(), "{rule}");
    let e = s.expand().unwrap();
    let whole = camera(&s, 96, 72, None);
    let (c, r) = s.bounding_sphere();
    let corner = |shift: f64| {
        let mut cam = whole;
        cam.view_height = whole.view_height / 3.0;
        cam.center = whole.center + whole.right * (r as f64 * (0.3 + shift));
        cam
    };
    // (the eye inside the motor, perspective)
    let inside = {
        let mut cam = camera(&s, 96, 72, Some(50.0));
        cam.view_height = r as f64 / 3.0;
        cam.center = c.as_dvec3() + cam.right * (r as f64 * 0.3);
        cam
    };
    let all = s.represented();
    let mut st = settings(whole, ShadowMode::IssmSoft);
    st.ssdo = SsdoMode::Semantic;
    st.lod.lod_pixels = 0.0;
    let mut rd = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
    let mut fragments = 0;
    // (last, the whole model per slot, as a perspective camera's are:
    // each sphere that made a fragment adds the light's receivers itself;
    // then a perspective camera, whose opaque spheres are drawn per batch)
    for (f, cam) in [corner(0.0), corner(0.0), corner(0.05), whole, whole, inside]
        .into_iter()
        .enumerate()
    {
        if f == 4 {
            rd.inspect()
                .see_through()
                .expect("stage")
                .set_per_slot(true);
        }
        rd.update(|x| x.camera = cam).expect("camera");
        rd.render_frame().expect("frame");
        let what = format!("frame {f}");
        let counts = rd.inspect().lod_counts().unwrap().expect("the cull ran");
        if f < 3 {
            assert!(
                (counts.camera_spheres as u64) < all * 3 / 4 && counts.camera_spheres > 0,
                "{what}: the camera drew {} of {all} spheres",
                counts.camera_spheres
            );
        }
        let stats = rd.inspect().see_through_stats().expect("see-through ran");
        fragments += stats.fragments;
        let per_batch = rd
            .inspect()
            .see_through()
            .is_some_and(|s| s.ran_per_batch());
        assert_eq!(
            per_batch,
            f < 4,
            "{what}: the fragments visited the picked batches per batch"
        );
        assert!(
            rd.inspect().camera_per_batch(),
            "{what}: the camera's opaque spheres were drawn per slot"
        );
        let mut se = st.clone();
        se.camera = cam;
        let b = frame(&ctx, &e, se);
        assert_frame_is(&rd.inspect(), &b, &what);
        assert_no_validation_messages(&ctx);
    }
    assert!(fragments > 1000, "{fragments} see-through fragments");
}

/// The key light draws only what may shadow a point the camera sees: the
/// instances and batches over the light texels the visible points' lookups
/// read (each point's texel, grown by the lookup's reach: ISSM t, PCF
/// its radius + 1) and nearer the light than the farthest of those points,
/// the rest hidden by the light's depth tiles. Zoomed into
/// the meso scene (the visible points' light rectangle spans much more than
/// the texels they read), with history over three frames, the shadows
/// equal the expanded scene's (no cull) bit for bit in each lookup (PCF's
/// self test compares the placed centre: the light's list slot of a sphere
/// is not the camera's); and the light draws under 1 % of the scene.
#[test]
fn the_light_draws_only_what_visible_points_read() {
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(1_000_000, 1).unwrap();
    let e = s.expand().unwrap();
    let mut cam = camera(&s, 160, 120, None);
    cam.view_height /= 16.0;
    let all = s.represented();
    // (wide: more light texels with atoms near their depth, where the
    // light's per-tile front test hides least; it failed with a front
    // half a radius too deep)
    let mut wide = camera(&s, 320, 240, None);
    wide.view_height /= 2.0;
    // (zoomed: the cases that also bound the light's share of the scene;
    // a PCF radius of 300 texels reaches 151 depth tiles of the 2048^2
    // map: a (2 x 151 + 1)^2 loop, past lavapipe's 65,535 back-edges, once
    // found no tile read and hid every caster)
    for (cam, zoomed, shadows, t, pcf) in [
        (wide, false, ShadowMode::Issm, Some(0), None),
        (cam, true, ShadowMode::IssmSoft, None, None),
        (cam, true, ShadowMode::Issm, Some(3), None),
        (cam, true, ShadowMode::SmPcf, None, None),
        (cam, false, ShadowMode::SmPcf, None, Some(300.0)),
    ] {
        let mut st = settings(cam, shadows);
        st.lod.lod_pixels = 0.0;
        st.issm.t = sphereshade::settings::IssmT(t);
        if let Some(radius) = pcf {
            st.shadow_maps.pcf_radius = radius;
        }
        let mut rd = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
        for _ in 0..3 {
            rd.render_frame().expect("frame");
        }
        let counts = rd.inspect().lod_counts().unwrap().expect("the cull ran");
        let b = frame(&ctx, &e, st);
        let what = format!("{shadows:?} t {t:?} pcf {pcf:?}: {counts:?} of {all}");
        assert_frame_is(&rd.inspect(), &b, &what);
        assert!(counts.light_spheres > 0, "{what}");
        // (the texels' rectangle alone kept 26 k spheres here, the reach of
        // 34 texels any lookup was once given more)
        if zoomed {
            assert!((counts.light_spheres as u64) < all / 100, "{what}");
            // (what lies farther from the light than every visible point
            // reading its texels is hidden too: the soft ISSM's light drew
            // 3.1x the camera's spheres without, 2.0x with; t 3 2.6x, 1.7x)
            assert!(
                (counts.light_spheres as f64) < 2.5 * counts.camera_spheres as f64,
                "{what}: the light draws casters behind every receiver"
            );
        }
        assert_no_validation_messages(&ctx);
    }
}

/// The key light's lists drawn per batch (each atom projected by its
/// instance's linear map; only those whose disc may hold a texel centre
/// placed and keyed as the per-slot raster keys them) give the per-slot
/// raster's frames bit for bit: coarse levels over the whole scene and
/// zoomed in, full detail, a 2048^2 light map whose texels are smaller
/// than the atoms zoomed in (every atom a candidate, footprints past 64
/// texels in bands), ISSM soft, hard and PCF.
#[test]
fn the_light_per_batch_draws_the_per_slot_map() {
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(1_000_000, 1).unwrap();
    let whole = camera(&s, 160, 120, None);
    let mut zoomed = whole;
    zoomed.view_height /= 16.0;
    let mut closer = whole;
    closer.view_height /= 64.0;
    for (cam, lod_pixels, shadows, size) in [
        (whole, 2.0, ShadowMode::IssmSoft, 512),
        (zoomed, 2.0, ShadowMode::IssmSoft, 512),
        (zoomed, 0.0, ShadowMode::Issm, 512),
        (closer, 0.0, ShadowMode::Issm, 2048),
        (whole, 2.0, ShadowMode::SmPcf, 512),
    ] {
        let mut st = settings(cam, shadows);
        st.lod.lod_pixels = lod_pixels;
        st.issm.size = size;
        let mut slots = st.clone();
        slots.lod.lod_light_per_slot = true;
        let mut a = Renderer::new(&ctx, &s, st).expect("renderer");
        let mut b = Renderer::new(&ctx, &s, slots).expect("renderer");
        for _ in 0..2 {
            a.render_frame().expect("frame");
            b.render_frame().expect("frame");
        }
        let counts = a.inspect().lod_counts().unwrap().expect("the cull ran");
        let what = format!("{shadows:?} lod-pixels {lod_pixels} map {size}: {counts:?}");
        assert!(counts.light_spheres > 0, "{what}");
        assert_eq!(
            Some(counts),
            b.inspect().lod_counts().unwrap(),
            "{what}: the same lists"
        );
        assert_same_frame(&a.inspect(), &b.inspect(), &what);
        assert_no_validation_messages(&ctx);
    }
}

/// The camera's lists drawn per batch, each atom tested against depth
/// tiles before it is drawn (early: last frame's final tiles; then the
/// early list again: the atoms those tiles hid that this frame's early
/// tiles do not; late: this frame's early tiles), give the per-slot
/// raster's frames bit for bit: a still camera (the early test hides most
/// atoms, the recheck is skipped: the tiles are the last frame's) over the
/// whole scene, zoomed in and close (atoms past 2x2 fine tiles: coarse
/// ones; footprints past 128 pixels in bands), a molecule far from the
/// origin, and a panning one (its early test places each atom where last
/// frame's view saw it: atoms hidden there and now in view are the
/// recheck's), and a perspective camera inside the scene, still and
/// panning. (A recheck that draws nothing, or an early test without the
/// recheck's, fails it.)
#[test]
fn the_camera_per_batch_draws_the_per_slot_frame() {
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(1_000_000, 1).unwrap();
    let whole = camera(&s, 160, 120, None);
    let mut zoomed = whole;
    zoomed.view_height /= 16.0;
    // (near the closest the camera's lists are drawn per batch: the median
    // atom radius 4.5 pixels, under src/stages/raster/mod.rs
    // CAM_BATCH_MAX_PIXELS; larger atoms span 2x2 coarse tiles and reach
    // the bands)
    let mut radii: Vec<f32> = s.spheres.iter().map(|a| a.radius).collect();
    radii.sort_by(f32::total_cmp);
    let mut closer = whole;
    closer.view_height = closer.height as f64 * radii[radii.len() / 2] as f64 / 4.5;
    let pan = meso_pan(&s);
    let still = |c| vec![c, c, c];
    let pans = [0.0, 0.0, 0.03, 0.06, 0.1].map(&pan).to_vec();
    // A molecule of 1,600 A (4,096 atoms on a grid, overlapping) placed 10^6
    // A from the origin, turned: the projection of its atoms by the
    // instance's linear map must not lose the ~10^-2 of a unit axis that a
    // difference of placed points there does (the 10^12 scene's proxies).
    let far = {
        use sphereshade::scene::instanced::InstancedBuilder;
        let atoms: Vec<scene::Sphere> = (0..4096)
            .map(|k| {
                let (x, y, z) = (k % 16, k / 16 % 16, k / 256);
                sphere([x as f32 * 100.0, y as f32 * 100.0, z as f32 * 100.0], 70.0)
            })
            .collect();
        let mut b = InstancedBuilder::default();
        let m = b.molecule("grid", 0, atoms);
        for k in 0..4 {
            let q = DQuat::from_rotation_y(0.7 * k as f64) * DQuat::from_rotation_x(0.5);
            let t = [1e6 + k as f64 * 1200.0, 1e6 + (k % 2) as f64 * 900.0, 0.0];
            b.instance_quat("grid", m, q, t).unwrap();
        }
        b.finish("far grids").unwrap()
    };
    let mut far_cam = camera(&far, 160, 120, None);
    far_cam.view_height /= 3.0;
    // Perspective: the eye inside the virion (atoms up to the eye, some
    // reaching its plane, larger the nearer), still and panning (its early
    // test places each atom where last frame's perspective view saw it).
    let r = s.bounding_sphere().1 as f64;
    let mut persp = camera(&s, 160, 120, Some(40.0));
    persp.view_height /= 8.0;
    let persp_pans = [0.0, 0.0, 0.01, 0.02]
        .map(|u| {
            let mut c = persp;
            c.center += c.right * (r * u);
            c
        })
        .to_vec();
    for (what, scene, cams, lod_pixels) in [
        ("whole", &s, still(whole), 2.0),
        ("zoomed", &s, still(zoomed), 2.0),
        ("close, full detail", &s, still(closer), 0.0),
        ("panning", &s, pans, 2.0),
        ("far from the origin", &far, still(far_cam), 0.0),
        ("perspective", &s, still(persp), 2.0),
        ("perspective, panning", &s, persp_pans, 2.0),
    ] {
        let s = scene;
        let mut st = settings(cams[0], ShadowMode::IssmSoft);
        st.lod.lod_pixels = lod_pixels;
        let mut slots = st.clone();
        slots.lod.lod_camera_per_slot = true;
        let mut a = Renderer::new(&ctx, s, st).expect("renderer");
        let mut b = Renderer::new(&ctx, s, slots).expect("renderer");
        for (f, cam) in cams.into_iter().enumerate() {
            a.update(|x| x.camera = cam).expect("camera");
            b.update(|x| x.camera = cam).expect("camera");
            a.render_frame().expect("frame");
            b.render_frame().expect("frame");
            let counts = a.inspect().lod_counts().unwrap().expect("the cull ran");
            let what = format!("{what}, frame {f}: {counts:?}");
            assert!(counts.camera_spheres > 0, "{what}");
            assert!(
                a.inspect().camera_per_batch() && !b.inspect().camera_per_batch(),
                "{what}: not drawn per batch and per slot"
            );
            assert_same_frame(&a.inspect(), &b.inspect(), &what);
        }
        assert_no_validation_messages(&ctx);
    }
}

/// A renderer's last frame is `b`: the same ids and depths, colours and
/// shadow AOV, bit for bit.
fn assert_frame_is(a: &Inspect, b: &Frame, what: &str) {
    assert!(
        a.read_vis().unwrap() == b.vis,
        "{what}: ids or depths differ"
    );
    assert!(a.read_color().unwrap() == b.color, "{what}: colours differ");
    assert!(
        a.read_shadow().unwrap() == b.shadow,
        "{what}: shadows differ"
    );
}

/// Two renderers' last frames: the same ids and depths, colours and shadow
/// AOV, bit for bit.
fn assert_same_frame(a: &Inspect, b: &Inspect, what: &str) {
    assert!(
        a.read_vis().unwrap() == b.read_vis().unwrap(),
        "{what}: ids or depths differ"
    );
    assert!(
        a.read_color().unwrap() == b.read_color().unwrap(),
        "{what}: colours differ"
    );
    assert!(
        a.read_shadow().unwrap() == b.read_shadow().unwrap(),
        "{what}: shadows differ"
    );
}

/// A camera on scene `s` (128x96, orthographic) zoomed 8x into its
/// default view and panned `shift` of its radius to the right.
fn meso_pan(s: &Scene) -> impl Fn(f64) -> sphereshade::camera::Camera {
    let r = s.bounding_sphere().1 as f64;
    let whole = camera(s, 128, 96, None);
    move |shift| {
        let mut cam = whole;
        cam.view_height = whole.view_height / 8.0;
        cam.center = whole.center + whole.right * (r * shift);
        cam
    }
}

/// Culling at coarse levels (their spheres grown past the atoms: each
/// (type, level) has its own bounds) never drops a visible sphere: on one
/// renderer panning over the meso scene (orthographic, so every frame
/// keeps the same levels), each frame's ids, depths, colours and shadows equal a
/// fresh renderer's first frame at that camera, which (its history not
/// seeded with the front instances, `lod_no_front`) draws every
/// instance in the window (no history, nothing yet to hide behind); from
/// the third frame on (the first's history is everything in the window)
/// the history and the depth tiles cull.
#[test]
fn culled_coarse_levels_are_never_visible() {
    let ctx = validated_context();
    // (a virion in plasma: proteins of thousands of atoms behind others)
    let s = sphereshade::scene::meso::meso(1_000_000, 1).unwrap();
    let pan = meso_pan(&s);
    let st = settings(pan(0.0), ShadowMode::IssmSoft);
    let mut rd = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
    let mut coarse = 0;
    for (f, shift) in [0.0, 0.0, 0.0, 0.02, 0.04].into_iter().enumerate() {
        let cam = pan(shift);
        rd.update(|x| x.camera = cam).expect("camera");
        rd.render_frame().expect("frame");
        let mut unseeded = settings(cam, ShadowMode::IssmSoft);
        unseeded.lod.lod_no_front = true;
        let mut fresh = Renderer::new(&ctx, &s, unseeded).unwrap();
        fresh.render_frame().unwrap();
        let (a, b) = (rd.inspect(), fresh.inspect());
        let levels = a.lod_levels().unwrap().unwrap();
        assert_eq!(
            Some(&levels),
            b.lod_levels().unwrap().as_ref(),
            "frame {f}: levels"
        );
        coarse += levels.iter().filter(|&&l| l > 0).count();
        assert_same_frame(&a, &b, &format!("frame {f}"));
        let (x, y) = (
            a.lod_counts().unwrap().unwrap(),
            b.lod_counts().unwrap().unwrap(),
        );
        if f >= 2 {
            // occlusion culled spheres the fresh frame drew, all hidden
            assert!(
                x.camera_spheres < y.camera_spheres,
                "frame {f}: {x:?} {y:?}"
            );
            assert!(x.light_spheres < y.light_spheres, "frame {f}: {x:?} {y:?}");
        }
        assert_no_validation_messages(&ctx);
    }
    assert!(coarse > 0, "no instance drew a coarse level");
}

/// Where the camera's early phase has no tiles to test against (a first
/// frame, a large move) its history is seeded with the front instances,
/// the nearest per cell of about a typical instance's radius
/// (glsl/lod_front.comp): the early image covers the window and the late
/// phase hides what lies behind. On the meso scene, a first frame and a
/// 2x zoom in and back out (large moves, as the bench orbit's 4x zooms)
/// equal an unseeded renderer's frames bit for bit (ids, depths, colours,
/// shadows) and draw fewer spheres, the seeds early and some late.
#[test]
fn front_instances_seed_a_camera_without_history() {
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(10_000_000, 1).unwrap();
    let whole = camera(&s, 320, 240, None);
    let mut zoomed = whole;
    zoomed.view_height /= 4.0;
    let mut middle = whole;
    middle.view_height /= 2.0;
    let st = settings(middle, ShadowMode::IssmSoft);
    let mut unseeded = st.clone();
    unseeded.lod.lod_no_front = true;
    let mut a = Renderer::new(&ctx, &s, st).expect("renderer");
    let mut b = Renderer::new(&ctx, &s, unseeded).expect("renderer");
    for (f, cam) in [middle, zoomed, middle].into_iter().enumerate() {
        a.update(|x| x.camera = cam).expect("camera");
        b.update(|x| x.camera = cam).expect("camera");
        a.render_frame().expect("frame");
        b.render_frame().expect("frame");
        let (ia, ib) = (a.inspect(), b.inspect());
        let (x, y) = (
            ia.lod_counts().unwrap().expect("the cull ran"),
            ib.lod_counts().unwrap().expect("the cull ran"),
        );
        let what = format!("frame {f}: seeded {x:?}, not {y:?}");
        assert_same_frame(&ia, &ib, &what);
        // (320x240: 167 k / 123 k / 178 k spheres unseeded, 139 k / 100 k
        // / 149 k seeded; the 2x zoom in is a large move too)
        assert!(x.camera_spheres < y.camera_spheres, "{what}");
        let early = x.camera_spheres - x.late_spheres;
        assert!(early > 0 && x.late_spheres > 0, "{what}");
        assert_no_validation_messages(&ctx);
    }
}

/// A camera that keeps moving empties its last depth tiles every frame, so
/// its early phase hides nothing and every instance it lists passes again;
/// its history is then the instances its final image shows
/// (glsl/lod_shown.comp), which the next frame lists early after a small
/// move (src/stages/raster/lod.rs `small_move`). Panning in small steps
/// over the meso scene, then standing, then turning 30 degrees and back:
/// each moved frame flags exactly the instances its id AOV shows (the CPU
/// reads each pixel's instance from its expanded id), a still frame none;
/// a small move after a moved frame lists early only instances that
/// showed (not the turn, nor a still frame, whose last tiles are valid:
/// `culled_instances_are_never_visible` has it list nothing late); and
/// every frame equals a fresh renderer's first frame at its camera.
#[test]
fn a_moving_camera_remembers_the_instances_it_showed() {
    use sphereshade::gpu::consts::VISIBLE_SHOWN;
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(1_000_000, 1).unwrap();
    let inst = s.instancing.as_ref().expect("an instanced scene");
    let pan = meso_pan(&s);
    let turned = sphereshade::bench::orbit_step_camera(&pan(0.03), 1, 30.0).unwrap();
    // (whether the camera moved: the first frame's has no last view)
    let frames = [
        (pan(0.0), true),
        (pan(0.0), false),
        (pan(0.01), true),
        (pan(0.02), true),
        (pan(0.03), true),
        (pan(0.03), false),
        (turned, true),
        (pan(0.03), true),
    ];
    let mut rd = Renderer::new(&ctx, &s, settings(pan(0.0), ShadowMode::IssmSoft)).unwrap();
    let mut last: Option<(Vec<bool>, bool)> = None;
    let mut checked = 0;
    for (f, (cam, moved)) in frames.into_iter().enumerate() {
        rd.update(|x| x.camera = cam).expect("camera");
        rd.render_frame().expect("frame");
        let a = rd.inspect();
        // After a moved frame and a small move since: the early list holds
        // only instances that frame showed.
        let early = a
            .lod_camera_early_instances()
            .unwrap()
            .expect("the cull ran");
        if let Some((shown, true)) = &last
            && moved
            && f != 7
        {
            let other = early.iter().filter(|&&k| !shown[k as usize]).count();
            assert_eq!(
                other,
                0,
                "frame {f}: {other} of {} early batches",
                early.len()
            );
            assert!(!early.is_empty(), "frame {f}: nothing listed early");
            checked += 1;
        }
        let flags = a.lod_camera_flags().unwrap().expect("the cull ran");
        let mut shown = vec![false; flags.len()];
        for id in a.read_ids().unwrap().into_iter().flatten() {
            let (k, _) = inst.locate(id).expect("an atom of the scene");
            shown[k] = true;
        }
        let flagged: Vec<bool> = flags.iter().map(|&w| w & VISIBLE_SHOWN != 0).collect();
        let count = shown.iter().filter(|&&x| x).count();
        assert!(count > 10, "frame {f}: {count} instances shown");
        if moved {
            let wrong = (0..shown.len()).filter(|&k| shown[k] != flagged[k]).count();
            assert_eq!(
                wrong, 0,
                "frame {f}: {wrong} of {count} instances flagged wrong"
            );
        } else {
            assert!(!flagged.contains(&true), "frame {f}: a still frame flagged");
        }
        let mut fresh = Renderer::new(&ctx, &s, settings(cam, ShadowMode::IssmSoft)).unwrap();
        fresh.render_frame().unwrap();
        assert_same_frame(&a, &fresh.inspect(), &format!("frame {f}"));
        assert_no_validation_messages(&ctx);
        last = Some((shown, moved));
    }
    assert_eq!(checked, 2, "small moves after a moved frame");
}

/// The late phase tests only what the early one deferred: a batch the
/// last frame's image hides on its own, an instance whole. Where the
/// deferral room is full, the instance is deferred from the batch that did
/// not fit on and the late phase recomputes the early tests for the rest.
/// Panning over the meso scene with ISSM (the light's view stays, so its
/// early phase defers the batches its last, masked, depth tiles hide; after
/// a pan some of them shadow what the camera now sees), a renderer with
/// room for one batch draws every frame exactly as one with the default
/// room, and both defer. (Skipping the batch that did not fit fails it.)
#[test]
fn deferred_batches_past_the_room_are_tested_with_their_instance() {
    let ctx = validated_context();
    let s = sphereshade::scene::meso::meso(1_000_000, 1).unwrap();
    let pan = meso_pan(&s);
    let st = settings(pan(0.0), ShadowMode::IssmSoft);
    let mut tight = st.clone();
    tight.lod.lod_deferred_batches = Some(1);
    let mut a = Renderer::new(&ctx, &s, st).expect("renderer");
    let mut b = Renderer::new(&ctx, &s, tight).expect("renderer");
    let (mut deferred, mut overflowed) = (0, 0);
    for (f, shift) in [0.0, 0.0, 0.0, 0.1, 0.1, 0.2].into_iter().enumerate() {
        for rd in [&mut a, &mut b] {
            rd.update(|x| x.camera = pan(shift)).expect("camera");
            rd.render_frame().expect("frame");
        }
        let (ia, ib) = (a.inspect(), b.inspect());
        assert_same_frame(&ia, &ib, &format!("frame {f}"));
        let (x, y) = (
            ia.lod_counts().unwrap().unwrap(),
            ib.lod_counts().unwrap().unwrap(),
        );
        let room = ia.lod_list_capacity().unwrap() / 4;
        for v in 0..2 {
            assert!(x.deferred[v][1] <= room, "frame {f}: {x:?} past {room}");
            deferred += x.deferred[v][1];
            overflowed += (y.deferred[v][1] > 1) as u32;
        }
        assert_no_validation_messages(&ctx);
    }
    assert!(deferred > 0, "no batch was deferred");
    assert!(overflowed > 0, "the room of one batch never overflowed");
}

/// An instance of thousands of batches, each tested against many depth
/// tiles, is culled in chunks of CULL_CHUNK_BATCHES: lavapipe ends every
/// loop of a shader invocation after 65,535 back-edges in all, silently,
/// and one invocation looping over all 4,096 batches of this cube (~30
/// tile loads a batch hidden behind the front, frames 2 and 3) stopped
/// part-way: its last batches were neither listed nor deferred. Three
/// frames from one camera equal the expanded scene (no cull) bit for bit,
/// ids, depths, colours and shadows, with the cull's lists and history.
#[test]
fn an_instance_of_thousands_of_batches_is_culled_whole() {
    use sphereshade::gpu::consts::CULL_CHUNK_BATCHES;
    use sphereshade::scene::instanced::InstancedBuilder;
    let ctx = validated_context();
    // 64^3 atoms in 4x4x4 blocks, one block a batch (64 atoms)
    let mut atoms = Vec::new();
    for b in 0..4096u32 {
        let (bx, by, bz) = (b % 16, b / 16 % 16, b / 256);
        for a in 0..64u32 {
            let (x, y, z) = (bx * 4 + a % 4, by * 4 + a / 4 % 4, bz * 4 + a / 16);
            atoms.push(sphere(
                [x as f32 * 1.5, y as f32 * 1.5, z as f32 * 1.5],
                0.9,
            ));
        }
    }
    assert!(atoms.len() / 64 > 8 * CULL_CHUNK_BATCHES as usize);
    let mut b = InstancedBuilder::default();
    let m = b.molecule("cube", 0, atoms);
    b.instance_quat("a", m, DQuat::IDENTITY, [0.0; 3]).unwrap();
    let q = DQuat::from_rotation_y(0.5) * DQuat::from_rotation_x(0.3);
    b.instance_quat("b", m, q, [150.0, 20.0, -40.0]).unwrap();
    let s = b.finish("cubes").unwrap();
    let e = s.expand().unwrap();
    let mut st = settings(camera(&s, 512, 384, None), ShadowMode::IssmSoft);
    st.lod.lod_pixels = 0.0;
    let mut rd = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
    let want = frame(&ctx, &e, st);
    for f in 0..3 {
        rd.render_frame().expect("frame");
        assert_frame_is(&rd.inspect(), &want, &format!("frame {f}"));
    }
    assert_no_validation_messages(&ctx);
}

/// Levels of detail: each instance's level follows its size on screen
/// (the coarsest whose switch size it is within: level 0 close up), and a
/// level coarser than last frame's is taken only once the size is a band
/// (LOD_BAND) below its switch size, so a viewer zooming across a switch
/// does not flicker; never a level above its switch size.
#[test]
fn levels_follow_the_size_on_screen_with_a_band() {
    use sphereshade::gpu::consts::LOD_BAND;
    use sphereshade::scene::instanced::lod::{MoleculeLod, level_for};
    let ctx = validated_context();
    let s = meso("sarscov2_2-no_bonds.bcif");
    let inst = s.instancing.as_ref().unwrap();
    let switch: Vec<Vec<f32>> = inst
        .molecules
        .iter()
        .map(|m| {
            let atoms: Vec<[f32; 4]> = s.spheres[m.first as usize..(m.first + m.atoms) as usize]
                .iter()
                .map(|a| [a.center[0], a.center[1], a.center[2], a.radius])
                .collect();
            MoleculeLod::new(&atoms).switch_ppu(&atoms, 2.0)
        })
        .collect();
    // the CPU twin of the cull's choice
    let expect = |prev: Option<&[u32]>, ppu: f32| -> Vec<u32> {
        (0..inst.instances())
            .map(|k| {
                let sw = &switch[inst.instance_molecule[k] as usize];
                let level = level_for(sw, ppu) as u32;
                let banded = level_for(sw, ppu * LOD_BAND) as u32;
                match prev {
                    Some(p) if p[k] <= level => p[k].max(banded),
                    _ => level,
                }
            })
            .collect()
    };
    // a switch size most types share (the first type's level 1)
    let sw1 = switch[0][1];
    let at = |ppu: f32| {
        let mut cam = camera(&s, 64, 48, None);
        cam.view_height = 48.0 / ppu as f64;
        cam
    };
    let levels = |r: &Renderer| r.inspect().lod_levels().unwrap().expect("the cull ran");
    let st = settings(at(sw1 * 1.3), ShadowMode::Issm);
    let mut r = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
    let mut prev: Option<Vec<u32>> = None;
    for (f, ppu) in [1.3f32, 0.95, 0.95, 0.8, 1.02, 2.0].into_iter().enumerate() {
        r.update(|x| x.camera = at(sw1 * ppu)).expect("camera");
        r.render_frame().expect("frame");
        let got = levels(&r);
        let want = expect(prev.as_deref(), sw1 * ppu);
        assert_eq!(got, want, "frame {f} at {ppu} x the switch size");
        // never coarser than the level its size allows
        let most = expect(None, sw1 * ppu);
        assert!(got.iter().zip(&most).all(|(g, m)| g <= m), "frame {f}");
        prev = Some(got);
    }
    // the band held level 0 at 0.95 x the switch size, where a fresh
    // renderer takes level 1
    let mut fresh = Renderer::new(&ctx, &s, settings(at(sw1 * 0.95), ShadowMode::Issm)).unwrap();
    fresh.render_frame().unwrap();
    let f = levels(&fresh);
    let k0 = inst.instance_molecule.iter().position(|&m| m == 0).unwrap();
    assert_eq!(f[k0], 1, "a fresh renderer at 0.95 x the switch size");
    assert_eq!(prev.unwrap()[k0], 0);
    assert_no_validation_messages(&ctx);
}

/// The LOD lists told to start one batch long (`--lod-list-batches 1`):
/// the first frame lists more, the lists grow and the frame is drawn again,
/// and its image is the one of lists long enough from the start (colour,
/// ids and depths, shadow AOV); the next frames fit. Lists a frame fills
/// past three quarters but fits grow only before the next frame: that
/// frame's ids (slots of its lists) still name its spheres. Under
/// validation.
#[test]
fn lod_lists_grow_when_a_frame_overflows() {
    let ctx = validated_context();
    let s = meso("flagellarmotor_2-no_bonds.bcif");
    let st = settings(camera(&s, 64, 48, None), ShadowMode::Issm);
    let mut short = st.clone();
    short.lod.lod_list_batches = Some(1);
    let mut a = Renderer::new(&ctx, &s, st.clone()).expect("renderer");
    let mut b = Renderer::new(&ctx, &s, short).expect("renderer");
    // (a first frame lists everything late: its longest list is the
    // larger view's count)
    a.render_frame().expect("frame");
    let first = a.inspect().lod_counts().unwrap().expect("the cull ran");
    let asked = first.camera_batches.max(first.light_batches);
    let mut nearly = st;
    nearly.lod.lod_list_batches = Some(asked + asked / 8);
    let mut c = Renderer::new(&ctx, &s, nearly).expect("renderer");
    c.render_frame().expect("frame");
    assert_eq!(c.inspect().lod_list_capacity(), Some(asked + asked / 8));
    assert_same_frame(&a.inspect(), &c.inspect(), "a frame that fit");
    c.render_frame().expect("frame");
    assert!(c.inspect().lod_list_capacity() > Some(asked + asked / 8));
    let mut a = Renderer::new(
        &ctx,
        &s,
        settings(camera(&s, 64, 48, None), ShadowMode::Issm),
    )
    .expect("renderer");
    for f in 0..2 {
        a.render_frame().expect("frame");
        b.render_frame().expect("frame");
        let (ia, ib) = (a.inspect(), b.inspect());
        let counts = ib.lod_counts().unwrap().expect("the cull ran");
        let cap = ib.lod_list_capacity().expect("lists");
        assert!(
            cap > 1 && cap >= counts.camera_batches.max(counts.light_batches),
            "frame {f}: {cap} batches for {counts:?}"
        );
        // (the counts may differ: the frame drawn again has the first
        // try's occlusion history, so it draws more early and hides more)
        assert_same_frame(&ia, &ib, &format!("frame {f}"));
    }
    assert_no_validation_messages(&ctx);
}

/// A scene of more than 2^24 spheres (262,145 instances of a 64-atom
/// molecule, 16,777,280 represented): the id AOV is RGBA16 (DESIGN.md),
/// index + 1 in R, G, B, and names expanded indices past 2^24.
#[test]
fn ids_past_2_pow_24_are_rgba16() {
    use sphereshade::scene::instanced::InstancedBuilder;
    let ctx = validated_context();
    let mut b = InstancedBuilder::default();
    let atoms: Vec<scene::Sphere> = (0..64)
        .map(|k| sphere([(k % 8) as f32 * 1.2, (k / 8) as f32 * 1.2, 0.0], 0.7))
        .collect();
    let m = b.molecule("block", 0, atoms);
    let n = (1 << 24) / 64 + 1;
    for k in 0..n {
        // a wall of blocks 512 wide, later ones nearer the viewer
        let (x, y) = ((k % 512) as f64 * 10.0, (k / 512) as f64 * 10.0);
        b.instance_quat("wall", m, DQuat::IDENTITY, [x, y, k as f64 * 1e-4])
            .unwrap();
    }
    let s = b.finish("wall").unwrap();
    assert_eq!(s.represented(), 16_777_280);
    let mut st = settings(camera(&s, 64, 48, None), ShadowMode::None);
    // the last block (instance 262,144 at (0, 5120)): ids past 2^24, and
    // its neighbours below
    st.camera.view_height = 20.0;
    st.camera.center = DVec3::new(4.2, 5120.0, 0.0);
    let mut r = Renderer::new(&ctx, &s, st).expect("renderer");
    r.render_frame().expect("frame");
    let vis = r.inspect().read_vis().unwrap();
    let img = sphereshade::run::aov_image(&r, sphereshade::settings::Aov::Id).unwrap();
    drop(r);
    assert_no_validation_messages(&ctx);
    let sphereshade::output::AovImage::Rgba16(img) = img else {
        panic!("the id AOV of 2^24+ spheres is not RGBA16");
    };
    let mut past = 0;
    for (p, &k) in img.pixels().zip(&vis) {
        let v = p.0[0] as u64 | (p.0[1] as u64) << 16 | (p.0[2] as u64) << 32;
        assert_eq!(p.0[3], 65535);
        if k == sphereshade::gpu::VIS_EMPTY {
            assert_eq!(v, 0);
            continue;
        }
        assert_eq!(v, (k & 0xFFFF_FFFF) + 1);
        past += (v > 1 << 24) as usize;
    }
    assert!(past > 100, "{past} pixels show a sphere past 2^24");
}

/// Past 2^32 atoms (66,004 instances of a 65,536-atom block, 4.3 * 10^9
/// represented) the LOD lists draw the scene, their slots being the
/// ids: four cubes in view, placed last, render the colour of a scene of
/// those four alone (the rest lies outside the window and is culled), and
/// their pixels name the same atoms, at expanded indices past 2^32, in
/// `read_ids` and in the id AOV (RGBA16, 48 bits; read back whole and
/// assembled from tiles). What names atoms by 32 bits (read_vis) and what
/// draws every atom (deep shadows) are refused in one line each.
#[test]
fn past_2_pow_32_atoms_draw_through_the_lod_lists() {
    use sphereshade::scene::instanced::InstancedBuilder;
    let ctx = validated_context();
    let atoms: Vec<scene::Sphere> = (0..65536)
        .map(|k| {
            let (x, y, z) = (k % 32, k / 32 % 32, k / 1024);
            sphere([x as f32 * 1.5, y as f32 * 1.5, z as f32 * 1.5], 0.9)
        })
        .collect();
    let near: Vec<(DQuat, [f64; 3])> = (0..4)
        .map(|k| {
            let q = DQuat::from_rotation_y(0.4 * k as f64) * DQuat::from_rotation_x(0.3);
            (q, [k as f64 * 60.0, (k % 2) as f64 * 30.0, 0.0])
        })
        .collect();
    let far = 66_000u32;
    // (rows to the side of the view; the small scene holds their first
    // and last, so both have the same bounds, the same depth keys)
    let at = |k: u32| {
        [
            2e3 + (k % 300) as f64 * 120.0,
            (k / 300) as f64 * 120.0,
            0.0,
        ]
    };
    let build = |far: &mut dyn Iterator<Item = u32>| {
        let mut b = InstancedBuilder::default();
        let m = b.molecule("cube", 0, atoms.clone());
        for k in far {
            b.instance_quat("far", m, DQuat::IDENTITY, at(k)).unwrap();
        }
        for &(q, t) in &near {
            b.instance_quat("near", m, q, t).unwrap();
        }
        b.finish("cubes").unwrap()
    };
    let (big, small) = (build(&mut (0..far)), build(&mut [0, far - 1].into_iter()));
    let offset = (far as u64 - 2) * 65536;
    assert!(offset > u32::MAX as u64);
    assert_eq!(big.represented(), (far as u64 + 4) * 65536);
    let near_only = build(&mut std::iter::empty());
    let mut st = settings(camera(&near_only, 64, 48, None), ShadowMode::None);
    st.lod.lod_pixels = 2.0;
    // (the id AOV's pixels: index + 1, 0 the background; in 48 bits from
    // 2^24 spheres on, else 24)
    let decode = |img: sphereshade::output::AovImage| -> Vec<Option<u64>> {
        use sphereshade::output::AovImage::{Rgba8, Rgba16};
        let v: Vec<u64> = match img {
            Rgba16(img) => img
                .pixels()
                .map(|p| p.0[0] as u64 | (p.0[1] as u64) << 16 | (p.0[2] as u64) << 32)
                .collect(),
            Rgba8(img) => img
                .pixels()
                .map(|p| p.0[0] as u64 | (p.0[1] as u64) << 8 | (p.0[2] as u64) << 16)
                .collect(),
            _ => panic!("the id AOV is RGBA8 or RGBA16"),
        };
        v.into_iter().map(|v| v.checked_sub(1)).collect()
    };
    let read = |s: &Scene| {
        let mut r = Renderer::new(&ctx, s, st.clone()).expect("renderer");
        r.render_frame().expect("frame");
        let aov = decode(sphereshade::run::aov_image(&r, Aov::Id).unwrap());
        let i = r.inspect();
        let drawn = i
            .lod_counts()
            .unwrap()
            .expect("the cull ran")
            .camera_spheres;
        let ids = i.read_ids().unwrap();
        let (color, vis) = (i.read_color().unwrap(), i.read_vis().map(|_| ()));
        assert!(aov == ids, "the id AOV names other atoms");
        // (the same image in tiles, each window drawn through its own lists)
        let (tiled, _) = r.render_image(Some(32)).expect("tiles");
        assert!(tiled.tiles > 1);
        // (the JSON's spheres_drawn of a tiled image: every tile's, at
        // least each atom that shows once, more than the last tile's)
        let tiles_drawn = r.inspect().spheres_drawn().unwrap();
        let last = r.inspect().lod_counts().unwrap().unwrap().camera_spheres as u64;
        let tiled = decode(sphereshade::run::image_aov(&tiled, Aov::Id));
        assert!(tiled == ids, "the tiled id AOV names other atoms");
        let shown: std::collections::HashSet<u64> = tiled.iter().flatten().copied().collect();
        assert!(
            tiles_drawn >= shown.len() as u64 && tiles_drawn > last,
            "tiles drew {tiles_drawn} spheres, the last {last}, {} show",
            shown.len()
        );
        (color, ids, drawn, vis)
    };
    let (color_b, ids_b, drawn_b, vis_b) = read(&big);
    let (color_s, ids_s, drawn_s, _) = read(&small);
    assert_no_validation_messages(&ctx);
    assert_eq!(drawn_b, drawn_s, "the far cubes are culled");
    assert!(color_b == color_s, "colours differ");
    let mut seen = 0;
    for (p, (b, s)) in ids_b.iter().zip(&ids_s).enumerate() {
        assert_eq!(*b, s.map(|e| e + offset), "pixel {p}");
        seen += s.is_some() as usize;
    }
    assert!(seen > 200, "{seen} pixels show a cube");
    let msg = vis_b.expect_err("32-bit ids past 2^32 atoms").to_string();
    assert!(!msg.contains('\n'), "{msg}");
    assert!(msg.starts_with("4325638144 atoms:"), "{msg}");
    let mut deep = st.clone();
    deep.shadows = ShadowMode::Deep;
    let msg = match Renderer::new(&ctx, &big, deep) {
        Ok(_) => panic!("deep shadows draw every atom past 2^32 ids"),
        Err(e) => e.to_string(),
    };
    assert!(!msg.contains('\n'), "{msg}");
    assert!(
        msg.contains("drawing every atom needs 4325638208 sphere ids"),
        "{msg}"
    );
    assert_no_validation_messages(&ctx);
}

/// The EXR layers of an instanced scene add `instance` and `atom` (index
/// within the molecule), agreeing with the `id` layer.
#[test]
fn exr_layers_name_instance_and_atom() {
    let ctx = validated_context();
    let s = meso("HIV-1_0.1.6-8_mixed_radii_pdb.json");
    let inst = s.instancing.as_ref().unwrap();
    let st = settings(camera(&s, 48, 36, None), ShadowMode::Issm);
    let (layers, stats) = sphereshade::run::render_layers(&ctx, &s, "hiv", st, 0.0).unwrap();
    assert_no_validation_messages(&ctx);
    assert_eq!(stats.instances, Some(11_681));
    assert_eq!(stats.spheres, 91_956);
    let get = |n: &str| &layers.iter().find(|l| l.0 == n).unwrap().1;
    let (id, instance, atom) = (get("id"), get("instance"), get("atom"));
    let mut seen = 0;
    for i in 0..id.len() {
        if id[i] == 0.0 {
            assert_eq!((instance[i], atom[i]), (-1.0, -1.0));
            continue;
        }
        let e = id[i] as u64 - 1;
        let (k, a) = inst.locate(e).unwrap();
        assert_eq!((instance[i], atom[i]), (k as f32, a as f32));
        seen += 1;
    }
    assert!(seen > 500, "{seen}");
}

/// ISSM hard shadows of an instanced scene against exact shadow rays
/// through the expanded spheres (f64): at least 99.5 % of the visible
/// pixels agree.
#[test]
fn instanced_issm_matches_exact_shadow_rays() {
    let ctx = validated_context();
    let s = capsid_60mer();
    let e = s.expand().unwrap();
    let mut st = settings(camera(&s, 160, 120, None), ShadowMode::Issm);
    // (full detail: the reference rays meet every atom; at this size the
    // coarse levels of the half-pixel rule would be drawn)
    st.lod.lod_pixels = 0.0;
    let (cam, light) = (st.camera, st.light);
    let mut r = Renderer::new(&ctx, &s, st).expect("renderer");
    r.render_frame().expect("frame");
    let ids = ids_from_vis(&r.inspect().read_vis().unwrap());
    let shadow = r.inspect().read_shadow().unwrap();
    drop(r);
    assert_no_validation_messages(&ctx);
    let (refs, img) = sphereshade::reference::shadow_image(&e.spheres, &cam, light, 1.0);
    let (mut compared, mut agree) = (0, 0);
    for i in 0..ids.len() {
        let Some(v) = refs[i] else { continue };
        if ids[i] != Some(img.ids[i]) {
            continue;
        }
        compared += 1;
        agree += ((shadow[i] < 0.5) == (v < 0.5)) as usize;
    }
    let pct = 100.0 * agree as f64 / compared as f64;
    eprintln!(
        "1F2N 60-mer: ISSM hard mask agrees with exact shadow rays on {pct:.3} % of {compared} pixels"
    );
    assert!(compared > 5000 && pct >= 99.5, "{pct} % of {compared}");
}

/// Each hierarchy level of an instanced scene (SARS-CoV-2: group, type,
/// molecule, chain) reaches the region words semantic SSDO compares: the
/// record of every covered block holds the region hash of its sphere at
/// the forced level, as the CPU's expansion gives it.
#[test]
fn hierarchy_levels_reach_the_regions() {
    let ctx = validated_context();
    let s = meso("sarscov2_2-no_bonds.bcif");
    let levels = s.level_names.len();
    assert_eq!(levels, 4);
    let cam = camera(&s, 96, 72, None);
    for level in 0..levels {
        let mut st = settings(cam, ShadowMode::None);
        st.ssdo = SsdoMode::Semantic;
        // thresholds putting this camera's zoom exactly at `level`
        let d = cam.view_height;
        st.ssdo_knobs.semantic_levels = Some(Levels(
            (0..levels - 1)
                .map(|j| if j < level { 100.0 * d } else { 0.01 * d })
                .collect(),
        ));
        let mut r = Renderer::new(&ctx, &s, st).expect("renderer");
        r.render_frame().expect("frame");
        let choice = r.inspect().level_choice().unwrap();
        assert_eq!((choice.level_a, choice.blend), (level as u32, 0.0));
        let records = r.inspect().read_records().unwrap();
        let vis = r.inspect().read_vis().unwrap();
        drop(r);
        let hw = cam.width.div_ceil(2);
        let mut seen = std::collections::HashSet::new();
        let mut checked = 0;
        for (b, rec) in records.iter().enumerate() {
            if !rec.covered {
                continue;
            }
            let (bx, by) = (b as u32 % hw, b as u32 / hw);
            let (x, y) = (2 * bx + rec.sub[0], 2 * by + rec.sub[1]);
            let id = vis[(y * cam.width + x) as usize] & 0xFFFF_FFFF;
            let region = s.sphere(id).unwrap().region[level];
            assert_eq!(
                rec.region_a,
                region_hash(region) & 0x7FFF,
                "level {level} block {b}"
            );
            seen.insert(region);
            checked += 1;
        }
        eprintln!(
            "level {level} ({}): {checked} blocks, {} regions",
            s.level_names[level],
            seen.len()
        );
        assert!(checked > 500 && seen.len() > 1, "level {level}");
    }
    assert_no_validation_messages(&ctx);
}

/// `--raster graphics` refuses an instanced scene in one line.
#[test]
fn the_graphics_baseline_refuses_instanced_scenes() {
    let ctx = validated_context();
    let s = meso("HIV-1_0.1.6-8_mixed_radii_pdb.json");
    let mut st = settings(camera(&s, 32, 24, None), ShadowMode::None);
    st.raster = sphereshade::settings::RasterMode::Graphics;
    let e = Renderer::new(&ctx, &s, st)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("--raster graphics") && !e.contains('\n'), "{e}");
    assert_no_validation_messages(&ctx);
}

/// A small BinaryCIF writer (the text mmCIF's categories, each column in
/// the encodings its values allow), for the reader's tests.
mod bcif_writer {
    use super::Value;

    pub enum Break {
        UnknownEncoding,
        ShortColumn,
    }

    fn map(pairs: Vec<(&str, Value)>) -> Value {
        Value::Map(
            pairs
                .into_iter()
                .map(|(k, v)| (Value::from(k), v))
                .collect(),
        )
    }
    fn enc(kind: &str, mut extra: Vec<(&str, Value)>) -> Value {
        extra.push(("kind", Value::from(kind)));
        map(extra)
    }
    fn bytes_i32(v: &[i64]) -> Vec<u8> {
        v.iter().flat_map(|&x| (x as i32).to_le_bytes()).collect()
    }

    /// Categories of a text mmCIF: (name, items, rows of raw tokens).
    fn categories(text: &str) -> Vec<(String, Vec<String>, Vec<Vec<String>>)> {
        let mut out: Vec<(String, Vec<String>, Vec<Vec<String>>)> = Vec::new();
        let mut lines = text.lines().peekable();
        let tokens = |l: &str| -> Vec<String> {
            let mut v = Vec::new();
            let b = l.as_bytes();
            let mut i = 0;
            while i < b.len() {
                if b[i].is_ascii_whitespace() {
                    i += 1;
                    continue;
                }
                if b[i] == b'\'' || b[i] == b'"' {
                    let q = b[i];
                    let mut j = i + 1;
                    while j < b.len()
                        && !(b[j] == q && (j + 1 == b.len() || b[j + 1].is_ascii_whitespace()))
                    {
                        j += 1;
                    }
                    v.push(l[i + 1..j.min(b.len())].to_string());
                    i = j + 1;
                } else {
                    let s = i;
                    while i < b.len() && !b[i].is_ascii_whitespace() {
                        i += 1;
                    }
                    v.push(l[s..i].to_string());
                }
            }
            v
        };
        while let Some(l) = lines.next() {
            if l.starts_with(';') {
                // a text field: skip to its end
                for m in lines.by_ref() {
                    if m.starts_with(';') {
                        break;
                    }
                }
                continue;
            }
            if l.starts_with("loop_") {
                let mut items = Vec::new();
                while let Some(n) = lines.peek() {
                    if n.starts_with('_') {
                        items.push(n.trim().to_string());
                        lines.next();
                    } else {
                        break;
                    }
                }
                let mut rows = Vec::new();
                let mut pending: Vec<String> = Vec::new();
                while let Some(n) = lines.peek() {
                    if n.starts_with('_')
                        || n.starts_with("loop_")
                        || n.starts_with('#')
                        || n.starts_with("data_")
                    {
                        break;
                    }
                    if n.starts_with(';') {
                        lines.next();
                        for m in lines.by_ref() {
                            if m.starts_with(';') {
                                break;
                            }
                        }
                        pending.push("?".into());
                    } else {
                        pending.extend(tokens(n));
                        lines.next();
                    }
                    while pending.len() >= items.len() && !items.is_empty() {
                        rows.push(pending.drain(..items.len()).collect());
                    }
                }
                let cat = items[0].split('.').next().unwrap().to_string();
                let items = items
                    .iter()
                    .map(|i| i.split_once('.').unwrap().1.to_string())
                    .collect();
                out.push((cat, items, rows));
            } else if l.starts_with('_') {
                let t = tokens(l);
                let (cat, item) = t[0].split_once('.').unwrap();
                let value = t.get(1).cloned().unwrap_or_else(|| "?".into());
                match out.last_mut() {
                    Some(c) if c.0 == cat && c.2.len() == 1 => {
                        c.1.push(item.to_string());
                        c.2[0].push(value);
                    }
                    _ => out.push((cat.to_string(), vec![item.to_string()], vec![vec![value]])),
                }
            }
        }
        out
    }

    /// One column's encoded data: integers (Delta, RunLength,
    /// IntegerPacking, ByteArray), fixed decimals (FixedPoint, Delta,
    /// IntegerPacking, ByteArray) or strings (StringArray).
    fn column(values: &[Option<&str>]) -> Value {
        let present: Vec<&str> = values.iter().flatten().copied().collect();
        let int_ok = !present.is_empty()
            && present
                .iter()
                .all(|v| v.parse::<i64>().is_ok_and(|i| i.to_string() == *v));
        if int_ok {
            let ints: Vec<i64> = values
                .iter()
                .map(|v| v.map_or(0, |s| s.parse().unwrap()))
                .collect();
            // Delta from the first value
            let origin = ints[0];
            let mut deltas = Vec::with_capacity(ints.len());
            let mut last = origin;
            for (k, &x) in ints.iter().enumerate() {
                deltas.push(if k == 0 { 0 } else { x - last });
                last = x;
            }
            // RunLength pairs
            let mut rl = Vec::new();
            for &d in &deltas {
                match rl.len() {
                    n if n >= 2 && rl[n - 2] == d => rl[n - 1] += 1,
                    _ => {
                        rl.push(d);
                        rl.push(1);
                    }
                }
            }
            // IntegerPacking into signed bytes
            let mut packed: Vec<u8> = Vec::new();
            for &x in &rl {
                let mut v = x;
                while v >= 127 {
                    packed.push(127);
                    v -= 127;
                }
                while v <= -128 {
                    packed.push(0x80);
                    v += 128;
                }
                packed.push(v as i8 as u8);
            }
            return map(vec![
                ("data", Value::Binary(packed)),
                (
                    "encoding",
                    Value::Array(vec![
                        enc(
                            "Delta",
                            vec![("origin", Value::from(origin)), ("srcType", Value::from(3))],
                        ),
                        enc(
                            "RunLength",
                            vec![
                                ("srcType", Value::from(3)),
                                ("srcSize", Value::from(ints.len())),
                            ],
                        ),
                        enc(
                            "IntegerPacking",
                            vec![
                                ("byteCount", Value::from(1)),
                                ("isUnsigned", Value::from(false)),
                                ("srcSize", Value::from(rl.len())),
                            ],
                        ),
                        enc("ByteArray", vec![("type", Value::from(1))]),
                    ]),
                ),
            ]);
        }
        let digits = |v: &str| v.split_once('.').map(|(_, f)| f.len());
        let dec_ok = !present.is_empty()
            && present.iter().all(|v| {
                let d = digits(v);
                d.is_some() && d == digits(present[0]) && v.replace('.', "").parse::<i64>().is_ok()
            });
        if dec_ok {
            let d = digits(present[0]).unwrap() as u32;
            let ints: Vec<i64> = values
                .iter()
                .map(|v| v.map_or(0, |s| s.replace('.', "").parse().unwrap()))
                .collect();
            let mut packed: Vec<u8> = Vec::new();
            let mut last = 0;
            for (k, &x) in ints.iter().enumerate() {
                let mut v = if k == 0 { x } else { x - last };
                last = x;
                while v >= 32767 {
                    packed.extend(32767i16.to_le_bytes());
                    v -= 32767;
                }
                while v <= -32768 {
                    packed.extend((-32768i16).to_le_bytes());
                    v += 32768;
                }
                packed.extend((v as i16).to_le_bytes());
            }
            return map(vec![
                ("data", Value::Binary(packed)),
                (
                    "encoding",
                    Value::Array(vec![
                        enc(
                            "FixedPoint",
                            vec![
                                ("factor", Value::from(10i64.pow(d))),
                                ("srcType", Value::from(33)),
                            ],
                        ),
                        enc(
                            "Delta",
                            vec![("origin", Value::from(0)), ("srcType", Value::from(3))],
                        ),
                        enc(
                            "IntegerPacking",
                            vec![
                                ("byteCount", Value::from(2)),
                                ("isUnsigned", Value::from(false)),
                            ],
                        ),
                        enc("ByteArray", vec![("type", Value::from(2))]),
                    ]),
                ),
            ]);
        }
        let mut table: Vec<&str> = Vec::new();
        let index: Vec<i64> = values
            .iter()
            .map(|v| match v {
                None => -1,
                Some(s) => match table.iter().position(|t| t == s) {
                    Some(i) => i as i64,
                    None => {
                        table.push(s);
                        table.len() as i64 - 1
                    }
                },
            })
            .collect();
        let mut offsets = vec![0i64];
        for t in &table {
            offsets.push(offsets.last().unwrap() + t.len() as i64);
        }
        map(vec![
            ("data", Value::Binary(bytes_i32(&index))),
            (
                "encoding",
                Value::Array(vec![enc(
                    "StringArray",
                    vec![
                        ("stringData", Value::from(table.concat())),
                        ("offsets", Value::Binary(bytes_i32(&offsets))),
                        (
                            "offsetEncoding",
                            Value::Array(vec![enc("ByteArray", vec![("type", Value::from(3))])]),
                        ),
                        (
                            "dataEncoding",
                            Value::Array(vec![enc("ByteArray", vec![("type", Value::from(3))])]),
                        ),
                    ],
                )]),
            ),
        ])
    }

    pub fn encode(text: &str, broken: Option<Break>) -> Vec<u8> {
        let mut cats = Vec::new();
        for (name, items, rows) in categories(text) {
            let mut columns = Vec::new();
            for (c, item) in items.iter().enumerate() {
                let raw: Vec<&str> = rows.iter().map(|r| r[c].as_str()).collect();
                let values: Vec<Option<&str>> = raw
                    .iter()
                    .map(|&v| (v != "." && v != "?").then_some(v))
                    .collect();
                let mut data = column(&values);
                if name == "_atom_site" {
                    match (&broken, item.as_str()) {
                        (Some(Break::UnknownEncoding), "Cartn_x") => {
                            data = map(vec![
                                ("data", Value::Binary(vec![0; 4])),
                                ("encoding", Value::Array(vec![enc("Zigzag", vec![])])),
                            ]);
                        }
                        (Some(Break::ShortColumn), "Cartn_y") => {
                            let short: Vec<Option<&str>> = values[..values.len() - 1].to_vec();
                            data = column(&short);
                        }
                        _ => {}
                    }
                }
                let mask = values.iter().any(Option::is_none).then(|| {
                    let m: Vec<u8> = raw
                        .iter()
                        .map(|&v| {
                            if v == "." {
                                1
                            } else if v == "?" {
                                2
                            } else {
                                0
                            }
                        })
                        .collect();
                    map(vec![
                        ("data", Value::Binary(m)),
                        (
                            "encoding",
                            Value::Array(vec![enc("ByteArray", vec![("type", Value::from(4))])]),
                        ),
                    ])
                });
                columns.push(map(vec![
                    ("name", Value::from(item.as_str())),
                    ("data", data),
                    ("mask", mask.unwrap_or(Value::Nil)),
                ]));
            }
            cats.push(map(vec![
                ("name", Value::from(name.as_str())),
                ("rowCount", Value::from(rows.len())),
                ("columns", Value::Array(columns)),
            ]));
        }
        let root = map(vec![
            ("version", Value::from("0.3.0")),
            ("encoder", Value::from("sphereshade tests")),
            (
                "dataBlocks",
                Value::Array(vec![map(vec![
                    ("header", Value::from("TEST")),
                    ("categories", Value::Array(cats)),
                ])]),
            ),
        ]);
        let mut out = Vec::new();
        rmpv::encode::write_value(&mut out, &root).unwrap();
        out
    }
}

/// A glob matching a label by its leading word characters (labels hold
/// spaces and punctuation the selection lexer splits on).
fn label_glob(label: &str) -> String {
    let head: String = label
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
        .collect();
    format!("{head}*")
}

/// Rules on an instanced model (`molecule`, `node`) act per molecule type
/// or per instance without expanding (copies told apart become variants),
/// and render as the expanded model with the same rules: colour words and
/// ids (mapped to input order) identical, with see-through spheres and
/// deep shadows, under validation.
#[test]
fn rules_on_an_instanced_model_render_as_the_expanded_model() {
    let file = data_file("meso/flagellarmotor_2-no_bonds.bcif");
    let load = |rules: &[(&str, String)], expand: bool| {
        let r: Vec<(&str, &str)> = rules.iter().map(|(k, t)| (*k, t.as_str())).collect();
        load_with_rules(&file, &r, expand)
    };
    let plain = load(&[], false);
    let inst = plain.instancing.as_ref().expect("instanced");
    let (m0, m1) = (&inst.molecules[0], &inst.molecules[1]);
    let node = &inst.nodes[inst.molecules[2].node as usize];
    let rules = vec![
        ("hide", format!("molecule {}", label_glob(&m0.label))),
        (
            "paint",
            format!("molecule {}=orange", label_glob(&m1.label)),
        ),
        ("alpha", format!("node {}=0.4", label_glob(&node.label))),
    ];
    let ruled = load(&rules, false);
    let expanded = load(&rules, true);
    let ri = ruled
        .instancing
        .as_ref()
        .expect("rules keep the model instanced");
    assert!(expanded.instancing.is_none());
    assert_eq!(ri.represented(), expanded.spheres.len() as u64);
    assert!(ri.represented() < inst.represented(), "nothing hidden");
    assert!(ruled.has_translucent() && expanded.has_translucent());
    eprintln!(
        "rules {rules:?}: {} of {} represented spheres kept, {} molecule variants, {} stored atoms",
        ri.represented(),
        inst.represented(),
        ri.molecules.len(),
        ruled.spheres.len()
    );
    let ctx = validated_context();
    let cam = camera(&plain, 128, 96, None);
    let mut s = settings(cam, ShadowMode::Deep);
    s.ssdo = SsdoMode::Semantic;
    let frame = |scene: &Scene| {
        let mut r = Renderer::new(&ctx, scene, s.clone()).expect("renderer");
        r.render_frame().expect("frame");
        let map = r.inspect().id_map();
        let ids: Vec<Option<u64>> = ids_from_vis(&r.inspect().read_vis().unwrap())
            .into_iter()
            .map(|id| id.map(|i| map.as_ref().map_or(i as u64, |m| m.input(i as u64))))
            .collect();
        (r.inspect().read_color().unwrap(), ids)
    };
    let (ci, ii) = frame(&ruled);
    let (ce, ie) = frame(&expanded);
    assert!(ii == ie, "ids differ");
    let n = ci.iter().zip(&ce).filter(|(a, b)| a != b).count();
    assert_eq!(n, 0, "{n} colour words differ");
    assert_no_validation_messages(&ctx);
}
