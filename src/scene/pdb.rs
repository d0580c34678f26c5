//! PDB reader: fixed columns, byte-level, no per-atom allocation.
//!
//! Handles the quirks of real files (see shared/data/README.md): touching
//! fields (`HETATM31151`, `PHEAA`, `1.00180.86`), two-letter chains in
//! columns 21-22, four-letter residue names (`TIP3`), hybrid-36 serials and
//! residue numbers, blank chains with segment ids, missing element columns,
//! residue numbers that wrap, MODEL/ENDMDL and REMARK 350 assemblies.

use super::atoms::AtomInfo;
use super::elements::{self, Element, trim};
use super::hybrid36;
use super::molecule::{AsmGroup, Assembly, AtomKeys, MolBuilder, find_assembly};
use super::text::{LineSource, parse_f32, show};
use super::{
    LoadOptions, MAX_SPHERES, ModelSelect, Scene, SceneError, check_coordinate, parse_error,
    too_many, truncated,
};

/// Four-letter residue names common in CHARMM/NAMD output whose fourth
/// letter sits in column 21 (where wide files put a two-letter chain).
const FOUR_LETTER_RESIDUES: [&[u8; 4]; 16] = [
    b"TIP3", b"TIP4", b"TIP5", b"SPCE", b"POPC", b"POPE", b"POPG", b"POPS", b"DPPC", b"DMPC",
    b"DOPC", b"DOPE", b"DLPC", b"DSPC", b"CHL1", b"CHOL",
];

/// The same names as integers: this test runs for every atom of a
/// two-letter-chain file, so it avoids slice comparisons.
const FOUR_LETTER_KEYS: [u32; 16] = {
    let mut keys = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        keys[i] = u32::from_le_bytes(*FOUR_LETTER_RESIDUES[i]);
        i += 1;
    }
    keys
};

pub(crate) fn parse(
    src: &mut LineSource,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let mut builder = MolBuilder::new(
        (src.raw_size() / 81 + 1).min(MAX_SPHERES),
        opts.assembly.is_some(),
    );
    let mut assemblies: Vec<Assembly> = Vec::new();

    // Atoms before any MODEL record form model 1.
    let mut models_seen = 0u32;
    let mut accepting = match opts.model {
        ModelSelect::First | ModelSelect::All => true,
        ModelSelect::Index(n) => n == 1,
    };
    let mut selected_found = false;
    let mut level0 = 0u32;
    let mut first_alt: Option<u8> = None;

    while let Some((line_no, line, cut)) = src.next()? {
        if line.starts_with(b"ATOM") || line.starts_with(b"HETATM") {
            if cut {
                return Err(truncated(name, line_no));
            }
            if accepting {
                atom(line, line_no, name, level0, &mut first_alt, &mut builder)?;
            }
        } else if line.starts_with(b"MODEL") {
            models_seen += 1;
            // Model serial in columns 11-14; writers disagree on alignment.
            let number = line
                .get(6..line.len().min(14))
                .and_then(|f| super::hybrid36::decode(4, trim(f)))
                .and_then(|n| u32::try_from(n).ok())
                .unwrap_or(models_seen);
            match opts.model {
                // The first model is complete once a second one starts.
                ModelSelect::First if models_seen > 1 => break,
                ModelSelect::First => accepting = true,
                ModelSelect::Index(n) => {
                    if selected_found && !accepting {
                        break;
                    }
                    accepting = number == n;
                    selected_found |= accepting;
                }
                ModelSelect::All => {
                    accepting = true;
                    level0 = models_seen - 1;
                }
            }
        } else if line.starts_with(b"ENDMDL") {
            if opts.model == ModelSelect::First {
                break;
            }
            accepting = false;
        } else if line.starts_with(b"REMARK 350") && opts.assembly.is_some() {
            remark350(line, line_no, name, &mut assemblies)?;
        }
    }

    if let ModelSelect::Index(n) = opts.model {
        let found = selected_found || (models_seen == 0 && n == 1);
        if !found {
            return Err(SceneError::Invalid(format!(
                "{name}: model {n} not found (the file has {} model{})",
                models_seen.max(1),
                if models_seen > 1 { "s" } else { "" }
            )));
        }
    }
    let assembly = match opts.assembly {
        Some(id) => Some(find_assembly(name, &assemblies, id)?),
        None => None,
    };
    builder.finish(name, opts.color_by, assembly)
}

