//! Deep shadow lists (after deep shadow maps on the GPU): per-tile chunked lists of every sphere whose
//! light-space disk overlaps each texel of the key light's map, sorted by
//! depth, walked with exact ray tests for hard or translucent shadows.
//!
//! Layout (DESIGN.md, the CUDA paper's): the N x N light map is split into
//! 8x8-texel tiles (one 64-invocation workgroup each); entries live in chunks
//! of 64 in structure-of-arrays buffers (depth, alpha, sphere id, next link,
//! transmittance); each tile has a chunk table (first chunk + chunk count)
//! and takes its chunks from one global pool with one atomicAdd; each texel
//! keeps its head (chunk << 6 | entry, i.e. the global entry index) and its
//! count. Links end with [`NONE`]. The paper's per-tile atomic sample
//! counter becomes the count pass's per-texel atomics plus the tile's
//! prefix sum: since a tile asks for all its chunks at once, they form one
//! contiguous run and each texel's entries are contiguous inside it (the
//! links are still written, in sorted order, and followed by the lookup).
//!
//! The visibility function of a texel is kept uncompressed (transmittance
//! after each entry) and in its epsilon-compressed piecewise-linear form
//! (|V' - V| <= [`EPSILON`], Eq. 1 of deep shadow maps on the GPU): nodes (depth, V) in two
//! structure-of-arrays buffers of twice the entry capacity, the texel whose
//! entries start at `head` owning node slots `2 * head ..` (`nodes` of them,
//! in depth order; a step is two nodes at the same depth, before and after).
//! n entries give at most 2n nodes (proof in glsl/deep_sort.comp), so the
//! node run needs no allocation of its own. The shadow lookup does not use
//! the nodes: it tests the listed spheres exactly instead of interpolating
//! V(z), which would need a per-texel depth, not a sphere's.
//!
//! Passes, each its own timestamp scope; the frame graph derives the
//! barrier between them from what each reads and writes:
//! - `deep_count`: clear, then count entries per texel (atomicAdd); large
//!   footprints are cut into 8-row band jobs run by whole workgroups;
//! - `deep_alloc`: per tile, a shared-memory prefix sum of texel counts and
//!   one pool atomicAdd for ceil(entries / 64) contiguous chunks; a tile
//!   that does not fit is flagged and gets nothing (no out-of-bounds writes);
//! - `deep_fill`: the same enumeration as the count (same pipeline), writing
//!   each entry at head + atomic per-texel cursor;
//! - `deep_sort`: per texel, sort its contiguous run by (depth, id), write
//!   links, transmittance and the epsilon-compressed visibility nodes;
//! - the lookup (glsl/lookup_deep.glsl, in `shade`): per visible pixel, walk
//!   its light texel's list with exact ray tests (the arrays read as texels:
//!   on lavapipe a storage load at per-lane addresses is a scalar loop).
//!
//! Vulkan has no forward-progress guarantee between invocations, so nothing
//! spins on another invocation (the paper's "pending chunk" busy-wait is
//! replaced by count -> allocate -> fill). GPU-AV does not check atomics:
//! every list and counter buffer carries [`GUARD_WORDS`] guard words after
//! its payload, filled once with [`GUARD_PATTERN`]; see [`DeepShadows::damaged_guards`].

use super::ShadowInputs;
use super::{FrameCheck, Lookup, LookupKind, ShadowParams, ShadowSetup, ShadowTechnique};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::gpu::blocks::{AllocPush, SortPush, SplatPush};
use crate::gpu::consts;
use crate::passes::bands::{BandArgs, BandCounters, BandJob, BandPipelines, JobList};
use crate::passes::scene::{SCENE_ATTRIBUTES, SCENE_GEOMETRY};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::settings::ShadowMode;
use crate::stages::raster::compute::ViewIndex;
use crate::vk::pipeline::{Binding, PipelineDesc, rw, texel, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
use ash::vk;
use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};
use std::any::Any;

mod lists;
mod readback;

