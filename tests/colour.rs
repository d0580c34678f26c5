//! Colour schemes and selection rules on 1tii.pdb, against the PDB file's
//! own columns read here (chain 22, residue name 18-20, B-factor 61-66) and
//! the colour maps' published tables (colorous); the rules' CLI errors.

mod common;

use common::*;
use sphereshade::scene::paint::{Colormap, Scheme, color_scheme};
use std::collections::{BTreeMap, HashSet};

/// (chain, residue name, B-factor, element) per ATOM/HETATM record, as the
/// PDB format's fixed columns give them (first model only).
fn pdb_columns() -> Vec<(String, String, f64, String)> {
    let text = std::fs::read_to_string(data_file("1tii.pdb")).unwrap();
    let mut out = Vec::new();
    for l in text.lines() {
        if l.starts_with("ENDMDL") {
            break;
        }
        if !(l.starts_with("ATOM  ") || l.starts_with("HETATM")) {
            continue;
        }
        let col = |a: usize, b: usize| l.get(a..b.min(l.len())).unwrap_or("").trim().to_string();
        out.push((
            col(21, 22),
            col(17, 20),
            col(60, 66).parse().unwrap(),
            col(76, 78),
        ));
    }
    out
}

fn colors(scheme: Scheme, map: Colormap) -> Vec<[u8; 3]> {
    let mut s = load_data("1tii.pdb");
    color_scheme(&mut s, scheme, map).unwrap();
    s.spheres
        .iter()
        .map(|s| [s.color[0], s.color[1], s.color[2]])
        .collect()
}

/// The map's parameter nearest to an RGB colour (1/2000 steps).
fn nearest_t(g: colorous::Gradient, c: [u8; 3]) -> f64 {
    (0..=2000)
        .map(|k| k as f64 / 2000.0)
        .min_by_key(|&t| {
            let m = g.eval_continuous(t);
            let d = |a: u8, b: u8| (a as i32 - b as i32).pow(2);
            d(m.r, c[0]) + d(m.g, c[1]) + d(m.b, c[2])
        })
        .unwrap()
}

