//! BinaryCIF: the categories of mmCIF in a MessagePack container, each
//! column a byte array with a chain of encodings (Mol*'s ciftools format,
//! version 0.3). Decoded here into typed columns that the mmCIF reader
//! consumes as it does text rows ([`Column::text`], [`Column::number`]).
//!
//! Encodings (applied in the listed order when writing, so undone in
//! reverse): ByteArray (little-endian Int8..Uint32, Float32/64),
//! FixedPoint (integers / factor), IntervalQuantization, RunLength (value,
//! count pairs), Delta (running sums from an origin), IntegerPacking
//! (wide integers as runs of 1- or 2-byte limit values), StringArray
//! (indices into a string table given by offsets). A column's optional
//! mask marks absent values: 1 = `.`, 2 = `?`.

use rmpv::Value;

/// A decoded file: its data blocks.
#[derive(Debug)]
pub struct File {
    pub blocks: Vec<Block>,
}

#[derive(Debug)]
pub struct Block {
    pub header: String,
    pub categories: Vec<Category>,
}

#[derive(Debug)]
pub struct Category {
    /// With its leading underscore, e.g. `_atom_site`.
    pub name: String,
    pub rows: usize,
    pub columns: Vec<Column>,
}

#[derive(Debug)]
pub struct Column {
    pub name: String,
    pub values: Values,
    /// Per row: 0 = a value, 1 = `.` (not applicable), 2 = `?` (unknown).
    pub mask: Option<Vec<u8>>,
}

/// A column's values, as the encodings left them.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    Int(Vec<i64>),
    Float(Vec<f64>),
    /// Fixed point with a power-of-ten factor: `ints[i] / 10^digits`,
    /// kept as integers so the text is the exact decimal the writer had.
    Decimal {
        ints: Vec<i64>,
        digits: u32,
    },
    Str {
        table: Vec<String>,
        index: Vec<i64>,
    },
}

impl Values {
    pub fn len(&self) -> usize {
        match self {
            Values::Int(v) => v.len(),
            Values::Float(v) => v.len(),
            Values::Decimal { ints, .. } => ints.len(),
            Values::Str { index, .. } => index.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl Column {
    fn present(&self, row: usize) -> bool {
        self.mask.as_ref().is_none_or(|m| m[row] == 0)
    }

    /// The value of `row` as CIF text into `out` (cleared), or false when
    /// the row has no value (masked, or a negative string index).
    pub fn text(&self, row: usize, out: &mut Vec<u8>) -> bool {
        out.clear();
        if !self.present(row) {
            return false;
        }
        use std::io::Write;
        match &self.values {
            Values::Int(v) => {
                let _ = write!(out, "{}", v[row]);
            }
            Values::Float(v) => {
                let _ = write!(out, "{}", v[row]);
            }
            Values::Decimal { ints, digits } => write_decimal(ints[row], *digits, out),
            Values::Str { table, index } => match usize::try_from(index[row]) {
                Ok(i) if i < table.len() => out.extend_from_slice(table[i].as_bytes()),
                _ => return false,
            },
        }
        true
    }

    /// The value of `row` as a number (f32 rounded as the text reader
    /// rounds the same decimal), or None when absent or not numeric.
    pub fn number(&self, row: usize) -> Option<f32> {
        if !self.present(row) {
            return None;
        }
        match &self.values {
            Values::Int(v) => Some(v[row] as f32),
            Values::Float(v) => Some(v[row] as f32).filter(|x| x.is_finite()),
            Values::Decimal { ints, digits } => {
                // (as parse_f32 reads `int / 10^digits` written out)
                let (m, d) = (ints[row], *digits as usize);
                if m.unsigned_abs() < 1_000_000_000_000_000_000 && d < POW10.len() {
                    let v = (m.unsigned_abs() as f64 / POW10[d]) as f32;
                    Some(if m < 0 { -v } else { v })
                } else {
                    let mut b = Vec::new();
                    write_decimal(m, *digits, &mut b);
                    std::str::from_utf8(&b).ok()?.parse().ok()
                }
            }
            Values::Str { .. } => {
                let mut b = Vec::new();
                self.text(row, &mut b)
                    .then(|| super::text::parse_f32(&b))
                    .flatten()
            }
        }
    }
}

const POW10: [f64; 19] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18,
];

/// `m / 10^digits` as exact decimal text (`-0.05`, `12.340`).
fn write_decimal(m: i64, digits: u32, out: &mut Vec<u8>) {
    let s = m.unsigned_abs().to_string();
    if m < 0 {
        out.push(b'-');
    }
    let d = digits as usize;
    if d == 0 {
        out.extend_from_slice(s.as_bytes());
        return;
    }
    if s.len() <= d {
        out.extend_from_slice(b"0.");
        out.extend(std::iter::repeat_n(b'0', d - s.len()));
        out.extend_from_slice(s.as_bytes());
    } else {
        let (int, frac) = s.split_at(s.len() - d);
        out.extend_from_slice(int.as_bytes());
        out.push(b'.');
        out.extend_from_slice(frac.as_bytes());
    }
}

impl File {
    /// The first data block (the readers use only that one, as for text).
    pub fn first_block(&self) -> Option<&Block> {
        self.blocks.first()
    }
}

impl Block {
    pub fn category(&self, name: &str) -> Option<&Category> {
        self.categories
            .iter()
            .find(|c| c.name.eq_ignore_ascii_case(name))
    }
}

impl Category {
    pub fn column(&self, name: &str) -> Option<&Column> {
        self.columns
            .iter()
            .find(|c| c.name.eq_ignore_ascii_case(name))
    }
}

/// Most values a column may decode to: far above any real file (the files
/// this targets have some 10^5-10^7 rows), and what bounds the memory a
/// hostile run-length or packed column can ask for.
pub const MAX_VALUES: usize = 1 << 28;

/// A decoding error; the caller adds the file name.
pub type DecodeError = String;

/// Decodes a whole BinaryCIF file.
pub fn decode(bytes: &[u8]) -> Result<File, DecodeError> {
    let mut cursor = bytes;
    let root = rmpv::decode::read_value(&mut cursor).map_err(|e| {
        format!("not a BinaryCIF file: the MessagePack container does not decode ({e})")
    })?;
    let blocks = field(&root, "dataBlocks")
        .and_then(Value::as_array)
        .ok_or("not a BinaryCIF file: the container has no dataBlocks list")?;
    let mut out = Vec::with_capacity(blocks.len());
    for (k, b) in blocks.iter().enumerate() {
        let header = field(b, "header")
            .and_then(Value::as_str)
            .ok_or_else(|| format!("data block {k} has no header"))?
            .to_string();
        let cats = field(b, "categories")
            .and_then(Value::as_array)
            .ok_or_else(|| format!("data block {header} has no categories list"))?;
        let mut categories = Vec::with_capacity(cats.len());
        for c in cats {
            categories.push(decode_category(c)?);
        }
        out.push(Block { header, categories });
    }
    Ok(File { blocks: out })
}

fn field<'a>(v: &'a Value, key: &str) -> Option<&'a Value> {
    v.as_map()?
        .iter()
        .find(|(k, _)| k.as_str() == Some(key))
        .map(|(_, v)| v)
}

