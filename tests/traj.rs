//! Trajectory readers against the ground truth of tests/data/traj/README.md
//! (read with MDAnalysis 2.11.0): atom 1, the last atom, the centroid, the
//! box and the time at the first and last frames; XTC against TRR of the
//! same run; DCD layouts written and read back; text trajectories; cut
//! files keep their earlier frames and name the frame and byte offset.

use sphereshade::traj::{self, Frame, Reader};
use std::path::{Path, PathBuf};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/traj")
        .join(name)
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sphereshade-traj-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join(name)
}

fn frame(r: &mut dyn Reader, k: usize) -> Frame {
    let mut f = Frame::default();
    r.read(k, &mut f)
        .unwrap_or_else(|e| panic!("frame {k}: {e}"));
    f
}

fn centroid(f: &Frame) -> [f64; 3] {
    let mut c = [0.0f64; 3];
    for p in &f.positions {
        for k in 0..3 {
            c[k] += p[k] as f64;
        }
    }
    c.map(|v| v / f.positions.len() as f64)
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64, what: &str) {
    for k in 0..3 {
        assert!(
            (a[k] - b[k]).abs() <= tol,
            "{what}: {a:?} vs {b:?} (tolerance {tol})"
        );
    }
}

fn p64(p: [f32; 3]) -> [f64; 3] {
    p.map(|v| v as f64)
}