#[test]
fn every_scheme_on_1tii() {
    let cols = pdb_columns();
    let n = cols.len();
    assert_eq!(
        load_data("1tii.pdb").spheres.len(),
        n,
        "one sphere per record"
    );

    // chain: one colour per chain, every chain its own
    let c = colors(Scheme::Chain, Colormap::Viridis);
    let mut per_chain: BTreeMap<&str, HashSet<[u8; 3]>> = BTreeMap::new();
    for (i, (ch, ..)) in cols.iter().enumerate() {
        per_chain.entry(ch).or_default().insert(c[i]);
    }
    assert!(per_chain.len() >= 2, "1tii has several chains");
    for (ch, set) in &per_chain {
        assert_eq!(set.len(), 1, "chain {ch} has {} colours", set.len());
    }
    let distinct: HashSet<_> = per_chain.values().flatten().collect();
    assert_eq!(distinct.len(), per_chain.len(), "chain colours repeat");
    // hierarchy on a protein: the chains again
    assert_eq!(colors(Scheme::Hierarchy, Colormap::Viridis), c);

    // bfactor: each atom the map's colour at its normalised B-factor
    // (so colours run monotone through the map with B), ends at 0 and 1
    let lo = cols.iter().map(|c| c.2).fold(f64::INFINITY, f64::min);
    let hi = cols.iter().map(|c| c.2).fold(f64::NEG_INFINITY, f64::max);
    assert!(hi > lo);
    let near = |a: [u8; 3], m: colorous::Color| {
        (a[0] as i32 - m.r as i32).abs() <= 1
            && (a[1] as i32 - m.g as i32).abs() <= 1
            && (a[2] as i32 - m.b as i32).abs() <= 1
    };
    for (map, g) in [
        (Colormap::Viridis, colorous::VIRIDIS),
        (Colormap::Magma, colorous::MAGMA),
        (Colormap::Turbo, colorous::TURBO),
    ] {
        let c = colors(Scheme::Bfactor, map);
        for (i, col) in cols.iter().enumerate() {
            let want = g.eval_continuous((col.2 - lo) / (hi - lo));
            assert!(
                near(c[i], want),
                "{map:?} atom {i} (B {}): {:?} vs {want:?}",
                col.2,
                c[i]
            );
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| cols[a].2.total_cmp(&cols[b].2));
        assert!(near(c[order[0]], g.eval_continuous(0.0)));
        assert!(near(c[order[n - 1]], g.eval_continuous(1.0)));
        // and monotone: the map's parameter of each colour, in B order
        let ts: Vec<f64> = order.iter().map(|&i| nearest_t(g, c[i])).collect();
        let back = ts.windows(2).filter(|w| w[1] < w[0] - 0.02).count();
        assert_eq!(back, 0, "{map:?}: colours step back through the map");
    }

    // index: the map along the file order
    let c = colors(Scheme::Index, Colormap::Turbo);
    for (i, &c) in c.iter().enumerate() {
        let want = colorous::TURBO.eval_continuous(i as f64 / (n - 1) as f64);
        assert!(near(c, want), "index {i}");
    }

    // residue: one colour per residue name; RasMol's ASP red, LYS blue
    let c = colors(Scheme::Residue, Colormap::Viridis);
    let mut per_res: BTreeMap<&str, HashSet<[u8; 3]>> = BTreeMap::new();
    for (i, (_, res, ..)) in cols.iter().enumerate() {
        per_res.entry(res).or_default().insert(c[i]);
    }
    for (res, set) in &per_res {
        assert_eq!(set.len(), 1, "residue {res}");
    }
    let of = |r: &str| *per_res[r].iter().next().unwrap();
    assert!(
        of("ASP")[0] > 200 && of("ASP")[2] < 50,
        "ASP {:?}",
        of("ASP")
    );
    assert!(
        of("LYS")[2] > 200 && of("LYS")[0] < 50,
        "LYS {:?}",
        of("LYS")
    );
    assert_ne!(of("GLY"), of("TRP"));

    // element: one colour per element, carbon differs from oxygen
    let c = colors(Scheme::Element, Colormap::Viridis);
    let mut per_el: BTreeMap<&str, HashSet<[u8; 3]>> = BTreeMap::new();
    for (i, (.., el)) in cols.iter().enumerate() {
        per_el.entry(el).or_default().insert(c[i]);
    }
    assert!(per_el.values().all(|s| s.len() == 1));
    assert_ne!(per_el["C"], per_el["O"]);

    // a uniform colour
    let c = colors(Scheme::Uniform([10, 200, 30]), Colormap::Viridis);
    assert!(c.iter().all(|&c| c == [10, 200, 30]));
}

/// Each scheme through the CLI: renders, and an unknown one is a one-line
/// error naming the choices.
#[test]
fn schemes_and_rules_on_the_command_line() {
    let exe = env!("CARGO_BIN_EXE_sphereshade");
    let data = data_file("1tii.pdb");
    let out = out_dir().join("colour-cli.png");
    let run = |extra: &[&str]| {
        let mut a = vec![
            "render",
            data.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--out",
            out.to_str().unwrap(),
        ];
        a.extend(extra);
        std::process::Command::new(exe)
            .args(&a)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap()
    };
    for scheme in [
        "element",
        "chain",
        "residue",
        "bfactor",
        "index",
        "hierarchy",
        "200,10,10",
    ] {
        let o = run(&["--color", scheme]);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{scheme}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let o = run(&["--color", "bfactor", "--colormap", "magma"]);
    assert_eq!(o.status.code(), Some(0));
    // every failure: exit 2 (usage) or 1, one line, naming what is wrong
    for (args, needle) in [
        (&["--color", "rainbow"][..], "rainbow"),
        (&["--color", "300,0,0"], "300"),
        (&["--colormap", "jet"], "jet"),
        (&["--hide", "chain"], "column"),
        (&["--hide", "resid 5-"], "column"),
        (&["--hide", "chain A and (name CA"], "column"),
        (&["--hide", "bogus X"], "bogus"),
        (&["--paint", "chain A"], "="),
        (&["--paint", "chain A=notacolour"], "notacolour"),
        (&["--alpha", "chain A=1.5"], "1.5"),
        (&["--alpha", "chain A=x"], "x"),
    ] {
        let o = run(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_ne!(o.status.code(), Some(0), "{args:?} accepted");
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        assert!(lines.iter().any(|l| l.contains(needle)), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // a rule that selects nothing says so and renders
    let o = run(&["--hide", "chain Q"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(String::from_utf8_lossy(&o.stderr).contains("selects no sphere"));
}
