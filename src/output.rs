//! What `render`/`bench` write: AOV images (DESIGN.md encodings), PNG files
//! written atomically (never a partial PNG), and the JSON stats record.

use crate::error::{Error, Result};
use crate::gpu::VIS_EMPTY;
use crate::settings::Aov;
use crate::stages::shadows::deep::DeepStats;
use crate::vk::PassTimes;
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::Path;

/// An encoded AOV image ready to be written.
pub enum AovImage {
    Rgba8(image::RgbaImage),
    /// `--png-depth 16` colour.
    Rgba16(image::ImageBuffer<image::Rgba<u16>, Vec<u16>>),
    Gray16(image::ImageBuffer<image::Luma<u16>, Vec<u16>>),
    Gray8(image::GrayImage),
}

impl AovImage {
    /// SHA-256 of the raw pixel bytes (format independent of PNG encoder).
    pub fn sha256(&self) -> String {
        let mut h = Sha256::new();
        self.hash_into(&mut h);
        format!("{:x}", h.finalize())
    }

    /// Feeds the raw pixel bytes to `h`: the bands of an image, fed in
    /// order, hash as the whole image does.
    pub fn hash_into(&self, h: &mut Sha256) {
        match self {
            AovImage::Rgba8(i) => h.update(i.as_raw()),
            AovImage::Rgba16(i) => h.update(bytemuck::cast_slice::<u16, u8>(i.as_raw())),
            AovImage::Gray16(i) => h.update(bytemuck::cast_slice::<u16, u8>(i.as_raw())),
            AovImage::Gray8(i) => h.update(i.as_raw()),
        }
    }

    fn height(&self) -> u32 {
        match self {
            AovImage::Rgba8(i) => i.height(),
            AovImage::Rgba16(i) => i.height(),
            AovImage::Gray16(i) => i.height(),
            AovImage::Gray8(i) => i.height(),
        }
    }

    fn width(&self) -> u32 {
        match self {
            AovImage::Rgba8(i) => i.width(),
            AovImage::Rgba16(i) => i.width(),
            AovImage::Gray16(i) => i.width(),
            AovImage::Gray8(i) => i.width(),
        }
    }

    /// The PNG colour type and depth, and the rows as PNG bytes (16-bit
    /// samples big-endian).
    fn png_rows(&self) -> (png::ColorType, png::BitDepth, std::borrow::Cow<'_, [u8]>) {
        use png::{BitDepth, ColorType};
        let be = |v: &[u16]| -> Vec<u8> { v.iter().flat_map(|x| x.to_be_bytes()).collect() };
        match self {
            AovImage::Rgba8(i) => (ColorType::Rgba, BitDepth::Eight, i.as_raw().into()),
            AovImage::Rgba16(i) => (ColorType::Rgba, BitDepth::Sixteen, be(i.as_raw()).into()),
            AovImage::Gray16(i) => (
                ColorType::Grayscale,
                BitDepth::Sixteen,
                be(i.as_raw()).into(),
            ),
            AovImage::Gray8(i) => (ColorType::Grayscale, BitDepth::Eight, i.as_raw().into()),
        }
    }

    /// The PNG file's bytes. The same encoder, settings and row-by-row
    /// stream as [`PngStream`], so a tiled render's streamed file and the
    /// whole image's bytes are identical (Python's `encode_png` relies on it).
    pub fn png_bytes(&self) -> Result<Vec<u8>> {
        use std::io::Write;
        let (color, depth, bytes) = self.png_rows();
        let out = SharedBytes::default();
        let mut w = png_writer(out.clone(), self.width(), self.height(), color, depth)
            .map_err(|e| Error::Internal(format!("PNG encoding: {e}")))?;
        let row = bytes.len() / self.height().max(1) as usize;
        for r in bytes.chunks(row.max(1)) {
            w.write_all(r)
                .map_err(|e| Error::Internal(format!("PNG encoding: {e}")))?;
        }
        w.finish()
            .map_err(|e| Error::Internal(format!("PNG encoding: {e}")))?;
        Ok(out.0.take())
    }

