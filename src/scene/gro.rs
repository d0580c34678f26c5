//! GROMACS .gro reader: title, atom count, fixed-column atom lines
//! (residue number 5, residue name 5, atom name 5, atom number 5, then x y z
//! in nm), box line. Several frames in one file are models.

use super::atoms::{AtomInfo, Known};
use super::elements::{self, trim};
use super::molecule::{AtomKeys, MolBuilder, key64};
use super::text::{LineSource, parse_f32, show, split_ws};
use super::{
    LoadOptions, MAX_SPHERES, ModelSelect, Scene, SceneError, check_coordinate, parse_error,
    too_many, truncated,
};

pub(crate) fn parse(
    src: &mut LineSource,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let mut builder = MolBuilder::new((src.raw_size() / 45 + 1).min(MAX_SPHERES), false);
    builder.set_known(Known {
        residue: true,
        name: true,
        element: true,
        ..Known::default()
    });
    let mut frame = 0u32;
    // Title line; blank lines after the last frame are allowed.
    while let Some((title_no, title, _)) = src.next()? {
        if title.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        frame += 1;
        let (count_no, count_line, _) = src
            .next()?
            .ok_or_else(|| parse_error(name, title_no + 1, "missing atom count line"))?;
        let mut last_line = count_no;
        let count: usize = std::str::from_utf8(count_line)
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .ok_or_else(|| {
                parse_error(
                    name,
                    count_no,
                    format!("bad atom count '{}'", show(count_line)),
                )
            })?;
        let (accept, level0) = match opts.model {
            ModelSelect::First => (frame == 1, 0),
            ModelSelect::Index(n) => (frame == n, 0),
            ModelSelect::All => (true, frame - 1),
        };
        // Field width of the coordinates: "%8.3f" normally, but GROMACS may
        // write more decimals (width = decimals + 5); the distance between
        // the first two decimal points gives it.
        let mut width = 0usize;
        for i in 0..count {
            let (line_no, line, cut) = src.next()?.ok_or_else(|| {
                parse_error(
                    name,
                    last_line + 1,
                    format!("file ends after {i} of {count} atoms"),
                )
            })?;
            last_line = line_no;
            if !accept {
                continue;
            }
            if width == 0 {
                width = coordinate_width(line);
            }
            if line.len() < 20 + 3 * width {
                return Err(parse_error(
                    name,
                    line_no,
                    format!(
                        "truncated atom line ({} characters, expected at least {})",
                        line.len(),
                        20 + 3 * width
                    ),
                ));
            }
            let mut center = [0.0f32; 3];
            for (k, (slot, axis)) in center.iter_mut().zip(["x", "y", "z"]).enumerate() {
                let field = &line[20 + k * width..20 + (k + 1) * width];
                let v = parse_f32(field).map(|v| v * 10.0).ok_or_else(|| {
                    parse_error(
                        name,
                        line_no,
                        format!("bad {axis} coordinate '{}'", show(field)),
                    )
                })?;
                *slot = check_coordinate(v, axis, name, line_no)?;
            }
            let element = elements::guess_name(&line[10..15], &line[5..10]);
            // Residue number + name, as written (numbers wrap at 100,000).
            let residue = key64(&[&line[..10]]);
            if cut {
                return Err(truncated(name, line_no));
            }
            if builder.len() >= MAX_SPHERES {
                return Err(too_many(name, line_no));
            }
            builder.push(
                center,
                element,
                AtomKeys {
                    level0,
                    chain: 0,
                    residue: u128::from(residue),
                    asm_chain: b"",
                    entity: b"",
                    info: AtomInfo {
                        resname: trim(&line[5..10]),
                        resid: std::str::from_utf8(trim(&line[..5]))
                            .ok()
                            .and_then(|v| v.parse().ok())
                            .unwrap_or(0),
                        name: trim(&line[10..15]),
                        ..Default::default()
                    },
                },
            );
        }
        // Box line (absent in some hand-written files): three or nine
        // numbers. An atom line here means the count was too small.
        match src.next()? {
            None => break,
            Some((box_no, line, _)) => {
                let mut toks = Vec::new();
                split_ws(line, &mut toks);
                let numbers = toks.iter().all(|t| parse_f32(t).is_some());
                if !(numbers && (toks.len() == 3 || toks.len() == 9)) && !toks.is_empty() {
                    return Err(parse_error(
                        name,
                        box_no,
                        format!(
                            "expected the box line after the {count} atoms the count on line \
                             {count_no} announced, found '{}' (does the count match the atom lines?)",
                            show(line)
                        ),
                    ));
                }
            }
        }
        if opts.model == ModelSelect::First && frame == 1 {
            break;
        }
        if let ModelSelect::Index(n) = opts.model
            && frame >= n
        {
            break;
        }
    }
    if let ModelSelect::Index(n) = opts.model
        && frame < n
    {
        return Err(SceneError::Invalid(format!(
            "{name}: frame {n} not found (the file has {frame})"
        )));
    }
    builder.finish(name, opts.color_by, None)
}

