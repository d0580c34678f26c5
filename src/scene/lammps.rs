//! LAMMPS text dumps (`dump atom/custom`): `ITEM: TIMESTEP`, `NUMBER OF
//! ATOMS`, `BOX BOUNDS` (orthogonal, or triclinic with xy xz yz), `ATOMS`
//! with named columns. Positions come from `x y z` (wrapped), `xu yu zu`
//! (unwrapped) or `xs ys zs` / `xsu ysu zsu` (scaled by the box); rows are
//! put in `id` order (dumps write them in any order). The atom kind is the
//! `element` column, else `type` (a radius and colour per type). As a
//! structure file the first frame is the scene.

use super::elements::Element;
use super::molecule::palette_color;
use super::text::{LineSource, parse_f32, show, split_ws};
use super::{MAX_SPHERES, Scene, SceneError, Sphere, check_coordinate, parse_error};

/// One dump frame, rows in id order.
#[derive(Clone, Debug, Default)]
pub struct DumpFrame {
    pub timestep: i64,
    /// Cell vectors a, b, c as rows (the dump's units).
    pub cell: [[f64; 3]; 3],
    pub ids: Vec<i64>,
    pub types: Vec<i64>,
    pub elements: Vec<Option<Element>>,
    pub positions: Vec<[f32; 3]>,
}

