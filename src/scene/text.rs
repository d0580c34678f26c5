//! Byte-level text helpers shared by the parsers: streaming line input
//! with bounded memory, a fast fixed-format float parser, and progress
//! reporting.

use std::io::BufRead;

use super::SceneError;

/// Longest line accepted (bytes): far above any real PDB/mmCIF/GRO/XYZ
/// line, and what bounds a reader's memory on a file without newlines
/// (e.g. `/dev/zero` or a gzip bomb of one byte value).
pub(crate) const MAX_LINE_BYTES: usize = 1 << 20;

/// Lines of a (possibly decompressed) text stream, read with bounded
/// memory: one line at a time (at most [`MAX_LINE_BYTES`]), 1-based line
/// numbers, a trailing `\r` removed (CRLF files parse like LF files), a
/// UTF-8 byte-order mark at the start skipped, NUL bytes refused (text
/// formats never contain them: binary garbage gets one clear message).
/// Progress is reported from the raw (compressed) bytes consumed.
pub(crate) struct LineSource<'a> {
    reader: Box<dyn BufRead + 'a>,
    name: String,
    buf: Vec<u8>,
    line: usize,
    /// Bytes of decompressed text consumed so far.
    offset: u64,
    /// The last line returned ended at end of input without a newline.
    unterminated: bool,
    raw_done: std::rc::Rc<std::cell::Cell<u64>>,
    raw_total: u64,
    progress: Progress<'a>,
}

/// One line: (1-based number, text without the line end, whether it ended
/// the input without a newline).
pub(crate) type Line<'a> = (usize, &'a [u8], bool);

/// Counts the raw bytes read through it (compressed input's progress).
pub(crate) struct Counting<R> {
    pub inner: R,
    pub done: std::rc::Rc<std::cell::Cell<u64>>,
}

impl<R: std::io::Read> std::io::Read for Counting<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(out)?;
        self.done.set(self.done.get() + n as u64);
        Ok(n)
    }
}

impl<'a> LineSource<'a> {
    /// `raw_done` counts the raw bytes consumed (of `raw_total`).
    pub(crate) fn new(
        reader: Box<dyn BufRead + 'a>,
        name: &str,
        raw_done: std::rc::Rc<std::cell::Cell<u64>>,
        raw_total: u64,
        progress: &'a mut dyn FnMut(u64, u64),
    ) -> Self {
        LineSource {
            reader,
            name: name.to_string(),
            buf: Vec::with_capacity(256),
            line: 0,
            offset: 0,
            unterminated: false,
            raw_done,
            raw_total,
            progress: Progress::new(progress, raw_total as usize),
        }
    }

    /// A source over bytes in memory (tests, embedded data).
    pub(crate) fn from_bytes(
        data: &'a [u8],
        name: &str,
        progress: &'a mut dyn FnMut(u64, u64),
    ) -> Self {
        let done = std::rc::Rc::new(std::cell::Cell::new(0));
        let counting = Counting {
            inner: data,
            done: done.clone(),
        };
        Self::new(
            Box::new(std::io::BufReader::with_capacity(1 << 16, counting)),
            name,
            done,
            data.len() as u64,
            progress,
        )
    }

    /// Raw input size in bytes (a capacity hint; the compressed size for
    /// gzip input).
    pub(crate) fn raw_size(&self) -> usize {
        self.raw_total as usize
    }

    /// The next line: (line number, text, whether it ended the input
    /// without a newline: a data record there may have been cut short), or
    /// None at the end of the input.
    #[allow(clippy::should_implement_trait)]
    pub(crate) fn next(&mut self) -> Result<Option<Line<'_>>, SceneError> {
        self.buf.clear();
        loop {
            let avail = match self.reader.fill_buf() {
                Ok(a) => a,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    return Err(SceneError::Invalid(format!(
                        "{}:{}: cannot read: {e}",
                        self.name,
                        self.line + 1
                    )));
                }
            };
            if avail.is_empty() {
                break;
            }
            let (take, done) = match find_byte(avail, b'\n') {
                Some(i) => (i + 1, true),
                None => (avail.len(), false),
            };
            if self.buf.len() + take > MAX_LINE_BYTES + 1 {
                return Err(SceneError::Invalid(format!(
                    "{}:{}: line longer than {} bytes: not a text structure file",
                    self.name,
                    self.line + 1,
                    MAX_LINE_BYTES
                )));
            }
            self.buf.extend_from_slice(&avail[..take]);
            self.reader.consume(take);
            if done {
                break;
            }
        }
        if self.buf.is_empty() {
            self.progress.finish();
            return Ok(None);
        }
        self.line += 1;
        self.offset += self.buf.len() as u64;
        self.progress.tick(self.raw_done.get() as usize);
        let mut line = &self.buf[..];
        self.unterminated = true;
        if let [head @ .., b'\n'] = line {
            line = head;
            self.unterminated = false;
        }
        if let [head @ .., b'\r'] = line {
            line = head;
        }
        if self.line == 1
            && let Some(rest) = line.strip_prefix(b"\xEF\xBB\xBF")
        {
            line = rest;
        }
        if find_byte(line, 0).is_some() {
            return Err(SceneError::Invalid(format!(
                "{}:{}: binary data (NUL byte), not a text structure file",
                self.name, self.line
            )));
        }
        Ok(Some((self.line, line, self.unterminated)))
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
        // (unknown size, e.g. a pipe: only the end is reported)
        if self.total > 0 && done >= self.next {
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

    fn all_lines(data: &[u8]) -> Result<Vec<(usize, Vec<u8>, bool)>, SceneError> {
        let mut cb = |_, _| {};
        let mut src = LineSource::from_bytes(data, "t", &mut cb);
        let mut v = Vec::new();
        while let Some((n, l, cut)) = src.next()? {
            v.push((n, l.to_vec(), cut));
        }
        Ok(v)
    }

    #[test]
    fn lines_strip_cr_bom_and_flag_the_unterminated_last() {
        let v = all_lines(b"\xEF\xBB\xBFa\r\nbb\n\nc").unwrap();
        let want: Vec<(usize, Vec<u8>, bool)> = vec![
            (1, b"a".to_vec(), false),
            (2, b"bb".to_vec(), false),
            (3, b"".to_vec(), false),
            (4, b"c".to_vec(), true),
        ];
        assert_eq!(v, want);
        // a BOM only counts at the very start
        assert_eq!(
            all_lines(b"x\n\xEF\xBB\xBFy\n").unwrap()[1].1,
            b"\xEF\xBB\xBFy"
        );
        assert!(all_lines(b"").unwrap().is_empty());
    }

    #[test]
    fn lines_refuse_nul_and_endless_lines() {
        let e = all_lines(b"ok\nbad\0line\n").unwrap_err().to_string();
        assert!(e.contains("t:2:") && e.contains("NUL"), "{e}");
        let long = vec![b'x'; MAX_LINE_BYTES + 10];
        let e = all_lines(&long).unwrap_err().to_string();
        assert!(e.contains("t:1:") && e.contains("longer than"), "{e}");
        // exactly the limit is fine
        let mut ok = vec![b'x'; MAX_LINE_BYTES];
        ok.push(b'\n');
        assert_eq!(all_lines(&ok).unwrap().len(), 1);
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
