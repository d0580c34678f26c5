//! Scenes of spheres: loading molecular and particle files (PDB, mmCIF, GRO,
//! XYZ, XYZR, optionally gzip-compressed) and generating procedural scenes.
//!
//! Every sphere carries region ids for up to [`MAX_LEVELS`] hierarchy levels
//! (outermost first, e.g. model / chain / residue / atom). Ids are small
//! integers whose only meaning is equality: two spheres share a region at a
//! level exactly when their ids at that level are equal.

pub mod elements;
pub mod hybrid36;

mod cif;
mod gro;
pub(crate) mod lammps;
mod molecule;
mod pdb;
mod procedural;
pub(crate) mod text;
mod xyz;

use std::io::{BufRead, Read};
use std::path::Path;

use glam::Vec3;

pub use procedural::procedural;
pub use xyz::from_arrays;

/// Number of region levels every sphere carries.
pub const MAX_LEVELS: usize = 4;

/// Most spheres a scene may hold: sphere ids are 24-bit in the id AOV and
/// the visibility keys. Every way of making spheres (files, assemblies,
/// `--replicate`, procedural `--atoms`) is checked against it before it
/// allocates.
pub const MAX_SPHERES: usize = (1 << 24) - 1;

/// Largest coordinate magnitude and radius accepted (Å): squares and sums of
/// squares of such values stay far from f32 overflow in every pass.
pub const MAX_COORDINATE: f32 = 1e15;

/// A coordinate checked against [`MAX_COORDINATE`].
pub(crate) fn check_coordinate(
    v: f32,
    axis: &str,
    name: &str,
    line: usize,
) -> Result<f32, SceneError> {
    if v.abs() <= MAX_COORDINATE {
        Ok(v)
    } else {
        Err(parse_error(
            name,
            line,
            format!(
                "{axis} coordinate {v:e} is outside ±{MAX_COORDINATE:e}, the range sphereshade renders in f32"
            ),
        ))
    }
}

/// A radius checked against [`MAX_COORDINATE`].
pub(crate) fn check_radius(r: f32, name: &str, line: usize) -> Result<f32, SceneError> {
    if r <= MAX_COORDINATE {
        Ok(r)
    } else {
        Err(parse_error(
            name,
            line,
            format!(
                "radius {r:e} is above {MAX_COORDINATE:e}, the range sphereshade renders in f32"
            ),
        ))
    }
}

/// The error for a file with more than [`MAX_SPHERES`] spheres (at the line
/// that would add one more).
pub(crate) fn too_many(name: &str, line: usize) -> SceneError {
    parse_error(
        name,
        line,
        format!(
            "more than {MAX_SPHERES} spheres, the most sphereshade renders (24-bit sphere ids)"
        ),
    )
}

/// The error for a data record that ends the file without a newline.
pub(crate) fn truncated(name: &str, line: usize) -> SceneError {
    parse_error(
        name,
        line,
        "the file ends inside this record (no newline after it): it looks cut short; \
         if it is complete, end it with a newline",
    )
}

/// Procedural scene used when no input is given.
pub const DEFAULT_SCENE: &str = "capsid";
/// Sphere count of the default procedural scene.
pub const DEFAULT_ATOMS: usize = 200_000;

/// One sphere: centre and radius in Å, RGBA colour, hierarchy region ids.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: [f32; 3],
    pub radius: f32,
    /// RGBA, A = 255.
    pub color: [u8; 4],
    /// Region id per level, outermost first; unused levels are 0.
    pub region: [u32; MAX_LEVELS],
}

/// A loaded or generated set of spheres.
#[derive(Clone, Debug)]
pub struct Scene {
    pub spheres: Vec<Sphere>,
    /// Names of the region levels in use, outermost first (len <= MAX_LEVELS).
    pub level_names: Vec<String>,
    /// File path, or "scene:NAME" for procedural scenes.
    pub source: String,
}

