//! The run loop shared by the CLI, the benchmark, the viewer and (later)
//! Python: load a scene, render frames, read AOV images back, and make the
//! stats record. Nothing here parses a command line beyond the clap
//! derives the CLI flattens.

use crate::error::{Error, Result};
use crate::output::{self, RunStats};
use crate::render::Renderer;
use crate::scene::paint::{Colormap, Paint, Rule, Scheme};
use crate::scene::{self, ColorBy, LoadOptions, ModelSelect, Scene};
use crate::settings::{Aov, Options, RenderSettings, ShadowMode, SsdoMode};
use crate::vk::{Context, ContextOptions, PassTimes};
use clap::Args;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

/// Where spheres come from (shared by render/bench/view).
#[derive(Args, Debug, Clone)]
pub struct SceneArgs {
    /// Structure file: .pdb .cif/.mmcif .gro .xyz .xyzr, optionally .gz.
    pub input: Option<PathBuf>,
    /// Procedural scene: capsid (default), lattice, random; meso (an HIV
    /// virion in plasma, instanced, --atoms up to ~4.2e9).
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
    #[arg(long, default_value_t = SceneArgs::default().radius_scale, allow_negative_numbers = true)]
    pub radius_scale: f32,
    /// Colour scheme: element, chain, residue (RasMol's amino colours),
    /// bfactor, index (input order), hierarchy (the outermost level that
    /// differs: chains of a protein, molecule types of a mesoscale scene),
    /// or one colour R,G,B.
    #[arg(long, default_value_t = SceneArgs::default().color, value_parser = check_scheme)]
    pub color: String,
    /// The map of `--color bfactor` and `--color index`.
    #[arg(long, value_enum, default_value_t = Colormap::default())]
    pub colormap: Colormap,
    /// Hide the spheres a selection picks (not loaded on the GPU: they
    /// cast no shadow), e.g. `--hide "water or hetatm"`. Repeatable; with
    /// --paint and --alpha applied in the order given.
    #[arg(long, value_name = "SEL", value_parser = ordered(Rule::hide))]
    pub hide: Vec<Ordered<Rule>>,
    /// Colour a selection: SEL=R,G,B (or #RRGGBB, or a name), e.g.
    /// `--paint "chain A=255,80,0"`. Repeatable.
    #[arg(long, value_name = "SEL=COLOR", value_parser = ordered(Rule::paint))]
    pub paint: Vec<Ordered<Rule>>,
    /// See-through spheres: SEL=A (alpha 0..1; 1 opaque), composited in
    /// exact depth order and casting translucent shadows (deep lists),
    /// e.g. `--alpha "not chain A=0.3"`. Repeatable.
    #[arg(long, value_name = "SEL=A", value_parser = ordered(Rule::alpha))]
    pub alpha: Vec<Ordered<Rule>>,
    /// Expand an instanced model (PetWorld, cellPACK, manifest, --assembly)
    /// into one sphere record per atom, as before instancing: the same
    /// image, for comparisons (at most 2^24 spheres).
    #[arg(long)]
    pub expand: bool,
}

impl Default for SceneArgs {
    fn default() -> Self {
        SceneArgs {
            input: None,
            scene: None,
            atoms: None,
            model: None,
            assembly: None,
            replicate: None,
            radius_scale: 1.0,
            color: "element".into(),
            colormap: Colormap::default(),
            hide: Vec::new(),
            paint: Vec::new(),
            alpha: Vec::new(),
            expand: false,
        }
    }
}

fn check_scheme(s: &str) -> std::result::Result<String, String> {
    Scheme::parse(s).map(|_| s.to_string())
}

/// A value with its place among the values of several flags: clap calls
/// value parsers in command-line order, so a counter orders `--hide`,
/// `--paint` and `--alpha` as given.
#[derive(Clone, Debug, PartialEq)]
pub struct Ordered<T> {
    pub seq: u64,
    pub value: T,
}

fn ordered<T: Clone + Send + Sync + 'static>(
    parse: fn(&str) -> std::result::Result<T, String>,
) -> impl Fn(&str) -> std::result::Result<Ordered<T>, String> + Clone + Send + Sync + 'static {
    static SEQ: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    move |s| {
        Ok(Ordered {
            seq: SEQ.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            value: parse(s)?,
        })
    }
}

impl SceneArgs {
    /// Appends a rule as its flag does (`kind`: "hide", "paint" or
    /// "alpha"), after every rule given so far (Python and tests; the
    /// error names the flag).
    pub fn add_rule(&mut self, kind: &str, text: &str) -> std::result::Result<(), String> {
        type Parse = fn(&str) -> std::result::Result<Rule, String>;
        let (parse, list): (Parse, &mut Vec<Ordered<Rule>>) = match kind {
            "hide" => (Rule::hide, &mut self.hide),
            "paint" => (Rule::paint, &mut self.paint),
            "alpha" => (Rule::alpha, &mut self.alpha),
            k => return Err(format!("rule kind '{k}': expected hide, paint or alpha")),
        };
        list.push(ordered(parse)(text).map_err(|e| format!("--{kind}: {e}"))?);
        Ok(())
    }

