//! `sphereshade view`: a window (winit 0.30 + ash-window) showing the
//! renderer's colour buffer, with an orbit camera, light and mode toggles,
//! and per-pass timings in the title bar. `--frames N --screenshot F` makes
//! it a headless-friendly smoke test (Xvfb), `--resize-test` resizes the
//! window half-way through.

mod player;
mod swapchain;

use crate::error::{Error, Result};
use crate::output;
use crate::render::Renderer;
use crate::run::{self, Exit, SceneArgs};
use crate::scene::Scene;
use crate::settings::{Axes, Options};
use crate::vk::{Context, ContextOptions};
use glam::DVec3;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use std::ffi::CString;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;
use swapchain::{Present, Swapchain};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

#[derive(clap::Args, Debug)]
#[command(after_help = HELP)]
pub struct ViewCmd {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub axes: Axes,
    #[command(flatten)]
    pub options: Options,
    /// Render this many frames, then exit (smoke test).
    #[arg(long)]
    pub frames: Option<u32>,
    /// Save the last frame to this PNG on exit.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Resize the window half-way through --frames (+40 x +24 pixels).
    #[arg(long)]
    pub resize_test: bool,
    /// Replay input, one action per frame, through the same handlers as
    /// keys and mouse (tests, measurements): `toggle-all` presses every mode
    /// key through all its states and drags the light 8 steps; `fly-in`
    /// turns the wheel one notch a frame for 64 frames (the view 0.9x as
    /// high each: from a whole scene into one molecule) and reports the
    /// frame intervals.
    #[arg(long, value_parser = ["toggle-all", "fly-in"])]
    pub script: Option<String>,
    /// Play a trajectory of the INPUT topology (space play/pause, left/right
    /// step, [ ] slower/faster, L loop).
    #[arg(long)]
    pub trajectory: Option<PathBuf>,
    /// Periodic boundaries of trajectory frames: keep, wrap, whole.
    #[arg(long, value_enum, default_value = "keep")]
    pub pbc: crate::traj::Pbc,
}

/// One scripted input action.
#[derive(Clone, Copy, Debug)]
enum Action {
    Key(&'static str),
    LightDrag(f64, f64),
    /// Wheel notches (positive: in).
    Zoom(f64),
}

fn script(name: &str) -> Vec<Action> {
    match name {
        "toggle-all" => {
            let mut v = Vec::new();
            // S cycles none -> issm -> issm-soft -> deep -> sm-pcf -> osm -> none.
            v.extend([Action::Key("s"); 6]);
            v.extend([Action::Key("o"); 3]);
            v.extend([Action::Key("b"); 2]);
            v.extend([Action::Key("-"), Action::Key("+")]);
            v.extend([Action::Key("t"); 3]);
            v.extend([Action::LightDrag(6.0, 3.0); 8]);
            // and once more with every technique alive, the light moved
            v.extend([Action::Key("s"); 6]);
            v
        }
        "fly-in" => vec![Action::Zoom(1.0); 64],
        _ => Vec::new(),
    }
}

pub const HELP: &str = "controls: left drag orbit | right/middle drag pan | wheel zoom | shift+drag light | \
S shadows (none/issm/issm-soft/deep/sm-pcf/osm) | O ssdo (off/plain/semantic) | B blur | +/- opacity | T see-through presets | R reset camera | \
P screenshot | H help | Esc quit | with --trajectory: space play/pause, left/right step, [ ] slower/faster, L loop";

/// A nested scene the viewer keeps: its proxies and the placements the
/// renderer's camera opened.
struct Nested {
    scene: Scene,
    proxies: crate::scene::instanced::nested::Proxies,
    open: Vec<bool>,
}

/// The viewer's renderer: BGRA where the swapchain is; orbiting and
/// zooming move only the camera, so the light map and lists are kept until
/// the light, opacity or mode changes.
fn viewer_renderer<'c>(
    ctx: &'c Context,
    swapchain: Option<&Swapchain>,
    scene: &Scene,
    settings: crate::settings::RenderSettings,
    proxies: Option<&crate::scene::instanced::nested::Proxies>,
) -> Result<Renderer<'c>> {
    let mut r = Renderer::with_proxies(ctx, scene, settings, proxies)?;
    r.set_bgra(swapchain.is_some_and(|sc| sc.is_bgra()));
    r.set_light_cache(true);
    Ok(r)
}