use lists::{Lists, guarded};

pub use readback::{DeepCounters, DeepRaw};

/// Tile side in texels (a tile is one 64-invocation workgroup).
pub const TILE: u32 = consts::DEEP_TILE;
/// Entries per chunk.
pub const CHUNK: u32 = consts::DEEP_CHUNK;
/// List terminator / "no chunk".
pub const NONE: u32 = consts::DEEP_NONE;
/// u32 guard words after every list and counter buffer.
pub const GUARD_WORDS: u64 = 64;
pub const GUARD_PATTERN: u32 = 0xDEE9_5AFE;
/// Footprints above this many texels are split into 8-row band jobs run by
/// whole workgroups (one invocation loops over smaller ones). On lavapipe a
/// band workgroup costs about as much as a 100-texel loop, hence 256 rather
/// than the rasterizer's 64.
pub const BIG_AREA: u32 = 256;
/// Band jobs per frame before the per-sphere fallback loop.
pub const JOB_CAPACITY: u32 = 1 << 18;
/// Tolerance of the compressed visibility function: one 8-bit AOV step.
pub const EPSILON: f32 = 1.0 / 255.0;
/// Bytes per entry slot in the SoA arrays: depth, alpha, id, next,
/// transmittance (20), plus its two visibility node slots of depth and V (16).
pub const BYTES_PER_ENTRY: u64 = 36;
/// Visibility node slots per entry slot (a texel's n entries give at most 2n
/// nodes).
pub const NODES_PER_ENTRY: u64 = 2;
/// Counter words (stats 0..15, band jobs 16..23) before the guard.
pub const COUNTER_WORDS: u64 = 32;

/// Indices into the counters buffer (the C_* words of src/gpu_consts.rs).
pub mod counter {
    use crate::gpu::consts as c;
    pub const CHUNKS: usize = c::C_CHUNKS as usize;
    pub const OVERFLOW: usize = c::C_OVERFLOW as usize;
    pub const ENTRIES: usize = c::C_ENTRIES as usize;
    pub const MAX_COUNT: usize = c::C_MAX_COUNT as usize;
    pub const NODES: usize = c::C_NODES as usize;
    pub const FILL_ERRORS: usize = c::C_FILL_ERRORS as usize;
    pub const MAX_NODES: usize = c::C_MAX_NODES as usize;
    pub const NONEMPTY: usize = c::C_NONEMPTY as usize;
    pub const DROPPED: usize = c::C_DROPPED as usize;
    pub const SORT_CUT: usize = c::C_SORT_CUT as usize;
    pub const BANDS_FULL: usize = c::C_BANDS_FULL as usize;
    pub const BANDS_REQ: usize = c::C_BANDS_REQ as usize;
    pub const BANDS_RUN: usize = c::C_BANDS_RUN as usize;
    pub const ARGS: usize = c::C_ARGS as usize;
}

/// Deep-list statistics of a frame (the JSON's `deep` object).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct DeepStats {
    pub entries: u64,
    pub chunks_used: u64,
    pub chunk_capacity: u64,
    pub bytes: u64,
    pub fixed_layer_bytes: u64,
    pub overflowed: bool,
}

/// Per-texel record (`DeepTexel` in glsl/deep.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq, Eq)]
pub struct DeepTexel {
    pub count: u32,
    pub fill: u32,
    pub head: u32,
    pub nodes: u32,
}

/// Per-tile chunk table (`DeepTile` in glsl/deep.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq, Eq)]
pub struct DeepTile {
    pub first_chunk: u32,
    pub chunks: u32,
    pub entries: u32,
    pub flags: u32,
}

pub const TILE_OVERFLOWED: u32 = consts::DEEP_TILE_OVERFLOWED;

