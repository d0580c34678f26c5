//! `lod_cull`: the views' sphere lists of an instanced scene with levels of
//! detail (glsl/lod_cull.comp, glsl/lod_args.comp). One invocation per
//! instance tests its bounding sphere against the camera's window and
//! chooses its level from its size on screen, then against the key
//! light's view with the camera's level; the kept instances' batches of
//! that level are listed per view, and the rasterizer visits a list in
//! place of the view's order, dispatched indirectly. Culled instances cost
//! one invocation of this pass and nothing after it.

use crate::error::Result;
use crate::gpu::blocks::{LodArgsPush, LodCullPush};
use crate::gpu::consts::{LOD_ARGS, LOD_SPHERES, LOD_WORDS};
use crate::passes::scene::{LodBuffers, SCENE_GEOMETRY, SceneBuffers};
use crate::passes::{LOCAL_SIZE, spirv};
use crate::vk::pipeline::{Binding, PipelineDesc, rw, texel, uniform};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder};
use ash::vk::Format;

use super::compute::ViewIndex;

const BINDINGS: [Binding; 7] = [
    uniform("GlobalsBlock"),
    texel("lodLevelTex", Format::R32G32B32A32_UINT),
    texel("lodBoundTex", Format::R32G32B32A32_SFLOAT),
    texel("lodInstanceTex", Format::R32G32B32A32_UINT),
    rw("Levels"),
    rw("List"),
    rw("Counters"),
];

/// Spheres and batches a frame's cull kept, per view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LodCounts {
    pub camera_batches: u32,
    pub camera_spheres: u32,
    pub light_batches: u32,
    pub light_spheres: u32,
}

pub struct LodCull {
    /// Orthographic and perspective cameras (constant 1).
    cull: [ComputePipeline; 2],
    args: ComputePipeline,
    /// Per view (camera, light): its batch list.
    lists: [Buffer; 2],
    /// Per view LOD_WORDS words: batches, spheres, dispatch arguments.
    counters: Buffer,
    /// Per instance: the camera's level.
    levels: Buffer,
    capacity: u32,
    instances: u32,
    empty_batch: u32,
    per: u32,
}

/// A view's list as the rasterizer takes it.
#[derive(Clone, Copy)]
pub struct LodView<'b> {
    pub list: &'b Buffer,
    pub counters: &'b Buffer,
    /// Byte offset of its indirect dispatch arguments in `counters`.
    pub args_offset: u64,
}

impl LodCull {
    pub const NAME: &'static str = "lod_cull";

    /// The pass for a scene with levels of detail (`lod`, its SCENE_SPEC
    /// `scene`).
    pub fn new(ctx: &Context, scene: u32, lod: &LodBuffers) -> Result<Self> {
        let bindings = [&BINDINGS[..], &SCENE_GEOMETRY].concat();
        let make = |name: &str, persp: u32| {
            ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: spirv::LOD_CULL_COMP,
                    bindings: &bindings,
                    push_size: std::mem::size_of::<LodCullPush>() as u32,
                    local_size: 64,
                    constants: &[persp],
                    scene,
                },
            )
        };
        let ortho = ctx.guard(make("lod cull", 0)?);
        let persp = ctx.guard(make("lod cull perspective", 1)?);
        let args = ctx.guard(ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: "lod args",
                shader: spirv::LOD_ARGS_COMP,
                bindings: &[rw("Counters")],
                push_size: std::mem::size_of::<LodArgsPush>() as u32,
                local_size: 1,
                constants: &[],
                scene: 0,
            },
        )?);
        // (room past the count for the last workgroup's lanes)
        let capacity = lod.base_batches + 64;
        let list = |name| Buffer::storage(ctx, name, capacity as u64 * 4);
        let camera = ctx.guard(list("camera LOD list")?);
        let light = ctx.guard(list("light LOD list")?);
        let counters = ctx.guard(crate::passes::bands::counters_buffer(
            ctx,
            "LOD counters",
            2 * LOD_WORDS as u64 * 4,
        )?);
        let levels = Buffer::storage(ctx, "LOD levels", lod.instance_count.max(1) as u64 * 4)?;
        Ok(LodCull {
            cull: [ortho.keep(), persp.keep()],
            args: args.keep(),
            lists: [camera.keep(), light.keep()],
            counters: counters.keep(),
            levels,
            capacity,
            instances: lod.instance_count,
            empty_batch: lod.empty_batch,
            per: 1 << (scene >> 8),
        })
    }

    /// The steps of the pass: both views' lists (the light's when
    /// `light`) and their dispatch arguments.
    pub fn steps<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        globals: &'b Buffer,
        scene: &'b SceneBuffers,
        perspective: bool,
        light: bool,
    ) -> Result<()> {
        let lod = scene.lod.as_ref().ok_or_else(|| {
            crate::error::Error::Internal("the scene has no levels of detail".into())
        })?;
        p.fill(&self.counters, self.counters.size, 0);
        let views: &[ViewIndex] = if light {
            &[ViewIndex::Camera, ViewIndex::Light]
        } else {
            &[ViewIndex::Camera]
        };
        for &v in views {
            let list = &self.lists[v as usize];
            p.fill(list, list.size, self.empty_batch);
            let mut bindings = vec![
                ("GlobalsBlock", globals),
                ("lodLevelTex", &lod.levels),
                ("lodBoundTex", &lod.bounds),
                ("lodInstanceTex", &lod.instances),
                ("Levels", &self.levels),
                ("List", list),
                ("Counters", &self.counters),
            ];
            bindings.extend(scene.geometry());
            let pipe = &self.cull[(v == ViewIndex::Camera && perspective) as usize];
            p.dispatch(
                pipe,
                &LodCullPush {
                    view_index: v as u32,
                    instances: self.instances,
                    capacity: self.capacity,
                    pad: 0,
                },
                Grid::Invocations(self.instances as u64),
                &bindings,
            );
        }
        p.dispatch(
            &self.args,
            &LodArgsPush {
                per: self.per,
                capacity: self.capacity,
                local_size: LOCAL_SIZE,
                pad: 0,
            },
            Grid::Groups([1, 1, 1]),
            &[("Counters", &self.counters)],
        );
        Ok(())
    }

    /// `view`'s list.
    pub fn view(&self, view: ViewIndex) -> LodView<'_> {
        LodView {
            list: &self.lists[view as usize],
            counters: &self.counters,
            args_offset: ((view as u32 * LOD_WORDS + LOD_ARGS) * 4) as u64,
        }
    }

    /// What the last frame's cull kept (after the frame).
    pub fn counts(&self, ctx: &Context) -> Result<LodCounts> {
        let w: Vec<u32> = self.counters.download_pod(ctx, 0, 2 * LOD_WORDS as u64)?;
        let l = LOD_WORDS as usize;
        Ok(LodCounts {
            camera_batches: w[0],
            camera_spheres: w[LOD_SPHERES as usize],
            light_batches: w[l],
            light_spheres: w[l + LOD_SPHERES as usize],
        })
    }

    /// Device memory: the lists, counters and levels.
    pub fn memory_bytes(&self) -> u64 {
        self.lists.iter().map(|b| b.size).sum::<u64>() + self.counters.size + self.levels.size
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for p in &mut self.cull {
            p.destroy(ctx);
        }
        self.args.destroy(ctx);
        for b in &mut self.lists {
            b.destroy(ctx);
        }
        self.counters.destroy(ctx);
        self.levels.destroy(ctx);
    }
}

crate::impl_destroy!(LodCull);
