//! XYZ (count, comment, `El x y z` lines; frames are models) and XYZR
//! (`x y z r [region ids...]`, `#` comments, radii used as given).

use super::elements::{self, Element};
use super::molecule::palette_color;
use super::text::{LineSource, parse_f32, show, split_ws};
use super::{
    LoadOptions, MAX_LEVELS, MAX_SPHERES, ModelSelect, Scene, SceneError, Sphere, check_coordinate,
    check_radius, parse_error, too_many, truncated,
};

pub(crate) fn parse_xyz(
    src: &mut LineSource,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let mut spheres = Vec::new();
    let mut atoms = super::atoms::Atoms::new(super::atoms::Known {
        element: true,
        ..Default::default()
    });
    let mut frame = 0u32;
    // (line of the last frame's count, the count)
    let mut last_count: Option<(usize, usize)> = None;
    while let Some((count_no, count_line, _)) = src.next()? {
        if count_line.iter().all(u8::is_ascii_whitespace) {
            continue; // blank lines between or after frames
        }
        let count: usize = match std::str::from_utf8(count_line)
            .ok()
            .and_then(|s| s.trim().parse().ok())
        {
            Some(c) => c,
            None => {
                let msg = match last_count {
                    // An atom line where the next frame's count should be:
                    // the previous count was too small.
                    Some((at, n)) if looks_like_atom(count_line) => format!(
                        "an atom line after the {n} atoms the count on line {at} announced \
                         (the count does not match the atom lines)"
                    ),
                    _ => format!("bad atom count '{}'", show(count_line)),
                };
                return Err(parse_error(name, count_no, msg));
            }
        };
        let done_before = match opts.model {
            ModelSelect::First => frame >= 1,
            ModelSelect::Index(n) => frame >= n,
            ModelSelect::All => false,
        };
        if done_before {
            // The frame after the selected one starts properly: stop.
            break;
        }
        frame += 1;
        last_count = Some((count_no, count));
        // Comment line (may be empty).
        let mut last_line = src.next()?.map_or(count_no, |(n, _, _)| n);
        let (accept, level0) = match opts.model {
            ModelSelect::First => (frame == 1, 0),
            ModelSelect::Index(n) => (frame == n, 0),
            ModelSelect::All => (true, frame - 1),
        };
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
            let mut toks = Vec::with_capacity(8);
            split_ws(line, &mut toks);
            if toks.len() < 4 {
                return Err(parse_error(
                    name,
                    line_no,
                    format!("expected 'element x y z', found {} fields", toks.len()),
                ));
            }
            let center = coords(&toks[1..4], name, line_no)?;
            let element = Element::from_symbol_or_number(toks[0])
                .unwrap_or_else(|| elements::guess_name(toks[0], b""));
            if cut {
                return Err(truncated(name, line_no));
            }
            if spheres.len() >= MAX_SPHERES {
                return Err(too_many(name, line_no));
            }
            let index = spheres.len() as u32;
            spheres.push(Sphere {
                center,
                radius: element.radius(),
                color: element.color(),
                region: [level0, index, 0, 0],
            });
            atoms.push(element, &Default::default());
        }
    }
    if let ModelSelect::Index(n) = opts.model
        && frame < n
    {
        return Err(SceneError::Invalid(format!(
            "{name}: frame {n} not found (the file has {frame})"
        )));
    }
    Ok(Scene {
        spheres,
        level_names: vec!["model".into(), "atom".into()],
        source: name.to_string(),
        instancing: None,
        expanded: false,
        atoms: Some(atoms),
        origin: None,
    })
}

/// `El x y z ...`: at least four fields, the second to fourth numbers.
fn looks_like_atom(line: &[u8]) -> bool {
    let mut toks = Vec::new();
    split_ws(line, &mut toks);
    toks.len() >= 4 && toks[1..4].iter().all(|t| parse_f32(t).is_some())
}

fn coords(toks: &[&[u8]], name: &str, line_no: usize) -> Result<[f32; 3], SceneError> {
    let mut c = [0.0f32; 3];
    for ((slot, tok), axis) in c.iter_mut().zip(toks).zip(["x", "y", "z"]) {
        let v = parse_f32(tok).ok_or_else(|| {
            parse_error(
                name,
                line_no,
                format!("bad {axis} coordinate '{}'", show(tok)),
            )
        })?;
        *slot = check_coordinate(v, axis, name, line_no)?;
    }
    Ok(c)
}

/// Colour for XYZR spheres without elements.
const XYZR_COLOR: [u8; 4] = [0xB4, 0xBE, 0xD2, 0xFF];