/// Cell lengths and angles (degrees) from its vectors.
fn lengths_angles(c: &[[f64; 3]; 3]) -> ([f64; 3], [f64; 3]) {
    let len = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let ang = |u: &[f64; 3], v: &[f64; 3]| {
        ((u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (len(u) * len(v)))
            .acos()
            .to_degrees()
    };
    (
        [len(&c[0]), len(&c[1]), len(&c[2])],
        [ang(&c[1], &c[2]), ang(&c[0], &c[2]), ang(&c[0], &c[1])],
    )
}

struct Truth {
    frame: usize,
    time: f64,
    first: [f64; 3],
    last: [f64; 3],
    centroid: [f64; 3],
}

fn check(r: &mut dyn Reader, atoms: usize, frames: usize, truth: &[Truth], tol: f64) {
    assert_eq!(r.atoms(), atoms);
    assert_eq!(r.frames(), frames);
    assert!(
        r.damage().is_none(),
        "{:?}",
        r.damage().map(|d| d.to_string())
    );
    for t in truth {
        let f = frame(r, t.frame);
        assert_eq!(f.positions.len(), atoms);
        let time = f.time_ps.expect("time");
        assert!(
            (time - t.time).abs() < 5e-4,
            "frame {}: time {time} vs {}",
            t.frame,
            t.time
        );
        close(p64(f.positions[0]), t.first, tol, "atom 1");
        close(p64(f.positions[atoms - 1]), t.last, tol, "last atom");
        close(centroid(&f), t.centroid, 1e-3 + tol / 10.0, "centroid");
    }
}

#[test]
fn xtc_and_trr_match_mdanalysis_and_each_other() {
    let truth = |xtc: bool| {
        vec![
            Truth {
                frame: 0,
                time: 0.0,
                first: if xtc {
                    [52.020, 43.560, 31.550]
                } else {
                    [52.017, 43.560, 31.555]
                },
                last: if xtc {
                    [62.960, 47.240, 3.750]
                } else {
                    [62.961, 47.239, 3.753]
                },
                centroid: [59.950, 39.883, 28.293],
            },
            Truth {
                frame: 9,
                time: 900.0,
                first: if xtc {
                    [52.760, 36.810, 30.420]
                } else {
                    [52.756, 36.813, 30.420]
                },
                last: if xtc {
                    [72.250, 34.570, 51.080]
                } else {
                    [72.252, 34.569, 51.082]
                },
                centroid: [60.101, 39.815, 28.349],
            },
        ]
    };
    let mut xtc = traj::open(&data("adk_oplsaa.xtc")).unwrap();
    check(xtc.as_mut(), 47681, 10, &truth(true), 6e-4);
    let mut trr = traj::open(&data("adk_oplsaa.trr")).unwrap();
    check(trr.as_mut(), 47681, 10, &truth(false), 6e-4);
    // the boxes: 80.017 (frame 0), 80.085 (frame 9); angles 60 60 90
    for (k, edge) in [(0, 80.017), (9, 80.085)] {
        for r in [&mut xtc, &mut trr] {
            let f = frame(r.as_mut(), k);
            let (l, a) = lengths_angles(&f.cell.expect("cell"));
            close(l, [edge; 3], 1e-3, "box lengths");
            close(a, [60.0, 60.0, 90.0], 1e-3, "box angles");
        }
    }
    // The same frames: XTC is TRR rounded to its precision (1000/nm).
    let mut worst = 0.0f64;
    for k in 0..10 {
        let (a, b) = (frame(xtc.as_mut(), k), frame(trr.as_mut(), k));
        for (p, q) in a.positions.iter().zip(&b.positions) {
            for i in 0..3 {
                worst = worst.max((p[i] - q[i]).abs() as f64);
            }
        }
    }
    eprintln!("XTC vs TRR: largest difference {worst:.5} Å over 10 frames");
    assert!(
        worst <= 0.0051,
        "XTC and TRR differ by {worst} Å (precision 0.005)"
    );
}

#[test]
fn dcd_matches_mdanalysis() {
    let mut r = traj::open(&data("adk_dims.dcd")).unwrap();
    check(
        r.as_mut(),
        3341,
        98,
        &[
            Truth {
                frame: 0,
                time: 1.0,
                first: [11.736, 8.501, -10.445],
                last: [5.585, 17.590, -6.966],
                centroid: [-0.042, 0.014, -0.035],
            },
            Truth {
                frame: 97,
                time: 98.0,
                first: [15.877, 6.849, -8.291],
                last: [12.377, 14.945, -6.561],
                centroid: [0.127, -0.247, -0.017],
            },
        ],
        6e-4,
    );
    assert!(frame(r.as_mut(), 0).cell.is_none());
}

#[test]
fn dcd_layouts_round_trip() {
    let frames: Vec<Vec<[f32; 3]>> = (0..3)
        .map(|k| {
            (0..5)
                .map(|i| [i as f32, k as f32 * 0.5, -(i as f32) * 1.25])
                .collect()
        })
        .collect();
    for big in [false, true] {
        for marker in [4, 8] {
            for cell in [None, Some([30.0, 40.0, 50.0, 90.0, 90.0, 120.0])] {
                let p = tmp(&format!("l-{big}-{marker}-{}.dcd", cell.is_some()));
                let mut f = std::fs::File::create(&p).unwrap();
                traj::write_dcd(&mut f, &frames, cell, big, marker).unwrap();
                drop(f);
                let mut r = traj::open(&p).unwrap_or_else(|e| panic!("{big} {marker}: {e}"));
                assert_eq!((r.atoms(), r.frames()), (5, 3));
                for (k, want) in frames.iter().enumerate() {
                    let got = frame(r.as_mut(), k);
                    assert_eq!(&got.positions, want, "big {big} marker {marker}");
                    assert!(
                        (got.time_ps.unwrap() - (10 + 10 * k) as f64 * 0.1 * 0.04888821).abs()
                            < 1e-6
                    );
                    if cell.is_some() {
                        let (l, a) = lengths_angles(&got.cell.unwrap());
                        close(l, [30.0, 40.0, 50.0], 1e-9, "cell");
                        close(a, [90.0, 90.0, 120.0], 1e-9, "angles");
                    }
                }
            }
        }
    }
}

#[test]
fn lammps_dump_rows_in_id_order() {
    let mut r = traj::open(&data("image_vf.lammpstrj")).unwrap();
    assert_eq!((r.atoms(), r.frames()), (7, 3));
    let f = frame(r.as_mut(), 0);
    // id 1 is the second row of frame 0, id 4 the first
    assert_eq!(f.positions[0], [4.99944, 5.00015, 5.50088]);
    assert_eq!(f.positions[3], [5.89113, 3.39852, 0.236896]);
    let (l, _) = lengths_angles(&f.cell.unwrap());
    close(l, [10.0; 3], 1e-9, "box");
    let f1 = frame(r.as_mut(), 1);
    assert_eq!(f1.positions[0], [8.86026, 1.45707, 6.49955]);
    // as a structure: the first frame, 7 spheres, types as level 0
    let s = sphereshade::scene::load(
        &data("image_vf.lammpstrj"),
        &Default::default(),
        &mut |_, _| {},
    )
    .unwrap();
    assert_eq!(s.spheres.len(), 7);
    assert_eq!(s.spheres[0].center, [4.99944, 5.00015, 5.50088]);
    assert_eq!(s.spheres[0].region[0], 1);
    assert_eq!(s.spheres[3].region[0], 2);
    // scaled and unwrapped columns, a triclinic box
    let dump = "ITEM: TIMESTEP\n5\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS xy xz yz pp pp pp\n0 12 2\n0 10 0\n0 10 0\n\
                ITEM: ATOMS id type xs ys zs\n2 1 0.5 0.5 0.5\n1 1 0 0 0\n";
    let p = tmp("scaled.lammpstrj");
    std::fs::write(&p, dump).unwrap();
    let mut r = traj::open(&p).unwrap();
    let f = frame(r.as_mut(), 0);
    assert_eq!(f.positions[0], [0.0, 0.0, 0.0]);
    // x = xlo + 0.5 * 10 + 0.5 * xy(2) = 6 (xlo_bound 0 - min(0, xy) = 0)
    assert_eq!(f.positions[1], [6.0, 5.0, 5.0]);
}

#[test]
fn text_trajectories_from_the_dcd() {
    // Three DCD frames written as a multi-model PDB, multi-frame GRO and XYZ.
    let topo = sphereshade::scene::load(&data("adk_open.pdb"), &Default::default(), &mut |_, _| {})
        .unwrap();
    let mut dcd = traj::open(&data("adk_dims.dcd")).unwrap();
    let frames: Vec<Frame> = [0, 40, 97]
        .iter()
        .map(|&k| frame(dcd.as_mut(), k))
        .collect();
    let n = topo.spheres.len();
    assert_eq!(n, dcd.atoms());
    let (mut pdb, mut gro, mut xyz) = (String::new(), String::new(), String::new());
    for (m, f) in frames.iter().enumerate() {
        pdb += &format!("MODEL     {:4}\n", m + 1);
        gro += &format!("frame t= {}\n{n}\n", m as f64 * 2.5);
        xyz += &format!("{n}\nframe {m}\n");
        for (i, p) in f.positions.iter().enumerate() {
            pdb += &format!(
                "ATOM  {:5} CA   GLY A{:4}    {:8.3}{:8.3}{:8.3}  1.00  0.00           C\n",
                (i + 1) % 100000,
                i / 10 % 10000,
                p[0],
                p[1],
                p[2]
            );
            gro += &format!(
                "{:5}GLY     CA{:5}{:8.3}{:8.3}{:8.3}\n",
                i / 10 % 100000,
                (i + 1) % 100000,
                p[0] / 10.0,
                p[1] / 10.0,
                p[2] / 10.0
            );
            xyz += &format!("C {} {} {}\n", p[0], p[1], p[2]);
        }
        pdb += "ENDMDL\n";
        gro += "   8.00000   8.00000   8.00000\n";
    }
    pdb += "END\n";
    for (name, text, tol) in [
        ("m.pdb", &pdb, 6e-4),
        ("m.gro", &gro, 6e-3),
        ("m.xyz", &xyz, 1e-6),
    ] {
        let p = tmp(name);
        std::fs::write(&p, text).unwrap();
        let mut r = traj::open(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!((r.atoms(), r.frames()), (n, 3), "{name}");
        for (k, want) in frames.iter().enumerate() {
            let got = frame(r.as_mut(), k);
            for (a, b) in got.positions.iter().zip(&want.positions) {
                close(p64(*a), p64(*b), tol, name);
            }
            if name == "m.gro" {
                assert_eq!(got.time_ps, Some(k as f64 * 2.5));
                close(
                    lengths_angles(&got.cell.unwrap()).0,
                    [80.0; 3],
                    1e-9,
                    "gro box",
                );
            }
        }
    }
}

#[test]
fn cut_files_keep_their_earlier_frames_and_say_where() {
    for (name, frames) in [
        ("adk_oplsaa.xtc", 10),
        ("adk_oplsaa.trr", 10),
        ("adk_dims.dcd", 98),
        ("image_vf.lammpstrj", 3),
    ] {
        let bytes = std::fs::read(data(name)).unwrap();
        let mut full = traj::open(&data(name)).unwrap();
        let reference: Vec<Frame> = (0..frames).map(|k| frame(full.as_mut(), k)).collect();
        let mut seed = 0x9E37_79B9u64 ^ bytes.len() as u64;
        for _ in 0..6 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let cut = (seed >> 11) as usize % bytes.len();
            let p = tmp(&format!("cut-{cut}-{name}"));
            std::fs::write(&p, &bytes[..cut]).unwrap();
            match traj::open(&p) {
                Err(e) => {
                    // nothing readable: a clean error naming the file
                    let msg = e.to_string();
                    assert!(msg.contains(&p.display().to_string()), "{msg}");
                    assert_eq!(msg.lines().count(), 1);
                }
                Ok(mut r) => {
                    let k = r.frames();
                    assert!(k < frames, "{name} cut at {cut}: {k} frames");
                    if name != "image_vf.lammpstrj" {
                        let d = r
                            .damage()
                            .unwrap_or_else(|| panic!("{name} cut at {cut}: no damage"));
                        let msg = d.to_string();
                        assert!(msg.contains(&format!("frame {k} at byte")), "{msg}");
                    }
                    for (j, want) in reference.iter().enumerate().take(k) {
                        let got = frame(r.as_mut(), j);
                        assert_eq!(
                            &got.positions, &want.positions,
                            "{name} cut at {cut}, frame {j}"
                        );
                    }
                }
            }
            let _ = std::fs::remove_file(&p);
        }
    }
}

/// adk_oplsaa is a rhombic dodecahedron whose raw XTC coordinates split
/// molecules across the boundary: `whole` joins every residue, `wrap`
/// puts every atom inside the cell.
#[test]
fn pbc_whole_joins_the_split_residues_of_adk() {
    let topo =
        sphereshade::scene::load(&data("adk_oplsaa.gro"), &Default::default(), &mut |_, _| {})
            .unwrap();
    let residues: Vec<u32> = topo.spheres.iter().map(|s| s.region[2]).collect();
    let mut r = traj::open(&data("adk_oplsaa.xtc")).unwrap();
    let f = frame(r.as_mut(), 9);
    let cell = f.cell.unwrap();
    // largest extent of any residue (Å)
    let extent = |p: &[[f32; 3]]| -> (f32, usize) {
        let mut by: std::collections::HashMap<u32, ([f32; 3], [f32; 3])> = Default::default();
        for (q, &res) in p.iter().zip(&residues) {
            let e = by.entry(res).or_insert((*q, *q));
            for (k, &v) in q.iter().enumerate() {
                e.0[k] = e.0[k].min(v);
                e.1[k] = e.1[k].max(v);
            }
        }
        let big = by
            .values()
            .filter(|(lo, hi)| (0..3).any(|k| hi[k] - lo[k] > 20.0))
            .count();
        let worst = by
            .values()
            .map(|(lo, hi)| (0..3).map(|k| hi[k] - lo[k]).fold(0.0f32, f32::max))
            .fold(0.0f32, f32::max);
        (worst, big)
    };
    let (raw_worst, raw_split) = extent(&f.positions);
    let mut whole = f.positions.clone();
    traj::apply_pbc(traj::Pbc::Whole, &mut whole, Some(&cell), &residues);
    let (w_worst, w_split) = extent(&whole);
    // the protein is one residue per amino acid: the biggest residue
    // (a water, an ion or an amino acid) spans a few Å
    eprintln!(
        "residues over 20 Å: raw {raw_split} (widest {raw_worst:.1} Å), whole {w_split} (widest {w_worst:.1} Å)"
    );
    assert!(
        raw_split >= 3 && raw_worst > 60.0,
        "the raw frame should have split molecules ({raw_split})"
    );
    assert_eq!(w_split, 0, "whole left {w_split} residues split");
    let mut wrapped = f.positions.clone();
    traj::apply_pbc(traj::Pbc::Wrap, &mut wrapped, Some(&cell), &residues);
    // inside: fractional coordinates in [0, 1) (the cell is lower triangular)
    let (a, b, c) = (cell[0], cell[1], cell[2]);
    for p in &wrapped {
        let fz = p[2] as f64 / c[2];
        let fy = (p[1] as f64 - fz * c[1]) / b[1];
        let fx = (p[0] as f64 - fz * c[0] - fy * b[0]) / a[0];
        for v in [fx, fy, fz] {
            assert!((-1e-4..1.0 + 1e-4).contains(&v), "{p:?} -> {fx} {fy} {fz}");
        }
    }
}
