//! GROMACS XTC through the `molly` decoder. The index is built here from
//! the frame headers (magic, atom count twice, the compressed size), so a
//! cut or inconsistent frame ends the index with a message instead of
//! reaching the decoder; molly's own panics on corrupt data are guarded.

use super::{Frame, Reader, TrajError, guarded, xdr};
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

pub struct Xtc {
    path: String,
    file: BufReader<std::fs::File>,
    offsets: Vec<u64>,
    atoms: usize,
    damage: Option<TrajError>,
    raw: molly::Frame,
}

const MAGIC_1995: i32 = 1995;
const MAGIC_2023: i32 = 2023;

impl Xtc {
    pub fn open(path: &Path) -> Result<Self, TrajError> {
        let ix = super::index_frames(path, "XTC", |f, pos, len| {
            header_size(f, pos, len).map(|(n, size)| (n, size, pos))
        })?;
        Ok(Xtc {
            path: ix.name,
            file: ix.file,
            offsets: ix.entries,
            atoms: ix.atoms,
            damage: ix.damage,
            raw: molly::Frame::default(),
        })
    }
}

/// Atoms and byte size of the frame at `pos`, from its header alone.
fn header_size(
    file: &mut BufReader<std::fs::File>,
    pos: u64,
    len: u64,
) -> Result<(usize, u64), String> {
    let e = xdr::header_error;
    file.seek(SeekFrom::Start(pos)).map_err(e)?;
    let magic = xdr::i32(file).map_err(e)?;
    if magic != MAGIC_1995 && magic != MAGIC_2023 {
        return Err(format!("bad magic number {magic} (not an XTC frame)"));
    }
    let n = xdr::i32(file).map_err(e)?;
    let mut rest = [0u8; 4 * 11]; // step, time, box (9)
    file.read_exact(&mut rest).map_err(e)?;
    let n2 = xdr::i32(file).map_err(e)?;
    if n < 0 || n != n2 {
        return Err(format!("inconsistent atom counts {n} and {n2}"));
    }
    let n = n as usize;
    if n > crate::scene::MAX_SPHERES {
        return Err(format!(
            "{n} atoms, more than {}",
            crate::scene::MAX_SPHERES
        ));
    }
    let mut size = 4 * 14u64;
    if n <= 9 {
        size += n as u64 * 12;
    } else {
        // precision, minint[3], maxint[3], smallidx, then the byte count
        let mut skip = [0u8; 32];
        file.read_exact(&mut skip).map_err(e)?;
        let nbytes = if magic == MAGIC_1995 {
            xdr::i32(file).map_err(e)? as i64
        } else {
            let mut b = [0u8; 8];
            file.read_exact(&mut b).map_err(e)?;
            i64::from_be_bytes(b)
        };
        if nbytes < 0 || nbytes as u64 > len {
            return Err(format!("bad compressed size {nbytes}"));
        }
        let nb = nbytes as u64;
        size += 32 + if magic == MAGIC_1995 { 4 } else { 8 } + nb + (4 - nb % 4) % 4;
    }
    if pos + size > len {
        return Err(format!(
            "the file ends inside the frame ({} of {size} bytes)",
            len - pos
        ));
    }
    Ok((n, size))
}

impl Reader for Xtc {
    fn atoms(&self) -> usize {
        self.atoms
    }
    fn offset(&self, k: usize) -> u64 {
        self.offsets[k]
    }
    fn frames(&self) -> usize {
        self.offsets.len()
    }
    fn damage(&self) -> Option<&TrajError> {
        self.damage.as_ref()
    }
    fn read(&mut self, k: usize, out: &mut Frame) -> Result<(), TrajError> {
        let offset = self.offsets[k];
        let (file, raw) = (&mut self.file, &mut self.raw);
        let r = guarded(|| {
            file.seek(SeekFrom::Start(offset))?;
            let mut reader = molly::XTCReader::new(&mut *file);
            reader.read_frame(raw)
        });
        r.map_err(|e| TrajError::Frame {
            path: self.path.clone(),
            frame: k,
            offset,
            msg: e.to_string(),
        })?;
        if raw.positions.len() != self.atoms * 3 {
            return Err(TrajError::Frame {
                path: self.path.clone(),
                frame: k,
                offset,
                msg: format!(
                    "decoded {} atoms, expected {}",
                    raw.positions.len() / 3,
                    self.atoms
                ),
            });
        }
        out.positions.clear();
        out.positions.extend(
            raw.positions
                .chunks_exact(3)
                .map(|p| [p[0] * 10.0, p[1] * 10.0, p[2] * 10.0]),
        );
        out.time_ps = Some(raw.time as f64);
        let b = raw.boxvec;
        let cell = [
            [b[0] as f64 * 10.0, b[1] as f64 * 10.0, b[2] as f64 * 10.0],
            [b[3] as f64 * 10.0, b[4] as f64 * 10.0, b[5] as f64 * 10.0],
            [b[6] as f64 * 10.0, b[7] as f64 * 10.0, b[8] as f64 * 10.0],
        ];
        out.cell = cell
            .iter()
            .any(|r| r.iter().any(|&v| v != 0.0))
            .then_some(cell);
        Ok(())
    }
}