pub(crate) fn parse_xyzr(src: &mut LineSource, name: &str) -> Result<Scene, SceneError> {
    let mut spheres = Vec::with_capacity((src.raw_size() / 32 + 1).min(MAX_SPHERES));
    let mut levels = 0usize;
    while let Some((line_no, line, cut)) = src.next()? {
        let mut toks = Vec::with_capacity(4 + MAX_LEVELS);
        let content = match line.iter().position(|&b| b == b'#') {
            Some(i) => &line[..i],
            None => line,
        };
        split_ws(content, &mut toks);
        if toks.is_empty() {
            continue;
        }
        if toks.len() < 4 {
            return Err(parse_error(
                name,
                line_no,
                format!(
                    "expected 'x y z r [region ids]', found {} fields",
                    toks.len()
                ),
            ));
        }
        if toks.len() > 4 + MAX_LEVELS {
            return Err(parse_error(
                name,
                line_no,
                format!(
                    "at most {MAX_LEVELS} region columns after x y z r, found {}",
                    toks.len() - 4
                ),
            ));
        }
        let center = coords(&toks[..3], name, line_no)?;
        let radius = parse_f32(toks[3]).filter(|r| *r > 0.0).ok_or_else(|| {
            parse_error(
                name,
                line_no,
                format!(
                    "bad radius '{}' (must be a finite number > 0)",
                    show(toks[3])
                ),
            )
        })?;
        let radius = check_radius(radius, name, line_no)?;
        let mut region = [0u32; MAX_LEVELS];
        for (slot, tok) in region.iter_mut().zip(&toks[4..]) {
            *slot = std::str::from_utf8(tok)
                .ok()
                .and_then(|s| s.parse::<u32>().ok())
                .ok_or_else(|| {
                    parse_error(
                        name,
                        line_no,
                        format!("bad region id '{}' (expected an integer >= 0)", show(tok)),
                    )
                })?;
        }
        if cut && content.len() == line.len() {
            return Err(truncated(name, line_no));
        }
        if spheres.len() >= MAX_SPHERES {
            return Err(too_many(name, line_no));
        }
        levels = levels.max(toks.len() - 4);
        spheres.push(Sphere {
            center,
            radius,
            color: XYZR_COLOR,
            region,
        });
    }
    Ok(xyzr_scene(spheres, levels, name))
}

/// The scene of `.xyzr` spheres with `levels` region columns: coloured by
/// the second level when there is one (chain-like), else the first, so
/// region structure is visible; one colour without levels.
pub(crate) fn xyzr_scene(mut spheres: Vec<Sphere>, levels: usize, name: &str) -> Scene {
    if levels > 0 {
        let level = levels.min(2) - 1;
        for s in &mut spheres {
            s.color = palette_color(s.region[level]);
        }
    } else {
        for s in &mut spheres {
            s.color = XYZR_COLOR;
        }
    }
    Scene {
        spheres,
        level_names: (0..levels).map(|i| format!("level{i}")).collect(),
        source: name.to_string(),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    }
}