fn decode_category(c: &Value) -> Result<Category, DecodeError> {
    let name = field(c, "name")
        .and_then(Value::as_str)
        .ok_or("a category has no name")?;
    let name = if name.starts_with('_') {
        name.to_string()
    } else {
        format!("_{name}")
    };
    let rows = field(c, "rowCount")
        .and_then(Value::as_u64)
        .ok_or_else(|| format!("category {name} has no rowCount"))? as usize;
    if rows > MAX_VALUES {
        return Err(format!(
            "category {name}: {rows} rows, more than {MAX_VALUES}"
        ));
    }
    let cols = field(c, "columns")
        .and_then(Value::as_array)
        .ok_or_else(|| format!("category {name} has no columns list"))?;
    let mut columns = Vec::with_capacity(cols.len());
    for col in cols {
        let cname = field(col, "name")
            .and_then(Value::as_str)
            .ok_or_else(|| format!("a column of {name} has no name"))?;
        let whole = format!("{name}.{cname}");
        let data = field(col, "data").ok_or_else(|| format!("column {whole} has no data"))?;
        let values = decode_data(data, rows).map_err(|e| format!("column {whole}: {e}"))?;
        if values.len() != rows {
            return Err(format!(
                "column {whole} has {} values, the category has {rows} rows",
                values.len()
            ));
        }
        let mask = match field(col, "mask") {
            None | Some(Value::Nil) => None,
            Some(m) => {
                let ints =
                    match decode_data(m, rows).map_err(|e| format!("mask of {whole}: {e}"))? {
                        Values::Int(v) => v,
                        _ => return Err(format!("mask of {whole} is not integers")),
                    };
                if ints.len() != rows {
                    return Err(format!(
                        "mask of {whole} has {} values, the category has {rows} rows",
                        ints.len()
                    ));
                }
                Some(ints.into_iter().map(|m| m.clamp(0, 2) as u8).collect())
            }
        };
        columns.push(Column {
            name: cname.to_string(),
            values,
            mask,
        });
    }
    Ok(Category {
        name,
        rows,
        columns,
    })
}

