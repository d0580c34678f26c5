//! Writes a scene as a Tachyon (Debian `tachyon`) model with the camera,
//! key light and sphere colours sphereshade would use for the same
//! arguments, to compare looks and CPU time with a ray tracer:
//!
//! ```text
//! cargo run --release --example tachyon_scene -- tests/data/1tii.pdb \
//!     --replicate 6x6x5 --width 1920 --height 1080 --out /tmp/1tii.dat [--ao 16] [--white]
//! tachyon /tmp/1tii.dat -numthreads 2 -o /tmp/1tii.tga
//! ```
//!
//! (see `sphereshade::tachyon` for the conventions)

use clap::Parser;
use sphereshade::run::{SceneArgs, load_scene};
use sphereshade::settings::{Axes, Options};
use sphereshade::tachyon::{TachyonLight, write_scene};
use std::io::Write;

#[derive(Parser)]
struct Cmd {
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    axes: Axes,
    #[command(flatten)]
    options: Options,
    /// The Tachyon model to write.
    #[arg(long)]
    out: std::path::PathBuf,
    /// Add Tachyon's sky-light ambient occlusion with this many samples.
    #[arg(long)]
    ao: Option<u32>,
    /// Every sphere white (for luminance comparisons).
    #[arg(long)]
    white: bool,
}

fn main() -> anyhow::Result<()> {
    let cmd = Cmd::parse();
    let (scene, _) = load_scene(&cmd.scene)?;
    let s = cmd.options.resolve(&cmd.axes, &scene)?;
    let mut f = std::io::BufWriter::new(std::fs::File::create(&cmd.out)?);
    let how = TachyonLight {
        ao_samples: cmd.ao,
        white: cmd.white,
    };
    write_scene(&mut f, &scene, &s.camera, s.light, how)?;
    f.flush()?;
    eprintln!(
        "wrote {} ({} spheres, {}x{})",
        cmd.out.display(),
        scene.spheres.len(),
        s.camera.width,
        s.camera.height
    );
    Ok(())
}
