//! The SSDO passes (after the semantic SSDO paper), one bounce:
//! `ssdo_prep` picks one representative pixel per 2x2 block and packs its
//! record (glsl/ssdo_record.glsl: view distance, octahedral normal, region
//! hashes, the key light it reflects). `ssdo` runs for every pixel when
//! spheres are small on screen, else once per block for its representative,
//! over the sample table's directions (a uniform buffer made once here);
//! the blur (stages/ssdo/blur.rs) smooths the result and shade upsamples the
//! blocks'. See glsl/ssdo.comp.

use crate::error::{Error, Result};
use crate::gpu::blocks::{ListPush, PrepSpec, SphereSpec, SsdoSpec};
pub use crate::gpu::blocks::{PrepPush, SsdoPush};
use crate::gpu::consts::{S_ARGS, S_GROUPS, S_RUN};
use crate::passes::bands::{BandArgs, BandCounters, counters_buffer};
use crate::passes::scene::{SCENE_ATTRIBUTES, SCENE_GEOMETRY};
use crate::passes::screen::{ScreenInputs, surface_bindings};
use crate::passes::tiles::{TILE_BINDING, Tiles};
use crate::passes::variants::{TiledDispatch, Variants};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::stages::shadows::{Lookup, LookupKind};
use crate::vk::pipeline::{Binding, PipelineDesc, ro, rw, texel, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
use ash::vk::Format;

use super::record::{TABLE_SIZE, sample_table};

/// Who receives SSDO: every covered pixel, one representative pixel per
/// 2x2 block, or every visible sphere (glsl/ssdo_sphere.comp, with
/// SSDO_SPHERE_DIRS directions and no blur).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Receivers {
    Pixel,
    Block,
    Sphere,
}

/// Tap counts per receiver (directions, far-search steps per direction:
/// per sphere, taps per azimuth line) and the receivers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Taps {
    pub dirs: u32,
    pub steps: u32,
    pub receivers: Receivers,
    /// Perspective camera: taps step along the pixel rays; orthographic
    /// ones step in view space, which needs no division per tap.
    pub perspective: bool,
}

impl Taps {
    fn constants(&self, semantic: bool) -> Vec<u32> {
        SsdoSpec {
            semantic,
            dirs: self.dirs,
            steps: self.steps,
            perspective: self.perspective,
            half: self.per_block(),
        }
        .constants()
    }

    pub fn per_block(&self) -> bool {
        self.receivers == Receivers::Block
    }

    pub fn per_sphere(&self) -> bool {
        self.receivers == Receivers::Sphere
    }

    fn sphere_constants(&self, semantic: bool) -> Vec<u32> {
        SphereSpec {
            semantic,
            steps: self.steps,
            perspective: self.perspective,
        }
        .constants()
    }
}

/// What `ssdo_prep` writes: the half-resolution records, the flags of the
/// spheres seen (per-sphere receivers; any buffer the pass may write
/// otherwise: unwritten) and the taps' block-ordered depth words.
pub struct PrepIo<'a> {
    pub records: &'a Buffer,
    pub flags: &'a Buffer,
    pub tap_depth: &'a Buffer,
}

/// What per-sphere `ssdo` reads (the records and tap depth `ssdo_prep`
/// wrote) and writes (the spheres' buffers: list, counters, result).
pub struct SphereIo<'a> {
    pub records: &'a Buffer,
    pub tap_depth: &'a Buffer,
    pub spheres: &'a SphereBuffers,
}

/// What per-pixel or per-block `ssdo` reads (the records and tap depth
/// `ssdo_prep` wrote) and writes: the result and, per pixel, the blur's
/// edge keys.
pub struct SsdoIo<'a> {
    pub records: &'a Buffer,
    pub tap_depth: &'a Buffer,
    pub ao: &'a Buffer,
    pub keys: &'a Buffer,
}

/// How a frame's SSDO passes run: the tap set, the region test, the
/// receivers' grid (blocks or pixels; `ssdo_prep`: always blocks) and the
/// tiles.
#[derive(Clone, Copy)]
pub struct Shape<'a> {
    pub taps: Taps,
    pub semantic: bool,
    pub grid: (u32, u32),
    pub tiles: Tiles<'a>,
}

pub struct SsdoPass {
    prep: Variants,
    ssdo: Variants,
    table: Buffer,
    /// Per-sphere receivers: the list, its dispatch arguments, the pass.
    list: Option<ComputePipeline>,
    args: Option<BandArgs>,
    sphere: Variants,
    /// The scene's SCENE_SPEC (kind and batch shift) for the pipelines reading it.
    scene: u32,
}

