//! See-through spheres (alpha below 1, DESIGN.md "Colour, selections and
//! translucency"): exact order-independent transparency in the camera view
//! through per-pixel fragment lists, built with the deep shadow lists'
//! count -> allocate -> fill machinery in the camera's view:
//!
//! - `oit_count`: every see-through sphere visits its footprint (the
//!   band skeleton of glsl/bands.glsl, exact ray-sphere test per pixel)
//!   and counts a fragment per pixel where its front hit lies in front of
//!   the opaque surface (the raster drew only opaque spheres);
//! - `oit_alloc`: per 8x8 pixel tile (one invocation each), a running sum
//!   of the counts and one pool `atomicAdd`: each pixel's fragments are
//!   contiguous from its head;
//!   a tile that does not fit is flagged, the pool grown and the frame
//!   rendered again (as the deep lists do);
//! - `oit_fill`: the same enumeration writing (depth key, sphere id);
//! - `shade` takes each pixel's fragments in (depth, id) order (selection
//!   scans, each keeping the least 8 after the last taken) until the
//!   transmittance is below 1/1024, and composites them, lit, front to back
//!   over the opaque surface.
//!
//! Host memory: nothing. Device memory: 16 B per pixel (count, cursor,
//! head and count again: the pair fill and shade read with one fetch) and
//! 8 B per fragment of the pool, plus band jobs.

use crate::error::{Error, Result};
use crate::gpu::blocks::{OitAllocPush, OitPickPush, OitSplatPush};
use crate::gpu::consts::{
    BATCH_PART_SLOTS, F_ARGS, F_BANDS_FULL, F_BANDS_REQ, F_BANDS_RUN, F_COMPOSITE_CUT,
    F_FILL_ERRORS, F_INLINED, F_MAX, F_OVERFLOW, F_PICK_ARGS, F_PIXELS, F_TOTAL, LOD_ARGS,
    LOD_BATCH_ARGS, LOD_BATCHES,
};
use crate::passes::bands::{BandArgs, BandCounters, BandJob, BandPipelines, JobList};
use crate::passes::scene::{SCENE_ATTRIBUTES, SCENE_GEOMETRY, SceneBuffers};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::stages::raster::compute::{CAM_BATCH_MAX_ROWS, LodView};
use crate::stages::raster::lod::LightRegion;
use crate::vk::pipeline::{Binding, PipelineDesc, ro, rw, texel, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder, Recorder};
use ash::vk;
use serde::{Deserialize, Serialize};

/// u32 guard words after every per-pixel and pool buffer.
pub const GUARD_WORDS: u64 = 64;
pub const GUARD_PATTERN: u32 = 0x0175_EE00;
/// Counter words (stats 0..15, band jobs 16..23).
pub(crate) const COUNTER_WORDS: u64 = 32;
/// Footprints above this many pixels go to band jobs (the rasterizer's
/// CPU threshold: the lists are a camera raster too).
const BIG_AREA: u32 = 1024;
/// Band jobs per frame at first (past them a sphere's own invocation
/// visits it and the frame is drawn again with a list twice as long).
const JOB_CAPACITY: u32 = 1 << 18;
/// Initial pool: fragments per pixel of the window.
const INITIAL_PER_PIXEL: u64 = 2;

const LAYOUT: BandCounters = BandCounters {
    job_capacity: JOB_CAPACITY,
    requested: F_BANDS_REQ,
    run: F_BANDS_RUN,
    args: F_ARGS,
};

/// A frame's fragment lists as read back: per pixel its count and head
/// (F_NONE: no fragments, or its tile did not fit), and the pool's
/// (depth key bits, sphere id) pairs.
pub struct FragmentLists {
    pub counts: Vec<u32>,
    pub heads: Vec<u32>,
    pub frags: Vec<[u32; 2]>,
}

/// The fragment lists of a frame, or of a tiled image's tiles together
/// (the JSON's `see_through`).
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct SeeThroughStats {
    /// Fragments in front of the opaque surfaces.
    pub fragments: u64,
    /// Pixels showing one or more.
    pub pixels: u64,
    /// Most fragments of one pixel.
    pub max_per_pixel: u64,
    /// Fragments the pool holds.
    pub capacity: u64,
    /// Device bytes of the lists (per-pixel words and the pool).
    pub bytes: u64,
    /// A frame did not fit and was rendered again with a larger pool.
    pub overflowed: bool,
}

