//! Pipelines of one shader made on first use, one per set of
//! specialization constants (a mode switch is a constant, not a copied
//! shader), and the dispatches of a tiled shader over the tile lists.

use super::tiles::Tiles;
use crate::error::Result;
use crate::vk::pipeline::{PipelineDesc, Shader};
use crate::vk::{Buffer, ComputePipeline, Context, PassBuilder};
use bytemuck::Pod;
use std::collections::HashMap;

/// One tiled dispatch: the pipeline (shader and constants, without
/// TILE_LIST), its push constants and buffers by binding name, and the
/// grid: `size` pixels, or blocks when `half`.
pub struct TiledDispatch<'a, 'b, P> {
    pub name: &'a str,
    pub shader: Shader,
    pub constants: &'a [u32],
    pub push: &'a P,
    pub tiles: Tiles<'b>,
    pub size: (u32, u32),
    pub half: bool,
    pub bufs: &'a [(&'static str, &'b Buffer)],
}

/// Pipelines made on first use, by (variant, constants).
#[derive(Default)]
pub struct Variants {
    made: HashMap<(usize, Vec<u32>), ComputePipeline>,
}

/// A variant is keyed by the address of its embedded SPIR-V: build.rs
/// makes each shader a `static`, whose bytes have one address (a `const`'s
/// may be copied per codegen unit, and then the key misses).
fn key(shader: Shader, constants: &[u32]) -> (usize, Vec<u32>) {
    (shader.spirv.as_ptr() as usize, constants.to_vec())
}

impl Variants {
    /// The pipeline of `desc` (specialization constants ids 1, 2, ...),
    /// made if new.
    pub fn ensure(&mut self, ctx: &Context, desc: &PipelineDesc) -> Result<()> {
        let key = key(desc.shader, desc.constants);
        if self.made.contains_key(&key) {
            return Ok(());
        }
        let pipe = ComputePipeline::new(ctx, desc)?;
        self.made.insert(key, pipe);
        Ok(())
    }

    pub fn get(&self, shader: Shader, constants: &[u32]) -> Option<&ComputePipeline> {
        self.made.get(&key(shader, constants))
    }

    /// [`Variants::ensure`] for a tiled shader (glsl/tiles.glsl): the
    /// pipelines with its TILE_LIST constant appended (the last id), for
    /// the covered and background lists or for every tile.
    pub fn ensure_tiled(&mut self, ctx: &Context, desc: &PipelineDesc, lists: bool) -> Result<()> {
        for &t in Tiles::constants(lists) {
            let mut c = desc.constants.to_vec();
            c.push(t);
            self.ensure(
                ctx,
                &PipelineDesc {
                    constants: &c,
                    ..*desc
                },
            )?;
        }
        Ok(())
    }

    /// A tiled shader's dispatches on a w x h grid (`half`: of blocks):
    /// one per tile list, `TileLists` bound to the lists (or, for every
    /// tile, to the first storage buffer given: unread).
    pub fn dispatch_tiled<'b, P: Pod>(
        &'b self,
        p: &mut PassBuilder<'b>,
        d: &TiledDispatch<'_, 'b, P>,
    ) -> Result<()> {
        let TiledDispatch {
            name,
            shader,
            constants,
            push,
            tiles,
            size,
            half,
            bufs,
        } = *d;
        // (for every tile the lists are unread: any storage buffer given)
        let fallback = bufs
            .iter()
            .map(|b| b.1)
            .find(|b| b.is_storage())
            .ok_or_else(|| crate::Error::Internal(format!("{name}: no storage buffer bound")))?;
        let mut all = bufs.to_vec();
        all.push(("TileLists", tiles.buffer(fallback)));
        for (t, grid) in tiles.dispatches(size, half) {
            let mut c = constants.to_vec();
            c.push(t);
            let pipe = self
                .get(shader, &c)
                .ok_or_else(|| crate::Error::Internal(format!("{name}: pipeline not prepared")))?;
            p.dispatch(pipe, push, grid, &all);
        }
        Ok(())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for (_, mut p) in self.made.drain() {
            p.destroy(ctx);
        }
    }
}
