//! What a bench report says: ratios between runs that differ in one
//! setting, the table and summary, the comparison with an earlier report,
//! and its chart.

use super::{BenchReport, chart};
use crate::error::{Error, Result};
use crate::output::{self, RunStats};
use crate::settings::{RasterMode, ShadowMode, SsdoMode};
use std::collections::BTreeMap;

/// What makes two runs the same run (`--compare` matches on it): a half
/// see-through run is not its opaque twin.
type RunKey = (
    String,
    u64,
    bool,
    u32,
    u32,
    String,
    String,
    String,
    u64,
    bool,
);

pub(super) fn key(r: &RunStats) -> RunKey {
    (
        r.input.clone(),
        r.spheres,
        r.instances.is_some(),
        r.width,
        r.height,
        r.shadows.clone(),
        r.ssdo.clone(),
        r.raster.clone(),
        (r.opacity * 1000.0).round() as u64,
        half_see_through(r),
    )
}

/// Data set and size of a run, as ratio names carry it in brackets (an
/// instanced model drawn expanded says so).
fn data_tag(r: &RunStats) -> String {
    let expanded = if r.expanded { " expanded" } else { "" };
    format!(
        "{} {}sph {}x{}{expanded}",
        r.input, r.spheres, r.width, r.height
    )
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
pub(super) fn paired(a_ms: &[f64], a: f64, b_ms: &[f64], b: f64) -> f64 {
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
/// A run with see-through spheres at opacity 1: bench's half see-through
/// frame (its spheres' alpha, not `--opacity`).
fn half_see_through(r: &RunStats) -> bool {
    r.see_through.is_some() && r.opacity == 1.0
}

pub fn ratios(runs: &[RunStats]) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    // (the JSON spells the modes as the command line does: `name()`)
    let find =
        |base: &RunStats, shadows: ShadowMode, ssdo: SsdoMode, raster: RasterMode, opacity: f64| {
            runs.iter().find(|r| {
                (r.input.as_str(), r.spheres, r.width, r.height)
                    == (base.input.as_str(), base.spheres, base.width, base.height)
                    && r.expanded == base.expanded
                    && r.shadows == shadows.name()
                    && r.ssdo == ssdo.name()
                    && r.raster == raster.name()
                    && (r.opacity - opacity).abs() < 1e-6
                    && !half_see_through(r)
            })
        };
    // Half of the spheres see-through, against the same frame opaque (any
    // technique: the name says which).
    for h in runs.iter().filter(|r| half_see_through(r)) {
        let same = |x: &&RunStats| {
            !half_see_through(x)
                && (x.input.as_str(), x.spheres, x.width, x.height, x.expanded)
                    == (h.input.as_str(), h.spheres, h.width, h.height, h.expanded)
                && (x.shadows.as_str(), x.ssdo.as_str(), x.raster.as_str())
                    == (h.shadows.as_str(), h.ssdo.as_str(), h.raster.as_str())
                && x.opacity == h.opacity
        };
        if let Some(o) = runs.iter().find(same) {
            out.insert(
                format!(
                    "see_through_half_over_opaque[{} {}+{}]",
                    data_tag(h),
                    h.shadows,
                    h.ssdo
                ),
                paired(
                    &h.frame_ms,
                    h.total_ms.median,
                    &o.frame_ms,
                    o.total_ms.median,
                ),
            );
        }
    }
    let bases = runs.iter().filter(|r| {
        r.shadows == ShadowMode::None.name()
            && r.ssdo == SsdoMode::Off.name()
            && r.raster == RasterMode::Compute.name()
            && r.opacity == 1.0
            && !half_see_through(r)
    });
    let frame = |x: &RunStats| x.total_ms.median;
    let over = |a: &RunStats, b: &RunStats| paired(&a.frame_ms, frame(a), &b.frame_ms, frame(b));
    for r in bases {
        let tag = data_tag(r);
        let hard = find(r, ShadowMode::Issm, SsdoMode::Off, RasterMode::Compute, 1.0);
        let soft = find(
            r,
            ShadowMode::IssmSoft,
            SsdoMode::Off,
            RasterMode::Compute,
            1.0,
        );
        let deep = find(r, ShadowMode::Deep, SsdoMode::Off, RasterMode::Compute, 1.0);
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
        if let Some(f) = find(
            r,
            ShadowMode::IssmSoft,
            SsdoMode::Semantic,
            RasterMode::Compute,
            1.0,
        ) {
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
        if let (Some(d5), Some(d)) = (
            find(r, ShadowMode::Deep, SsdoMode::Off, RasterMode::Compute, 0.5),
            deep,
        ) {
            out.insert(format!("deep_translucent_over_opaque[{tag}]"), over(d5, d));
        }
        if let (Some(se), Some(pl)) = (
            find(
                r,
                ShadowMode::IssmSoft,
                SsdoMode::Semantic,
                RasterMode::Compute,
                1.0,
            ),
            find(
                r,
                ShadowMode::IssmSoft,
                SsdoMode::Plain,
                RasterMode::Compute,
                1.0,
            ),
        ) {
            out.insert(format!("semantic_over_plain[{tag}]"), over(se, pl));
        }
        if let Some(g) = find(
            r,
            ShadowMode::None,
            SsdoMode::Off,
            RasterMode::Graphics,
            1.0,
        ) && let (Some(gr), Some(cr)) = (pass_ms(g, "raster"), pass_ms(r, "raster"))
        {
            out.insert(format!("graphics_over_compute_raster[{tag}]"), gr / cr);
        }
        out.insert(
            format!("ms_per_million_spheres[{tag}]"),
            frame(r) / (r.spheres as f64 / 1e6),
        );
    }
    // An instanced model against itself expanded (same rounds), and
    // against the 1M capsid at the same size (its own rounds: medians).
    for r in runs.iter().filter(|r| r.instances.is_some()) {
        let tech = format!("{}/{}", r.shadows, r.ssdo);
        let twin = runs.iter().find(|x| {
            x.expanded
                && (
                    x.input.as_str(),
                    x.spheres,
                    x.width,
                    x.height,
                    &x.shadows,
                    &x.ssdo,
                    &x.raster,
                ) == (
                    r.input.as_str(),
                    r.spheres,
                    r.width,
                    r.height,
                    &r.shadows,
                    &r.ssdo,
                    &r.raster,
                )
                && (x.opacity - r.opacity).abs() < 1e-6
        });
        if let Some(x) = twin {
            out.insert(
                format!("instanced_over_expanded[{} {tech}]", data_tag(r)),
                over(r, x),
            );
        }
        let capsid = runs.iter().find(|x| {
            x.input == "scene:capsid"
                && x.spheres == 1_000_000
                && (x.width, x.height, &x.shadows, &x.ssdo, &x.raster)
                    == (r.width, r.height, &r.shadows, &r.ssdo, &r.raster)
        });
        if let Some(c) = capsid {
            out.insert(
                format!("over_capsid_1m[{} {tech}]", data_tag(r)),
                frame(r) / frame(c),
            );
        }
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
            let what = if r.shadows == ShadowMode::None.name() {
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
    if r.ssdo != SsdoMode::Off.name() {
        l += &format!("+{}", r.ssdo);
    }
    if r.opacity < 1.0 {
        l += &format!(" a{}", r.opacity);
    }
    if r.raster != RasterMode::Compute.name() {
        l += " gfx";
    }
    if half_see_through(r) {
        l += " half see-through";
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
            "{} {}x{} {}/{}/{}{}",
            n.input,
            n.width,
            n.height,
            n.shadows,
            n.ssdo,
            n.raster,
            if half_see_through(n) {
                " half see-through"
            } else {
                ""
            }
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

pub(super) fn write_chart(report: &BenchReport, path: &std::path::Path) -> Result<()> {
    output::AovImage::Rgba8(
        image::DynamicImage::ImageRgb8(chart::bar_chart(&report.runs)).to_rgba8(),
    )
    .save_png(path)
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
            instances: None,
            molecules: None,
            unique_atoms: None,
            placements: None,
            expanded: false,
            spheres_drawn: 2_000_000,
            camera: Default::default(),
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
            see_through: None,
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
        // the same frame with half of the spheres see-through: it is
        // neither the full frame nor a local-lighting base
        let mut half = full.clone();
        half.total_ms.median = 50.0;
        half.see_through = Some(Default::default());
        let runs = vec![
            run("none", 1.0, 10.0),
            hard,
            run("issm-soft", 1.0, 13.2),
            half,
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
        assert!((get("see_through_half_over_opaque") - 2.5).abs() < 1e-12);
        assert!(
            get("see_through_half_over_opaque").to_bits()
                == r[&format!(
                    "see_through_half_over_opaque[{} issm-soft+semantic]",
                    data_tag(&runs[4])
                )]
                    .to_bits()
        );
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
        // A half see-through run matches its own kind, not the opaque run
        // of the same technique listed before it.
        let half = |raster, total| {
            let mut r = run("issm", raster, total);
            r.see_through = Some(Default::default());
            r
        };
        let old = BenchReport {
            runs: vec![run("issm", 2.0, 8.0), half(4.0, 40.0)],
            ..old
        };
        let new = BenchReport {
            runs: vec![half(2.0, 20.0), run("issm", 2.0, 8.0)],
            ..new
        };
        let c = compare(&new, &old);
        assert_eq!(c.len(), 4, "{c:?}");
        assert!(c[0].0.ends_with("half see-through"), "{c:?}");
        assert_eq!((c[1].1.as_str(), c[1].2), ("total", 0.5));
        assert_eq!((c[3].1.as_str(), c[3].2), ("total", 1.0));
    }
}
