//! mmCIF reader: the `_atom_site` loop (fast, one row per line) plus the
//! small `_pdbx_struct_assembly_gen` / `_pdbx_struct_oper_list` categories
//! for biological assemblies.

use std::collections::HashMap;

mod assembly;
mod binary;
mod instanced;

use assembly::assemblies;
#[cfg(test)]
use assembly::{IDENTITY, oper_expression};
pub(crate) use binary::parse_bcif;
use instanced::{atom_model, finish_instanced, instanced_kind};

use super::atoms::AtomInfo;
use super::elements::{self, Element};
use super::molecule::{AtomKeys, MolBuilder, find_assembly, key64};
use super::text::{LineSource, parse_f32, show};
use super::{
    LoadOptions, MAX_SPHERES, ModelSelect, Scene, SceneError, check_coordinate, parse_error,
    too_many, truncated,
};

/// Splits a CIF line into tokens: whitespace-separated, `'...'` / `"..."`
/// quoted (a quote only closes when followed by whitespace or the line end,
/// so `'O5''` style names survive), `#` starts a comment between tokens.
/// Quoted tokens keep their quotes, so a quoted value is never mistaken for
/// an item name or keyword; [`unquote`] strips them.
pub(crate) fn tokenize<'a>(line: &'a [u8], out: &mut Vec<&'a [u8]>) -> Result<(), String> {
    out.clear();
    let n = line.len();
    let mut i = 0;
    while i < n {
        let c = line[i];
        if c.is_ascii_whitespace() {
            i += 1;
            continue;
        }
        if c == b'#' {
            break;
        }
        if c == b'\'' || c == b'"' {
            let mut j = i + 1;
            loop {
                if j >= n {
                    return Err(format!("unterminated {} quote", c as char));
                }
                if line[j] == c && (j + 1 == n || line[j + 1].is_ascii_whitespace()) {
                    break;
                }
                j += 1;
            }
            out.push(&line[i..=j]);
            i = j + 1;
        } else {
            let start = i;
            while i < n && !line[i].is_ascii_whitespace() {
                i += 1;
            }
            out.push(&line[start..i]);
        }
    }
    Ok(())
}

/// The text of a token without its quotes.
pub(crate) fn unquote(tok: &[u8]) -> &[u8] {
    match tok {
        [q, inner @ .., e] if (*q == b'\'' || *q == b'"') && e == q => inner,
        _ => tok,
    }
}

/// `?` (unknown) and `.` (not applicable) both mean "no value".
fn value(tok: &[u8]) -> Option<&[u8]> {
    (tok != b"?" && tok != b".").then(|| unquote(tok))
}

/// Column indices of the `_atom_site` items we use.
#[derive(Default)]
struct Columns {
    x: Option<usize>,
    y: Option<usize>,
    z: Option<usize>,
    type_symbol: Option<usize>,
    label_atom: Option<usize>,
    auth_atom: Option<usize>,
    auth_asym: Option<usize>,
    label_asym: Option<usize>,
    label_seq: Option<usize>,
    auth_seq: Option<usize>,
    label_comp: Option<usize>,
    auth_comp: Option<usize>,
    ins_code: Option<usize>,
    model: Option<usize>,
    alt: Option<usize>,
    entity: Option<usize>,
    group: Option<usize>,
    bfactor: Option<usize>,
}