impl Scene {
    /// Component-wise min and max of the sphere centres (None if empty).
    pub fn center_bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = Vec3::from(self.spheres.first()?.center);
        Some(self.spheres.iter().fold((first, first), |(lo, hi), s| {
            let c = Vec3::from(s.center);
            (lo.min(c), hi.max(c))
        }))
    }

    /// Sphere enclosing every sphere: centred on the centre of the bounding
    /// box of the centres (the default view centre), radius reaching the
    /// farthest sphere surface. `(0, 0)` for an empty scene.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        let Some((lo, hi)) = self.center_bounds() else {
            return (Vec3::ZERO, 0.0);
        };
        let c = (lo + hi) * 0.5;
        let r = self
            .spheres
            .iter()
            .map(|s| Vec3::from(s.center).distance(c) + s.radius)
            .fold(0.0f32, f32::max);
        (c, r)
    }

    /// Largest radius (0 for an empty scene).
    pub fn max_radius(&self) -> f32 {
        self.spheres.iter().map(|s| s.radius).fold(0.0, f32::max)
    }

    /// Multiplies every radius by `f`.
    pub fn scale_radii(&mut self, f: f32) {
        for s in &mut self.spheres {
            s.radius *= f;
        }
    }

    /// Tiles the scene `n[0] x n[1] x n[2]` times on a lattice whose spacing
    /// is the extent of the centres plus a gap of twice the largest radius,
    /// so copies never touch. Every region id is combined with the copy
    /// index, so copies are distinct regions at every level in use (a scene
    /// without levels gets a "copy" level). Zero counts are treated as 1.
    pub fn replicate(&self, n: [u32; 3]) -> Scene {
        let n = n.map(|v| v.max(1));
        let copies = n[0] as usize * n[1] as usize * n[2] as usize;
        let mut level_names = self.level_names.clone();
        if level_names.is_empty() {
            level_names.push("copy".to_string());
        }
        let Some((lo, hi)) = self.center_bounds() else {
            return Scene {
                spheres: Vec::new(),
                level_names,
                source: self.source.clone(),
            };
        };
        let step = (hi - lo) + Vec3::splat(2.0 * self.max_radius());
        // Id stride per level: one past the largest id in use.
        let mut stride = [1u32; MAX_LEVELS];
        for s in &self.spheres {
            for (st, &r) in stride.iter_mut().zip(&s.region) {
                *st = (*st).max(r.saturating_add(1));
            }
        }
        let levels = level_names.len().min(MAX_LEVELS);
        let mut spheres = Vec::with_capacity(self.spheres.len().saturating_mul(copies));
        let mut copy = 0u32;
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let offset = step * Vec3::new(i as f32, j as f32, k as f32);
                    spheres.extend(self.spheres.iter().map(|s| {
                        let mut t = *s;
                        t.center = (Vec3::from(s.center) + offset).to_array();
                        let levels = t.region.iter_mut().zip(&stride).take(levels);
                        for (r, &st) in levels {
                            *r = copy.wrapping_mul(st).wrapping_add(*r);
                        }
                        t
                    }));
                    copy += 1;
                }
            }
        }
        Scene {
            spheres,
            level_names,
            source: self.source.clone(),
        }
    }
}

/// Which model(s) of a multi-model file (NMR ensembles, trajectories) to load.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModelSelect {
    /// The first model (files without MODEL records are one model).
    First,
    /// The model with this 1-based number (MODEL record / pdbx_PDB_model_num;
    /// frame number for GRO and XYZ).
    Index(u32),
    /// Every model, each its own level-0 region.
    All,
}

/// How molecular files are coloured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorBy {
    Element,
    Chain,
}

#[derive(Clone, Debug)]
pub struct LoadOptions {
    pub model: ModelSelect,
    /// Biological assembly to build (PDB REMARK 350 BIOMOLECULE n, mmCIF
    /// `_pdbx_struct_assembly_gen` assembly_id n): each operator's copy of
    /// the listed chains, each copy its own level-0 region.
    pub assembly: Option<u32>,
    pub color_by: ColorBy,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            model: ModelSelect::First,
            assembly: None,
            color_by: ColorBy::Element,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}:{line}: {msg}")]
    Parse {
        path: String,
        line: usize,
        msg: String,
    },
    #[error("{path}: no spheres found")]
    Empty { path: String },
    #[error(
        "{path}: unknown file extension (expected .pdb, .ent, .cif, .mmcif, .gro, .xyz, .xyzr, .lammpstrj, .dump, optionally .gz)"
    )]
    UnknownFormat { path: String },
    #[error("unknown procedural scene '{0}' (expected capsid, lattice, random)")]
    UnknownScene(String),
    #[error("{0}")]
    Invalid(String),
}

