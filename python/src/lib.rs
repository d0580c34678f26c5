//! `import sphereshade` (DESIGN.md "Python"): numpy arrays in, images out,
//! through the library the CLI uses. Options are the CLI's (`issm_t=1` is
//! `--issm-t 1`), parsed by the same clap definitions, so a bad value gives
//! the CLI's message as a `ValueError`. Rendering releases the GIL; a
//! Renderer is locked while in use, so two Python threads can share one.

use clap::Parser;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyAny, PyBool, PyDict, PyList, PyTuple};
use sphereshade::output::AovImage;
use sphereshade::render::Renderer as RustRenderer;
use sphereshade::scene::{self, Scene as RustScene};
use sphereshade::settings::{Aov, Axes, Options};
use sphereshade::vk::{Context, ContextOptions};
use std::sync::Mutex;

/// The CLI's rendering options, parsed from keyword arguments.
#[derive(Parser, Debug)]
#[command(name = "sphereshade", no_binary_name = true)]
struct PyOptions {
    #[command(flatten)]
    axes: Axes,
    #[command(flatten)]
    options: Options,
    #[arg(long, value_enum, default_value = "color")]
    aov: Aov,
}

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// The one-line message of a library error (as the CLI prints it).
fn lib_error(e: sphereshade::Error) -> PyErr {
    match e {
        sphereshade::Error::Input(_)
        | sphereshade::Error::Scene(_)
        | sphereshade::Error::Traj(_) => value_error(e),
        other => PyRuntimeError::new_err(other.to_string()),
    }
}

/// `key=value` keyword arguments as CLI words (`view_dir=(0, 0, -1)` is
/// `--view-dir 0,0,-1`, `validate=True` is `--validate`).
fn kwargs_to_args(kwargs: Option<&Bound<'_, PyDict>>) -> PyResult<Vec<String>> {
    let mut args = Vec::new();
    let Some(kw) = kwargs else { return Ok(args) };
    for (k, v) in kw.iter() {
        let key: String = k.extract()?;
        let flag = format!("--{}", key.replace('_', "-"));
        if v.is_none() {
            continue;
        }
        if let Ok(b) = v.downcast::<PyBool>() {
            if b.is_true() {
                args.push(flag);
            }
            continue;
        }
        let text = if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
            let parts: Vec<String> = v
                .try_iter()?
                .map(|x| x.and_then(|x| x.str().map(|s| s.to_string())))
                .collect::<PyResult<_>>()?;
            parts.join(",")
        } else {
            v.str()?.to_string()
        };
        // `--flag=value`: a negative value is the option's, not a flag
        args.push(format!("{flag}={text}"));
    }
    Ok(args)
}

fn parse_options(words: Vec<String>) -> PyResult<PyOptions> {
    PyOptions::try_parse_from(words).map_err(|e| {
        let text = e.render().to_string();
        let line = text.lines().next().unwrap_or("invalid option").trim();
        value_error(line.strip_prefix("error: ").unwrap_or(line))
    })
}

/// An (N, 3) float32/float64 array as positions; wrong shapes, dtypes and
/// NaN are a ValueError.
fn positions_of(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f32; 3]>> {
    let arr: PyReadonlyArray2<f32> = if let Ok(x) = a.extract::<PyReadonlyArray2<f32>>() {
        x
    } else if let Ok(x) = a.extract::<PyReadonlyArray2<f64>>() {
        let v: Vec<f32> = x.as_array().iter().map(|&v| v as f32).collect();
        let shape = x.shape().to_vec();
        let owned =
            numpy::ndarray::Array2::from_shape_vec((shape[0], shape[1]), v).map_err(value_error)?;
        return rows3(owned.view(), what);
    } else {
        return Err(value_error(format!(
            "{what} must be a 2-D float32 or float64 array of shape (N, 3)"
        )));
    };
    rows3(arr.as_array(), what)
}

