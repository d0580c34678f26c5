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
    /// The PNG to write (written atomically: never a partial file).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the run's stats (per-pass ms, memory, image hash) as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Measured frames (timings are median/min/max over them).
    #[arg(long, default_value_t = 1)]
    pub frames: u32,
    /// Frames rendered (and not measured) before the measured ones.
    #[arg(long, default_value_t = 0)]
    pub warmup: u32,
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
    // Every output checked before any work (and none aliasing another).
    let mut outs = vec![output::OutFile {
        flag: "--out",
        path: &args.out,
        extensions: &["png"],
    }];
    if let Some(j) = &args.json {
        outs.push(output::OutFile {
            flag: "--json",
            path: j,
            extensions: &["json"],
        });
    }
    output::check_outputs(&outs)?;
    run::check_frames(args.frames)?;
    let (scene, load_ms) = run::load_scene(&args.scene)?;
    let settings = args.options.resolve(&args.axes, &scene)?;
    let ctx = run::context_for(&args.options)?;
    let input = run::input_name(&args.scene);
    let outcome = run::render_run(
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
        output::shown(&args.out)
    );
    Ok(if n > 0 {
        Exit::ValidationMessages(n)
    } else {
        Exit::Ok
    })
}
