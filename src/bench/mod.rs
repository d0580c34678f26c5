//! `sphereshade bench`: a matrix of runs (cross product of the list-valued
//! flags) in one process on one device so ratios between runs are fair;
//! per-pass timestamp medians, memory, image hashes, derived ratios, and
//! `--compare` against an earlier JSON. `cargo bench` (benches/frame.rs)
//! calls the same code.

pub mod chart;

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
    /// Procedural scenes (comma list) used when no input file is given.
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
    /// Small matrix that finishes in about two minutes on lavapipe.
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
    load_ms: f64,
}

fn data_sets(a: &BenchArgs, atoms: &[usize]) -> Result<Vec<DataSet>> {
    let mut sets = Vec::new();
    let base = SceneArgs {
        replicate: a.replicate,
        radius_scale: a.radius_scale,
        ..SceneArgs::default()
    };
    if a.inputs.is_empty() {
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
                    load_ms,
                });
            }
        }
    } else {
        if a.atoms.is_some() || a.scene.is_some() {
            return Err(Error::Input(
                "--atoms/--scene apply when no input file is given".into(),
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
    };
    vec![
        t(S::None, O::Off, Compute, 1.0),
        t(S::Issm, O::Off, Compute, 1.0),
        t(S::IssmSoft, O::Off, Compute, 1.0),
        t(S::Deep, O::Off, Compute, 1.0),
        t(S::Deep, O::Off, Compute, 0.5),
        t(S::IssmSoft, O::Semantic, Compute, 1.0),
        t(S::IssmSoft, O::Plain, Compute, 1.0),
        t(S::None, O::Off, Graphics, 1.0),
    ]
}

/// The real structure files the repository carries (tests/data, copied
/// from ../shared/data with their provenance).
pub fn data_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data"))
}

fn shared_data_files() -> Vec<PathBuf> {
    let dir = data_dir();
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| crate::scene::format_of(p).is_some())
                .collect()
        })
        .unwrap_or_default();
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

