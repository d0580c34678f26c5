//! `sphereshade bench`: a matrix of runs (cross product of the list-valued
//! flags) in one process on one device so ratios between runs are fair;
//! per-pass timestamp medians, memory, image hashes, derived ratios, and
//! `--compare` against an earlier JSON. `cargo bench` (benches/frame.rs)
//! calls the same code.

pub mod chart;
mod report;

use report::write_chart;
pub use report::{compare, ratios, read_report, summary, table};

use crate::error::{Error, Result};
use crate::output::{self, RunStats};
use crate::run::{self, SceneArgs};
use crate::scene::Scene;
use crate::settings::{Aov, Axes, Options, RasterMode, ShadowMode, SsdoMode};
use crate::vk::Context;
use clap::ValueEnum;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct BenchArgs {
    /// Structure files; each is one data set of the matrix.
    pub inputs: Vec<PathBuf>,
    /// Procedural scenes (comma list): the data sets when no input file is
    /// given, else with `--atoms` more data sets beside the files.
    #[arg(long)]
    pub scene: Option<String>,
    /// Comma list of sphere counts for procedural scenes.
    #[arg(long)]
    pub atoms: Option<String>,
    /// Comma list of shadow modes.
    #[arg(long)]
    pub shadows: Option<String>,
    /// Comma list of SSDO modes.
    #[arg(long)]
    pub ssdo: Option<String>,
    /// Comma list of raster modes.
    #[arg(long)]
    pub raster: Option<String>,
    /// Comma list of opacities.
    #[arg(long)]
    pub opacity: Option<String>,
    /// Comma list: `on` draws instanced models (PetWorld, cellPACK,
    /// manifests, --assembly) instanced, `off` expanded into one sphere
    /// record per atom as before instancing (at most 2^24). Plain inputs
    /// run once either way.
    #[arg(long)]
    pub instancing: Option<String>,
    /// Comma list: `off` (opaque spheres as loaded), `half` (the first half
    /// of the sphere records see-through at alpha 0.5). The default matrix
    /// adds one `half` run of the full frame.
    #[arg(long)]
    pub see_through: Option<String>,
    /// Comma list of image sizes, e.g. 1920x1080,3840x2160.
    #[arg(long, conflicts_with_all = ["width", "height"])]
    pub size: Option<String>,
    /// One image size instead of --size (both --width and --height).
    #[arg(long, requires = "height")]
    pub width: Option<u32>,
    /// Image height with --width.
    #[arg(long, requires = "width")]
    pub height: Option<u32>,
    /// Measured frames per run (medians, min and max over them).
    #[arg(long, default_value_t = 5)]
    pub frames: u32,
    /// Unmeasured frames per run before the measured ones.
    #[arg(long, default_value_t = 1)]
    pub warmup: u32,
    /// Small matrix (the 100k capsid at 960x540: local lighting, ISSM hard
    /// and soft) that finishes in seconds on lavapipe.
    #[arg(long)]
    pub quick: bool,
    /// The JSON report (rewritten after every run; `"complete"` says whether
    /// the matrix finished).
    #[arg(long)]
    pub json: PathBuf,
    /// Earlier bench JSON: print per-pass ratios new/old for matching runs.
    #[arg(long)]
    pub compare: Option<PathBuf>,
    /// Tile every input in a lattice, e.g. 6x6x5.
    #[arg(long, value_parser = run::parse_replicate)]
    pub replicate: Option<[u32; 3]>,
    /// Multiply all radii.
    #[arg(long, default_value_t = SceneArgs::default().radius_scale, allow_negative_numbers = true)]
    pub radius_scale: f32,
    /// Camera, light, technique and device options, as for `render`.
    #[command(flatten)]
    pub options: Options,
    /// Also write a bar chart PNG of per-pass median ms.
    #[arg(long)]
    pub chart: Option<PathBuf>,
    /// Keep the camera fixed (by default measured frames orbit the scene,
    /// every fourth one zoomed in 4x).
    #[arg(long)]
    pub no_orbit: bool,
    /// Orbit DEG per measured frame instead, none zoomed: a viewer's
    /// moving camera (its culls' history is a moved view's every frame).
    #[arg(
        long,
        value_name = "DEG",
        conflicts_with = "no_orbit",
        allow_negative_numbers = true
    )]
    pub orbit: Option<f64>,
    /// Run nothing: print the table and summary of the existing --json
    /// file (e.g. of an interrupted bench).
    #[arg(long)]
    pub summarize: bool,
}