fn rows3(a: numpy::ndarray::ArrayView2<f32>, what: &str) -> PyResult<Vec<[f32; 3]>> {
    if a.ncols() != 3 {
        return Err(value_error(format!(
            "{what} must have shape (N, 3), got {:?}",
            a.shape()
        )));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

fn vector_f32(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f32>> {
    if let Ok(x) = a.extract::<numpy::PyReadonlyArray1<f32>>() {
        return Ok(x.as_array().to_vec());
    }
    if let Ok(x) = a.extract::<numpy::PyReadonlyArray1<f64>>() {
        return Ok(x.as_array().iter().map(|&v| v as f32).collect());
    }
    Err(value_error(format!(
        "{what} must be a 1-D float32 or float64 array"
    )))
}

/// The scene of the arrays, checked as the CLI checks a file.
fn scene_of(
    positions: &Bound<'_, PyAny>,
    radii: &Bound<'_, PyAny>,
    colors: Option<&Bound<'_, PyAny>>,
    regions: Option<&Bound<'_, PyAny>>,
) -> PyResult<RustScene> {
    let p = positions_of(positions, "positions")?;
    let r = vector_f32(radii, "radii")?;
    let c: Option<Vec<[u8; 4]>> = match colors {
        None => None,
        Some(c) => {
            let a = c.extract::<PyReadonlyArray2<u8>>().map_err(|_| {
                value_error("colors must be a 2-D uint8 array of shape (N, 4) (RGBA)")
            })?;
            let a = a.as_array();
            if a.ncols() != 4 {
                return Err(value_error(format!(
                    "colors must have shape (N, 4), got {:?}",
                    a.shape()
                )));
            }
            Some(
                a.rows()
                    .into_iter()
                    .map(|r| [r[0], r[1], r[2], r[3]])
                    .collect(),
            )
        }
    };
    let g: Option<(Vec<u32>, usize)> = match regions {
        None => None,
        Some(g) => {
            let a = g.extract::<PyReadonlyArray2<u32>>().map_err(|_| {
                value_error("regions must be a 2-D uint32 array of shape (N, L), L <= 4")
            })?;
            let a = a.as_array();
            Some((a.iter().copied().collect(), a.ncols()))
        }
    };
    scene::from_arrays(
        &p,
        &r,
        c.as_deref(),
        g.as_ref().map(|(v, l)| (v.as_slice(), *l)),
        "arrays",
    )
    .map_err(value_error)
}

/// Vulkan state owned by one Python object: the context is boxed (its
/// address never changes) and the renderer, which borrows it, is dropped
/// first.
struct Inner {
    renderer: Option<RustRenderer<'static>>,
    ctx: Option<Box<Context>>,
    options: PyOptions,
    topology: RustScene,
    timings: Vec<(String, f64)>,
}

// SAFETY: every Vulkan object here is used by one thread at a time (the
// Mutex in `Renderer`), which is the external synchronisation Vulkan asks
// for; nothing is tied to the creating thread.
unsafe impl Send for Inner {}

impl Inner {
    fn new(scene: RustScene, options: PyOptions) -> Result<Self, sphereshade::Error> {
        let ctx = Box::new(Context::new(&ContextOptions {
            validate: options.options.validate,
            device_index: options.options.device,
            ..Default::default()
        })?);
        let mut settings = options.options.resolve(&options.axes, &scene)?;
        settings.aovs = matches!(options.aov, Aov::Shadow | Aov::Ao);
        // SAFETY: the renderer's borrow of the context is extended to
        // 'static; the context is boxed, never moved out while the renderer
        // lives, and `drop` / `close` drop the renderer first.
        let ctx_ref: &'static Context = unsafe { &*(ctx.as_ref() as *const Context) };
        let tile = settings.tile_size;
        let renderer = RustRenderer::new_windowed(ctx_ref, &scene, settings, tile)?;
        Ok(Inner {
            renderer: Some(renderer),
            ctx: Some(ctx),
            options,
            topology: scene,
            timings: Vec::new(),
        })
    }

    fn renderer_mut(&mut self) -> Result<&mut RustRenderer<'static>, sphereshade::Error> {
        self.renderer
            .as_mut()
            .ok_or_else(|| sphereshade::Error::Internal("the renderer was closed".into()))
    }

    fn set_positions(&mut self, p: &[[f32; 3]]) -> Result<(), sphereshade::Error> {
        self.renderer_mut()?.set_positions(p)?;
        // (camera defaults follow the spheres where they are now)
        for (s, q) in self.topology.spheres.iter_mut().zip(p) {
            s.center = *q;
        }
        Ok(())
    }

    fn render(&mut self) -> Result<AovImage, sphereshade::Error> {
        let aov = self.options.aov;
        let r = self.renderer_mut()?;
        // as `render` does it: supersampling (colour only) and tiles
        let s = r.settings();
        let n = s.ssaa_for(aov);
        let tile = s.tile_size;
        let (img, times) = sphereshade::run::render_supersampled(
            r,
            n,
            tile,
            Some(sphereshade::render::tiles::Keep::ALL),
            &mut |_, _| {},
        )?;
        let img = img.ok_or_else(|| sphereshade::Error::Internal("no image read back".into()))?;
        let image = sphereshade::run::image_aov(&img, aov);
        self.timings = times.iter().map(|(n, t)| (n.to_string(), *t)).collect();
        Ok(image)
    }

    /// Tears down the renderer and the device; the validation messages
    /// counted, leak reports included.
    fn close(&mut self) -> u32 {
        self.renderer = None;
        match self.ctx.take() {
            Some(ctx) => ctx.finish().0,
            None => 0,
        }
    }
}

impl Drop for Inner {
    fn drop(&mut self) {
        self.close();
    }
}

fn image_to_py<'py>(py: Python<'py>, image: AovImage) -> Bound<'py, PyAny> {
    match image {
        AovImage::Rgba8(i) => {
            let (w, h) = i.dimensions();
            let a =
                numpy::ndarray::Array3::from_shape_vec((h as usize, w as usize, 4), i.into_raw())
                    .expect("RGBA buffer of its size");
            a.into_pyarray(py).into_any()
        }
        AovImage::Rgba16(i) => {
            let (w, h) = i.dimensions();
            let a =
                numpy::ndarray::Array3::from_shape_vec((h as usize, w as usize, 4), i.into_raw())
                    .expect("RGBA16 buffer of its size");
            a.into_pyarray(py).into_any()
        }
        AovImage::Gray16(i) => {
            let (w, h) = i.dimensions();
            let a = numpy::ndarray::Array2::from_shape_vec((h as usize, w as usize), i.into_raw())
                .expect("grey buffer of its size");
            a.into_pyarray(py).into_any()
        }
        AovImage::Gray8(i) => {
            let (w, h) = i.dimensions();
            let a = numpy::ndarray::Array2::from_shape_vec((h as usize, w as usize), i.into_raw())
                .expect("grey buffer of its size");
            a.into_pyarray(py).into_any()
        }
    }
}