    /// The colour scheme (None: the loader's element or chain colours)
    /// and the rules in command-line order.
    pub fn paint(&self) -> Paint {
        let mut rules: Vec<&Ordered<Rule>> = self
            .hide
            .iter()
            .chain(&self.paint)
            .chain(&self.alpha)
            .collect();
        rules.sort_by_key(|r| r.seq);
        let scheme = match self.color.as_str() {
            "element" | "chain" => None,
            s => Scheme::parse(s).ok(),
        };
        Paint {
            scheme,
            colormap: self.colormap,
            rules: rules.into_iter().map(|r| r.value.clone()).collect(),
        }
    }
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

/// Progress of a long load on stderr (`show`): updated in place on a
/// terminal, every 25 % as lines in a log.
struct Progress {
    label: String,
    show: bool,
    tty: bool,
    last: u64,
}

impl Progress {
    fn new(label: String, show: bool) -> Self {
        Progress {
            label,
            show,
            tty: std::io::stderr().is_terminal(),
            last: 0,
        }
    }

    fn update(&mut self, done: u64, total: u64) {
        let pct = (done.saturating_mul(100)).checked_div(total).unwrap_or(0);
        let step = if self.tty { 5 } else { 25 };
        if self.show && pct >= self.last + step && pct < 100 {
            self.last = pct;
            if self.tty {
                eprint!("\r{}: {pct:3}%", self.label);
            } else {
                eprintln!("{}: {pct}%", self.label);
            }
        }
    }

