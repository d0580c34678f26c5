//! Scenes of spheres: loading molecular and particle files (PDB, mmCIF, GRO,
//! XYZ, XYZR, optionally gzip-compressed) and generating procedural scenes.
//!
//! Every sphere carries region ids for up to [`MAX_LEVELS`] hierarchy levels
//! (outermost first, e.g. model / chain / residue / atom). Ids are small
//! integers whose only meaning is equality: two spheres share a region at a
//! level exactly when their ids at that level are equal.

pub mod atoms;
pub mod bcif;
pub mod elements;
pub mod hybrid36;
pub mod instanced;
pub mod paint;
pub mod select;

mod cif;
mod gro;
pub(crate) mod lammps;
pub mod meso;
pub mod meso_json;
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
    /// The spheres; for an instanced scene the atoms of its molecule types,
    /// each in its own frame (`region[0]`: the chain within the molecule),
    /// never expanded: see [`Scene::for_each_sphere`].
    pub spheres: Vec<Sphere>,
    /// Names of the region levels in use, outermost first (len <= MAX_LEVELS).
    pub level_names: Vec<String>,
    /// File path, or "scene:NAME" for procedural scenes.
    pub source: String,
    /// Molecule types, instances and the hierarchy of an instanced scene.
    pub instancing: Option<instanced::Instancing>,
    /// Made by expanding an instanced scene ([`Scene::expand`]): one sphere
    /// record per represented atom (the JSON says so).
    pub expanded: bool,
    /// What selections read per sphere record (files that name atoms).
    pub atoms: Option<atoms::Atoms>,
    /// After `--hide`: where the spheres kept came from in input order
    /// (what the id AOV names). None: nothing hidden.
    pub origin: Option<Origin>,
}

/// The input-order index of the spheres a subset kept.
#[derive(Clone, Debug, PartialEq)]
pub enum Origin {
    /// Plain: per sphere record, and the count as loaded.
    Plain { index: Vec<u32>, total: u64 },
    /// Instanced: per instance kept its index and first atom's input
    /// index as loaded, per stored atom its index in its molecule as
    /// loaded.
    Instanced {
        instance: Vec<u32>,
        first: Vec<u64>,
        atom: Vec<u32>,
        /// Spheres represented as loaded.
        total: u64,
    },
}

impl Scene {
    /// A scene of these spheres (not instanced).
    pub fn plain(
        spheres: Vec<Sphere>,
        level_names: Vec<String>,
        source: impl Into<String>,
    ) -> Self {
        Scene {
            spheres,
            level_names,
            source: source.into(),
            instancing: None,
            expanded: false,
            atoms: None,
            origin: None,
        }
    }

    /// Component-wise min and max of the sphere centres (None if empty).
    pub fn center_bounds(&self) -> Option<(Vec3, Vec3)> {
        if let Some(n) = self.nesting() {
            // (the block's centre box placed: its corners' box)
            let (lo, hi) = self.extremes()?.center_bounds()?;
            return n.placed_box(lo, hi);
        }
        if let Some(e) = self.extremes() {
            return e.center_bounds();
        }
        let mut b: Option<(Vec3, Vec3)> = None;
        self.for_each_geometry(|c, _| {
            let c = Vec3::from(c);
            b = Some(b.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
        });
        b
    }

    /// Sphere enclosing every sphere: centred on the centre of the bounding
    /// box of the centres (the default view centre), radius reaching the
    /// farthest sphere surface. `(0, 0)` for an empty scene.
    pub fn bounding_sphere(&self) -> (Vec3, f32) {
        if let Some(n) = self.nesting() {
            let b = self.extremes().and_then(|e| e.bounding_sphere());
            return b.map_or((Vec3::ZERO, 0.0), |(c, r)| n.placed_sphere(c, r));
        }
        if let Some(e) = self.extremes() {
            return e.bounding_sphere().unwrap_or((Vec3::ZERO, 0.0));
        }
        let Some((lo, hi)) = self.center_bounds() else {
            return (Vec3::ZERO, 0.0);
        };
        let c = (lo + hi) * 0.5;
        let mut r = 0.0f32;
        self.for_each_geometry(|p, radius| r = r.max(Vec3::from(p).distance(c) + radius));
        (c, r)
    }

    /// The placements of a nested scene.
    pub fn nesting(&self) -> Option<&instanced::nested::Nesting> {
        self.instancing.as_ref()?.nesting.as_ref()
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
                instancing: None,
                expanded: false,
                atoms: None,
                origin: None,
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
            instancing: None,
            expanded: false,
            atoms: None,
            origin: None,
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
        "{path}: unknown file extension (expected .pdb, .ent, .cif, .mmcif, .bcif, .gro, .xyz, .xyzr, .lammpstrj, .dump, .json, optionally .gz)"
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
    /// BinaryCIF (mmCIF categories in a MessagePack container).
    Bcif,
    /// A cellPACK packing result or a mesoscale manifest.
    Json,
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
            "bcif" => Format::Bcif,
            "json" => Format::Json,
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
    if matches!(format, Format::Bcif | Format::Json) {
        // Binary containers and JSON are read whole (their files are small:
        // the molecules are stored once).
        let mut data = Vec::new();
        let mut reader = reader;
        let mut chunk = vec![0u8; 1 << 16];
        loop {
            let n = reader.read(&mut chunk).map_err(io_err)?;
            if n == 0 {
                break;
            }
            data.extend_from_slice(&chunk[..n]);
            progress(done.get(), total);
        }
        progress(total, total);
        return parse_whole(&data, format, &name, path.parent(), opts);
    }
    let mut src = text::LineSource::new(reader, &name, done, total, progress);
    parse_source(&mut src, format, &name, opts)
}

/// A BinaryCIF or JSON file already in memory; `dir` is where relative
/// paths of a manifest start.
fn parse_whole(
    data: &[u8],
    format: Format,
    name: &str,
    dir: Option<&Path>,
    opts: &LoadOptions,
) -> Result<Scene, SceneError> {
    let scene = match format {
        Format::Bcif => cif::parse_bcif(data, name, opts)?,
        _ => meso_json::parse(data, name, dir.unwrap_or(Path::new(".")), opts)?,
    };
    check_loaded(scene, name)
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
    if matches!(format, Format::Bcif | Format::Json) {
        return parse_whole(data, format, name, None, opts);
    }
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
        Format::Bcif | Format::Json => {
            return Err(SceneError::Invalid(format!(
                "{name}: internal: a whole-file format read as lines"
            )));
        }
    };
    check_loaded(scene, name)
}

/// The empty and too-large checks every loaded scene passes.
fn check_loaded(scene: Scene, name: &str) -> Result<Scene, SceneError> {
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
mod tests;
