//! Semantic SSDO with one bounce at half resolution (seed 001):
//! `ssdo_prep` picks one representative pixel per 2x2 block and packs its
//! record (glsl/ssdo_record.glsl: view distance, octahedral normal, region
//! hashes, the key light it reflects). `ssdo` runs for every pixel when
//! spheres are small on screen, else once per block for its representative,
//! over the sample table's directions (a uniform buffer made once here);
//! the blur (passes/blur.rs) smooths the result and shade upsamples the
//! blocks'. See glsl/ssdo.comp.

use super::bands::{BandArgs, BandCounters, counters_buffer};
use super::coverage::{TILE_BINDING, Tiles};
use super::shade::{SURFACE_BINDINGS, ScreenInputs, Variants, variant};
use super::shadows::{Lookup, LookupKind};
use super::{LOCAL_SIZE, spirv};
use crate::error::{Error, Result};
use crate::gpu::consts::{S_ARGS, S_GROUPS, S_RUN};
use crate::vk::pipeline::{Binding, PipelineDesc, ro, rw, texel, uniform, wo};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, Recorder};
use ash::vk::Format;
use bytemuck::{Pod, Zeroable};

/// Entries of the sample table (at most this many directions).
pub const TABLE_SIZE: usize = 64;

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct PrepPush {
    pub level_a: u32,
    pub level_b: u32,
    pub pad: [u32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SsdoPush {
    pub r_near: f32,
    pub r_far: f32,
    /// Weight of level b in the region test.
    pub blend: f32,
    pub bounce: f32,
    pub level_a: u32,
    pub level_b: u32,
    /// The per-pixel blur compares regions at level b (else a): the keys'.
    pub blur_level_b: u32,
    pub pad: u32,
}

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
    fn constants(&self, semantic: bool) -> [u32; 5] {
        [
            semantic as u32,
            self.dirs,
            self.steps,
            self.perspective as u32,
            self.per_block() as u32,
        ]
    }

    pub fn per_block(&self) -> bool {
        self.receivers == Receivers::Block
    }

    pub fn per_sphere(&self) -> bool {
        self.receivers == Receivers::Sphere
    }

    fn sphere_constants(&self, semantic: bool) -> [u32; 3] {
        [semantic as u32, self.steps, self.perspective as u32]
    }
}

/// Radical inverse in base b (the Halton sequence), as glsl/ssdo_common.glsl.
pub fn halton(mut i: u32, b: u32) -> f64 {
    let (mut f, mut r) = (1.0, 0.0);
    while i > 0 {
        f /= b as f64;
        r += f * (i % b) as f64;
        i /= b;
    }
    r
}

/// The sample table: cosine-weighted tangent-space directions (Halton
/// points in bases 2 and 3 through Malley's concentric disk mapping) and a
/// base-5 Halton value for the near sample's distance.
pub fn sample_table() -> [[f32; 4]; TABLE_SIZE] {
    let mut t = [[0.0f32; 4]; TABLE_SIZE];
    for (k, e) in t.iter_mut().enumerate() {
        let i = k as u32 + 1;
        let (u, v) = (halton(i, 2), halton(i, 3));
        let (ox, oy) = (2.0 * u - 1.0, 2.0 * v - 1.0);
        let (mut dx, mut dy) = (0.0, 0.0);
        if ox != 0.0 || oy != 0.0 {
            let pi4 = std::f64::consts::FRAC_PI_4;
            let (r, th) = if ox.abs() > oy.abs() {
                (ox, pi4 * (oy / ox))
            } else {
                (oy, 2.0 * pi4 - pi4 * (ox / oy))
            };
            dx = r * th.cos();
            dy = r * th.sin();
        }
        let z = (1.0 - dx * dx - dy * dy).max(0.0).sqrt();
        *e = [dx as f32, dy as f32, z as f32, halton(i, 5) as f32];
    }
    t
}

pub struct SsdoPass {
    prep: Variants,
    ssdo: Variants,
    table: Buffer,
    /// Per-sphere receivers: the list, its dispatch arguments, the pass.
    list: Option<ComputePipeline>,
    args: Option<BandArgs>,
    sphere: Variants,
}

/// The per-sphere SSDO's buffers, for one sphere count: the flags
/// ssdo_prep sets, the list of flagged spheres, its counters (words S_*)
/// and the result, 16 bytes per sphere (ssdo_common.glsl).
pub struct SphereBuffers {
    pub spheres: u32,
    pub flags: Buffer,
    pub list: Buffer,
    pub counters: Buffer,
    pub ao: Buffer,
}

impl SphereBuffers {
    pub fn new(ctx: &Context, spheres: u32) -> Result<Self> {
        let n = spheres.max(1) as u64;
        let flags = ctx.guard(Buffer::storage(
            ctx,
            "ssdo sphere flags",
            flag_words(n) * 4,
        )?);
        let list = ctx.guard(Buffer::storage(ctx, "ssdo sphere list", n * 4)?);
        let counters = ctx.guard(counters_buffer(ctx, "ssdo sphere counters", 32)?);
        let ao = Buffer::storage(ctx, "ssdo sphere ao", n * 16)?;
        Ok(SphereBuffers {
            spheres,
            flags: flags.keep(),
            list: list.keep(),
            counters: counters.keep(),
            ao,
        })
    }

    pub fn bytes(&self) -> u64 {
        self.flags.size + self.list.size + self.counters.size + self.ao.size
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.flags,
            &mut self.list,
            &mut self.counters,
            &mut self.ao,
        ] {
            b.destroy(ctx);
        }
    }
}

