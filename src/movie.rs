//! `render TOPOLOGY --trajectory TRAJ`: frames to PNG files and/or a movie
//! (DESIGN.md "Trajectories and movies"). One renderer for the whole run:
//! each frame uploads only positions; a reader thread reads (and applies
//! `--pbc` to) the next frames while the GPU renders the current one, and
//! a writer thread encodes and writes the PNGs, so reading, rendering and
//! writing overlap. Progress (frame, frames/s, ETA) on stderr.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::output::{self, RunStats, shown};
use crate::render::Renderer;
use crate::render::tiles::Keep;
use crate::run;
use crate::scene::Scene;
use crate::settings::{Aov, RenderSettings};
use crate::traj::{self, Frame, FrameRange, Pbc};
use crate::vk::Context;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// What to make of a trajectory.
pub struct MovieArgs<'a> {
    pub trajectory: &'a Path,
    pub range: FrameRange,
    /// PNG per frame: `%d` / `%0Nd` replaced by the frame index.
    pub out: Option<&'a Path>,
    pub movie: Option<&'a Path>,
    pub fps: f64,
    /// JSON Lines: one render object per frame, with `frame` and `time_ps`.
    pub json: Option<&'a Path>,
    pub camera_each: bool,
    pub orbit_deg: f64,
    pub pbc: Pbc,
    pub aov: Aov,
}

/// The per-frame JSON object: DESIGN's render object plus frame and time.
#[derive(Serialize)]
struct FrameStats<'a> {
    #[serde(flatten)]
    run: &'a RunStats,
    frame: usize,
    time_ps: Option<f64>,
}

/// Replaces `%d` or `%0Nd` in a file-name pattern by `k`; None without one.
pub fn frame_path(pattern: &Path, k: usize) -> Option<PathBuf> {
    let s = pattern.to_str()?;
    let i = s.find('%')?;
    let rest = &s[i + 1..];
    let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
    let after = &rest[digits.len()..];
    let after = after.strip_prefix('d')?;
    let width: usize = digits.trim_start_matches('0').parse().unwrap_or(0);
    let zero = digits.starts_with('0');
    let n = if zero {
        format!("{k:0width$}")
    } else {
        format!("{k:width$}")
    };
    Some(PathBuf::from(format!("{}{n}{after}", &s[..i])))
}

/// Checks what can be checked before any frame is read: outputs, ffmpeg.
pub fn check(args: &MovieArgs) -> Result<()> {
    if args.out.is_none() && args.movie.is_none() {
        return Err(Error::Input(
            "--trajectory needs --out DIR/name_%05d.png and/or --movie FILE.mp4".into(),
        ));
    }
    let mut outs = Vec::new();
    let probe;
    if let Some(p) = args.out {
        probe = frame_path(p, 0).ok_or_else(|| {
            Error::Input(format!(
                "--out {}: with --trajectory the name needs %d or %05d (the frame index)",
                shown(p)
            ))
        })?;
        outs.push(output::OutFile {
            flag: "--out",
            path: &probe,
            extensions: &["png"],
        });
    }
    if let Some(m) = args.movie {
        outs.push(output::OutFile {
            flag: "--movie",
            path: m,
            extensions: &["mp4", "mkv", "mov", "webm"],
        });
    }
    if let Some(j) = args.json {
        outs.push(output::OutFile {
            flag: "--json",
            path: j,
            extensions: &["jsonl", "json"],
        });
    }
    output::check_outputs(&outs)?;
    if args.movie.is_some() && args.aov != Aov::Color {
        return Err(Error::Input("--movie writes the color AOV only".into()));
    }
    if args.movie.is_some() {
        let found = std::process::Command::new("ffmpeg")
            .arg("-version")
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if !found {
            return Err(Error::Input(
                "--movie needs ffmpeg on PATH (apt-get install ffmpeg, or tools/setup.sh); \
                 --out DIR/f_%05d.png writes the frames without it"
                    .into(),
            ));
        }
    }
    if !(args.fps > 0.0 && args.fps <= 1000.0) {
        return Err(Error::Input("--fps must be between 0 and 1000".into()));
    }
    if !args.orbit_deg.is_finite() {
        return Err(Error::Input("--orbit must be a finite angle".into()));
    }
    Ok(())
}

