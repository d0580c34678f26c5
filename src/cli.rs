//! Command line (DESIGN.md): `info`, `render`, `bench`, `view`.

use crate::error::{Error, Result};
use crate::output;
use crate::run::{self, SceneArgs};
use crate::settings::{Aov, Axes, Options};
use crate::vk::{Context, ContextOptions};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

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
        /// Device index to try (as listed), instead of the preference order.
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

#[derive(Args, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub axes: Axes,
    #[command(flatten)]
    pub options: Options,
    /// What --out holds.
    #[arg(long, value_enum, default_value = "color")]
    pub aov: Aov,
    /// The PNG to write (written atomically: never a partial file); with
    /// --trajectory a pattern with %d or %05d, replaced by the frame index.
    #[arg(long, short = 'o')]
    pub out: Option<PathBuf>,
    /// Also write the run's stats (per-pass ms, memory, image hash) as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Measured frames (timings are median/min/max over them); with
    /// --trajectory the frames to render, A:B:S (0-based, B exclusive, any
    /// part may be empty, e.g. `::10`, `5:`; default all).
    #[arg(long, allow_hyphen_values = true)]
    pub frames: Option<String>,
    /// A trajectory for the INPUT topology: .xtc .trr .dcd .lammpstrj/.dump,
    /// or a multi-model .pdb/.cif, multi-frame .gro/.xyz.
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// With --trajectory: also (or only) write an H.264 movie through ffmpeg.
    #[arg(long)]
    pub movie: Option<PathBuf>,
    /// Movie frame rate.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// With --trajectory: fit the camera to the first rendered frame and keep
    /// it (`first`), or refit every frame (`each`).
    #[arg(long, default_value = "first", value_parser = ["first", "each"])]
    pub camera: String,
    /// With --trajectory: rotate the camera DEG per frame about its up axis.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub orbit: f64,
    /// Periodic boundaries of trajectory frames: keep, wrap atoms into the
    /// cell, or make each residue whole.
    #[arg(long, value_enum, default_value = "keep")]
    pub pbc: crate::traj::Pbc,
    /// Frames rendered (and not measured) before the measured ones.
    #[arg(long, default_value_t = 0)]
    pub warmup: u32,
    /// Bits per channel of the colour PNG.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u8).range(8..=16))]
    pub png_depth: u8,
}

