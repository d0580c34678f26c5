//! Trajectories: frames of atom positions for a topology loaded by
//! [`crate::scene`] (DESIGN.md "Trajectories and movies"). Every reader
//! builds an index of frame offsets when it opens a file (headers only) and
//! then reads any frame by seeking: memory does not grow with the length.
//! A frame that is cut or corrupt ends the index; the frames before it stay
//! readable and [`Reader::damage`] says what is wrong, where.
//!
//! Coordinates are Å (XTC/TRR store nm), times ps, cells Å.
//! A leaf beside `scene` (it uses the scene parsers for multi-model
//! PDB/mmCIF/GRO/XYZ files and LAMMPS dumps).

mod dcd;
mod models;
mod pbc;
mod trr;
mod xtc;

pub use dcd::write_dcd;
pub use pbc::{Pbc, apply_pbc};

use std::path::Path;

/// One frame: positions in topology order (Å), the simulation time (ps)
/// when the format stores it, the periodic cell when it has one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    pub positions: Vec<[f32; 3]>,
    pub time_ps: Option<f64>,
    /// Cell vectors a, b, c as rows (Å).
    pub cell: Option<[[f64; 3]; 3]>,
}

impl Frame {
    /// Keeps the atoms `index` names (a topology subset by `--hide`), in
    /// that order; `None` keeps all.
    pub fn keep(&mut self, index: Option<&[u32]>) {
        if let Some(ix) = index {
            let all = std::mem::take(&mut self.positions);
            self.positions = ix
                .iter()
                .map(|&i| all.get(i as usize).copied().unwrap_or_default())
                .collect();
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum TrajError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    /// A frame that cannot be read: the file, the 0-based frame and the
    /// byte offset where it starts.
    #[error("{path}: frame {frame} at byte {offset}: {msg}")]
    Frame {
        path: String,
        frame: usize,
        offset: u64,
        msg: String,
    },
    #[error("{0}")]
    Invalid(String),
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
}

/// A trajectory file opened for random access.
pub trait Reader: Send {
    /// Atoms per frame.
    fn atoms(&self) -> usize;
    /// Frames in the index (the complete ones).
    fn frames(&self) -> usize;
    /// Reads frame `k` (0-based, < `frames()`).
    fn read(&mut self, k: usize, out: &mut Frame) -> Result<(), TrajError>;
    /// What stopped the index early (a cut or corrupt frame), if anything.
    fn damage(&self) -> Option<&TrajError>;
    /// The byte where frame `k` starts (< `frames()`).
    fn offset(&self, k: usize) -> u64;
}

/// Every reader behind [`open`]: a frame whose decoded coordinates are not
/// finite (a NaN in a binary frame, a damaged precision, a `nan` in text)
/// or beyond the range sphereshade renders stops the run at that frame, as
/// a damaged frame does, naming it and its byte offset.
struct Checked {
    inner: Box<dyn Reader>,
    path: String,
}

impl Reader for Checked {
    fn atoms(&self) -> usize {
        self.inner.atoms()
    }
    fn frames(&self) -> usize {
        self.inner.frames()
    }
    fn damage(&self) -> Option<&TrajError> {
        self.inner.damage()
    }
    fn offset(&self, k: usize) -> u64 {
        self.inner.offset(k)
    }
    fn read(&mut self, k: usize, out: &mut Frame) -> Result<(), TrajError> {
        self.inner.read(k, out)?;
        let limit = crate::scene::MAX_COORDINATE;
        if let Some(i) = out
            .positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite() && c.abs() <= limit))
        {
            return Err(TrajError::Frame {
                path: self.path.clone(),
                frame: k,
                offset: self.inner.offset(k),
                msg: format!(
                    "atom {i} is at {:?}: not finite or beyond ±{limit:e} (a damaged frame?)",
                    out.positions[i]
                ),
            });
        }
        Ok(())
    }
}

/// Trajectory formats, by extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TrajFormat {
    Xtc,
    Trr,
    Dcd,
    Lammps,
    /// Multi-model PDB/mmCIF or multi-frame GRO/XYZ (scene formats).
    Models(crate::scene::Format),
}

pub fn format_of(path: &Path) -> Option<TrajFormat> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    Some(match ext.as_str() {
        "xtc" => TrajFormat::Xtc,
        "trr" => TrajFormat::Trr,
        "dcd" => TrajFormat::Dcd,
        "lammpstrj" | "dump" => TrajFormat::Lammps,
        _ => match crate::scene::format_of(path)? {
            (_, true) => return None, // gzip has no random access
            (f, false) => TrajFormat::Models(f),
        },
    })
}

