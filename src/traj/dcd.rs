//! CHARMM/NAMD DCD: Fortran unformatted records (a length marker before
//! and after each), little- or big-endian, 32- or 64-bit markers (both
//! sniffed from the first record, which is 84 bytes long), an optional unit
//! cell record per frame (CHARMM flag), X, Y and Z as f32 records. Fixed
//! atoms (NAMNF > 0) are refused. Time: (ISTART + k * NSAVC) * DELTA AKMA
//! units (1 AKMA = 0.04888821 ps), as MDAnalysis reports it.

use super::{Frame, Reader, TrajError};
use std::io::{BufReader, Read, Seek, SeekFrom, Write};
use std::path::Path;

const AKMA_PS: f64 = 0.04888821;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Layout {
    big_endian: bool,
    marker: u64, // 4 or 8 bytes
}

impl Layout {
    fn int(&self, b: &[u8]) -> i64 {
        match (self.marker, self.big_endian) {
            (4, false) => i32::from_le_bytes(b[..4].try_into().unwrap_or_default()) as i64,
            (4, true) => i32::from_be_bytes(b[..4].try_into().unwrap_or_default()) as i64,
            (_, false) => i64::from_le_bytes(b[..8].try_into().unwrap_or_default()),
            (_, true) => i64::from_be_bytes(b[..8].try_into().unwrap_or_default()),
        }
    }
    fn i32(&self, b: &[u8]) -> i32 {
        let a: [u8; 4] = b[..4].try_into().unwrap_or_default();
        if self.big_endian {
            i32::from_be_bytes(a)
        } else {
            i32::from_le_bytes(a)
        }
    }
    fn f32(&self, b: &[u8]) -> f32 {
        f32::from_bits(self.i32(b) as u32)
    }
    fn f64(&self, b: &[u8]) -> f64 {
        let a: [u8; 8] = b[..8].try_into().unwrap_or_default();
        if self.big_endian {
            f64::from_be_bytes(a)
        } else {
            f64::from_le_bytes(a)
        }
    }
}

pub struct Dcd {
    path: String,
    file: BufReader<std::fs::File>,
    layout: Layout,
    atoms: usize,
    first: u64,
    frame_size: u64,
    frames: usize,
    has_cell: bool,
    istart: i64,
    nsavc: i64,
    delta: f64,
    damage: Option<TrajError>,
    buf: Vec<u8>,
}

/// Reads one Fortran record (marker, body, marker) into `out`.
fn record(r: &mut impl Read, l: Layout, out: &mut Vec<u8>, max: u64) -> Result<(), String> {
    let mut m = [0u8; 8];
    let e = |e: std::io::Error| match e.kind() {
        std::io::ErrorKind::UnexpectedEof => "the file ends inside a record".to_string(),
        _ => e.to_string(),
    };
    r.read_exact(&mut m[..l.marker as usize]).map_err(e)?;
    let n = l.int(&m);
    if n < 0 || n as u64 > max {
        return Err(format!("bad record length {n}"));
    }
    out.resize(n as usize, 0);
    r.read_exact(out).map_err(e)?;
    r.read_exact(&mut m[..l.marker as usize]).map_err(e)?;
    if l.int(&m) != n {
        return Err(format!("record markers disagree ({n} and {})", l.int(&m)));
    }
    Ok(())
}

