//! Images larger than one device allocation (8K on lavapipe's 128 MiB
//! `maxStorageBufferRange`), rendered in tiles with
//! the same camera. A tile's buffers hold a window of the image: the tile
//! and a margin around it as wide as the screen-space passes reach (SSDO
//! taps, the blur, the screen-space shadow march), so every kept pixel sees
//! exactly the neighbours it sees untiled; rays and per-pixel patterns use
//! image coordinates (glsl/shared.glsl `image_px`), so a tile computes the
//! same bits. Light-space structures are built once and reused by every
//! tile (the light cache).

use super::Renderer;
use crate::camera::Window;
use crate::error::{Error, Result};
use crate::vk::{Context, PassTimes};

/// Window origins are multiples of this: the SSDO block (2), its 4x4
/// rotation pattern over blocks and the 8x8 workgroup tiles then line up
/// with the untiled image's.
pub const ALIGN: u32 = 8;

/// One tile: the pixels it keeps and the window its buffers hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub kept: Window,
    pub window: Window,
}

/// A whole image read back: colour, visibility keys and (when kept) the
/// shadow|ao AOV words, row-major.
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// RGBA8 words, or with `wide` two words (RGBA16) per pixel.
    pub color: Vec<u32>,
    pub wide: bool,
    /// Visibility keys: depth word, then the sphere's expanded index (a
    /// scene past 2^32 atoms: its slot; `wide_ids` names it).
    pub vis: Vec<u64>,
    /// A scene past 2^32 atoms (`Inspect::ids_fit` false): each pixel's
    /// expanded index + 1 (0: background), read with `Inspect::read_ids`.
    pub wide_ids: Option<Vec<u64>>,
    pub aov: Option<Vec<u32>>,
    /// Tiles rendered (1 = untiled).
    pub tiles: usize,
    /// Spheres the scene represents (the id AOV's encoding depends on it).
    pub spheres: u64,
    /// Scene ids to input indices after rules hid spheres.
    pub ids: Option<std::sync::Arc<crate::scene::paint::IdMap>>,
}

/// The most pixels one window may have on this device: the visibility
/// buffer (8 B/px plus guard words) must fit one storage buffer range and
/// its 32-bit view (2 texels/px) one texel buffer.
pub fn max_window_pixels(ctx: &Context) -> u64 {
    let l = &ctx.props.limits;
    let by_range = (l.max_storage_buffer_range as u64 / 8)
        .saturating_sub(crate::stages::raster::compute::VIS_GUARD_WORDS);
    let by_texels = l.max_texel_buffer_elements as u64 / 2;
    by_range.min(by_texels)
}

/// Tiles covering a `width` x `height` image: one whole-image tile when it
/// fits in `max_pixels` and no size is forced; else square tiles (side a
/// multiple of ALIGN) whose windows, with `margin` on every side, fit.
pub fn plan(
    width: u32,
    height: u32,
    margin: u32,
    max_pixels: u64,
    forced: Option<u32>,
) -> Result<Vec<Tile>> {
    let whole = Window {
        x: 0,
        y: 0,
        width,
        height,
    };
    if forced.is_none() && whole.pixels() <= max_pixels {
        return Ok(vec![Tile {
            kept: whole,
            window: whole,
        }]);
    }
    let side = match forced {
        Some(t) => t.max(1).div_ceil(ALIGN) * ALIGN,
        None => {
            // the window of a tile of side s spans at most s + 2 margin + ALIGN
            let fit = (max_pixels as f64).sqrt() as u64;
            let s =
                fit.saturating_sub(2 * margin as u64 + ALIGN as u64) / ALIGN as u64 * ALIGN as u64;
            if s == 0 {
                return Err(Error::DeviceLimit(format!(
                    "the screen-space passes reach {margin} px, more than a tile of this \
                     device can hold ({max_pixels} px per buffer): lower --width/--height"
                )));
            }
            s.min(u32::MAX as u64) as u32
        }
    };
    let mut tiles = Vec::new();
    for ty in (0..height).step_by(side as usize) {
        for tx in (0..width).step_by(side as usize) {
            let kept = Window {
                x: tx,
                y: ty,
                width: side.min(width - tx),
                height: side.min(height - ty),
            };
            let x0 = tx.saturating_sub(margin) / ALIGN * ALIGN;
            let y0 = ty.saturating_sub(margin) / ALIGN * ALIGN;
            let x1 = (tx as u64 + side as u64 + margin as u64).min(width as u64) as u32;
            let y1 = (ty as u64 + side as u64 + margin as u64).min(height as u64) as u32;
            let window = Window {
                x: x0,
                y: y0,
                width: x1 - x0,
                height: y1 - y0,
            };
            if window.pixels() > max_pixels {
                return Err(Error::DeviceLimit(format!(
                    "a {side} px tile with its {margin} px margin needs {} px, more than this \
                     device's {max_pixels} per buffer: use a smaller tile",
                    window.pixels()
                )));
            }
            tiles.push(Tile { kept, window });
        }
    }
    Ok(tiles)
}