/// Opens a trajectory and builds its frame index.
pub fn open(path: &Path) -> Result<Box<dyn Reader>, TrajError> {
    let name = path.display().to_string();
    let format = format_of(path).ok_or_else(|| {
        TrajError::Invalid(format!(
            "{name}: not a trajectory (expected .xtc, .trr, .dcd, .lammpstrj/.dump, or an \
             uncompressed multi-model .pdb/.cif or multi-frame .gro/.xyz)"
        ))
    })?;
    let io = |source| TrajError::Io {
        path: name.clone(),
        source,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::other("is a directory")));
    }
    let inner: Box<dyn Reader> = match format {
        TrajFormat::Xtc => Box::new(xtc::Xtc::open(path)?),
        TrajFormat::Trr => Box::new(trr::Trr::open(path)?),
        TrajFormat::Dcd => Box::new(dcd::Dcd::open(path)?),
        TrajFormat::Lammps => Box::new(models::Models::open(path, models::Kind::Lammps)?),
        TrajFormat::Models(f) => Box::new(models::Models::open(path, models::Kind::Scene(f))?),
    };
    Ok(Box::new(Checked { inner, path: name }))
}

/// `--frames A:B:S`: 0-based, B exclusive, any part may be empty; negative
/// A or B count from the end (Python slices).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    pub start: Option<i64>,
    pub stop: Option<i64>,
    pub step: i64,
}

impl Default for FrameRange {
    fn default() -> Self {
        FrameRange {
            start: None,
            stop: None,
            step: 1,
        }
    }
}

impl std::str::FromStr for FrameRange {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("'{s}': expected A:B:S (0-based, B exclusive, parts may be empty)");
        let parts: Vec<&str> = s.split(':').collect();
        if parts.is_empty() || parts.len() > 3 {
            return Err(bad());
        }
        let num = |p: &str| -> Result<Option<i64>, String> {
            let p = p.trim();
            if p.is_empty() {
                Ok(None)
            } else {
                p.parse::<i64>().map(Some).map_err(|_| bad())
            }
        };
        let start = num(parts[0])?;
        if parts.len() == 1 {
            // a single frame index
            let k = start.ok_or_else(bad)?;
            return Ok(FrameRange {
                start: Some(k),
                stop: Some(if k == -1 { i64::MAX } else { k + 1 }),
                step: 1,
            });
        }
        let stop = num(parts[1])?;
        let step = match parts.get(2) {
            Some(p) => num(p)?.unwrap_or(1),
            None => 1,
        };
        if step <= 0 {
            return Err(format!("'{s}': the step must be at least 1"));
        }
        Ok(FrameRange { start, stop, step })
    }
}

impl std::fmt::Display for FrameRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let o = |v: Option<i64>| v.map(|v| v.to_string()).unwrap_or_default();
        write!(f, "{}:{}:{}", o(self.start), o(self.stop), self.step)
    }
}

impl FrameRange {
    /// The frame indices of a trajectory of `n` frames.
    pub fn indices(&self, n: usize) -> Vec<usize> {
        let n = n as i64;
        let resolve = |v: i64| if v < 0 { (n + v).max(0) } else { v.min(n) };
        let a = self.start.map_or(0, resolve);
        let b = self
            .stop
            .map_or(n, |v| if v == i64::MAX { n } else { resolve(v) });
        (a..b)
            .step_by(self.step as usize)
            .map(|k| k as usize)
            .collect()
    }
}

/// Runs a decoder that may panic on corrupt data (third-party code),
/// turning a panic into an error without printing it.
pub(crate) fn guarded<T>(f: impl FnOnce() -> std::io::Result<T>) -> std::io::Result<T> {
    quiet_panics::install();
    quiet_panics::QUIET.with(|q| q.set(true));
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    quiet_panics::QUIET.with(|q| q.set(false));
    match r {
        Ok(r) => r,
        // (the decoder's own words, "assertion `left != right` failed" or
        // an index out of bounds, say nothing to a user: the data is bad)
        Err(_) => Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "corrupt data: the frame does not decode",
        )),
    }
}

mod quiet_panics {
    use std::cell::Cell;
    use std::sync::Once;

    thread_local! {
        pub static QUIET: Cell<bool> = const { Cell::new(false) };
    }

    /// A panic hook that stays silent while a guarded decoder runs on this
    /// thread and defers to the previous hook otherwise.
    pub fn install() {
        static ONCE: Once = Once::new();
        ONCE.call_once(|| {
            let previous = std::panic::take_hook();
            std::panic::set_hook(Box::new(move |info| {
                if !QUIET.with(|q| q.get()) {
                    previous(info);
                }
            }));
        });
    }
}