/// Parses one ATOM/HETATM record (already known to be selected).
#[inline]
fn atom(
    line: &[u8],
    line_no: usize,
    name: &str,
    level0: u32,
    first_alt: &mut Option<u8>,
    builder: &mut MolBuilder,
) -> Result<(), SceneError> {
    if line.len() < 54 {
        return Err(parse_error(
            name,
            line_no,
            format!(
                "truncated {} record ({} characters; coordinates need columns 31-54)",
                show(&line[..line.len().min(6)]),
                line.len()
            ),
        ));
    }
    // Alternate locations: keep blank and the first letter seen (usually A).
    let alt = line[16];
    if alt != b' ' {
        match *first_alt {
            None => *first_alt = Some(alt),
            Some(a) if a != alt => return Ok(()),
            Some(_) => {}
        }
    }
    let coord = |range: std::ops::Range<usize>, axis: &str| {
        parse_f32(&line[range.clone()]).ok_or_else(|| {
            parse_error(
                name,
                line_no,
                format!(
                    "bad {axis} coordinate '{}' (columns {}-{})",
                    show(&line[range.clone()]),
                    range.start + 1,
                    range.end
                ),
            )
        })
    };
    let center = [
        check_coordinate(coord(30..38, "x")?, "x", name, line_no)?,
        check_coordinate(coord(38..46, "y")?, "y", name, line_no)?,
        check_coordinate(coord(46..54, "z")?, "z", name, line_no)?,
    ];
    if builder.len() >= MAX_SPHERES {
        return Err(too_many(name, line_no));
    }

    // Column 21 is blank in standard files. Wide files put the first letter
    // of a two-letter chain there (`PHEAA`); CHARMM puts the fourth letter of
    // a residue name there (`TIP3`, `POPC `).
    let (c21, c22) = (line[20], line[21]);
    let res4: &[u8] = &line[17..21];
    let two_letter_chain = c21.is_ascii_alphabetic()
        && c22 != b' '
        && !FOUR_LETTER_KEYS.contains(&u32::from_le_bytes([line[17], line[18], line[19], c21]));
    let chain: &[u8] = if two_letter_chain {
        &line[20..22]
    } else {
        &line[21..22]
    };
    let res_name: &[u8] = if two_letter_chain || c21 == b' ' {
        &line[17..20]
    } else {
        res4
    };
    // Chain key: the two chain columns as written, plus the segment id
    // (columns 73-76) when the chain is blank, so blank-chain files still
    // tell molecules apart. Packed exactly into a u64.
    let mut key = [0u8; 8];
    key[0] = if two_letter_chain { c21 } else { b' ' };
    key[1] = c22;
    if key[..2] == *b"  " {
        let seg = line.get(72..line.len().min(76)).unwrap_or(b"");
        key[2..2 + seg.len()].copy_from_slice(seg);
    }
    let chain_key = u64::from_le_bytes(key);
    // Residue key: name, chain, number and insertion code exactly as written
    // (hybrid-36 or wrapped numbers need no decoding for change detection).
    let mut res = [0u8; 16];
    res[..10].copy_from_slice(&line[17..27]);
    let residue = u128::from_le_bytes(res);

    let element = line
        .get(76..line.len().min(78))
        .and_then(Element::from_symbol)
        .unwrap_or_else(|| elements::guess_pdb(&line[12..16], res_name));

    builder.push(
        center,
        element,
        AtomKeys {
            level0,
            chain: chain_key,
            residue,
            asm_chain: trim(chain),
            entity: b"",
            info: AtomInfo {
                chain: trim(chain),
                resname: trim(res_name),
                resid: hybrid36::decode(4, &line[22..26]).map_or(0, |v| v as i32),
                name: trim(&line[12..16]),
                hetatm: line.starts_with(b"HETATM"),
                bfactor: line
                    .get(60..line.len().min(66))
                    .and_then(parse_f32)
                    .unwrap_or(0.0),
            },
        },
    );
    Ok(())
}

