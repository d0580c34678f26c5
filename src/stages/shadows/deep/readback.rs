//! Read-backs of the deep lists (tests and stats): counters, the raw
//! structure-of-arrays buffers, each texel's sorted list and visibility
//! nodes, and the guard words after every list and counter buffer.

use super::*;

/// Everything the GPU built in the last frame, for tests and debugging.
#[derive(Clone, Debug)]
pub struct DeepRaw {
    pub map_width: u32,
    pub map_height: u32,
    pub tiles_x: u32,
    pub tiles_y: u32,
    pub chunk_capacity: u32,
    pub counters: Vec<u32>,
    pub texels: Vec<DeepTexel>,
    pub tiles: Vec<DeepTile>,
    /// Entry arrays, the first min(chunks requested, capacity) * 64 entries.
    pub depth: Vec<f32>,
    pub alpha: Vec<f32>,
    pub ids: Vec<u32>,
    pub next: Vec<u32>,
    pub trans: Vec<f32>,
    /// Visibility node arrays, [`NODES_PER_ENTRY`] slots per entry above.
    pub node_depth: Vec<f32>,
    pub node_vis: Vec<f32>,
}

impl DeepRaw {
    /// Per texel, its visibility nodes (see
    /// [`DeepShadows::read_visibility_nodes`]), at most its 2 x count slots
    /// (the GPU never writes past them) and what lies inside the arrays read.
    pub fn visibility_nodes(&self) -> Vec<Vec<(f32, f32)>> {
        self.texels
            .iter()
            .map(|t| {
                if t.nodes == 0 || t.head == NONE {
                    return Vec::new();
                }
                let start = (t.head as usize * NODES_PER_ENTRY as usize).min(self.node_depth.len());
                let n = t.nodes.min(t.count.saturating_mul(NODES_PER_ENTRY as u32));
                let end = (start + n as usize).min(self.node_depth.len());
                (start..end)
                    .map(|i| (self.node_depth[i], self.node_vis[i]))
                    .collect()
            })
            .collect()
    }
}

/// Counters of the last frame beyond [`DeepStats`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeepCounters {
    pub chunks_requested: u32,
    pub overflowed: bool,
    pub entries: u32,
    pub max_depth_complexity: u32,
    /// Nodes of the epsilon-compressed visibility functions, all texels.
    pub compressed_nodes: u32,
    pub max_compressed_nodes: u32,
    pub nonempty_texels: u32,
    /// Entries not stored because their tile overflowed.
    pub dropped_entries: u32,
    /// Fill slots outside their texel's run (a bug if not 0).
    pub fill_errors: u32,
    /// Texels whose sort the device's loop limit cut short (lavapipe).
    pub sort_cut: u32,
    pub band_jobs: u32,
    /// A sphere's bands did not fit the job list (C_BANDS_FULL).
    pub bands_full: bool,
}

impl DeepCounters {
    /// From the counter words (COUNTER_WORDS from the start).
    pub fn of_words(c: &[u32]) -> Result<Self> {
        if c.len() < COUNTER_WORDS as usize {
            return Err(crate::Error::Internal(format!(
                "{} deep-list counter words, {COUNTER_WORDS} expected",
                c.len()
            )));
        }
        Ok(DeepCounters {
            chunks_requested: c[counter::CHUNKS],
            overflowed: c[counter::OVERFLOW] != 0,
            entries: c[counter::ENTRIES],
            max_depth_complexity: c[counter::MAX_COUNT],
            compressed_nodes: c[counter::NODES],
            max_compressed_nodes: c[counter::MAX_NODES],
            nonempty_texels: c[counter::NONEMPTY],
            dropped_entries: c[counter::DROPPED],
            fill_errors: c[counter::FILL_ERRORS],
            sort_cut: c[counter::SORT_CUT],
            band_jobs: c[counter::BANDS_RUN],
            bands_full: c[counter::BANDS_FULL] != 0,
        })
    }
}

impl DeepShadows {
    /// The counters of the last frame.
    pub fn read_counters(&self, ctx: &Context) -> Result<DeepCounters> {
        DeepCounters::of_words(&self.counters.download_pod(ctx, 0, COUNTER_WORDS)?)
    }

    pub fn read_stats(&self, ctx: &Context) -> Result<DeepStats> {
        Ok(self.stats_of(&self.read_counters(ctx)?))
    }

