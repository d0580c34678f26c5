//! Command line (DESIGN.md): `info`, `render`, `bench`, `view`.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::output::{self, RunStats};
use crate::render::{PassTimes, Renderer, default_camera};
use crate::scene::{self, ColorBy, LoadOptions, ModelSelect, Scene};
use crate::settings::{
    Aov, IssmParams, RasterMode, RenderSettings, ShadowMapParams, ShadowMode, SsdoMode,
};
use crate::vk::{Context, ContextOptions};
use clap::{Args, Parser, Subcommand};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Parser, Debug)]
#[command(
    name = "sphereshade",
    version,
    about = "Vulkan compute renderer for millions of spheres"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// List Vulkan devices, the chosen device, limits and features.
    Info {
        #[arg(long)]
        device: Option<usize>,
    },
    /// Render one scene to a PNG (and optionally JSON stats).
    Render(RenderArgs),
    /// Run a benchmark matrix and write per-pass timings as JSON.
    Bench(crate::bench::BenchArgs),
    /// Open a window; see `H` in the window or the README for controls.
    View(crate::app::ViewCmd),
}

/// Where spheres come from (shared by render/bench/view).
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Structure file: .pdb .cif/.mmcif .gro .xyz .xyzr, optionally .gz.
    pub input: Option<PathBuf>,
    /// Procedural scene: capsid (default), lattice, random.
    #[arg(long)]
    pub scene: Option<String>,
    /// Sphere count of the procedural scene.
    #[arg(long)]
    pub atoms: Option<usize>,
    /// Model to load: a MODEL number or `all` (default: the first).
    #[arg(long)]
    pub model: Option<String>,
    /// Biological assembly (REMARK 350 BIOMOLECULE number) to build.
    #[arg(long)]
    pub assembly: Option<u32>,
    /// Tile the input in a lattice, e.g. 6x6x5.
    #[arg(long, value_parser = parse_replicate)]
    pub replicate: Option<[u32; 3]>,
    /// Multiply all radii.
    #[arg(long, default_value_t = 1.0)]
    pub radius_scale: f32,
    /// Colour by element (default) or chain.
    #[arg(long, default_value = "element", value_parser = ["element", "chain"])]
    pub color: String,
}

/// Image, camera, lighting and technique options.
#[derive(Args, Debug, Clone)]
pub struct ViewArgs {
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    #[arg(long, value_enum, default_value = "issm-soft")]
    pub shadows: ShadowMode,
    #[arg(long, default_value_t = 512)]
    pub issm_size: u32,
    /// Patch half-size t, or `auto`.
    #[arg(long, default_value = "auto")]
    pub issm_t: String,
    #[arg(long)]
    pub soft_s: Option<f32>,
    #[arg(long)]
    pub soft_x: Option<f32>,
    #[arg(long)]
    pub soft_b: Option<f32>,
    /// Depth shadow map side in texels (`--shadows sm-pcf`).
    #[arg(long, default_value_t = 2048)]
    pub sm_size: u32,
    /// Constant depth bias of the shadow map, in map texels.
    #[arg(long, default_value_t = 0.5)]
    pub sm_bias: f32,
    /// Slope-scaled bias factor: times tan(N, light) times the lookup reach
    /// (half a texel diagonal + PCF radius), in texels.
    #[arg(long, default_value_t = 1.0)]
    pub sm_slope_bias: f32,
    /// PCF taps on a Vogel disk rotated per pixel (0 or 1 = single tap).
    #[arg(long, default_value_t = 16)]
    pub pcf_samples: u32,
    /// PCF disk radius in shadow-map texels.
    #[arg(long, default_value_t = 1.5)]
    pub pcf_radius: f32,
    /// Opacity shadow map side in texels (`--shadows osm`).
    #[arg(long, default_value_t = 512)]
    pub osm_size: u32,
    /// Depth slices of the opacity shadow map.
    #[arg(long, default_value_t = 64)]
    pub osm_slices: u32,
    /// Opacity of every sphere (0..1) for translucent shadows.
    #[arg(long, default_value_t = 1.0)]
    pub opacity: f32,
    #[arg(long, value_enum, default_value = "semantic")]
    pub ssdo: SsdoMode,
    #[arg(long, default_value = "on", value_parser = ["on", "off"])]
    pub blur: String,
    #[arg(long, value_enum, default_value = "compute")]
    pub raster: RasterMode,
    /// Key-light direction (from the light toward the scene).
    #[arg(long, value_parser = parse_vec3, default_value = "-1,-1,-1", allow_hyphen_values = true)]
    pub light: DVec3,
    #[arg(long, value_parser = parse_vec3, default_value = "0,0,-1", allow_hyphen_values = true)]
    pub view_dir: DVec3,
    #[arg(long, value_parser = parse_vec3, default_value = "0,1,0", allow_hyphen_values = true)]
    pub up: DVec3,
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    pub view_center: Option<DVec3>,
    /// Orthographic view height in world units.
    #[arg(long)]
    pub view_height: Option<f64>,
    /// Perspective vertical field of view in degrees.
    #[arg(long)]
    pub fov: Option<f64>,
    /// Enable validation (GPU-assisted + synchronization); exit 3 on any message.
    #[arg(long)]
    pub validate: bool,
    /// Physical device index (see `sphereshade info`).
    #[arg(long)]
    pub device: Option<usize>,
    /// Initial deep-list pool size in chunks of 64 entries (grown on overflow).
    #[arg(long)]
    pub deep_pool_chunks: Option<u32>,
    /// Zoom thresholds for semantic SSDO levels: comma list of visible
    /// heights (world units, descending) where the next finer level takes over.
    #[arg(long)]
    pub semantic_levels: Option<String>,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub view: ViewArgs,
    /// What --out holds.
    #[arg(long, value_enum, default_value = "color")]
    pub aov: Aov,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Measured frames (timings are median/min/max over them).
    #[arg(long, default_value_t = 1)]
    pub frames: u32,
    #[arg(long, default_value_t = 0)]
    pub warmup: u32,
}