impl SeeThroughStats {
    /// Adds a tile's frame: counts summed (a tile's margin, shared with its
    /// neighbours, counted in each), the largest pool and pixel.
    fn add(&mut self, tile: &SeeThroughStats) {
        self.fragments += tile.fragments;
        self.pixels += tile.pixels;
        self.max_per_pixel = self.max_per_pixel.max(tile.max_per_pixel);
        self.capacity = self.capacity.max(tile.capacity);
        self.bytes = self.bytes.max(tile.bytes);
        self.overflowed |= tile.overflowed;
    }
}

/// The per-pixel words and the pool, sized for a window.
struct Lists {
    pixels: u64,
    capacity: u32,
    counts: Buffer,
    cursor: Buffer,
    heads: Buffer,
    frags: Buffer,
}

fn guarded(ctx: &Context, name: &str, words: u64) -> Result<Buffer> {
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
    Buffer::guarded(ctx, name, words, GUARD_WORDS, GUARD_PATTERN, usage)
}

impl Lists {
    fn new(ctx: &Context, pixels: u64, capacity: u32) -> Result<Self> {
        let counts = ctx.guard(guarded(ctx, "fragment counts", pixels)?);
        let cursor = ctx.guard(guarded(ctx, "fragment cursors", pixels)?);
        let heads = ctx.guard(guarded(ctx, "fragment heads", 2 * pixels)?);
        let frags = guarded(ctx, "fragments", capacity as u64 * 2)?;
        Ok(Lists {
            pixels,
            capacity,
            counts: counts.keep(),
            cursor: cursor.keep(),
            heads: heads.keep(),
            frags,
        })
    }

    fn buffers(&self) -> [(&Buffer, u64); 4] {
        [
            (&self.counts, self.pixels),
            (&self.cursor, self.pixels),
            (&self.heads, 2 * self.pixels),
            (&self.frags, self.capacity as u64 * 2),
        ]
    }

    fn bytes(&self) -> u64 {
        self.buffers().iter().map(|(b, _)| b.size).sum()
    }

    fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.counts,
            &mut self.cursor,
            &mut self.heads,
            &mut self.frags,
        ] {
            b.destroy(ctx);
        }
    }
}

/// The most fragments one pool can hold on this device: two words each in
/// one storage buffer, which shade also reads as RG32UI texels.
fn max_capacity(ctx: &Context) -> u64 {
    let limits = &ctx.props.limits;
    let range = limits.max_storage_buffer_range as u64;
    let storage = (range / 4).saturating_sub(GUARD_WORDS) / 2;
    storage.min((limits.max_texel_buffer_elements as u64).saturating_sub(GUARD_WORDS / 2))
}

/// Bytes of the inline bits of `ids` ids.
fn inline_bytes(ids: u32) -> u64 {
    (ids as u64).div_ceil(32).max(1) * 4
}

/// The picked batches of the camera's LOD lists (their list positions)
/// and the blocks of stored atoms with see-through ones (a bit each).
struct Pick {
    picked: Buffer,
    blocks: Buffer,
    /// Per part of a picked batch (the per-batch splat): the atoms its
    /// count found may make fragments, which its fill visits.
    masks: Buffer,
    /// Entries `picked` holds.
    room: u32,
}

impl Pick {
    fn destroy(&mut self, ctx: &Context) {
        self.picked.destroy(ctx);
        self.blocks.destroy(ctx);
        self.masks.destroy(ctx);
    }
}

/// The splat's count and fill per picked batch (glsl/oit_splat.comp
/// BATCHES, orthographic cameras: raster.comp's bound on the window), as
/// per-sphere pipelines: their bands are the per-slot ones'.
struct Batches([ComputePipeline; 2]);

impl Batches {
    fn destroy(&mut self, ctx: &Context) {
        for p in &mut self.0 {
            p.destroy(ctx);
        }
    }
}

/// Invocations of the per-batch splat per batch of a scene of this
/// SCENE_SPEC (glsl/batch_parts.glsl).
fn batch_parts(spec: u32) -> u32 {
    ((1u32 << (spec >> 8)) / BATCH_PART_SLOTS).max(1)
}