    /// Writes a PNG atomically ([`write_atomic`]).
    pub fn save_png(&self, path: &Path) -> Result<()> {
        let bytes = self.png_bytes()?;
        write_atomic(path, |tmp| {
            std::fs::write(tmp, &bytes)
                .map_err(|e| Error::Input(format!("{}: cannot write PNG: {e}", shown(path))))
        })
    }
}

/// A PNG written band by band, rows in order, so host memory holds one
/// band of a huge image, not the image. The encoder starts with the first
/// band (its colour type and depth).
pub struct PngStream {
    file: Option<std::fs::File>,
    writer: Option<png::StreamWriter<'static, std::fs::File>>,
    width: u32,
    height: u32,
    rows: u32,
    shown: String,
}

impl PngStream {
    pub fn create(path: &Path, width: u32, height: u32) -> Result<Self> {
        let file = std::fs::File::create(path)
            .map_err(|e| Error::Input(format!("{}: cannot write PNG: {e}", shown(path))))?;
        Ok(PngStream {
            file: Some(file),
            writer: None,
            width,
            height,
            rows: 0,
            shown: shown(path),
        })
    }

    fn err(&self, e: impl std::fmt::Display) -> Error {
        Error::Input(format!("{}: cannot write PNG: {e}", self.shown))
    }

    /// Appends the rows of `band` (the image's width, the next rows).
    pub fn write(&mut self, band: &AovImage) -> Result<()> {
        use std::io::Write;
        let (color, depth, bytes) = band.png_rows();
        if band.width() != self.width {
            return Err(Error::Internal(format!(
                "a band {} px wide for a {} px PNG",
                band.width(),
                self.width
            )));
        }
        if self.writer.is_none() {
            let file = self
                .file
                .take()
                .ok_or_else(|| self.err("already finished"))?;
            let w =
                png_writer(file, self.width, self.height, color, depth).map_err(|e| self.err(e))?;
            self.writer = Some(w);
        }
        let row = bytes.len() / band_rows(band).max(1) as usize;
        self.rows += band_rows(band);
        let w = self
            .writer
            .as_mut()
            .ok_or_else(|| Error::Internal("PNG writer".into()))?;
        for r in bytes.chunks(row.max(1)) {
            w.write_all(r)
                .map_err(|e| Error::Input(format!("cannot write PNG: {e}")))?;
        }
        Ok(())
    }

    /// Ends the file (every row must have been written).
    pub fn finish(mut self) -> Result<()> {
        if self.rows != self.height {
            return Err(Error::Internal(format!(
                "{} of {} PNG rows written",
                self.rows, self.height
            )));
        }
        let w = self.writer.take().ok_or_else(|| self.err("no rows"))?;
        w.finish().map_err(|e| self.err(e))
    }
}

/// An in-memory sink the stream writer can own (its writer is `'static`).
#[derive(Clone, Default)]
struct SharedBytes(std::rc::Rc<std::cell::RefCell<Vec<u8>>>);

impl std::io::Write for SharedBytes {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// The one PNG encoder configuration every file goes through.
fn png_writer<W: std::io::Write + 'static>(
    out: W,
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
) -> std::result::Result<png::StreamWriter<'static, W>, png::EncodingError> {
    let mut enc = png::Encoder::new(out, width, height);
    enc.set_color(color);
    enc.set_depth(depth);
    enc.write_header()?.into_stream_writer()
}

fn band_rows(img: &AovImage) -> u32 {
    match img {
        AovImage::Rgba8(i) => i.height(),
        AovImage::Rgba16(i) => i.height(),
        AovImage::Gray16(i) => i.height(),
        AovImage::Gray8(i) => i.height(),
    }
}