/// The whole bench output.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchReport {
    pub runs: Vec<RunStats>,
    /// Derived ratios (name -> value), see `ratios`.
    #[serde(default)]
    pub ratios: BTreeMap<String, f64>,
    /// Runs that could not be made (e.g. a buffer over the device's limit):
    /// the matrix goes on without them.
    #[serde(default)]
    pub failed: Vec<FailedRun>,
    /// False while the matrix is still running (the JSON is rewritten after
    /// every run, so an interrupted bench keeps what it measured).
    #[serde(default = "yes")]
    pub complete: bool,
}

fn yes() -> bool {
    true
}

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FailedRun {
    pub run: String,
    pub error: String,
}

fn list<T: ValueEnum + Clone>(s: &Option<String>, default: &[T], flag: &str) -> Result<Vec<T>> {
    match s {
        None => Ok(default.to_vec()),
        Some(s) => s
            .split(',')
            .map(|p| {
                T::from_str(p.trim(), true)
                    .map_err(|_| Error::Input(format!("{flag} {s}: '{p}' is not valid")))
            })
            .collect(),
    }
}

fn parse_list<T: std::str::FromStr + Clone>(
    s: &Option<String>,
    default: &[T],
    flag: &str,
) -> Result<Vec<T>> {
    match s {
        None => Ok(default.to_vec()),
        Some(s) => s
            .split(',')
            .map(|p| {
                p.trim()
                    .parse::<T>()
                    .map_err(|_| Error::Input(format!("{flag} {s}: '{p}' is not valid")))
            })
            .collect(),
    }
}

/// A comma list of two words meaning false and true (`--instancing on,off`).
fn switch_list(s: &str, flag: &str, words: [(&str, bool); 2]) -> Result<Vec<bool>> {
    s.split(',')
        .map(|p| {
            words
                .iter()
                .find(|(w, _)| *w == p.trim())
                .map(|&(_, v)| v)
                .ok_or_else(|| {
                    Error::Input(format!(
                        "{flag} {s}: '{p}' is not {} or {}",
                        words[0].0, words[1].0
                    ))
                })
        })
        .collect()
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| Error::Input(format!("--size {s}: expected WxH")))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (1..=16384).contains(v))
    };
    match (p(w), p(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(Error::Input(format!(
            "--size {s}: expected WxH with 1..16384"
        ))),
    }
}

/// One data set of the matrix.
struct DataSet {
    name: String,
    scene: Scene,
    /// An instanced scene expanded, when `--instancing` lists `off`.
    expanded: Option<Scene>,
    load_ms: f64,
}

fn data_sets(a: &BenchArgs, atoms: &[usize]) -> Result<Vec<DataSet>> {
    let mut sets = Vec::new();
    let base = SceneArgs {
        replicate: a.replicate,
        radius_scale: a.radius_scale,
        ..SceneArgs::default()
    };
    // procedural scenes: alone, or beside files when asked for by name
    // (e.g. a model against the 1M capsid in one run)
    if a.inputs.is_empty() || (a.scene.is_some() && a.atoms.is_some()) {
        let names = a.scene.clone().unwrap_or_else(|| {
            if a.quick {
                "capsid".into()
            } else {
                "capsid,lattice".into()
            }
        });
        for name in names.split(',') {
            for &n in atoms {
                let args = SceneArgs {
                    scene: Some(name.trim().to_string()),
                    atoms: Some(n),
                    ..base.clone()
                };
                eprintln!("bench: building scene {name} with {n} spheres");
                let (scene, load_ms) = run::load_scene(&args)?;
                sets.push(DataSet {
                    name: format!("scene:{}", name.trim()),
                    scene,
                    expanded: None,
                    load_ms,
                });
            }
        }
    }
    if !a.inputs.is_empty() {
        if a.atoms.is_some() != a.scene.is_some() {
            return Err(Error::Input(
                "with input files, --scene and --atoms go together (procedural data sets beside \
                 the files)"
                    .into(),
            ));
        }
        for p in &a.inputs {
            let args = SceneArgs {
                input: Some(p.clone()),
                ..base.clone()
            };
            eprintln!("bench: loading {}", p.display());
            let (scene, load_ms) = run::load_scene(&args)?;
            sets.push(DataSet {
                name: p.display().to_string(),
                scene,
                expanded: None,
                load_ms,
            });
        }
    }
    Ok(sets)
}