/// The camera of frame i (0-based among the rendered frames).
fn camera_for(base: &Camera, fitted: Option<Camera>, i: usize, orbit_deg: f64) -> Result<Camera> {
    let c = fitted.unwrap_or(*base);
    if orbit_deg == 0.0 {
        return Ok(c);
    }
    let q = glam::DQuat::from_axis_angle(c.up, (orbit_deg * i as f64).to_radians());
    Camera::new(
        c.center,
        q * c.dir,
        c.up,
        c.view_height,
        c.fov_deg,
        c.width,
        c.height,
    )
}

/// Renders the frames. `resolve` makes the settings (camera) for a scene:
/// it is called with the topology at the first rendered frame's positions
/// (and again per frame with `--camera each`).
pub fn render_trajectory(
    ctx: &Context,
    topology: &Scene,
    input: &str,
    args: &MovieArgs,
    resolve: &dyn Fn(&Scene) -> Result<RenderSettings>,
) -> Result<usize> {
    if topology.instancing.is_some() {
        return Err(Error::Input(format!(
            "{}: an instanced model has no per-atom trajectory (--trajectory needs a plain topology)",
            shown(Path::new(&topology.source))
        )));
    }
    let mut reader = traj::open(args.trajectory)?;
    // (frames hold every atom as loaded: --hide keeps a subset of them)
    let (tname, top_n, traj_n) = (
        shown(args.trajectory),
        topology.input_count() as usize,
        reader.atoms(),
    );
    if top_n != traj_n {
        return Err(Error::Input(format!(
            "{} has {top_n} atoms, {tname} has {traj_n}: the trajectory does not belong to this topology",
            shown(Path::new(&topology.source))
        )));
    }
    let indices = args.range.indices(reader.frames());
    if indices.is_empty() {
        let damage = reader
            .damage()
            .map(|d| format!(" ({d})"))
            .unwrap_or_default();
        return Err(Error::Input(format!(
            "--frames {} selects no frame of {tname}, which has {} frame(s){damage}",
            args.range,
            reader.frames()
        )));
    }
    // Frames past the end of a damaged file were asked for: say so at the end.
    let wanted_past = args
        .range
        .stop
        .is_none_or(|b| b < 0 || b == i64::MAX || b as usize > reader.frames());
    let damage = reader
        .damage()
        .map(|d| d.to_string())
        .filter(|_| wanted_past);
    // Residues for --pbc whole: the residue level of molecular topologies.
    let residues: Vec<u32> = if topology.level_names.len() >= 3 {
        topology.spheres.iter().map(|s| s.region[2]).collect()
    } else {
        (0..topology.spheres.len() as u32).collect()
    };
    let kept: Option<std::sync::Arc<Vec<u32>>> = match &topology.origin {
        Some(crate::scene::Origin::Plain { index, .. }) => Some(index.clone().into()),
        _ => None,
    };

    // The camera is fitted to frame 0 of the trajectory, whatever the
    // range: runs over disjoint ranges then render exactly the frames one
    // run would (DESIGN's "first rendered frame" would make them differ).
    let mut scene = topology.clone();
    let mut f0 = Frame::default();
    reader.read(0, &mut f0)?;
    f0.keep(kept.as_deref().map(Vec::as_slice));
    traj::apply_pbc(args.pbc, &mut f0.positions, f0.cell.as_ref(), &residues);
    for (s, p) in scene.spheres.iter_mut().zip(&f0.positions) {
        s.center = *p;
    }
    let mut settings = resolve(&scene)?;
    settings.aovs |= matches!(args.aov, Aov::Shadow | Aov::Ao);
    let base = settings.camera;
    // supersampling and tiles as `render` does them
    let n = settings.ssaa_for(args.aov);
    let tile = settings.tile_size;
    let mut renderer = Renderer::new_windowed(ctx, &scene, settings, tile)?;

    // Reader thread: frames (PBC applied) through a short queue.
    let (tx, rx) = std::sync::mpsc::sync_channel::<Result<(usize, Frame)>>(2);
    let list = indices.clone();
    let pbc = args.pbc;
    let reading = std::thread::spawn(move || {
        let mut busy = 0.0f64;
        for k in list {
            let t = Instant::now();
            let mut f = Frame::default();
            let r = reader.read(k, &mut f).map_err(Error::from).map(|()| {
                f.keep(kept.as_deref().map(Vec::as_slice));
                traj::apply_pbc(pbc, &mut f.positions, f.cell.as_ref(), &residues);
                (k, f)
            });
            busy += t.elapsed().as_secs_f64();
            let stop = r.is_err();
            if tx.send(r).is_err() || stop {
                break;
            }
        }
        busy
    });

    // Writer thread: PNG encoding and atomic writes off the render loop.
    let (wtx, wrx) = std::sync::mpsc::sync_channel::<(PathBuf, output::AovImage)>(2);
    let writing = std::thread::spawn(move || -> Result<f64> {
        let mut busy = 0.0f64;
        for (path, image) in wrx {
            let t = Instant::now();
            image.save_png(&path)?;
            busy += t.elapsed().as_secs_f64();
        }
        Ok(busy)
    });

    if args.movie.is_some() {
        watch_signals();
    }
    let mut movie = match args.movie {
        Some(m) => Some(Ffmpeg::start(
            m,
            args.fps,
            topology_size(resolve, topology)?,
        )?),
        None => None,
    };
    let mut json = args.json.map(|_| String::new());
    let progress = Progress::new(indices.len());
    let mut done = 0usize;
    // Seconds in each step of the render loop (the reader and the writer
    // run beside it).
    let (mut t_wait, mut t_upload, mut t_render, mut t_back, mut t_movie) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    let started = Instant::now();
    let result = (|| -> Result<()> {
        let mut tick = Instant::now();
        let mut lap = |acc: &mut f64| {
            *acc += tick.elapsed().as_secs_f64();
            tick = Instant::now();
        };
        for msg in rx.iter() {
            lap(&mut t_wait);
            if INTERRUPTED.load(Ordering::Relaxed) {
                return Err(Error::Input("interrupted by a signal".into()));
            }
            let (k, frame) = msg?;
            let fitted = if args.camera_each {
                for (s, p) in scene.spheres.iter_mut().zip(&frame.positions) {
                    s.center = *p;
                }
                Some(resolve(&scene)?.camera)
            } else {
                None
            };
            let r = &mut renderer;
            r.set_positions(&frame.positions)
                .map_err(|e| Error::Input(format!("{tname}: frame {k}: {e}")))?;
            // (the orbit angle follows the frame index, not the position in
            // the range, for the same reason as the camera)
            let cam = camera_for(&base, fitted, k, args.orbit_deg)?;
            r.update(|s| s.camera = cam)?;
            lap(&mut t_upload);
            let (img, times) =
                run::render_supersampled(r, n, tile, Some(Keep::ALL), &mut |_, _| {})?;
            lap(&mut t_render);
            let img = img.ok_or_else(|| Error::Internal("no image read back".into()))?;
            let image = run::image_aov(&img, args.aov);
            lap(&mut t_back);
            if let Some(m) = movie.as_mut() {
                m.push(&image)?;
            }
            lap(&mut t_movie);
            if let Some(j) = json.as_mut() {
                let stats = run::run_stats(ctx, r, input, &[times], 0.0, &image.sha256());
                let line = serde_json::to_string(&FrameStats {
                    run: &stats,
                    frame: k,
                    time_ps: frame.time_ps,
                })
                .map_err(|e| Error::Internal(format!("JSON: {e}")))?;
                j.push_str(&line);
                j.push('\n');
            }
            if let Some(p) = args.out
                && let Some(path) = frame_path(p, k)
                && wtx.send((path, image)).is_err()
            {
                break; // the writer failed: its error is reported below
            }
            done += 1;
            progress.tick(done, k, frame.time_ps);
        }
        Ok(())
    })();
    drop(wtx);
    drop(rx);
    let wrote = writing
        .join()
        .unwrap_or_else(|_| Err(Error::Internal("PNG writer panicked".into())));
    let t_read = reading.join().unwrap_or(0.0);
    let total = started.elapsed().as_secs_f64();
    progress.finish(done, total);
    if done > 0 {
        let ms = |t: f64| 1e3 * t / done as f64;
        eprintln!(
            "per frame: render {:.0} ms, upload + light refit {:.0} ms, read-back {:.0} ms, movie {:.0} ms, \
             waiting for the reader {:.0} ms; beside the loop: reading {:.0} ms, PNG writing {:.0} ms",
            ms(t_render),
            ms(t_upload),
            ms(t_back),
            ms(t_movie),
            ms(t_wait),
            ms(t_read),
            ms(*wrote.as_ref().unwrap_or(&0.0))
        );
    }
    drop(renderer);
    // A movie is written whole or not at all: on any error (or a damaged
    // file's missing frames) the temporary file goes with `movie`.
    let no_movie = |e: Error| match &movie {
        Some(_) => {
            // (a terminal's Ctrl-C also stops ffmpeg: name the cause)
            let why = if INTERRUPTED.load(Ordering::Relaxed) {
                "interrupted by a signal".to_string()
            } else {
                e.to_string()
            };
            Error::Input(format!(
                "{} ({done} frame(s) had been rendered; no movie written)",
                why.trim_end_matches('.')
            ))
        }
        None => e,
    };
    if INTERRUPTED.load(Ordering::Relaxed) && result.is_ok() {
        return Err(no_movie(Error::Input("interrupted by a signal".into())));
    }
    // PNG frames: the ones before the error are on disk, and the line says so
    if let Err(e) = &result
        && movie.is_none()
        && args.out.is_some()
        && wrote.is_ok()
    {
        return Err(Error::Input(format!(
            "{} (the {done} frames before it were rendered and written)",
            e.to_string().trim_end_matches('.')
        )));
    }
    result.map_err(no_movie)?;
    wrote.map_err(no_movie)?;
    if let Some(d) = damage.as_ref()
        && movie.is_some()
    {
        return Err(no_movie(Error::Input(d.to_string())));
    }
    if let Some(m) = movie.take() {
        m.finish()?;
    }
    if let (Some(path), Some(text)) = (args.json, json) {
        output::write_atomic(path, |tmp| {
            std::fs::write(tmp, text).map_err(|e| Error::Io {
                path: shown(path),
                source: e,
            })
        })?;
    }
    if let Some(d) = damage {
        return Err(Error::Input(format!(
            "{d} (the {done} frames before it were rendered and written)"
        )));
    }
    Ok(done)
}