pub fn run(a: &BenchArgs) -> Result<BenchReport> {
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
                        });
                    }
                }
            }
        }
        t
    } else {
        default_techniques()
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
                let desc = format!(
                    "{} ({} spheres) {w}x{h} shadows={} ssdo={} raster={} opacity={}",
                    set.name,
                    set.scene.spheres.len(),
                    t.shadows.name(),
                    t.ssdo.name(),
                    t.raster.name(),
                    t.opacity
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
    let settings = a.options.resolve(&axes, &set.scene)?;
    let base = settings.camera;
    let run = run::PreparedRun::new(
        ctx,
        &set.scene,
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
            let cam = orbit_camera(&p.base, k, frames)?;
            p.run.renderer().update(|s| s.camera = cam)?;
        }
        f(&mut p.run)
    };
    for k in 0..frames {
        for (p, err) in live.iter_mut().filter(|(_, e)| e.is_none()) {
            *err = step(p, k, &mut |r| r.frame(k + 1 == frames)).err();
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

fn key(r: &RunStats) -> (String, u64, u32, u32, String, String, String, u64) {
    (
        r.input.clone(),
        r.spheres,
        r.width,
        r.height,
        r.shadows.clone(),
        r.ssdo.clone(),
        r.raster.clone(),
        (r.opacity * 1000.0).round() as u64,
    )
}

/// Data set and size of a run, as ratio names carry it in brackets.
fn data_tag(r: &RunStats) -> String {
    format!("{} {}sph {}x{}", r.input, r.spheres, r.width, r.height)
}

fn pass_ms(r: &RunStats, name: &str) -> Option<f64> {
    r.passes
        .iter()
        .find(|p| p.name == name)
        .map(|p| p.median_ms)
}

/// a / b for two runs measured together: the median of their per-frame
/// ratios when both list the same number of frames (frame k of each was
/// rendered in the same round), else the ratio of their medians (`a`, `b`).
fn paired(a_ms: &[f64], a: f64, b_ms: &[f64], b: f64) -> f64 {
    if a_ms.is_empty() || a_ms.len() != b_ms.len() || b_ms.iter().any(|&t| t <= 0.0) {
        return a / b;
    }
    let mut r: Vec<f64> = a_ms.iter().zip(b_ms).map(|(x, y)| x / y).collect();
    output::median(&mut r)
}

/// Derived ratios between runs of the same data set and size that differ in
/// one setting (medians of per-frame ratios, `paired`, unless noted), named after data set and size:
/// ISSM overhead (issm / none, issm-soft / none), soft/hard, deep/ISSM,
/// translucent/opaque deep, semantic/plain SSDO (full frames), graphics /
/// compute raster (the `raster` pass), and ms per million spheres of the
/// local-lighting frame.
pub fn ratios(runs: &[RunStats]) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    let find = |base: &RunStats, shadows: &str, ssdo: &str, raster: &str, opacity: f64| {
        runs.iter().find(|r| {
            (r.input.as_str(), r.spheres, r.width, r.height)
                == (base.input.as_str(), base.spheres, base.width, base.height)
                && r.shadows == shadows
                && r.ssdo == ssdo
                && r.raster == raster
                && (r.opacity - opacity).abs() < 1e-6
        })
    };
    let bases = runs.iter().filter(|r| {
        r.shadows == "none" && r.ssdo == "off" && r.raster == "compute" && r.opacity == 1.0
    });
    let frame = |x: &RunStats| x.total_ms.median;
    let over = |a: &RunStats, b: &RunStats| paired(&a.frame_ms, frame(a), &b.frame_ms, frame(b));
    for r in bases {
        let tag = data_tag(r);
        let hard = find(r, "issm", "off", "compute", 1.0);
        let soft = find(r, "issm-soft", "off", "compute", 1.0);
        let deep = find(r, "deep", "off", "compute", 1.0);
        if let Some(h) = hard {
            out.insert(format!("issm_overhead[{tag}]"), over(h, r));
            if let Some(c) = &h.light_cached {
                // the local frames of the same rounds where `bench` measured
                // them (measure_pool), else its own
                let (local, local_ms) = r
                    .light_cached
                    .as_ref()
                    .map_or((frame(r), &r.frame_ms), |l| {
                        (l.total_ms.median, &l.frame_ms)
                    });
                out.insert(
                    format!("issm_cached_overhead[{tag}]"),
                    paired(&c.frame_ms, c.total_ms.median, local_ms, local),
                );
            }
        }
        // The full default frame against local lighting.
        if let Some(f) = find(r, "issm-soft", "semantic", "compute", 1.0) {
            out.insert(format!("full_over_local[{tag}]"), over(f, r));
        }
        if let Some(s) = soft {
            out.insert(format!("issm_soft_overhead[{tag}]"), over(s, r));
        }
        if let (Some(s), Some(h)) = (soft, hard) {
            out.insert(format!("soft_over_hard[{tag}]"), over(s, h));
        }
        if let (Some(d), Some(h)) = (deep, hard) {
            out.insert(format!("deep_over_issm[{tag}]"), over(d, h));
        }
        if let (Some(d5), Some(d)) = (find(r, "deep", "off", "compute", 0.5), deep) {
            out.insert(format!("deep_translucent_over_opaque[{tag}]"), over(d5, d));
        }
        if let (Some(se), Some(pl)) = (
            find(r, "issm-soft", "semantic", "compute", 1.0),
            find(r, "issm-soft", "plain", "compute", 1.0),
        ) {
            out.insert(format!("semantic_over_plain[{tag}]"), over(se, pl));
        }
        if let Some(g) = find(r, "none", "off", "graphics", 1.0)
            && let (Some(gr), Some(cr)) = (pass_ms(g, "raster"), pass_ms(r, "raster"))
        {
            out.insert(format!("graphics_over_compute_raster[{tag}]"), gr / cr);
        }
        out.insert(
            format!("ms_per_million_spheres[{tag}]"),
            frame(r) / (r.spheres as f64 / 1e6),
        );
    }
    // Scaling: the exponent k of frame ms ~ spheres^k between the smallest
    // and largest count of one data set (1 = linear, below 1 = sub-linear).
    let mut series: BTreeMap<String, Vec<(u64, f64)>> = BTreeMap::new();
    for r in runs {
        let tag = format!(
            "{} {}x{} {}/{}/{} op={}",
            r.input, r.width, r.height, r.shadows, r.ssdo, r.raster, r.opacity
        );
        series
            .entry(tag)
            .or_default()
            .push((r.spheres, r.total_ms.median));
    }
    for (tag, mut pts) in series {
        pts.sort_by_key(|p| p.0);
        let (Some(&(n0, t0)), Some(&(n1, t1))) = (pts.first(), pts.last()) else {
            continue;
        };
        if n1 > n0 && t0 > 0.0 && t1 > 0.0 {
            out.insert(
                format!("scaling_exponent[{tag} {n0}..{n1}]"),
                (t1 / t0).ln() / (n1 as f64 / n0 as f64).ln(),
            );
        }
    }
    out
}

/// A readable table of runs: one line per run, pass medians in ms.
pub fn table(report: &BenchReport) -> String {
    let mut s = String::new();
    for r in &report.runs {
        s += &format!(
            "{:<28} {:>9} {:>9} {:<9} {:<8} {:<7} op={:<4} total {:>9.2} ms (min {:.2}, max {:.2}) mem {:>6.1} MB\n",
            r.input.rsplit('/').next().unwrap_or(&r.input),
            r.spheres,
            format!("{}x{}", r.width, r.height),
            r.shadows,
            r.ssdo,
            r.raster,
            r.opacity,
            r.total_ms.median,
            r.total_ms.min,
            r.total_ms.max,
            r.gpu_memory_bytes as f64 / 1e6
        );
        let passes: Vec<String> = r
            .passes
            .iter()
            .map(|p| format!("{} {:.2}", p.name, p.median_ms))
            .collect();
        s += &format!("    {}\n", passes.join(" | "));
        if let Some(c) = &r.light_cached {
            let passes: Vec<String> = c
                .passes
                .iter()
                .map(|p| format!("{} {:.2}", p.name, p.median_ms))
                .collect();
            let what = if r.shadows == "none" {
                "alongside the cached frames"
            } else {
                "light map cached"
            };
            s += &format!(
                "    {what}: total {:.2} ms: {}\n",
                c.total_ms.median,
                passes.join(" | ")
            );
        }
        let mem: Vec<String> = r
            .gpu_memory
            .iter()
            .map(|(k, v)| format!("{k} {:.1}", *v as f64 / 1e6))
            .collect();
        if !mem.is_empty() {
            s += &format!("    memory MB: {}\n", mem.join(" | "));
        }
    }
    for f in &report.failed {
        s += &format!("FAILED {}: {}\n", f.run, f.error);
    }
    if !report.ratios.is_empty() {
        s += "ratios:\n";
        for (k, v) in &report.ratios {
            s += &format!("  {k} = {v:.3}\n");
        }
    }
    s
}

/// Short column label of a technique, e.g. `issm-soft+semantic`,
/// `deep a0.5`, `none gfx`.
fn technique_label(r: &RunStats) -> String {
    let mut l = r.shadows.clone();
    if r.ssdo != "off" {
        l += &format!("+{}", r.ssdo);
    }
    if r.opacity < 1.0 {
        l += &format!(" a{}", r.opacity);
    }
    if r.raster != "compute" {
        l += " gfx";
    }
    l
}

/// A compact markdown matrix: one row per data set and size with the frame
/// median (ms) of every technique, the largest GPU memory of the row, and
/// the row's main ratios; runs that failed show as `-`.
pub fn summary(report: &BenchReport) -> String {
    let mut cols: Vec<String> = Vec::new();
    let mut rows: Vec<(String, u64, u32, u32)> = Vec::new();
    for r in &report.runs {
        let c = technique_label(r);
        if !cols.contains(&c) {
            cols.push(c);
        }
        let row = (r.input.clone(), r.spheres, r.width, r.height);
        if !rows.contains(&row) {
            rows.push(row);
        }
    }
    let ratio_cols = [
        ("issm_overhead", "ISSM/local"),
        ("soft_over_hard", "soft/hard"),
        ("deep_over_issm", "deep/ISSM"),
        ("semantic_over_plain", "sem/plain"),
        ("graphics_over_compute_raster", "gfx/compute raster"),
    ];
    let mut s = format!(
        "| data set | spheres | size | {} | max MB | {} |\n",
        cols.join(" | "),
        ratio_cols.map(|c| c.1).join(" | ")
    );
    s += &format!(
        "|---|---:|---|{}\n",
        "---:|".repeat(cols.len() + 1 + ratio_cols.len())
    );
    for (input, spheres, w, h) in &rows {
        let in_row: Vec<&RunStats> = report
            .runs
            .iter()
            .filter(|r| (&r.input, r.spheres, r.width, r.height) == (input, *spheres, *w, *h))
            .collect();
        let cells: Vec<String> = cols
            .iter()
            .map(|c| {
                in_row
                    .iter()
                    .find(|r| &technique_label(r) == c)
                    .map_or("-".into(), |r| format!("{:.0}", r.total_ms.median))
            })
            .collect();
        let mem = in_row.iter().map(|r| r.gpu_memory_bytes).max().unwrap_or(0);
        let tag = format!("[{}]", data_tag(in_row[0]));
        let ratios: Vec<String> = ratio_cols
            .iter()
            .map(|(k, _)| {
                report
                    .ratios
                    .get(&format!("{k}{tag}"))
                    .map_or("-".into(), |v| format!("{v:.2}"))
            })
            .collect();
        s += &format!(
            "| {} | {spheres} | {w}x{h} | {} | {:.0} | {} |\n",
            input.rsplit('/').next().unwrap_or(input),
            cells.join(" | "),
            mem as f64 / 1e6,
            ratios.join(" | ")
        );
    }
    let scaling: Vec<String> = report
        .ratios
        .iter()
        .filter(|(k, _)| k.starts_with("scaling_exponent"))
        .map(|(k, v)| format!("- {k} = {v:.2}"))
        .collect();
    if !scaling.is_empty() {
        s += &format!("\n{}\n", scaling.join("\n"));
    }
    s
}

/// Per-pass ratios new/old for runs present in both reports.
pub fn compare(new: &BenchReport, old: &BenchReport) -> Vec<(String, String, f64)> {
    let mut out = Vec::new();
    for n in &new.runs {
        let Some(o) = old.runs.iter().find(|o| key(o) == key(n)) else {
            continue;
        };
        let tag = format!(
            "{} {}x{} {}/{}/{}",
            n.input, n.width, n.height, n.shadows, n.ssdo, n.raster
        );
        for p in &n.passes {
            if let Some(op) = o.passes.iter().find(|q| q.name == p.name)
                && op.median_ms > 0.0
            {
                out.push((tag.clone(), p.name.clone(), p.median_ms / op.median_ms));
            }
        }
        if o.total_ms.median > 0.0 {
            out.push((tag, "total".into(), n.total_ms.median / o.total_ms.median));
        }
    }
    out
}

pub fn read_report(path: &std::path::Path) -> Result<BenchReport> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.display().to_string(),
        source: e,
    })?;
    serde_json::from_str(&text)
        .map_err(|e| Error::Input(format!("{}: not a bench JSON: {e}", path.display())))
}