    /// The stats of counters read back.
    pub fn stats_of(&self, c: &DeepCounters) -> DeepStats {
        DeepStats {
            entries: c.entries as u64,
            chunks_used: c.chunks_requested as u64,
            chunk_capacity: self.capacity as u64,
            bytes: self.list_bytes(),
            fixed_layer_bytes: c.max_depth_complexity as u64 * self.texel_count() * BYTES_PER_ENTRY,
            overflowed: c.overflowed,
        }
    }

    /// Reads every deep-list buffer back (entries up to the chunks in use).
    pub fn read_raw(&self, ctx: &Context) -> Result<DeepRaw> {
        let counters: Vec<u32> = self.counters.download_pod(ctx, 0, COUNTER_WORDS)?;
        let used = (counters[counter::CHUNKS].min(self.capacity) as u64) * CHUNK as u64;
        let (tiles_x, tiles_y) = self.tiles_xy();
        let l = &self.lists;
        Ok(DeepRaw {
            map_width: self.light.width,
            map_height: self.light.height,
            tiles_x,
            tiles_y,
            chunk_capacity: self.capacity,
            texels: self.texels.download_pod(ctx, 0, self.texel_count())?,
            tiles: self
                .tiles
                .download_pod(ctx, 0, tiles_x as u64 * tiles_y as u64)?,
            depth: l.depth.download_pod(ctx, 0, used)?,
            alpha: l.alpha.download_pod(ctx, 0, used)?,
            ids: l.ids.download_pod(ctx, 0, used)?,
            next: l.next.download_pod(ctx, 0, used)?,
            trans: l.trans.download_pod(ctx, 0, used)?,
            node_depth: Lists::download_nodes(ctx, &l.node_depth, used)?,
            node_vis: Lists::download_nodes(ctx, &l.node_vis, used)?,
            counters,
        })
    }

    /// Per texel (row-major over the light map), the list in link order:
    /// (sphere id, depth, alpha). At most `count` links are followed.
    pub fn read_lists(&self, ctx: &Context) -> Result<Vec<Vec<(u32, f32, f32)>>> {
        let raw = self.read_raw(ctx)?;
        Ok(raw
            .texels
            .iter()
            .map(|t| {
                let mut out = Vec::new();
                let mut a = t.head;
                while a != NONE && (a as usize) < raw.ids.len() && out.len() < t.count as usize {
                    out.push((
                        raw.ids[a as usize],
                        raw.depth[a as usize],
                        raw.alpha[a as usize],
                    ));
                    a = raw.next[a as usize];
                }
                out
            })
            .collect())
    }

    /// Per texel (row-major over the light map), the nodes (depth, V) of its
    /// epsilon-compressed visibility function in order: V'(z) = 1 before the
    /// first node, linear between nodes, a step where two nodes share a
    /// depth, the last node's V after it. Empty for empty texels.
    pub fn read_visibility_nodes(&self, ctx: &Context) -> Result<Vec<Vec<(f32, f32)>>> {
        let raw = self.read_raw(ctx)?;
        Ok(raw.visibility_nodes())
    }

    pub(super) fn guarded_buffers(&self) -> Vec<(&Buffer, u64)> {
        let entries = self.entry_capacity() as u64;
        let mut v = vec![
            (&self.texels, self.texel_count() * 4),
            (&self.tiles, tile_count(&self.light) * 4),
            (&self.counters, COUNTER_WORDS),
            (&self.jobs.buf, self.jobs.entries() as u64 * 2),
            (
                &self.inline_bits,
                (self.sphere_count as u64).div_ceil(32).max(1),
            ),
        ];
        // (each node parity array holds one word per entry slot)
        v.extend(
            self.lists
                .entries()
                .into_iter()
                .chain(self.lists.nodes())
                .map(|b| (b, entries)),
        );
        v
    }

    /// Names of the buffers whose guard words were overwritten (empty = ok).
    pub fn damaged_guards(&self, ctx: &Context) -> Result<Vec<String>> {
        let mut bad = Vec::new();
        for (buf, words) in self.guarded_buffers() {
            let g: Vec<u32> = buf.download_pod(ctx, words, GUARD_WORDS)?;
            if g.iter().any(|&w| w != GUARD_PATTERN) {
                bad.push(buf.name.clone());
            }
        }
        Ok(bad)
    }
}