/// Camera parameters the controls change.
#[derive(Clone, Copy, Debug)]
struct Orbit {
    center: DVec3,
    dir: DVec3,
    up: DVec3,
    height: f64,
    fov: Option<f64>,
}

enum Loading {
    Pending(
        std::thread::JoinHandle<Result<(Scene, f64)>>,
        Arc<AtomicU64>,
    ),
    /// The scene is on the GPU (the renderer keeps what it needs).
    Done,
    Taken,
}

struct App<'c> {
    ctx: &'c Context,
    cmd: ViewCmd,
    window: Option<Arc<Window>>,
    swapchain: Option<Swapchain>,
    renderer: Option<Renderer<'c>>,
    loading: Loading,
    home: Option<Orbit>,
    orbit: Option<Orbit>,
    size: (u32, u32),
    frames: u32,
    /// When the first frame was presented (fps averages start there).
    second_frame_at: Option<Instant>,
    /// When `view` started (start-up to first frame is reported).
    started: Instant,
    resized_once: bool,
    /// A nested scene (its placements reopened as the camera moves).
    nested: Option<Nested>,
    cursor: (f64, f64),
    buttons: [bool; 3],
    shift: bool,
    screenshots: u32,
    last_title: Instant,
    fps_frames: u32,
    error: Option<Error>,
    exit: Exit,
    actions: std::collections::VecDeque<Action>,
    /// Seconds spent in mode toggles and light-drag steps (handler only).
    toggle_times: Vec<f64>,
    /// Seconds between successive presents (a stall is a long one).
    intervals: Vec<f64>,
    last_present: Option<Instant>,
    drag_times: Vec<f64>,
    player: Option<player::Player>,
    /// T's see-through presets: the colours as loaded, each sphere record's
    /// hierarchy group (`paint::hierarchy_groups`), and the preset shown.
    loaded_colors: Vec<[u8; 4]>,
    groups: Vec<u32>,
    preset: usize,
}

/// T cycles these (the first is the colours and --alpha rules as loaded).
const PRESETS: [&str; 3] = [
    "as loaded",
    "first group opaque, the others at alpha 0.3",
    "every sphere at alpha 0.5",
];

fn preset_colors(preset: usize, loaded: &[[u8; 4]], groups: &[u32]) -> Vec<[u8; 4]> {
    let first = groups.first().copied().unwrap_or(0);
    loaded
        .iter()
        .zip(groups)
        .map(|(c, &g)| match preset {
            1 if g != first => [c[0], c[1], c[2], 77],
            1 => [c[0], c[1], c[2], 255],
            2 => [c[0], c[1], c[2], 128],
            _ => *c,
        })
        .collect()
}

/// The next value of a mode in its declaration order (wrapping): S and O
/// cycle through every technique without a list of their own.
fn next<T: clap::ValueEnum + PartialEq + Copy>(v: T) -> T {
    let all = T::value_variants();
    let i = all.iter().position(|x| *x == v).unwrap_or(0);
    all[(i + 1) % all.len()]
}

fn rotate(v: DVec3, axis: DVec3, angle: f64) -> DVec3 {
    glam::DQuat::from_axis_angle(axis.normalize(), angle) * v
}

impl<'c> App<'c> {
    fn fail(&mut self, el: &ActiveEventLoop, e: Error) {
        self.error = Some(e);
        el.exit();
    }