/// The index of a file of self-delimiting frames (XTC, TRR): one entry per
/// complete frame, the atom count they share, and what ended the index
/// early (a cut or corrupt frame, or a frame with another atom count).
pub(crate) struct FrameIndex<E> {
    pub name: String,
    pub file: std::io::BufReader<std::fs::File>,
    pub entries: Vec<E>,
    pub atoms: usize,
    pub damage: Option<TrajError>,
}

/// Builds a [`FrameIndex`] by walking the frame headers: `header(file, pos,
/// len)` reads the header of the frame at byte `pos` and gives (atoms,
/// frame size in bytes, entry), or the reason it cannot. `format` names
/// the file kind in the error for an empty file.
pub(crate) fn index_frames<E>(
    path: &Path,
    format: &str,
    mut header: impl FnMut(
        &mut std::io::BufReader<std::fs::File>,
        u64,
        u64,
    ) -> Result<(usize, u64, E), String>,
) -> Result<FrameIndex<E>, TrajError> {
    let name = path.display().to_string();
    let io = |source| TrajError::Io {
        path: name.clone(),
        source,
    };
    let f = std::fs::File::open(path).map_err(io)?;
    let len = f.metadata().map_err(io)?.len();
    let mut file = std::io::BufReader::new(f);
    let mut entries = Vec::new();
    let mut atoms = None;
    let mut damage = None;
    let mut pos = 0u64;
    while pos < len {
        let frame = entries.len();
        let bad = |msg: String| TrajError::Frame {
            path: name.clone(),
            frame,
            offset: pos,
            msg,
        };
        match header(&mut file, pos, len) {
            Ok((n, size, entry)) => {
                if let Some(a) = atoms
                    && a != n
                {
                    damage = Some(bad(format!("{n} atoms, the frames before have {a}")));
                    break;
                }
                atoms = Some(n);
                entries.push(entry);
                pos += size;
            }
            Err(msg) => {
                damage = Some(bad(msg));
                break;
            }
        }
    }
    let atoms = atoms.ok_or_else(|| match damage.take() {
        Some(d) => d,
        None => TrajError::Invalid(format!("{name}: empty {format} file")),
    })?;
    Ok(FrameIndex {
        name,
        file,
        entries,
        atoms,
        damage,
    })
}

/// Big-endian XDR reading for XTC/TRR headers.
pub(crate) mod xdr {
    use std::io::Read;

    /// A header read error as its message ("the file ends inside the frame
    /// header" for a cut file).
    pub fn header_error(e: std::io::Error) -> String {
        match e.kind() {
            std::io::ErrorKind::UnexpectedEof => {
                "the file ends inside the frame header".to_string()
            }
            _ => e.to_string(),
        }
    }

    pub fn i32(r: &mut impl Read) -> std::io::Result<i32> {
        let mut b = [0u8; 4];
        r.read_exact(&mut b)?;
        Ok(i32::from_be_bytes(b))
    }
    pub fn f32(r: &mut impl Read) -> std::io::Result<f32> {
        let mut b = [0u8; 4];
        r.read_exact(&mut b)?;
        Ok(f32::from_be_bytes(b))
    }
    pub fn f64(r: &mut impl Read) -> std::io::Result<f64> {
        let mut b = [0u8; 8];
        r.read_exact(&mut b)?;
        Ok(f64::from_be_bytes(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ranges_slice_like_python() {
        let r = |s: &str| s.parse::<FrameRange>().unwrap().indices(10);
        assert_eq!(r(":"), (0..10).collect::<Vec<_>>());
        assert_eq!(r("::3"), vec![0, 3, 6, 9]);
        assert_eq!(r("5:"), vec![5, 6, 7, 8, 9]);
        assert_eq!(r("2:5"), vec![2, 3, 4]);
        assert_eq!(r("-3:"), vec![7, 8, 9]);
        assert_eq!(r(":-8"), vec![0, 1]);
        assert_eq!(r("4"), vec![4]);
        assert_eq!(r("-1"), vec![9]);
        assert_eq!(r("8:20"), vec![8, 9]);
        assert!(r("7:3").is_empty());
        assert!(r("20:").is_empty());
        assert!(r("-20:2").len() == 2);
        for bad in ["a:b", "1:2:0", "1:2:-1", "1:2:3:4", ""] {
            assert!(bad.parse::<FrameRange>().is_err(), "{bad}");
        }
        assert_eq!("::10".parse::<FrameRange>().unwrap().to_string(), "::10");
    }

    #[test]
    fn guarded_turns_panics_into_errors_quietly() {
        let e = guarded::<()>(|| panic!("index out of bounds")).unwrap_err();
        assert!(e.to_string().contains("corrupt data"), "{e}");
        assert_eq!(guarded(|| Ok(3)).unwrap(), 3);
    }
}
