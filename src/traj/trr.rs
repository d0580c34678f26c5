//! GROMACS TRR (XDR, big-endian): a header of block sizes per frame, then
//! the box, virial, pressure, positions, velocities and forces blocks that
//! are present, in single or double precision (from the block sizes).

use super::{Frame, Reader, TrajError, xdr};
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

struct Entry {
    offset: u64,
    /// Byte offset of the positions block (None: the frame has none).
    x_at: Option<u64>,
    box_at: Option<u64>,
    double: bool,
    time: f64,
}

pub struct Trr {
    path: String,
    file: BufReader<std::fs::File>,
    index: Vec<Entry>,
    atoms: usize,
    damage: Option<TrajError>,
}

const MAGIC: i32 = 1993;

impl Trr {
    pub fn open(path: &Path) -> Result<Self, TrajError> {
        let ix = super::index_frames(path, "TRR", header)?;
        Ok(Trr {
            path: ix.name,
            file: ix.file,
            index: ix.entries,
            atoms: ix.atoms,
            damage: ix.damage,
        })
    }
}

/// (atoms, frame size, entry) of the frame at `pos`.
fn header(
    file: &mut BufReader<std::fs::File>,
    pos: u64,
    len: u64,
) -> Result<(usize, u64, Entry), String> {
    let e = xdr::header_error;
    file.seek(SeekFrom::Start(pos)).map_err(e)?;
    let magic = xdr::i32(file).map_err(e)?;
    if magic != MAGIC {
        return Err(format!("bad magic number {magic} (not a TRR frame)"));
    }
    let slen = xdr::i32(file).map_err(e)?;
    let n = xdr::i32(file).map_err(e)?;
    if !(0..=128).contains(&slen) || !(0..=128).contains(&n) {
        return Err("bad version string".into());
    }
    let padded = (n as usize).div_ceil(4) * 4;
    let mut version = vec![0u8; padded];
    file.read_exact(&mut version).map_err(e)?;
    if !version.starts_with(b"GMX_trn_file") {
        return Err("bad version string (not GMX_trn_file)".into());
    }
    let mut h = [0i32; 13];
    for v in &mut h {
        *v = xdr::i32(file).map_err(e)?;
    }
    let [
        ir,
        ene,
        box_size,
        vir,
        pres,
        top,
        sym,
        x_size,
        v_size,
        f_size,
        natoms,
        _step,
        _nre,
    ] = h;
    if h[..10].iter().any(|&s| s < 0) || natoms <= 0 {
        return Err("negative block size or atom count".into());
    }
    if ir != 0 || ene != 0 || top != 0 || sym != 0 {
        return Err("unsupported TRR blocks (ir, energy, topology or symmetry)".into());
    }
    let natoms = natoms as usize;
    if natoms > crate::scene::MAX_SPHERES {
        return Err(format!(
            "{natoms} atoms, more than {}",
            crate::scene::MAX_SPHERES
        ));
    }
    // Precision from the block sizes (as GROMACS does).
    let real = if box_size != 0 {
        box_size as u64 / 9
    } else if x_size != 0 {
        x_size as u64 / (natoms as u64 * 3)
    } else if v_size != 0 {
        v_size as u64 / (natoms as u64 * 3)
    } else if f_size != 0 {
        f_size as u64 / (natoms as u64 * 3)
    } else {
        4
    };
    if real != 4 && real != 8 {
        return Err(format!("block sizes give {real}-byte reals"));
    }
    for (s, what, per) in [
        (box_size, "box", 9),
        (vir, "virial", 9),
        (pres, "pressure", 9),
        (x_size, "positions", natoms as u64 * 3),
        (v_size, "velocities", natoms as u64 * 3),
        (f_size, "forces", natoms as u64 * 3),
    ] {
        if s != 0 && s as u64 != per * real {
            return Err(format!(
                "{what} block of {s} bytes, expected {}",
                per * real
            ));
        }
    }
    let double = real == 8;
    let time = if double {
        xdr::f64(file).map_err(e)?
    } else {
        xdr::f32(file).map_err(e)? as f64
    };
    let header = 4 * 3 + padded as u64 + 13 * 4 + 2 * real;
    let box_at = (box_size != 0).then_some(pos + header);
    let x_at = (x_size != 0).then_some(pos + header + (box_size + vir + pres) as u64);
    let size = header
        + [box_size, vir, pres, x_size, v_size, f_size]
            .iter()
            .map(|&s| s as u64)
            .sum::<u64>();
    if pos + size > len {
        return Err(format!(
            "the file ends inside the frame ({} of {size} bytes)",
            len - pos
        ));
    }
    Ok((
        natoms,
        size,
        Entry {
            offset: pos,
            x_at,
            box_at,
            double,
            time,
        },
    ))
}

impl Reader for Trr {
    fn atoms(&self) -> usize {
        self.atoms
    }
    fn offset(&self, k: usize) -> u64 {
        self.index[k].offset
    }
    fn frames(&self) -> usize {
        self.index.len()
    }
    fn damage(&self) -> Option<&TrajError> {
        self.damage.as_ref()
    }
    fn read(&mut self, k: usize, out: &mut Frame) -> Result<(), TrajError> {
        let e = &self.index[k];
        let err = |msg: String| TrajError::Frame {
            path: self.path.clone(),
            frame: k,
            offset: e.offset,
            msg,
        };
        let x_at = e
            .x_at
            .ok_or_else(|| err("the frame has no positions block".into()))?;
        let real = |f: &mut BufReader<std::fs::File>| -> std::io::Result<f64> {
            if e.double {
                xdr::f64(f)
            } else {
                xdr::f32(f).map(f64::from)
            }
        };
        let io = |x: std::io::Error| err(x.to_string());
        out.cell = None;
        if let Some(b) = e.box_at {
            self.file.seek(SeekFrom::Start(b)).map_err(io)?;
            let mut cell = [[0.0; 3]; 3];
            for row in &mut cell {
                for v in row.iter_mut() {
                    *v = real(&mut self.file).map_err(io)? * 10.0;
                }
            }
            out.cell = cell
                .iter()
                .any(|r| r.iter().any(|&v| v != 0.0))
                .then_some(cell);
        }
        self.file.seek(SeekFrom::Start(x_at)).map_err(io)?;
        out.positions.clear();
        out.positions.reserve(self.atoms);
        for _ in 0..self.atoms {
            let mut p = [0.0f32; 3];
            for v in &mut p {
                *v = (real(&mut self.file).map_err(io)? * 10.0) as f32;
            }
            out.positions.push(p);
        }
        out.time_ps = Some(e.time);
        Ok(())
    }
}