/// A path or any text quoted from input, safe to print on one line:
/// control characters (ESC, BEL, newlines...) and other non-printable
/// characters are escaped (`\x1b`, `\n`, `\u{200b}`), so neither a hostile
/// file nor a file name can inject terminal sequences or split a line.
pub fn printable(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 || c == '\x7f' => out.push_str(&format!("\\x{:02x}", c as u32)),
            c if c.is_control()
                || matches!(c as u32, 0x200b..=0x200f | 0x2028..=0x202e | 0x2066..=0x2069 | 0xfeff) =>
            {
                out.push_str(&format!("\\u{{{:x}}}", c as u32))
            }
            c => out.push(c),
        }
    }
    out
}

/// A path for a message (see [`printable`]).
pub fn shown(p: &Path) -> String {
    printable(&p.display().to_string())
}

/// One file a command will write: the option naming it, its path and
/// the extensions it may have.
pub struct OutFile<'a> {
    pub flag: &'static str,
    pub path: &'a Path,
    pub extensions: &'static [&'static str],
}

/// Checks every output of a command before any work is done: the
/// extension, an existing writable directory (a probe file is created and
/// removed), not a directory itself, and no two outputs naming one file.
pub fn check_outputs(files: &[OutFile]) -> Result<()> {
    let mut seen: Vec<(std::path::PathBuf, &str)> = Vec::new();
    for f in files {
        let p = f.path;
        let bad = |why: String| Error::Input(format!("{} {}: {why}", f.flag, shown(p)));
        let ext = p
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        if !f
            .extensions
            .iter()
            .any(|want| ext.as_deref() == Some(*want))
        {
            let want: Vec<String> = f.extensions.iter().map(|e| format!(".{e}")).collect();
            return Err(bad(format!("expected a {} file name", want.join(" or "))));
        }
        if p.file_name().is_none() || p.is_dir() {
            return Err(bad("is a directory, not a file name".into()));
        }
        let dir = match p.parent().filter(|d| !d.as_os_str().is_empty()) {
            Some(d) => d.to_path_buf(),
            None => std::path::PathBuf::from("."),
        };
        if !dir.is_dir() {
            return Err(bad(format!("directory {} does not exist", shown(&dir))));
        }
        let probe = dir.join(format!(".sphereshade-probe-{}", std::process::id()));
        match std::fs::File::create(&probe) {
            Ok(_) => {
                let _ = std::fs::remove_file(&probe);
            }
            Err(e) => {
                return Err(bad(format!("cannot write in {}: {e}", shown(&dir))));
            }
        }
        // The same file under two names: compare canonical directories
        // and the file names.
        let canon = std::fs::canonicalize(&dir)
            .unwrap_or(dir)
            .join(p.file_name().unwrap_or_default());
        let canon = std::fs::canonicalize(&canon).unwrap_or(canon);
        if let Some((_, other)) = seen.iter().find(|(c, _)| *c == canon) {
            return Err(bad(format!(
                "is also the {other} file; give each output its own file"
            )));
        }
        seen.push((canon, f.flag));
    }
    Ok(())
}

/// Writes `path` through a temporary file in the same directory, renamed
/// into place when `write` succeeds: a reader never sees a partial file,
/// and the temporary file is removed on every error path.
pub fn write_atomic(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let file_name = path
        .file_name()
        .ok_or_else(|| Error::Input(format!("{}: not a file name", shown(path))))?;
    let tmp = path.with_file_name(format!(
        ".{}.{}.tmp",
        file_name.to_string_lossy(),
        std::process::id()
    ));
    let done = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|e| Error::Io {
            path: shown(path),
            source: e,
        })
    });
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

/// `color`: RGBA8 from the composite buffer.
pub fn color_image(w: u32, h: u32, color: &[u32]) -> AovImage {
    let bytes: Vec<u8> = color.iter().flat_map(|c| c.to_le_bytes()).collect();
    AovImage::Rgba8(
        image::RgbaImage::from_raw(w, h, bytes).unwrap_or_else(|| image::RgbaImage::new(w, h)),
    )
}

