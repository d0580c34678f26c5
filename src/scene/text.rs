//! Byte-level text helpers shared by the parsers: line iteration, a fast
//! fixed-format float parser, and progress reporting.

/// Iterates over the lines of a byte buffer, yielding `(line_number,
/// byte_offset_of_line_end, line)` with 1-based line numbers. A trailing
/// `\r` is removed so CRLF files parse like LF files.
pub(crate) struct Lines<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Lines<'a> {
    pub(crate) fn new(data: &'a [u8]) -> Self {
        Lines {
            data,
            pos: 0,
            line: 0,
        }
    }
}

impl<'a> Iterator for Lines<'a> {
    type Item = (usize, usize, &'a [u8]);

    fn next(&mut self) -> Option<Self::Item> {
        if self.pos >= self.data.len() {
            return None;
        }
        let rest = &self.data[self.pos..];
        let (mut line, advance) = match find_byte(rest, b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        if let [head @ .., b'\r'] = line {
            line = head;
        }
        self.pos += advance;
        self.line += 1;
        Some((self.line, self.pos, line))
    }
}

/// Position of the first `needle` in `hay`, eight bytes at a time (the
/// line scan is a large share of parse time for big files).
pub(crate) fn find_byte(hay: &[u8], needle: u8) -> Option<usize> {
    const LO: u64 = 0x0101_0101_0101_0101;
    const HI: u64 = 0x8080_8080_8080_8080;
    let pattern = LO * u64::from(needle);
    let chunks = hay.chunks_exact(8);
    let tail = chunks.remainder();
    for (i, chunk) in chunks.enumerate() {
        let mut word = [0u8; 8];
        word.copy_from_slice(chunk);
        let x = u64::from_le_bytes(word) ^ pattern;
        // Classic "has a zero byte" test; the lowest flagged byte is exact.
        let found = x.wrapping_sub(LO) & !x & HI;
        if found != 0 {
            return Some(i * 8 + (found.trailing_zeros() / 8) as usize);
        }
    }
    let base = hay.len() - tail.len();
    tail.iter().position(|&b| b == needle).map(|p| base + p)
}

const POW10: [f64; 19] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18,
];

/// Parses a decimal number such as the `%8.3f` coordinate fields of PDB and
/// GRO files, surrounded by optional blanks. Plain `[-+]ddd.ddd` takes a
/// fast integer path; anything else (exponents, long mantissas) goes through
/// `str::parse`. Returns `None` for malformed or non-finite values ("nan"
/// and "inf" parse in Rust, but are never valid coordinates).
pub(crate) fn parse_f32(field: &[u8]) -> Option<f32> {
    let n = field.len();
    let mut i = 0;
    while i < n && field[i] == b' ' {
        i += 1;
    }
    let neg = i < n && field[i] == b'-';
    if i < n && (field[i] == b'-' || field[i] == b'+') {
        i += 1;
    }
    let mut mant: u64 = 0;
    let digits_start = i;
    while i < n && field[i].is_ascii_digit() {
        mant = mant
            .wrapping_mul(10)
            .wrapping_add(u64::from(field[i] - b'0'));
        i += 1;
    }
    let mut n_digits = i - digits_start;
    let mut frac = 0;
    if i < n && field[i] == b'.' {
        i += 1;
        let frac_start = i;
        while i < n && field[i].is_ascii_digit() {
            mant = mant
                .wrapping_mul(10)
                .wrapping_add(u64::from(field[i] - b'0'));
            i += 1;
        }
        frac = i - frac_start;
        n_digits += frac;
    }
    while i < n && field[i] == b' ' {
        i += 1;
    }
    // At most 18 digits cannot overflow u64 and divide exactly by 10^frac.
    if i == n && (1..=18).contains(&n_digits) {
        let v = (mant as f64 / POW10[frac]) as f32;
        return Some(if neg { -v } else { v });
    }
    let v: f32 = std::str::from_utf8(super::elements::trim(field))
        .ok()?
        .parse()
        .ok()?;
    v.is_finite().then_some(v)
}

/// Splits a line on ASCII whitespace into `out` (cleared first).
pub(crate) fn split_ws<'a>(line: &'a [u8], out: &mut Vec<&'a [u8]>) {
    out.clear();
    out.extend(
        line.split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty()),
    );
}

/// Shows a field in an error message (lossy, length-limited).
pub(crate) fn show(field: &[u8]) -> String {
    let s = String::from_utf8_lossy(field);
    let s = s.trim();
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.to_string()
    }
}