/// The lookup's bindings (glsl/lookup_deep.glsl).
const LOOKUP: [Binding; 5] = [
    texel("deepTexelTex", vk::Format::R32G32B32A32_UINT),
    texel("deepTileTex", vk::Format::R32G32B32A32_UINT),
    texel("deepDepthTex", vk::Format::R32_SFLOAT),
    texel("deepAlphaTex", vk::Format::R32_SFLOAT),
    texel("deepIdTex", vk::Format::R32_UINT),
];

const _: () = assert!(std::mem::size_of::<DeepTexel>() == 16);
const _: () = assert!(std::mem::size_of::<DeepTile>() == 16);

const MODE_COUNT: u32 = 0;
const MODE_FILL: u32 = 1;

pub struct DeepShadows {
    pub light: Camera,
    sphere_count: u32,
    capacity: u32,
    texels: Buffer,
    tiles: Buffer,
    counters: Buffer,
    /// Band jobs (guarded; JOB_CAPACITY unless a test lowers the limit).
    jobs: JobList,
    inline_bits: Buffer,
    lists: Lists,
    /// The splat shader in count mode and in fill mode (specialization
    /// constant 2), each per sphere and per band.
    count: BandPipelines,
    fill: BandPipelines,
    args: BandArgs,
    alloc: ComputePipeline,
    sort: ComputePipeline,
    /// Statistics of the last frame (after any pool growth).
    pub stats: Option<DeepStats>,
    /// The last frame overflowed (and was rendered again).
    retried: bool,
}

/// Initial pool size without `--deep-pool-chunks`: the sum over spheres of
/// the texel squares a disk of R texels overlaps (the area of the disk grown
/// by a texel square: pi R^2 + 4R + 1), 25% headroom and one partly used
/// chunk per tile. Spheres outside the light view count too (harmless).
/// Pool growth on overflow fixes any underestimate.
pub fn estimate_pool_chunks(light: &Camera, radii: impl Iterator<Item = f32>) -> u32 {
    let texel = light.view_height / light.width.max(1) as f64;
    let entries: f64 = radii
        .map(|r| {
            let r = r as f64 / texel + 0.01;
            std::f64::consts::PI * r * r + 4.0 * r + 1.0
        })
        .sum();
    let tiles = tile_count(light) as f64;
    let chunks = entries / CHUNK as f64 * 1.25 + tiles;
    chunks.clamp(64.0, max_chunks_hard() as f64) as u32
}

/// Link encoding (chunk << 6 | entry) must stay below the terminator.
fn max_chunks_hard() -> u32 {
    (u32::MAX - 1) / CHUNK
}

fn tile_count(light: &Camera) -> u64 {
    light.width.div_ceil(TILE) as u64 * light.height.div_ceil(TILE) as u64
}