/// Spheres from arrays (the Python module): centres, radii, optional RGBA
/// colours and region ids (`levels` per sphere, outermost first). Without
/// colours they are coloured as an `.xyzr` file with the same columns, so
/// the same arrays render as that file does. Checked as a file would be.
pub fn from_arrays(
    positions: &[[f32; 3]],
    radii: &[f32],
    colors: Option<&[[u8; 4]]>,
    regions: Option<(&[u32], usize)>,
    name: &str,
) -> Result<Scene, SceneError> {
    let n = positions.len();
    let bad = |m: String| SceneError::Invalid(m);
    if n == 0 {
        return Err(bad("no spheres (positions is empty)".into()));
    }
    if n > MAX_SPHERES {
        return Err(bad(format!("{n} spheres, more than {MAX_SPHERES}")));
    }
    if radii.len() != n {
        return Err(bad(format!("{} radii for {n} positions", radii.len())));
    }
    if let Some(c) = colors
        && c.len() != n
    {
        return Err(bad(format!("{} colours for {n} positions", c.len())));
    }
    let levels = regions.map_or(0, |r| r.1);
    if levels > MAX_LEVELS {
        return Err(bad(format!("{levels} region levels, at most {MAX_LEVELS}")));
    }
    if let Some((r, l)) = regions
        && r.len() != n * l
    {
        return Err(bad(format!(
            "{} region ids for {n} spheres x {l} levels",
            r.len()
        )));
    }
    let mut spheres = Vec::with_capacity(n);
    for (i, (p, &r)) in positions.iter().zip(radii).enumerate() {
        for (v, axis) in p.iter().zip(["x", "y", "z"]) {
            if !(v.is_finite() && v.abs() <= super::MAX_COORDINATE) {
                return Err(bad(format!(
                    "positions[{i}]: {axis} = {v} is not finite or beyond ±{:e}",
                    super::MAX_COORDINATE
                )));
            }
        }
        if !(r > 0.0 && r <= super::MAX_COORDINATE) {
            return Err(bad(format!(
                "radii[{i}] = {r}: must be a finite number > 0"
            )));
        }
        let mut region = [0u32; MAX_LEVELS];
        if let Some((ids, l)) = regions {
            region[..l].copy_from_slice(&ids[i * l..(i + 1) * l]);
        }
        spheres.push(Sphere {
            center: *p,
            radius: r,
            color: XYZR_COLOR,
            region,
        });
    }
    let mut scene = xyzr_scene(spheres, levels, name);
    if let Some(c) = colors {
        for (s, c) in scene.spheres.iter_mut().zip(c) {
            s.color = *c;
        }
    }
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::super::{Format, parse_str};
    use super::*;

    fn load(text: &str, format: Format) -> Result<Scene, SceneError> {
        parse_str(text, format, "t", &LoadOptions::default())
    }

    fn err_line(text: &str, format: Format) -> usize {
        match load(text, format) {
            Err(SceneError::Parse { line, .. }) => line,
            other => panic!("expected a parse error, got {other:?}"),
        }
    }

    #[test]
    fn xyz_frames_and_elements() {
        let text =
            "3\nwater\nO 0 0 0\nH 0.96 0 0\n1 -0.24 0.93 0 extra\n2\nframe 2\nC 1 1 1\nCl 2 2 2\n";
        let s = load(text, Format::Xyz).unwrap();
        assert_eq!(s.spheres.len(), 3);
        assert_eq!(s.spheres[0].radius, Element::O.radius());
        assert_eq!(s.spheres[2].radius, Element::H.radius()); // atomic number 1
        assert_eq!(s.spheres[1].center, [0.96, 0.0, 0.0]);
        let all = LoadOptions {
            model: ModelSelect::All,
            ..LoadOptions::default()
        };
        let s = parse_str(text, Format::Xyz, "t", &all).unwrap();
        assert_eq!(s.spheres.len(), 5);
        assert_eq!(s.spheres[4].radius, Element::CL.radius());
        assert_eq!(s.spheres[4].region[0], 1);
        let two = LoadOptions {
            model: ModelSelect::Index(2),
            ..LoadOptions::default()
        };
        assert_eq!(
            parse_str(text, Format::Xyz, "t", &two)
                .unwrap()
                .spheres
                .len(),
            2
        );
    }

    #[test]
    fn xyz_malformed() {
        assert_eq!(err_line("x\n", Format::Xyz), 1);
        assert_eq!(err_line("2\nc\nC 0 0 0\n", Format::Xyz), 4);
        assert_eq!(err_line("1\nc\nC 0 0\n", Format::Xyz), 3);
        assert_eq!(err_line("1\nc\nC 0 inf 0\n", Format::Xyz), 3);
        assert_eq!(err_line("1\nc\nC 0 NaN 0\n", Format::Xyz), 3);
        assert!(matches!(
            load("", Format::Xyz),
            Err(SceneError::Empty { .. })
        ));
        assert!(matches!(
            load("0\nnone\n", Format::Xyz),
            Err(SceneError::Empty { .. })
        ));
    }

    #[test]
    fn xyzr_regions_and_comments() {
        let text = "# header\n1 2 3 1.5 7 8\n\n  4 5 6 0.5   # trailing comment\n-1e1 0 0 2 9\n";
        let s = load(text, Format::Xyzr).unwrap();
        assert_eq!(s.spheres.len(), 3);
        assert_eq!(s.level_names, vec!["level0", "level1"]);
        assert_eq!(s.spheres[0].region, [7, 8, 0, 0]);
        assert_eq!(s.spheres[1].region, [0, 0, 0, 0]);
        assert_eq!(s.spheres[2].region, [9, 0, 0, 0]);
        assert_eq!(s.spheres[2].center, [-10.0, 0.0, 0.0]);
        assert_eq!(s.spheres[1].radius, 0.5);
        assert_eq!(s.spheres[0].color, palette_color(8));

        let s = load("0 0 0 1\n", Format::Xyzr).unwrap();
        assert!(s.level_names.is_empty());
        assert_eq!(s.spheres[0].color, XYZR_COLOR);
        let s = load("0 0 0 1 1 2 3 4\n", Format::Xyzr).unwrap();
        assert_eq!(s.spheres[0].region, [1, 2, 3, 4]);
        assert_eq!(s.level_names.len(), 4);
    }

    #[test]
    fn xyzr_malformed() {
        assert_eq!(err_line("0 0 0 1\n0 0 0\n", Format::Xyzr), 2);
        assert_eq!(err_line("0 0 0 0\n", Format::Xyzr), 1);
        assert_eq!(err_line("0 0 0 -1\n", Format::Xyzr), 1);
        assert_eq!(err_line("0 0 0 nan\n", Format::Xyzr), 1);
        assert_eq!(err_line("# c\n0 0 0 inf\n", Format::Xyzr), 2);
        assert_eq!(err_line("0 0 NaN 1\n", Format::Xyzr), 1);
        assert_eq!(err_line("0 0 x 1\n", Format::Xyzr), 1);
        assert_eq!(err_line("0 0 0 1 -3\n", Format::Xyzr), 1);
        assert_eq!(err_line("0 0 0 1 1.5\n", Format::Xyzr), 1);
        assert_eq!(err_line("0 0 0 1 1 2 3 4 5\n", Format::Xyzr), 1);
        assert!(matches!(
            load("# only comments\n\n", Format::Xyzr),
            Err(SceneError::Empty { .. })
        ));
    }
}