/// Writes a single-part OpenEXR of `w` x `h` f32 channels, atomically
/// (the layer names of DESIGN.md: `R,G,B,A`, `depth`, `id`, ...).
pub fn write_exr(path: &Path, w: u32, h: u32, channels: Vec<(&str, Vec<f32>)>) -> Result<()> {
    let names: Vec<&str> = channels.iter().map(|c| c.0).collect();
    write_exr_bands(path, w, h, &names, &mut |band| band(0, &channels))
}

/// A band of EXR rows: its first row and its channels (each `w` x rows
/// f32, in the order of the names given to `write_exr_bands`).
pub type ExrBand<'a> = dyn FnMut(u32, &[(&str, Vec<f32>)]) -> Result<()> + 'a;

/// `write_exr` with the pixels produced band by band: `produce` is called
/// once with a sink taking bands top to bottom. Scan-line blocks of one row
/// (RLE), so the file holds one band at a time, never the image.
pub fn write_exr_bands(
    path: &Path,
    w: u32,
    h: u32,
    names: &[&str],
    produce: &mut dyn FnMut(&mut ExrBand<'_>) -> Result<()>,
) -> Result<()> {
    use exr::block::{BlockIndex, UncompressedBlock, writer::ChunksWriter};
    use exr::meta::BlockDescription;
    use exr::meta::attribute::{ChannelDescription, ChannelList, SampleType};
    use exr::meta::header::Header;
    use exr::prelude::{Compression, LineOrder, SmallVec, Vec2};
    let exr_err = |e: &dyn std::fmt::Display| {
        crate::error::Error::Input(format!("{}: cannot write EXR: {e}", shown(path)))
    };
    // OpenEXR stores channels sorted by name; `order[k]` is the band index
    // of the k-th stored channel.
    let mut order: Vec<usize> = (0..names.len()).collect();
    order.sort_by(|&a, &b| names[a].as_bytes().cmp(names[b].as_bytes()));
    let mut list = SmallVec::new();
    for &k in &order {
        let name = exr::meta::attribute::Text::new_or_none(names[k])
            .ok_or_else(|| exr_err(&format!("channel name {:?}", names[k])))?;
        list.push(ChannelDescription::new(name, SampleType::F32, true));
    }
    let size = Vec2(w as usize, h as usize);
    let mut header = Header::new(exr::meta::attribute::Text::default(), size, SmallVec::new());
    header.channels = ChannelList::new(list);
    let header = header.with_encoding(
        Compression::RLE,
        BlockDescription::ScanLines,
        LineOrder::Increasing,
    );
    let headers: exr::meta::Headers = SmallVec::from_vec(vec![header]);
    write_atomic(path, |tmp| {
        let file = std::fs::File::create(tmp).map_err(|e| exr_err(&e))?;
        let mut failed = None;
        let mut next = 0u32;
        let written = exr::block::write(
            std::io::BufWriter::new(file),
            headers,
            true,
            |meta, chunks| {
                let mut blocks = chunks.sequential_blocks_compressor(&meta);
                let mut sink = |y0: u32, band: &[(&str, Vec<f32>)]| -> Result<()> {
                    let rows = band.first().map_or(0, |c| c.1.len() / w.max(1) as usize);
                    if y0 != next || band.len() != names.len() {
                        return Err(crate::error::Error::Internal(format!(
                            "EXR band at row {y0} (expected {next})"
                        )));
                    }
                    for r in 0..rows {
                        let mut data = Vec::with_capacity(w as usize * 4 * names.len());
                        for &k in &order {
                            let line = &band[k].1[r * w as usize..(r + 1) * w as usize];
                            data.extend_from_slice(bytemuck::cast_slice(line));
                        }
                        let y = y0 as usize + r;
                        let index = BlockIndex {
                            layer: 0,
                            pixel_position: Vec2(0, y),
                            pixel_size: Vec2(w as usize, 1),
                            level: Vec2(0, 0),
                        };
                        blocks
                            .compress_block(y, UncompressedBlock { index, data })
                            .map_err(|e| exr_err(&e))?;
                    }
                    next = y0 + rows as u32;
                    Ok(())
                };
                if let Err(e) = produce(&mut sink) {
                    failed = Some(e);
                    return Err(exr::error::Error::Aborted);
                }
                Ok(())
            },
        );
        if let Some(e) = failed {
            return Err(e);
        }
        written.map_err(|e| exr_err(&e))?;
        if next != h {
            return Err(crate::error::Error::Internal(format!(
                "EXR of {h} rows got {next}"
            )));
        }
        Ok(())
    })
}

/// `color` at 16 bits per channel from the RGBA16 colour buffer (two
/// words per pixel: R|G<<16, B|A<<16).
pub fn color16_image(w: u32, h: u32, words: &[u32]) -> AovImage {
    let data: Vec<u16> = words
        .iter()
        .flat_map(|&x| [(x & 0xFFFF) as u16, (x >> 16) as u16])
        .collect();
    AovImage::Rgba16(
        image::ImageBuffer::from_raw(w, h, data).unwrap_or_else(|| image::ImageBuffer::new(w, h)),
    )
}

/// The box filter of `--ssaa n`: images of the same pixels at n x n
/// sub-pixel positions summed in linear colour (the shader's encoding is a
/// 2.2 power), colour weighted by alpha (coverage); `finish` gives their
/// average in the buffer layout: one word per pixel (RGBA8) or two
/// (RGBA16, `wide`).
pub struct Accumulator {
    acc: Vec<[f32; 4]>,
    samples: u32,
    wide: bool,
    /// 8-bit code -> linear value.
    lut8: Vec<f32>,
}

impl Accumulator {
    pub fn new(pixels: usize, wide: bool) -> Self {
        Accumulator {
            acc: vec![[0.0; 4]; pixels],
            samples: 0,
            wide,
            lut8: (0..256).map(|v| (v as f32 / 255.0).powf(2.2)).collect(),
        }
    }

    pub fn add(&mut self, words: &[u32]) {
        let lut8 = &self.lut8;
        for (i, a) in self.acc.iter_mut().enumerate() {
            let c = if self.wide {
                let (x, y) = (words[2 * i], words[2 * i + 1]);
                let c = [x & 0xFFFF, x >> 16, y & 0xFFFF, y >> 16].map(|v| v as f32 / 65535.0);
                [c[0].powf(2.2), c[1].powf(2.2), c[2].powf(2.2), c[3]]
            } else {
                let c = words[i].to_le_bytes();
                [
                    lut8[c[0] as usize],
                    lut8[c[1] as usize],
                    lut8[c[2] as usize],
                    c[3] as f32 / 255.0,
                ]
            };
            for k in 0..3 {
                a[k] += c[k] * c[3];
            }
            a[3] += c[3];
        }
        self.samples += 1;
    }

    pub fn finish(&self) -> Vec<u32> {
        let n = self.samples.max(1) as f32;
        let per = if self.wide { 2 } else { 1 };
        let mut out = vec![0u32; self.acc.len() * per];
        for (o, acc) in self.acc.iter().enumerate() {
            let a = acc[3] / n;
            let enc = |k: usize| {
                if acc[3] > 0.0 {
                    (acc[k] / acc[3]).clamp(0.0, 1.0).powf(1.0 / 2.2)
                } else {
                    0.0
                }
            };
            if self.wide {
                let q = |v: f32| (v * 65535.0 + 0.5) as u32;
                out[2 * o] = q(enc(0)) | (q(enc(1)) << 16);
                out[2 * o + 1] = q(enc(2)) | (q(a) << 16);
            } else {
                let q = |v: f32| (v * 255.0 + 0.5) as u32;
                out[o] = q(enc(0)) | (q(enc(1)) << 8) | (q(enc(2)) << 16) | (q(a) << 24);
            }
        }
        out
    }
}

/// Sphere index per pixel from the visibility buffer (None = background).
pub fn ids_from_vis(vis: &[u64]) -> Vec<Option<u32>> {
    vis.iter()
        .map(|&k| (k != VIS_EMPTY).then_some((k & 0xFFFF_FFFF) as u32))
        .collect()
}

/// Scenes of this many spheres or more get the wide id AOV.
pub const WIDE_IDS: u64 = 1 << 24;

/// `id`: (index + 1) little-endian in R, G, B; A = 255; background
/// 0,0,0,255. A scene of `spheres` >= 2^24 (DESIGN.md): RGBA16, index + 1
/// in R (bits 0-15), G (16-31), B (32-47), A = 65535. `visible`: each
/// pixel's sphere as an index in expanded order (None: background).
pub fn id_image(
    w: u32,
    h: u32,
    visible: &[Option<u64>],
    spheres: u64,
    ids: Option<&crate::scene::paint::IdMap>,
) -> AovImage {
    let spheres = ids.and_then(|m| m.total()).unwrap_or(spheres);
    let input = |id: Option<u64>| id.map(|i| ids.map_or(i, |m| m.input(i)));
    if spheres >= WIDE_IDS {
        let mut img = image::ImageBuffer::<image::Rgba<u16>, Vec<u16>>::new(w, h);
        for (p, &id) in img.pixels_mut().zip(visible) {
            let v = input(id).map_or(0, |i| i + 1);
            *p = image::Rgba([v as u16, (v >> 16) as u16, (v >> 32) as u16, 65535]);
        }
        return AovImage::Rgba16(img);
    }
    let mut img = image::RgbaImage::new(w, h);
    for (p, &id) in img.pixels_mut().zip(visible) {
        let v = input(id).map_or(0, |i| i + 1);
        *p = image::Rgba([
            (v & 0xFF) as u8,
            ((v >> 8) & 0xFF) as u8,
            ((v >> 16) & 0xFF) as u8,
            255,
        ]);
    }
    AovImage::Rgba8(img)
}

/// `depth`: 16-bit, 0 = nearest visible depth in the frame, 65534 = farthest,
/// 65535 = background. `depth` is the G-buffer depth key (< 0 = background).
pub fn depth_image(w: u32, h: u32, depth: &[f32]) -> AovImage {
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for &d in depth.iter().filter(|d| **d >= 0.0) {
        lo = lo.min(d);
        hi = hi.max(d);
    }
    let span = (hi - lo).max(f32::MIN_POSITIVE);
    let data = depth
        .iter()
        .map(|&d| {
            if d < 0.0 {
                65535
            } else {
                (((d - lo) / span) * 65534.0).round().clamp(0.0, 65534.0) as u16
            }
        })
        .collect();
    AovImage::Gray16(
        image::ImageBuffer::from_raw(w, h, data).unwrap_or_else(|| image::ImageBuffer::new(w, h)),
    )
}

/// 8-bit grayscale of a [0,1] quantity, background (mask false) = 255.
pub fn unit_image(w: u32, h: u32, values: impl Iterator<Item = f32>, covered: &[bool]) -> AovImage {
    let data = values
        .zip(covered)
        .map(|(v, &c)| {
            if c {
                (v.clamp(0.0, 1.0) * 255.0).round() as u8
            } else {
                255
            }
        })
        .collect();
    AovImage::Gray8(
        image::GrayImage::from_raw(w, h, data).unwrap_or_else(|| image::GrayImage::new(w, h)),
    )
}

pub fn aov_name(aov: Aov) -> String {
    aov.name()
}

#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct PassStats {
    pub name: String,
    pub median_ms: f64,
    pub min_ms: f64,
    pub max_ms: f64,
}

