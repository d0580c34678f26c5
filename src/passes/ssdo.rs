//! Semantic SSDO with one bounce at half resolution (seed 001):
//! `ssdo_prep` picks one representative pixel per 2x2 block and packs its
//! record (glsl/ssdo_record.glsl: view distance, octahedral normal, region
//! hashes, the key light it reflects). `ssdo` runs for every pixel when
//! spheres are small on screen, else once per block for its representative,
//! over the sample table's directions (a uniform buffer made once here);
//! the blur (passes/blur.rs) smooths the result and shade upsamples the
//! blocks'. See glsl/ssdo.comp.

use super::shade::{SURFACE_BINDINGS, ScreenInputs, Variants, tile_grid, variant};
use super::shadows::Lookup;
use super::spirv;
use crate::error::{Error, Result};
use crate::vk::pipeline::{Binding, texel, uniform, wo};
use crate::vk::{Buffer, Context, Recorder};
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

/// Tap counts per receiver (directions, far-search steps per direction)
/// and whether the receivers are the 2x2 blocks (else every pixel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Taps {
    pub dirs: u32,
    pub steps: u32,
    pub half: bool,
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
            self.half as u32,
        ]
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
}

const PREP_OUTPUT: Binding = wo("Records");
const SSDO_BINDINGS: [Binding; 9] = [
    uniform("GlobalsBlock"),
    texel("recordTex", Format::R32G32B32A32_UINT),
    uniform("SampleTable"),
    wo("Ao"),
    texel("visTex", Format::R32G32_UINT),
    texel("sphereTex", Format::R32G32B32A32_SFLOAT),
    texel("attrTex", Format::R32G32B32A32_UINT),
    texel("visWordTex", Format::R32_UINT),
    wo("Keys"),
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
        })
    }

    pub fn table(&self) -> &Buffer {
        &self.table
    }

    fn prep_bindings(lookup: &Lookup) -> Vec<Binding> {
        let mut b = SURFACE_BINDINGS.to_vec();
        b.push(PREP_OUTPUT);
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
    ) -> Result<()> {
        if taps.dirs as usize > TABLE_SIZE || taps.dirs == 0 || taps.steps == 0 {
            return Err(Error::Internal(format!("ssdo: bad tap counts {taps:?}")));
        }
        self.prep.ensure(
            ctx,
            Self::PREP_NAME,
            variant(lookup.kind, false),
            &Self::prep_bindings(lookup),
            std::mem::size_of::<PrepPush>() as u32,
            &[lookup.soft as u32, lookup.core_only() as u32],
        )?;
        self.ssdo.ensure(
            ctx,
            Self::NAME,
            spirv::SSDO_COMP,
            &SSDO_BINDINGS,
            std::mem::size_of::<SsdoPush>() as u32,
            &taps.constants(semantic),
        )
    }

    /// `ssdo_prep`: the half-resolution records.
    pub fn record_prep(
        &self,
        rec: &mut Recorder,
        io: &ScreenInputs,
        lookup: &Lookup,
        records: &Buffer,
        push: &PrepPush,
        half: (u32, u32),
    ) -> Result<()> {
        let pipe = self
            .prep
            .get(
                variant(lookup.kind, false),
                &[lookup.soft as u32, lookup.core_only() as u32],
            )
            .ok_or_else(|| Error::Internal("ssdo_prep: pipeline not prepared".into()))?;
        let mut bufs = vec![
            ("GlobalsBlock", io.globals),
            ("visTex", io.vis),
            ("sphereTex", io.spheres),
            ("attrTex", io.attrs),
            ("Records", records),
        ];
        bufs.extend(lookup.buffers.iter().copied());
        rec.pass(Self::PREP_NAME, |p| {
            p.dispatch(pipe, push, tile_grid(half.0, half.1), &bufs);
            Ok(())
        })
    }

    /// `ssdo`: ambient visibility + bounce per receiver into `ao` (and per
    /// pixel the blur's edge keys into `keys`); `size`
    /// is the receivers' grid (half resolution with `taps.half`).
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
    ) -> Result<()> {
        let pipe = self
            .ssdo
            .get(spirv::SSDO_COMP, &taps.constants(semantic))
            .ok_or_else(|| Error::Internal("ssdo: pipeline not prepared".into()))?;
        rec.pass(Self::NAME, |p| {
            p.dispatch(
                pipe,
                push,
                tile_grid(size.0, size.1),
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
            );
            Ok(())
        })
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.prep.destroy(ctx);
        self.ssdo.destroy(ctx);
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