/// The splat's bindings (count and fill, per slot or per batch).
fn splat_bindings() -> Vec<Binding> {
    [
        &[
            uniform("GlobalsBlock"),
            texel("visWordTex", vk::Format::R32_UINT),
            rw("Count"),
            rw("Cursor"),
            texel("oitHeadTex", vk::Format::R32G32_UINT),
            wo("Frags"),
            rw("Counters"),
            rw("Jobs"),
            rw("Inline"),
            texel("orderTex", vk::Format::R32_UINT),
            texel("hizTex", vk::Format::R32_UINT),
            rw("Masks"),
            rw("Region"),
        ][..],
        &SCENE_GEOMETRY,
        &SCENE_ATTRIBUTES,
    ]
    .concat()
}

fn splat_desc<'a>(name: &'a str, bindings: &'a [Binding], scene: u32) -> PipelineDesc<'a> {
    PipelineDesc {
        name,
        shader: spirv::OIT_SPLAT_COMP,
        bindings,
        push_size: std::mem::size_of::<OitSplatPush>() as u32,
        local_size: LOCAL_SIZE,
        constants: &[],
        scene,
    }
}

/// The stage: made the first time a frame has see-through spheres.
pub struct SeeThrough {
    /// The splat shader counting and filling, each for orthographic and
    /// perspective cameras (specialization constants 3 and 2).
    count: [BandPipelines; 2],
    fill: [BandPipelines; 2],
    args: BandArgs,
    alloc: ComputePipeline,
    /// glsl/oit_pick.comp's modes 0, 1, 2.
    pickers: [ComputePipeline; 3],
    /// Its buffers (frames that draw the LOD lists: `ensure_picks`).
    picks: Option<Pick>,
    /// The scene's SCENE_SPEC (pipelines made later).
    scene: u32,
    /// The per-batch splat (made with the picks).
    batches: Option<Batches>,
    /// Whether the last frame recorded ran it.
    ran_batches: std::cell::Cell<bool>,
    /// Test hook: per slot whatever the camera.
    per_slot: std::cell::Cell<bool>,
    counters: Buffer,
    jobs: JobList,
    /// A bit per id a frame may name (`ensure_ids`).
    inline_bits: Buffer,
    /// Ids `inline_bits` covers.
    inline_ids: u32,
    /// Whether a bit may be set (a frame's count set some: F_INLINED; a
    /// new buffer): the next frame clears them first.
    inline_dirty: std::cell::Cell<bool>,
    lists: Option<Lists>,
    /// The last frame's lists.
    pub stats: Option<SeeThroughStats>,
    /// The tiles of the image being rendered so far (None: not tiled).
    tiles: Option<SeeThroughStats>,
    retried: bool,
}

/// What the lists read in a frame.
pub struct SeeThroughInputs<'a> {
    pub globals: &'a Buffer,
    pub scene: &'a SceneBuffers,
    /// The opaque visibility buffer.
    pub vis: &'a Buffer,
    /// The camera raster's sphere order (runs front to back): neighbours
    /// in space are visited together (1M capsid, half see-through: count
    /// 190 -> 120 ms, fill 470 -> 365 ms against input order).
    pub order: &'a Buffer,
    pub perspective: bool,
    /// A frame that draws the LOD lists: the camera's early and late
    /// lists, whose batches with see-through atoms are visited in place of
    /// every sphere (the lists name what the camera may see, at its level
    /// of detail).
    pub lod: Option<[LodView<'a>; 2]>,
    /// With `lod`: the camera's depth tiles of this frame's final opaque
    /// image (their buffer, shift and 2-px tiles' first word): a sphere
    /// they hide whole makes no fragment and is not visited.
    pub tiles: Option<(&'a Buffer, u32, u32)>,
    /// With `lod`, where the key light culls after the fragments: its
    /// region and receiver words, emptied here; the count adds each
    /// sphere that made a fragment.
    pub receivers: Option<LightRegion<'a>>,
}

/// What `coverage` and `shade` read of them (and the counters, where
/// shade counts the composites a loop limit cut: F_COMPOSITE_CUT).
#[derive(Clone, Copy)]
pub struct SeeThroughOutputs<'a> {
    pub counts: &'a Buffer,
    pub heads: &'a Buffer,
    pub frags: &'a Buffer,
    pub counters: &'a Buffer,
}