/// Calls the caller's progress callback about every 1 % of the input.
pub(crate) struct Progress<'a> {
    cb: &'a mut dyn FnMut(u64, u64),
    total: u64,
    step: u64,
    next: u64,
}

impl<'a> Progress<'a> {
    pub(crate) fn new(cb: &'a mut dyn FnMut(u64, u64), total: usize) -> Self {
        let total = total as u64;
        let step = (total / 100).max(1);
        Progress {
            cb,
            total,
            step,
            next: step,
        }
    }

    /// Reports `done` bytes if another ~1 % has passed. Cheap otherwise.
    #[inline]
    pub(crate) fn tick(&mut self, done: usize) {
        let done = done as u64;
        if done >= self.next {
            (self.cb)(done.min(self.total), self.total);
            self.next = done + self.step;
        }
    }

    pub(crate) fn finish(&mut self) {
        (self.cb)(self.total, self.total);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_fields() {
        assert_eq!(parse_f32(b"  42.053"), Some(42.053));
        assert_eq!(parse_f32(b" -10.253"), Some(-10.253));
        assert_eq!(parse_f32(b"131.128 "), Some(131.128));
        assert_eq!(parse_f32(b"-0.841"), Some(-0.841));
        assert_eq!(parse_f32(b"+1.5"), Some(1.5));
        assert_eq!(parse_f32(b"7"), Some(7.0));
        assert_eq!(parse_f32(b"7."), Some(7.0));
        assert_eq!(parse_f32(b".5"), Some(0.5));
        assert_eq!(parse_f32(b"1.5e2"), Some(150.0));
        assert_eq!(parse_f32(b"-2E-1"), Some(-0.2));
        assert_eq!(parse_f32(b"1234567.8901234567890"), Some(1234567.9));
        assert_eq!(parse_f32(b""), None);
        assert_eq!(parse_f32(b"    "), None);
        assert_eq!(parse_f32(b"-"), None);
        assert_eq!(parse_f32(b"."), None);
        assert_eq!(parse_f32(b"1.2.3"), None);
        assert_eq!(parse_f32(b"12a.0"), None);
        assert_eq!(parse_f32(b"nan"), None);
        assert_eq!(parse_f32(b"NaN"), None);
        assert_eq!(parse_f32(b"inf"), None);
        assert_eq!(parse_f32(b"-infinity"), None);
        assert_eq!(parse_f32(b"1e39"), None);
        assert_eq!(parse_f32(b"\xff\xfe"), None);
        // The fast path agrees with the standard library on %8.3f values.
        for i in (-999_999i32..=999_999).step_by(7919) {
            let s = format!("{:8.3}", f64::from(i) / 1000.0);
            assert_eq!(parse_f32(s.as_bytes()), s.trim().parse::<f32>().ok(), "{s}");
        }
    }

    #[test]
    fn find_byte_matches_position() {
        let mut data = Vec::new();
        for i in 0..300u32 {
            data.push((i * 37 % 251) as u8);
        }
        for needle in [0u8, 10, 37, 128, 200, 255] {
            for start in 0..40 {
                let hay = &data[start..];
                assert_eq!(
                    find_byte(hay, needle),
                    hay.iter().position(|&b| b == needle),
                    "{needle} {start}"
                );
            }
        }
        assert_eq!(find_byte(b"", b'a'), None);
        assert_eq!(
            find_byte(b"\x01\x01\x01\x01\x01\x01\x01\x00\n", b'\n'),
            Some(8)
        );
        assert_eq!(
            find_byte(b"\x00\x00\x01\x01\x01\x01\x01\x0a", b'\n'),
            Some(7)
        );
    }

    #[test]
    fn lines_strip_cr() {
        let v: Vec<_> = Lines::new(b"a\r\nbb\n\nc")
            .map(|(n, _, l)| (n, l))
            .collect();
        assert_eq!(
            v,
            vec![
                (1, &b"a"[..]),
                (2, &b"bb"[..]),
                (3, &b""[..]),
                (4, &b"c"[..])
            ]
        );
    }

    #[test]
    fn progress_steps() {
        let mut calls = Vec::new();
        let mut cb = |d, t| calls.push((d, t));
        let mut p = Progress::new(&mut cb, 1000);
        for i in 0..=1000 {
            p.tick(i);
        }
        p.finish();
        assert_eq!(calls.len(), 101);
        assert_eq!(calls.last(), Some(&(1000, 1000)));
    }
}