/// The per-sphere SSDO's buffers, for one sphere count and buffer size:
/// the flags ssdo_prep sets (a bit per sphere), the list of flagged
/// spheres with each flag word's first entry, its counters (words S_*)
/// and the results, 16 bytes per listed sphere (ssdo_common.glsl). A
/// sphere seen is seen in a pixel, so the list holds at most the
/// buffer's pixels.
pub struct SphereBuffers {
    pub spheres: u32,
    /// Entries the list and the results hold.
    pub capacity: u32,
    pub flags: Buffer,
    pub list: Buffer,
    pub word_base: Buffer,
    pub counters: Buffer,
    pub ao: Buffer,
}

impl SphereBuffers {
    /// The bytes [`SphereBuffers::new`] takes for these counts.
    pub fn bytes_for(spheres: u32, pixels: u64) -> u64 {
        let n = spheres.max(1) as u64;
        let capacity = n.min(pixels.max(1));
        2 * flag_words(n) * 4 + capacity * 20 + 32
    }

    pub fn new(ctx: &Context, spheres: u32, pixels: u64) -> Result<Self> {
        let n = spheres.max(1) as u64;
        let capacity = n.min(pixels.max(1));
        let words = flag_words(n);
        let flags = ctx.guard(Buffer::storage(ctx, "ssdo sphere flags", words * 4)?);
        let list = ctx.guard(Buffer::storage(ctx, "ssdo sphere list", capacity * 4)?);
        let word_base = ctx.guard(Buffer::storage(ctx, "ssdo sphere word bases", words * 4)?);
        let counters = ctx.guard(counters_buffer(ctx, "ssdo sphere counters", 32)?);
        let ao = Buffer::storage(ctx, "ssdo sphere ao", capacity * 16)?;
        Ok(SphereBuffers {
            spheres,
            capacity: capacity as u32,
            flags: flags.keep(),
            list: list.keep(),
            word_base: word_base.keep(),
            counters: counters.keep(),
            ao,
        })
    }

    pub fn bytes(&self) -> u64 {
        self.flags.size + self.list.size + self.word_base.size + self.counters.size + self.ao.size
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.flags,
            &mut self.list,
            &mut self.word_base,
            &mut self.counters,
            &mut self.ao,
        ] {
            b.destroy(ctx);
        }
    }
}

crate::impl_destroy!(SphereBuffers);

/// Words of the per-sphere flags: one bit per sphere.
fn flag_words(spheres: u64) -> u64 {
    spheres.div_ceil(32)
}

const _: () = assert!(LOCAL_SIZE.is_power_of_two());

const LIST_COUNTERS: BandCounters = BandCounters {
    job_capacity: u32::MAX,
    requested: S_GROUPS,
    run: S_RUN,
    args: S_ARGS,
};

const PREP_OUTPUTS: [Binding; 3] = [wo("Records"), rw("Flags"), wo("TapDepth")];
const LIST_BINDINGS: [Binding; 4] = [ro("Flags"), wo("List"), rw("Counters"), wo("WordBase")];
const SPHERE_BINDINGS: [Binding; 7] = [
    uniform("GlobalsBlock"),
    texel("recordTex", Format::R32G32B32A32_UINT),
    wo("SphereAo"),
    ro("List"),
    ro("Counters"),
    texel("visWordTex", Format::R32_UINT),
    texel("tapDepthTex", Format::R32_UINT),
];
const SSDO_BINDINGS: [Binding; 8] = [
    uniform("GlobalsBlock"),
    texel("recordTex", Format::R32G32B32A32_UINT),
    uniform("SampleTable"),
    wo("Ao"),
    texel("visTex", Format::R32G32_UINT),
    texel("tapDepthTex", Format::R32_UINT),
    wo("Keys"),
    TILE_BINDING,
];

/// A pass's own bindings and the scene's (geometry and attributes).
fn with_scene(own: &[Binding]) -> Vec<Binding> {
    [own, &SCENE_GEOMETRY, &SCENE_ATTRIBUTES].concat()
}

impl SsdoPass {
    pub const PREP_NAME: &'static str = "ssdo_prep";
    pub const NAME: &'static str = "ssdo";