/// One technique combination of the matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Technique {
    shadows: ShadowMode,
    ssdo: SsdoMode,
    raster: RasterMode,
    opacity: f32,
    /// Draw an instanced model expanded (`--instancing off`).
    expanded: bool,
    /// The first half of the sphere records see-through at alpha 0.5 (the
    /// cost of see-through spheres against the same frame opaque).
    half: bool,
}

/// The default techniques: local lighting, ISSM hard/soft, deep opaque and
/// translucent, the full frame with semantic and with plain SSDO, and the
/// graphics raster baseline (each differs from a neighbour in one setting,
/// so the ratios below compare like with like).
fn default_techniques() -> Vec<Technique> {
    use RasterMode::*;
    use ShadowMode as S;
    use SsdoMode as O;
    let t = |shadows, ssdo, raster, opacity| Technique {
        shadows,
        ssdo,
        raster,
        opacity,
        expanded: false,
        half: false,
    };
    vec![
        t(S::None, O::Off, Compute, 1.0),
        t(S::Issm, O::Off, Compute, 1.0),
        t(S::IssmSoft, O::Off, Compute, 1.0),
        t(S::Deep, O::Off, Compute, 1.0),
        t(S::Deep, O::Off, Compute, 0.5),
        t(S::IssmSoft, O::Semantic, Compute, 1.0),
        t(S::IssmSoft, O::Plain, Compute, 1.0),
        Technique {
            half: true,
            ..t(S::IssmSoft, O::Semantic, Compute, 1.0)
        },
        t(S::None, O::Off, Graphics, 1.0),
    ]
}

/// The real structure files the repository carries (tests/data, copied
/// from ../shared/data with their provenance).
pub fn data_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data"))
}

/// The structure files of tests/data and the mesoscale models of
/// tests/data/meso (a BinaryCIF twin of an mmCIF file is the same spheres:
/// left out).
fn shared_data_files() -> Vec<PathBuf> {
    let dir = data_dir();
    let mut files: Vec<PathBuf> = Vec::new();
    for d in [dir.clone(), dir.join("meso")] {
        if let Ok(rd) = std::fs::read_dir(&d) {
            files.extend(
                rd.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| crate::scene::format_of(p).is_some())
                    .filter(|p| {
                        !(p.extension().is_some_and(|e| e == "bcif")
                            && p.with_extension("cif").exists())
                    }),
            );
        }
    }
    files.sort();
    files
}

/// The camera of measured frame `k` of `n`: an orbit of the view direction
/// around the up axis, every fourth frame zoomed in 4x (larger spheres on
/// screen, fewer per pixel; depth complexity changes with the angle).
pub fn orbit_camera(base: &crate::camera::Camera, k: u32, n: u32) -> Result<crate::camera::Camera> {
    let angle = std::f64::consts::TAU * k as f64 / n.max(1) as f64;
    let dir = glam::DQuat::from_axis_angle(base.up, angle) * base.dir;
    let height = if k % 4 == 3 {
        base.view_height / 4.0
    } else {
        base.view_height
    };
    crate::camera::Camera::new(
        base.center,
        dir,
        base.up,
        height,
        base.fov_deg,
        base.width,
        base.height,
    )
}

