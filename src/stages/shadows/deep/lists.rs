//! The deep lists' device buffers: entries and visibility nodes in
//! structure-of-arrays chunks, each followed by guard words.

use super::*;

/// The entry arrays (structure of arrays), `capacity` chunks of 64 each, and
/// the visibility node arrays, [`NODES_PER_ENTRY`] slots per entry slot,
/// split by slot parity (slot s at s / 2 of array s % 2) so that no array
/// is longer than an entry array.
pub(super) struct Lists {
    pub(super) depth: Buffer,
    pub(super) alpha: Buffer,
    pub(super) ids: Buffer,
    pub(super) next: Buffer,
    pub(super) trans: Buffer,
    pub(super) node_depth: [Buffer; 2],
    pub(super) node_vis: [Buffer; 2],
}

impl Lists {
    pub(super) fn new(ctx: &Context, chunks: u32) -> Result<Self> {
        let n = chunks as u64 * CHUNK as u64;
        let mut made = ctx.guard(Vec::new());
        for (name, words) in [
            ("deep depth", n),
            ("deep alpha", n),
            ("deep sphere id", n),
            ("deep next", n),
            ("deep transmittance", n),
            ("deep node depth even", n),
            ("deep node visibility even", n),
            ("deep node depth odd", n),
            ("deep node visibility odd", n),
        ] {
            // (the lookup reads the entry arrays as texels)
            made.push(guarded(
                ctx,
                name,
                words,
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            )?);
        }
        let mut it = made.keep().into_iter();
        let mut take = || it.next().expect("nine buffers");
        let (depth, alpha, ids, next, trans) = (take(), take(), take(), take(), take());
        let (d0, v0, d1, v1) = (take(), take(), take(), take());
        Ok(Lists {
            depth,
            alpha,
            ids,
            next,
            trans,
            node_depth: [d0, d1],
            node_vis: [v0, v1],
        })
    }

    /// The entry arrays (one u32/f32 per entry slot).
    pub(super) fn entries(&self) -> [&Buffer; 5] {
        [&self.depth, &self.alpha, &self.ids, &self.next, &self.trans]
    }

    /// The node arrays (together [`NODES_PER_ENTRY`] words per entry slot).
    pub(super) fn nodes(&self) -> [&Buffer; 4] {
        [
            &self.node_depth[0],
            &self.node_vis[0],
            &self.node_depth[1],
            &self.node_vis[1],
        ]
    }

    /// One node quantity (slots in order) from its two parity arrays.
    pub(super) fn download_nodes(
        ctx: &Context,
        arrays: &[Buffer; 2],
        entries: u64,
    ) -> Result<Vec<f32>> {
        let even: Vec<f32> = arrays[0].download_pod(ctx, 0, entries)?;
        let odd: Vec<f32> = arrays[1].download_pod(ctx, 0, entries)?;
        Ok(even
            .into_iter()
            .zip(odd)
            .flat_map(|(a, b)| [a, b])
            .collect())
    }

    pub(super) fn destroy(&mut self, ctx: &Context) {
        for b in [
            &mut self.depth,
            &mut self.alpha,
            &mut self.ids,
            &mut self.next,
            &mut self.trans,
        ]
        .into_iter()
        .chain(self.node_depth.iter_mut())
        .chain(self.node_vis.iter_mut())
        {
            b.destroy(ctx);
        }
    }
}

/// A device-local buffer of `words` u32 followed by the guard words.
pub(super) fn guarded(
    ctx: &Context,
    name: &str,
    words: u64,
    usage: vk::BufferUsageFlags,
) -> Result<Buffer> {
    Buffer::guarded(ctx, name, words, GUARD_WORDS, GUARD_PATTERN, usage)
}