/// Width of one coordinate field, from the spacing of decimal points.
fn coordinate_width(line: &[u8]) -> usize {
    let rest = line.get(20..).unwrap_or(b"");
    let mut dots = rest
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == b'.')
        .map(|(i, _)| i);
    match (dots.next(), dots.next()) {
        (Some(a), Some(b)) if (6..=20).contains(&(b - a)) => b - a,
        _ => 8,
    }
}

#[cfg(test)]
mod tests {
    use super::super::elements::Element;
    use super::super::{Format, parse_str};
    use super::*;

    const GRO: &str = "\
Test water box
    5
    1SOL     OW    1   0.126   1.624   1.679
    1SOL    HW1    2   0.190   1.661   1.747
    1SOL    HW2    3   0.177   1.568   1.613
    2NA      NA    4   1.000   2.000   3.000
    3CL      CL    5  -1.000  -2.000  -3.000
   1.86206   1.86206   1.86206
";

    fn load(text: &str, opts: &LoadOptions) -> Result<Scene, SceneError> {
        parse_str(text, Format::Gro, "t.gro", opts)
    }

    #[test]
    fn reads_atoms_in_angstrom() {
        let s = load(GRO, &LoadOptions::default()).unwrap();
        assert_eq!(s.spheres.len(), 5);
        let c = s.spheres[0].center;
        assert!(
            (c[0] - 1.26).abs() < 1e-5
                && (c[1] - 16.24).abs() < 1e-5
                && (c[2] - 16.79).abs() < 1e-5
        );
        assert_eq!(s.spheres[0].radius, Element::O.radius());
        assert_eq!(s.spheres[1].radius, Element::H.radius());
        assert_eq!(s.spheres[3].radius, Element::NA.radius());
        assert_eq!(s.spheres[4].radius, Element::CL.radius());
        let res: Vec<u32> = s.spheres.iter().map(|s| s.region[2]).collect();
        assert_eq!(res, vec![0, 0, 0, 1, 2]);
    }

    #[test]
    fn high_precision_and_frames() {
        let text = "\
t
 1
    1SOL     OW    1   0.12600   1.62400   1.67900
 1 1 1
t2
 1
    1SOL     OW    1   0.22600   1.62400   1.67900
 1 1 1

";
        let s = load(text, &LoadOptions::default()).unwrap();
        assert_eq!(s.spheres.len(), 1);
        assert!((s.spheres[0].center[0] - 1.26).abs() < 1e-6);
        let all = LoadOptions {
            model: ModelSelect::All,
            ..LoadOptions::default()
        };
        let s = load(text, &all).unwrap();
        assert_eq!(s.spheres.len(), 2);
        assert_eq!(s.spheres[1].region[0], 1);
        let two = LoadOptions {
            model: ModelSelect::Index(2),
            ..LoadOptions::default()
        };
        let s = load(text, &two).unwrap();
        assert!((s.spheres[0].center[0] - 2.26).abs() < 1e-6);
        let three = LoadOptions {
            model: ModelSelect::Index(3),
            ..LoadOptions::default()
        };
        assert!(matches!(load(text, &three), Err(SceneError::Invalid(_))));
    }

    #[test]
    fn malformed() {
        let err = |t: &str| load(t, &LoadOptions::default()).unwrap_err();
        assert!(matches!(err("t\nabc\n"), SceneError::Parse { line: 2, .. }));
        assert!(matches!(err("t\n"), SceneError::Parse { line: 2, .. }));
        // Count says 3, the file ends after 2 atoms.
        let short = "t\n 3\n    1SOL     OW    1   0.126   1.624   1.679\n    1SOL    HW1    2   0.190   1.661   1.747\n";
        assert!(matches!(err(short), SceneError::Parse { line: 5, .. }));
        assert!(matches!(
            err("t\n 1\n    1SOL     OW    1   0.126   1.624\n"),
            SceneError::Parse { line: 3, .. }
        ));
        assert!(matches!(
            err("t\n 1\n    1SOL     OW    1   0.126     nan   1.679\n"),
            SceneError::Parse { line: 3, .. }
        ));
        assert!(matches!(err("t\n 0\n 1 1 1\n"), SceneError::Empty { .. }));
    }
}