#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct TotalStats {
    pub median: f64,
    pub min: f64,
    pub max: f64,
}

/// Frames that reused the light-space structure (only the camera's passes
/// ran): per-pass medians and the frame total, as in the run object.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct CachedStats {
    pub passes: Vec<PassStats>,
    pub total_ms: TotalStats,
    /// Each measured frame's total, in order (see `RunStats::frame_ms`).
    #[serde(default)]
    pub frame_ms: Vec<f64>,
}

/// The camera a frame used (fitted or given), as DESIGN.md's `camera`.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct CameraStats {
    pub view_dir: [f64; 3],
    pub up: [f64; 3],
    pub view_center: [f64; 3],
    pub view_height: f64,
    pub fov: Option<f64>,
}

impl CameraStats {
    pub fn of(c: &crate::camera::Camera) -> Self {
        CameraStats {
            view_dir: c.dir.to_array(),
            up: c.up.to_array(),
            view_center: c.center.to_array(),
            view_height: c.view_height,
            fov: c.fov_deg,
        }
    }
}

/// One run, exactly the DESIGN.md JSON object.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct RunStats {
    pub device: String,
    pub driver: String,
    pub input: String,
    /// Spheres represented (an instanced scene's expanded count).
    pub spheres: u64,
    /// Instanced scenes (null otherwise): instances, molecule types and
    /// their atoms stored once.
    #[serde(default)]
    pub instances: Option<u64>,
    #[serde(default)]
    pub molecules: Option<u64>,
    #[serde(default)]
    pub unique_atoms: Option<u64>,
    /// A nested scene's placements (its `instances`, `molecules` and
    /// `unique_atoms` are then those of the scene the camera drew: the
    /// opened placements' instances and the proxies).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub placements: Option<u64>,
    /// An instanced model drawn expanded (`--expand`, bench `--instancing
    /// off`): one sphere record per atom.
    #[serde(default)]
    pub expanded: bool,
    /// Spheres the frame drew (after culling and level of detail; every
    /// represented sphere until those exist).
    #[serde(default)]
    pub spheres_drawn: u64,
    /// The camera used.
    #[serde(default)]
    pub camera: CameraStats,
    pub width: u32,
    pub height: u32,
    pub frames: u32,
    pub shadows: String,
    pub ssdo: String,
    pub raster: String,
    pub opacity: f64,
    pub passes: Vec<PassStats>,
    pub total_ms: TotalStats,
    pub load_ms: f64,
    pub gpu_memory_bytes: u64,
    /// `gpu_memory_bytes` by buffer class (an addition to DESIGN.md's object).
    #[serde(default)]
    pub gpu_memory: std::collections::BTreeMap<String, u64>,
    pub validation_messages: u32,
    pub deep: Option<DeepStats>,
    /// See-through spheres' fragment lists (null without any).
    pub see_through: Option<crate::stages::see_through::SeeThroughStats>,
    pub image_sha256: String,
    /// With a light-space technique, `bench` also measures frames that
    /// reuse its map/lists (camera moving, light fixed): an addition to
    /// DESIGN.md's object. A run without one that `bench` measured beside
    /// such runs holds its plain frames of those rounds here (the
    /// denominator of the cached ratio); null otherwise.
    #[serde(default)]
    pub light_cached: Option<CachedStats>,
    /// Each measured frame's `total_ms`, in order: an addition to
    /// DESIGN.md's object. `bench` renders frame k of the runs it compares
    /// in one round, so their k-th frames pair up (same moment, same orbit
    /// camera) and its ratios are medians of per-frame ratios.
    #[serde(default)]
    pub frame_ms: Vec<f64>,
}