/// The camera of measured frame `k` orbiting `deg` a frame about the up
/// axis, none zoomed.
pub fn orbit_step_camera(
    base: &crate::camera::Camera,
    k: u32,
    deg: f64,
) -> Result<crate::camera::Camera> {
    let dir = glam::DQuat::from_axis_angle(base.up, (deg * k as f64).to_radians()) * base.dir;
    crate::camera::Camera::new(
        base.center,
        dir,
        base.up,
        base.view_height,
        base.fov_deg,
        base.width,
        base.height,
    )
}

pub fn run(a: &BenchArgs) -> Result<BenchReport> {
    if a.orbit.is_some_and(|d| !d.is_finite()) {
        return Err(Error::Input(
            "--orbit must be a finite number of degrees".into(),
        ));
    }
    let explicit =
        a.shadows.is_some() || a.ssdo.is_some() || a.raster.is_some() || a.opacity.is_some();
    let techniques = if explicit || a.quick {
        let def_shadows = if a.quick {
            vec![ShadowMode::None, ShadowMode::Issm, ShadowMode::IssmSoft]
        } else {
            vec![ShadowMode::None]
        };
        let shadows = list(&a.shadows, &def_shadows, "--shadows")?;
        let ssdo = list(&a.ssdo, &[SsdoMode::Off], "--ssdo")?;
        let raster = list(&a.raster, &[RasterMode::Compute], "--raster")?;
        let opacity: Vec<f32> = parse_list(&a.opacity, &[1.0], "--opacity")?;
        if opacity.iter().any(|o| !(0.0..=1.0).contains(o)) {
            return Err(Error::Input(
                "--opacity values must be between 0 and 1".into(),
            ));
        }
        let mut t = Vec::new();
        for &shadows in &shadows {
            for &ssdo in &ssdo {
                for &raster in &raster {
                    for &opacity in &opacity {
                        t.push(Technique {
                            shadows,
                            ssdo,
                            raster,
                            opacity,
                            expanded: false,
                            half: false,
                        });
                    }
                }
            }
        }
        t
    } else {
        default_techniques()
    };
    let instancing = match &a.instancing {
        None => vec![true],
        Some(s) => switch_list(s, "--instancing", [("on", true), ("off", false)])?,
    };
    let techniques: Vec<Technique> = instancing
        .iter()
        .flat_map(|&on| {
            techniques.iter().map(move |t| Technique {
                expanded: !on,
                ..*t
            })
        })
        .collect();
    let techniques: Vec<Technique> = match &a.see_through {
        None => techniques,
        Some(s) => {
            let halves = switch_list(s, "--see-through", [("off", false), ("half", true)])?;
            let mut v: Vec<Technique> = Vec::new();
            for t in techniques.iter().filter(|t| !t.half) {
                for &half in &halves {
                    v.push(Technique { half, ..*t });
                }
            }
            v
        }
    };
    let def_atoms = if a.quick {
        vec![100_000]
    } else {
        vec![100_000, 1_000_000, 4_000_000]
    };
    let atoms: Vec<usize> = parse_list(&a.atoms, &def_atoms, "--atoms")?;
    let sizes = match (&a.size, a.width.zip(a.height)) {
        (_, Some((w, h))) => vec![parse_size(&format!("{w}x{h}"))?],
        (None, _) if a.quick => vec![(960, 540)],
        (None, _) => vec![(1920, 1080), (3840, 2160)],
        (Some(s), _) => s.split(',').map(parse_size).collect::<Result<_>>()?,
    };
    let mut sets = data_sets(a, &atoms)?;
    if instancing.contains(&false) {
        for s in &mut sets {
            if s.scene.instancing.is_some() {
                s.expanded = Some(s.scene.expand()?);
            }
        }
    }
    if a.inputs.is_empty() && a.scene.is_none() && a.atoms.is_none() && !a.quick {
        // The default matrix also covers the real files and a 1M lattice of 1TII.
        let files = shared_data_files();
        if files.is_empty() {
            eprintln!(
                "bench: {} not found; running the procedural data sets only",
                data_dir().display()
            );
        }
        let extra = BenchArgs {
            inputs: files,
            quick: true,
            ..a.clone()
        };
        sets.extend(data_sets(&extra, &[])?);
        if let Some(tii) = extra.inputs.iter().find(|p| p.ends_with("1tii.pdb")) {
            let lattice = BenchArgs {
                inputs: vec![tii.clone()],
                replicate: Some([6, 6, 5]),
                quick: true,
                ..a.clone()
            };
            let mut more = data_sets(&lattice, &[])?;
            for d in &mut more {
                d.name = format!("{} 6x6x5", d.name);
            }
            sets.extend(more);
        }
    }
    let options = crate::vk::ContextOptions {
        validate: a.options.validate,
        device_index: a.options.device,
        ..Default::default()
    };
    let ctx = Context::new(&options)?;
    eprintln!("bench: device {} ({})", ctx.info.name, ctx.info.driver);

    let total = sets.len() * sizes.len() * techniques.len();
    let mut report = BenchReport {
        runs: Vec::new(),
        ratios: BTreeMap::new(),
        failed: Vec::new(),
        complete: false,
    };
    let started = std::time::Instant::now();
    let mut done = 0usize;
    // Sizes outermost: the cheaper size's whole matrix is measured (and
    // written) before the expensive one starts.
    for &(w, h) in &sizes {
        for set in &sets {
            // One slot per technique, filled in the matrix's order.
            let mut results: Vec<Option<std::result::Result<RunStats, FailedRun>>> =
                techniques.iter().map(|_| None).collect();
            let mut pool: Vec<Pending> = Vec::new();
            let mut pool_bytes = 0u64;
            for (i, t) in techniques.iter().enumerate() {
                done += 1;
                if t.expanded && set.expanded.is_none() {
                    // (a plain scene: its `on` run is the same run)
                    continue;
                }
                if t.raster == RasterMode::Graphics && !t.expanded && set.scene.instancing.is_some()
                {
                    eprintln!(
                        "bench: {}: the graphics baseline draws plain scenes only (skipped; \
                         --instancing off draws it expanded)",
                        set.name
                    );
                    continue;
                }
                let desc = format!(
                    "{} ({} spheres) {w}x{h} shadows={} ssdo={} raster={} opacity={}{}{}",
                    set.name,
                    set.scene.represented(),
                    t.shadows.name(),
                    t.ssdo.name(),
                    t.raster.name(),
                    t.opacity,
                    if t.expanded { " instancing=off" } else { "" },
                    if t.half { " half see-through" } else { "" }
                );
                let elapsed = started.elapsed().as_secs_f64();
                let eta = if done > 1 {
                    format!(
                        ", about {:.0} min left at this rate",
                        elapsed / (done - 1) as f64 * (total - done + 1) as f64 / 60.0
                    )
                } else {
                    String::new()
                };
                eprintln!(
                    "bench: run {done}/{total} ({:.0} s elapsed{eta}): {desc}",
                    elapsed
                );
                if t.raster == RasterMode::Graphics {
                    // Measured on lavapipe: once a queue has drawn, its later
                    // timestamps are binned with the draw's scene and all land
                    // at the end of the command buffer (every compute pass
                    // after the first then reads 0 ms). A device of its own
                    // keeps the draw away from the compute runs' timings, so
                    // this run is measured alone.
                    let r = Context::new(&options).and_then(|g| {
                        let r = bench_one(&g, a, set, t, w, h);
                        let (n, _) = g.finish();
                        r.map(|mut s| {
                            s.validation_messages = s.validation_messages.max(n);
                            s
                        })
                    });
                    results[i] = Some(r.map_err(|e| failed_run(desc, e)));
                    continue;
                }
                match prepare(&ctx, a, set, t, (w, h), i, desc.clone()) {
                    Ok(p) => {
                        let bytes: u64 = p.run.memory_bytes();
                        if !pool.is_empty() && pool_bytes + bytes > POOL_BYTES {
                            for (j, d, r) in measure_pool(&ctx, a, std::mem::take(&mut pool)) {
                                results[j] = Some(r.map_err(|e| failed_run(d, e)));
                            }
                            pool_bytes = 0;
                        }
                        pool_bytes += bytes;
                        pool.push(p);
                    }
                    Err(e) => results[i] = Some(Err(failed_run(desc, e))),
                }
            }
            for (j, d, r) in measure_pool(&ctx, a, pool) {
                results[j] = Some(r.map_err(|e| failed_run(d, e)));
            }
            for r in results.into_iter().flatten() {
                match r {
                    Ok(stats) => report.runs.push(stats),
                    Err(f) => report.failed.push(f),
                }
            }
            report.ratios = ratios(&report.runs);
            output::write_json(&a.json, &report)?;
        }
    }
    // Leak reports come at device destruction: charge them to the last run.
    let (n, _) = ctx.finish();
    if let Some(last) = report.runs.last_mut() {
        last.validation_messages = last.validation_messages.max(n);
    }
    report.ratios = ratios(&report.runs);
    report.complete = true;
    Ok(report)
}

