//! The repository stands alone: the data the tests and the default bench
//! use is in tests/data, byte for byte the shared files (sha256 from its
//! README), and docs/DESIGN.md is the shared contract (checked when
//! ../shared is beside the checkout).

use sha2::{Digest, Sha256};
use std::path::Path;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Checks every `| file | bytes | sha256 |` row of DIR/README.md; returns
/// how many rows there were.
fn check_table(dir: &Path) -> usize {
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    let mut n = 0;
    for line in readme.lines() {
        // | file | bytes | sha256 |
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() != 5
            || cells[3].len() != 64
            || !cells[3].chars().all(|c| c.is_ascii_hexdigit())
        {
            continue;
        }
        let (file, bytes, sha) = (cells[1], cells[2].replace(',', ""), cells[3]);
        let data = std::fs::read(dir.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(data.len().to_string(), bytes, "{file}: size");
        assert_eq!(
            format!("{:x}", Sha256::digest(&data)),
            sha,
            "{file}: sha256"
        );
        n += 1;
    }
    n
}

#[test]
fn test_data_matches_its_provenance_table() {
    let dir = Path::new(ROOT).join("tests/data");
    assert_eq!(
        check_table(&dir),
        11,
        "expected the 11 structure files in the table"
    );
    assert_eq!(
        check_table(&dir.join("meso")),
        4,
        "expected the 4 mesoscale models in tests/data/meso/README.md"
    );
    assert_eq!(
        check_table(&dir.join("traj")),
        6,
        "expected the 6 trajectory files in tests/data/traj/README.md"
    );
}

#[test]
fn design_copy_is_in_sync_with_the_shared_contract() {
    let shared = Path::new(ROOT).join("../shared/DESIGN.md");
    let Ok(contract) = std::fs::read_to_string(&shared) else {
        eprintln!("skipped: {} not beside the checkout", shared.display());
        return;
    };
    let copy = std::fs::read_to_string(Path::new(ROOT).join("docs/DESIGN.md")).unwrap();
    assert!(
        copy == contract,
        "docs/DESIGN.md differs from ../shared/DESIGN.md: copy it again"
    );
}

/// Module paths named in `text` by `crate::` or `super::` paths, absolute
/// (from the crate root), with `{a, b::c}` groups expanded one level.
fn named_paths(text: &str, here: &[String]) -> Vec<Vec<String>> {
    let ident = |s: &str| -> usize {
        s.find(|c: char| !(c.is_alphanumeric() || c == '_'))
            .unwrap_or(s.len())
    };
    let mut out = Vec::new();
    for (key, base) in [
        ("crate::", Vec::new()),
        ("super::", here[..here.len().saturating_sub(1)].to_vec()),
    ] {
        let mut rest = text;
        while let Some(i) = rest.find(key) {
            let before = rest[..i].chars().last();
            rest = &rest[i + key.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let mut path = base.clone();
            let mut s = rest;
            loop {
                if let Some(g) = s.strip_prefix('{') {
                    let end = g.find('}').unwrap_or(g.len());
                    for item in g[..end].split(',') {
                        let item = item.trim();
                        let n = ident(item);
                        if n > 0 {
                            let mut p = path.clone();
                            p.push(item[..n].to_string());
                            out.push(p);
                        }
                    }
                    break;
                }
                let n = ident(s);
                if n == 0 {
                    break;
                }
                path.push(s[..n].to_string());
                s = &s[n..];
                match s.strip_prefix("::") {
                    Some(t) => s = t,
                    None => break,
                }
            }
            if path.len() > base.len() {
                out.push(path);
            }
        }
    }
    out
}

/// No two modules of one folder import each other, directly or around a
/// loop, at any level of src/ (names re-exported by a `mod.rs` count as
/// their defining module's). Unit-test modules may reach anywhere.
#[test]
fn no_import_cycles_inside_any_folder() {
    use std::collections::{BTreeMap, BTreeSet};
    // Module path of every file: src/a/b.rs -> [a, b], src/a/mod.rs -> [a].
    let mut files: Vec<(Vec<String>, String)> = Vec::new();
    let mut stack = vec![Path::new(ROOT).join("src")];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
                continue;
            }
            if p.extension().is_none_or(|x| x != "rs") {
                continue;
            }
            let rel = p.strip_prefix(Path::new(ROOT).join("src")).unwrap();
            let mut m: Vec<String> = rel
                .with_extension("")
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            if matches!(m.last().map(String::as_str), Some("mod" | "lib" | "main")) {
                m.pop();
            }
            let text = std::fs::read_to_string(&p).unwrap();
            let text = match text.find("#[cfg(test)]\nmod tests") {
                Some(i) => text[..i].to_string(),
                None => text,
            };
            // Code only: a doc link is not an import.
            let text: String = text
                .lines()
                .map(|l| l.split("//").next().unwrap_or(""))
                .collect::<Vec<_>>()
                .join("\n");
            files.push((m, text));
        }
    }
    let modules: BTreeSet<Vec<String>> = files.iter().map(|(m, _)| m.clone()).collect();
    // `pub use child::{A, B}` in a folder's root: A and B live in child.
    let mut reexport: BTreeMap<(Vec<String>, String), String> = BTreeMap::new();
    for (m, text) in &files {
        for line in text.lines() {
            let Some(rest) = line.trim().strip_prefix("pub use ") else {
                continue;
            };
            let child: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            let mut cm = m.clone();
            cm.push(child.clone());
            if !modules.contains(&cm) {
                continue;
            }
            let names = rest[child.len()..].trim_start_matches("::");
            for n in names
                .trim_matches(|c| c == '{' || c == '}' || c == ';')
                .split(',')
            {
                let n = n
                    .trim()
                    .rsplit("::")
                    .next()
                    .unwrap_or("")
                    .trim_end_matches(['}', ';']);
                reexport.insert((m.clone(), n.trim().to_string()), child.clone());
            }
        }
    }
    // Edges between siblings: folder -> (a -> {b}).
    let mut edges: BTreeMap<Vec<String>, BTreeMap<String, BTreeSet<String>>> = BTreeMap::new();
    for (m, text) in &files {
        for mut target in named_paths(text, m) {
            // The longest prefix that is a module, then one re-export step.
            while target.len() > 1 && !modules.contains(&target) {
                let name = target.pop().unwrap();
                if let Some(child) = reexport.get(&(target.clone(), name)) {
                    target.push(child.clone());
                    break;
                }
            }
            let common = m.iter().zip(&target).take_while(|(a, b)| a == b).count();
            if common < m.len() && common < target.len() {
                edges
                    .entry(m[..common].to_vec())
                    .or_default()
                    .entry(m[common].clone())
                    .or_default()
                    .insert(target[common].clone());
            }
        }
    }
    let mut cycles = Vec::new();
    for (folder, g) in &edges {
        // A cycle exists iff some node reaches itself.
        for start in g.keys() {
            let mut seen = BTreeSet::new();
            let mut todo: Vec<&String> = g[start].iter().collect();
            while let Some(n) = todo.pop() {
                if n == start {
                    cycles.push(format!("src/{}: {start} is on a cycle", folder.join("/")));
                    break;
                }
                if seen.insert(n.clone()) {
                    todo.extend(g.get(n).into_iter().flatten());
                }
            }
        }
    }
    assert!(cycles.is_empty(), "import cycles:\n{}", cycles.join("\n"));
}