pub fn parse_vec3(s: &str) -> std::result::Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(format!("'{s}': expected X,Y,Z"));
    }
    let mut v = [0.0; 3];
    for (o, p) in v.iter_mut().zip(&parts) {
        *o = p
            .trim()
            .parse::<f64>()
            .map_err(|_| format!("'{s}': '{p}' is not a number"))?;
        if !o.is_finite() {
            return Err(format!("'{s}': components must be finite"));
        }
    }
    Ok(DVec3::from_array(v))
}

pub fn parse_replicate(s: &str) -> std::result::Result<[u32; 3], String> {
    let parts: Vec<&str> = s.split(['x', 'X']).collect();
    if parts.len() != 3 {
        return Err(format!("'{s}': expected AxBxC, e.g. 6x6x5"));
    }
    let mut v = [0u32; 3];
    for (o, p) in v.iter_mut().zip(&parts) {
        *o = p
            .trim()
            .parse()
            .map_err(|_| format!("'{s}': '{p}' is not a positive integer"))?;
        if *o == 0 {
            return Err(format!("'{s}': counts must be at least 1"));
        }
    }
    Ok(v)
}

/// Loads the scene the arguments describe, with progress on stderr for
/// files above a few megabytes. Returns the scene and the load time in ms.
pub fn load_scene(args: &SceneArgs) -> Result<(Scene, f64)> {
    load_scene_with_progress(args, &mut |_, _| {})
}

/// `load_scene` that also reports (bytes done, bytes total) to `report`.
pub fn load_scene_with_progress(
    args: &SceneArgs,
    report: &mut dyn FnMut(u64, u64),
) -> Result<(Scene, f64)> {
    let t0 = Instant::now();
    let mut scene = match (&args.input, &args.scene) {
        (Some(_), Some(_)) => {
            return Err(Error::Invalid(
                "give an input file or --scene, not both".into(),
            ));
        }
        (Some(path), None) => {
            let model = match args.model.as_deref() {
                None => ModelSelect::First,
                Some("all") => ModelSelect::All,
                Some(n) => ModelSelect::Index(n.parse().map_err(|_| {
                    Error::Invalid(format!("--model {n}: expected a number or `all`"))
                })?),
            };
            let opts = LoadOptions {
                model,
                assembly: args.assembly,
                color_by: if args.color == "chain" {
                    ColorBy::Chain
                } else {
                    ColorBy::Element
                },
            };
            let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            let show = size > 8 << 20;
            let mut last = 0u64;
            let mut progress = |done: u64, total: u64| {
                report(done, total);
                let pct = (done * 100).checked_div(total).unwrap_or(0);
                if show && pct >= last + 5 {
                    last = pct;
                    eprint!("\rloading {}: {pct:3}%", path.display());
                }
            };
            let s = scene::load(path, &opts, &mut progress)?;
            if show {
                eprintln!(
                    "\rloading {}: done, {} spheres",
                    path.display(),
                    s.spheres.len()
                );
            }
            s
        }
        (None, name) => {
            if args.model.is_some() || args.assembly.is_some() {
                return Err(Error::Invalid(
                    "--model/--assembly apply to input files only".into(),
                ));
            }
            let name = name.as_deref().unwrap_or(scene::DEFAULT_SCENE);
            let atoms = args.atoms.unwrap_or(scene::DEFAULT_ATOMS);
            if atoms == 0 {
                return Err(Error::Invalid("--atoms must be at least 1".into()));
            }
            scene::procedural(name, atoms, 1)?
        }
    };
    if args.atoms.is_some() && args.input.is_some() {
        return Err(Error::Invalid(
            "--atoms applies to procedural scenes (--scene) only".into(),
        ));
    }
    if let Some(n) = args.replicate {
        // Refuse before allocating: sphere ids are 24-bit in the id AOV.
        let total = scene.spheres.len() as u64 * n.iter().map(|&k| k as u64).product::<u64>();
        if total >= 1 << 24 {
            return Err(Error::Invalid(format!(
                "--replicate {}x{}x{}: {total} spheres; at most 16,777,215 are supported",
                n[0], n[1], n[2]
            )));
        }
        scene = scene.replicate(n);
    }
    if !(args.radius_scale > 0.0 && args.radius_scale.is_finite()) {
        return Err(Error::Invalid("--radius-scale must be positive".into()));
    }
    if args.radius_scale != 1.0 {
        scene.scale_radii(args.radius_scale);
    }
    Ok((scene, t0.elapsed().as_secs_f64() * 1e3))
}