impl DeepShadows {
    pub fn new(setup: &ShadowSetup) -> Result<Self> {
        let ctx = setup.ctx;
        let light = setup.fit(setup.settings.issm.size)?;
        let pool_chunks = setup.settings.deep.pool_chunks;
        let sphere_count = setup.geom.slots();
        if light.fov_deg.is_some() {
            return Err(Error::Internal(
                "deep shadow lists need an orthographic light view".into(),
            ));
        }
        let capacity = match pool_chunks {
            Some(0) => {
                return Err(Error::Input("--deep-pool-chunks must be at least 1".into()));
            }
            Some(c) => c,
            None => estimate_pool_chunks(&light, setup.radii()),
        };
        let capacity = Self::check_capacity(ctx, capacity as u64, pool_chunks.is_none())?;
        let texel_count = light.width as u64 * light.height as u64;
        let range = ctx.props.limits.max_storage_buffer_range as u64;
        if (texel_count * 4 + GUARD_WORDS) * 4 > range {
            return Err(Error::DeviceLimit(format!(
                "--shadows deep: a {}x{} light map needs a {} MiB texel table, more than the device's \
                 maxStorageBufferRange ({} MiB); lower --issm-size",
                light.width,
                light.height,
                (texel_count * 16) >> 20,
                range >> 20
            )));
        }
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        // (the lookup reads the texel and tile tables as texels)
        let lookup = storage | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let pipe = |name: &str, shader, bindings: &[_], push: usize, local: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader,
                    bindings,
                    push_size: push as u32,
                    local_size: local,
                    constants: &[],
                    scene: 0,
                },
            )
        };
        // Build everything, releasing what was made if a later step fails.
        let mut bufs = ctx.guard(Vec::new());
        let args = ctx.guard(BandArgs::new(ctx, "deep band args")?);
        let jobs = ctx.guard(JobList::guarded(
            ctx,
            "deep band jobs",
            JOB_CAPACITY,
            (GUARD_WORDS, GUARD_PATTERN),
        )?);
        bufs.push(guarded(ctx, "deep texels", texel_count * 4, lookup)?);
        bufs.push(guarded(ctx, "deep tiles", tile_count(&light) * 4, lookup)?);
        bufs.push(guarded(
            ctx,
            "deep counters",
            COUNTER_WORDS,
            storage | vk::BufferUsageFlags::INDIRECT_BUFFER,
        )?);
        bufs.push(guarded(
            ctx,
            "deep inline spheres",
            (sphere_count as u64).div_ceil(32).max(1),
            storage,
        )?);
        let splat = |mode: u32, name: &str| {
            BandPipelines::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: spirv::DEEP_SPLAT_COMP,
                    bindings: &[
                        &[
                            uniform("GlobalsBlock"),
                            rw("Texels"),
                            texel("deepTexelWordTex", vk::Format::R32_UINT),
                            wo("Depth"),
                            wo("Alpha"),
                            wo("Ids"),
                            rw("Counters"),
                            rw("Jobs"),
                            rw("Inline"),
                            texel("deepTileTex", vk::Format::R32G32B32A32_UINT),
                            texel("orderTex", vk::Format::R32_UINT),
                        ][..],
                        &SCENE_GEOMETRY,
                        &SCENE_ATTRIBUTES,
                    ]
                    .concat(),
                    push_size: std::mem::size_of::<SplatPush>() as u32,
                    local_size: LOCAL_SIZE,
                    constants: &[],
                    scene: setup.scene,
                },
                &[mode],
            )
        };
        let count = ctx.guard(splat(MODE_COUNT, "deep count")?);
        let fill = ctx.guard(splat(MODE_FILL, "deep fill")?);
        let alloc = ctx.guard(pipe(
            "deep alloc",
            spirv::DEEP_ALLOC_COMP,
            &[
                uniform("GlobalsBlock"),
                rw("Texels"),
                wo("Tiles"),
                rw("Counters"),
            ],
            std::mem::size_of::<AllocPush>(),
            64,
        )?);
        let sort = ctx.guard(pipe(
            "deep sort",
            spirv::DEEP_SORT_COMP,
            &[
                uniform("GlobalsBlock"),
                rw("Texels"),
                rw("Depth"),
                rw("Alpha"),
                rw("Ids"),
                wo("Next"),
                wo("Trans"),
                rw("Counters"),
                wo("NodeDepthEven"),
                wo("NodeVisEven"),
                wo("NodeDepthOdd"),
                wo("NodeVisOdd"),
            ],
            std::mem::size_of::<SortPush>(),
            64,
        )?);
        let lists = Lists::new(ctx, capacity)?;
        let mut b = bufs.keep().into_iter();
        let mut nb = || b.next().expect("buffers");
        let (texels, tiles, counters, inline_bits) = (nb(), nb(), nb(), nb());
        Ok(DeepShadows {
            light,
            sphere_count,
            capacity,
            texels,
            tiles,
            counters,
            jobs: jobs.keep(),
            inline_bits,
            lists,
            count: count.keep(),
            fill: fill.keep(),
            args: args.keep(),
            alloc: alloc.keep(),
            sort: sort.keep(),
            stats: None,
            retried: false,
        })
    }

    /// Clamps (estimates) or rejects (explicit sizes) a pool the device
    /// cannot address: each entry array and each node parity array (one
    /// word per entry slot) must fit in maxStorageBufferRange, the entry
    /// arrays the lookup reads as R32 texels in maxTexelBufferElements, and
    /// links must stay below the terminator (which also keeps node slots,
    /// 2 x entry, in u32).
    fn check_capacity(ctx: &Context, chunks: u64, clamp: bool) -> Result<u32> {
        let limits = &ctx.props.limits;
        let range = limits.max_storage_buffer_range as u64;
        let by_range = (range.saturating_sub(GUARD_WORDS * 4) / 4) / CHUNK as u64;
        let by_texels =
            (limits.max_texel_buffer_elements as u64).saturating_sub(GUARD_WORDS) / CHUNK as u64;
        let max = by_range.min(by_texels).min(max_chunks_hard() as u64).max(1);
        if chunks <= max {
            Ok(chunks as u32)
        } else if clamp {
            Ok(max as u32)
        } else {
            Err(Error::DeviceLimit(format!(
                "--deep-pool-chunks {chunks}: more than the {max} chunks of {CHUNK} entries the device \
                 can address (maxStorageBufferRange {range} bytes, maxTexelBufferElements {} \
                 per list array)",
                limits.max_texel_buffer_elements
            )))
        }
    }

    /// Test hook: allow at most `jobs` band jobs per frame (clamped to
    /// the list's entries) so the full-job-list fallback (voided slots, the
    /// sphere's own invocation looping over its footprint) can be exercised
    /// on small scenes. Takes effect from the next recorded frame.
    pub fn set_job_limit(&self, jobs: u32) {
        self.jobs.set_limit(jobs);
    }

    /// The band jobs a frame may queue.
    pub fn job_limit(&self) -> u32 {
        self.jobs.capacity()
    }

    pub fn tiles_xy(&self) -> (u32, u32) {
        (
            self.light.width.div_ceil(TILE),
            self.light.height.div_ceil(TILE),
        )
    }

    /// Pool size in chunks.
    pub fn chunk_capacity(&self) -> u32 {
        self.capacity
    }

    fn entry_capacity(&self) -> u32 {
        self.capacity * CHUNK
    }

    fn texel_count(&self) -> u64 {
        self.light.width as u64 * self.light.height as u64
    }

    /// `deep_count`, `deep_alloc`, `deep_fill`, `deep_sort`.
    fn record_lists<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        let l = &self.lists;
        let mut splat_bufs = vec![
            ("GlobalsBlock", f.globals),
            ("Texels", &self.texels),
            ("deepTexelWordTex", &self.texels),
            ("deepTileTex", &self.tiles),
            ("orderTex", f.raster.order(ViewIndex::Light)),
            ("Depth", &l.depth),
            ("Alpha", &l.alpha),
            ("Ids", &l.ids),
            ("Counters", &self.counters),
            ("Jobs", &self.jobs.buf),
            ("Inline", &self.inline_bits),
        ];
        splat_bufs.extend(f.scene.geometry());
        splat_bufs.extend(f.scene.attributes());
        let job_capacity = self.jobs.capacity();
        let splat = SplatPush {
            sphere_count: self.sphere_count,
            big_area: BIG_AREA,
            job_capacity,
            entry_capacity: self.entry_capacity(),
        };
        let band_counters = BandCounters {
            job_capacity,
            requested: counter::BANDS_REQ as u32,
            run: counter::BANDS_RUN as u32,
            args: counter::ARGS as u32,
        };
        let (tx, ty) = self.tiles_xy();

        rec.pass("deep_count", |p| {
            p.fill(&self.texels, self.texel_count() * 16, 0);
            p.fill(&self.counters, COUNTER_WORDS * 4, 0);
            let inline_words = (self.sphere_count as u64).div_ceil(32).max(1);
            p.fill(&self.inline_bits, inline_words * 4, 0);
            self.args.steps(
                p,
                &BandJob {
                    spheres: &self.count.spheres,
                    bands: &self.count.bands,
                    push: &splat,
                    bindings: &splat_bufs,
                    sphere_count: self.sphere_count,
                    indirect: None,
                    counters: &self.counters,
                    layout: &band_counters,
                },
            );
            Ok(())
        })?;
        rec.pass("deep_alloc", |p| {
            p.dispatch(
                &self.alloc,
                &AllocPush {
                    chunk_capacity: self.capacity,
                },
                Grid::Groups([tx, ty, 1]),
                &[
                    ("GlobalsBlock", f.globals),
                    ("Texels", &self.texels),
                    ("Tiles", &self.tiles),
                    ("Counters", &self.counters),
                ],
            );
            Ok(())
        })?;
        rec.pass("deep_fill", |p| {
            // The count pass left the band arguments; recomputing them is one
            // invocation and keeps one recorded sequence for both modes.
            self.args.steps(
                p,
                &BandJob {
                    spheres: &self.fill.spheres,
                    bands: &self.fill.bands,
                    push: &splat,
                    bindings: &splat_bufs,
                    sphere_count: self.sphere_count,
                    indirect: None,
                    counters: &self.counters,
                    layout: &band_counters,
                },
            );
            Ok(())
        })?;
        rec.pass("deep_sort", |p| {
            p.dispatch(
                &self.sort,
                &SortPush {
                    eps: EPSILON,
                    entry_capacity: self.entry_capacity(),
                },
                Grid::Groups([tx, ty, 1]),
                &[
                    ("GlobalsBlock", f.globals),
                    ("Texels", &self.texels),
                    ("Depth", &l.depth),
                    ("Alpha", &l.alpha),
                    ("Ids", &l.ids),
                    ("Next", &l.next),
                    ("Trans", &l.trans),
                    ("Counters", &self.counters),
                    ("NodeDepthEven", &l.node_depth[0]),
                    ("NodeVisEven", &l.node_vis[0]),
                    ("NodeDepthOdd", &l.node_depth[1]),
                    ("NodeVisOdd", &l.node_vis[1]),
                ],
            );
            Ok(())
        })
    }

    /// Grows the pool to at least `needed_chunks` (plus 1/8 headroom); the
    /// caller renders the frame again. The old lists are discarded.
    pub fn grow(&mut self, ctx: &Context, needed_chunks: u64) -> Result<()> {
        if needed_chunks <= self.capacity as u64 {
            return Ok(());
        }
        let want = needed_chunks + needed_chunks / 8 + 1;
        let max = Self::check_capacity(ctx, u64::MAX, true)? as u64;
        if needed_chunks > max {
            return Err(Error::DeviceLimit(format!(
                "deep shadow lists need {needed_chunks} chunks of {CHUNK} entries, more than the device can \
                 address ({max} chunks: maxStorageBufferRange per list array); lower --issm-size"
            )));
        }
        let capacity = want.min(max) as u32;
        // The previous frame was waited on; nothing in flight uses the lists.
        ctx.wait_idle();
        let lists = Lists::new(ctx, capacity)?;
        self.lists.destroy(ctx);
        self.lists = lists;
        self.capacity = capacity;
        Ok(())
    }

    /// Bytes of the deep-list structure proper (the JSON's `bytes`): the
    /// entry and node arrays at their allocated capacity, the texel and tile
    /// tables and the counters, guard words included; not the band-job scratch.
    pub fn list_bytes(&self) -> u64 {
        let fixed = self.texels.size + self.tiles.size + self.counters.size;
        let l = &self.lists;
        fixed
            + l.entries()
                .iter()
                .chain(l.nodes().iter())
                .map(|b| b.size)
                .sum::<u64>()
    }

    /// Bytes of every buffer this pass owns (lists and band-job scratch).
    pub fn memory_bytes(&self) -> u64 {
        self.guarded_buffers().iter().map(|(b, _)| b.size).sum()
    }

    /// (chunk pool: entries and visibility nodes, everything else: texel
    /// heads, tile tables, counters, jobs).
    pub fn memory_split(&self) -> (u64, u64) {
        let pool: u64 = self
            .lists
            .entries()
            .into_iter()
            .chain(self.lists.nodes())
            .map(|b| b.size)
            .sum();
        (pool, self.memory_bytes() - pool)
    }

    fn destroy_all(&mut self, ctx: &Context) {
        self.count.destroy(ctx);
        self.fill.destroy(ctx);
        self.alloc.destroy(ctx);
        self.sort.destroy(ctx);
        self.args.destroy(ctx);
        for b in [
            &mut self.texels,
            &mut self.tiles,
            &mut self.counters,
            &mut self.inline_bits,
        ] {
            b.destroy(ctx);
        }
        self.jobs.destroy(ctx);
        self.lists.destroy(ctx);
    }
}