crate::impl_destroy!(SphereBuffers);

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ListPush {
    /// Flag words, one bit per sphere.
    words: u32,
    /// log2 of ssdo_sphere.comp's workgroup size (groups counted by shifts).
    group_shift: u32,
    pad: [u32; 2],
}

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
const LIST_BINDINGS: [Binding; 3] = [ro("Flags"), wo("List"), rw("Counters")];
const SPHERE_BINDINGS: [Binding; 9] = [
    uniform("GlobalsBlock"),
    texel("recordTex", Format::R32G32B32A32_UINT),
    wo("SphereAo"),
    ro("List"),
    ro("Counters"),
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("attrTex", Format::R32_UINT),
    texel("visWordTex", Format::R32_UINT),
    texel("tapDepthTex", Format::R32_UINT),
];
const SSDO_BINDINGS: [Binding; 10] = [
    uniform("GlobalsBlock"),
    texel("recordTex", Format::R32G32B32A32_UINT),
    uniform("SampleTable"),
    wo("Ao"),
    texel("visTex", Format::R32G32_UINT),
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("attrTex", Format::R32_UINT),
    texel("visWordTex", Format::R32_UINT),
    wo("Keys"),
    TILE_BINDING,
];

impl SsdoPass {
    pub const PREP_NAME: &'static str = "ssdo_prep";
    pub const NAME: &'static str = "ssdo";