impl Columns {
    /// The item indices the reader looks at.
    fn used(&self) -> Vec<usize> {
        [
            self.x,
            self.y,
            self.z,
            self.type_symbol,
            self.label_atom,
            self.auth_atom,
            self.auth_asym,
            self.label_asym,
            self.label_seq,
            self.auth_seq,
            self.label_comp,
            self.auth_comp,
            self.ins_code,
            self.model,
            self.alt,
            self.entity,
            self.group,
            self.bfactor,
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    fn new(items: &[String]) -> Self {
        let mut c = Columns::default();
        for (i, item) in items.iter().enumerate() {
            let slot = match item.strip_prefix("_atom_site.").unwrap_or("") {
                "Cartn_x" => &mut c.x,
                "Cartn_y" => &mut c.y,
                "Cartn_z" => &mut c.z,
                "type_symbol" => &mut c.type_symbol,
                "label_atom_id" => &mut c.label_atom,
                "auth_atom_id" => &mut c.auth_atom,
                "auth_asym_id" => &mut c.auth_asym,
                "label_asym_id" => &mut c.label_asym,
                "label_seq_id" => &mut c.label_seq,
                "auth_seq_id" => &mut c.auth_seq,
                "label_comp_id" => &mut c.label_comp,
                "auth_comp_id" => &mut c.auth_comp,
                "pdbx_PDB_ins_code" => &mut c.ins_code,
                "pdbx_PDB_model_num" => &mut c.model,
                "label_alt_id" => &mut c.alt,
                "label_entity_id" => &mut c.entity,
                "group_PDB" => &mut c.group,
                "B_iso_or_equiv" => &mut c.bfactor,
                _ => continue,
            };
            *slot = Some(i);
        }
        c
    }
}

/// A small category kept as strings (loop or key-value form).
#[derive(Default, Debug)]
struct Category {
    items: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Category {
    fn col(&self, item: &str) -> Option<usize> {
        self.items.iter().position(|i| i.eq_ignore_ascii_case(item))
    }
}

/// Categories read for assemblies and instanced models (PetWorld's model
/// names, cellPACK's hierarchy paths in the entity descriptions).
const KEPT: [&str; 4] = [
    "_pdbx_struct_assembly_gen",
    "_pdbx_struct_oper_list",
    "_pdbx_model",
    "_entity",
];

fn category_of(item: &str) -> &str {
    item.split('.').next().unwrap_or(item)
}

enum State {
    /// Between loops (key-value pairs may appear).
    Outside,
    /// Reading the item names after `loop_`.
    LoopItems,
    /// Reading the values of an ordinary loop.
    LoopValues,
    /// Reading `_atom_site` rows, one per line.
    AtomRows,
}

/// One `_atom_site` row, from text tokens or a BinaryCIF row.
pub(crate) trait AtomRow {
    /// The value of item i: None for `?`, `.` (or masked in BinaryCIF).
    fn value(&self, i: usize) -> Option<&[u8]>;
    /// Item i as a coordinate, or the text to show in the error.
    fn coordinate(&self, i: Option<usize>) -> Result<f32, String>;
}

/// A text row: its tokens.
struct TextRow<'a, 'b>(&'a [&'b [u8]]);

impl AtomRow for TextRow<'_, '_> {
    fn value(&self, i: usize) -> Option<&[u8]> {
        value(self.0[i])
    }

    fn coordinate(&self, i: Option<usize>) -> Result<f32, String> {
        let tok = i.map_or(&b"?"[..], |i| self.0[i]);
        parse_f32(tok).ok_or_else(|| show(tok))
    }
}

/// Selection and bookkeeping while reading `_atom_site` rows.
pub(crate) struct AtomReader {
    model: ModelSelect,
    cols: Columns,
    n_items: usize,
    models: Vec<i64>,
    last_model: Option<(i64, bool, u32)>,
    selected_found: bool,
    first_alt: Option<Vec<u8>>,
}

impl AtomReader {
    fn new(model: ModelSelect, cols: Columns, n_items: usize) -> Self {
        AtomReader {
            model,
            cols,
            n_items,
            models: Vec::new(),
            last_model: None,
            selected_found: false,
            first_alt: None,
        }
    }

    /// A text row: its token count checked first.
    fn text_row(
        &mut self,
        toks: &[&[u8]],
        line_no: usize,
        name: &str,
        builder: &mut MolBuilder,
    ) -> Result<(), SceneError> {
        if toks.len() != self.n_items {
            return Err(parse_error(
                name,
                line_no,
                format!(
                    "_atom_site row has {} values, expected {}",
                    toks.len(),
                    self.n_items
                ),
            ));
        }
        self.row(&TextRow(toks), line_no, name, builder)
    }

    fn row(
        &mut self,
        row: &dyn AtomRow,
        line_no: usize,
        name: &str,
        builder: &mut MolBuilder,
    ) -> Result<(), SceneError> {
        let get = |c: Option<usize>| c.and_then(|i| row.value(i));

        // Model selection; rows of one model are contiguous, so cache it.
        let model_num = match get(self.cols.model) {
            Some(t) => std::str::from_utf8(t)
                .ok()
                .and_then(|s| s.parse::<i64>().ok())
                .ok_or_else(|| {
                    parse_error(name, line_no, format!("bad model number '{}'", show(t)))
                })?,
            None => 1,
        };
        let (accept, level0) = match self.last_model {
            Some((m, acc, l0)) if m == model_num => (acc, l0),
            _ => {
                let index = match self.models.iter().position(|&m| m == model_num) {
                    Some(i) => i,
                    None => {
                        self.models.push(model_num);
                        self.models.len() - 1
                    }
                };
                let (acc, l0) = match self.model {
                    ModelSelect::First => (index == 0, 0),
                    ModelSelect::Index(n) => (model_num == i64::from(n), 0),
                    ModelSelect::All => (true, index as u32),
                };
                self.selected_found |= acc;
                self.last_model = Some((model_num, acc, l0));
                (acc, l0)
            }
        };
        if !accept {
            return Ok(());
        }
        if let Some(alt) = get(self.cols.alt) {
            match &self.first_alt {
                None => self.first_alt = Some(alt.to_vec()),
                Some(a) if a.as_slice() != alt => return Ok(()),
                Some(_) => {}
            }
        }
        let mut center = [0.0f32; 3];
        for (slot, (col, axis)) in center.iter_mut().zip([
            (self.cols.x, "Cartn_x"),
            (self.cols.y, "Cartn_y"),
            (self.cols.z, "Cartn_z"),
        ]) {
            let v = row
                .coordinate(col)
                .map_err(|tok| parse_error(name, line_no, format!("bad {axis} value '{tok}'")))?;
            *slot = check_coordinate(v, axis, name, line_no)?;
        }
        if builder.len() >= MAX_SPHERES {
            return Err(too_many(name, line_no));
        }
        let comp = get(self.cols.label_comp)
            .or_else(|| get(self.cols.auth_comp))
            .unwrap_or(b"");
        let element = get(self.cols.type_symbol)
            .and_then(Element::from_symbol)
            .unwrap_or_else(|| {
                let atom = get(self.cols.label_atom)
                    .or_else(|| get(self.cols.auth_atom))
                    .unwrap_or(b"");
                elements::guess_name(atom, comp)
            });
        let label_asym = get(self.cols.label_asym);
        let chain = get(self.cols.auth_asym).or(label_asym).unwrap_or(b"");
        let residue = key64(&[
            get(self.cols.label_seq).unwrap_or(b""),
            get(self.cols.auth_seq).unwrap_or(b""),
            comp,
            get(self.cols.ins_code).unwrap_or(b""),
        ]);
        builder.push(
            center,
            element,
            AtomKeys {
                level0,
                chain: key64(&[chain]),
                residue: u128::from(residue),
                asm_chain: label_asym.unwrap_or(chain),
                entity: get(self.cols.entity).unwrap_or(b""),
                info: AtomInfo {
                    chain,
                    resname: comp,
                    resid: get(self.cols.auth_seq)
                        .or_else(|| get(self.cols.label_seq))
                        .and_then(|v| std::str::from_utf8(v).ok()?.parse().ok())
                        .unwrap_or(0),
                    name: get(self.cols.auth_atom)
                        .or_else(|| get(self.cols.label_atom))
                        .unwrap_or(b""),
                    hetatm: get(self.cols.group).is_some_and(|g| g == b"HETATM"),
                    bfactor: get(self.cols.bfactor).and_then(parse_f32).unwrap_or(0.0),
                },
            },
        );
        Ok(())
    }
}

pub(crate) fn parse(
    src: &mut LineSource,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let mut builder = MolBuilder::new(
        (src.raw_size() / 90 + 1).min(MAX_SPHERES),
        opts.assembly.is_some(),
    );
    let mut state = State::Outside;
    let mut items: Vec<String> = Vec::new();
    let mut loop_line = 0usize;
    let mut atoms: Option<AtomReader> = None;
    let mut atom_loop_done = false;
    // Ordinary loops / key-value pairs of the kept categories.
    let mut kept: HashMap<&'static str, Category> = HashMap::new();
    let mut row: Vec<String> = Vec::new();
    let mut pending_key: Option<String> = None;
    let mut in_text_field = false;
    // The first data block's name (cellPACK exports: CELLPACK_MODEL).
    let mut header: Option<String> = None;

    while let Some((line_no, line, cut)) = src.next()? {
        // (tokens borrow this line only)
        let mut toks: Vec<&[u8]> = Vec::with_capacity(32);
        // Multi-line text fields (;...;) are single values we never use.
        if line.first() == Some(&b';') {
            in_text_field = !in_text_field;
            if in_text_field {
                continue;
            }
            toks.clear();
            toks.push(b"?");
        } else if in_text_field {
            continue;
        } else {
            if let State::AtomRows = state {
                let first = line.iter().copied().find(|b| !b.is_ascii_whitespace());
                match first {
                    None | Some(b'#') => continue,
                    Some(b'_') => {}
                    Some(_) if !line.starts_with(b"loop_") && !line.starts_with(b"data_") => {
                        tokenize(line, &mut toks).map_err(|m| parse_error(name, line_no, m))?;
                        if cut {
                            return Err(truncated(name, line_no));
                        }
                        if let Some(reader) = atoms.as_mut() {
                            reader.text_row(&toks, line_no, name, &mut builder)?;
                        }
                        continue;
                    }
                    Some(_) => {}
                }
                // The atom loop ended; this line starts something else.
                state = State::Outside;
                atom_loop_done = true;
            }
            // Outside the atom loop only the kept categories matter, so a
            // malformed line there is skipped rather than fatal.
            if tokenize(line, &mut toks).is_err() {
                continue;
            }
        }

        for &tok in &toks {
            if tok.starts_with(b"data_") {
                if atom_loop_done {
                    // Only the first data block is read.
                    return finish(builder, name, opts, atoms, &kept, header.as_deref());
                }
                if header.is_none() {
                    header = Some(String::from_utf8_lossy(&tok[5..]).into_owned());
                }
                state = State::Outside;
                pending_key = None;
                continue;
            }
            if tok == b"loop_" {
                state = State::LoopItems;
                items.clear();
                loop_line = line_no;
                pending_key = None;
                continue;
            }
            let is_item = tok.first() == Some(&b'_');
            match state {
                State::LoopItems if is_item => {
                    items.push(String::from_utf8_lossy(tok).into_owned());
                }
                State::LoopItems => {
                    // First value: the item list is complete.
                    if items.first().is_some_and(|i| i.starts_with("_atom_site."))
                        && !atom_loop_done
                    {
                        let cols = Columns::new(&items);
                        if cols.x.is_none() || cols.y.is_none() || cols.z.is_none() {
                            return Err(parse_error(
                                name,
                                loop_line,
                                "the _atom_site loop lacks Cartn_x, Cartn_y or Cartn_z",
                            ));
                        }
                        // (what an instanced model needs is known by now:
                        // its categories come before the atoms)
                        let kind = instanced_kind(opts, &kept, header.as_deref());
                        let model = atom_model(name, opts, kind)?;
                        if opts.assembly.is_some() || kind.is_some() {
                            builder.track_assembly();
                        }
                        atoms = Some(AtomReader::new(model, cols, items.len()));
                        state = State::AtomRows;
                        // This whole line is the first row.
                        if cut {
                            return Err(truncated(name, line_no));
                        }
                        if let Some(reader) = atoms.as_mut() {
                            reader.text_row(&toks, line_no, name, &mut builder)?;
                        }
                        break;
                    }
                    state = State::LoopValues;
                    row.clear();
                    loop_value(tok, &items, &mut row, &mut kept)
                        .map_err(|m| parse_error(name, line_no, m))?;
                }
                State::LoopValues if !is_item => loop_value(tok, &items, &mut row, &mut kept)
                    .map_err(|m| parse_error(name, line_no, m))?,
                State::LoopValues | State::Outside => {
                    state = State::Outside;
                    if is_item {
                        pending_key = Some(String::from_utf8_lossy(tok).into_owned());
                    } else if let Some(key) = pending_key.take() {
                        key_value(key, tok, &mut kept);
                    }
                }
                State::AtomRows => {}
            }
        }
    }
    finish(builder, name, opts, atoms, &kept, header.as_deref())
}

/// Rows kept per category (assembly generators and operators): far above
/// any real entry, and what bounds the memory of a hostile file.
const MAX_KEPT_ROWS: usize = 1 << 20;

/// One value of an ordinary loop: rows of kept categories are stored.
fn loop_value(
    tok: &[u8],
    items: &[String],
    row: &mut Vec<String>,
    kept: &mut HashMap<&'static str, Category>,
) -> Result<(), String> {
    let Some(cat) = items
        .first()
        .and_then(|i| KEPT.iter().copied().find(|k| category_of(i) == *k))
    else {
        return Ok(());
    };
    row.push(String::from_utf8_lossy(unquote(tok)).into_owned());
    if row.len() == items.len() {
        let entry = kept.entry(cat).or_default();
        if entry.items.is_empty() {
            entry.items = items.to_vec();
        }
        if entry.rows.len() >= MAX_KEPT_ROWS {
            return Err(format!("more than {MAX_KEPT_ROWS} rows of {cat}"));
        }
        entry.rows.push(std::mem::take(row));
    }
    Ok(())
}

/// A key-value pair (single-row category form).
fn key_value(key: String, tok: &[u8], kept: &mut HashMap<&'static str, Category>) {
    let Some(cat) = KEPT.iter().copied().find(|k| category_of(&key) == *k) else {
        return;
    };
    let entry = kept.entry(cat).or_default();
    if entry.rows.is_empty() {
        entry.rows.push(Vec::new());
    }
    entry.items.push(key);
    entry.rows[0].push(String::from_utf8_lossy(unquote(tok)).into_owned());
}

fn finish(
    builder: MolBuilder,
    name: &str,
    opts: &LoadOptions,
    atoms: Option<AtomReader>,
    kept: &HashMap<&'static str, Category>,
    header: Option<&str>,
) -> Result<Scene, SceneError> {
    if let ModelSelect::Index(n) = opts.model
        && atoms.as_ref().is_some_and(|a| !a.selected_found)
    {
        return Err(SceneError::Invalid(format!("{name}: model {n} not found")));
    }
    let kind = instanced_kind(opts, kept, header);
    if let Some(kind) = kind {
        // (an empty file has no atoms to instance: the usual error)
        if atoms.is_some() {
            return finish_instanced(builder, name, opts, atoms, kept, kind);
        }
    }
    let assemblies = match opts.assembly {
        Some(want) => assemblies(name, kept, want)?,
        None => Vec::new(),
    };
    let assembly = match opts.assembly {
        Some(id) => Some(find_assembly(name, &assemblies, id)?),
        None => None,
    };
    builder.finish(name, opts.color_by, assembly)
}

#[cfg(test)]
mod tests {
    use super::super::{Format, parse_str};
    use super::*;

    fn toks(line: &str) -> Vec<String> {
        let mut v = Vec::new();
        tokenize(line.as_bytes(), &mut v).unwrap();
        v.iter()
            .map(|t| String::from_utf8_lossy(unquote(t)).into_owned())
            .collect()
    }

    #[test]
    fn tokenizer_quotes() {
        assert_eq!(toks("a  b\tc"), vec!["a", "b", "c"]);
        assert_eq!(toks("'a b' \"c d\" e"), vec!["a b", "c d", "e"]);
        assert_eq!(toks("'O5'' x"), vec!["O5'", "x"]);
        assert_eq!(toks("\"it's\" O5'"), vec!["it's", "O5'"]);
        assert_eq!(toks("a # comment 'x"), vec!["a"]);
        assert_eq!(toks("a#b"), vec!["a#b"]);
        assert_eq!(toks("''"), vec![""]);
        assert!(tokenize(b"'abc", &mut Vec::new()).is_err());
        // Quoted values keep their quotes until unquoted, so they are never
        // taken for item names.
        let mut raw = Vec::new();
        tokenize(b"1 '_atom_site.id' x", &mut raw).unwrap();
        assert_eq!(raw[1], b"'_atom_site.id'");
    }

    const CIF: &str = "\
data_TEST
#
_struct.title 'a test'
loop_
_atom_site.group_PDB
_atom_site.id
_atom_site.type_symbol
_atom_site.label_atom_id
_atom_site.label_alt_id
_atom_site.label_comp_id
_atom_site.label_asym_id
_atom_site.label_seq_id
_atom_site.Cartn_x
_atom_site.Cartn_y
_atom_site.Cartn_z
_atom_site.auth_seq_id
_atom_site.auth_asym_id
_atom_site.pdbx_PDB_model_num
ATOM   1 N  N   . GLY A 1 1.0 2.0 3.0 1 A 1
ATOM   2 C  CA  . GLY A 1 2.0 2.0 3.0 1 A 1
ATOM   3 C  CA  A SER A 2 3.0 2.0 3.0 2 A 1
ATOM   4 C  CA  B SER A 2 9.0 2.0 3.0 2 A 1
HETATM 5 O  O   . HOH B . 4.0 2.0 3.0 101 A 1
HETATM 6 CL CL  . CL  C . 5.0 2.0 3.0 102 B 1
ATOM   7 N  N   . GLY A 1 1.5 2.0 3.0 1 A 2
ATOM   8 C  CA  . GLY A 1 2.5 2.0 3.0 1 A 2
#
loop_
_pdbx_struct_oper_list.id
_pdbx_struct_oper_list.type
_pdbx_struct_oper_list.matrix[1][1]
_pdbx_struct_oper_list.matrix[1][2]
_pdbx_struct_oper_list.matrix[1][3]
_pdbx_struct_oper_list.vector[1]
_pdbx_struct_oper_list.matrix[2][1]
_pdbx_struct_oper_list.matrix[2][2]
_pdbx_struct_oper_list.matrix[2][3]
_pdbx_struct_oper_list.vector[2]
_pdbx_struct_oper_list.matrix[3][1]
_pdbx_struct_oper_list.matrix[3][2]
_pdbx_struct_oper_list.matrix[3][3]
_pdbx_struct_oper_list.vector[3]
1 'identity operation' 1 0 0 0 0 1 0 0 0 0 1 0
2 'shift' 1 0 0 100 0 1 0 0 0 0 1 0
#
_pdbx_struct_assembly_gen.assembly_id       1
_pdbx_struct_assembly_gen.oper_expression   '(1-2)'
_pdbx_struct_assembly_gen.asym_id_list      A,B
#
";

    fn load(text: &str, opts: &LoadOptions) -> Result<Scene, SceneError> {
        parse_str(text, Format::Cif, "t.cif", opts)
    }

    #[test]
    fn atom_site_models_altlocs_chains() {
        let s = load(CIF, &LoadOptions::default()).unwrap();
        assert_eq!(s.spheres.len(), 5); // model 1 without altloc B
        assert_eq!(s.spheres[0].center, [1.0, 2.0, 3.0]);
        assert_eq!(s.spheres[0].radius, Element::N.radius());
        assert_eq!(s.spheres[4].radius, Element::CL.radius());
        let chains: Vec<u32> = s.spheres.iter().map(|s| s.region[1]).collect();
        assert_eq!(chains, vec![0, 0, 0, 0, 1]); // auth_asym_id A, A, A, A, B
        let res: Vec<u32> = s.spheres.iter().map(|s| s.region[2]).collect();
        assert_eq!(res, vec![0, 0, 1, 2, 3]);

        let all = LoadOptions {
            model: ModelSelect::All,
            ..LoadOptions::default()
        };
        let s = load(CIF, &all).unwrap();
        assert_eq!(s.spheres.len(), 7);
        assert_eq!(s.spheres[6].region[0], 1);

        let two = LoadOptions {
            model: ModelSelect::Index(2),
            ..LoadOptions::default()
        };
        let s = load(CIF, &two).unwrap();
        assert_eq!(s.spheres.len(), 2);
        assert_eq!(s.spheres[0].center[0], 1.5);
        let three = LoadOptions {
            model: ModelSelect::Index(3),
            ..LoadOptions::default()
        };
        assert!(matches!(load(CIF, &three), Err(SceneError::Invalid(_))));
    }

    #[test]
    fn assembly_from_oper_list() {
        let o = LoadOptions {
            assembly: Some(1),
            ..LoadOptions::default()
        };
        let s = load(CIF, &o).unwrap();
        // label_asym A (3 atoms after altlocs) and B (1 atom), operators 1,
        // 2: instanced, the 4 atoms stored once, 8 represented.
        let inst = s.instancing.as_ref().unwrap();
        assert_eq!((s.spheres.len(), inst.instances()), (4, 2));
        assert_eq!(s.represented(), 8);
        let e = s.expand().unwrap();
        assert_eq!(e.spheres[4].center[0], 101.0);
        // levels: the copy (the atoms are all of auth chain A: no chain level)
        assert_eq!(s.level_names, ["molecule"]);
        assert_eq!((e.spheres[3].region[0], e.spheres[4].region[0]), (0, 1));
        let o = LoadOptions {
            assembly: Some(2),
            ..LoadOptions::default()
        };
        assert!(matches!(load(CIF, &o), Err(SceneError::Invalid(_))));
    }

    #[test]
    fn oper_expressions() {
        let mut ops = HashMap::new();
        for i in 1..=5u32 {
            let mut m = IDENTITY;
            m[0][3] = i as f32;
            ops.insert(i.to_string(), m);
        }
        assert_eq!(oper_expression("1", &ops).unwrap().len(), 1);
        assert_eq!(oper_expression("1,2,3", &ops).unwrap().len(), 3);
        assert_eq!(oper_expression("(1-5)", &ops).unwrap().len(), 5);
        // 5^11 operators are refused before any is built
        let bomb = "(1-5)".repeat(11);
        let e = oper_expression(&bomb, &ops).unwrap_err();
        assert!(e.contains("more than 16777215"), "{e}");
        let p = oper_expression("(1,2)(3-5)", &ops).unwrap();
        assert_eq!(p.len(), 6);
        assert_eq!(p[0][0][3], 4.0);
        assert!(oper_expression("(9)", &ops).is_err());
        assert!(oper_expression("(5-1)", &ops).is_err());
        assert!(oper_expression("", &ops).is_err());
    }

    #[test]
    fn malformed_rows() {
        // Wrong token count on line 21 (the 3rd row).
        let bad = CIF.replace(
            "ATOM   3 C  CA  A SER A 2 3.0 2.0 3.0 2 A 1",
            "ATOM   3 C  CA  A SER A 2 3.0 2.0 3.0 2 A",
        );
        match load(&bad, &LoadOptions::default()) {
            Err(SceneError::Parse { line, .. }) => assert_eq!(line, 21),
            other => panic!("{other:?}"),
        }
        let bad = CIF.replace("GLY A 1 2.0 2.0", "GLY A 1 nan 2.0");
        assert!(matches!(
            load(&bad, &LoadOptions::default()),
            Err(SceneError::Parse { line: 20, .. })
        ));
        let bad = CIF.replace("GLY A 1 2.0 2.0 3.0", "GLY A 1 2.0 ? 3.0");
        assert!(matches!(
            load(&bad, &LoadOptions::default()),
            Err(SceneError::Parse { line: 20, .. })
        ));
        let bad = CIF.replace("ATOM   2 C  CA  .", "ATOM   2 C  'CA  .");
        assert!(matches!(
            load(&bad, &LoadOptions::default()),
            Err(SceneError::Parse { line: 20, .. })
        ));
        let bad = CIF.replace("_atom_site.Cartn_y\n", "_atom_site.Cartn_q\n");
        assert!(matches!(
            load(&bad, &LoadOptions::default()),
            Err(SceneError::Parse { line: 4, .. })
        ));
        assert!(matches!(
            load("data_x\n#\n", &LoadOptions::default()),
            Err(SceneError::Empty { .. })
        ));
    }

    #[test]
    fn text_fields_and_single_line_loops() {
        let text = "\
data_x
_struct.title
;
loop_ inside a text field must not matter
;
loop_
_atom_site.id _atom_site.type_symbol _atom_site.Cartn_x _atom_site.Cartn_y _atom_site.Cartn_z
1 C 1 2 3
2 O 4 5 6
";
        let s = load(text, &LoadOptions::default()).unwrap();
        assert_eq!(s.spheres.len(), 2);
        assert_eq!(s.spheres[1].radius, Element::O.radius());
    }
}