/// The device memory that the runs measured together may hold at once: a
/// matrix's larger runs (4M spheres at 4K with deep lists) are then
/// measured in smaller groups.
const POOL_BYTES: u64 = 3 << 30;

fn failed_run(run: String, e: Error) -> FailedRun {
    eprintln!("bench: {run} failed: {e}");
    FailedRun {
        run,
        error: e.to_string(),
    }
}

/// The scene with its first half of sphere records at alpha 0.5 (an
/// instanced scene: the first half of each molecule's atoms).
fn half_see_through(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    let mut half = |r: std::ops::Range<usize>| {
        let n = r.len() / 2;
        for sp in &mut s.spheres[r.start..r.start + n] {
            sp.color[3] = 128;
        }
    };
    match &scene.instancing {
        Some(inst) => {
            for m in &inst.molecules {
                half(m.first as usize..(m.first + m.atoms) as usize);
            }
        }
        None => half(0..scene.spheres.len()),
    }
    s
}

/// A run set up and warmed up, waiting for its measured frames.
struct Pending<'c> {
    /// The technique's place in the matrix.
    index: usize,
    desc: String,
    run: run::PreparedRun<'c>,
    /// The camera the orbit starts from.
    base: crate::camera::Camera,
}

/// Sets technique `index` of the matrix up on one data set at one size
/// (renderer, warm-up).
fn prepare<'c>(
    ctx: &'c Context,
    a: &BenchArgs,
    set: &DataSet,
    t: &Technique,
    (w, h): (u32, u32),
    index: usize,
    desc: String,
) -> Result<Pending<'c>> {
    let axes = Axes {
        width: w,
        height: h,
        shadows: t.shadows,
        ssdo: t.ssdo,
        raster: t.raster,
        opacity: t.opacity,
    };
    let half;
    let mut scene = match (&set.expanded, t.expanded) {
        (Some(e), true) => e,
        _ => &set.scene,
    };
    if t.half {
        half = half_see_through(scene);
        scene = &half;
    }
    let mut settings = a.options.resolve(&axes, scene)?;
    // `--opacity` measures translucent shadows (the deep lists' cost) on
    // spheres drawn opaque; see-through spheres are `--see-through half`'s
    // runs (every sphere see-through at 1M+ spheres overflows lavapipe's
    // 128 MiB buffers: 25.7 M fragments on the 1M capsid at 1080p).
    settings.opaque_view = !t.half;
    let base = settings.camera;
    let run = run::PreparedRun::new(
        ctx,
        scene,
        settings,
        &run::RunRequest {
            input: &set.name,
            aov: Aov::Color,
            warmup: a.warmup,
            frames: a.frames,
            load_ms: set.load_ms,
        },
    )?;
    Ok(Pending {
        index,
        desc,
        run,
        base,
    })
}

