//! Tile lists (glsl/tiles.glsl): the per-pixel passes after the
//! rasterizer run their full shader on the regions `coverage` found
//! covered and a background-only variant on the rest (TILE_LIST, the last
//! specialization constant of a tiled shader), or one shader on every tile.

use super::LOCAL_SIZE;
use super::bands::counters_buffer;
use crate::error::Result;
use crate::gpu::consts::{TL_ARGS, TL_LIST, TL_REGION};
use crate::vk::pipeline::{Binding, ro};
use crate::vk::{Buffer, Context, Grid};

/// Regions of a w x h buffer.
pub fn regions(w: u32, h: u32) -> u64 {
    w.div_ceil(TL_REGION) as u64 * h.div_ceil(TL_REGION) as u64
}

/// The tile-list buffer of a w x h target: counts, dispatch arguments and
/// one word per region (4 B per 256 pixels).
pub fn lists_buffer(ctx: &Context, w: u32, h: u32) -> Result<Buffer> {
    counters_buffer(ctx, "tile lists", (TL_LIST as u64 + regions(w, h)) * 4)
}

/// The binding every tiled shader declares (`TileLists`, tiles.glsl).
pub const TILE_BINDING: Binding = ro("TileLists");

/// Groups for an image in 8x8 tiles (glsl/tiles.glsl), folded into y.
pub fn tile_grid(w: u32, h: u32) -> Grid<'static> {
    Grid::Invocations(w.div_ceil(8) as u64 * h.div_ceil(8) as u64 * LOCAL_SIZE as u64)
}

/// Which tiles of its grid a per-pixel pass runs.
#[derive(Clone, Copy)]
pub enum Tiles<'a> {
    /// Every tile, one shader (TILE_LIST = 0).
    All,
    /// The covered regions with the full shader (TILE_LIST = 1), the
    /// background ones with its background path (TILE_LIST = 2), from
    /// these lists (this frame's `coverage`).
    Lists(&'a Buffer),
}

impl<'a> Tiles<'a> {
    /// The TILE_LIST constants whose pipelines a pass needs.
    pub fn constants(lists: bool) -> &'static [u32] {
        if lists { &[1, 2] } else { &[0] }
    }

    /// The dispatches of a pass on a w x h grid (half: the half-resolution
    /// blocks, a region is one tile of them): (TILE_LIST, grid).
    pub fn dispatches(self, (w, h): (u32, u32), half: bool) -> Vec<(u32, Grid<'a>)> {
        match self {
            Tiles::All => vec![(0, tile_grid(w, h))],
            Tiles::Lists(b) => {
                let at = |k: u32| Grid::Indirect(b, (TL_ARGS + 3 * k) as u64 * 4);
                let first = if half { 2 } else { 0 };
                vec![(1, at(first)), (2, at(first + 1))]
            }
        }
    }

    /// The buffer bound as `TileLists` (any buffer for [`Tiles::All`]:
    /// unread).
    pub fn buffer(self, fallback: &'a Buffer) -> &'a Buffer {
        match self {
            Tiles::All => fallback,
            Tiles::Lists(b) => b,
        }
    }
}