impl Dcd {
    pub fn open(path: &Path) -> Result<Self, TrajError> {
        let name = path.display().to_string();
        let bad = |msg: String| TrajError::Invalid(format!("{name}: {msg}"));
        let io = |source| TrajError::Io {
            path: name.clone(),
            source,
        };
        let f = std::fs::File::open(path).map_err(io)?;
        let len = f.metadata().map_err(io)?.len();
        let mut file = BufReader::new(f);
        let mut head = [0u8; 8];
        file.read_exact(&mut head)
            .map_err(|_| bad("too short for a DCD header".into()))?;
        // (64-bit markers first: a 32-bit little-endian 84 also reads as
        // 84 in the first four bytes of a 64-bit one)
        let layout = [
            Layout {
                big_endian: false,
                marker: 8,
            },
            Layout {
                big_endian: true,
                marker: 8,
            },
            Layout {
                big_endian: false,
                marker: 4,
            },
            Layout {
                big_endian: true,
                marker: 4,
            },
        ]
        .into_iter()
        .find(|l| l.int(&head) == 84)
        .ok_or_else(|| bad("not a DCD file (the first record is not 84 bytes)".into()))?;
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        let mut rec = Vec::new();
        let mut next = |file: &mut BufReader<std::fs::File>, what: &str| {
            record(file, layout, &mut rec, len)
                .map_err(|m| bad(format!("header {what}: {m}")))
                .map(|()| rec.clone())
        };
        let h = next(&mut file, "record")?;
        if h.len() != 84 || &h[..4] != b"CORD" {
            return Err(bad("header record is not CORD".into()));
        }
        let ic = |i: usize| layout.i32(&h[4 + 4 * i..]);
        let (istart, nsavc, namnf) = (ic(1) as i64, ic(2) as i64, ic(8));
        let charmm = ic(19) != 0;
        let delta = if charmm {
            layout.f32(&h[4 + 4 * 9..]) as f64
        } else {
            layout.f64(&h[4 + 4 * 9..])
        };
        let has_cell = charmm && ic(10) != 0;
        let four_d = charmm && ic(11) != 0;
        if namnf != 0 {
            return Err(bad(format!("{namnf} fixed atoms (NAMNF): not supported")));
        }
        if four_d {
            return Err(bad("4D coordinates: not supported".into()));
        }
        next(&mut file, "title")?;
        let n = next(&mut file, "atom count")?;
        if n.len() != 4 {
            return Err(bad("the atom count record is not 4 bytes".into()));
        }
        let atoms = layout.i32(&n);
        if atoms <= 0 || atoms as usize > crate::scene::MAX_SPHERES {
            return Err(bad(format!("bad atom count {atoms}")));
        }
        let atoms = atoms as usize;
        let first = file.stream_position().map_err(io)?;
        let m = layout.marker;
        let frame_size = (if has_cell { 48 + 2 * m } else { 0 }) + 3 * (4 * atoms as u64 + 2 * m);
        let frames = ((len - first) / frame_size) as usize;
        let rest = (len - first) % frame_size;
        let damage = (rest != 0).then(|| TrajError::Frame {
            path: name.clone(),
            frame: frames,
            offset: first + frames as u64 * frame_size,
            msg: format!("the file ends inside the frame ({rest} of {frame_size} bytes)"),
        });
        if frames == 0 {
            return Err(damage.unwrap_or_else(|| bad("no frames".into())));
        }
        Ok(Dcd {
            path: name,
            file,
            layout,
            atoms,
            first,
            frame_size,
            frames,
            has_cell,
            istart,
            nsavc,
            delta,
            damage,
            buf: Vec::new(),
        })
    }
}

impl Reader for Dcd {
    fn atoms(&self) -> usize {
        self.atoms
    }
    fn offset(&self, k: usize) -> u64 {
        self.first + k as u64 * self.frame_size
    }
    fn frames(&self) -> usize {
        self.frames
    }
    fn damage(&self) -> Option<&TrajError> {
        self.damage.as_ref()
    }
    fn read(&mut self, k: usize, out: &mut Frame) -> Result<(), TrajError> {
        let offset = self.first + k as u64 * self.frame_size;
        let err = |msg: String| TrajError::Frame {
            path: self.path.clone(),
            frame: k,
            offset,
            msg,
        };
        self.file
            .seek(SeekFrom::Start(offset))
            .map_err(|e| err(e.to_string()))?;
        let l = self.layout;
        out.cell = None;
        if self.has_cell {
            record(&mut self.file, l, &mut self.buf, 48).map_err(err)?;
            if self.buf.len() != 48 {
                return Err(err("the unit cell record is not 48 bytes".into()));
            }
            // CHARMM order: A, gamma, B, beta, alpha, C (angles as cosines
            // or degrees depending on the writer).
            let v: Vec<f64> = (0..6).map(|i| l.f64(&self.buf[8 * i..])).collect();
            out.cell = Some(cell_from(v[0], v[2], v[5], v[4], v[3], v[1]));
        }
        out.positions.resize(self.atoms, [0.0; 3]);
        for axis in 0..3 {
            record(&mut self.file, l, &mut self.buf, 4 * self.atoms as u64).map_err(err)?;
            if self.buf.len() != 4 * self.atoms {
                return Err(err(format!(
                    "coordinate record of {} bytes, expected {}",
                    self.buf.len(),
                    4 * self.atoms
                )));
            }
            for (p, c) in out.positions.iter_mut().zip(self.buf.chunks_exact(4)) {
                p[axis] = l.f32(c);
            }
        }
        out.time_ps = Some((self.istart + k as i64 * self.nsavc) as f64 * self.delta * AKMA_PS);
        Ok(())
    }
}

