//! `sphereshade bench`: a matrix of runs (cross product of the list-valued
//! flags) in one process on one device so ratios between runs are fair;
//! per-pass timestamp medians, memory, image hashes, derived ratios, and
//! `--compare` against an earlier JSON. `cargo bench` (benches/frame.rs)
//! calls the same code.

use crate::cli::{self, SceneArgs, ViewArgs};
use crate::error::{Error, Result};
use crate::output::{self, RunStats};
use crate::scene::Scene;
use crate::settings::{Aov, RasterMode, ShadowMode, SsdoMode};
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
    #[arg(long)]
    pub size: Option<String>,
    #[arg(long, default_value_t = 5)]
    pub frames: u32,
    #[arg(long, default_value_t = 1)]
    pub warmup: u32,
    /// Small matrix that finishes in about two minutes on lavapipe.
    #[arg(long)]
    pub quick: bool,
    #[arg(long)]
    pub json: PathBuf,
    /// Earlier bench JSON: print per-pass ratios new/old for matching runs.
    #[arg(long)]
    pub compare: Option<PathBuf>,
    #[arg(long, value_parser = cli::parse_replicate)]
    pub replicate: Option<[u32; 3]>,
    #[arg(long, default_value_t = 1.0)]
    pub radius_scale: f32,
    /// Key-light direction.
    #[arg(long, value_parser = cli::parse_vec3, default_value = "-1,-1,-1", allow_hyphen_values = true)]
    pub light: glam::DVec3,
    #[arg(long)]
    pub validate: bool,
    #[arg(long)]
    pub device: Option<usize>,
}

/// The whole bench output.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchReport {
    pub runs: Vec<RunStats>,
    /// Derived ratios (name -> value), see `ratios`.
    #[serde(default)]
    pub ratios: BTreeMap<String, f64>,
}