/// What an encoding step works on.
enum Data {
    Bytes(Vec<u8>),
    Values(Values),
}

/// An encoded array `{data, encoding: [...]}` decoded (encodings undone
/// last to first). `expect` bounds the sizes a step may produce.
fn decode_data(v: &Value, expect: usize) -> Result<Values, DecodeError> {
    let bytes = match field(v, "data") {
        Some(Value::Binary(b)) => b.clone(),
        _ => return Err("data is not a byte array".into()),
    };
    let encs = field(v, "encoding")
        .and_then(Value::as_array)
        .ok_or("no encoding list")?;
    let mut data = Data::Bytes(bytes);
    for e in encs.iter().rev() {
        data = step(data, e, expect)?;
    }
    match data {
        Data::Values(v) => Ok(v),
        Data::Bytes(_) => Err("the encodings end in raw bytes (no ByteArray)".into()),
    }
}

fn num(e: &Value, key: &str, kind: &str) -> Result<f64, DecodeError> {
    match field(e, key) {
        Some(Value::Integer(i)) => i.as_f64().ok_or_else(|| format!("{kind}: bad {key}")),
        Some(Value::F32(x)) => Ok(*x as f64),
        Some(Value::F64(x)) => Ok(*x),
        _ => Err(format!("{kind} encoding without {key}")),
    }
}

fn ints(data: Data, kind: &str) -> Result<Vec<i64>, DecodeError> {
    match data {
        Data::Values(Values::Int(v)) => Ok(v),
        _ => Err(format!("{kind} needs integers")),
    }
}

/// Checks a size some step is about to produce.
fn check_size(n: u128, kind: &str) -> Result<usize, DecodeError> {
    if n > MAX_VALUES as u128 {
        return Err(format!(
            "{kind} would make {n} values, more than {MAX_VALUES}"
        ));
    }
    Ok(n as usize)
}