    /// The passes for a scene of this SCENE_SPEC (passes::scene).
    pub fn new(ctx: &Context, scene: u32) -> Result<Self> {
        let table = Buffer::new(
            ctx,
            "ssdo sample table",
            (TABLE_SIZE * 16) as u64,
            ash::vk::BufferUsageFlags::UNIFORM_BUFFER,
            gpu_allocator::MemoryLocation::GpuOnly,
        )?;
        let table = ctx.guard(table);
        table.upload(ctx, 0, bytemuck::cast_slice(&sample_table()))?;
        Ok(SsdoPass {
            prep: Variants::default(),
            ssdo: Variants::default(),
            table: table.keep(),
            list: None,
            args: None,
            sphere: Variants::default(),
            scene,
        })
    }

    pub fn table(&self) -> &Buffer {
        &self.table
    }

    fn prep_bindings(lookup: &Lookup) -> Vec<Binding> {
        let mut b = surface_bindings();
        b.extend_from_slice(&PREP_OUTPUTS);
        b.push(TILE_BINDING);
        b.extend_from_slice(lookup.bindings);
        b
    }

    /// Makes the pipelines of these modes if this is their first use.
    pub fn prepare(
        &mut self,
        ctx: &Context,
        lookup: &Lookup,
        semantic: bool,
        taps: Taps,
        lists: bool,
    ) -> Result<()> {
        if taps.dirs as usize > TABLE_SIZE || taps.dirs == 0 || taps.steps == 0 {
            return Err(Error::Internal(format!("ssdo: bad tap counts {taps:?}")));
        }
        self.prep.ensure_tiled(
            ctx,
            &PipelineDesc {
                name: Self::PREP_NAME,
                shader: lookup.kind.shader(false),
                bindings: &Self::prep_bindings(lookup),
                push_size: std::mem::size_of::<PrepPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &Self::prep_constants(lookup, taps),
                scene: self.scene,
            },
            lists,
        )?;
        if taps.per_sphere() {
            if self.list.is_none() {
                self.list = Some(ComputePipeline::new(
                    ctx,
                    &PipelineDesc {
                        name: "ssdo_list",
                        shader: spirv::SSDO_LIST_COMP,
                        bindings: &LIST_BINDINGS,
                        push_size: std::mem::size_of::<ListPush>() as u32,
                        local_size: LOCAL_SIZE,
                        constants: &[],
                        scene: 0,
                    },
                )?);
            }
            if self.args.is_none() {
                self.args = Some(BandArgs::new(ctx, "ssdo_sphere args")?);
            }
            return self.sphere.ensure(
                ctx,
                &PipelineDesc {
                    name: Self::NAME,
                    shader: spirv::SSDO_SPHERE_COMP,
                    bindings: &with_scene(&SPHERE_BINDINGS),
                    push_size: std::mem::size_of::<SsdoPush>() as u32,
                    local_size: LOCAL_SIZE,
                    constants: &taps.sphere_constants(semantic),
                    scene: self.scene,
                },
            );
        }
        self.ssdo.ensure_tiled(
            ctx,
            &PipelineDesc {
                name: Self::NAME,
                shader: spirv::SSDO_COMP,
                bindings: &with_scene(&SSDO_BINDINGS),
                push_size: std::mem::size_of::<SsdoPush>() as u32,
                local_size: LOCAL_SIZE,
                constants: &taps.constants(semantic),
                scene: self.scene,
            },
            lists,
        )
    }

    /// With per-sphere receivers the records feed only the bounce (4 bits a
    /// channel): their key-light visibility skips the soft penumbra and
    /// reads only the ISSM's 2x2 texels around the point (1M capsid at
    /// 1080p: 21 pixels of the image change, by at most 17 levels).
    fn prep_constants(lookup: &Lookup, taps: Taps) -> Vec<u32> {
        let quad = lookup.quad() || (lookup.kind == LookupKind::Issm && taps.per_sphere());
        PrepSpec {
            soft: lookup.soft && !taps.per_sphere(),
            core_only: lookup.core_only() || quad,
            mark: taps.per_sphere(),
            perspective: taps.perspective,
            quad,
        }
        .constants()
    }