/// Copies the `kept` pixels of a `window`-sized buffer into rows `y0..` of
/// an image (a band of it).
fn place<T: Copy>(dst: &mut [T], width: u32, y0: u32, tile: &Tile, src: &[T]) {
    let (k, w) = (tile.kept, tile.window);
    for y in 0..k.height {
        let sy = (k.y + y - w.y) as usize * w.width as usize + (k.x - w.x) as usize;
        let dy = (k.y + y - y0) as usize * width as usize + k.x as usize;
        dst[dy..dy + k.width as usize].copy_from_slice(&src[sy..sy + k.width as usize]);
    }
}

/// The rows of a plan: ranges of its tiles that keep the same image rows
/// (a plan lists tiles row by row).
pub fn tile_rows(tiles: &[Tile]) -> Vec<std::ops::Range<usize>> {
    let mut rows: Vec<std::ops::Range<usize>> = Vec::new();
    for (i, t) in tiles.iter().enumerate() {
        match rows.last_mut() {
            Some(r) if tiles[r.start].kept.y == t.kept.y => r.end = i + 1,
            _ => rows.push(i..i + 1),
        }
    }
    rows
}

/// What a band reads back besides colour: the visibility keys (ids,
/// depth, coverage) and the shadow|ao words. A colour image needs neither.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Keep {
    pub vis: bool,
    pub aov: bool,
}

impl Keep {
    pub const ALL: Keep = Keep {
        vis: true,
        aov: true,
    };
}