/// Resolves the view arguments against a scene into render settings.
pub fn settings_for(scene: &Scene, v: &ViewArgs) -> Result<RenderSettings> {
    let camera: Camera = default_camera(
        scene,
        v.width,
        v.height,
        v.view_dir,
        v.up,
        v.view_center,
        v.view_height,
        v.fov,
    )?;
    if !(0.0..=1.0).contains(&v.opacity) {
        return Err(Error::Invalid("--opacity must be between 0 and 1".into()));
    }
    if !(v.light.length() > 0.0) {
        return Err(Error::Invalid(
            "--light must be a non-zero direction".into(),
        ));
    }
    if !(16..=8192).contains(&v.issm_size) {
        return Err(Error::Invalid(
            "--issm-size must be between 16 and 8192".into(),
        ));
    }
    let mut issm = IssmParams {
        size: v.issm_size,
        ..Default::default()
    };
    issm.t =
        match v.issm_t.as_str() {
            "auto" => None,
            t => Some(t.parse::<u32>().ok().filter(|t| *t <= 32).ok_or_else(|| {
                Error::Invalid(format!("--issm-t {t}: expected 0..32 or `auto`"))
            })?),
        };
    for (val, slot, name) in [
        (v.soft_s, &mut issm.soft_s, "--soft-s"),
        (v.soft_x, &mut issm.soft_x, "--soft-x"),
        (v.soft_b, &mut issm.soft_b, "--soft-b"),
    ] {
        if let Some(x) = val {
            if !(x > 0.0 && x.is_finite()) {
                return Err(Error::Invalid(format!("{name} must be positive")));
            }
            *slot = x;
        }
    }
    // Baseline shadow map (sm-pcf) and opacity shadow map (osm) options.
    if !(16..=8192).contains(&v.sm_size) {
        return Err(Error::Invalid(
            "--sm-size must be between 16 and 8192".into(),
        ));
    }
    for (x, name) in [
        (v.sm_bias, "--sm-bias"),
        (v.sm_slope_bias, "--sm-slope-bias"),
        (v.pcf_radius, "--pcf-radius"),
    ] {
        if !(0.0..=1e4).contains(&x) {
            return Err(Error::Invalid(format!(
                "{name} must be between 0 and 10000 (texels)"
            )));
        }
    }
    if v.pcf_samples > 256 {
        return Err(Error::Invalid(
            "--pcf-samples must be between 0 and 256".into(),
        ));
    }
    if !(16..=4096).contains(&v.osm_size) {
        return Err(Error::Invalid(
            "--osm-size must be between 16 and 4096".into(),
        ));
    }
    if !(1..=1024).contains(&v.osm_slices) {
        return Err(Error::Invalid(
            "--osm-slices must be between 1 and 1024".into(),
        ));
    }
    let shadow_maps = ShadowMapParams {
        sm_size: v.sm_size,
        sm_bias: v.sm_bias,
        sm_slope_bias: v.sm_slope_bias,
        pcf_samples: v.pcf_samples,
        pcf_radius: v.pcf_radius,
        osm_size: v.osm_size,
        osm_slices: v.osm_slices,
    };
    Ok(RenderSettings {
        camera,
        light: v.light,
        shadows: v.shadows,
        issm,
        shadow_maps,
        opacity: v.opacity,
        ssdo: v.ssdo,
        blur: v.blur == "on",
        raster: v.raster,
        deep_pool_chunks: v.deep_pool_chunks,
        semantic_levels: match &v.semantic_levels {
            None => None,
            Some(s) => {
                let t: Vec<f64> = s
                    .split(',')
                    .map(|p| {
                        p.trim()
                            .parse::<f64>()
                            .ok()
                            .filter(|x| *x > 0.0 && x.is_finite())
                    })
                    .collect::<Option<_>>()
                    .ok_or_else(|| {
                        Error::Invalid(format!("--semantic-levels {s}: expected positive numbers"))
                    })?;
                if t.windows(2).any(|w| w[1] >= w[0]) {
                    return Err(Error::Invalid(format!(
                        "--semantic-levels {s}: thresholds must descend"
                    )));
                }
                Some(t)
            }
        },
    })
}

