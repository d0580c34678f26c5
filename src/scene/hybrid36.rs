//! Hybrid-36 numbers (Grosse-Kunstleve et al.), used by PDB writers for
//! serials past 99,999 and residue numbers past 9,999: decimal while it
//! fits, then upper-case base 36 starting at "A000..", then lower-case
//! base 36 starting at "a000..".

fn pow(base: i64, exp: usize) -> i64 {
    (0..exp).fold(1i64, |acc, _| acc.saturating_mul(base))
}

/// Decodes a hybrid-36 field of the given width (blanks allowed around it).
/// Returns `None` for malformed input instead of failing.
pub fn decode(width: usize, field: &[u8]) -> Option<i64> {
    let s = super::elements::trim(field);
    let first = *s.first()?;
    if width == 0 || s.len() > width {
        return None;
    }
    if first.is_ascii_digit() || first == b'-' || first == b'+' {
        return std::str::from_utf8(s).ok()?.parse::<i64>().ok();
    }
    // Letter-led values always use the full width.
    if s.len() != width {
        return None;
    }
    let upper = first.is_ascii_uppercase();
    if !upper && !first.is_ascii_lowercase() {
        return None;
    }
    let mut v: i64 = 0;
    for &b in s {
        let d = match b {
            b'0'..=b'9' => b - b'0',
            b'A'..=b'Z' if upper => b - b'A' + 10,
            b'a'..=b'z' if !upper => b - b'a' + 10,
            _ => return None,
        };
        v = v.checked_mul(36)?.checked_add(i64::from(d))?;
    }
    let block = pow(36, width - 1);
    let base = v - 10 * block + pow(10, width);
    Some(if upper { base } else { base + 26 * block })
}

/// Encodes `value` in hybrid-36 with the given width (right-justified
/// decimal when it fits). `None` if it does not fit at all.
pub fn encode(width: usize, value: i64) -> Option<String> {
    if width == 0 {
        return None;
    }
    let dec_max = pow(10, width);
    let dec_min = -pow(10, width - 1);
    if value >= dec_min && value < dec_max {
        return Some(format!("{value:>width$}"));
    }
    if value < 0 {
        return None;
    }
    let block = pow(36, width - 1);
    let mut rest = value - dec_max;
    let upper = rest < 26 * block;
    if !upper {
        rest -= 26 * block;
        if rest >= 26 * block {
            return None;
        }
    }
    let mut v = rest + 10 * block;
    let digits: &[u8; 36] = if upper {
        b"0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    } else {
        b"0123456789abcdefghijklmnopqrstuvwxyz"
    };
    let mut out = vec![b'0'; width];
    for slot in out.iter_mut().rev() {
        *slot = digits[(v % 36) as usize];
        v /= 36;
    }
    String::from_utf8(out).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimal_range() {
        assert_eq!(decode(5, b"    1"), Some(1));
        assert_eq!(decode(5, b"99999"), Some(99_999));
        assert_eq!(decode(4, b"  -5"), Some(-5));
        assert_eq!(decode(4, b"9999"), Some(9999));
    }

    #[test]
    fn letter_blocks() {
        // Reference values from the hybrid-36 paper / iotbx.
        assert_eq!(decode(5, b"A0000"), Some(100_000));
        assert_eq!(decode(5, b"A0001"), Some(100_001));
        assert_eq!(decode(5, b"ZZZZZ"), Some(43_770_015));
        assert_eq!(decode(5, b"a0000"), Some(43_770_016));
        assert_eq!(decode(5, b"zzzzz"), Some(87_440_031));
        assert_eq!(decode(4, b"A000"), Some(10_000));
        assert_eq!(decode(4, b"ZZZZ"), Some(1_223_055));
        assert_eq!(decode(4, b"a000"), Some(1_223_056));
        // The last serial of pdb1tw7_..._h36.pdb.
        assert_eq!(decode(5, b"A00GA"), Some(100_586));
    }

    #[test]
    fn malformed_is_none() {
        assert_eq!(decode(5, b"     "), None);
        assert_eq!(decode(5, b"A00"), None);
        assert_eq!(decode(5, b"Aa000"), None);
        assert_eq!(decode(5, b"A0-00"), None);
        assert_eq!(decode(4, b"12x4"), None);
        assert_eq!(decode(4, b"\xff000"), None);
    }

    #[test]
    fn round_trip() {
        for &w in &[4usize, 5] {
            for v in [
                0i64, 1, 9999, 10_000, 99_999, 100_000, 123_456, 1_223_055, 1_223_056, 5_000_000,
            ] {
                if let Some(s) = encode(w, v) {
                    assert_eq!(s.len(), w);
                    assert_eq!(decode(w, s.as_bytes()), Some(v), "{w} {v} {s}");
                }
            }
        }
        assert_eq!(encode(5, 100_000).as_deref(), Some("A0000"));
        assert_eq!(encode(4, 2_446_112), None);
    }
}