/// A renderer for one set of spheres: `render()` returns the image as a
/// numpy array (H, W, 4) uint8 for `aov="color"`/`"id"`, (H, W) for the
/// 16-bit and 8-bit AOVs; `set_positions` uploads a new trajectory frame.
#[pyclass(frozen, module = "sphereshade")]
struct Renderer {
    inner: Mutex<Inner>,
}

impl Renderer {
    /// Runs `f` on the locked state with the GIL released: waiting for the
    /// lock while holding the GIL would deadlock against a thread that
    /// holds the lock and needs the GIL back.
    fn with<R: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut Inner) -> Result<R, sphereshade::Error> + Send,
    ) -> PyResult<R> {
        py.allow_threads(|| {
            let mut g = self.inner.lock().map_err(|_| {
                sphereshade::Error::Internal("a previous call failed inside the renderer".into())
            })?;
            f(&mut g)
        })
        .map_err(lib_error)
    }
}

#[pymethods]
impl Renderer {
    /// `width`, `height`, `shadows`, `ssdo` and every other option come
    /// in `options` as the CLI's (their defaults: 1920x1080, issm-soft,
    /// semantic).
    #[new]
    #[pyo3(signature = (positions, radii, colors=None, regions=None, *, camera=None, **options))]
    fn new(
        py: Python<'_>,
        positions: &Bound<'_, PyAny>,
        radii: &Bound<'_, PyAny>,
        colors: Option<&Bound<'_, PyAny>>,
        regions: Option<&Bound<'_, PyAny>>,
        camera: Option<&Bound<'_, PyDict>>,
        options: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let scene = scene_of(positions, radii, colors, regions)?;
        let mut words: Vec<String> = Vec::new();
        words.extend(kwargs_to_args(camera)?);
        words.extend(kwargs_to_args(options)?);
        let opts = parse_options(words)?;
        let inner = py
            .allow_threads(|| Inner::new(scene, opts))
            .map_err(lib_error)?;
        Ok(Renderer {
            inner: Mutex::new(inner),
        })
    }