impl<'a> Renderer<'a> {
    /// A renderer for images of any size: made with a small window when
    /// the whole image cannot be one (or tiles are forced); `render_image`
    /// then sets each tile's window.
    pub fn new_windowed(
        ctx: &'a Context,
        scene: &crate::scene::Scene,
        settings: crate::settings::RenderSettings,
        forced_tile: Option<u32>,
    ) -> Result<Renderer<'a>> {
        let cam = settings.camera;
        let whole = Window::whole(&cam);
        if forced_tile.is_none() && whole.pixels() <= max_window_pixels(ctx) {
            return Renderer::new(ctx, scene, settings);
        }
        let mut s = settings;
        s.window = Some(Window {
            x: 0,
            y: 0,
            width: cam.width.min(ALIGN),
            height: cam.height.min(ALIGN),
        });
        Renderer::new(ctx, scene, s)
    }

    /// How far (pixels) the screen-space passes of this renderer's modes
    /// reach from a pixel: the margin a tile needs so it computes the
    /// untiled pixels. 0 when no screen-space pass runs.
    pub fn tile_margin(&self) -> u32 {
        let s = &self.settings;
        let outline = crate::stages::shading::outline_px(s);
        if !s.ssdo_on() {
            return outline;
        }
        let cam = &s.camera;
        let p = self.res.ssdo_params(s);
        let mut reach = p.ssdo.r_far.max(p.ssdo.r_near) as f64;
        if self.res.stages.shadows.active().is_none() {
            reach = reach.max(p.screen.f0[0] as f64);
        }
        if p.taps.per_sphere() {
            // per-sphere receivers march from a sphere's surface point
            // facing each direction: up to a diameter from the pixel
            let r = self.res.geom.radius_range().1;
            reach += 2.0 * r as f64;
        }
        let mut ppu = cam.pixels_per_unit();
        if cam.fov_deg.is_some() {
            // a world length at view distance z spans dist / z times its
            // length at the view centre: the nearest sphere sets the reach
            let (eye, dir, dist) = (cam.eye(), cam.dir, cam.eye_distance());
            let near = self.res.geom.nearest_along(eye, dir).unwrap_or(f64::MAX);
            ppu *= dist / near.max(1e-3 * dist);
        }
        let px = (reach * ppu).ceil().min(1e6) as u32;
        // + the blur's and upsample's reach, the block and rounding slack
        px + p.blur_reach_px() + outline + 2 * ALIGN
    }

    /// Whether an image read back carries its keys (`Image::vis`): asked
    /// for (`vis`), or cheap (the ids fit the keys: past 2^32 atoms naming
    /// the visible spheres reads the LOD lists back).
    fn keys_wanted(&self, vis: bool) -> bool {
        vis || self.inspect().ids_fit()
    }

    /// Renders the whole image, in tiles when one window cannot hold it on
    /// this device or `forced_tile` asks for a tile side, and reads it back.
    /// The pass times are summed over the tiles.
    pub fn render_image(&mut self, forced_tile: Option<u32>) -> Result<(Image, PassTimes)> {
        let (img, t) = self.render_image_with(forced_tile, Some(Keep::ALL), &mut |_, _| {})?;
        let img = img.ok_or_else(|| Error::Internal("render_image read nothing".into()))?;
        Ok((img, t))
    }

    /// The tiles `render_image` renders for this image.
    pub fn tile_plan(&self, forced_tile: Option<u32>) -> Result<Vec<Tile>> {
        let cam = self.settings.camera;
        plan(
            cam.width,
            cam.height,
            self.tile_margin(),
            max_window_pixels(self.ctx),
            forced_tile,
        )
    }

    /// `render_image` that reads back colour and what `read` keeps (the
    /// keys whenever they name the spheres cheaply), or an untiled frame
    /// not at all with None (measured frames before the last need no
    /// pixels; tiles are read, all of them with None), calling
    /// `on_tile(done, tiles)` after each tile.
    pub fn render_image_with(
        &mut self,
        forced_tile: Option<u32>,
        read: Option<Keep>,
        on_tile: &mut dyn FnMut(usize, usize),
    ) -> Result<(Option<Image>, PassTimes)> {
        let cam = self.settings.camera;
        let tiles = self.tile_plan(forced_tile)?;
        let aovs = self.settings.aovs;
        let wide = self.settings.look.color16;
        if tiles.len() == 1 {
            if self.settings.window.is_some() {
                self.update(|s| s.window = None)?;
            }
            let times = self.render_frame()?;
            on_tile(1, 1);
            let Some(keep) = read else {
                return Ok((None, times));
            };
            let (vis, wide_ids) = if self.keys_wanted(keep.vis) {
                self.inspect().read_keys()?
            } else {
                let n = cam.width as usize * cam.height as usize;
                (vec![crate::gpu::VIS_EMPTY; n], None)
            };
            let image = Image {
                width: cam.width,
                height: cam.height,
                color: self.inspect().read_color()?,
                wide,
                vis,
                wide_ids,
                aov: if aovs && keep.aov {
                    Some(self.inspect().read_aov()?)
                } else {
                    None
                },
                tiles: 1,
                spheres: self.inspect().represented(),
                ids: self.inspect().id_map(),
            };
            return Ok((Some(image), times));
        }
        let n = cam.width as usize * cam.height as usize;
        let read = read.unwrap_or(Keep::ALL);
        let keep = Keep {
            vis: self.keys_wanted(read.vis),
            aov: read.aov,
        };
        let mut image = Image {
            width: cam.width,
            height: cam.height,
            color: vec![0; if wide { 2 * n } else { n }],
            wide,
            vis: vec![crate::gpu::VIS_EMPTY; n],
            wide_ids: (keep.vis && !self.inspect().ids_fit()).then(|| vec![0; n]),
            aov: (aovs && keep.aov).then(|| vec![0; n]),
            tiles: tiles.len(),
            spheres: self.inspect().represented(),
            ids: self.inspect().id_map(),
        };
        let mut sum = PassTimes::default();
        let cache = self.res.stages.shadows.cache();
        // the light structure is built by the first tile, reused by the rest
        self.set_light_cache(true);
        let result = (|| {
            let mut done = 0;
            for row in tile_rows(&tiles) {
                let (band, t) = self.render_row(&tiles[row.clone()], keep)?;
                sum.add(&t);
                let at = band.y0 as usize * cam.width as usize;
                let per = if wide { 2 } else { 1 };
                image.color[per * at..per * at + band.image.color.len()]
                    .copy_from_slice(&band.image.color);
                image.vis[at..at + band.image.vis.len()].copy_from_slice(&band.image.vis);
                if let (Some(a), Some(b)) = (image.wide_ids.as_mut(), &band.image.wide_ids) {
                    a[at..at + b.len()].copy_from_slice(b);
                }
                if let (Some(a), Some(b)) = (image.aov.as_mut(), &band.image.aov) {
                    a[at..at + b.len()].copy_from_slice(b);
                }
                done += row.len();
                on_tile(done, tiles.len());
            }
            Ok::<_, Error>(())
        })();
        self.set_light_cache(cache);
        result?;
        Ok((Some(image), sum))
    }

    /// Renders one row of a plan's tiles (`tile_rows`) into a band: the
    /// image's rows those tiles keep, every column, reading back colour and
    /// what `keep` asks for (the rest left empty). The caller sets the
    /// light cache (the first tile builds the light structure).
    pub fn render_row(&mut self, tiles: &[Tile], keep: Keep) -> Result<(Band, PassTimes)> {
        let cam = self.settings.camera;
        let wide = self.settings.look.color16;
        let first = tiles
            .first()
            .ok_or_else(|| Error::Internal("an empty row of tiles".into()))?;
        let (y0, rows) = (first.kept.y, first.kept.height);
        let n = cam.width as usize * rows as usize;
        let aovs = keep.aov && self.settings.aovs;
        let mut image = Image {
            width: cam.width,
            height: rows,
            color: vec![0; if wide { 2 * n } else { n }],
            wide,
            vis: if keep.vis {
                vec![crate::gpu::VIS_EMPTY; n]
            } else {
                Vec::new()
            },
            wide_ids: (keep.vis && !self.inspect().ids_fit()).then(|| vec![0; n]),
            aov: aovs.then(|| vec![0; n]),
            tiles: tiles.len(),
            spheres: self.inspect().represented(),
            ids: self.inspect().id_map(),
        };
        let mut sum = PassTimes::default();
        for tile in tiles {
            self.set_tile(tile.window, tile.kept)?;
            let t = self.render_frame()?;
            sum.add(&t);
            if let (Some(c), Some(d)) = (self.inspect().lod_counts()?, self.tiles_drawn.as_mut()) {
                *d += c.camera_spheres as u64;
            }
            let color = self.inspect().read_color()?;
            if wide {
                place::<[u32; 2]>(
                    bytemuck::cast_slice_mut(&mut image.color),
                    cam.width,
                    y0,
                    tile,
                    bytemuck::cast_slice(&color),
                );
            } else {
                place(&mut image.color, cam.width, y0, tile, &color);
            }
            if keep.vis {
                let (vis, wide_ids) = self.inspect().read_keys()?;
                place(&mut image.vis, cam.width, y0, tile, &vis);
                if let (Some(a), Some(b)) = (image.wide_ids.as_mut(), wide_ids) {
                    place(a, cam.width, y0, tile, &b);
                }
            }
            if let Some(a) = image.aov.as_mut() {
                place(a, cam.width, y0, tile, &self.inspect().read_aov()?);
            }
        }
        Ok((Band { y0, image }, sum))
    }
}