/// Cell vectors from lengths and angles (degrees, or cosines when all
/// three are within [-1, 1], as NAMD writes them).
fn cell_from(a: f64, b: f64, c: f64, alpha: f64, beta: f64, gamma: f64) -> [[f64; 3]; 3] {
    let cosines = [alpha, beta, gamma].iter().all(|x| x.abs() <= 1.0);
    let cos = |x: f64| if cosines { x } else { x.to_radians().cos() };
    let (ca, cb, cg) = (cos(alpha), cos(beta), cos(gamma));
    let sg = (1.0 - cg * cg).max(0.0).sqrt().max(1e-12);
    let cx = cb;
    let cy = (ca - cb * cg) / sg;
    let cz = (1.0 - cx * cx - cy * cy).max(0.0).sqrt();
    [
        [a, 0.0, 0.0],
        [b * cg, b * sg, 0.0],
        [c * cx, c * cy, c * cz],
    ]
}

/// Writes a DCD (tests, tools): `frames` of positions, optionally with a
/// unit cell (lengths a b c, angles alpha beta gamma in degrees) per frame,
/// in the given endianness and marker width (4 or 8).
pub fn write_dcd(
    w: &mut impl Write,
    frames: &[Vec<[f32; 3]>],
    cell: Option<[f64; 6]>,
    big_endian: bool,
    marker: usize,
) -> std::io::Result<()> {
    let i32b = |v: i32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let mark = |w: &mut dyn Write, n: usize| -> std::io::Result<()> {
        match (marker, big_endian) {
            (4, false) => w.write_all(&(n as i32).to_le_bytes()),
            (4, true) => w.write_all(&(n as i32).to_be_bytes()),
            (_, false) => w.write_all(&(n as i64).to_le_bytes()),
            (_, true) => w.write_all(&(n as i64).to_be_bytes()),
        }
    };
    let rec = |w: &mut dyn Write, body: &[u8]| -> std::io::Result<()> {
        mark(w, body.len())?;
        w.write_all(body)?;
        mark(w, body.len())
    };
    let atoms = frames.first().map_or(0, |f| f.len());
    let mut h = b"CORD".to_vec();
    let mut ic = [0i32; 20];
    ic[0] = frames.len() as i32;
    ic[1] = 10;
    ic[2] = 10;
    ic[10] = cell.is_some() as i32;
    ic[19] = 24;
    for (i, v) in ic.iter().enumerate() {
        if i == 9 {
            let d = (0.1f32).to_bits() as i32; // DELTA
            h.extend(i32b(d));
        } else {
            h.extend(i32b(*v));
        }
    }
    rec(w, &h)?;
    let mut title = i32b(1).to_vec();
    title.extend([b' '; 80]);
    rec(w, &title)?;
    rec(w, &i32b(atoms as i32))?;
    for f in frames {
        if let Some([a, b, c, al, be, ga]) = cell {
            let mut body = Vec::new();
            for v in [a, ga, b, be, al, c] {
                body.extend(if big_endian {
                    v.to_be_bytes()
                } else {
                    v.to_le_bytes()
                });
            }
            rec(w, &body)?;
        }
        for axis in 0..3 {
            let body: Vec<u8> = f
                .iter()
                .flat_map(|p| i32b(p[axis].to_bits() as i32))
                .collect();
            rec(w, &body)?;
        }
    }
    Ok(())
}
