//! Text trajectories: multi-model PDB (MODEL records), multi-frame GRO and
//! XYZ, LAMMPS dumps (an index of each frame's byte range, built by one
//! streaming scan; a frame is read by parsing its range with the scene
//! parsers), and multi-model mmCIF (frame k is model k + 1, re-parsed from
//! the file, since models need not be contiguous).

use super::{Frame, Reader, TrajError};
use crate::scene::{self, Format, LoadOptions, ModelSelect};
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Scene(Format),
    Lammps,
}

pub struct Models {
    path: PathBuf,
    name: String,
    kind: Kind,
    /// Byte range of each frame (mmCIF: unused; frames are model numbers).
    ranges: Vec<(u64, u64)>,
    atoms: usize,
    damage: Option<TrajError>,
}

impl Models {
    pub fn open(path: &Path, kind: Kind) -> Result<Self, TrajError> {
        let name = path.display().to_string();
        let io = |source| TrajError::Io {
            path: name.clone(),
            source,
        };
        let mut m = Models {
            path: path.to_path_buf(),
            name: name.clone(),
            kind,
            ranges: Vec::new(),
            atoms: 0,
            damage: None,
        };
        if kind == Kind::Scene(Format::Cif) {
            // Count models with one streaming parse of all of them.
            let all = LoadOptions {
                model: ModelSelect::All,
                ..LoadOptions::default()
            };
            let s = scene::load(path, &all, &mut |_, _| {})?;
            let models = s.spheres.iter().map(|s| s.region[0] + 1).max().unwrap_or(1) as u64;
            m.ranges = (0..models).map(|k| (k, k)).collect();
            m.atoms = s.spheres.iter().filter(|s| s.region[0] == 0).count();
            return Ok(m);
        }
        let f = std::fs::File::open(path).map_err(io)?;
        let len = f.metadata().map_err(io)?.len();
        m.ranges = scan(BufReader::new(f), kind, len).map_err(io)?;
        if m.ranges.is_empty() {
            return Err(TrajError::Invalid(format!("{name}: no frames")));
        }
        // Frame 0 fixes the atom count; a frame that will not parse ends
        // the index (the frames before it stay readable).
        let mut frame = Frame::default();
        m.read_range(0, &mut frame)?;
        m.atoms = frame.positions.len();
        // A file cut short is cut in its last frame: check that one now so
        // the index holds complete frames only.
        let last = m.ranges.len() - 1;
        if last > 0 {
            let bad = match m.read_range(last, &mut frame) {
                Err(e) => Some(e),
                Ok(()) if frame.positions.len() != m.atoms => Some(TrajError::Frame {
                    path: name.clone(),
                    frame: last,
                    offset: m.ranges[last].0,
                    msg: format!("{} atoms, frame 0 has {}", frame.positions.len(), m.atoms),
                }),
                Ok(()) => None,
            };
            if let Some(e) = bad {
                m.ranges.pop();
                m.damage = Some(e);
            }
        }
        Ok(m)
    }

    fn read_range(&self, k: usize, out: &mut Frame) -> Result<(), TrajError> {
        let (a, b) = self.ranges[k];
        let err = |msg: String| TrajError::Frame {
            path: self.name.clone(),
            frame: k,
            offset: a,
            msg,
        };
        if let Kind::Scene(Format::Cif) = self.kind {
            let opts = LoadOptions {
                model: ModelSelect::Index(k as u32 + 1),
                ..LoadOptions::default()
            };
            let s =
                scene::load(&self.path, &opts, &mut |_, _| {}).map_err(|e| err(e.to_string()))?;
            out.positions = s.spheres.iter().map(|s| s.center).collect();
            out.time_ps = None;
            out.cell = None;
            return Ok(());
        }
        let mut f = std::fs::File::open(&self.path).map_err(|e| err(e.to_string()))?;
        f.seek(SeekFrom::Start(a)).map_err(|e| err(e.to_string()))?;
        let mut text = vec![0u8; (b - a) as usize];
        f.read_exact(&mut text).map_err(|e| err(e.to_string()))?;
        match self.kind {
            Kind::Lammps => {
                let mut cb = |_, _| {};
                let mut src = scene::text::LineSource::from_bytes(&text, &self.name, &mut cb);
                // (the parser's "PATH:LINE: what": the path is named once)
                let inner = |e: scene::SceneError| {
                    let text = e.to_string();
                    match text
                        .strip_prefix(&format!("{}:", self.name))
                        .and_then(|rest| rest.split_once(':'))
                    {
                        Some((line, what)) => err(format!("line {line} of the frame:{what}")),
                        None => err(text),
                    }
                };
                let d = scene::lammps::read_frame(&mut src, &self.name)
                    .map_err(inner)?
                    .ok_or_else(|| err("empty frame".into()))?;
                // Text after the frame's atoms that starts no frame: a
                // damaged `ITEM: TIMESTEP` line (the frame after it would
                // otherwise be lost and the rest renumbered).
                while let Some((n, l, _)) = src.next().map_err(|e| err(e.to_string()))? {
                    if !l.iter().all(u8::is_ascii_whitespace) {
                        return Err(err(format!(
                            "line {n} of the frame, '{}', follows its atoms: expected 'ITEM: TIMESTEP' (a damaged frame header?)",
                            scene::text::show(l)
                        )));
                    }
                }
                out.positions = d.positions;
                out.time_ps = None;
                out.cell = Some(d.cell);
            }
            Kind::Scene(format) => {
                let s = scene::parse_bytes(&text, format, &self.name, &LoadOptions::default())
                    .map_err(|e| err(e.to_string()))?;
                out.positions = s.spheres.iter().map(|s| s.center).collect();
                out.time_ps = match format {
                    Format::Gro => gro_time(&text),
                    _ => None,
                };
                out.cell = match format {
                    Format::Gro => gro_box(&text),
                    _ => None,
                };
            }
        }
        Ok(())
    }
}