    pub fn new(ctx: &Context) -> Result<Self> {
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
        })
    }

    pub fn table(&self) -> &Buffer {
        &self.table
    }

    fn prep_bindings(lookup: &Lookup) -> Vec<Binding> {
        let mut b = SURFACE_BINDINGS.to_vec();
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
            Self::PREP_NAME,
            variant(lookup.kind, false),
            &Self::prep_bindings(lookup),
            std::mem::size_of::<PrepPush>() as u32,
            &Self::prep_constants(lookup, taps),
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
                    },
                )?);
            }
            if self.args.is_none() {
                self.args = Some(BandArgs::new(ctx, "ssdo_sphere args")?);
            }
            return self.sphere.ensure(
                ctx,
                Self::NAME,
                spirv::SSDO_SPHERE_COMP,
                &SPHERE_BINDINGS,
                std::mem::size_of::<SsdoPush>() as u32,
                &taps.sphere_constants(semantic),
            );
        }
        self.ssdo.ensure_tiled(
            ctx,
            Self::NAME,
            spirv::SSDO_COMP,
            &SSDO_BINDINGS,
            std::mem::size_of::<SsdoPush>() as u32,
            &taps.constants(semantic),
            lists,
        )
    }

    /// With per-sphere receivers the records feed only the bounce (4 bits a
    /// channel): their key-light visibility skips the soft penumbra and
    /// reads only the ISSM's 2x2 texels around the point (1M capsid at
    /// 1080p: 21 pixels of the image change, by at most 17 levels).
    fn prep_constants(lookup: &Lookup, taps: Taps) -> [u32; 5] {
        let quad = lookup.quad() || (lookup.kind == LookupKind::Issm && taps.per_sphere());
        [
            (lookup.soft && !taps.per_sphere()) as u32,
            (lookup.core_only() || quad) as u32,
            taps.per_sphere() as u32,
            taps.perspective as u32,
            quad as u32,
        ]
    }

    /// `ssdo_prep`: the half-resolution records, and with per-sphere
    /// receivers the flags of the spheres seen (into `flags`: the sphere
    /// buffers' then; any buffer the pass may write otherwise) and the
    /// taps' block-ordered depth words (into `tap_depth`).
    #[allow(clippy::too_many_arguments)]
    pub fn record_prep(
        &self,
        rec: &mut Recorder,
        io: &ScreenInputs,
        lookup: &Lookup,
        (records, flags, tap_depth): (&Buffer, &Buffer, &Buffer),
        push: &PrepPush,
        taps: Taps,
        half: (u32, u32),
        tiles: Tiles,
    ) -> Result<()> {
        let mut bufs = io.surface_buffers();
        bufs.extend([
            ("Records", records),
            ("Flags", flags),
            ("TapDepth", tap_depth),
        ]);
        bufs.extend(lookup.buffers.iter().copied());
        rec.pass(Self::PREP_NAME, |p| {
            if taps.per_sphere() {
                p.fill(flags, flags.size, 0);
            }
            self.prep.dispatch_tiled(
                p,
                Self::PREP_NAME,
                variant(lookup.kind, false),
                &Self::prep_constants(lookup, taps),
                push,
                tiles,
                (half, true),
                &bufs,
            )
        })
    }

    /// `ssdo` with per-sphere receivers: the flagged spheres listed, the
    /// list's dispatch arguments, then one invocation per listed sphere
    /// into `sb.ao`; the taps read `tap_depth` (what `ssdo_prep` wrote).
    #[allow(clippy::too_many_arguments)]
    pub fn record_spheres(
        &self,
        rec: &mut Recorder,
        io: &ScreenInputs,
        (records, tap_depth): (&Buffer, &Buffer),
        sb: &SphereBuffers,
        push: &SsdoPush,
        semantic: bool,
        taps: Taps,
    ) -> Result<()> {
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
            pad: [0; 2],
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
                ],
            );
            args.step(p, &sb.counters, &LIST_COUNTERS);
            p.dispatch(
                pipe,
                push,
                Grid::Indirect(&sb.counters, LIST_COUNTERS.args_offset()),
                &[
                    ("GlobalsBlock", io.globals),
                    ("recordTex", records),
                    ("SphereAo", &sb.ao),
                    ("List", &sb.list),
                    ("Counters", &sb.counters),
                    ("sphereTex", io.spheres),
                    ("attrTex", io.attrs),
                    ("visWordTex", io.vis),
                    ("tapDepthTex", tap_depth),
                ],
            );
            Ok(())
        })
    }

    /// `ssdo`: ambient visibility + bounce per receiver into `ao` (and per
    /// pixel the blur's edge keys into `keys`); `size`
    /// is the receivers' grid (half resolution per block).
    #[allow(clippy::too_many_arguments)]
    pub fn record_ssdo(
        &self,
        rec: &mut Recorder,
        io: &ScreenInputs,
        records: &Buffer,
        (ao, keys): (&Buffer, &Buffer),
        push: &SsdoPush,
        semantic: bool,
        taps: Taps,
        size: (u32, u32),
        tiles: Tiles,
    ) -> Result<()> {
        rec.pass(Self::NAME, |p| {
            self.ssdo.dispatch_tiled(
                p,
                Self::NAME,
                spirv::SSDO_COMP,
                &taps.constants(semantic),
                push,
                tiles,
                (size, taps.per_block()),
                &[
                    ("GlobalsBlock", io.globals),
                    ("recordTex", records),
                    ("SampleTable", &self.table),
                    ("Ao", ao),
                    ("visTex", io.vis),
                    ("sphereTex", io.spheres),
                    ("attrTex", io.attrs),
                    ("visWordTex", io.vis),
                    ("Keys", keys),
                ],
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

/// A record as the GPU packs it (glsl/ssdo_record.glsl), unpacked on the
/// CPU for tests and debugging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Record {
    pub z: f32,
    pub normal: [f32; 3],
    pub region_a: u32,
    pub region_b: u32,
    pub sub: [u32; 2],
    pub radiance: [f32; 3],
    pub visibility: f32,
    pub covered: bool,
}

/// 15-bit hash of a region id, as `region_hash` in GLSL.
pub fn region_hash(r: u32) -> u32 {
    r.wrapping_mul(2_654_435_761) >> 17
}

fn unpack_snorm16(u: u32) -> f32 {
    (u as u16 as i16 as f32 / 32767.0).clamp(-1.0, 1.0)
}

/// Octahedral normal decode, as `unpack_normal` in GLSL.
pub fn unpack_normal(u: u32) -> [f32; 3] {
    let (ex, ey) = (unpack_snorm16(u & 0xFFFF), unpack_snorm16(u >> 16));
    let mut n = [ex, ey, 1.0 - ex.abs() - ey.abs()];
    if n[2] < 0.0 {
        let (x, y) = (n[0], n[1]);
        n[0] = (1.0 - y.abs()) * if x >= 0.0 { 1.0 } else { -1.0 };
        n[1] = (1.0 - x.abs()) * if y >= 0.0 { 1.0 } else { -1.0 };
    }
    let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    [n[0] / l, n[1] / l, n[2] / l]
}

fn pack_snorm16(v: f32) -> u32 {
    ((v.clamp(-1.0, 1.0) * 32767.0).round() as i16) as u16 as u32
}

/// Octahedral normal encode, as `pack_normal` in GLSL.
pub fn pack_normal(n: [f32; 3]) -> u32 {
    let l1 = n[0].abs() + n[1].abs() + n[2].abs();
    let (mut x, mut y) = (n[0] / l1, n[1] / l1);
    if n[2] < 0.0 {
        let (ox, oy) = (x, y);
        x = (1.0 - oy.abs()) * if ox >= 0.0 { 1.0 } else { -1.0 };
        y = (1.0 - ox.abs()) * if oy >= 0.0 { 1.0 } else { -1.0 };
    }
    pack_snorm16(x) | (pack_snorm16(y) << 16)
}

fn unorm8(v: f32) -> u32 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u32
}

/// RGBA8 packing, as `pack_rgba8` in GLSL (R in the low byte).
pub fn pack_rgba8(c: [f32; 4]) -> u32 {
    unorm8(c[0]) | (unorm8(c[1]) << 8) | (unorm8(c[2]) << 16) | (unorm8(c[3]) << 24)
}

impl Record {
    /// Packs as `pack_record` in GLSL (tests feed the blur with it).
    pub fn pack(&self) -> [u32; 4] {
        if !self.covered {
            return [f32::INFINITY.to_bits(), 0, 0, 0];
        }
        let [r, g, b] = self.radiance;
        [
            self.z.to_bits(),
            pack_normal(self.normal),
            (self.region_a & 0x7FFF)
                | ((self.region_b & 0x7FFF) << 15)
                | ((self.sub[0] | (self.sub[1] << 1)) << 30),
            pack_rgba8([r, g, b, self.visibility]),
        ]
    }

    pub fn unpack(t: [u32; 4]) -> Record {
        let z = f32::from_bits(t[0]);
        let c = t[3].to_le_bytes();
        Record {
            z,
            covered: !z.is_infinite(),
            normal: unpack_normal(t[1]),
            region_a: t[2] & 0x7FFF,
            region_b: (t[2] >> 15) & 0x7FFF,
            sub: [(t[2] >> 30) & 1, t[2] >> 31],
            radiance: [
                c[0] as f32 / 255.0,
                c[1] as f32 / 255.0,
                c[2] as f32 / 255.0,
            ],
            visibility: c[3] as f32 / 255.0,
        }
    }
}