fn step(data: Data, e: &Value, expect: usize) -> Result<Data, DecodeError> {
    let kind = field(e, "kind")
        .and_then(Value::as_str)
        .ok_or("an encoding has no kind")?;
    Ok(Data::Values(match kind {
        "ByteArray" => {
            let Data::Bytes(b) = data else {
                return Err("ByteArray applies to raw bytes only".into());
            };
            let t = num(e, "type", kind)? as i64;
            byte_array(&b, t)?
        }
        "FixedPoint" => {
            let factor = num(e, "factor", kind)?;
            if !(factor.is_finite() && factor != 0.0) {
                return Err(format!("FixedPoint factor {factor}"));
            }
            let v = ints(data, kind)?;
            let digits = (0..=18u32).find(|&d| 10f64.powi(d as i32) == factor);
            match digits {
                Some(digits) => Values::Decimal { ints: v, digits },
                None => Values::Float(v.into_iter().map(|x| x as f64 / factor).collect()),
            }
        }
        "IntervalQuantization" => {
            let (lo, hi) = (num(e, "min", kind)?, num(e, "max", kind)?);
            let steps = num(e, "numSteps", kind)?;
            if !(steps >= 2.0) {
                return Err(format!("IntervalQuantization numSteps {steps}"));
            }
            let d = (hi - lo) / (steps - 1.0);
            let v = ints(data, kind)?;
            Values::Float(v.into_iter().map(|x| lo + d * x as f64).collect())
        }
        "RunLength" => {
            let v = ints(data, kind)?;
            if v.len() % 2 != 0 {
                return Err("RunLength data has an odd length".into());
            }
            let mut total: u128 = 0;
            for p in v.chunks_exact(2) {
                if p[1] < 0 {
                    return Err(format!("RunLength count {}", p[1]));
                }
                total += p[1] as u128;
            }
            let n = check_size(total, kind)?;
            if let Some(src) = field(e, "srcSize").and_then(Value::as_u64)
                && src as u128 != total
            {
                return Err(format!(
                    "RunLength makes {total} values, srcSize says {src}"
                ));
            }
            let mut out = Vec::with_capacity(n);
            for p in v.chunks_exact(2) {
                out.extend(std::iter::repeat_n(p[0], p[1] as usize));
            }
            Values::Int(out)
        }
        "Delta" => {
            let origin = num(e, "origin", kind)? as i64;
            let mut v = ints(data, kind)?;
            let mut acc = origin;
            for x in &mut v {
                acc = acc.wrapping_add(*x);
                *x = acc;
            }
            Values::Int(v)
        }
        "IntegerPacking" => {
            let bytes = num(e, "byteCount", kind)? as i64;
            let unsigned = field(e, "isUnsigned")
                .and_then(Value::as_bool)
                .unwrap_or(false);
            let (upper, lower) = match (bytes, unsigned) {
                (1, true) => (0xFF, i64::MIN),
                (2, true) => (0xFFFF, i64::MIN),
                (1, false) => (0x7F, -0x80),
                (2, false) => (0x7FFF, -0x8000),
                _ => return Err(format!("IntegerPacking byteCount {bytes}")),
            };
            let v = ints(data, kind)?;
            let mut out = Vec::with_capacity(v.len().min(expect.max(1)));
            let mut acc = 0i64;
            for x in v {
                // a limit value continues the number (unsigned: only the upper)
                if x == upper || x == lower {
                    acc = acc.wrapping_add(x);
                    continue;
                }
                out.push(acc.wrapping_add(x));
                acc = 0;
            }
            if let Some(src) = field(e, "srcSize").and_then(Value::as_u64)
                && src as usize != out.len()
            {
                return Err(format!(
                    "IntegerPacking makes {} values, srcSize says {src}",
                    out.len()
                ));
            }
            Values::Int(out)
        }
        "StringArray" => {
            let Data::Bytes(b) = data else {
                return Err("StringArray applies to raw bytes only".into());
            };
            let strings = field(e, "stringData")
                .and_then(Value::as_str)
                .ok_or("StringArray without stringData")?;
            let sub = |key: &str, enc: &str| -> Result<Vec<i64>, DecodeError> {
                let mut d = Data::Bytes(match field(e, key) {
                    Some(Value::Binary(x)) => x.clone(),
                    _ => return Err(format!("StringArray without {key}")),
                });
                let encs = field(e, enc)
                    .and_then(Value::as_array)
                    .ok_or_else(|| format!("StringArray without {enc}"))?;
                for s in encs.iter().rev() {
                    d = step(d, s, expect)?;
                }
                ints(d, "StringArray")
            };
            let offsets = sub("offsets", "offsetEncoding")?;
            let index = {
                let mut d = Data::Bytes(b);
                let encs = field(e, "dataEncoding")
                    .and_then(Value::as_array)
                    .ok_or("StringArray without dataEncoding")?;
                for s in encs.iter().rev() {
                    d = step(d, s, expect)?;
                }
                ints(d, "StringArray")?
            };
            let mut table = Vec::with_capacity(offsets.len().saturating_sub(1));
            for w in offsets.windows(2) {
                let (a, z) = (w[0], w[1]);
                let piece = usize::try_from(a)
                    .ok()
                    .zip(usize::try_from(z).ok())
                    .filter(|(a, z)| a <= z)
                    .and_then(|(a, z)| strings.get(a..z))
                    .ok_or_else(|| format!("StringArray offsets {a}..{z} outside its strings"))?;
                table.push(piece.to_string());
            }
            if let Some(&bad) = index.iter().find(|&&i| i >= table.len() as i64) {
                return Err(format!(
                    "StringArray index {bad} past its {} strings",
                    table.len()
                ));
            }
            Values::Str { table, index }
        }
        other => return Err(format!("unknown encoding '{other}'")),
    }))
}

/// A little-endian array of the ByteArray type code.
fn byte_array(b: &[u8], t: i64) -> Result<Values, DecodeError> {
    fn each<const N: usize, T>(b: &[u8], f: impl Fn([u8; N]) -> T) -> Result<Vec<T>, DecodeError> {
        if !b.len().is_multiple_of(N) {
            return Err(format!(
                "ByteArray of {} bytes is not a whole number of {N}-byte values",
                b.len()
            ));
        }
        Ok(b.chunks_exact(N)
            .map(|c| f(c.try_into().unwrap_or([0; N])))
            .collect())
    }
    Ok(match t {
        1 => Values::Int(each::<1, _>(b, |c| i8::from_le_bytes(c) as i64)?),
        2 => Values::Int(each::<2, _>(b, |c| i16::from_le_bytes(c) as i64)?),
        3 => Values::Int(each::<4, _>(b, |c| i32::from_le_bytes(c) as i64)?),
        4 => Values::Int(each::<1, _>(b, |c| c[0] as i64)?),
        5 => Values::Int(each::<2, _>(b, |c| u16::from_le_bytes(c) as i64)?),
        6 => Values::Int(each::<4, _>(b, |c| u32::from_le_bytes(c) as i64)?),
        32 => Values::Float(each::<4, _>(b, |c| f32::from_le_bytes(c) as f64)?),
        33 => Values::Float(each::<8, _>(b, f64::from_le_bytes)?),
        _ => return Err(format!("unknown ByteArray type {t}")),
    })
}

#[cfg(test)]
mod tests;