impl Image {
    /// Each pixel's visible sphere as an index in expanded order (None:
    /// background), past 2^32 atoms too.
    pub fn expanded_ids(&self) -> Vec<Option<u64>> {
        match &self.wide_ids {
            Some(w) => w.iter().map(|&v| v.checked_sub(1)).collect(),
            None => crate::output::ids_from_vis(&self.vis)
                .into_iter()
                .map(|i| i.map(u64::from))
                .collect(),
        }
    }
}

/// Rows `y0..y0 + image.height` of an image (all its columns).
pub struct Band {
    pub y0: u32,
    pub image: Image,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image_once_with_aligned_windows() {
        for (w, h, m, t) in [(100, 70, 13, 32), (64, 64, 0, 8), (1000, 9, 40, 24)] {
            let tiles = plan(w, h, m, u64::MAX, Some(t)).unwrap();
            let mut seen = vec![0u8; (w * h) as usize];
            for tl in &tiles {
                assert_eq!(tl.window.x % ALIGN, 0);
                assert_eq!(tl.window.y % ALIGN, 0);
                assert!(
                    tl.window.fits(
                        &crate::camera::Camera::new(
                            glam::DVec3::ZERO,
                            glam::DVec3::NEG_Z,
                            glam::DVec3::Y,
                            1.0,
                            None,
                            w,
                            h
                        )
                        .unwrap()
                    )
                );
                let (k, wi) = (tl.kept, tl.window);
                // the margin is there wherever the image goes on
                assert!(k.x - wi.x >= m.min(k.x));
                assert!(k.y - wi.y >= m.min(k.y));
                assert!(wi.x + wi.width >= (k.x + k.width + m).min(w));
                assert!(wi.y + wi.height >= (k.y + k.height + m).min(h));
                for y in k.y..k.y + k.height {
                    for x in k.x..k.x + k.width {
                        seen[(y * w + x) as usize] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "{w}x{h} tile {t}");
        }
    }

    #[test]
    fn a_fitting_image_is_one_tile_and_a_hopeless_margin_an_error() {
        let t = plan(640, 480, 50, 640 * 480, None).unwrap();
        assert_eq!(t.len(), 1);
        assert_eq!(t[0].window.pixels(), 640 * 480);
        let t = plan(7680, 4320, 50, 16_777_152, None).unwrap();
        assert!(t.len() > 1 && t.iter().all(|t| t.window.pixels() <= 16_777_152));
        let e = plan(7680, 4320, 5000, 16_777_152, None).unwrap_err();
        assert!(e.to_string().contains("reach 5000 px"), "{e}");
    }
}