impl ShadowTechnique for DeepShadows {
    fn mode(&self) -> ShadowMode {
        ShadowMode::Deep
    }

    fn light(&self) -> &Camera {
        &self.light
    }

    fn record_light<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        self.record_lists(rec, f)
    }

    fn lookup(&self, _opacity: f32) -> Lookup<'_> {
        let l = &self.lists;
        Lookup {
            kind: LookupKind::Deep,
            soft: false,
            bindings: &LOOKUP,
            buffers: vec![
                ("deepTexelTex", &self.texels),
                ("deepTileTex", &self.tiles),
                ("deepDepthTex", &l.depth),
                ("deepAlphaTex", &l.alpha),
                ("deepIdTex", &l.ids),
            ],
            params: ShadowParams {
                u: [self.entry_capacity(), 0, 0, 0],
                ..Default::default()
            },
        }
    }

    /// The same map size and pool; the lists are rebuilt every frame, and
    /// the pool grows when the new view needs more.
    fn refit(&mut self, setup: &ShadowSetup) -> Result<()> {
        self.light = setup.fit(self.light.width)?;
        if setup.geom.slots() != self.sphere_count {
            return Err(Error::Internal(
                "deep lists: the sphere count changed; make a new technique".into(),
            ));
        }
        Ok(())
    }

    fn memory(&self) -> Vec<(&'static str, u64)> {
        let (pool, tables) = self.memory_split();
        vec![("deep_pool", pool), ("deep_tables", tables)]
    }

    /// Reads the frame's counters; on overflow grows the pool so the frame
    /// can be rendered again (the renderer gives up after a few tries).
    fn after_frame(&mut self, ctx: &Context, words: &[u32]) -> Result<FrameCheck> {
        let c = DeepCounters::of_words(words)?;
        // (first: a visit the loop limit cut may also have filled outside
        // its run)
        if c.bands_full {
            self.jobs.grow(ctx, "deep lists")?;
            return Ok(FrameCheck::Retry);
        }
        if c.sort_cut > 0 {
            return Err(Error::DeviceLimit(format!(
                "deep shadow lists of up to {} entries a light texel: {} texels are longer than \
                 this device sorts in one shader invocation (lavapipe stops every loop after \
                 65,535 steps); raise --issm-size or use --shadows issm-soft",
                c.max_depth_complexity, c.sort_cut
            )));
        }
        let mut stats = self.stats_of(&c);
        if !stats.overflowed {
            // Report that this frame needed a retry even though the final one fit.
            stats.overflowed = std::mem::take(&mut self.retried);
            self.stats = Some(stats);
            return Ok(FrameCheck::Done);
        }
        self.retried = true;
        self.grow(ctx, stats.chunks_used)?;
        self.stats = Some(stats);
        Ok(FrameCheck::Retry)
    }

    fn readback(&self) -> Option<(&Buffer, u64, u64)> {
        Some((&self.counters, 0, COUNTER_WORDS))
    }

    fn checks_frames(&self) -> bool {
        true
    }

    fn as_any(&self) -> &dyn Any {
        self
    }

    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }

    fn destroy(&mut self, ctx: &Context) {
        self.destroy_all(ctx);
    }
}
