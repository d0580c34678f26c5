//! The CPU side of SSDO's GPU data: the sample table (uploaded once) and
//! the records as glsl/ssdo_record.glsl packs them (tests unpack them).

/// Entries of the sample table (at most this many directions).
pub const TABLE_SIZE: usize = 64;

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