/// The image size the settings give (ffmpeg needs it up front).
fn topology_size(
    resolve: &dyn Fn(&Scene) -> Result<RenderSettings>,
    s: &Scene,
) -> Result<(u32, u32)> {
    let c = resolve(s)?.camera;
    Ok((c.width, c.height))
}

/// Set by SIGINT/SIGTERM during a `--movie` run: the loop stops after the
/// frame it is on, and the temporary movie is removed on the way out.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// Turns SIGINT/SIGTERM into [`INTERRUPTED`] (once per process).
fn watch_signals() {
    // (a second call, or a host that already handles them: keep theirs)
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::Relaxed));
}

/// Frames piped to ffmpeg (H.264, yuv420p), written to a temporary name
/// and renamed when ffmpeg succeeds.
struct Ffmpeg {
    child: std::process::Child,
    tmp: PathBuf,
    path: PathBuf,
}

impl Ffmpeg {
    fn start(path: &Path, fps: f64, (w, h): (u32, u32)) -> Result<Self> {
        let file = path.file_name().unwrap_or_default().to_string_lossy();
        let ext = path.extension().unwrap_or_default().to_string_lossy();
        let tmp = path.with_file_name(format!(".{file}.{}.tmp.{ext}", std::process::id()));
        if w % 2 == 1 || h % 2 == 1 {
            eprintln!(
                "sphereshade: --movie: {w}x{h} padded to {}x{} (H.264 needs even sizes)",
                w + w % 2,
                h + h % 2
            );
        }
        let child = std::process::Command::new("ffmpeg")
            .args([
                "-hide_banner",
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgba",
            ])
            .args(["-s", &format!("{w}x{h}"), "-r", &fps.to_string(), "-i", "-"])
            .args([
                "-c:v",
                "libx264",
                "-pix_fmt",
                "yuv420p",
                "-vf",
                "pad=ceil(iw/2)*2:ceil(ih/2)*2",
            ])
            .arg(&tmp)
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .map_err(|e| Error::Input(format!("--movie: cannot start ffmpeg: {e}")))?;
        Ok(Ffmpeg {
            child,
            tmp,
            path: path.to_path_buf(),
        })
    }

