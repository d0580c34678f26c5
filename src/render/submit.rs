//! Frames: recorded into a frame slot, submitted, waited for, their
//! timestamps read; the deep lists may ask for a frame again.

use super::{Renderer, graph};
use crate::error::{Error, Result};
use crate::settings::RasterMode;
use crate::stages::raster::compute::ViewIndex;
use crate::stages::shadows::FrameCheck;
use crate::vk::{PassTimes, Recorder};
use ash::vk;

/// Frames the deep lists, the see-through fragments or the LOD lists may
/// ask to render again (growth) before the frame fails.
const MAX_RETRIES: usize = 4;

impl Renderer<'_> {
    /// Sorts the views' sphere orders that are stale (the view turned far,
    /// or the spheres moved) before a frame draws them: the camera's when
    /// the compute rasterizer draws it, the light's when the technique
    /// draws that view (others never pay for it), neither when the frame
    /// draws the LOD cull's lists instead.
    fn ensure_orders(&mut self) -> Result<()> {
        if self.res.lod_lists(&self.settings) {
            return Ok(());
        }
        if !self.res.scene.static_made {
            // The static batch table the orders' batches name (its error,
            // past 2^32 ids, before any order is sorted); frames in flight
            // may read its placeholder.
            self.wait_idle()?;
            self.res.scene.ensure_static(self.ctx, &self.res.geom)?;
        }
        let views = [
            (
                ViewIndex::Camera,
                self.settings.camera.dir,
                self.settings.raster == RasterMode::Compute,
            ),
            (
                ViewIndex::Light,
                self.settings.light,
                self.settings.shadows.orders_light_view(),
            ),
        ];
        for (view, dir, drawn) in views {
            if drawn && self.res.stages.raster.compute.order_stale(view, dir) {
                // Frames in flight read the order.
                self.wait_idle()?;
                let t = std::time::Instant::now();
                self.res
                    .stages
                    .raster
                    .compute
                    .set_order(self.ctx, view, &self.res.geom, dir)?;
                log::debug!(
                    "{view:?} sphere order sorted in {:.1} ms",
                    t.elapsed().as_secs_f64() * 1e3
                );
            }
        }
        Ok(())
    }

    /// Renders one frame and waits for it; when the active technique asks
    /// (the deep lists grew their pool), renders it again.
    pub fn render_frame(&mut self) -> Result<PassTimes> {
        for _ in 0..=MAX_RETRIES {
            let slot = self.submit()?;
            let times = self
                .finish_slot(slot)?
                .ok_or_else(|| Error::Internal("frame results missing".into()))?;
            if self.after_frame(slot)? == FrameCheck::Done {
                return Ok(times);
            }
        }
        Err(Error::DeviceLimit(
            "the deep shadow lists', see-through fragments', LOD lists' or band jobs' pool still \
             overflows after growing it"
                .into(),
        ))
    }

    /// The deep lists, the see-through fragments, the LOD lists and the
    /// band jobs check their pools (from `slot`'s frame, finished, the GPU
    /// idle); a frame any of them overflowed is rendered again.
    fn after_frame(&mut self, slot: usize) -> Result<FrameCheck> {
        use super::frame::readback as w;
        let words = self.slots[slot].readback()?;
        let shadows = self
            .res
            .stages
            .shadows
            .after_frame(self.ctx, &words[w::LIGHT..][..w::LIGHT_COUNT])?;
        let see = self.res.see_through(&self.settings);
        let grown = match &mut self.res.stages.see_through {
            Some(s) if see => {
                s.after_frame(self.ctx, &words[w::SEE_THROUGH..][..w::SEE_THROUGH_COUNT])?
            }
            _ => false,
        };
        let lod = self.res.stages.raster.after_frame(
            self.ctx,
            &mut self.res.scene,
            words[w::RASTER_BANDS] != 0,
            &words[w::LOD..],
        )?;
        Ok(if grown || lod {
            FrameCheck::Retry
        } else {
            shadows
        })
    }

    /// Whether each frame must be checked before the next is recorded.
    fn checks_frames(&self) -> bool {
        self.res.stages.shadows.checks_frames()
            || self.res.see_through(&self.settings)
            || self.res.lod_lists(&self.settings)
    }

    /// Records and submits the next frame without waiting for it; returns
    /// the per-pass times of the frame that used this slot before (already
    /// finished, or waited for: at most one other frame stays in flight).
    /// A technique that checks each frame (deep lists) makes this wait like
    /// `render_frame`. The finished frame's band flags are read from its
    /// slot: if its bands did not fit (a sphere's own invocation drew them,
    /// and on lavapipe a footprint past 65,535 pixels loses rows), the jobs
    /// grow and this frame is drawn and checked like `render_frame` (the
    /// frames already in flight, at most two, show what they drew).
    pub fn render_frame_pipelined(&mut self) -> Result<Option<PassTimes>> {
        if self.checks_frames() {
            return self.render_frame().map(Some);
        }
        let slot = self.next_slot;
        let previous = self.finish_slot(slot)?;
        if previous.is_some() && self.bands_overflowed(slot)? {
            self.wait_idle()?;
            self.after_frame(slot)?;
            // (the frames in flight saw the same flags: acted on once)
            for s in &mut self.slots {
                s.clear_readback()?;
            }
            return self.render_frame().map(Some);
        }
        self.submit()?;
        Ok(previous)
    }

    /// Whether `slot`'s finished frame flagged band jobs past a list (a
    /// technique that does not check every frame copies only such flags).
    fn bands_overflowed(&self, slot: usize) -> Result<bool> {
        use super::frame::readback as w;
        let words = self.slots[slot].readback()?;
        Ok(words[w::RASTER_BANDS] != 0
            || words[w::LIGHT..][..w::LIGHT_COUNT].iter().any(|&x| x != 0))
    }

    /// Waits for every frame in flight.
    pub fn wait_idle(&mut self) -> Result<()> {
        for i in 0..self.slots.len() {
            self.slots[i].wait(self.ctx)?;
        }
        Ok(())
    }

    /// Waits for the frame last submitted with `slot` and reads its timings.
    fn finish_slot(&mut self, slot: usize) -> Result<Option<PassTimes>> {
        let fs = &mut self.slots[slot];
        fs.wait(self.ctx)?;
        if !fs.pending {
            return Ok(None);
        }
        fs.pending = false;
        fs.profiler.results(self.ctx).map(Some)
    }

    /// Records and submits one frame in the next slot (whose previous frame
    /// must have finished); returns the slot.
    fn submit(&mut self) -> Result<usize> {
        self.ensure_orders()?;
        // (the lists a frame that fit asked for: its ids were their slots)
        if self.res.stages.raster.growth_pending() {
            self.wait_idle()?;
            self.res
                .stages
                .raster
                .before_frame(self.ctx, &mut self.res.scene)?;
        }
        let ids = self
            .res
            .scene
            .slots_when(self.res.lod_lists(&self.settings));
        if ids != self.last_ids {
            // (SSDO's per-sphere buffers are remade for them)
            self.wait_idle()?;
            self.last_ids = ids;
        }
        let ctx = self.ctx;
        let dev = &ctx.device;
        let slot = self.next_slot;
        self.next_slot = (slot + 1) % self.slots.len();
        let Renderer {
            settings,
            slots,
            res,
            ..
        } = self;
        let params = res.prepare(ctx, settings)?;
        let fs = &mut slots[slot];
        fs.wait(ctx)?;
        match fs.globals.mapped_mut() {
            Some(m) => m.copy_from_slice(bytemuck::bytes_of(&res.globals)),
            None => fs
                .globals
                .upload(ctx, 0, bytemuck::bytes_of(&res.globals))?,
        }
        // This slot's previous frame finished: its descriptor sets are free,
        // its readback words read.
        fs.arena.reset(ctx)?;
        fs.clear_readback()?;
        let cmd = fs.cmd;
        // SAFETY: the slot's previous submission finished (its fence).
        unsafe {
            dev.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .map_err(|result| Error::Vk {
                    call: "vkResetCommandBuffer",
                    result,
                })?;
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            dev.begin_command_buffer(cmd, &begin)
                .map_err(|result| Error::Vk {
                    call: "vkBeginCommandBuffer",
                    result,
                })?;
        }
        fs.profiler.begin_frame(ctx, cmd);
        let recorded = {
            let mut rec = Recorder::new(ctx, cmd, &mut fs.arena, Some(&mut fs.profiler));
            rec.restrict_to(graph::pass_names());
            res.record_frame(settings, &params, &fs.globals, &fs.readback, &mut rec)
        };
        // SAFETY: cmd is in the recording state.
        unsafe { dev.end_command_buffer(cmd) }.map_err(|result| Error::Vk {
            call: "vkEndCommandBuffer",
            result,
        })?;
        recorded?;
        // The light-space structure this frame builds serves the next ones
        // until something it depends on changes.
        res.stages.shadows.recorded();
        let cmds = [cmd];
        let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
        // SAFETY: the fence is unsignalled only by this submission.
        unsafe {
            dev.reset_fences(&[fs.fence]).map_err(|result| Error::Vk {
                call: "vkResetFences",
                result,
            })?;
            dev.queue_submit(ctx.queue, &submit, fs.fence)
                .map_err(|result| Error::Vk {
                    call: "vkQueueSubmit",
                    result,
                })?;
        }
        fs.pending = true;
        Ok(slot)
    }

    /// Records the frame into a throwaway command buffer that is never
    /// submitted and returns the recorder's log of steps and barriers
    /// (tests check it with [`crate::vk::barrier::check_hazards`]).
    pub fn frame_log(&mut self) -> Result<Vec<crate::vk::barrier::Event>> {
        // (prepare may remake buffers a frame in flight reads)
        self.wait_idle()?;
        self.ensure_orders()?;
        let ctx = self.ctx;
        let params = self.res.prepare(ctx, &self.settings)?;
        let cmd = ctx.command_buffer("frame log")?;
        let mut arena = crate::vk::descriptors::DescriptorArena::default();
        let begin = vk::CommandBufferBeginInfo::default();
        // SAFETY: a fresh command buffer, freed below, never submitted.
        let result = unsafe { ctx.device.begin_command_buffer(cmd, &begin) }
            .map_err(|result| Error::Vk {
                call: "vkBeginCommandBuffer",
                result,
            })
            .and_then(|_| {
                let mut rec = Recorder::new(ctx, cmd, &mut arena, None);
                rec.restrict_to(graph::pass_names());
                rec.keep_log();
                self.res.record_frame(
                    &self.settings,
                    &params,
                    &self.slots[0].globals,
                    &self.slots[0].readback,
                    &mut rec,
                )?;
                Ok(rec.take_log())
            });
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe {
            let _ = ctx.device.end_command_buffer(cmd);
            ctx.device.free_command_buffers(ctx.command_pool, &[cmd]);
        }
        arena.destroy(ctx);
        result
    }
}