/// Parses one `REMARK 350` line into the assembly list.
fn remark350(
    line: &[u8],
    line_no: usize,
    name: &str,
    list: &mut Vec<Assembly>,
) -> Result<(), SceneError> {
    let text = String::from_utf8_lossy(line.get(10..).unwrap_or(b""));
    let t = text.trim();
    let chains_after = |s: &str| -> Vec<Vec<u8>> {
        s.split(',')
            .map(|c| c.trim().as_bytes().to_vec())
            .filter(|c| !c.is_empty())
            .collect()
    };
    if let Some(rest) = t.strip_prefix("BIOMOLECULE:") {
        let id = rest.trim().parse::<u32>().map_err(|_| {
            parse_error(
                name,
                line_no,
                format!("bad BIOMOLECULE number '{}'", rest.trim()),
            )
        })?;
        list.push(Assembly {
            id,
            groups: Vec::new(),
        });
    } else if let Some(pos) = t.find("APPLY THE FOLLOWING TO CHAINS:") {
        let chains = chains_after(&t[pos + "APPLY THE FOLLOWING TO CHAINS:".len()..]);
        current(list).groups.push(AsmGroup {
            chains,
            ops: Vec::new(),
        });
    } else if let Some(rest) = t.strip_prefix("AND CHAINS:") {
        let group = current_group(current(list));
        group.chains.extend(chains_after(rest));
    } else if let Some(rest) = t.strip_prefix("BIOMT") {
        let bad = || parse_error(name, line_no, "malformed BIOMT record");
        let row = rest
            .bytes()
            .next()
            .and_then(|b| (b'1'..=b'3').contains(&b).then(|| usize::from(b - b'1')))
            .ok_or_else(bad)?;
        let mut fields = rest[1..].split_whitespace().skip(1); // skip serial
        let mut v = [0.0f32; 4];
        for slot in &mut v {
            *slot = fields
                .next()
                .and_then(|f| parse_f32(f.as_bytes()))
                .ok_or_else(bad)?;
        }
        let group = current_group(current(list));
        if row == 0 || group.ops.is_empty() {
            group.ops.push([
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
            ]);
        }
        if let Some(op) = group.ops.last_mut() {
            op[row] = v;
        }
    }
    Ok(())
}

/// The assembly being read (an implicit one if BIOMOLECULE is missing).
fn current(list: &mut Vec<Assembly>) -> &mut Assembly {
    if list.is_empty() {
        list.push(Assembly {
            id: 1,
            groups: Vec::new(),
        });
    }
    let last = list.len() - 1;
    &mut list[last]
}

/// The chain group being read (all chains if no APPLY line preceded).
fn current_group(asm: &mut Assembly) -> &mut AsmGroup {
    if asm.groups.is_empty() {
        asm.groups.push(AsmGroup::default());
    }
    let last = asm.groups.len() - 1;
    &mut asm.groups[last]
}

#[cfg(test)]
mod tests {
    use super::super::{ColorBy, Format, parse_str};
    use super::*;

    fn load(text: &str, opts: &LoadOptions) -> Result<Scene, SceneError> {
        parse_str(text, Format::Pdb, "t.pdb", opts)
    }

    fn def(text: &str) -> Scene {
        load(text, &LoadOptions::default()).unwrap()
    }

    fn distinct(s: &Scene, level: usize) -> usize {
        let mut v: Vec<u32> = s.spheres.iter().map(|s| s.region[level]).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    }

    fn expect_parse_err(text: &str, line: usize) {
        match load(text, &LoadOptions::default()) {
            Err(SceneError::Parse { line: l, path, .. }) => {
                assert_eq!(l, line, "{text}");
                assert_eq!(path, "t.pdb");
            }
            other => panic!("expected parse error at line {line}, got {other:?}"),
        }
    }