    /// The camera of the current orbit and window size.
    fn camera(&self) -> Result<Option<crate::camera::Camera>> {
        let Some(o) = self.orbit else {
            return Ok(None);
        };
        let (w, h) = self.size;
        crate::camera::Camera::new(o.center, o.dir, o.up, o.height, o.fov, w, h).map(Some)
    }

    /// The window size changed: new screen targets, nothing else.
    fn resize_renderer(&mut self) -> Result<()> {
        let Some(cam) = self.camera()? else {
            return Ok(());
        };
        if let Some(r) = &mut self.renderer {
            r.update(|s| {
                s.camera = cam;
                s.window = None;
            })?;
        }
        Ok(())
    }

    fn update_camera(&mut self) -> Result<()> {
        let (Some(r), Some(o)) = (&mut self.renderer, self.orbit) else {
            return Ok(());
        };
        let (w, h) = self.size;
        let cam = crate::camera::Camera::new(o.center, o.dir, o.up, o.height, o.fov, w, h)?;
        if let Some(n) = &mut self.nested {
            let open = crate::render::nesting::opening(&n.scene, Some(&n.proxies), &cam)?.open;
            if open != n.open {
                // Other placements to open: a renderer for them (the
                // resolved scene's tables are the renderer's own; ~1 s for
                // the 10^12 meso scene, the frame in flight first)
                let t = Instant::now();
                let mut s = r.settings().clone();
                s.camera = cam;
                self.renderer = None;
                let fresh = viewer_renderer(
                    self.ctx,
                    self.swapchain.as_ref(),
                    &n.scene,
                    s,
                    Some(&n.proxies),
                )?;
                n.open = open;
                eprintln!(
                    "view: placements reopened ({} open) in {:.0} ms",
                    n.open.iter().filter(|&&x| x).count(),
                    t.elapsed().as_secs_f64() * 1e3
                );
                self.renderer = Some(fresh);
                return Ok(());
            }
        }
        r.update(|s| s.camera = cam)
    }

    fn screenshot(&mut self, path: &std::path::Path) -> Result<()> {
        let Some(r) = &self.renderer else {
            return Ok(());
        };
        let mut color = r.inspect().read_color()?;
        if r.inspect().is_bgra() {
            for c in &mut color {
                let b = c.to_le_bytes();
                *c = u32::from_le_bytes([b[2], b[1], b[0], b[3]]);
            }
        }
        let (w, h) = (r.settings().camera.width, r.settings().camera.height);
        output::color_image(w, h, &color).save_png(path)?;
        eprintln!("view: wrote {}", path.display());
        Ok(())
    }

