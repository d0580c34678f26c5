//! The look against a ray tracer, for any structure (tools/look-vs-tachyon.sh):
//! renders the file as white `.xyzr` spheres (no hierarchy) with the
//! default modes (the tool and the test use 640x480), and Debian's `tachyon` on the same camera (same key
//! light, hard shadows, 64-sample sky-light AO); prints the luminance rank
//! correlation and spread over the covered pixels (the goals: >= 0.9 and
//! >= 0.6 x Tachyon's) and writes a side-by-side picture (ours left).
//!
//! ```text
//! cargo run --release --example look_vs_tachyon -- tests/data/1tii.pdb --width 640 --height 480
//! # an image made by another build, same camera and size (coverage from Tachyon's):
//! cargo run --release --example look_vs_tachyon -- tests/data/1tii.pdb --width 640 --height 480 --image old.png
//! ```

use anyhow::Context as _;
use clap::Parser;
use sphereshade::run::{SceneArgs, load_scene};
use sphereshade::settings::{Axes, Options};
use sphereshade::tachyon;

#[derive(Parser)]
struct Cmd {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    axes: Axes,
    #[command(flatten)]
    options: Options,
    /// Keep the file's hierarchy (white spheres still): semantic SSDO then
    /// counts only occluders of other regions.
    #[arg(long)]
    hierarchy: bool,
    /// Compare this PNG (rendered elsewhere with the same camera and size)
    /// instead of rendering here.
    #[arg(long)]
    image: Option<std::path::PathBuf>,
    /// Where the Tachyon model, its PPM and the side-by-side PNG go.
    #[arg(long, default_value = "target/look")]
    out_dir: std::path::PathBuf,
}

fn main() -> anyhow::Result<()> {
    let cmd = Cmd::parse();
    let (scene, _) = load_scene(&cmd.scene)?;
    let mut white = tachyon::white_spheres(&scene);
    if cmd.hierarchy {
        white.level_names = scene.level_names.clone();
        for (w, s) in white.spheres.iter_mut().zip(&scene.spheres) {
            w.region = s.region;
        }
    }
    let scene = white;
    let settings = cmd.options.resolve(&cmd.axes, &scene)?;
    let (width, height) = (cmd.axes.width, cmd.axes.height);
    std::fs::create_dir_all(&cmd.out_dir)?;
    let name = cmd
        .scene
        .input
        .as_ref()
        .and_then(|p| p.file_name())
        .map_or("scene".into(), |n| n.to_string_lossy().to_string());
    let (stats, side) = match &cmd.image {
        None => {
            let ctx = sphereshade::vk::Context::new(&Default::default())?;
            tachyon::compare_look(&ctx, &scene, settings, &cmd.out_dir, &name)
                .map_err(anyhow::Error::msg)?
        }
        Some(png) => {
            let img = image::open(png)
                .with_context(|| png.display().to_string())?
                .to_rgb8();
            anyhow::ensure!(
                img.dimensions() == (width, height),
                "{} is {}x{}, not {}x{}",
                png.display(),
                img.width(),
                img.height(),
                width,
                height
            );
            let reference = tachyon::reference_image(
                &scene,
                &settings.camera,
                settings.light,
                &cmd.out_dir,
                &name,
            )
            .map_err(anyhow::Error::msg)?;
            let ours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
            let covered = vec![true; ours.len()];
            tachyon::look_stats(width, height, &ours, &covered, &reference)
        }
    };
    let out = cmd.out_dir.join(format!("{name}-vs-tachyon.png"));
    side.save(&out)?;
    println!("{name}: {stats}; wrote {}", out.display());
    Ok(())
}