    #[test]
    fn basic_columns_and_elements() {
        let s = def("\
HEADER    TEST
ATOM      1  N   GLY D   1      42.053  -9.336  17.867  1.00 43.86           N  
ATOM      2  CA  GLY D   1      42.704 -10.253  18.851  1.00 41.67           C  
ANISOU    2  CA  GLY D   1     5025   4936   4663    200    220    -20       C  
TER
HETATM 5477  O   HOH     1      19.099   9.698 -13.097  1.00 32.87           O  
END
");
        assert_eq!(s.spheres.len(), 3);
        assert_eq!(s.spheres[0].center, [42.053, -9.336, 17.867]);
        assert_eq!(s.spheres[0].radius, Element::N.radius());
        assert_eq!(s.spheres[1].radius, Element::C.radius());
        assert_eq!(s.spheres[2].radius, Element::O.radius());
        assert_eq!(distinct(&s, 1), 2); // D and blank
        assert_eq!(distinct(&s, 2), 2);
        assert_eq!(s.level_names, vec!["model", "chain", "residue", "atom"]);
        assert_eq!(s.spheres[2].region[3], 2);
    }

    #[test]
    fn touching_fields_two_letter_chains_and_hybrid36() {
        // pdb4v8r_h36 style: HETATM touching a hybrid-36 serial, PHEAA,
        // `PHEAa1005`, occupancy touching B, element columns BE / MG.
        let s = def("\
ATOM      1  N   PHEAA   5     131.128  15.297 139.774  1.00150.60         A N  
ATOM      2  CA  PHEAa1005     129.714  14.803 139.851  1.00150.60         A C  
HETATMA0LGO  BE  BEFAA 602      99.650   2.287 160.398  1.00146.00        HABE  
HETATMA0LGP  MG   MGAA 603      99.650   2.287 160.398  1.00146.00        HAMG  
");
        assert_eq!(s.spheres.len(), 4);
        // AA and Aa are different chains; BEF/MG stay in chain AA.
        let chains: Vec<u32> = s.spheres.iter().map(|s| s.region[1]).collect();
        assert_eq!(chains, vec![0, 1, 0, 0]);
        assert_eq!(s.spheres[2].radius, Element::BE.radius());
        assert_eq!(s.spheres[3].radius, Element::MG.radius());
        assert_eq!(s.spheres[0].center, [131.128, 15.297, 139.774]);
    }

    #[test]
    fn charmm_tip3_segids_and_name_guessing() {
        // pdb1tw7 style: TIP3 in columns 18-21, blank chain, segment ids,
        // no element columns, CLA chloride, hybrid-36 serial and resSeq.
        let s = def("\
ATOM      1  N   PRO     1      -7.107  15.915   5.611  1.00  1.00      PROA    
ATOM      2 HG21 THR     2      -7.623  16.764   5.779  1.00  0.00      PROA    
ATOM   3111  OH2 TIP3    1     -28.430 -30.303 -33.703  1.00  0.00      SOLV    
ATOM   3112  H1  TIP3    1     -28.542 -29.334 -33.779  1.00  0.00      SOLV    
ATOM  A0000  OH2 TIP3 A000     -28.430 -30.303 -33.703  1.00  0.00      SOLV    
ATOM  A00GA  CLA CLA     1      -0.841 -10.575 -10.880  1.00  0.00       CLA    
");
        assert_eq!(s.spheres.len(), 6);
        let r: Vec<f32> = s.spheres.iter().map(|s| s.radius).collect();
        assert_eq!(
            r,
            vec![
                Element::N.radius(),
                Element::H.radius(),
                Element::O.radius(),
                Element::H.radius(),
                Element::O.radius(),
                Element::CL.radius()
            ]
        );
        // Chains from segment ids: PROA, SOLV, CLA.
        assert_eq!(distinct(&s, 1), 3);
        // Residues: PRO 1, THR 2, TIP3 1, TIP3 A000, CLA 1.
        assert_eq!(distinct(&s, 2), 5);
    }

    #[test]
    fn element_column_wins_over_name() {
        // rho.pdb: chloride written " CL " with element C stays carbon.
        let s = def(
            "HETATM51930  CL  CL   3239      52.680  19.430  14.500  0.00  0.00           C  \n",
        );
        assert_eq!(s.spheres[0].radius, Element::C.radius());
        // Without the element column the ion rule reads it as chlorine.
        let s = def("HETATM51930  CL  CL   3239      52.680  19.430  14.500  0.00  0.00\n");
        assert_eq!(s.spheres[0].radius, Element::CL.radius());
    }

    #[test]
    fn residue_numbers_wrap() {
        let s = def("\
HETATM    1  OW  SOL  9999      52.680  19.430  14.500  0.00  0.00           O  
HETATM    2  OW  SOL     0      52.680  19.430  14.500  0.00  0.00           O  
HETATM    3  OW  SOL     1      52.680  19.430  14.500  0.00  0.00           O  
HETATM    4  OW  SOL  9999      52.680  19.430  14.500  0.00  0.00           O  
");
        assert_eq!(distinct(&s, 2), 4);
    }

    #[test]
    fn altlocs_keep_first() {
        let s = def("\
ATOM      1  CA AGLY A   1       1.000   1.000   1.000  0.50  1.00           C  
ATOM      2  CA BGLY A   1       2.000   2.000   2.000  0.50  1.00           C  
ATOM      3  N   GLY A   2       3.000   3.000   3.000  1.00  1.00           N  
");
        assert_eq!(s.spheres.len(), 2);
        assert_eq!(s.spheres[1].center, [3.0; 3]);
    }

    const MODELS: &str = "\
MODEL        1
ATOM      1  CA  GLY A   1       1.000   1.000   1.000  1.00  1.00           C  
ENDMDL
MODEL        2
ATOM      1  CA  GLY A   1       2.000   1.000   1.000  1.00  1.00           C  
ATOM      2  CA  GLY A   2       2.000   1.000   1.000  1.00  1.00           C  
ENDMDL
MODEL        3
ATOM      1  CA  GLY A   1       3.000   1.000   1.000  1.00  1.00           C  
ATOM      2  CA  GLY A   2       3.000   1.000   1.000  1.00  1.00           C  
ATOM      3  CA  GLY A   3       3.000   1.000   1.000  1.00  1.00           C  
ENDMDL
";

    #[test]
    fn model_selection() {
        let mut o = LoadOptions::default();
        assert_eq!(load(MODELS, &o).unwrap().spheres.len(), 1);
        o.model = ModelSelect::Index(2);
        let s = load(MODELS, &o).unwrap();
        assert_eq!(s.spheres.len(), 2);
        assert_eq!(s.spheres[0].center[0], 2.0);
        o.model = ModelSelect::Index(3);
        assert_eq!(load(MODELS, &o).unwrap().spheres.len(), 3);
        o.model = ModelSelect::All;
        let s = load(MODELS, &o).unwrap();
        assert_eq!(s.spheres.len(), 6);
        assert_eq!(distinct(&s, 0), 3);
        assert_eq!(distinct(&s, 1), 3); // chain A per model
        o.model = ModelSelect::Index(4);
        assert!(matches!(load(MODELS, &o), Err(SceneError::Invalid(_))));
        // A file without MODEL records is model 1.
        let one =
            "ATOM      1  CA  GLY A   1       1.000   1.000   1.000  1.00  1.00           C\n";
        o.model = ModelSelect::Index(1);
        assert_eq!(load(one, &o).unwrap().spheres.len(), 1);
        o.model = ModelSelect::Index(2);
        assert!(matches!(load(one, &o), Err(SceneError::Invalid(_))));
    }

    const BIOMT: &str = "\
REMARK 350 BIOMOLECULE: 1
REMARK 350 APPLY THE FOLLOWING TO CHAINS: A,
REMARK 350                    AND CHAINS: C
REMARK 350   BIOMT1   1  1.000000  0.000000  0.000000        0.00000
REMARK 350   BIOMT2   1  0.000000  1.000000  0.000000        0.00000
REMARK 350   BIOMT3   1  0.000000  0.000000  1.000000        0.00000
REMARK 350   BIOMT1   2 -1.000000  0.000000  0.000000       10.00000
REMARK 350   BIOMT2   2  0.000000  1.000000  0.000000        0.00000
REMARK 350   BIOMT3   2  0.000000  0.000000  1.000000        0.00000
REMARK 350 BIOMOLECULE: 2
REMARK 350 APPLY THE FOLLOWING TO CHAINS: B
REMARK 350   BIOMT1   1  1.000000  0.000000  0.000000        0.00000
REMARK 350   BIOMT2   1  0.000000  1.000000  0.000000        0.00000
REMARK 350   BIOMT3   1  0.000000  0.000000  1.000000        0.00000
ATOM      1  CA  GLY A   1       1.000   1.000   1.000  1.00  1.00           C  
ATOM      2  CA  GLY B   1       2.000   1.000   1.000  1.00  1.00           C  
ATOM      3  CA  GLY C   1       3.000   1.000   1.000  1.00  1.00           C  
";

    #[test]
    fn assemblies() {
        let mut o = LoadOptions {
            assembly: Some(1),
            color_by: ColorBy::Chain,
            ..LoadOptions::default()
        };
        let s = load(BIOMT, &o).unwrap();
        let x: Vec<f32> = s.spheres.iter().map(|s| s.center[0]).collect();
        assert_eq!(x, vec![1.0, 3.0, 9.0, 7.0]);
        assert_eq!(distinct(&s, 0), 2);
        assert_eq!(distinct(&s, 1), 4);
        o.assembly = Some(2);
        let s = load(BIOMT, &o).unwrap();
        assert_eq!(s.spheres.len(), 1);
        assert_eq!(s.spheres[0].center[0], 2.0);
        o.assembly = Some(3);
        let err = load(BIOMT, &o).unwrap_err();
        assert!(err.to_string().contains("assembly 3 not found"), "{err}");
        // Without REMARK 350 every assembly is missing.
        o.assembly = Some(1);
        assert!(matches!(load(MODELS, &o), Err(SceneError::Invalid(_))));
    }

    #[test]
    fn malformed_records() {
        // Truncated record.
        expect_parse_err(
            "ATOM      1  CA  GLY A   1       1.000   1.000   1.000  1.00  1.00           C\n\
             ATOM      2  CA  GLY A   1       1.000   1.000\n",
            2,
        );
        // Non-numeric, NaN and infinite coordinates.
        expect_parse_err(
            "REMARK\nATOM      1  CA  GLY A   1       1.000   abcde   1.000  1.00  1.00           C\n",
            2,
        );
        expect_parse_err(
            "ATOM      1  CA  GLY A   1         NaN   1.000   1.000  1.00  1.00           C\n",
            1,
        );
        expect_parse_err(
            "ATOM      1  CA  GLY A   1       1.000   1.000     inf  1.00  1.00           C\n",
            1,
        );
        expect_parse_err(
            "ATOM      1  CA  GLY A   1       1.000   1.000        \n",
            1,
        );
        // Malformed BIOMT only matters when assemblies are requested.
        let bad = "REMARK 350   BIOMT1   1  1.0 zz\n\
                   ATOM      1  CA  GLY A   1       1.000   1.000   1.000  1.00  1.00           C\n";
        assert_eq!(def(bad).spheres.len(), 1);
        let o = LoadOptions {
            assembly: Some(1),
            ..LoadOptions::default()
        };
        assert!(matches!(
            load(bad, &o),
            Err(SceneError::Parse { line: 1, .. })
        ));
        // No atoms at all.
        assert!(matches!(
            load("HEADER\nEND\n", &LoadOptions::default()),
            Err(SceneError::Empty { .. })
        ));
        assert!(matches!(
            load("", &LoadOptions::default()),
            Err(SceneError::Empty { .. })
        ));
    }

    #[test]
    fn short_lines_without_optional_columns() {
        // 54 characters: no occupancy, segment or element columns.
        let s = def("ATOM      1  CA  GLY A   1       1.000   1.000   1.000\n");
        assert_eq!(s.spheres.len(), 1);
        assert_eq!(s.spheres[0].radius, Element::C.radius());
        // CRLF line ends.
        let s = def("ATOM      1  O   HOH A   1       1.000   1.000   1.000\r\n");
        assert_eq!(s.spheres[0].radius, Element::O.radius());
    }
}