pub use crate::run::Exit;

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
    if args.trajectory.is_some() {
        return render_trajectory(args);
    }
    for (set, flag) in [
        (args.movie.is_some(), "--movie"),
        (args.camera != "first", "--camera"),
        (args.orbit != 0.0, "--orbit"),
        (args.pbc != crate::traj::Pbc::Keep, "--pbc"),
    ] {
        if set {
            return Err(Error::Input(format!("{flag} applies to --trajectory runs")));
        }
    }
    let out = args
        .out
        .clone()
        .ok_or_else(|| Error::Input("render needs --out FILE.png".into()))?;
    let frames: u32 = match args.frames.as_deref() {
        None => 1,
        Some(s) => s.parse().map_err(|_| {
            Error::Input(format!(
                "--frames {s}: expected a number of measured frames (A:B:S ranges need --trajectory)"
            ))
        })?,
    };
    // Every output checked before any work (and none aliasing another).
    let exr = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if exr && args.aov != Aov::Color {
        return Err(Error::Input(
            "--out FILE.exr holds every layer (R,G,B,A, depth, id, shadow, ao, normal): --aov applies to PNG".into(),
        ));
    }
    if args.png_depth != 8 && args.png_depth != 16 {
        return Err(Error::Input(format!(
            "--png-depth {}: expected 8 or 16",
            args.png_depth
        )));
    }
    if exr && args.png_depth != 8 {
        return Err(Error::Input(
            "--png-depth applies to PNG: --out FILE.exr is 32-bit float".into(),
        ));
    }
    if args.png_depth == 16 && args.aov != Aov::Color {
        return Err(Error::Input(
            "--png-depth 16 applies to the colour image".into(),
        ));
    }
    let mut outs = vec![output::OutFile {
        flag: "--out",
        path: &out,
        extensions: &["png", "exr"],
    }];
    if let Some(j) = &args.json {
        outs.push(output::OutFile {
            flag: "--json",
            path: j,
            extensions: &["json"],
        });
    }
    output::check_outputs(&outs)?;
    run::check_frames(frames)?;
    let (scene, load_ms) = run::load_scene(&args.scene)?;
    let mut settings = args.options.resolve(&args.axes, &scene)?;
    settings.look.color16 = args.png_depth == 16;
    let translucent = scene.has_translucent();
    settings.check_see_through(translucent)?;
    if let Some(n) = settings.see_through_note(translucent) {
        eprintln!("note: {n}");
    }
    let ctx = run::context_for(&args.options)?;
    let input = run::input_name(&args.scene);
    if exr {
        // Band by band into the file: host memory holds one band of layers.
        let (w, h) = (settings.camera.width, settings.camera.height);
        let names = run::layer_names(&scene);
        let mut stats = None;
        output::write_exr_bands(&out, w, h, &names, &mut |sink| {
            let s = run::render_layer_bands(&ctx, &scene, &input, settings.clone(), load_ms, sink)?;
            stats = Some(s);
            Ok(())
        })?;
        let mut stats = stats.ok_or_else(|| Error::Internal("no EXR stats".into()))?;
        let (n, _) = ctx.finish();
        stats.validation_messages = n;
        if let Some(j) = &args.json {
            output::write_json(j, &stats)?;
        }
        eprintln!(
            "{input}: {} spheres, {w}x{h}, frame {:.2} ms, wrote {}",
            stats.spheres,
            stats.total_ms.median,
            output::shown(&out)
        );
        return Ok(if n > 0 {
            Exit::ValidationMessages(n)
        } else {
            Exit::Ok
        });
    }
    let (w, h) = (settings.camera.width, settings.camera.height);
    let mut run = run::PreparedRun::new(
        &ctx,
        &scene,
        settings,
        &run::RunRequest {
            input: &input,
            aov: args.aov,
            warmup: args.warmup,
            frames,
            load_ms,
        },
    )?;
    for _ in 1..frames {
        run.frame(false)?;
    }
    // A tiled image goes to the PNG band by band (host memory holds one
    // band); an image of one tile is encoded whole.
    let tiled = run.renderer().tile_plan(args.options.tile_size)?.len() > 1;
    if tiled {
        output::write_atomic(&out, |tmp| {
            let mut png = output::PngStream::create(tmp, w, h)?;
            run.frame_streamed(&mut |band| png.write(band))?;
            png.finish()
        })?;
    } else {
        run.frame(true)?;
    }
    let outcome = run.finish(&ctx)?;
    let mut stats = outcome.stats;
    // Tear the device down first so leak reports are counted too.
    let (n, _) = ctx.finish();
    stats.validation_messages = n;
    if let Some(image) = outcome.image {
        image.save_png(&out)?;
    }
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
        output::shown(&out)
    );
    Ok(if n > 0 {
        Exit::ValidationMessages(n)
    } else {
        Exit::Ok
    })
}