fn list<T: ValueEnum + Clone>(s: &Option<String>, default: &[T], flag: &str) -> Result<Vec<T>> {
    match s {
        None => Ok(default.to_vec()),
        Some(s) => s
            .split(',')
            .map(|p| {
                T::from_str(p.trim(), true)
                    .map_err(|_| Error::Invalid(format!("{flag} {s}: '{p}' is not valid")))
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
                    .map_err(|_| Error::Invalid(format!("{flag} {s}: '{p}' is not valid")))
            })
            .collect(),
    }
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| Error::Invalid(format!("--size {s}: expected WxH")))?;
    let p = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|v| (1..=16384).contains(v))
    };
    match (p(w), p(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(Error::Invalid(format!(
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
        input: None,
        scene: None,
        atoms: None,
        model: None,
        assembly: None,
        replicate: a.replicate,
        radius_scale: a.radius_scale,
        color: "element".into(),
    };
    if a.inputs.is_empty() {
        let names = a.scene.clone().unwrap_or_else(|| "capsid".into());
        for name in names.split(',') {
            for &n in atoms {
                let args = SceneArgs {
                    scene: Some(name.trim().to_string()),
                    atoms: Some(n),
                    ..base.clone()
                };
                eprintln!("bench: building scene {name} with {n} spheres");
                let (scene, load_ms) = cli::load_scene(&args)?;
                sets.push(DataSet {
                    name: format!("scene:{}", name.trim()),
                    scene,
                    load_ms,
                });
            }
        }
    } else {
        if a.atoms.is_some() || a.scene.is_some() {
            return Err(Error::Invalid(
                "--atoms/--scene apply when no input file is given".into(),
            ));
        }
        for p in &a.inputs {
            let args = SceneArgs {
                input: Some(p.clone()),
                ..base.clone()
            };
            eprintln!("bench: loading {}", p.display());
            let (scene, load_ms) = cli::load_scene(&args)?;
            sets.push(DataSet {
                name: p.display().to_string(),
                scene,
                load_ms,
            });
        }
    }
    Ok(sets)
}

/// Modes a run can use today; others are rejected up front with a clear line.
fn check_supported(shadows: ShadowMode, raster: RasterMode) -> Result<()> {
    let _ = raster; // both raster modes are implemented
    let _ = shadows; // every shadow mode is implemented (deep included)
    Ok(())
}

pub fn run(a: &BenchArgs) -> Result<BenchReport> {
    let (def_atoms, def_sizes, def_shadows): (Vec<usize>, Vec<(u32, u32)>, Vec<ShadowMode>) =
        if a.quick {
            (
                vec![100_000],
                vec![(960, 540)],
                vec![ShadowMode::None, ShadowMode::Issm, ShadowMode::IssmSoft],
            )
        } else {
            (
                vec![100_000, 1_000_000],
                vec![(1920, 1080)],
                vec![ShadowMode::None, ShadowMode::Issm, ShadowMode::IssmSoft],
            )
        };
    let shadows = list(&a.shadows, &def_shadows, "--shadows")?;
    let ssdo = list(&a.ssdo, &[SsdoMode::Off], "--ssdo")?;
    let raster = list(&a.raster, &[RasterMode::Compute], "--raster")?;
    let opacity: Vec<f32> = parse_list(&a.opacity, &[1.0], "--opacity")?;
    let atoms: Vec<usize> = parse_list(&a.atoms, &def_atoms, "--atoms")?;
    let sizes = match &a.size {
        None => def_sizes,
        Some(s) => s.split(',').map(parse_size).collect::<Result<_>>()?,
    };
    for &sh in &shadows {
        for &ra in &raster {
            check_supported(sh, ra)?;
        }
    }
    if opacity.iter().any(|o| !(0.0..=1.0).contains(o)) {
        return Err(Error::Invalid(
            "--opacity values must be between 0 and 1".into(),
        ));
    }
    let sets = data_sets(a, &atoms)?;
    let ctx = Context::new(&crate::vk::ContextOptions {
        validate: a.validate,
        device_index: a.device,
        ..Default::default()
    })?;
    eprintln!("bench: device {} ({})", ctx.info.name, ctx.info.driver);

    let total =
        sets.len() * shadows.len() * ssdo.len() * raster.len() * opacity.len() * sizes.len();
    let mut runs = Vec::new();
    for set in &sets {
        for &(w, h) in &sizes {
            for &sh in &shadows {
                for &ss in &ssdo {
                    for &ra in &raster {
                        for &op in &opacity {
                            eprintln!(
                                "bench: run {}/{total}: {} ({} spheres) {w}x{h} shadows={} ssdo={} raster={} opacity={op}",
                                runs.len() + 1,
                                set.name,
                                set.scene.spheres.len(),
                                sh.name(),
                                ss.name(),
                                ra.name()
                            );
                            let view = ViewArgs {
                                width: w,
                                height: h,
                                shadows: sh,
                                issm_size: 512,
                                issm_t: "auto".into(),
                                soft_s: None,
                                soft_x: None,
                                soft_b: None,
                                opacity: op,
                                ssdo: ss,
                                blur: "on".into(),
                                raster: ra,
                                light: a.light,
                                view_dir: glam::DVec3::new(0.0, 0.0, -1.0),
                                up: glam::DVec3::Y,
                                view_center: None,
                                view_height: None,
                                fov: None,
                                validate: a.validate,
                                device: a.device,
                                deep_pool_chunks: None,
                                semantic_levels: None,
                            };
                            let settings = cli::settings_for(&set.scene, &view)?;
                            let out = cli::render_run(
                                &ctx,
                                &set.scene,
                                &set.name,
                                settings,
                                Aov::Color,
                                a.warmup,
                                a.frames,
                                set.load_ms,
                            )?;
                            runs.push(out.stats);
                        }
                    }
                }
            }
        }
    }
    let ratios = ratios(&runs);
    Ok(BenchReport { runs, ratios })
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

/// Derived ratios of frame medians between runs that differ in one setting:
/// ISSM overhead (issm-soft / none and issm / none), soft/hard, and time per
/// million spheres per data set, each named after the data set and size.
pub fn ratios(runs: &[RunStats]) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    let find = |base: &RunStats, shadows: &str| {
        runs.iter().find(|r| {
            let (a, b) = (key(r), key(base));
            (a.0, a.1, a.2, a.3, &a.5, &a.6, a.7) == (b.0, b.1, b.2, b.3, &b.5, &b.6, b.7)
                && r.shadows == shadows
        })
    };
    for r in runs.iter().filter(|r| r.shadows == "none") {
        let tag = format!("{} {}sph {}x{}", r.input, r.spheres, r.width, r.height);
        if let Some(h) = find(r, "issm") {
            out.insert(
                format!("issm_overhead[{tag}]"),
                h.total_ms.median / r.total_ms.median,
            );
        }
        if let Some(s) = find(r, "issm-soft") {
            out.insert(
                format!("issm_soft_overhead[{tag}]"),
                s.total_ms.median / r.total_ms.median,
            );
            if let Some(h) = find(r, "issm") {
                out.insert(
                    format!("soft_over_hard[{tag}]"),
                    s.total_ms.median / h.total_ms.median,
                );
            }
        }
        out.insert(
            format!("ms_per_million_spheres[{tag}]"),
            r.total_ms.median / (r.spheres as f64 / 1e6),
        );
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
    }
    if !report.ratios.is_empty() {
        s += "ratios:\n";
        for (k, v) in &report.ratios {
            s += &format!("  {k} = {v:.3}\n");
        }
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
        .map_err(|e| Error::Invalid(format!("{}: not a bench JSON: {e}", path.display())))
}

/// The `bench` subcommand: run, print, write, compare.
pub fn main(a: &BenchArgs) -> Result<u32> {
    let old = a.compare.as_deref().map(read_report).transpose()?;
    let report = run(a)?;
    print!("{}", table(&report));
    output::write_json(&a.json, &report)?;
    if let Some(old) = old {
        println!("compare (new / old median ms):");
        for (run, pass, r) in compare(&report, &old) {
            println!("  {run:<60} {pass:<14} {r:.3}");
        }
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
            validation_messages: 0,
            deep: None,
            image_sha256: String::new(),
        }
    }

    #[test]
    fn ratios_divide_matching_runs() {
        let runs = vec![
            run("none", 1.0, 10.0),
            run("issm", 1.0, 11.0),
            run("issm-soft", 1.0, 13.2),
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
    }

    #[test]
    fn compare_is_new_over_old_per_pass() {
        let old = BenchReport {
            runs: vec![run("issm", 2.0, 8.0)],
            ratios: Default::default(),
        };
        let new = BenchReport {
            runs: vec![run("issm", 3.0, 4.0), run("none", 1.0, 1.0)],
            ratios: Default::default(),
        };
        let c = compare(&new, &old);
        assert_eq!(c.len(), 2, "only the matching run is compared: {c:?}");
        assert_eq!((c[0].1.as_str(), c[0].2), ("raster", 1.5));
        assert_eq!((c[1].1.as_str(), c[1].2), ("total", 0.5));
    }
}