    /// Renders a frame (the GIL is released meanwhile) and returns the image.
    fn render<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let image = self.with(py, |inner| inner.render())?;
        Ok(image_to_py(py, image))
    }

    /// New centres, (N, 3) float32/float64, same N: a trajectory frame.
    fn set_positions(&self, py: Python<'_>, positions: &Bound<'_, PyAny>) -> PyResult<()> {
        let p = positions_of(positions, "positions")?;
        self.with(py, |inner| inner.set_positions(&p))
    }

    /// Moves the camera: `view_dir`, `up`, `view_center`, `view_height`,
    /// `fov` as in the CLI (unset ones: the defaults for these spheres at
    /// their current positions).
    #[pyo3(signature = (**camera))]
    fn set_camera(&self, py: Python<'_>, camera: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        let (w, h) = self.with(py, |inner| {
            Ok((inner.options.axes.width, inner.options.axes.height))
        })?;
        let mut words: Vec<String> = vec![
            "--width".into(),
            w.to_string(),
            "--height".into(),
            h.to_string(),
        ];
        words.extend(kwargs_to_args(camera)?);
        let opts = parse_options(words)?;
        self.with(py, move |inner| {
            let settings = opts.options.resolve(&opts.axes, &inner.topology)?;
            inner.renderer_mut()?.update(|s| s.camera = settings.camera)
        })
    }

    /// Milliseconds per pass of the last frame.
    #[getter]
    fn timings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let t = self.with(py, |inner| Ok(inner.timings.clone()))?;
        let d = PyDict::new(py);
        for (n, v) in t {
            d.set_item(n, v)?;
        }
        Ok(d)
    }

    /// Validation messages counted so far (with `validate=True`).
    #[getter]
    fn validation_messages(&self, py: Python<'_>) -> PyResult<u32> {
        self.with(py, |inner| {
            Ok(inner.ctx.as_ref().map_or(0, |c| c.validation_messages()))
        })
    }

    /// Frees the GPU objects now; returns the validation messages counted,
    /// leak reports at device destruction included. Later calls raise.
    fn close(&self, py: Python<'_>) -> PyResult<u32> {
        self.with(py, |inner| Ok(inner.close()))
    }
}

/// Spheres read from a file: `positions` (N, 3) float32, `radii` (N,),
/// `colors` (N, 4) uint8, `regions` (N, L) uint32, `level_names`.
#[pyclass(frozen, module = "sphereshade")]
struct Scene {
    scene: RustScene,
}

#[pymethods]
impl Scene {
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f32>> {
        let v: Vec<Vec<f32>> = self
            .scene
            .spheres
            .iter()
            .map(|s| s.center.to_vec())
            .collect();
        PyArray2::from_vec2(py, &v).expect("rows of 3")
    }
    #[getter]
    fn radii<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        let v: Vec<f32> = self.scene.spheres.iter().map(|s| s.radius).collect();
        v.into_pyarray(py)
    }
    #[getter]
    fn colors<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u8>> {
        let v: Vec<Vec<u8>> = self
            .scene
            .spheres
            .iter()
            .map(|s| s.color.to_vec())
            .collect();
        PyArray2::from_vec2(py, &v).expect("rows of 4")
    }
    #[getter]
    fn regions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<u32>> {
        let l = self.scene.level_names.len();
        let v: Vec<Vec<u32>> = self
            .scene
            .spheres
            .iter()
            .map(|s| s.region[..l].to_vec())
            .collect();
        if v.is_empty() || l == 0 {
            return numpy::ndarray::Array2::<u32>::zeros((self.scene.spheres.len(), l))
                .into_pyarray(py);
        }
        PyArray2::from_vec2(py, &v).expect("rows of L")
    }
    #[getter]
    fn level_names(&self) -> Vec<String> {
        self.scene.level_names.clone()
    }
    fn __len__(&self) -> usize {
        self.scene.spheres.len()
    }
    fn __repr__(&self) -> String {
        format!(
            "sphereshade.Scene({} spheres from {}, levels {:?})",
            self.scene.spheres.len(),
            self.scene.source,
            self.scene.level_names
        )
    }
}