    fn push(&mut self, image: &output::AovImage) -> Result<()> {
        use std::io::Write;
        let output::AovImage::Rgba8(img) = image else {
            return Err(Error::Internal("--movie: not a colour image".into()));
        };
        let stdin = self
            .child
            .stdin
            .as_mut()
            .ok_or_else(|| Error::Internal("ffmpeg stdin".into()))?;
        stdin
            .write_all(img.as_raw())
            .map_err(|e| Error::Input(format!("--movie: ffmpeg stopped reading frames: {e}")))
    }

    fn finish(mut self) -> Result<()> {
        drop(self.child.stdin.take());
        let out = std::mem::replace(&mut self.child, dummy_child()?).wait_with_output();
        let ok = matches!(&out, Ok(o) if o.status.success());
        if !ok {
            let _ = std::fs::remove_file(&self.tmp);
            let why = out
                .ok()
                .map(|o| {
                    String::from_utf8_lossy(&o.stderr)
                        .lines()
                        .next()
                        .unwrap_or("")
                        .to_string()
                })
                .unwrap_or_default();
            return Err(Error::Input(format!("--movie: ffmpeg failed: {why}")));
        }
        std::fs::rename(&self.tmp, &self.path).map_err(|e| Error::Io {
            path: shown(&self.path),
            source: e,
        })
    }
}