/// Shorthand for a parse error at a 1-based line.
pub(crate) fn parse_error(path: &str, line: usize, msg: impl Into<String>) -> SceneError {
    SceneError::Parse {
        path: path.to_string(),
        line,
        msg: msg.into(),
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Pdb,
    Cif,
    Gro,
    Xyz,
    Xyzr,
    /// LAMMPS text dump (the first frame).
    Lammps,
}

impl Format {
    fn from_extension(ext: &str) -> Option<Format> {
        Some(match ext.to_ascii_lowercase().as_str() {
            "pdb" | "ent" => Format::Pdb,
            "cif" | "mmcif" => Format::Cif,
            "gro" => Format::Gro,
            "xyz" => Format::Xyz,
            "xyzr" => Format::Xyzr,
            "lammpstrj" | "dump" => Format::Lammps,
            _ => return None,
        })
    }
}

/// Format by extension (`.pdb`, `.cif.gz`, ...). The bool says whether the
/// file is gzip-compressed: by a `.gz` suffix, or sniffed from the magic
/// bytes 1f 8b when the file can be read.
pub fn format_of(path: &Path) -> Option<(Format, bool)> {
    let (format, gz_ext) = format_by_name(path)?;
    Some((format, gz_ext || has_gzip_magic(path)))
}

fn format_by_name(path: &Path) -> Option<(Format, bool)> {
    let ext = path.extension()?.to_str()?;
    if ext.eq_ignore_ascii_case("gz") {
        let inner = Path::new(path.file_stem()?).extension()?.to_str()?;
        return Some((Format::from_extension(inner)?, true));
    }
    Some((Format::from_extension(ext)?, false))
}

fn has_gzip_magic(path: &Path) -> bool {
    let mut magic = [0u8; 2];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok_and(|()| magic == [0x1f, 0x8b])
}

/// Loads a structure or particle file. `progress(bytes_done, bytes_total)`
/// is called about every 1 % of the file's (raw, possibly compressed)
/// bytes. The text is parsed as it streams in, a line at a time, so memory
/// follows the spheres kept, not the file size.
pub fn load(
    path: &Path,
    opts: &LoadOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Scene, SceneError> {
    let name = path.display().to_string();
    let (format, gz_ext) =
        format_by_name(path).ok_or_else(|| SceneError::UnknownFormat { path: name.clone() })?;
    let io_err = |source| SceneError::Io {
        path: name.clone(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    if meta.is_dir() {
        return Err(io_err(std::io::Error::other("is a directory")));
    }
    // (0 for pipes and devices: progress then only reports the end)
    let total = meta.len();
    let done = std::rc::Rc::new(std::cell::Cell::new(0u64));
    let mut raw = std::io::BufReader::with_capacity(
        1 << 16,
        text::Counting {
            inner: file,
            done: done.clone(),
        },
    );
    let gz = gz_ext || raw.fill_buf().map_err(io_err)?.starts_with(&[0x1f, 0x8b]);
    let reader: Box<dyn BufRead> = if gz {
        Box::new(std::io::BufReader::with_capacity(
            1 << 16,
            GzErrors(flate2::bufread::MultiGzDecoder::new(raw)),
        ))
    } else {
        Box::new(raw)
    };
    let mut src = text::LineSource::new(reader, &name, done, total, progress);
    parse_source(&mut src, format, &name, opts)
}

/// Gzip decoding errors say so ("gzip: ...").
struct GzErrors<R>(R);

impl<R: Read> Read for GzErrors<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        self.0
            .read(out)
            .map_err(|e| std::io::Error::new(e.kind(), format!("gzip: {e}")))
    }
}

/// Parses text already in memory (tests, embedded data).
pub fn parse_str(
    text: &str,
    format: Format,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    parse_bytes(text.as_bytes(), format, name, opts)
}

/// Parses bytes already in memory.
pub fn parse_bytes(
    data: &[u8],
    format: Format,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let mut cb = |_, _| {};
    let mut src = text::LineSource::from_bytes(data, name, &mut cb);
    parse_source(&mut src, format, name, opts)
}

fn parse_source(
    src: &mut text::LineSource,
    format: Format,
    name: &str,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let scene = match format {
        Format::Pdb => pdb::parse(src, name, opts)?,
        Format::Cif => cif::parse(src, name, opts)?,
        Format::Gro => gro::parse(src, name, opts)?,
        Format::Xyz => xyz::parse_xyz(src, name, opts)?,
        Format::Xyzr => xyz::parse_xyzr(src, name)?,
        Format::Lammps => lammps::parse(src, name)?,
    };
    if scene.spheres.is_empty() {
        return Err(SceneError::Empty {
            path: name.to_string(),
        });
    }
    if scene.spheres.len() > MAX_SPHERES {
        return Err(SceneError::Invalid(format!(
            "{name}: {} spheres, more than {MAX_SPHERES}, the most sphereshade renders (24-bit sphere ids)",
            scene.spheres.len()
        )));
    }
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(c: [f32; 3], r: f32, region: [u32; MAX_LEVELS]) -> Sphere {
        Sphere {
            center: c,
            radius: r,
            color: [255; 4],
            region,
        }
    }

    fn two() -> Scene {
        Scene {
            spheres: vec![
                sphere([0.0, 0.0, 0.0], 1.0, [0, 0, 0, 0]),
                sphere([4.0, 2.0, 0.0], 2.0, [0, 1, 1, 1]),
            ],
            level_names: vec![
                "model".into(),
                "chain".into(),
                "residue".into(),
                "atom".into(),
            ],
            source: "test".into(),
        }
    }

    #[test]
    fn bounds() {
        let s = two();
        let (lo, hi) = s.center_bounds().unwrap();
        assert_eq!(lo, Vec3::ZERO);
        assert_eq!(hi, Vec3::new(4.0, 2.0, 0.0));
        let (c, r) = s.bounding_sphere();
        assert_eq!(c, Vec3::new(2.0, 1.0, 0.0));
        assert!((r - (5.0f32.sqrt() + 2.0)).abs() < 1e-6);
        assert_eq!(s.max_radius(), 2.0);
        let mut t = s.clone();
        t.scale_radii(0.5);
        assert_eq!(t.max_radius(), 1.0);
        let empty = Scene {
            spheres: vec![],
            level_names: vec![],
            source: String::new(),
        };
        assert_eq!(empty.center_bounds(), None);
        assert_eq!(empty.bounding_sphere(), (Vec3::ZERO, 0.0));
        assert_eq!(empty.max_radius(), 0.0);
    }

    #[test]
    fn replicate_counts_and_regions() {
        let s = two();
        let r = s.replicate([2, 3, 4]);
        assert_eq!(r.spheres.len(), 2 * 24);
        let mut level0: Vec<u32> = r.spheres.iter().map(|s| s.region[0]).collect();
        level0.sort_unstable();
        level0.dedup();
        assert_eq!(level0.len(), 24);
        // Atom-level ids stay unique across copies.
        let mut atoms: Vec<u32> = r.spheres.iter().map(|s| s.region[3]).collect();
        atoms.sort_unstable();
        atoms.dedup();
        assert_eq!(atoms.len(), 48);
        // Copies do not overlap: spacing is extent + 2 * max radius.
        let (lo, hi) = r.center_bounds().unwrap();
        assert_eq!(lo, Vec3::ZERO);
        assert_eq!(hi, Vec3::new(4.0 + 8.0, 2.0 + 2.0 * 6.0, 3.0 * 4.0));
        // Degenerate counts and scenes without levels.
        let mut bare = two();
        bare.level_names.clear();
        for sp in &mut bare.spheres {
            sp.region = [0; MAX_LEVELS];
        }
        let r = bare.replicate([0, 2, 1]);
        assert_eq!(r.spheres.len(), 4);
        assert_eq!(r.level_names, vec!["copy".to_string()]);
        assert_ne!(r.spheres[0].region[0], r.spheres[2].region[0]);
    }

    #[test]
    fn formats_by_name() {
        let f = |p: &str| format_of(Path::new(p));
        assert_eq!(f("a.pdb"), Some((Format::Pdb, false)));
        assert_eq!(f("a.ENT"), Some((Format::Pdb, false)));
        assert_eq!(f("dir.x/a.cif.gz"), Some((Format::Cif, true)));
        assert_eq!(f("a.mmcif"), Some((Format::Cif, false)));
        assert_eq!(f("a.gro"), Some((Format::Gro, false)));
        assert_eq!(f("a.xyz.GZ"), Some((Format::Xyz, true)));
        assert_eq!(f("a.xyzr"), Some((Format::Xyzr, false)));
        assert_eq!(f("a.txt"), None);
        assert_eq!(f("a.gz"), None);
        assert_eq!(f("noext"), None);
    }

    fn temp_path(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("sphereshade-{}-{name}", std::process::id()))
    }

    const MINI_PDB: &str = "\
ATOM      1  N   GLY A   1      42.053  -9.336  17.867  1.00 43.86           N
ATOM      2  CA  GLY A   1      42.704 -10.253  18.851  1.00 41.67           C
HETATM    3  O   HOH     2      19.099   9.698 -13.097  1.00 32.87           O
";

    #[test]
    fn gzip_load_and_sniff() {
        use std::io::Write;
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        enc.write_all(MINI_PDB.as_bytes()).unwrap();
        let gz = enc.finish().unwrap();

        let p = temp_path("mini.pdb.gz");
        std::fs::write(&p, &gz).unwrap();
        let mut calls = 0;
        let s = load(&p, &LoadOptions::default(), &mut |_, _| calls += 1).unwrap();
        assert_eq!(s.spheres.len(), 3);
        assert!(calls > 0);
        assert_eq!(format_of(&p), Some((Format::Pdb, true)));

        // Compressed content behind a plain extension is sniffed.
        let p2 = temp_path("sniffed.pdb");
        std::fs::write(&p2, &gz).unwrap();
        assert_eq!(format_of(&p2), Some((Format::Pdb, true)));
        assert_eq!(
            load(&p2, &LoadOptions::default(), &mut |_, _| {})
                .unwrap()
                .spheres
                .len(),
            3
        );

        // Corrupt stream: an I/O error naming the file, no panic.
        let mut bad = gz.clone();
        let mid = bad.len() / 2;
        for b in &mut bad[12..mid] {
            *b ^= 0x5a;
        }
        let p3 = temp_path("corrupt.pdb.gz");
        std::fs::write(&p3, &bad).unwrap();
        let err = load(&p3, &LoadOptions::default(), &mut |_, _| {}).unwrap_err();
        assert!(
            matches!(err, SceneError::Io { .. } | SceneError::Invalid(_)),
            "{err}"
        );
        assert!(err.to_string().contains("corrupt.pdb.gz"), "{err}");

        // Truncated stream.
        std::fs::write(&p3, &gz[..gz.len() / 2]).unwrap();
        let err = load(&p3, &LoadOptions::default(), &mut |_, _| {}).unwrap_err();
        assert!(err.to_string().contains("gzip"), "{err}");

        for p in [p, p2, p3] {
            let _ = std::fs::remove_file(p);
        }
    }

    #[test]
    fn load_errors() {
        let opts = LoadOptions::default();
        let err = load(Path::new("x.txt"), &opts, &mut |_, _| {}).unwrap_err();
        assert!(matches!(err, SceneError::UnknownFormat { .. }));
        let err = load(Path::new("/nonexistent/x.pdb"), &opts, &mut |_, _| {}).unwrap_err();
        assert!(matches!(err, SceneError::Io { .. }));
        assert!(err.to_string().starts_with("/nonexistent/x.pdb: "));

        let p = temp_path("empty.xyzr");
        std::fs::write(&p, b"").unwrap();
        let err = load(&p, &opts, &mut |_, _| {}).unwrap_err();
        assert!(matches!(err, SceneError::Empty { .. }), "{err}");

        std::fs::write(&p, b"1 2 3 1\n\x00\x01\x02garbage\xff\xfe").unwrap();
        let err = load(&p, &opts, &mut |_, _| {}).unwrap_err();
        assert!(matches!(err, SceneError::Invalid(_)), "{err}");
        assert!(err.to_string().contains(":2:"), "{err}");
        let _ = std::fs::remove_file(p);
    }

    #[test]
    fn invalid_utf8_is_a_parse_error() {
        let opts = LoadOptions::default();
        for (fmt, text) in [
            (Format::Xyzr, &b"1 2 3 1\n1 \xff 3 1\n"[..]),
            (Format::Xyz, &b"1\nc\nC 1 \xc3\x28 3\n"[..]),
            (
                Format::Pdb,
                &b"ATOM      1  N   GLY A   1      4\xff.053  -9.336  17.867  1.00\n"[..],
            ),
        ] {
            let err = parse_bytes(text, fmt, "bin", &opts).unwrap_err();
            assert!(matches!(err, SceneError::Parse { .. }), "{err}");
        }
    }

    /// Truncating or corrupting input anywhere must give a result or an
    /// error, never a panic.
    #[test]
    fn mangled_input_never_panics() {
        let samples: [(Format, &str); 5] = [
            (
                Format::Pdb,
                "REMARK 350 BIOMOLECULE: 1\n\
                 REMARK 350 APPLY THE FOLLOWING TO CHAINS: A\n\
                 REMARK 350   BIOMT1   1  1.000000  0.000000  0.000000        0.00000\n\
                 REMARK 350   BIOMT2   1  0.000000  1.000000  0.000000        0.00000\n\
                 REMARK 350   BIOMT3   1  0.000000  0.000000  1.000000        0.00000\n\
                 MODEL        1\n\
                 ATOM      1  N   PHEAA   5     131.128  15.297 139.774  1.00150.60         A N\n\
                 HETATMA0LGO  BE  BEFAA 602      99.650   2.287 160.398  1.00146.00        HABE\n\
                 ATOM   3111  OH2 TIP3    1     -28.430 -30.303 -33.703  1.00  0.00      SOLV\n\
                 ENDMDL\nMODEL        2\n\
                 ATOM      1  CA AGLY A   1       1.000   1.000   1.000  0.50  1.00           C\n\
                 ENDMDL\n",
            ),
            (
                Format::Cif,
                "data_x\nloop_\n_atom_site.id\n_atom_site.type_symbol\n_atom_site.label_alt_id\n\
                 _atom_site.label_asym_id\n_atom_site.Cartn_x\n_atom_site.Cartn_y\n_atom_site.Cartn_z\n\
                 _atom_site.pdbx_PDB_model_num\n1 C . A 1.0 2.0 3.0 1\n2 'O' A A 1 2 3 1\n\
                 3 N . B 1 2 3 2\n#\n_pdbx_struct_oper_list.id 1\n\
                 _pdbx_struct_oper_list.matrix[1][1] 1\n_pdbx_struct_assembly_gen.assembly_id 1\n\
                 _pdbx_struct_assembly_gen.oper_expression '(1)'\n_pdbx_struct_assembly_gen.asym_id_list A\n",
            ),
            (
                Format::Gro,
                "t\n 2\n    1SOL     OW    1   0.126   1.624   1.679\n    2NA      NA    2   1.000   2.000   3.000\n 1 1 1\n",
            ),
            (Format::Xyz, "2\nc\nO 0 0 0\nH 0.96 0 0\n1\nf2\nC 1 1 1\n"),
            (Format::Xyzr, "# c\n1 2 3 1.5 7 8\n4 5 6 0.5 # t\n"),
        ];
        let opts = [
            LoadOptions::default(),
            LoadOptions {
                model: ModelSelect::All,
                assembly: Some(1),
                color_by: ColorBy::Chain,
            },
            LoadOptions {
                model: ModelSelect::Index(2),
                ..LoadOptions::default()
            },
        ];
        let mut rng = 0x1234_5678_9abc_def0u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let alphabet = b" \n\r\t.-+0123456789eE'\";#_ABCXYZnai\xff\xc3";
        for (format, text) in samples {
            let bytes = text.as_bytes();
            for o in &opts {
                for cut in 0..bytes.len() {
                    let _ = parse_bytes(&bytes[..cut], format, "f", o);
                }
                for _ in 0..2000 {
                    let mut m = bytes.to_vec();
                    for _ in 0..1 + next() % 4 {
                        let i = (next() % m.len() as u64) as usize;
                        m[i] = alphabet[(next() % alphabet.len() as u64) as usize];
                    }
                    let _ = parse_bytes(&m, format, "f", o);
                }
            }
        }
    }

    #[test]
    fn error_messages_name_file_and_line() {
        let err = parse_error("a.pdb", 7, "bad x");
        assert_eq!(err.to_string(), "a.pdb:7: bad x");
        assert_eq!(
            SceneError::UnknownScene("foo".into()).to_string(),
            "unknown procedural scene 'foo' (expected capsid, lattice, random)"
        );
    }
}
