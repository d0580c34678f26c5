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
        7,
        "expected the 7 structure files in the table"
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