/// A finished placeholder child (so `finish` can take the real one).
fn dummy_child() -> Result<std::process::Child> {
    std::process::Command::new("true")
        .spawn()
        .map_err(|e| Error::Internal(format!("spawn: {e}")))
}

impl Drop for Ffmpeg {
    fn drop(&mut self) {
        // (an error path: no partial movie is left)
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.tmp);
    }
}

/// Frame progress on stderr: a bar with frames/s and ETA on a terminal,
/// a line every 10 % otherwise.
struct Progress {
    bar: indicatif::ProgressBar,
    total: usize,
    tty: bool,
    started: Instant,
}

impl Progress {
    fn new(total: usize) -> Self {
        use std::io::IsTerminal;
        let tty = std::io::stderr().is_terminal();
        let bar = if tty {
            let b = indicatif::ProgressBar::new(total as u64);
            if let Ok(style) = indicatif::ProgressStyle::with_template(
                "{bar:30} {pos}/{len} frames | {msg} | {per_sec} | ETA {eta}",
            ) {
                b.set_style(style);
            }
            b
        } else {
            indicatif::ProgressBar::hidden()
        };
        Progress {
            bar,
            total,
            tty,
            started: Instant::now(),
        }
    }

    fn tick(&self, done: usize, frame: usize, time_ps: Option<f64>) {
        let t = time_ps
            .map(|t| format!(", t = {t:.1} ps"))
            .unwrap_or_default();
        if self.tty {
            self.bar.set_message(format!("frame {frame}{t}"));
            self.bar.set_position(done as u64);
        } else if done == self.total
            || (done * 10 / self.total.max(1)) > ((done - 1) * 10 / self.total.max(1))
        {
            let s = self.started.elapsed().as_secs_f64();
            eprintln!(
                "frame {frame}{t}: {done}/{} ({:.2} frames/s)",
                self.total,
                done as f64 / s.max(1e-9)
            );
        }
    }

    fn finish(&self, done: usize, seconds: f64) {
        self.bar.finish_and_clear();
        eprintln!(
            "rendered {done} frame(s) in {seconds:.1} s ({:.2} frames/s)",
            done as f64 / seconds.max(1e-9)
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_patterns() {
        let p = |s: &str, k| frame_path(Path::new(s), k).map(|p| p.display().to_string());
        assert_eq!(p("d/f_%05d.png", 42).as_deref(), Some("d/f_00042.png"));
        assert_eq!(p("f%d.png", 7).as_deref(), Some("f7.png"));
        assert_eq!(p("f%3d.png", 7).as_deref(), Some("f  7.png"));
        assert_eq!(p("f.png", 7), None);
        assert_eq!(p("f%s.png", 7), None);
    }
}