    fn title(&mut self, times: &[(&'static str, f64)]) {
        let Some(win) = &self.window else { return };
        self.fps_frames += 1;
        let dt = self.last_title.elapsed().as_secs_f64();
        if dt < 0.5 && self.frames > 1 {
            return;
        }
        let fps = self.fps_frames as f64 / dt.max(1e-9);
        self.fps_frames = 0;
        self.last_title = Instant::now();
        let gpu: f64 = times.iter().map(|t| t.1).sum();
        let passes: Vec<String> = times.iter().map(|(n, t)| format!("{n} {t:.1}")).collect();
        let Some(r) = &self.renderer else { return };
        let (n, s) = (r.inspect().represented(), r.settings());
        let playing = self
            .player
            .as_ref()
            .map(|p| format!("{} | ", p.status()))
            .unwrap_or_default();
        win.set_title(&format!(
            "sphereshade | {playing}{n} spheres | {fps:.1} fps | gpu {gpu:.1} ms | shadows {} ssdo {} blur {} opacity {:.2} | {} | H help",
            s.shadows.name(),
            s.ssdo.name(),
            if s.ssdo_knobs.blur { "on" } else { "off" },
            s.opacity,
            passes.join(" ")
        ));
    }

    fn frame(&mut self, el: &ActiveEventLoop) -> Result<()> {
        // Scene still loading: show progress, keep the window responsive.
        if let Loading::Pending(handle, pct) = &self.loading {
            if !handle.is_finished() {
                if let Some(w) = &self.window {
                    w.set_title(&format!(
                        "sphereshade | loading {}%",
                        pct.load(Ordering::Relaxed)
                    ));
                }
                return Ok(());
            }
            let Loading::Pending(handle, _) = std::mem::replace(&mut self.loading, Loading::Taken)
            else {
                return Ok(());
            };
            let (scene, _) = handle
                .join()
                .map_err(|_| Error::Internal("scene loader thread panicked".into()))??;
            let axes = Axes {
                width: self.size.0.max(1),
                height: self.size.1.max(1),
                ..self.cmd.axes.clone()
            };
            let settings = self.cmd.options.resolve(&axes, &scene)?;
            let c = settings.camera;
            let o = Orbit {
                center: c.center,
                dir: c.dir,
                up: c.up,
                height: c.view_height,
                fov: c.fov_deg,
            };
            self.home = Some(o);
            self.orbit = Some(o);
            let started = Instant::now();
            let proxies = crate::render::nesting::proxies_of(&scene, settings.lod.pixels())?;
            let r = viewer_renderer(
                self.ctx,
                self.swapchain.as_ref(),
                &scene,
                settings,
                proxies.as_ref(),
            )?;
            eprintln!(
                "view: renderer ready in {:.0} ms ({} spheres)",
                started.elapsed().as_secs_f64() * 1e3,
                r.inspect().represented()
            );
            if let Some(t) = &self.cmd.trajectory {
                if scene.instancing.is_some() {
                    return Err(crate::Error::Input(format!(
                        "{}: an instanced model has no per-atom trajectory",
                        scene.source
                    )));
                }
                let residues: Vec<u32> = if scene.level_names.len() >= 3 {
                    scene.spheres.iter().map(|s| s.region[2]).collect()
                } else {
                    (0..scene.spheres.len() as u32).collect()
                };
                // (frames hold every atom as loaded; --hide keeps a subset)
                let kept = match &scene.origin {
                    Some(crate::scene::Origin::Plain { index, .. }) => Some(index.clone()),
                    _ => None,
                };
                self.player = Some(player::Player::open(
                    t,
                    scene.input_count() as usize,
                    self.cmd.pbc,
                    residues,
                    kept,
                )?);
            }
            self.renderer = Some(r);
            self.loading = Loading::Done;
            self.loaded_colors = scene.spheres.iter().map(|s| s.color).collect();
            self.groups = crate::scene::paint::hierarchy_groups(&scene);
            // A nested scene: kept, with its proxies, to reopen placements
            // as the camera moves (`update_camera`).
            self.nested = match proxies {
                Some(proxies) => {
                    let open = match &self.renderer {
                        Some(r) => {
                            crate::render::nesting::opening(
                                &scene,
                                Some(&proxies),
                                &r.settings().camera,
                            )?
                            .open
                        }
                        None => Vec::new(),
                    };
                    Some(Nested {
                        scene,
                        proxies,
                        open,
                    })
                }
                None => None,
            };
        }
        if let Some(a) = self.actions.pop_front() {
            self.act(a)?;
        }
        if self.size.0 == 0 || self.size.1 == 0 {
            return Ok(()); // minimised
        }
        let Some(r) = &mut self.renderer else {
            return Ok(());
        };
        // A trajectory frame that arrived replaces the positions (smoke runs
        // with --frames step at once, so N frames play N trajectory frames).
        if let Some(p) = &mut self.player
            && let Some(f) = p.poll(self.cmd.frames.is_some())?
        {
            r.set_positions(&f.positions)?;
        }
        // At most two frames in flight: this returns the timings of the frame
        // submitted two calls ago (already done), never stalling on this one.
        let times = r.render_frame_pipelined()?.unwrap_or_default();
        let Some(sc) = &mut self.swapchain else {
            return Ok(());
        };
        let stale = (sc.extent.width, sc.extent.height) != self.size;
        if stale || matches!(sc.present(self.ctx, r.color_buffer())?, Present::Recreate) {
            sc.recreate(self.ctx, self.size.0, self.size.1)?;
            let ext = (sc.extent.width, sc.extent.height);
            if ext != self.size || stale {
                self.size = ext;
                self.resize_renderer()?;
            }
            return Ok(());
        }
        self.frames += 1;
        let now = Instant::now();
        if let Some(t) = self.last_present.replace(now) {
            self.intervals.push((now - t).as_secs_f64());
        }
        if self.frames == 1 {
            self.second_frame_at = Some(now);
            eprintln!(
                "view: first frame presented {:.0} ms after start",
                self.started.elapsed().as_secs_f64() * 1e3
            );
        }
        self.title(&times);
        if let Some(n) = self.cmd.frames {
            if self.cmd.resize_test && !self.resized_once && self.frames >= n / 2 {
                self.resized_once = true;
                if let Some(w) = &self.window {
                    let _ =
                        w.request_inner_size(PhysicalSize::new(self.size.0 + 40, self.size.1 + 24));
                }
            }
            if self.frames >= n && (!self.cmd.resize_test || self.resized_once) {
                // Average over the frames after the first (pipeline warm-up).
                if let Some(t0) = self.second_frame_at {
                    let fps = (self.frames - 1) as f64 / t0.elapsed().as_secs_f64().max(1e-9);
                    eprintln!(
                        "view: {} frames at {}x{}, {fps:.2} fps (frames 2..{})",
                        self.frames, self.size.0, self.size.1, self.frames
                    );
                }
                if let Some(p) = self.cmd.screenshot.clone() {
                    self.screenshot(&p)?;
                }
                el.exit();
            }
        }
        Ok(())
    }

    /// Replays one scripted action through the input handlers.
    fn act(&mut self, a: Action) -> Result<()> {
        match a {
            Action::Key(k) => self.key(&Key::Character(k.into())),
            Action::LightDrag(dx, dy) => {
                let (shift, buttons) = (self.shift, self.buttons);
                self.shift = true;
                self.buttons = [true, false, false];
                let r = self.drag(dx, dy);
                (self.shift, self.buttons) = (shift, buttons);
                r
            }
            Action::Zoom(steps) => self.zoom(steps),
        }
    }

    /// The wheel: each notch in makes the view 0.9x as high.
    fn zoom(&mut self, steps: f64) -> Result<()> {
        if let Some(o) = &mut self.orbit {
            o.height *= 0.9f64.powf(steps);
        }
        self.update_camera()
    }

    fn key(&mut self, key: &Key) -> Result<()> {
        if let Some(p) = &mut self.player {
            match key.as_ref() {
                Key::Named(NamedKey::Space) => p.toggle_play(),
                Key::Named(NamedKey::ArrowLeft) => p.step(-1),
                Key::Named(NamedKey::ArrowRight) => p.step(1),
                Key::Character("[") => p.faster(0.5),
                Key::Character("]") => p.faster(2.0),
                Key::Character("l" | "L") => p.looping = !p.looping,
                _ => return self.mode_key(key),
            }
            return Ok(());
        }
        self.mode_key(key)
    }

    fn mode_key(&mut self, key: &Key) -> Result<()> {
        let Some(r) = &mut self.renderer else {
            return Ok(());
        };
        let s = r.settings().clone();
        let started = Instant::now();
        match key.as_ref() {
            Key::Character("s" | "S") => r.update(|n| n.shadows = next(s.shadows))?,
            Key::Character("o" | "O") => r.update(|n| n.ssdo = next(s.ssdo))?,
            Key::Character("b" | "B") => r.update(|n| n.ssdo_knobs.blur = !s.ssdo_knobs.blur)?,
            Key::Character("+" | "=") => r.update(|n| n.opacity = (s.opacity + 0.1).min(1.0))?,
            Key::Character("-" | "_") => r.update(|n| n.opacity = (s.opacity - 0.1).max(0.0))?,
            Key::Character("t" | "T") => {
                self.preset = (self.preset + 1) % PRESETS.len();
                let colors = preset_colors(self.preset, &self.loaded_colors, &self.groups);
                r.set_colors(&colors)?;
                eprintln!("view: see-through preset: {}", PRESETS[self.preset]);
            }
            Key::Character("r" | "R") => {
                self.orbit = self.home;
                return self.update_camera();
            }
            Key::Character("p" | "P") => {
                self.screenshots += 1;
                let p = PathBuf::from(format!("sphereshade-{}.png", self.screenshots));
                return self.screenshot(&p);
            }
            Key::Character("h" | "H") => {
                println!("{HELP}");
                if let Some(w) = &self.window {
                    w.set_title(HELP);
                }
                return Ok(());
            }
            _ => return Ok(()),
        }
        self.toggle_times.push(started.elapsed().as_secs_f64());
        Ok(())
    }

    fn drag(&mut self, dx: f64, dy: f64) -> Result<()> {
        let Some(o) = &mut self.orbit else {
            return Ok(());
        };
        let right = o.dir.cross(o.up).normalize();
        if self.shift && self.buttons[0] {
            // light direction: rotate around the view axes
            if let Some(r) = &mut self.renderer {
                let started = Instant::now();
                let l = r.settings().light;
                let light = rotate(rotate(l, o.up, dx * 0.01), right, dy * 0.01);
                r.update(|s| s.light = light)?;
                self.drag_times.push(started.elapsed().as_secs_f64());
            }
            return Ok(());
        }
        if self.buttons[0] {
            // orbit around the view centre
            o.dir = rotate(rotate(o.dir, o.up, -dx * 0.005), right, -dy * 0.005).normalize();
            let r = o.dir.cross(o.up);
            if r.length() > 1e-6 {
                o.up = r.normalize().cross(o.dir).normalize();
            }
        } else if self.buttons[1] || self.buttons[2] {
            let per_px = o.height / self.size.1.max(1) as f64;
            let up = right.cross(o.dir);
            o.center += (-dx * right + dy * up) * per_px;
        } else {
            return Ok(());
        }
        self.update_camera()
    }
}

impl ApplicationHandler for App<'_> {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let attrs = Window::default_attributes()
            .with_title("sphereshade")
            .with_inner_size(PhysicalSize::new(self.size.0, self.size.1));
        let made = (|| -> Result<()> {
            let window = Arc::new(
                el.create_window(attrs)
                    .map_err(|e| Error::Input(format!("cannot open a window: {e}")))?,
            );
            let dh = window
                .display_handle()
                .map_err(|e| Error::Input(format!("display handle: {e}")))?;
            let wh = window
                .window_handle()
                .map_err(|e| Error::Input(format!("window handle: {e}")))?;
            // SAFETY: the display and window handles come from the live winit window.
            let surface = unsafe {
                ash_window::create_surface(
                    &self.ctx.entry,
                    &self.ctx.instance,
                    dh.as_raw(),
                    wh.as_raw(),
                    None,
                )
            }
            .map_err(|result| Error::Vk {
                call: "vkCreate*SurfaceKHR",
                result,
            })?;
            let size = window.inner_size();
            self.size = (size.width, size.height);
            self.swapchain = Some(Swapchain::new(self.ctx, surface, size.width, size.height)?);
            self.window = Some(window);
            Ok(())
        })();
        if let Err(e) = made {
            self.fail(el, e);
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                el.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                self.size = (size.width, size.height);
                Ok(())
            }
            WindowEvent::RedrawRequested => self.frame(el),
            WindowEvent::ModifiersChanged(m) => {
                self.shift = m.state().shift_key();
                Ok(())
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                if event.logical_key == Key::Named(NamedKey::Escape) {
                    el.exit();
                    Ok(())
                } else {
                    self.key(&event.logical_key)
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let i = match button {
                    MouseButton::Left => 0,
                    MouseButton::Right => 1,
                    MouseButton::Middle => 2,
                    _ => return,
                };
                self.buttons[i] = state == ElementState::Pressed;
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                let (dx, dy) = (position.x - self.cursor.0, position.y - self.cursor.1);
                self.cursor = (position.x, position.y);
                if self.buttons.iter().any(|b| *b) {
                    self.drag(dx, dy)
                } else {
                    Ok(())
                }
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y as f64,
                    MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
                };
                self.zoom(steps)
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(el, e);
        }
    }

