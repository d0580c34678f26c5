//! Writes a scene as a Tachyon (Debian `tachyon`) model with the camera,
//! key light and sphere colours sphereshade would use for the same
//! arguments, to compare looks and CPU time with a ray tracer:
//!
//! ```text
//! cargo run --release --example tachyon_scene -- tests/data/1tii.pdb \
//!     --replicate 6x6x5 --width 1920 --height 1080 --out /tmp/1tii.dat [--ao]
//! tachyon /tmp/1tii.dat -numthreads 2 -o /tmp/1tii.tga
//! ```
//!
//! Tachyon's orthographic view spans 1 / ZOOM world units vertically
//! (checked with one sphere); its frame is left-handed, so the whole
//! world is written mirrored in x (spheres, camera, light), which gives
//! the image sphereshade renders. DIRECTIONAL_LIGHT DIRECTION points from
//! the light toward the scene, like `--light`. `--ao` adds Tachyon's
//! sky-light ambient occlusion (16 samples) over the hard shadows.

use clap::Parser;
use sphereshade::run::{SceneArgs, load_scene};
use sphereshade::settings::{Axes, Options};
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
    /// Add Tachyon's ambient occlusion (sky light, 16 samples).
    #[arg(long)]
    ao: bool,
}

fn main() -> anyhow::Result<()> {
    let cmd = Cmd::parse();
    let (scene, _) = load_scene(&cmd.scene)?;
    let s = cmd.options.resolve(&cmd.axes, &scene)?;
    let c = &s.camera;
    anyhow::ensure!(c.fov_deg.is_none(), "only orthographic cameras are written");
    let m = |v: glam::DVec3| glam::DVec3::new(-v.x, v.y, v.z);
    let mut f = std::io::BufWriter::new(std::fs::File::create(&cmd.out)?);
    // The eye sits outside the scene on the view axis (orthographic: only
    // the direction matters).
    let (bc, br) = scene.bounding_sphere();
    let eye = m(c.center - c.dir * (c.center.distance(bc.as_dvec3()) + 4.0 * br as f64 + 1.0));
    let (dir, up) = (m(c.dir), m(c.up));
    writeln!(f, "BEGIN_SCENE\nRESOLUTION {} {}", c.width, c.height)?;
    writeln!(
        f,
        "CAMERA\n  PROJECTION ORTHOGRAPHIC\n  ZOOM {}\n  ASPECTRATIO 1.0\n  ANTIALIASING 0\n  RAYDEPTH 4\n  \
         CENTER {} {} {}\n  VIEWDIR {} {} {}\n  UPDIR {} {} {}\nEND_CAMERA",
        1.0 / c.view_height,
        eye.x,
        eye.y,
        eye.z,
        dir.x,
        dir.y,
        dir.z,
        up.x,
        up.y,
        up.z
    )?;
    let l = m(s.light.normalize());
    writeln!(
        f,
        "DIRECTIONAL_LIGHT DIRECTION {} {} {} COLOR 1 1 1\nBACKGROUND 0.12 0.12 0.14",
        l.x, l.y, l.z
    )?;
    if cmd.ao {
        // (VMD's export: sky colour, direct light rescaled, samples)
        writeln!(
            f,
            "SHADER_MODE FULL\n  AMBIENT_OCCLUSION\n    AMBIENT_COLOR 0.8 0.8 0.8\n    RESCALE_DIRECT 0.6\n    \
             SAMPLES 16\nEND_SHADER_MODE"
        )?;
    }
    for sp in &scene.spheres {
        let [r, g, b, _] = sp.color.map(|v| v as f32 / 255.0);
        writeln!(
            f,
            "SPHERE CENTER {} {} {} RAD {} TEXTURE AMBIENT 0.15 DIFFUSE 0.75 SPECULAR 0.0 OPACITY 1.0 \
             PHONG PLASTIC 0.3 PHONG_SIZE 30 COLOR {r:.3} {g:.3} {b:.3} TEXFUNC 0",
            -sp.center[0], sp.center[1], sp.center[2], sp.radius
        )?;
    }
    writeln!(f, "END_SCENE")?;
    f.flush()?;
    eprintln!(
        "wrote {} ({} spheres, {}x{})",
        cmd.out.display(),
        scene.spheres.len(),
        c.width,
        c.height
    );
    Ok(())
}