impl SeeThrough {
    /// `ids`: the sphere ids its inline bits cover at first
    /// ([`SeeThrough::ensure_ids`]); `band_jobs`: the band job list's
    /// first length (None: 2^18).
    pub fn new(ctx: &Context, scene: u32, ids: u32, band_jobs: Option<u32>) -> Result<Self> {
        let splat = |mode: u32, name: &str| -> Result<[BandPipelines; 2]> {
            let bindings = splat_bindings();
            let desc = splat_desc(name, &bindings, scene);
            // constants 2 (PERSP) and 3 (MODE)
            let ortho = ctx.guard(BandPipelines::new(ctx, &desc, &[0, mode])?);
            let persp = BandPipelines::new(ctx, &desc, &[1, mode])?;
            Ok([ortho.keep(), persp])
        };
        let count = ctx.guard(splat(0, "oit count")?);
        let fill = ctx.guard(splat(1, "oit fill")?);
        let alloc = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "oit alloc",
                shader: spirv::OIT_ALLOC_COMP,
                bindings: &[
                    uniform("GlobalsBlock"),
                    ro("Count"),
                    wo("Head"),
                    rw("Counters"),
                ],
                push_size: std::mem::size_of::<OitAllocPush>() as u32,
                local_size: 64,
                constants: &[],
                scene: 0,
            },
        )?);
        let picker = |mode: u32| {
            let bindings = [
                &[
                    uniform("GlobalsBlock"),
                    ro("LodCounters"),
                    rw("Blocks"),
                    wo("Picked"),
                    rw("Counters"),
                ][..],
                &SCENE_GEOMETRY,
                &SCENE_ATTRIBUTES,
            ]
            .concat();
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name: "oit pick",
                    shader: spirv::OIT_PICK_COMP,
                    bindings: &bindings,
                    push_size: std::mem::size_of::<OitPickPush>() as u32,
                    local_size: LOCAL_SIZE,
                    constants: &[mode],
                    scene,
                },
            )
        };
        let pick0 = ctx.guard(picker(0)?);
        let pick1 = ctx.guard(picker(1)?);
        let pick2 = ctx.guard(picker(2)?);
        let args = ctx.guard(BandArgs::new(ctx, "oit band args")?);
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER;
        let counters = ctx.guard(Buffer::guarded(
            ctx,
            "fragment counters",
            COUNTER_WORDS,
            GUARD_WORDS,
            GUARD_PATTERN,
            usage,
        )?);
        let jobs = ctx.guard(JobList::new(
            ctx,
            "oit band jobs",
            band_jobs.unwrap_or(JOB_CAPACITY),
        )?);
        let inline_bits = Buffer::storage(ctx, "oit inline spheres", inline_bytes(ids))?;
        Ok(SeeThrough {
            count: count.keep(),
            fill: fill.keep(),
            args: args.keep(),
            alloc: alloc.keep(),
            pickers: [pick0.keep(), pick1.keep(), pick2.keep()],
            picks: None,
            scene,
            batches: None,
            ran_batches: std::cell::Cell::new(false),
            per_slot: std::cell::Cell::new(false),
            counters: counters.keep(),
            jobs: jobs.keep(),
            inline_bits,
            inline_ids: ids,
            inline_dirty: std::cell::Cell::new(true),
            lists: None,
            stats: None,
            tiles: None,
            retried: false,
        })
    }

    /// Lists for a window of `pixels` (made, or remade when the window
    /// changed; the pool keeps its size or starts at 2 per pixel).
    pub fn prepare(&mut self, ctx: &Context, pixels: u64, initial: Option<u32>) -> Result<()> {
        if self.lists.as_ref().is_some_and(|l| l.pixels == pixels) {
            return Ok(());
        }
        let capacity = match (&self.lists, initial) {
            (Some(l), _) => l.capacity as u64,
            (None, Some(n)) => n.max(1) as u64,
            (None, None) => (pixels * INITIAL_PER_PIXEL).max(1024),
        }
        .min(max_capacity(ctx));
        ctx.wait_idle();
        let lists = Lists::new(ctx, pixels, capacity as u32)?;
        if let Some(mut old) = self.lists.replace(lists) {
            old.destroy(ctx);
        }
        Ok(())
    }

    /// Makes the inline bits cover `ids` (a frame's id range: the LOD
    /// lists' slots where it draws them; they grow with the lists).
    pub fn ensure_ids(&mut self, ctx: &Context, ids: u32) -> Result<()> {
        if ids <= self.inline_ids {
            return Ok(());
        }
        ctx.wait_idle();
        let bits = Buffer::storage(ctx, "oit inline spheres", inline_bytes(ids))?;
        let mut old = std::mem::replace(&mut self.inline_bits, bits);
        old.destroy(ctx);
        self.inline_ids = ids;
        self.inline_dirty.set(true);
        Ok(())
    }

    /// Makes the pick buffers hold `room` batches and blocks of `stored`
    /// atoms (a frame that draws the LOD lists; they grow with them).
    pub fn ensure_picks(&mut self, ctx: &Context, room: u32, stored: u64) -> Result<()> {
        if self.batches.is_none() {
            let bindings = splat_bindings();
            let desc = splat_desc("oit batches", &bindings, self.scene);
            // constants 2 (PERSP), 3 (MODE), 4 (BATCHES)
            let count = ctx.guard(BandPipelines::pass(ctx, &desc, 0, &[0, 0, 1])?);
            let fill = BandPipelines::pass(ctx, &desc, 0, &[0, 1, 1])?;
            self.batches = Some(Batches([count.keep(), fill]));
        }
        let words = stored.div_ceil(64 * 32).max(1);
        if self
            .picks
            .as_ref()
            .is_some_and(|p| p.room >= room && p.blocks.size >= words * 4)
        {
            return Ok(());
        }
        ctx.wait_idle();
        let picked = ctx.guard(Buffer::storage(
            ctx,
            "oit picked batches",
            room.max(1) as u64 * 4,
        )?);
        let blocks = ctx.guard(Buffer::storage(ctx, "oit see-through blocks", words * 4)?);
        let parts = batch_parts(self.scene) as u64;
        let masks = Buffer::storage(ctx, "oit part masks", room.max(1) as u64 * parts * 4)?;
        if let Some(mut old) = self.picks.replace(Pick {
            picked: picked.keep(),
            blocks: blocks.keep(),
            masks,
            room,
        }) {
            old.destroy(ctx);
        }
        Ok(())
    }

    fn lists(&self) -> Result<&Lists> {
        self.lists
            .as_ref()
            .ok_or_else(|| Error::Internal("see-through lists used before prepare".into()))
    }

    /// What coverage and shade read.
    pub fn outputs(&self) -> Result<SeeThroughOutputs<'_>> {
        let l = self.lists()?;
        Ok(SeeThroughOutputs {
            counts: &l.counts,
            heads: &l.heads,
            frags: &l.frags,
            counters: &self.counters,
        })
    }

    /// `oit_count`, `oit_alloc`, `oit_fill`. Returns whether the count
    /// emptied the light's region and added its receivers (`io.receivers`
    /// on a frame that draws the LOD lists).
    pub fn record(
        &self,
        rec: &mut Recorder,
        io: &SeeThroughInputs,
        size: (u32, u32),
    ) -> Result<bool> {
        let l = self.lists()?;
        let pixels = size.0 as u64 * size.1 as u64;
        if pixels != l.pixels {
            return Err(Error::Internal("see-through lists of another size".into()));
        }
        let mut bufs = vec![
            ("GlobalsBlock", io.globals),
            ("visWordTex", io.vis),
            ("Count", &l.counts),
            ("Cursor", &l.cursor),
            ("oitHeadTex", &l.heads),
            ("Frags", &l.frags),
            ("Counters", &self.counters),
            ("Jobs", &self.jobs.buf),
            ("Inline", &self.inline_bits),
        ];
        // What the fragments visit: every sphere in the camera's order, or
        // in a frame that draws the LOD lists the camera's listed batches
        // that hold see-through atoms (picked first: a batch's slots are
        // ids, as the raster's), dispatched indirectly
        let shift = io.scene.spec >> 8;
        let (order, sphere_count, indirect, pick) = match (&io.lod, &self.picks) {
            // (the static table's slots now: made by the first frame that
            // draws every atom)
            (None, _) => (io.order, io.scene.slots, None, None),
            (Some(views), Some(pick)) => {
                if views.iter().any(|v| 2 * v.capacity > pick.room) {
                    return Err(Error::Internal("see-through pick list too short".into()));
                }
                let args = (&self.counters, F_PICK_ARGS as u64 * 4);
                (
                    &pick.picked,
                    ((pick.room as u64) << shift).min(u32::MAX as u64) as u32,
                    Some(args),
                    Some((views, pick)),
                )
            }
            (Some(_), None) => {
                return Err(Error::Internal(
                    "see-through pick buffers were not made".into(),
                ));
            }
        };
        bufs.push(("orderTex", order));
        // Per picked batch: an orthographic camera with the final image's
        // tiles (any texel buffer bound where none are read).
        let batches = match (&self.batches, io.tiles) {
            (Some(b), Some(t))
                if pick.is_some()
                    && !io.perspective
                    && size.1 <= CAM_BATCH_MAX_ROWS
                    && !self.per_slot.get() =>
            {
                Some((b, t))
            }
            _ => None,
        };
        self.ran_batches.set(batches.is_some());
        let tiles = batches.map(|b| b.1);
        bufs.push(("hizTex", tiles.map_or(io.vis, |t| t.0)));
        bufs.push(("Masks", pick.map_or(&self.inline_bits, |(_, p)| &p.masks)));
        // (the count adds receivers only on instanced scenes)
        let receivers = io.receivers.filter(|_| pick.is_some());
        bufs.push(("Region", receivers.map_or(&self.inline_bits, |r| r.region)));
        bufs.extend(io.scene.geometry());
        bufs.extend(io.scene.attributes());
        let push = OitSplatPush {
            sphere_count,
            big_area: BIG_AREA,
            job_capacity: self.jobs.capacity(),
            capacity: l.capacity,
            hiz_shift: tiles.map_or(0, |t| t.1),
            micro_base: tiles.map_or(0, |t| t.2),
            receivers: receivers.is_some() as u32,
            receiver_shift: receivers.map_or(0, |r| r.shift),
            slack: receivers.map_or(0.0, |r| r.slack),
        };
        let ids = io.scene.frame_slots();
        if self.inline_ids < ids {
            return Err(Error::Internal("see-through inline bits too short".into()));
        }
        let view = io.perspective as usize;
        let layout = self.jobs.layout(LAYOUT);
        // count and fill: one enumeration, two modes
        let job = |spheres, bands| BandJob {
            spheres,
            bands,
            push: &push,
            bindings: &bufs,
            sphere_count,
            indirect,
            counters: &self.counters,
            layout: &layout,
        };
        rec.pass("oit_count", |p| {
            p.fill(&l.counts, pixels * 4, 0);
            p.fill(&l.cursor, pixels * 4, 0);
            p.fill(&self.counters, COUNTER_WORDS * 4, 0);
            if self.inline_dirty.replace(false) {
                p.fill(&self.inline_bits, inline_bytes(ids), 0);
            }
            if let Some((views, pick)) = pick {
                self.pick_steps(p, io, views, pick, batches.is_some());
            }
            if let Some(r) = &receivers {
                r.empty(p);
            }
            let spheres = batches.map_or(&self.count[view].spheres, |b| &(b.0).0[0]);
            self.args.steps(p, &job(spheres, &self.count[view].bands));
            Ok(())
        })?;
        rec.pass("oit_alloc", |p| {
            p.dispatch(
                &self.alloc,
                &OitAllocPush {
                    capacity: l.capacity,
                },
                Grid::Groups([(size.0.div_ceil(8) * size.1.div_ceil(8)).div_ceil(64), 1, 1]),
                &[
                    ("GlobalsBlock", io.globals),
                    ("Count", &l.counts),
                    ("Head", &l.heads),
                    ("Counters", &self.counters),
                ],
            );
            Ok(())
        })?;
        rec.pass("oit_fill", |p| {
            let spheres = batches.map_or(&self.fill[view].spheres, |b| &(b.0).0[1]);
            self.args.steps(p, &job(spheres, &self.fill[view].bands));
            Ok(())
        })?;
        Ok(receivers.is_some())
    }

    /// The picks of `oit_count` (glsl/oit_pick.comp): the blocks of stored
    /// atoms with see-through ones, the camera lists' batches over them,
    /// the splat's dispatch arguments.
    fn pick_steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        io: &SeeThroughInputs<'b>,
        views: &[LodView<'b>; 2],
        pick: &'b Pick,
        batches: bool,
    ) {
        let mut bufs = vec![
            ("GlobalsBlock", io.globals),
            ("LodCounters", views[0].counters),
            ("Blocks", &pick.blocks),
            ("Picked", &pick.picked),
            ("Counters", &self.counters),
        ];
        bufs.extend(io.scene.geometry());
        bufs.extend(io.scene.attributes());
        let stored = (io.scene.colors.size / 4) as u32;
        let push = OitPickPush {
            list_base: 0,
            list_word: 0,
            capacity: stored,
            room: pick.room,
            per_batch: if batches {
                batch_parts(io.scene.spec)
            } else {
                1 << (io.scene.spec >> 8)
            },
        };
        p.fill(&pick.blocks, pick.blocks.size, 0);
        p.dispatch(
            &self.pickers[0],
            &push,
            Grid::Invocations(stored as u64),
            &bufs,
        );
        for v in views {
            let push = OitPickPush {
                list_base: v.base,
                list_word: v.words + LOD_BATCHES,
                capacity: v.capacity,
                ..push
            };
            // (at least an invocation per listed batch: lod_args.comp)
            let at = v.args_offset + ((LOD_BATCH_ARGS - LOD_ARGS) * 4) as u64;
            p.dispatch(
                &self.pickers[1],
                &push,
                Grid::Indirect(v.counters, at),
                &bufs,
            );
        }
        p.dispatch(&self.pickers[2], &push, Grid::Groups([1, 1, 1]), &bufs);
    }

    /// The frame's counter words.
    pub fn read_counters(&self, ctx: &Context) -> Result<Vec<u32>> {
        self.counters.download_pod(ctx, 0, COUNTER_WORDS)
    }

    /// The counters the host reads after each frame (buffer, words).
    pub fn readback(&self) -> (&Buffer, u64) {
        (&self.counters, COUNTER_WORDS)
    }

    /// From the frame's copy of its counters ([`Self::readback`]): on
    /// overflow grows the pool to what the frame needs (plus 1/8) so it
    /// can be rendered again.
    pub fn after_frame(&mut self, ctx: &Context, c: &[u32]) -> Result<bool> {
        if c.len() < COUNTER_WORDS as usize {
            self.inline_dirty.set(true);
            return Err(Error::Internal("see-through counters missing".into()));
        }
        if c[F_INLINED as usize] != 0 {
            self.inline_dirty.set(true);
        }
        // (first: a visit the loop limit cut may also have filled outside
        // its run)
        if c[F_BANDS_FULL as usize] != 0 {
            self.jobs.grow(ctx, "see-through")?;
            return Ok(true);
        }
        if c[F_FILL_ERRORS as usize] != 0 {
            return Err(Error::Internal(format!(
                "see-through fill wrote {} fragments outside their runs",
                c[F_FILL_ERRORS as usize]
            )));
        }
        // (a frame drawn again with a larger pool is checked then)
        let cut = c[F_COMPOSITE_CUT as usize];
        if cut != 0 && c[F_OVERFLOW as usize] == 0 {
            return Err(Error::DeviceLimit(format!(
                "see-through pixels of up to {} fragments: {cut} pixels are more than this device \
                 composites in one shader invocation; give the see-through spheres a higher alpha \
                 or make fewer of them see-through",
                c[F_MAX as usize]
            )));
        }
        let (capacity, bytes, pixels) = {
            let l = self.lists()?;
            (l.capacity, l.bytes(), l.pixels)
        };
        let overflowed = c[F_OVERFLOW as usize] != 0;
        let needed = c[F_TOTAL as usize] as u64;
        self.stats = Some(SeeThroughStats {
            fragments: needed,
            pixels: c[F_PIXELS as usize] as u64,
            max_per_pixel: c[F_MAX as usize] as u64,
            capacity: capacity as u64,
            bytes,
            overflowed: overflowed || self.retried,
        });
        if !overflowed {
            self.retried = false;
            if let (Some(t), Some(s)) = (self.tiles.as_mut(), self.stats.as_ref()) {
                t.add(s);
            }
            return Ok(false);
        }
        let max = max_capacity(ctx);
        if needed > max {
            return Err(Error::DeviceLimit(format!(
                "see-through spheres make {needed} fragments in front of the opaque ones, more than \
                 the {max} one device buffer holds: render in tiles (--tile-size) or make fewer \
                 spheres see-through"
            )));
        }
        let want = (needed + needed / 8 + 1).min(max) as u32;
        ctx.wait_idle();
        let lists = Lists::new(ctx, pixels, want)?;
        if let Some(mut old) = self.lists.replace(lists) {
            old.destroy(ctx);
        }
        self.retried = true;
        Ok(true)
    }

    /// Test hook: at most `jobs` band jobs a frame (0: the list's
    /// length), from the next frame.
    pub fn set_job_limit(&self, jobs: u32) {
        self.jobs.set_limit(if jobs == 0 { u32::MAX } else { jobs });
    }

    /// Whether the last frame recorded visited the picked batches per
    /// batch (an orthographic camera's LOD lists), testing each atom
    /// against the final opaque image's depth tiles.
    pub fn ran_per_batch(&self) -> bool {
        self.ran_batches.get()
    }

    /// Test hook: from the next frame, the picked batches are visited per
    /// slot (`on`) whatever the camera, as a perspective one's are.
    pub fn set_per_slot(&self, on: bool) {
        self.per_slot.set(on);
    }

    /// Entries of the band job list (grown where a frame asked more).
    pub fn job_capacity(&self) -> u32 {
        self.jobs.capacity()
    }

    /// Frames from now on are tiles of one image (`first`: its first tile
    /// starts the sums), or whole images (`tile` false).
    pub fn set_tiled(&mut self, tile: bool, first: bool) {
        if !tile {
            self.tiles = None;
        } else if first || self.tiles.is_none() {
            self.tiles = Some(SeeThroughStats::default());
        }
    }

    /// The lists of the image: its tiles' together when tiled, else the
    /// last frame's.
    pub fn image_stats(&self) -> Option<SeeThroughStats> {
        self.tiles.clone().or_else(|| self.stats.clone())
    }

    /// Device bytes: the lists, counters and band-job scratch.
    pub fn memory_bytes(&self) -> u64 {
        self.lists.as_ref().map_or(0, Lists::bytes)
            + self.counters.size
            + self.jobs.buf.size
            + self.inline_bits.size
            + self
                .picks
                .as_ref()
                .map_or(0, |p| p.picked.size + p.blocks.size + p.masks.size)
    }

    /// Names of the buffers whose guard words a pass overwrote.
    pub fn damaged_guards(&self, ctx: &Context) -> Result<Vec<String>> {
        let mut bad = Vec::new();
        let mut check = |b: &Buffer, words: u64| -> Result<()> {
            let g: Vec<u32> = b.download_pod(ctx, words, GUARD_WORDS)?;
            if g.iter().any(|&w| w != GUARD_PATTERN) {
                bad.push(b.name.clone());
            }
            Ok(())
        };
        check(&self.counters, COUNTER_WORDS)?;
        if let Some(l) = &self.lists {
            for (b, words) in l.buffers() {
                check(b, words)?;
            }
        }
        Ok(bad)
    }

    /// Every pixel's fragments as the fill left them (in atomic order).
    pub fn read_lists(&self, ctx: &Context) -> Result<FragmentLists> {
        let l = self.lists()?;
        let counts = l.counts.download_pod(ctx, 0, l.pixels)?;
        let pairs: Vec<[u32; 2]> = l.heads.download_pod(ctx, 0, l.pixels)?;
        let heads = pairs.iter().map(|p| p[0]).collect();
        let used = (self.read_counters(ctx)?[F_TOTAL as usize] as u64).min(l.capacity as u64);
        let frags = l.frags.download_pod(ctx, 0, used)?;
        Ok(FragmentLists {
            counts,
            heads,
            frags,
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for p in self.count.iter_mut().chain(self.fill.iter_mut()) {
            p.destroy(ctx);
        }
        self.args.destroy(ctx);
        self.alloc.destroy(ctx);
        for p in &mut self.pickers {
            p.destroy(ctx);
        }
        if let Some(p) = &mut self.picks {
            p.destroy(ctx);
        }
        if let Some(b) = &mut self.batches {
            b.destroy(ctx);
        }
        for b in [
            &mut self.counters,
            &mut self.jobs.buf,
            &mut self.inline_bits,
        ] {
            b.destroy(ctx);
        }
        if let Some(l) = &mut self.lists {
            l.destroy(ctx);
        }
    }
}

crate::impl_destroy!(SeeThrough);