    /// `ssdo_prep`: the half-resolution records, and with per-sphere
    /// receivers the flags of the spheres seen and the taps' block-ordered
    /// depth words.
    pub fn record_prep(
        &self,
        rec: &mut Recorder,
        screen: &ScreenInputs,
        lookup: &Lookup,
        io: &PrepIo,
        push: &PrepPush,
        shape: &Shape,
    ) -> Result<()> {
        let mut bufs = screen.surface_buffers();
        bufs.extend([
            ("Records", io.records),
            ("Flags", io.flags),
            ("TapDepth", io.tap_depth),
        ]);
        bufs.extend(lookup.buffers.iter().copied());
        let taps = shape.taps;
        rec.pass(Self::PREP_NAME, |p| {
            if taps.per_sphere() {
                p.fill(io.flags, io.flags.size, 0);
            }
            self.prep.dispatch_tiled(
                p,
                &TiledDispatch {
                    name: Self::PREP_NAME,
                    shader: lookup.kind.shader(false),
                    constants: &Self::prep_constants(lookup, taps),
                    push,
                    tiles: shape.tiles,
                    size: shape.grid,
                    half: true,
                    bufs: &bufs,
                },
            )
        })
    }

    /// `ssdo` with per-sphere receivers: the flagged spheres listed, the
    /// list's dispatch arguments, then one invocation per listed sphere
    /// into the spheres' result; the taps read the tap depth words.
    pub fn record_spheres(
        &self,
        rec: &mut Recorder,
        screen: &ScreenInputs,
        io: &SphereIo,
        push: &SsdoPush,
        shape: &Shape,
    ) -> Result<()> {
        let (sb, io_, semantic, taps) = (io.spheres, screen, shape.semantic, shape.taps);
        let missing = || Error::Internal("ssdo: per-sphere pipelines not prepared".into());
        let list = self.list.as_ref().ok_or_else(missing)?;
        let args = self.args.as_ref().ok_or_else(missing)?;
        let pipe = self
            .sphere
            .get(spirv::SSDO_SPHERE_COMP, &taps.sphere_constants(semantic))
            .ok_or_else(missing)?;
        let words = flag_words(sb.spheres as u64);
        let lp = ListPush {
            words: words as u32,
            group_shift: LOCAL_SIZE.trailing_zeros(),
            capacity: sb.capacity,
            pad: 0,
        };
        rec.pass(Self::NAME, |p| {
            p.fill(&sb.counters, sb.counters.size, 0);
            p.dispatch(
                list,
                &lp,
                Grid::Invocations(words),
                &[
                    ("Flags", &sb.flags),
                    ("List", &sb.list),
                    ("Counters", &sb.counters),
                    ("WordBase", &sb.word_base),
                ],
            );
            args.step(p, &sb.counters, &LIST_COUNTERS);
            let mut bufs = vec![
                ("GlobalsBlock", io_.globals),
                ("recordTex", io.records),
                ("SphereAo", &sb.ao),
                ("List", &sb.list),
                ("Counters", &sb.counters),
                ("visWordTex", io_.vis),
                ("tapDepthTex", io.tap_depth),
            ];
            bufs.extend(io_.scene.geometry());
            bufs.extend(io_.scene.attributes());
            p.dispatch(
                pipe,
                push,
                Grid::Indirect(&sb.counters, LIST_COUNTERS.args_offset()),
                &bufs,
            );
            Ok(())
        })
    }

    /// `ssdo`: ambient visibility + bounce per receiver (the shape's grid:
    /// blocks or pixels) into the result, and per pixel the blur's edge
    /// keys.
    pub fn record_ssdo(
        &self,
        rec: &mut Recorder,
        screen: &ScreenInputs,
        io: &SsdoIo,
        push: &SsdoPush,
        shape: &Shape,
    ) -> Result<()> {
        let taps = shape.taps;
        let mut bufs = vec![
            ("GlobalsBlock", screen.globals),
            ("recordTex", io.records),
            ("SampleTable", &self.table),
            ("Ao", io.ao),
            ("visTex", screen.vis),
            ("tapDepthTex", io.tap_depth),
            ("Keys", io.keys),
        ];
        bufs.extend(screen.scene.geometry());
        bufs.extend(screen.scene.attributes());
        rec.pass(Self::NAME, |p| {
            self.ssdo.dispatch_tiled(
                p,
                &TiledDispatch {
                    name: Self::NAME,
                    shader: spirv::SSDO_COMP,
                    constants: &taps.constants(shape.semantic),
                    push,
                    tiles: shape.tiles,
                    size: shape.grid,
                    half: taps.per_block(),
                    bufs: &bufs,
                },
            )
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.prep.destroy(ctx);
        self.ssdo.destroy(ctx);
        self.sphere.destroy(ctx);
        if let Some(l) = &mut self.list {
            l.destroy(ctx);
        }
        if let Some(a) = &mut self.args {
            a.destroy(ctx);
        }
        self.table.destroy(ctx);
    }
}

crate::impl_destroy!(SsdoPass);