/// Loads a structure file as the CLI does (`model`: a number or "all");
/// an instanced model comes expanded (one row per represented sphere).
/// `color`/`colormap` are `--color`/`--colormap`; `rules` is a list of
/// (kind, text) pairs, kind "hide", "paint" or "alpha", applied in order as
/// the CLI's `--hide`/`--paint`/`--alpha`; `hide`, `paint`, `alpha` (a
/// string or a list) are applied after them, in that order.
#[pyfunction]
#[pyo3(signature = (path, model=None, assembly=None, color="element", colormap="viridis",
                    rules=None, hide=None, paint=None, alpha=None))]
#[allow(clippy::too_many_arguments)]
fn load(
    py: Python<'_>,
    path: std::path::PathBuf,
    model: Option<&Bound<'_, PyAny>>,
    assembly: Option<u32>,
    color: &str,
    colormap: &str,
    rules: Option<Vec<(String, String)>>,
    hide: Option<&Bound<'_, PyAny>>,
    paint: Option<&Bound<'_, PyAny>>,
    alpha: Option<&Bound<'_, PyAny>>,
) -> PyResult<Scene> {
    let model = match model {
        None => None,
        Some(m) => Some(m.str()?.to_string()),
    };
    let colormap =
        <sphereshade::scene::paint::Colormap as clap::ValueEnum>::from_str(colormap, true)
            .map_err(|_| {
                value_error(format!(
                    "colormap '{colormap}': expected viridis, magma or turbo"
                ))
            })?;
    sphereshade::scene::paint::Scheme::parse(color)
        .map_err(|e| value_error(format!("color: {e}")))?;
    let mut args = sphereshade::run::SceneArgs {
        input: Some(path),
        model,
        assembly,
        color: color.to_string(),
        colormap,
        ..Default::default()
    };
    // one list in application order: rules, then hide, paint, alpha
    let mut all: Vec<(String, String)> = rules.unwrap_or_default();
    for (kind, v) in [("hide", hide), ("paint", paint), ("alpha", alpha)] {
        let Some(v) = v else { continue };
        let texts: Vec<String> = match v.extract::<String>() {
            Ok(one) => vec![one],
            Err(_) => v.extract()?,
        };
        all.extend(texts.into_iter().map(|t| (kind.to_string(), t)));
    }
    for (kind, text) in all {
        args.add_rule(&kind, &text).map_err(value_error)?;
    }
    let args = sphereshade::run::SceneArgs {
        expand: true,
        ..args
    };
    let (scene, _) = py
        .allow_threads(|| sphereshade::run::load_scene(&args))
        .map_err(lib_error)?;
    Ok(Scene { scene })
}