pub fn context_for(v: &ViewArgs) -> Result<Context> {
    Context::new(&ContextOptions {
        validate: v.validate,
        device_index: v.device,
        ..Default::default()
    })
}

/// Renders `frames` measured frames after `warmup` ones.
pub fn run_frames(r: &mut Renderer, warmup: u32, frames: u32) -> Result<Vec<PassTimes>> {
    run_frames_with(r, warmup, frames, &mut |_, _| Ok(()))
}

/// `run_frames` calling `before(renderer, k)` ahead of measured frame k
/// (the benchmark moves the camera along its orbit there).
pub fn run_frames_with(
    r: &mut Renderer,
    warmup: u32,
    frames: u32,
    before: &mut dyn FnMut(&mut Renderer, u32) -> Result<()>,
) -> Result<Vec<PassTimes>> {
    for _ in 0..warmup {
        r.render_frame()?;
    }
    (0..frames.max(1))
        .map(|k| {
            before(r, k)?;
            r.render_frame()
        })
        .collect()
}

/// Reads the requested AOV back from the renderer and encodes it.
pub fn aov_image(r: &Renderer, aov: Aov) -> Result<output::AovImage> {
    let (w, h) = (r.settings.camera.width, r.settings.camera.height);
    Ok(match aov {
        Aov::Color => output::color_image(w, h, &r.read_color()?),
        Aov::Id => output::id_image(w, h, &r.read_vis()?),
        Aov::Depth => {
            let d: Vec<f32> = r.read_gpos()?.iter().map(|p| p[3]).collect();
            output::depth_image(w, h, &d)
        }
        Aov::Shadow | Aov::Ao => {
            let covered: Vec<bool> = r
                .read_vis()?
                .iter()
                .map(|&k| k != crate::gpu::VIS_EMPTY)
                .collect();
            if aov == Aov::Shadow {
                output::unit_image(w, h, r.read_shadow()?.into_iter(), &covered)
            } else {
                let ao: Vec<f32> = if r.settings.ssdo == SsdoMode::Off {
                    vec![1.0; covered.len()]
                } else {
                    r.read_ambient()?.into_iter().map(|a| a[0]).collect()
                };
                // (ambient visibility after the blur, as DESIGN.md specifies)
                output::unit_image(w, h, ao.into_iter(), &covered)
            }
        }
    })
}

/// Everything one render run produces.
pub struct RunOutcome {
    pub stats: RunStats,
    pub image: output::AovImage,
}

/// Loads nothing: renders an already loaded scene with settings, returning
/// the stats record and the AOV image.
#[allow(clippy::too_many_arguments)]
pub fn render_run(
    ctx: &Context,
    scene: &Scene,
    input: &str,
    settings: RenderSettings,
    aov: Aov,
    warmup: u32,
    frames: u32,
    load_ms: f64,
) -> Result<RunOutcome> {
    render_run_with(
        ctx,
        scene,
        input,
        settings,
        aov,
        warmup,
        frames,
        load_ms,
        &mut |_, _| Ok(()),
    )
}