pub(crate) fn median(v: &mut [f64]) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Median/min/max per pass (in first-frame order) and of the frame total.
pub fn summarize(frames: &[PassTimes]) -> (Vec<PassStats>, TotalStats) {
    let mut passes = Vec::new();
    if let Some(first) = frames.first() {
        for (name, _) in first.iter() {
            let mut v: Vec<f64> = frames
                .iter()
                .filter_map(|f| f.iter().find(|(n, _)| n == name).map(|(_, t)| *t))
                .collect();
            let (mn, mx) = (
                v.iter().cloned().fold(f64::MAX, f64::min),
                v.iter().cloned().fold(f64::MIN, f64::max),
            );
            passes.push(PassStats {
                name: name.to_string(),
                median_ms: median(&mut v),
                min_ms: mn,
                max_ms: mx,
            });
        }
    }
    let mut totals: Vec<f64> = frames.iter().map(|f| f.total_ms).collect();
    let (mn, mx) = (
        totals.iter().cloned().fold(f64::MAX, f64::min),
        totals.iter().cloned().fold(f64::MIN, f64::max),
    );
    let total = if totals.is_empty() {
        TotalStats {
            median: 0.0,
            min: 0.0,
            max: 0.0,
        }
    } else {
        TotalStats {
            median: median(&mut totals),
            min: mn,
            max: mx,
        }
    };
    (passes, total)
}