/// The PNG bytes the CLI would write for an image array (same encoder).
#[pyfunction]
fn encode_png<'py>(
    py: Python<'py>,
    image: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, pyo3::types::PyBytes>> {
    let img = if let Ok(a) = image.extract::<numpy::PyReadonlyArray3<u8>>() {
        let a = a.as_array();
        let (h, w, c) = a.dim();
        if c != 4 {
            return Err(value_error(
                "expected (H, W, 4) uint8 or (H, W) uint8/uint16",
            ));
        }
        let raw: Vec<u8> = a.iter().copied().collect();
        AovImage::Rgba8(
            image::RgbaImage::from_raw(w as u32, h as u32, raw)
                .ok_or_else(|| value_error("size"))?,
        )
    } else if let Ok(a) = image.extract::<PyReadonlyArray2<u16>>() {
        let a = a.as_array();
        let (h, w) = a.dim();
        AovImage::Gray16(
            image::ImageBuffer::from_raw(w as u32, h as u32, a.iter().copied().collect())
                .ok_or_else(|| value_error("size"))?,
        )
    } else if let Ok(a) = image.extract::<PyReadonlyArray2<u8>>() {
        let a = a.as_array();
        let (h, w) = a.dim();
        AovImage::Gray8(
            image::GrayImage::from_raw(w as u32, h as u32, a.iter().copied().collect())
                .ok_or_else(|| value_error("size"))?,
        )
    } else {
        return Err(value_error(
            "expected (H, W, 4) uint8 or (H, W) uint8/uint16",
        ));
    };
    let bytes = img.png_bytes().map_err(lib_error)?;
    Ok(pyo3::types::PyBytes::new(py, &bytes))
}

/// SHA-256 of an image's raw pixel bytes (the JSON's `image_sha256`).
#[pyfunction]
fn image_sha256(image: &Bound<'_, PyAny>) -> PyResult<String> {
    let a = image
        .extract::<numpy::PyReadonlyArrayDyn<u8>>()
        .map(|a| a.as_array().iter().copied().collect::<Vec<u8>>())
        .or_else(|_| {
            image.extract::<numpy::PyReadonlyArrayDyn<u16>>().map(|a| {
                a.as_array()
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect::<Vec<u8>>()
            })
        })
        .map_err(|_| value_error("expected a uint8 or uint16 image array"))?;
    use sha2::Digest;
    Ok(format!("{:x}", sha2::Sha256::digest(&a)))
}

/// A trajectory file read by sphereshade's own readers (.xtc .trr .dcd
/// .lammpstrj, multi-model .pdb/.cif, multi-frame .gro/.xyz): `len(t)`
/// frames, `t[k]` the (N, 3) float32 positions in Å, `t.time(k)` in ps.
#[pyclass(frozen, module = "sphereshade")]
struct Trajectory {
    reader: Mutex<Box<dyn sphereshade::traj::Reader>>,
    frames: usize,
    atoms: usize,
}

impl Trajectory {
    fn frame(&self, k: isize) -> PyResult<sphereshade::traj::Frame> {
        let n = self.frames as isize;
        let k = if k < 0 { k + n } else { k };
        if !(0..n).contains(&k) {
            return Err(pyo3::exceptions::PyIndexError::new_err(format!(
                "frame {k} of a {n}-frame trajectory"
            )));
        }
        let mut f = sphereshade::traj::Frame::default();
        self.reader
            .lock()
            .map_err(|_| PyRuntimeError::new_err("reader poisoned"))?
            .read(k as usize, &mut f)
            .map_err(value_error)?;
        Ok(f)
    }
}

#[pymethods]
impl Trajectory {
    #[new]
    fn new(path: std::path::PathBuf) -> PyResult<Self> {
        let r = sphereshade::traj::open(&path).map_err(value_error)?;
        Ok(Trajectory {
            frames: r.frames(),
            atoms: r.atoms(),
            reader: Mutex::new(r),
        })
    }
    fn __len__(&self) -> usize {
        self.frames
    }
    #[getter]
    fn atoms(&self) -> usize {
        self.atoms
    }
    fn __getitem__<'py>(&self, py: Python<'py>, k: isize) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let f = self.frame(k)?;
        let v: Vec<Vec<f32>> = f.positions.iter().map(|p| p.to_vec()).collect();
        PyArray2::from_vec2(py, &v).map_err(value_error)
    }
    /// The frame's time in ps (None when the format has none).
    fn time(&self, k: isize) -> PyResult<Option<f64>> {
        Ok(self.frame(k)?.time_ps)
    }
}

#[pymodule]
fn _sphereshade(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Trajectory>()?;
    m.add_class::<Renderer>()?;
    m.add_class::<Scene>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(encode_png, m)?)?;
    m.add_function(wrap_pyfunction!(image_sha256, m)?)?;
    Ok(())
}