/// The byte ranges of the frames of a text trajectory.
fn scan(mut r: impl BufRead, kind: Kind, len: u64) -> std::io::Result<Vec<(u64, u64)>> {
    let mut starts: Vec<u64> = Vec::new();
    let mut line = Vec::new();
    let mut pos = 0u64;
    // GRO/XYZ: frames are count-delimited blocks.
    let mut skip = 0usize;
    let mut pending_count = false;
    loop {
        line.clear();
        let n = read_line_bounded(&mut r, &mut line)?;
        if n == 0 {
            break;
        }
        let here = pos;
        pos += n as u64;
        let text = line.strip_suffix(b"\n").unwrap_or(&line);
        match kind {
            Kind::Lammps => {
                // A header no dump writes (`ITEM: TIMESTEX`) starts a frame
                // too: that frame then fails to read, naming itself and its
                // offset, instead of hiding in the frame before it.
                const ITEMS: [&[u8]; 4] = [
                    b"ITEM: TIMESTEP",
                    b"ITEM: NUMBER OF ATOMS",
                    b"ITEM: BOX BOUNDS",
                    b"ITEM: ATOMS",
                ];
                if text.starts_with(b"ITEM: TIMESTEP")
                    || (text.starts_with(b"ITEM:") && !ITEMS.iter().any(|i| text.starts_with(i)))
                {
                    starts.push(here);
                }
            }
            Kind::Scene(Format::Pdb) => {
                if text.starts_with(b"MODEL") {
                    starts.push(here);
                }
            }
            Kind::Scene(Format::Gro) | Kind::Scene(Format::Xyz) => {
                let gro = kind == Kind::Scene(Format::Gro);
                if skip > 0 {
                    skip -= 1;
                    continue;
                }
                if pending_count {
                    // GRO: this is the count line after the title.
                    pending_count = false;
                    let count: usize = std::str::from_utf8(text)
                        .ok()
                        .and_then(|s| s.trim().parse().ok())
                        .unwrap_or(0);
                    skip = count.min(scene::MAX_SPHERES) + 1; // atoms + box line
                    continue;
                }
                if text.iter().all(u8::is_ascii_whitespace) {
                    continue;
                }
                starts.push(here);
                if gro {
                    pending_count = true;
                } else {
                    let count: usize = std::str::from_utf8(text)
                        .ok()
                        .and_then(|s| s.trim().parse().ok())
                        .unwrap_or(0);
                    skip = count.min(scene::MAX_SPHERES) + 1; // comment + atoms
                }
            }
            Kind::Scene(_) => {}
        }
    }
    if kind == Kind::Scene(Format::Pdb) && starts.is_empty() {
        // no MODEL records: the file is one frame
        return Ok(vec![(0, len.min(pos))]);
    }
    let mut ranges: Vec<(u64, u64)> = starts.windows(2).map(|w| (w[0], w[1])).collect();
    if let Some(&last) = starts.last() {
        ranges.push((last, len.min(pos)));
    }
    Ok(ranges)
}

/// One line (with its newline), refusing lines over the scene limit.
fn read_line_bounded(r: &mut impl BufRead, out: &mut Vec<u8>) -> std::io::Result<usize> {
    let n = r
        .by_ref()
        .take(scene::text::MAX_LINE_BYTES as u64 + 1)
        .read_until(b'\n', out)?;
    if n > scene::text::MAX_LINE_BYTES {
        return Err(std::io::Error::other(format!(
            "a line longer than {} bytes: not a text trajectory",
            scene::text::MAX_LINE_BYTES
        )));
    }
    Ok(n)
}

/// `t= 900.00000` in a GRO title line (GROMACS writes it).
fn gro_time(text: &[u8]) -> Option<f64> {
    let title = text.split(|&b| b == b'\n').next()?;
    let s = std::str::from_utf8(title).ok()?;
    let i = s.find("t=")?;
    s[i + 2..].split_whitespace().next()?.parse().ok()
}

/// The GRO box line (nm: v1(x) v2(y) v3(z) [v1(y) v1(z) v2(x) v2(z) v3(x)
/// v3(y)]) as cell rows in Å.
fn gro_box(text: &[u8]) -> Option<[[f64; 3]; 3]> {
    let s = std::str::from_utf8(text).ok()?;
    let last = s.lines().rev().find(|l| !l.trim().is_empty())?;
    let v: Vec<f64> = last
        .split_whitespace()
        .map(|t| t.parse::<f64>().map(|x| x * 10.0))
        .collect::<Result<_, _>>()
        .ok()?;
    match v.len() {
        3 => Some([[v[0], 0.0, 0.0], [0.0, v[1], 0.0], [0.0, 0.0, v[2]]]),
        9 => Some([[v[0], v[3], v[4]], [v[5], v[1], v[6]], [v[7], v[8], v[2]]]),
        _ => None,
    }
}

impl Reader for Models {
    fn atoms(&self) -> usize {
        self.atoms
    }
    fn offset(&self, k: usize) -> u64 {
        self.ranges[k].0
    }
    fn frames(&self) -> usize {
        self.ranges.len()
    }
    fn damage(&self) -> Option<&TrajError> {
        self.damage.as_ref()
    }
    fn read(&mut self, k: usize, out: &mut Frame) -> Result<(), TrajError> {
        self.read_range(k, out)?;
        if out.positions.len() != self.atoms {
            return Err(TrajError::Frame {
                path: self.name.clone(),
                frame: k,
                offset: self.ranges[k].0,
                msg: format!("{} atoms, frame 0 has {}", out.positions.len(), self.atoms),
            });
        }
        Ok(())
    }
}