/// Writes JSON atomically ([`write_atomic`]).
pub fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let text =
        serde_json::to_string_pretty(value).map_err(|e| Error::Internal(format!("JSON: {e}")))?;
    write_atomic(path, |tmp| {
        std::fs::write(tmp, text + "\n").map_err(|e| Error::Io {
            path: shown(path),
            source: e,
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("sphereshade-out-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn entries(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn atomic_writes_leave_no_temporary_file_on_any_failure() {
        let d = scratch("atomic");
        // the writer fails
        let p = d.join("a.json");
        let e = write_atomic(&p, |tmp| {
            std::fs::write(tmp, b"partial").unwrap();
            Err(Error::Input("encoder failed".into()))
        });
        assert!(e.is_err());
        assert!(entries(&d).is_empty(), "{:?}", entries(&d));
        // the rename fails: the target is a non-empty directory
        let blocked = d.join("b.png");
        std::fs::create_dir_all(blocked.join("x")).unwrap();
        let e = write_atomic(&blocked, |tmp| {
            std::fs::write(tmp, b"png").map_err(|e| Error::Io {
                path: "t".into(),
                source: e,
            })
        });
        assert!(e.is_err());
        assert_eq!(entries(&d), vec!["b.png".to_string()]);
        // success: only the file
        write_json(&p, &serde_json::json!({"ok": true})).unwrap();
        assert_eq!(entries(&d), vec!["a.json".to_string(), "b.png".to_string()]);
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn outputs_are_checked_before_work() {
        let d = scratch("check");
        let png = d.join("o.png");
        let ok = [OutFile {
            flag: "--out",
            path: &png,
            extensions: &["png"],
        }];
        check_outputs(&ok).unwrap();
        assert!(entries(&d).is_empty(), "the probe file stayed");
        let same = d.join("./o.png");
        let twice = [
            OutFile {
                flag: "--out",
                path: &png,
                extensions: &["png"],
            },
            OutFile {
                flag: "--screenshot",
                path: &same,
                extensions: &["png"],
            },
        ];
        let e = check_outputs(&twice).unwrap_err().to_string();
        assert!(e.contains("also the --out file"), "{e}");
        let dir_itself = [OutFile {
            flag: "--out",
            path: &d,
            extensions: &["png", ""],
        }];
        assert!(check_outputs(&dir_itself).is_err());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn printable_escapes_control_characters() {
        assert_eq!(printable("a\nb\x1b[31m\x07"), "a\\nb\\x1b[31m\\x07");
        assert_eq!(printable("é ✓"), "é ✓");
        assert_eq!(printable("x\u{202e}y"), "x\\u{202e}y");
    }
}