/// Measures the runs of one data set and size together: frame k of every
/// run, then frame k + 1 of every run, and so on; then, when any run has a
/// light-space structure, its cached frames the same way, every run taking
/// part (a run without one renders its plain frame there, so cached ratios
/// divide frames of the same rounds). On a shared machine whose speed
/// drifts by tens of percent within seconds, the ratios between runs were
/// otherwise as noisy as the runs themselves (full / local 1.85-2.26 for
/// one build over three `bench` runs, measured one run after another).
/// Returns (matrix index, description, stats) per run.
fn measure_pool(
    ctx: &Context,
    a: &BenchArgs,
    pool: Vec<Pending>,
) -> Vec<(usize, String, Result<RunStats>)> {
    let frames = a.frames.max(1);
    let orbit = !a.no_orbit && a.frames > 1;
    if pool.len() > 1 {
        eprintln!(
            "bench: measuring {} runs together, {frames} frames each in turn",
            pool.len()
        );
    }
    let mut live: Vec<(Pending, Option<Error>)> = pool.into_iter().map(|p| (p, None)).collect();
    let step = |p: &mut Pending, k: u32, f: &mut dyn FnMut(&mut run::PreparedRun) -> Result<()>| {
        if orbit {
            let cam = match a.orbit {
                Some(deg) => orbit_step_camera(&p.base, k, deg)?,
                None => orbit_camera(&p.base, k, frames)?,
            };
            p.run.renderer().update(|s| s.camera = cam)?;
        }
        f(&mut p.run)
    };
    for k in 0..frames {
        for (p, err) in live.iter_mut().filter(|(_, e)| e.is_none()) {
            *err = step(p, k, &mut |r| r.frame_hashed(k + 1 == frames)).err();
        }
    }
    if live.iter().any(|(p, e)| e.is_none() && p.run.has_light()) {
        for (p, err) in live
            .iter_mut()
            .filter(|(p, e)| e.is_none() && p.run.has_light())
        {
            *err = p.run.start_cached().err();
        }
        for k in 0..frames {
            for (p, err) in live.iter_mut().filter(|(_, e)| e.is_none()) {
                *err = step(p, k, &mut |r| r.cached_frame()).err();
            }
        }
    }
    live.into_iter()
        .map(|(p, err)| {
            let stats = match err {
                Some(e) => Err(e),
                None => p.run.finish(ctx).map(|o| o.stats),
            };
            (p.index, p.desc, stats)
        })
        .collect()
}

