//! BinaryCIF files read as their text mmCIF would be: each `_atom_site`
//! row formatted back into the text the row reader takes (exact decimals
//! of fixed-point columns), the kept categories as strings.

use super::{
    AtomReader, AtomRow, Category, Columns, KEPT, MAX_KEPT_ROWS, atom_model, finish, instanced_kind,
};
use crate::scene::molecule::MolBuilder;
use crate::scene::text::show;
use crate::scene::{LoadOptions, Scene, SceneError};
use std::collections::HashMap;

/// A BinaryCIF `_atom_site` row: the text of each item the reader uses.
struct BcifRow<'c> {
    cat: &'c crate::scene::bcif::Category,
    row: usize,
    used: Vec<usize>,
    texts: Vec<Vec<u8>>,
    present: Vec<bool>,
}

impl<'c> BcifRow<'c> {
    fn new(cat: &'c crate::scene::bcif::Category, used: Vec<usize>) -> Self {
        let n = cat.columns.len();
        BcifRow {
            cat,
            row: 0,
            used,
            texts: vec![Vec::new(); n],
            present: vec![false; n],
        }
    }

    fn load(&mut self, row: usize) {
        self.row = row;
        for &i in &self.used {
            self.present[i] = self.cat.columns[i].text(row, &mut self.texts[i]);
        }
    }
}

impl AtomRow for BcifRow<'_> {
    fn value(&self, i: usize) -> Option<&[u8]> {
        self.present[i].then(|| self.texts[i].as_slice())
    }

    fn coordinate(&self, i: Option<usize>) -> Result<f32, String> {
        let Some(i) = i else {
            return Err("?".into());
        };
        let col = &self.cat.columns[i];
        col.number(self.row).ok_or_else(|| {
            let mut b = Vec::new();
            if col.text(self.row, &mut b) {
                show(&b)
            } else {
                "?".into()
            }
        })
    }
}

/// A BinaryCIF file (the first data block), read exactly as its text
/// mmCIF would be: the same `_atom_site` rules and categories.
pub(crate) fn parse_bcif(data: &[u8], name: &str, opts: &LoadOptions) -> Result<Scene, SceneError> {
    let bad = |m: String| SceneError::Invalid(format!("{name}: {m}"));
    let file = crate::scene::bcif::decode(data).map_err(|e| bad(format!("BinaryCIF: {e}")))?;
    let block = file
        .first_block()
        .ok_or_else(|| bad("BinaryCIF: no data block".into()))?;
    let mut kept: HashMap<&'static str, Category> = HashMap::new();
    let mut text = Vec::new();
    for cat in &block.categories {
        let Some(k) = KEPT.iter().find(|k| cat.name.eq_ignore_ascii_case(k)) else {
            continue;
        };
        if cat.rows > MAX_KEPT_ROWS {
            return Err(bad(format!("more than {MAX_KEPT_ROWS} rows of {k}")));
        }
        let items = cat
            .columns
            .iter()
            .map(|c| format!("{}.{}", cat.name, c.name))
            .collect();
        let rows = (0..cat.rows)
            .map(|r| {
                cat.columns
                    .iter()
                    .map(|c| {
                        if c.text(r, &mut text) {
                            String::from_utf8_lossy(&text).into_owned()
                        } else {
                            "?".to_string()
                        }
                    })
                    .collect()
            })
            .collect();
        kept.insert(k, Category { items, rows });
    }
    let header = Some(block.header.as_str());
    let kind = instanced_kind(opts, &kept, header);
    let mut builder = MolBuilder::new(0, opts.assembly.is_some());
    let mut atoms = None;
    if let Some(cat) = block.category("_atom_site") {
        let items: Vec<String> = cat
            .columns
            .iter()
            .map(|c| format!("_atom_site.{}", c.name))
            .collect();
        let cols = Columns::new(&items);
        if cols.x.is_none() || cols.y.is_none() || cols.z.is_none() {
            return Err(bad(
                "the _atom_site category lacks Cartn_x, Cartn_y or Cartn_z".into(),
            ));
        }
        let model = atom_model(name, opts, kind)?;
        if opts.assembly.is_some() || kind.is_some() {
            builder.track_assembly();
        }
        // (coordinates are read as numbers, not as text)
        let xyz = [cols.x, cols.y, cols.z];
        let used = cols
            .used()
            .into_iter()
            .filter(|&i| !xyz.contains(&Some(i)))
            .collect();
        let mut reader = AtomReader::new(model, cols, items.len());
        let mut row = BcifRow::new(cat, used);
        for r in 0..cat.rows {
            row.load(r);
            reader
                .row(&row, r + 1, name, &mut builder)
                .map_err(|e| match e {
                    SceneError::Parse { line, msg, .. } => {
                        bad(format!("_atom_site row {line}: {msg}"))
                    }
                    other => other,
                })?;
        }
        atoms = Some(reader);
    }
    finish(builder, name, opts, atoms, &kept, header)
}