    fn about_to_wait(&mut self, _el: &ActiveEventLoop) {
        if let Some(w) = &self.window {
            w.request_redraw();
        }
    }
}

/// Runs the viewer until the window closes or `--frames` are done.
pub fn run(cmd: ViewCmd) -> Result<Exit> {
    let started = Instant::now();
    // Everything the options can get wrong, before a window or device.
    if let Some(p) = &cmd.screenshot {
        crate::output::check_outputs(&[crate::output::OutFile {
            flag: "--screenshot",
            path: p,
            extensions: &["png"],
        }])?;
    }
    if cmd.frames == Some(0) {
        return Err(Error::Input("--frames must be at least 1".into()));
    }
    if cmd.options.ssaa > 1 || cmd.options.tile_size.is_some() {
        return Err(Error::Input(
            "--ssaa and --tile-size apply to `render` (the window shows one sample per pixel)"
                .into(),
        ));
    }
    let (w, h) = (cmd.axes.width, cmd.axes.height);
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(Error::Input(
            "--width/--height must be between 1 and 16384".into(),
        ));
    }
    let display_vars = ["DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"];
    if display_vars
        .iter()
        .all(|v| std::env::var_os(v).is_none_or(|s| s.is_empty()))
    {
        return Err(Error::Input(
            "view needs a display: none of DISPLAY, WAYLAND_DISPLAY, WAYLAND_SOCKET is set \
             (headless: use `render`, or run under xvfb-run)"
                .into(),
        ));
    }
    let event_loop = EventLoop::new().map_err(|e| {
        // winit prefixes "os error at <source file>:<line>: "; keep the reason.
        let e = e.to_string();
        let first = e.lines().next().unwrap_or("no display");
        let reason = match first.find(".rs:") {
            Some(i) => first[i..].split_once(": ").map_or(first, |(_, r)| r),
            None => first,
        };
        Error::Input(format!("cannot open a window: {reason}"))
    })?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let dh = event_loop
        .display_handle()
        .map_err(|e| Error::Input(format!("display handle: {e}")))?;
    let exts =
        ash_window::enumerate_required_extensions(dh.as_raw()).map_err(|result| Error::Vk {
            call: "enumerate_required_extensions",
            result,
        })?;
    let instance_extensions: Vec<CString> = exts
        .iter()
        // SAFETY: ash_window returns static NUL-terminated extension names.
        .map(|&p| unsafe { std::ffi::CStr::from_ptr(p) }.to_owned())
        .collect();
    let ctx = Context::new(&ContextOptions {
        validate: cmd.options.validate,
        device_index: cmd.options.device,
        instance_extensions,
        swapchain: true,
    })?;

    // Load on a thread so the window opens at once and shows progress.
    let pct = Arc::new(AtomicU64::new(0));
    let scene_args = cmd.scene.clone();
    let p2 = pct.clone();
    let handle = std::thread::spawn(move || {
        run::load_scene_with_progress(&scene_args, &mut |d, t| {
            p2.store((d * 100).checked_div(t).unwrap_or(0), Ordering::Relaxed);
        })
    });
    let size = (cmd.axes.width, cmd.axes.height);
    let actions = cmd.script.as_deref().map(script).unwrap_or_default().into();
    let mut app = App {
        ctx: &ctx,
        cmd,
        window: None,
        swapchain: None,
        renderer: None,
        loading: Loading::Pending(handle, pct),
        home: None,
        orbit: None,
        size,
        frames: 0,
        second_frame_at: None,
        started,
        resized_once: false,
        nested: None,
        cursor: (0.0, 0.0),
        buttons: [false; 3],
        shift: false,
        screenshots: 0,
        last_title: Instant::now(),
        fps_frames: 0,
        error: None,
        exit: Exit::Ok,
        actions,
        toggle_times: Vec::new(),
        intervals: Vec::new(),
        last_present: None,
        drag_times: Vec::new(),
        player: None,
        loaded_colors: Vec::new(),
        groups: Vec::new(),
        preset: 0,
    };
    let ran = event_loop.run_app(&mut app);
    if let Some(p) = &app.player {
        eprintln!(
            "view: played {} trajectory frame(s) of {} (last shown: frame {})",
            p.shown, p.n, p.current
        );
    }
    let mean_ms = |v: &[f64]| 1e3 * v.iter().sum::<f64>() / v.len().max(1) as f64;
    if app.cmd.script.is_some() && !app.intervals.is_empty() {
        let each: Vec<String> = app
            .intervals
            .iter()
            .map(|t| format!("{:.0}", 1e3 * t))
            .collect();
        log::info!(
            "view: frame intervals (ms, from frame 2): {}",
            each.join(" ")
        );
        let mut v = app.intervals.clone();
        v.sort_by(f64::total_cmp);
        let (at, most) = app
            .intervals
            .iter()
            .enumerate()
            .fold((0, 0.0), |b, (i, &t)| if t > b.1 { (i + 2, t) } else { b });
        eprintln!(
            "view: {} frame intervals: median {:.1} ms, longest {:.1} ms (before frame {at}); \
             final view height {}",
            v.len(),
            1e3 * v[v.len() / 2],
            1e3 * most,
            app.orbit.map_or(0.0, |o| o.height)
        );
    }
    if !app.toggle_times.is_empty() || !app.drag_times.is_empty() {
        eprintln!(
            "view: {} mode toggles, mean {:.1} ms (max {:.1}); {} light-drag steps, mean {:.1} ms; \
             renderers created {}, pipelines created {}",
            app.toggle_times.len(),
            mean_ms(&app.toggle_times),
            1e3 * app.toggle_times.iter().cloned().fold(0.0, f64::max),
            app.drag_times.len(),
            mean_ms(&app.drag_times),
            crate::render::RENDERERS_CREATED.load(Ordering::Relaxed),
            ctx.pipelines_compiled(),
        );
        if let Some(r) = &app.renderer {
            let s = r.settings();
            eprintln!(
                "view: final state shadows {} ssdo {} blur {} opacity {} light {}",
                s.shadows,
                s.ssdo,
                if s.ssdo_knobs.blur { "on" } else { "off" },
                s.opacity,
                crate::settings::V3(s.light)
            );
        }
    }
    // Destroy in order: renderer, swapchain (and surface), then the context.
    app.renderer = None;
    if let Some(mut sc) = app.swapchain.take() {
        sc.destroy(&ctx);
    }
    app.window = None;
    if let Some(e) = app.error.take() {
        return Err(e);
    }
    ran.map_err(|e| Error::Input(format!("event loop: {e}")))?;
    let exit = std::mem::replace(&mut app.exit, Exit::Ok);
    drop(app);
    let (n, _) = ctx.finish();
    Ok(if n > 0 {
        Exit::ValidationMessages(n)
    } else {
        exit
    })
}