/// `render_run` with a hook before each measured frame (see `run_frames_with`).
#[allow(clippy::too_many_arguments)]
pub fn render_run_with(
    ctx: &Context,
    scene: &Scene,
    input: &str,
    settings: RenderSettings,
    aov: Aov,
    warmup: u32,
    frames: u32,
    load_ms: f64,
    before: &mut dyn FnMut(&mut Renderer, u32) -> Result<()>,
) -> Result<RunOutcome> {
    let mut r = Renderer::new(ctx, scene, settings)?;
    let times = run_frames_with(&mut r, warmup, frames, before)?;
    let image = aov_image(&r, aov)?;
    let (passes, total_ms) = output::summarize(&times);
    let gpu_memory = r.memory_by_class();
    let s = &r.settings;
    let stats = RunStats {
        device: ctx.info.name.clone(),
        driver: ctx.info.driver.clone(),
        input: input.to_string(),
        spheres: r.sphere_count as u64,
        width: s.camera.width,
        height: s.camera.height,
        frames: frames.max(1),
        shadows: s.shadows.name(),
        ssdo: s.ssdo.name(),
        raster: s.raster.name(),
        opacity: s.opacity as f64,
        passes,
        total_ms,
        load_ms,
        gpu_memory_bytes: gpu_memory.values().sum(),
        gpu_memory,
        validation_messages: ctx.validation_messages(),
        deep: r.deep_stats.clone(),
        image_sha256: image.sha256(),
    };
    Ok(RunOutcome { stats, image })
}

fn input_name(args: &SceneArgs) -> String {
    match (&args.input, &args.scene) {
        (Some(p), _) => p.display().to_string(),
        (None, s) => format!("scene:{}", s.as_deref().unwrap_or(scene::DEFAULT_SCENE)),
    }
}

/// Exit status the binary should use.
pub enum Exit {
    Ok,
    ValidationMessages(u32),
}

pub fn run(cli: Cli) -> Result<Exit> {
    match cli.command {
        Command::Info { device } => info(device),
        Command::Render(args) => render(args),
        Command::View(args) => crate::app::run(args),
        Command::Bench(args) => {
            let n = crate::bench::main(&args)?;
            Ok(if n > 0 {
                Exit::ValidationMessages(n)
            } else {
                Exit::Ok
            })
        }
    }
}

fn info(device: Option<usize>) -> Result<Exit> {
    let (devices, limits) = crate::vk::enumerate_devices()?;
    if devices.is_empty() {
        return Err(Error::NoDevice);
    }
    for (d, l) in devices.iter().zip(&limits) {
        println!(
            "[{}] {} ({}), Vulkan {}, driver {}",
            d.index, d.name, d.kind, d.api_version, d.driver
        );
        println!("    limits: {l}");
        if d.missing_features.is_empty() {
            println!(
                "    required features: all present (shaderInt64, shaderBufferInt64Atomics, synchronization2, timestamps)"
            );
        } else {
            println!(
                "    missing required features: {}",
                d.missing_features.join(", ")
            );
        }
    }
    let ctx = Context::new(&ContextOptions {
        device_index: device,
        ..Default::default()
    })?;
    println!("chosen device: [{}] {}", ctx.info.index, ctx.info.name);
    Ok(Exit::Ok)
}

fn render(args: RenderArgs) -> Result<Exit> {
    check_out_path(&args.out)?;
    let (scene, load_ms) = load_scene(&args.scene)?;
    let settings = settings_for(&scene, &args.view)?;
    let ctx = context_for(&args.view)?;
    let input = input_name(&args.scene);
    let outcome = render_run(
        &ctx,
        &scene,
        &input,
        settings,
        args.aov,
        args.warmup,
        args.frames,
        load_ms,
    )?;
    let mut stats = outcome.stats;
    // Tear the device down first so leak reports are counted too.
    let (n, _) = ctx.finish();
    stats.validation_messages = n;
    outcome.image.save_png(&args.out)?;
    if let Some(j) = &args.json {
        output::write_json(j, &stats)?;
    }
    eprintln!(
        "{}: {} spheres, {}x{}, frame {:.2} ms (median of {}), wrote {}",
        input,
        stats.spheres,
        stats.width,
        stats.height,
        stats.total_ms.median,
        stats.frames,
        args.out.display()
    );
    Ok(if n > 0 {
        Exit::ValidationMessages(n)
    } else {
        Exit::Ok
    })
}

fn check_out_path(p: &Path) -> Result<()> {
    let ext = p
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    if ext.as_deref() != Some("png") {
        return Err(Error::Invalid(format!(
            "--out {}: expected a .png file name",
            p.display()
        )));
    }
    if let Some(dir) = p.parent().filter(|d| !d.as_os_str().is_empty())
        && !dir.is_dir()
    {
        return Err(Error::Invalid(format!(
            "--out {}: directory {} does not exist",
            p.display(),
            dir.display()
        )));
    }
    Ok(())
}