fn write_chart(report: &BenchReport, path: &std::path::Path) -> Result<()> {
    output::AovImage::Rgba8(
        image::DynamicImage::ImageRgb8(chart::bar_chart(&report.runs)).to_rgba8(),
    )
    .save_png(path)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::{PassStats, TotalStats};

    fn run(shadows: &str, raster_ms: f64, total: f64) -> RunStats {
        RunStats {
            device: "d".into(),
            driver: "v".into(),
            input: "scene:capsid".into(),
            spheres: 2_000_000,
            width: 64,
            height: 48,
            frames: 3,
            shadows: shadows.into(),
            ssdo: "off".into(),
            raster: "compute".into(),
            opacity: 1.0,
            passes: vec![PassStats {
                name: "raster".into(),
                median_ms: raster_ms,
                min_ms: raster_ms,
                max_ms: raster_ms,
            }],
            total_ms: TotalStats {
                median: total,
                min: total,
                max: total,
            },
            load_ms: 0.0,
            gpu_memory_bytes: 0,
            gpu_memory: Default::default(),
            validation_messages: 0,
            deep: None,
            image_sha256: String::new(),
            light_cached: None,
            frame_ms: vec![],
        }
    }

    #[test]
    fn ratios_divide_matching_runs() {
        let mut hard = run("issm", 1.0, 11.0);
        hard.light_cached = Some(crate::output::CachedStats {
            passes: vec![],
            total_ms: TotalStats {
                median: 10.5,
                min: 10.5,
                max: 10.5,
            },
            frame_ms: vec![],
        });
        let mut full = run("issm-soft", 1.0, 20.0);
        full.ssdo = "semantic".into();
        let runs = vec![
            run("none", 1.0, 10.0),
            hard,
            run("issm-soft", 1.0, 13.2),
            full,
        ];
        let r = ratios(&runs);
        let get = |p: &str| {
            r.iter()
                .find(|(k, _)| k.starts_with(p))
                .map(|(_, v)| *v)
                .unwrap()
        };
        assert!((get("issm_overhead") - 1.1).abs() < 1e-12);
        assert!((get("issm_soft_overhead") - 1.32).abs() < 1e-12);
        assert!((get("soft_over_hard") - 1.2).abs() < 1e-12);
        assert!((get("ms_per_million_spheres") - 5.0).abs() < 1e-12);
        assert!((get("issm_cached_overhead") - 1.05).abs() < 1e-12);
        assert!((get("full_over_local") - 2.0).abs() < 1e-12);
        // measured together, the cached frames divide by the local frames
        // of the same rounds
        let mut runs = runs;
        runs[0].light_cached = Some(crate::output::CachedStats {
            passes: vec![],
            total_ms: TotalStats {
                median: 7.0,
                min: 7.0,
                max: 7.0,
            },
            frame_ms: vec![],
        });
        let r = ratios(&runs);
        let cached = r
            .iter()
            .find(|(k, _)| k.starts_with("issm_cached_overhead"))
            .map(|(_, v)| *v);
        assert!((cached.unwrap() - 1.5).abs() < 1e-12);
        assert!(
            r.iter()
                .any(|(k, v)| k.starts_with("issm_overhead") && (*v - 1.1).abs() < 1e-12)
        );
    }

    /// Runs measured together divide frame by frame: a slow spell that hit
    /// one round hits both runs' frames of it and cancels.
    #[test]
    fn ratios_pair_the_frames_of_one_round() {
        let mut local = run("none", 1.0, 20.0);
        local.frame_ms = vec![10.0, 20.0, 30.0];
        let mut hard = run("issm", 1.0, 22.0);
        hard.frame_ms = vec![12.0, 22.0, 60.0];
        let get = |runs: &[RunStats]| {
            ratios(runs)
                .into_iter()
                .find(|(k, _)| k.starts_with("issm_overhead"))
                .map(|(_, v)| v)
                .unwrap()
        };
        // per-frame 1.2, 1.1, 2.0: median 1.2 (the medians' ratio is 1.1)
        assert!((get(&[local.clone(), hard.clone()]) - 1.2).abs() < 1e-12);
        // frames that do not pair up: the medians' ratio
        hard.frame_ms.pop();
        assert!((get(&[local, hard]) - 1.1).abs() < 1e-12);
        assert!((paired(&[], 3.0, &[], 2.0) - 1.5).abs() < 1e-12);
        assert!((paired(&[1.0, 3.0], 2.0, &[1.0, 1.0], 1.0) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn scaling_exponent_is_the_log_log_slope() {
        let mut runs = Vec::new();
        for (n, t) in [
            (100_000, 10.0),
            (1_000_000, 40.0),
            (4_000_000, 10.0 * 40f64.sqrt()),
        ] {
            let mut r = run("none", 1.0, t);
            r.spheres = n;
            runs.push(r);
        }
        let r = ratios(&runs);
        let k: Vec<f64> = r
            .iter()
            .filter(|(k, _)| k.starts_with("scaling_exponent"))
            .map(|(_, v)| *v)
            .collect();
        assert_eq!(k.len(), 1, "{r:?}");
        // Smallest to largest count: 40x spheres, sqrt(40)x time.
        assert!((k[0] - 0.5).abs() < 1e-12, "{k:?}");
    }

    #[test]
    fn summary_has_one_row_per_data_set_and_a_column_per_technique() {
        let mut runs = vec![run("none", 1.0, 10.0), run("issm", 1.0, 11.0)];
        let mut big = run("none", 1.0, 40.0);
        big.spheres = 4_000_000;
        runs.push(big);
        let report = BenchReport {
            ratios: ratios(&runs),
            runs,
            failed: Vec::new(),
            complete: true,
        };
        let s = summary(&report);
        let lines: Vec<&str> = s.lines().collect();
        assert!(lines[0].contains("| none | issm |"), "{s}");
        assert!(lines[2].contains("| 2000000 | 64x48 | 10 | 11 |"), "{s}");
        assert!(lines[2].contains("| 1.10 |"), "ISSM overhead: {s}");
        // The 4M row has no ISSM run: a dash, not a number.
        assert!(lines[3].contains("| 4000000 | 64x48 | 40 | - |"), "{s}");
        assert!(s.contains("scaling_exponent"), "{s}");
    }

    #[test]
    fn compare_is_new_over_old_per_pass() {
        let old = BenchReport {
            runs: vec![run("issm", 2.0, 8.0)],
            ratios: Default::default(),
            failed: Vec::new(),
            complete: true,
        };
        let new = BenchReport {
            runs: vec![run("issm", 3.0, 4.0), run("none", 1.0, 1.0)],
            ratios: Default::default(),
            failed: Vec::new(),
            complete: true,
        };
        let c = compare(&new, &old);
        assert_eq!(c.len(), 2, "only the matching run is compared: {c:?}");
        assert_eq!((c[0].1.as_str(), c[0].2), ("raster", 1.5));
        assert_eq!((c[1].1.as_str(), c[1].2), ("total", 0.5));
    }
}