/// `render TOPOLOGY --trajectory TRAJ ...` (see `movie`).
fn render_trajectory(args: RenderArgs) -> Result<Exit> {
    let Some(traj_path) = args.trajectory.as_deref() else {
        return Err(Error::Internal("no trajectory".into()));
    };
    if args.scene.input.is_none() {
        return Err(Error::Input(
            "--trajectory needs a topology INPUT (a structure file with the same atoms)".into(),
        ));
    }
    if args.scene.assembly.is_some() || args.scene.replicate.is_some() {
        return Err(Error::Input(
            "--assembly and --replicate do not apply to trajectories".into(),
        ));
    }
    let range: crate::traj::FrameRange = match args.frames.as_deref() {
        None => Default::default(),
        Some(s) => s
            .parse()
            .map_err(|e: String| Error::Input(format!("--frames {e}")))?,
    };
    let m = crate::movie::MovieArgs {
        trajectory: traj_path,
        range,
        out: args.out.as_deref(),
        movie: args.movie.as_deref(),
        fps: args.fps,
        json: args.json.as_deref(),
        camera_each: args.camera == "each",
        orbit_deg: args.orbit,
        pbc: args.pbc,
        aov: args.aov,
    };
    crate::movie::check(&m)?;
    let (scene, _) = run::load_scene(&args.scene)?;
    let ctx = run::context_for(&args.options)?;
    let input = run::input_name(&args.scene);
    let resolve = |s: &crate::scene::Scene| args.options.resolve(&args.axes, s);
    let done = crate::movie::render_trajectory(&ctx, &scene, &input, &m, &resolve)?;
    let (n, _) = ctx.finish();
    let _ = done;
    Ok(if n > 0 {
        Exit::ValidationMessages(n)
    } else {
        Exit::Ok
    })
}

/// `--opt -5` becomes `--opt=-5`: clap takes a separate word starting with
/// `-` for a flag, so a negative value read "unexpected argument '-5'"
/// without naming its option; joined, the option's own check names it
/// ("invalid value '-5' for '--width <WIDTH>'"). A negative number (or a
/// list starting with one, `-1,0,0`, `-1x1x1`) after a `--long` option
/// without `=` is that option's value: no input or flag looks like one.
pub fn negative_values(
    args: impl IntoIterator<Item = std::ffi::OsString>,
) -> Vec<std::ffi::OsString> {
    let mut out: Vec<std::ffi::OsString> = Vec::new();
    for a in args {
        let negative = a
            .to_str()
            .and_then(|s| s.strip_prefix('-'))
            .is_some_and(|r| r.starts_with(|c: char| c.is_ascii_digit() || c == '.'));
        let joins = out
            .last()
            .and_then(|p| p.to_str())
            .is_some_and(|p| p.starts_with("--") && p.len() > 2 && !p.contains('='));
        if negative && joins {
            let mut joined = out.pop().unwrap_or_default();
            joined.push("=");
            joined.push(&a);
            out.push(joined);
        } else {
            out.push(a);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    #[test]
    fn a_negative_value_joins_its_option() {
        let words = |v: &[&str]| v.iter().map(std::ffi::OsString::from).collect::<Vec<_>>();
        assert_eq!(
            super::negative_values(words(&[
                "x", "--width", "-5", "--light", "-1,-1,-1", "-o", "-2"
            ])),
            words(&["x", "--width=-5", "--light=-1,-1,-1", "-o", "-2"])
        );
        // a value already joined, a flag, an input: left as they are
        assert_eq!(
            super::negative_values(words(&[
                "x",
                "--fov=-3",
                "--validate",
                "a.pdb",
                "--out",
                "-"
            ])),
            words(&["x", "--fov=-3", "--validate", "a.pdb", "--out", "-"])
        );
    }

    /// Every subcommand parses the flattened knobs beside its own flags
    /// (a clap id used twice, as `size` by bench's `--size` and a knob's
    /// field, fails only at parse time in release builds).
    #[test]
    fn every_subcommand_parses_the_shared_knobs() {
        let knobs = [
            "--issm-size",
            "256",
            "--issm-t",
            "auto",
            "--sm-size",
            "64",
            "--outline",
            "1",
        ];
        for sub in [
            vec!["render", "--scene", "random"],
            vec!["bench", "--size", "64x48", "--json", "x.json"],
            vec!["view", "--scene", "random"],
        ] {
            let mut args = vec!["sphereshade"];
            args.extend(sub.iter().copied());
            args.extend(knobs);
            let cli =
                super::Cli::try_parse_from(&args).unwrap_or_else(|e| panic!("{}: {e}", sub[0]));
            let text = format!("{cli:?}");
            assert!(text.contains("size: 256"), "{}: {text}", sub[0]);
        }
    }
}