/// Measures one technique on one data set at one size, alone.
fn bench_one(
    ctx: &Context,
    a: &BenchArgs,
    set: &DataSet,
    t: &Technique,
    w: u32,
    h: u32,
) -> Result<RunStats> {
    let p = prepare(ctx, a, set, t, (w, h), 0, String::new())?;
    match measure_pool(ctx, a, vec![p]).pop() {
        Some((_, _, stats)) => stats,
        None => Err(Error::Internal("run not measured".into())),
    }
}

/// The `bench` subcommand: run, print, write, compare.
pub fn main(a: &BenchArgs) -> Result<u32> {
    let mut outs = Vec::new();
    if !a.summarize {
        outs.push(output::OutFile {
            flag: "--json",
            path: &a.json,
            extensions: &["json"],
        });
    }
    if let Some(c) = &a.chart {
        outs.push(output::OutFile {
            flag: "--chart",
            path: c,
            extensions: &["png"],
        });
    }
    output::check_outputs(&outs)?;
    run::check_frames(a.frames)?;
    if a.summarize {
        let report = read_report(&a.json)?;
        print!("{}", table(&report));
        print!("{}", summary(&report));
        if let Some(c) = &a.chart {
            write_chart(&report, c)?;
        }
        return Ok(0);
    }
    let old = a.compare.as_deref().map(read_report).transpose()?;
    let report = run(a)?;
    print!("{}", table(&report));
    print!("{}", summary(&report));
    output::write_json(&a.json, &report)?;
    if let Some(c) = &a.chart {
        write_chart(&report, c)?;
    }
    if let Some(old) = old {
        println!("compare (new / old median ms):");
        for (run, pass, r) in compare(&report, &old) {
            println!("  {run:<60} {pass:<14} {r:.3}");
        }
    }
    if !report.failed.is_empty() {
        return Err(Error::Input(format!(
            "{} of {} runs failed (listed above and under \"failed\" in {})",
            report.failed.len(),
            report.failed.len() + report.runs.len(),
            a.json.display()
        )));
    }
    Ok(report
        .runs
        .iter()
        .map(|r| r.validation_messages)
        .max()
        .unwrap_or(0))
}