    /// Clears the terminal line (before the caller's last word or an
    /// error).
    fn clear(&self) {
        if self.show && self.tty && self.last > 0 {
            eprint!("\r\x1b[K");
        }
    }
}

/// Loads the scene the arguments describe, with progress on stderr for
/// files above a few megabytes. Returns the scene and the load time in ms.
pub fn load_scene(args: &SceneArgs) -> Result<(Scene, f64)> {
    load_scene_with_progress(args, &mut |_, _| {})
}

/// `load_scene` that also reports (bytes done, bytes total) to `report`
/// (`--scene meso`: atoms placed, atoms wanted).
pub fn load_scene_with_progress(
    args: &SceneArgs,
    report: &mut dyn FnMut(u64, u64),
) -> Result<(Scene, f64)> {
    let t0 = Instant::now();
    let mut scene = match (&args.input, &args.scene) {
        (Some(_), Some(_)) => {
            return Err(Error::Input(
                "give an input file or --scene, not both".into(),
            ));
        }
        (Some(path), None) => {
            let model = match args.model.as_deref() {
                None => ModelSelect::First,
                Some("all") => ModelSelect::All,
                Some(n) => ModelSelect::Index(n.parse().map_err(|_| {
                    Error::Input(format!("--model {n}: expected a number or `all`"))
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
            // Progress for files that take a while (raw bytes: a .gz
            // reports its compressed share): updated in place on a
            // terminal, every 25 % as lines in a log.
            let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            let gz = scene::format_of(path).is_some_and(|(_, gz)| gz);
            let show = size > if gz { 2 << 20 } else { 8 << 20 };
            let shown = crate::output::printable(&path.display().to_string());
            let mut progress = Progress::new(format!("loading {shown}"), show);
            let s = scene::load(path, &opts, &mut |done, total| {
                report(done, total);
                progress.update(done, total);
            });
            progress.clear();
            let s = s?;
            if show {
                eprintln!("loading {shown}: done, {} spheres", s.spheres.len());
            }
            s
        }
        (None, name) => {
            if args.model.is_some() || args.assembly.is_some() {
                return Err(Error::Input(
                    "--model/--assembly apply to input files only".into(),
                ));
            }
            let name = name.as_deref().unwrap_or(scene::DEFAULT_SCENE);
            let atoms = args.atoms.unwrap_or(scene::DEFAULT_ATOMS);
            if name.eq_ignore_ascii_case("meso") {
                // instanced: as many atoms as an instanced scene represents
                let most = scene::meso::MAX_ATOMS.min(scene::instanced::MAX_REPRESENTED);
                if atoms == 0 || atoms as u64 > most {
                    return Err(Error::Input(format!(
                        "--atoms {atoms}: the meso scene holds between 1 and {most} atoms"
                    )));
                }
                let t = std::time::Instant::now();
                // (10^9 atoms build in ~2 s, 10^10 in ~30)
                let mut progress =
                    Progress::new("building the meso scene".into(), atoms as u64 >= 1 << 30);
                let s = scene::meso::meso_with_progress(atoms as u64, 1, &mut |done, total| {
                    report(done, total);
                    progress.update(done, total);
                });
                progress.clear();
                let s = s?;
                log::info!(
                    "meso scene: {} atoms in {} instances, built in {:.0} ms",
                    s.represented(),
                    s.instancing.as_ref().map_or(0, |i| i.instances()),
                    t.elapsed().as_secs_f64() * 1e3
                );
                s
            } else if atoms == 0 || atoms > scene::MAX_SPHERES {
                return Err(Error::Input(format!(
                    "--atoms {atoms}: must be between 1 and {}, the most sphereshade renders",
                    scene::MAX_SPHERES
                )));
            } else {
                scene::procedural(name, atoms, 1)?
            }
        }
    };
    // Colours and rules first: on an instanced scene they apply per
    // molecule type or instance (what --expand then expands).
    let paint = args.paint();
    if !paint.is_empty() {
        let (s, applied) = scene::paint::apply(scene, &paint)?;
        scene = s;
        for (rule, n) in paint.rules.iter().zip(&applied.selected) {
            if *n == 0 {
                // (what a `molecule` or `node` rule could have named)
                let hint = match &scene.instancing {
                    Some(i) if rule.sel.per_instance() => {
                        format!(" ({})", crate::output::printable(&i.names_hint(8)))
                    }
                    _ => String::new(),
                };
                eprintln!(
                    "note: {} '{}' selects no sphere{hint}",
                    rule.flag,
                    crate::output::printable(&rule.text)
                );
            }
        }
    }
    if args.expand && scene.instancing.is_some() {
        scene = scene.expand()?;
    }
    if args.atoms.is_some() && args.input.is_some() {
        return Err(Error::Input(
            "--atoms applies to procedural scenes (--scene) only".into(),
        ));
    }
    if let Some(n) = args.replicate {
        if scene.origin.is_some() {
            return Err(Error::Input(
                "--replicate copies the whole input: it does not combine with --hide".into(),
            ));
        }
        if scene.instancing.is_some() {
            return Err(Error::Input(
                "--replicate applies to plain scenes (an instanced model: add --expand)".into(),
            ));
        }
        // Refuse before allocating: sphere ids are 24-bit in the id AOV.
        let total =
            scene.spheres.len() as u128 * n.iter().map(|&k| k.max(1) as u128).product::<u128>();
        if total > scene::MAX_SPHERES as u128 {
            return Err(Error::Input(format!(
                "--replicate {}x{}x{}: {total} spheres, more than {}, the most sphereshade renders",
                n[0],
                n[1],
                n[2],
                scene::MAX_SPHERES
            )));
        }
        scene = scene.replicate(n);
    }
    if !(args.radius_scale > 0.0 && args.radius_scale.is_finite()) {
        return Err(Error::Input("--radius-scale must be positive".into()));
    }
    if args.radius_scale != 1.0 {
        scene.scale_radii(args.radius_scale);
        if scene.max_radius() > scene::MAX_COORDINATE {
            return Err(Error::Input(format!(
                "--radius-scale {}: the largest radius becomes {:e}, above {:e}, the range \
                 sphereshade renders in f32",
                args.radius_scale,
                scene.max_radius(),
                scene::MAX_COORDINATE
            )));
        }
    }
    Ok((scene, t0.elapsed().as_secs_f64() * 1e3))
}

/// The Vulkan context the options ask for (validation, device index).
pub fn context_for(o: &Options) -> Result<Context> {
    Context::new(&ContextOptions {
        validate: o.validate,
        device_index: o.device,
        ..Default::default()
    })
}

/// `--frames` counts measured frames: zero would measure nothing.
pub fn check_frames(frames: u32) -> Result<()> {
    if frames == 0 {
        return Err(Error::Input("--frames must be at least 1".into()));
    }
    Ok(())
}

/// Reads the requested AOV back from the renderer and encodes it.
pub fn aov_image(r: &Renderer, aov: Aov) -> Result<output::AovImage> {
    let cam = &r.settings().camera;
    let (w, h) = (cam.width, cam.height);
    Ok(match aov {
        Aov::Color => output::color_image(w, h, &r.inspect().read_color()?),
        Aov::Id => output::id_image(
            w,
            h,
            &r.inspect().read_ids()?,
            r.inspect().represented(),
            r.inspect().id_map().as_deref(),
        ),
        Aov::Depth => {
            let d: Vec<f32> = r.inspect().read_gpos()?.iter().map(|p| p[3]).collect();
            output::depth_image(w, h, &d)
        }
        Aov::Shadow | Aov::Ao => {
            let covered: Vec<bool> = r
                .inspect()
                .read_vis_slots()?
                .iter()
                .map(|&k| k != crate::gpu::VIS_EMPTY)
                .collect();
            if aov == Aov::Shadow {
                output::unit_image(w, h, r.inspect().read_shadow()?.into_iter(), &covered)
            } else {
                let ao: Vec<f32> = if r.settings().ssdo == SsdoMode::Off {
                    vec![1.0; covered.len()]
                } else {
                    r.inspect()
                        .read_ambient()?
                        .into_iter()
                        .map(|a| a[0])
                        .collect()
                };
                // (ambient visibility after the blur, as DESIGN.md specifies)
                output::unit_image(w, h, ao.into_iter(), &covered)
            }
        }
    })
}

/// Renders the whole image (tiled when needed) and, with `n` > 1, n x n
/// times with the camera moved to each sub-pixel sample position
/// ((k + 0.5) / n - 0.5 pixels per axis), averaging the colour in linear
/// light (alpha = coverage); the other buffers are the last sample's. The
/// light structure is built once (it does not depend on the camera); the
/// pass times are summed over the samples. Measured on 1TII and the 1M
/// capsid (README): cheaper than rendering at n times the size, whose tiles
/// need margins n times wider for the same SSDO radius.
pub fn render_supersampled(
    r: &mut Renderer,
    n: u32,
    tile: Option<u32>,
    read: Option<crate::render::tiles::Keep>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Option<crate::render::tiles::Image>, PassTimes)> {
    if n <= 1 {
        return r.render_image_with(tile, read, progress);
    }
    let samples = (n * n) as usize;
    // (every sample is read: its colour is averaged)
    let keep = read.unwrap_or(crate::render::tiles::Keep::ALL);
    let base = r.settings().clone();
    let cache = r.inspect().light_cache();
    r.set_light_cache(true);
    let result = (|| {
        let mut sum = PassTimes::default();
        let pixels = base.camera.width as usize * base.camera.height as usize;
        let mut acc = output::Accumulator::new(pixels, base.look.color16);
        let mut last = None;
        for sy in 0..n {
            for sx in 0..n {
                let off = |k: u32| (k as f64 + 0.5) / n as f64 - 0.5;
                let cam = base.shifted(off(sx), off(sy)).camera;
                r.update(|s| s.camera = cam)?;
                let k = (sy * n + sx) as usize;
                let (img, t) = r.render_image_with(tile, Some(keep), &mut |done, tiles| {
                    progress(k * tiles + done, samples * tiles)
                })?;
                let img = img.ok_or_else(|| Error::Internal("no image read back".into()))?;
                sum.add(&t);
                acc.add(&img.color);
                last = Some(img);
            }
        }
        let mut img = last.ok_or_else(|| Error::Internal("no samples".into()))?;
        img.color = acc.finish();
        Ok((Some(img), sum))
    })();
    r.set_light_cache(cache);
    r.update(|s| s.camera = base.camera)?;
    result
}

/// Renders the whole image band by band, each band a row of the tile plan
/// (the whole image when it is one tile), with `n` x `n` supersampling of
/// the colour per band, and hands each band to `on_band` in order: host
/// memory holds one band, not the image (a 16384² image in bands of a few
/// thousand rows). The light structure is built once; the pass times are
/// summed over tiles and samples. The bands are the pixels of
/// `render_supersampled`'s image.
pub fn render_bands(
    r: &mut Renderer,
    n: u32,
    tile: Option<u32>,
    keep: crate::render::tiles::Keep,
    progress: &mut dyn FnMut(usize, usize),
    on_band: &mut dyn FnMut(crate::render::tiles::Band) -> Result<()>,
) -> Result<PassTimes> {
    let tiles = r.tile_plan(tile)?;
    if tiles.len() == 1 {
        let (img, t) = render_supersampled(r, n, tile, Some(keep), progress)?;
        let image = img.ok_or_else(|| Error::Internal("no image read back".into()))?;
        on_band(crate::render::tiles::Band { y0: 0, image })?;
        return Ok(t);
    }
    let samples = (n.max(1) * n.max(1)) as usize;
    let base = r.settings().clone();
    let cache = r.inspect().light_cache();
    r.set_light_cache(true);
    let result = (|| {
        let mut sum = PassTimes::default();
        let rows = crate::render::tiles::tile_rows(&tiles);
        let mut done = 0;
        for row in rows {
            let mut acc = None;
            let mut last = None;
            for k in 0..samples {
                if n > 1 {
                    let off = |i: usize| (i as f64 + 0.5) / n as f64 - 0.5;
                    let (sx, sy) = (k % n as usize, k / n as usize);
                    let cam = base.shifted(off(sx), off(sy)).camera;
                    r.update(|s| s.camera = cam)?;
                }
                let (band, t) = r.render_row(&tiles[row.clone()], keep)?;
                sum.add(&t);
                if n > 1 {
                    let px = band.image.width as usize * band.image.height as usize;
                    acc.get_or_insert_with(|| output::Accumulator::new(px, base.look.color16))
                        .add(&band.image.color);
                }
                done += row.len();
                progress(done, tiles.len() * samples);
                last = Some(band);
            }
            let mut band = last.ok_or_else(|| Error::Internal("no samples".into()))?;
            if let Some(a) = acc {
                band.image.color = a.finish();
            }
            on_band(band)?;
        }
        Ok(sum)
    })();
    r.set_light_cache(cache);
    if n > 1 {
        r.update(|s| s.camera = base.camera)?;
    }
    result
}

/// What an AOV image needs read back besides colour.
fn keep_for(aov: Aov) -> crate::render::tiles::Keep {
    crate::render::tiles::Keep {
        vis: aov != Aov::Color,
        aov: matches!(aov, Aov::Shadow | Aov::Ao),
    }
}

/// Progress of a frame made of several steps (tiles x sub-pixel samples)
/// on stderr: updated in place on a terminal, a line every 10 % in a log;
/// silent for one-step frames.
pub struct StepProgress {
    what: &'static str,
    tty: bool,
    started: Instant,
    last_tenth: usize,
}

impl StepProgress {
    pub fn new(what: &'static str) -> Self {
        StepProgress {
            what,
            tty: std::io::stderr().is_terminal(),
            started: Instant::now(),
            last_tenth: 0,
        }
    }

    pub fn tick(&mut self, done: usize, total: usize) {
        if total <= 1 {
            return;
        }
        if done == 1 {
            self.started = Instant::now();
            self.last_tenth = 0;
        }
        let s = self.started.elapsed().as_secs_f64();
        let eta = s / done as f64 * (total - done) as f64;
        let line = format!(
            "{}: {done}/{total} tiles x samples, {s:.1} s, ETA {eta:.0} s",
            self.what
        );
        if self.tty {
            eprint!("\r\x1b[K{line}");
            if done == total {
                eprint!("\r\x1b[K");
            }
        } else if done * 10 / total > self.last_tenth {
            self.last_tenth = done * 10 / total;
            eprintln!("{line}");
        }
    }
}

/// The AOV of a whole image (tiled or not, supersampled or not).
pub fn image_aov(img: &crate::render::tiles::Image, aov: Aov) -> output::AovImage {
    let (w, h) = (img.width, img.height);
    let covered = || -> Vec<bool> {
        img.vis
            .iter()
            .map(|&k| k != crate::gpu::VIS_EMPTY)
            .collect()
    };
    match aov {
        Aov::Color => {
            if img.wide {
                output::color16_image(w, h, &img.color)
            } else {
                output::color_image(w, h, &img.color)
            }
        }
        Aov::Id => output::id_image(w, h, &img.expanded_ids(), img.spheres, img.ids.as_deref()),
        Aov::Depth => {
            let d: Vec<f32> = img.vis.iter().map(|&k| depth_of(k)).collect();
            output::depth_image(w, h, &d)
        }
        Aov::Shadow | Aov::Ao => {
            let words = img.aov.as_deref().unwrap_or(&[]);
            let shift = if aov == Aov::Shadow { 0 } else { 16 };
            let values = (0..img.vis.len()).map(|i| {
                words
                    .get(i)
                    .map_or(1.0, |a| ((a >> shift) & 0xFFFF) as f32 / 65535.0)
            });
            output::unit_image(w, h, values, &covered())
        }
    }
}

/// The depth key of a visibility word (-1 for background).
fn depth_of(k: u64) -> f32 {
    if k == crate::gpu::VIS_EMPTY {
        -1.0
    } else {
        f32::from_bits((k >> 32) as u32)
    }
}

/// Named f32 channels of an image, in order.
pub type Layers = Vec<(&'static str, Vec<f32>)>;

/// The names of the OpenEXR layers `render_layer_bands` writes for
/// `scene`, in the order of its bands' layers.
pub fn layer_names(scene: &Scene) -> Vec<&'static str> {
    let mut names = vec![
        "R", "G", "B", "A", "depth", "id", "shadow", "ao", "normal.X", "normal.Y", "normal.Z",
    ];
    if scene.instancing.is_some() {
        names.extend(["instance", "atom"]);
    }
    names
}

/// The OpenEXR layers of DESIGN.md for one image: `R,G,B,A` (linear; the
/// colour supersampled with `settings.ssaa`), `depth` (view distance as the
/// shaders' view_z, world units; +inf on background), `id` (index + 1 as a
/// float, 0 on background), `shadow`, `ao` (1 on background) and
/// `normal.X/Y/Z` (world space, 0 on background). The non-colour layers
/// come from a one-sample-per-pixel frame, as the PNG AOVs do.
pub fn render_layers(
    ctx: &Context,
    scene: &Scene,
    input: &str,
    settings: RenderSettings,
    load_ms: f64,
) -> Result<(Layers, RunStats)> {
    let mut whole: Layers = layer_names(scene)
        .into_iter()
        .map(|n| (n, Vec::new()))
        .collect();
    let stats = render_layer_bands(ctx, scene, input, settings, load_ms, &mut |_, band| {
        for ((_, all), (_, v)) in whole.iter_mut().zip(band) {
            all.extend_from_slice(v);
        }
        Ok(())
    })?;
    Ok((whole, stats))
}

/// `render_layers` a band of tile rows at a time: `on_band(y0, layers)`
/// gets rows `y0..` of every layer (`layer_names` order), top to bottom, so
/// host memory holds one band, not the image.
pub fn render_layer_bands(
    ctx: &Context,
    scene: &Scene,
    input: &str,
    settings: RenderSettings,
    load_ms: f64,
    on_band: &mut output::ExrBand<'_>,
) -> Result<RunStats> {
    use crate::render::tiles::Keep;
    let tile = settings.tile_size;
    let mut s1 = settings.clone();
    s1.aovs = true;
    s1.look.color16 = true;
    let cam = s1.camera;
    let n = settings.ssaa_for(Aov::Color);
    let mut r = Renderer::new_windowed(ctx, scene, s1.clone(), tile)?;
    let mut hash = <sha2::Sha256 as sha2::Digest>::new();
    let ids = scene.id_map();
    // A tile row is cut into bands of 64 rows: the f32 layers (44 B/px)
    // would otherwise be the largest host buffer.
    let mut emit = |y0: u32, img: &crate::render::tiles::Image, color: &[u32]| -> Result<()> {
        let w = img.width as usize;
        for r0 in (0..img.height).step_by(64) {
            let rows = r0..(r0 + 64).min(img.height);
            let words = &color[2 * w * rows.start as usize..2 * w * rows.end as usize];
            output::color16_image(img.width, rows.len() as u32, words).hash_into(&mut hash);
            let layers = band_layers(scene, &s1, y0, img, color, rows, ids.as_ref())?;
            on_band(y0 + r0, &layers)?;
        }
        Ok(())
    };
    let tiles = r.tile_plan(tile)?;
    let times = if tiles.len() == 1 {
        let (img, times) = r.render_image(tile)?;
        let color = if n > 1 {
            render_supersampled(&mut r, n, tile, Some(Keep::ALL), &mut |_, _| {})?
                .0
                .map(|i| i.color)
                .unwrap_or_default()
        } else {
            img.color.clone()
        };
        emit(0, &img, &color)?;
        times
    } else {
        // Each band: the one-sample frame, then the colour's sub-pixel
        // samples of the same rows (the light view is the first frame's).
        let cache = r.inspect().light_cache();
        r.set_light_cache(true);
        let result = (|| -> Result<PassTimes> {
            let mut first = PassTimes::default();
            for row in crate::render::tiles::tile_rows(&tiles) {
                let (band, t) = r.render_row(&tiles[row.clone()], Keep::ALL)?;
                first.add(&t);
                let mut color = None;
                if n > 1 {
                    let px = band.image.width as usize * band.image.height as usize;
                    let mut acc = output::Accumulator::new(px, true);
                    let off = |i: u32| (i as f64 + 0.5) / n as f64 - 0.5;
                    for k in 0..n * n {
                        let c = settings.shifted(off(k % n), off(k / n)).camera;
                        r.update(|s| s.camera = c)?;
                        let keep = Keep {
                            vis: false,
                            aov: false,
                        };
                        acc.add(&r.render_row(&tiles[row.clone()], keep)?.0.image.color);
                    }
                    r.update(|s| s.camera = cam)?;
                    color = Some(acc.finish());
                }
                let color = color.as_deref().unwrap_or(&band.image.color);
                emit(band.y0, &band.image, color)?;
            }
            Ok(first)
        })();
        r.set_light_cache(cache);
        result?
    };
    let mut stats = run_stats(
        ctx,
        &r,
        input,
        &[times],
        load_ms,
        &format!("{:x}", sha2::Digest::finalize(hash)),
    );
    stats.width = cam.width;
    stats.height = cam.height;
    Ok(stats)
}

/// The layers of rows `rows` of one band (rows `y0..` of the image) from
/// its one-sample frame `img` and its (supersampled) RGBA16 colour words.
fn band_layers(
    scene: &Scene,
    s1: &RenderSettings,
    y0: u32,
    img: &crate::render::tiles::Image,
    color_words: &[u32],
    rows: std::ops::Range<u32>,
    ids: Option<&crate::scene::paint::IdMap>,
) -> Result<Layers> {
    let cam = s1.camera;
    let w = img.width;
    let px = w as usize * rows.len();
    let first = w as usize * rows.start as usize;
    let (mut rgba, mut depth, mut id) = (
        vec![vec![0.0f32; px]; 4],
        vec![f32::INFINITY; px],
        vec![0.0f32; px],
    );
    let (mut shadow, mut ao) = (vec![1.0f32; px], vec![1.0f32; px]);
    let mut normal = vec![vec![0.0f32; px]; 3];
    // instanced scenes: the instance and the atom within its molecule
    let inst = scene.instancing.as_ref();
    let (mut instance, mut atom) = if inst.is_some() {
        (vec![-1.0f32; px], vec![-1.0f32; px])
    } else {
        (Vec::new(), Vec::new())
    };
    let words = img.aov.as_deref().unwrap_or(&[]);
    let expanded = img.expanded_ids();
    let base = if cam.fov_deg.is_some() {
        cam.eye()
    } else {
        cam.center
    };
    for i in 0..px {
        let j = first + i;
        let (a, b) = (color_words[2 * j], color_words[2 * j + 1]);
        let c = [a & 0xFFFF, a >> 16, b & 0xFFFF, b >> 16].map(|v| v as f32 / 65535.0);
        for k in 0..3 {
            rgba[k][i] = c[k].powf(2.2);
        }
        rgba[3][i] = c[3];
        let Some(sid) = expanded[j] else {
            continue;
        };
        // (input order: after --hide, what the scene id came from)
        let (input, loc) = match ids {
            Some(m) => m.locate(sid),
            None => (
                sid,
                inst.and_then(|n| n.locate(sid)).map(|(k, a)| (k as u32, a)),
            ),
        };
        id[i] = (input + 1) as f32;
        if let Some((k, a)) = loc {
            instance[i] = k as f32;
            atom[i] = a as f32;
        }
        if let Some(&a) = words.get(j) {
            shadow[i] = (a & 0xFFFF) as f32 / 65535.0;
            ao[i] = if s1.ssdo_on() {
                (a >> 16) as f32 / 65535.0
            } else {
                1.0
            };
        }
        let sp = scene
            .sphere(sid)
            .ok_or_else(|| Error::Internal(format!("sphere {sid} of the id layer")))?;
        let c = glam::DVec3::new(
            sp.center[0] as f64,
            sp.center[1] as f64,
            sp.center[2] as f64,
        );
        let (x, y) = (j as u32 % w, y0 + j as u32 / w);
        let p = crate::reference::visible_point(&cam, x, y, c, sp.radius as f64);
        let nrm = (p - c).normalize_or_zero();
        for k in 0..3 {
            normal[k][i] = nrm[k] as f32;
        }
        depth[i] = (p - base).dot(cam.dir) as f32;
    }
    let [r_, g_, b_, a_] =
        <[Vec<f32>; 4]>::try_from(rgba).map_err(|_| Error::Internal("rgba".into()))?;
    let [nx, ny, nz] =
        <[Vec<f32>; 3]>::try_from(normal).map_err(|_| Error::Internal("normal".into()))?;
    let mut layers = vec![
        ("R", r_),
        ("G", g_),
        ("B", b_),
        ("A", a_),
        ("depth", depth),
        ("id", id),
        ("shadow", shadow),
        ("ao", ao),
        ("normal.X", nx),
        ("normal.Y", ny),
        ("normal.Z", nz),
    ];
    if inst.is_some() {
        layers.push(("instance", instance));
        layers.push(("atom", atom));
    }
    Ok(layers)
}

/// Everything one render run produces.
pub struct RunOutcome {
    pub stats: RunStats,
    /// The last frame's AOV image (None when it was streamed in bands:
    /// `PreparedRun::frame_streamed`).
    pub image: Option<output::AovImage>,
}

/// What a render run renders around its settings: the image kind, the
/// frames, and what its stats record says about the input.
#[derive(Clone, Copy, Debug)]
pub struct RunRequest<'a> {
    /// The input as the stats record names it.
    pub input: &'a str,
    pub aov: Aov,
    /// Unmeasured frames first.
    pub warmup: u32,
    /// Measured frames (at least 1).
    pub frames: u32,
    /// Scene load time for the stats record.
    pub load_ms: f64,
}

/// Loads nothing: renders an already loaded scene with settings, returning
/// the stats record and the AOV image.
pub fn render_run(
    ctx: &Context,
    scene: &Scene,
    settings: RenderSettings,
    req: &RunRequest,
) -> Result<RunOutcome> {
    render_run_with(ctx, scene, settings, req, false, &mut |_, _| Ok(()))
}

/// `render_run` calling `before(renderer, k)` ahead of measured frame k
/// (the benchmark moves the camera along its orbit there); with `cached`, and a light-space shadow technique,
/// the same frames again reusing its structure (`RunStats::light_cached`).
pub fn render_run_with(
    ctx: &Context,
    scene: &Scene,
    settings: RenderSettings,
    req: &RunRequest,
    cached: bool,
    before: &mut dyn FnMut(&mut Renderer, u32) -> Result<()>,
) -> Result<RunOutcome> {
    let mut run = PreparedRun::new(ctx, scene, settings, req)?;
    let frames = req.frames.max(1);
    for k in 0..frames {
        before(run.renderer(), k)?;
        run.frame(k + 1 == frames)?;
    }
    if cached && run.has_light() {
        run.start_cached()?;
        for k in 0..frames {
            before(run.renderer(), k)?;
            run.cached_frame()?;
        }
    }
    run.finish(ctx)
}

/// One run between its warm-up and its stats record: a renderer, the
/// times of its measured frames and its last image. `render_run_with`
/// measures one run at a time; `bench` keeps several and renders their
/// frames in turn, so that a slow spell of the machine falls on every run
/// it compares alike (lavapipe's frame times drift by 20 % from one second
/// to the next on a shared machine).
pub struct PreparedRun<'c> {
    r: Renderer<'c>,
    input: String,
    aov: Aov,
    samples: u32,
    tile: Option<u32>,
    load_ms: f64,
    progress: StepProgress,
    /// What a measured frame's image reads back besides colour.
    keep: crate::render::tiles::Keep,
    times: Vec<PassTimes>,
    cached: Vec<PassTimes>,
    last: Option<crate::render::tiles::Image>,
    /// The SHA-256 of the last frame's AOV image when it was streamed in
    /// bands (a tiled image: never held whole).
    streamed: Option<String>,
}

impl<'c> PreparedRun<'c> {
    /// Creates the renderer and renders the unmeasured warm-up frames
    /// (`req.frames` is the caller's to count).
    pub fn new(
        ctx: &'c Context,
        scene: &Scene,
        settings: RenderSettings,
        req: &RunRequest,
    ) -> Result<Self> {
        let RunRequest {
            input,
            aov,
            warmup,
            load_ms,
            ..
        } = *req;
        let mut settings = settings;
        settings.aovs |= matches!(aov, Aov::Shadow | Aov::Ao);
        let samples = settings.ssaa_for(aov);
        let tile = settings.tile_size;
        let r = Renderer::new_windowed(ctx, scene, settings, tile)?;
        let mut run = PreparedRun {
            r,
            input: input.to_string(),
            aov,
            samples,
            tile,
            load_ms,
            progress: StepProgress::new("rendering"),
            // (a colour image past 2^32 atoms: no LOD lists read back)
            keep: crate::render::tiles::Keep {
                vis: aov != Aov::Color,
                aov: true,
            },
            times: Vec::new(),
            cached: Vec::new(),
            last: None,
            streamed: None,
        };
        for _ in 0..warmup {
            let (r, p) = (&mut run.r, &mut run.progress);
            render_supersampled(r, samples, tile, None, &mut |d, t| p.tick(d, t))?;
        }
        Ok(run)
    }

    pub fn renderer(&mut self) -> &mut Renderer<'c> {
        &mut self.r
    }

    /// Device memory of the run's buffers.
    pub fn memory_bytes(&self) -> u64 {
        self.r.inspect().memory_by_class().values().sum()
    }

    /// Whether the active technique has a light-space structure to cache.
    pub fn has_light(&self) -> bool {
        self.r.settings().shadows != ShadowMode::None
    }

    /// Renders one measured frame; `read` keeps its image.
    pub fn frame(&mut self, read: bool) -> Result<()> {
        let (r, p) = (&mut self.r, &mut self.progress);
        let (img, t) = render_supersampled(
            r,
            self.samples,
            self.tile,
            read.then_some(self.keep),
            &mut |d, n| p.tick(d, n),
        )?;
        self.times.push(t);
        self.last = img.or(self.last.take());
        Ok(())
    }

    /// `frame`, keeping only the image's hash when the image is tiled (it
    /// is streamed through band by band: `bench` at 16384² holds no image).
    pub fn frame_hashed(&mut self, read: bool) -> Result<()> {
        if read && self.r.tile_plan(self.tile)?.len() > 1 {
            return self.frame_streamed(&mut |_| Ok(()));
        }
        self.frame(read)
    }

    /// Renders one measured frame band by band ([`render_bands`]), giving
    /// `sink` the AOV image of each band in order (the depth AOV, whose
    /// encoding spans the image, once whole: 4 bytes a pixel meanwhile);
    /// keeps the image's hash for the stats, not the image.
    pub fn frame_streamed(
        &mut self,
        sink: &mut dyn FnMut(&output::AovImage) -> Result<()>,
    ) -> Result<()> {
        let aov = self.aov;
        let mut hash = <sha2::Sha256 as sha2::Digest>::new();
        let mut depth: Vec<f32> = Vec::new();
        let (mut width, mut height) = (0, 0);
        let (r, p) = (&mut self.r, &mut self.progress);
        let t = render_bands(
            r,
            self.samples,
            self.tile,
            keep_for(aov),
            &mut |d, n| p.tick(d, n),
            &mut |band| {
                width = band.image.width;
                height += band.image.height;
                if aov == Aov::Depth {
                    depth.extend(band.image.vis.iter().map(|&k| depth_of(k)));
                    return Ok(());
                }
                let img = image_aov(&band.image, aov);
                img.hash_into(&mut hash);
                sink(&img)
            },
        )?;
        if aov == Aov::Depth {
            let img = output::depth_image(width, height, &depth);
            img.hash_into(&mut hash);
            sink(&img)?;
        }
        self.times.push(t);
        self.last = None;
        self.streamed = Some(format!("{:x}", sha2::Digest::finalize(hash)));
        Ok(())
    }

    /// Turns the light cache on and renders the frame that builds the
    /// structure the cached frames reuse (unmeasured).
    pub fn start_cached(&mut self) -> Result<()> {
        self.r.set_light_cache(true);
        self.r.render_frame()?;
        Ok(())
    }

    /// Renders one measured frame with the light cache on (after
    /// `start_cached`; without a light structure, the run's plain frame,
    /// which `bench` measures alongside the others' cached frames).
    pub fn cached_frame(&mut self) -> Result<()> {
        let t = self.r.render_frame()?;
        self.cached.push(t);
        Ok(())
    }

    /// The stats record and the last image (None when it was streamed).
    pub fn finish(mut self, ctx: &Context) -> Result<RunOutcome> {
        self.r.set_light_cache(false);
        let (image, sha) = match (self.last.take(), self.streamed.take()) {
            (Some(img), _) => {
                let image = image_aov(&img, self.aov);
                let sha = image.sha256();
                (Some(image), sha)
            }
            (None, Some(sha)) => (None, sha),
            (None, None) => return Err(Error::Internal("no image read back".into())),
        };
        let mut stats = run_stats(ctx, &self.r, &self.input, &self.times, self.load_ms, &sha);
        if !self.cached.is_empty() {
            let (passes, total_ms) = output::summarize(&self.cached);
            stats.light_cached = Some(output::CachedStats {
                passes,
                total_ms,
                frame_ms: self.cached.iter().map(|t| t.total_ms).collect(),
            });
        }
        Ok(RunOutcome { stats, image })
    }
}

/// The DESIGN.md stats record of frames `times` rendered by `r`, whose
/// last image is `image`.
pub fn run_stats(
    ctx: &Context,
    r: &Renderer,
    input: &str,
    times: &[PassTimes],
    load_ms: f64,
    image_sha256: &str,
) -> RunStats {
    let (passes, total_ms) = output::summarize(times);
    let gpu_memory = r.inspect().memory_by_class();
    let s = r.settings();
    let counts = r.inspect().instancing();
    // (a second read of the counters spheres_drawn reads: only when shown)
    if log::log_enabled!(log::Level::Info)
        && let Ok(Some(c)) = r.inspect().lod_counts()
    {
        log::info!("last frame's LOD cull kept {c:?}");
    }
    RunStats {
        device: ctx.info.name.clone(),
        driver: ctx.info.driver.clone(),
        input: input.to_string(),
        spheres: r.inspect().represented(),
        instances: counts.map(|c| c.instances),
        molecules: counts.map(|c| c.molecules),
        unique_atoms: counts.map(|c| c.unique_atoms),
        placements: counts.and_then(|c| c.placements),
        expanded: r.inspect().expanded(),
        // (a failed read-back of the cull's counters leaves the bound)
        spheres_drawn: r.inspect().spheres_drawn().unwrap_or_else(|e| {
            log::warn!("spheres drawn: {e}");
            r.inspect().represented()
        }),
        camera: output::CameraStats::of(&s.camera),
        width: s.camera.width,
        height: s.camera.height,
        frames: times.len().max(1) as u32,
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
        deep: r.inspect().deep_stats(),
        see_through: r.inspect().see_through_stats(),
        image_sha256: image_sha256.to_string(),
        light_cached: None,
        frame_ms: times.iter().map(|t| t.total_ms).collect(),
    }
}

/// The input's name in the JSON: the file, or `scene:NAME`.
pub fn input_name(args: &SceneArgs) -> String {
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