/// Reads the next frame from `src` (None at the end of the input).
pub(crate) fn read_frame(
    src: &mut LineSource,
    name: &str,
) -> Result<Option<DumpFrame>, SceneError> {
    let mut f = DumpFrame::default();
    // ITEM: TIMESTEP (blank lines before it are allowed)
    let first = loop {
        match src.next()? {
            None => return Ok(None),
            Some((_, l, _)) if l.iter().all(u8::is_ascii_whitespace) => continue,
            Some((n, l, _)) => break (n, l.to_vec()),
        }
    };
    if !first.1.starts_with(b"ITEM: TIMESTEP") {
        return Err(parse_error(
            name,
            first.0,
            format!("expected 'ITEM: TIMESTEP', found '{}'", show(&first.1)),
        ));
    }
    let mut value_line = |what: &str| -> Result<(usize, Vec<u8>), SceneError> {
        match src.next()? {
            Some((n, l, _)) => Ok((n, l.to_vec())),
            None => Err(parse_error(
                name,
                first.0,
                format!("the file ends before {what}"),
            )),
        }
    };
    let int = |n: usize, l: &[u8], what: &str| -> Result<i64, SceneError> {
        std::str::from_utf8(l)
            .ok()
            .and_then(|s| s.split_whitespace().next()?.parse().ok())
            .ok_or_else(|| parse_error(name, n, format!("bad {what} '{}'", show(l))))
    };
    let (n, l) = value_line("the timestep")?;
    f.timestep = int(n, &l, "timestep")?;
    let (n, l) = value_line("NUMBER OF ATOMS")?;
    if !l.starts_with(b"ITEM: NUMBER OF ATOMS") {
        return Err(parse_error(
            name,
            n,
            format!("expected 'ITEM: NUMBER OF ATOMS', found '{}'", show(&l)),
        ));
    }
    let (n, l) = value_line("the atom count")?;
    let count = int(n, &l, "atom count")?;
    if count < 0 || count as usize > MAX_SPHERES {
        return Err(parse_error(
            name,
            n,
            format!("atom count {count}: must be between 0 and {MAX_SPHERES}"),
        ));
    }
    let count = count as usize;
    let (n, l) = value_line("BOX BOUNDS")?;
    if !l.starts_with(b"ITEM: BOX BOUNDS") {
        return Err(parse_error(
            name,
            n,
            format!("expected 'ITEM: BOX BOUNDS', found '{}'", show(&l)),
        ));
    }
    let triclinic = String::from_utf8_lossy(&l).contains("xy");
    let mut bounds = [[0.0f64; 3]; 3];
    for row in &mut bounds {
        let (n, l) = value_line("the box bounds")?;
        let mut toks = Vec::new();
        split_ws(&l, &mut toks);
        let want = if triclinic { 3 } else { 2 };
        if toks.len() < want {
            return Err(parse_error(
                name,
                n,
                format!("expected {want} box bound values, found {}", toks.len()),
            ));
        }
        for (slot, t) in row.iter_mut().zip(&toks) {
            *slot = parse_f32(t)
                .ok_or_else(|| parse_error(name, n, format!("bad box bound '{}'", show(t))))?
                as f64;
        }
    }
    // Triclinic bounds are of the bounding box: undo the tilt (LAMMPS docs).
    let (xy, xz, yz) = if triclinic {
        (bounds[0][2], bounds[1][2], bounds[2][2])
    } else {
        (0.0, 0.0, 0.0)
    };
    let xlo = bounds[0][0] - 0.0f64.min(xy).min(xz).min(xy + xz);
    let xhi = bounds[0][1] - 0.0f64.max(xy).max(xz).max(xy + xz);
    let ylo = bounds[1][0] - 0.0f64.min(yz);
    let yhi = bounds[1][1] - 0.0f64.max(yz);
    let (zlo, zhi) = (bounds[2][0], bounds[2][1]);
    f.cell = [
        [xhi - xlo, 0.0, 0.0],
        [xy, yhi - ylo, 0.0],
        [xz, yz, zhi - zlo],
    ];
    let origin = [xlo, ylo, zlo];
    let (hn, header) = value_line("ITEM: ATOMS")?;
    let Some(cols) = header.strip_prefix(b"ITEM: ATOMS") else {
        return Err(parse_error(
            name,
            hn,
            format!("expected 'ITEM: ATOMS', found '{}'", show(&header)),
        ));
    };
    let mut names = Vec::new();
    split_ws(cols, &mut names);
    let col = |n: &str| names.iter().position(|c| *c == n.as_bytes());
    let (pos, scaled) = if let (Some(x), Some(y), Some(z)) = (col("x"), col("y"), col("z")) {
        ([x, y, z], false)
    } else if let (Some(x), Some(y), Some(z)) = (col("xu"), col("yu"), col("zu")) {
        ([x, y, z], false)
    } else if let (Some(x), Some(y), Some(z)) = (col("xs"), col("ys"), col("zs")) {
        ([x, y, z], true)
    } else if let (Some(x), Some(y), Some(z)) = (col("xsu"), col("ysu"), col("zsu")) {
        ([x, y, z], true)
    } else {
        return Err(parse_error(
            name,
            hn,
            "the ATOMS columns have no x y z, xu yu zu, xs ys zs or xsu ysu zsu",
        ));
    };
    let (id_col, type_col, el_col) = (col("id"), col("type"), col("element"));
    let mut rows: Vec<(i64, i64, Option<Element>, [f32; 3])> =
        Vec::with_capacity(count.min(1 << 20));
    for i in 0..count {
        let mut toks = Vec::with_capacity(names.len());
        let (n, l, _) = match src.next()? {
            Some(x) => x,
            None => {
                return Err(parse_error(
                    name,
                    hn + i,
                    format!("file ends after {i} of {count} atoms"),
                ));
            }
        };
        split_ws(l, &mut toks);
        if toks.len() < names.len() {
            return Err(parse_error(
                name,
                n,
                format!(
                    "{} values, the ATOMS line names {} columns",
                    toks.len(),
                    names.len()
                ),
            ));
        }
        let num = |c: usize, what: &str| -> Result<f64, SceneError> {
            parse_f32(toks[c])
                .map(f64::from)
                .ok_or_else(|| parse_error(name, n, format!("bad {what} '{}'", show(toks[c]))))
        };
        let mut s = [0.0f64; 3];
        for (k, slot) in s.iter_mut().enumerate() {
            *slot = num(pos[k], ["x", "y", "z"][k])?;
        }
        let p = if scaled {
            // r = origin + s . cell
            let c = &f.cell;
            [
                origin[0] + s[0] * c[0][0] + s[1] * c[1][0] + s[2] * c[2][0],
                origin[1] + s[1] * c[1][1] + s[2] * c[2][1],
                origin[2] + s[2] * c[2][2],
            ]
        } else {
            s
        };
        let mut center = [0.0f32; 3];
        for (k, v) in center.iter_mut().enumerate() {
            *v = check_coordinate(p[k] as f32, ["x", "y", "z"][k], name, n)?;
        }
        let int_col = |c: Option<usize>, what: &str, default: i64| -> Result<i64, SceneError> {
            match c {
                None => Ok(default),
                Some(c) => std::str::from_utf8(toks[c])
                    .ok()
                    .and_then(|s| s.parse::<i64>().ok())
                    .ok_or_else(|| parse_error(name, n, format!("bad {what} '{}'", show(toks[c])))),
            }
        };
        let id = int_col(id_col, "id", i as i64 + 1)?;
        let ty = int_col(type_col, "type", 1)?;
        let el = el_col.and_then(|c| Element::from_symbol(toks[c]));
        // (a last atom line without a newline is a normal line: it parsed
        // whole, every column present)
        rows.push((id, ty, el, center));
    }
    rows.sort_by_key(|r| r.0);
    if rows.windows(2).any(|w| w[0].0 == w[1].0) {
        return Err(parse_error(name, hn, "two atoms of the frame share an id"));
    }
    f.ids = rows.iter().map(|r| r.0).collect();
    f.types = rows.iter().map(|r| r.1).collect();
    f.elements = rows.iter().map(|r| r.2).collect();
    f.positions = rows.iter().map(|r| r.3).collect();
    Ok(Some(f))
}

/// The first frame of a dump as a scene: element radii and colours when
/// there is an `element` column, else 1.0 (radius) and a palette colour per
/// `type`. Levels: type, atom.
pub(crate) fn parse(src: &mut LineSource, name: &str) -> Result<Scene, SceneError> {
    let f = read_frame(src, name)?.ok_or_else(|| SceneError::Empty {
        path: name.to_string(),
    })?;
    Ok(frame_scene(&f, name))
}

pub(crate) fn frame_scene(f: &DumpFrame, name: &str) -> Scene {
    let spheres = f
        .positions
        .iter()
        .enumerate()
        .map(|(i, &center)| {
            let ty = f.types[i].max(0) as u32;
            let (radius, color) = match f.elements[i] {
                Some(e) => (e.radius(), e.color()),
                None => (1.0, palette_color(ty)),
            };
            Sphere {
                center,
                radius,
                color,
                region: [ty, i as u32, 0, 0],
            }
        })
        .collect();
    Scene {
        spheres,
        level_names: vec!["type".into(), "atom".into()],
        source: name.to_string(),
        instancing: None,
        expanded: false,
        atoms: None,
        origin: None,
    }
}
