//! Band jobs, shared by the camera raster, the deep lists and the opacity
//! maps (the GLSL skeleton is glsl/bands.glsl): a per-sphere dispatch
//! handles small footprints itself and queues 8-row bands of big ones; one
//! invocation turns the band count into indirect dispatch arguments; the
//! band pipeline (same shader, BAND_PASS = 1) then runs every band.

use crate::error::Result;
pub use crate::gpu::blocks::BandCounters;
use crate::vk::pipeline::{PipelineDesc, rw};
use crate::vk::{Buffer, ComputePipeline, Context, Grid, PassBuilder};
use bytemuck::Pod;
use std::sync::atomic::{AtomicU32, Ordering};

/// The most band jobs one buffer holds (8 bytes each).
pub fn max_jobs(ctx: &Context) -> u32 {
    (ctx.props.limits.max_storage_buffer_range / 8).max(1)
}

/// A band job list's next length after a frame's spheres did not fit it
/// (one invocation visited a footprint lavapipe's loop limit may cut):
/// twice `capacity` (a frame's overflow is rare: the 10^12 scene's first
/// frame at 2,024 A asks 1-2 M jobs of the camera raster, whose list then
/// holds 8 MB more), at most `most`; past that a one-line error
/// naming `what` (the pass).
pub fn grown_jobs(capacity: u32, most: u32, what: &str) -> Result<u32> {
    if capacity >= most {
        return Err(crate::error::Error::DeviceLimit(format!(
            "{what}: a frame's large spheres need more than {most} band jobs (one buffer's most)"
        )));
    }
    Ok(capacity.max(1).saturating_mul(2).min(most))
}

/// A pass's band job list (8 bytes a job), bound as "Jobs": its length
/// goes to the push constants and `BandCounters::job_capacity`; where a
/// frame's spheres did not fit, the pass grows it ([`JobList::grow`]) and
/// the frame is drawn again.
pub struct JobList {
    pub buf: Buffer,
    /// Jobs the buffer holds.
    entries: u32,
    /// Jobs a frame may queue: `entries`, unless a test lowered it
    /// ([`JobList::set_limit`]; atomic: set through a shared reference).
    limit: AtomicU32,
    name: &'static str,
    /// Guard words after the jobs and their pattern (the deep lists'
    /// buffers all carry them), or none.
    guard: Option<(u64, u32)>,
}

impl JobList {
    /// `first` jobs (at least 1, at most one buffer's).
    pub fn new(ctx: &Context, name: &'static str, first: u32) -> Result<Self> {
        Self::make(ctx, name, first, None)
    }

    /// The same, with `words` guard words of `pattern` after the jobs.
    pub fn guarded(
        ctx: &Context,
        name: &'static str,
        first: u32,
        (words, pattern): (u64, u32),
    ) -> Result<Self> {
        Self::make(ctx, name, first, Some((words, pattern)))
    }

    fn make(
        ctx: &Context,
        name: &'static str,
        first: u32,
        guard: Option<(u64, u32)>,
    ) -> Result<Self> {
        let entries = first.clamp(1, Self::most(ctx, guard));
        Ok(JobList {
            buf: Self::buffer(ctx, name, entries, guard)?,
            entries,
            limit: AtomicU32::new(entries),
            name,
            guard,
        })
    }

    /// The most jobs one buffer holds (with its guard words).
    fn most(ctx: &Context, guard: Option<(u64, u32)>) -> u32 {
        let words = guard.map_or(0, |g| g.0);
        max_jobs(ctx).saturating_sub(words.min(u32::MAX as u64) as u32)
    }

    fn buffer(
        ctx: &Context,
        name: &str,
        entries: u32,
        guard: Option<(u64, u32)>,
    ) -> Result<Buffer> {
        match guard {
            None => Buffer::storage(ctx, name, entries as u64 * 8),
            Some((words, pattern)) => Buffer::guarded(
                ctx,
                name,
                entries as u64 * 2,
                words,
                pattern,
                ash::vk::BufferUsageFlags::STORAGE_BUFFER,
            ),
        }
    }

    /// The jobs a frame may queue.
    pub fn capacity(&self) -> u32 {
        self.limit.load(Ordering::Relaxed)
    }

    /// The jobs the buffer holds (its guard words follow them: word
    /// `2 x entries`).
    pub fn entries(&self) -> u32 {
        self.entries
    }

    /// Test hook: at most `jobs` a frame (0 to the buffer's), so that a
    /// small scene exercises the full-list path; from the next frame.
    pub fn set_limit(&self, jobs: u32) {
        self.limit.store(jobs.min(self.entries), Ordering::Relaxed);
    }

    /// `base` (the pass's counter words) with this list's length.
    pub fn layout(&self, base: BandCounters) -> BandCounters {
        BandCounters {
            job_capacity: self.capacity(),
            ..base
        }
    }

    /// After a frame whose spheres did not fit: a list [`grown_jobs`]
    /// long (`what` names the pass in the error past one buffer's most).
    pub fn grow(&mut self, ctx: &Context, what: &str) -> Result<()> {
        let limit = self.capacity();
        let grown = grown_jobs(limit, Self::most(ctx, self.guard), what)?;
        if grown > self.entries {
            ctx.wait_idle();
            let buf = Self::buffer(ctx, self.name, grown, self.guard)?;
            let mut old = std::mem::replace(&mut self.buf, buf);
            old.destroy(ctx);
            self.entries = grown;
        }
        log::info!("{what}: band jobs {limit} -> {grown} (a frame asked more)");
        self.limit.store(grown, Ordering::Relaxed);
        Ok(())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.buf.destroy(ctx);
    }
}

impl BandCounters {
    /// Byte offset of the indirect dispatch arguments.
    pub fn args_offset(&self) -> u64 {
        self.args as u64 * 4
    }
}

/// A pass's counter words: storage (atomics) and indirect dispatch arguments.
pub fn counters_buffer(ctx: &Context, name: &str, bytes: u64) -> Result<Buffer> {
    Buffer::new(
        ctx,
        name,
        bytes,
        ash::vk::BufferUsageFlags::STORAGE_BUFFER | ash::vk::BufferUsageFlags::INDIRECT_BUFFER,
        gpu_allocator::MemoryLocation::GpuOnly,
    )
}

/// One band-skeleton job of a pass: which pipelines (per sphere, per
/// band: variants of the per-sphere pass may share one band pipeline),
/// what they read and write (`bindings` serve both pipelines; `counters`
/// is the buffer bound as "Counters", with its words at `layout`).
pub struct BandJob<'a, 'b, P> {
    pub spheres: &'b ComputePipeline,
    pub bands: &'b ComputePipeline,
    pub push: &'a P,
    pub bindings: &'a [(&'static str, &'b Buffer)],
    pub sphere_count: u32,
    /// The per-sphere dispatch's group counts from a buffer (at a byte
    /// offset) instead of `sphere_count` invocations: the LOD cull's lists.
    pub indirect: Option<(&'b Buffer, u64)>,
    pub counters: &'b Buffer,
    pub layout: &'a BandCounters,
}

/// The args pipeline (one per owning pass, named after it).
pub struct BandArgs {
    pipe: ComputePipeline,
}

/// The two pipelines of a band-skeleton shader: per sphere and per band.
pub struct BandPipelines {
    pub spheres: ComputePipeline,
    pub bands: ComputePipeline,
}

impl BandPipelines {
    /// Both pipelines of `desc`'s shader; `constants` are ids 2, 3, ... (id
    /// 1 is BAND_PASS).
    pub fn new(ctx: &Context, desc: &PipelineDesc, constants: &[u32]) -> Result<Self> {
        let spheres = ctx.guard(Self::pass(ctx, desc, 0, constants)?);
        let bands = Self::pass(ctx, desc, 1, constants)?;
        Ok(BandPipelines {
            spheres: spheres.keep(),
            bands,
        })
    }

    /// One of the two: `band` 0, per sphere (alone for a variant that
    /// shares another's band pipeline), 1 per band.
    pub fn pass(
        ctx: &Context,
        desc: &PipelineDesc,
        band: u32,
        constants: &[u32],
    ) -> Result<ComputePipeline> {
        let mut c = vec![band];
        c.extend_from_slice(constants);
        let suffix = if band == 0 { "" } else { " bands" };
        ComputePipeline::new(
            ctx,
            &PipelineDesc {
                name: &format!("{}{suffix}", desc.name),
                constants: &c,
                ..*desc
            },
        )
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.spheres.destroy(ctx);
        self.bands.destroy(ctx);
    }
}

impl BandArgs {
    pub fn new(ctx: &Context, name: &str) -> Result<Self> {
        Ok(BandArgs {
            pipe: ComputePipeline::new(
                ctx,
                &PipelineDesc {
                    name,
                    shader: super::spirv::BAND_ARGS_COMP,
                    bindings: &[rw("Counters")],
                    push_size: std::mem::size_of::<BandCounters>() as u32,
                    local_size: 1,
                    constants: &[],
                    scene: 0,
                },
            )?,
        })
    }

    /// Adds the per-sphere dispatch, the args step and the indirect band
    /// dispatch of `job` to a pass.
    pub fn steps<'b, P: Pod>(&'b self, p: &mut PassBuilder<'b>, job: &BandJob<'_, 'b, P>) {
        let grid = match job.indirect {
            Some((b, offset)) => Grid::Indirect(b, offset),
            None => Grid::Invocations(job.sphere_count as u64),
        };
        p.dispatch(job.spheres, job.push, grid, job.bindings);
        self.step(p, job.counters, job.layout);
        p.dispatch(
            job.bands,
            job.push,
            Grid::Indirect(job.counters, job.layout.args_offset()),
            job.bindings,
        );
    }

    /// The args step alone: `layout.requested` workgroups into indirect
    /// dispatch arguments at `layout.args`.
    pub fn step<'b>(
        &'b self,
        p: &mut PassBuilder<'b>,
        counters: &'b Buffer,
        layout: &BandCounters,
    ) {
        p.dispatch(
            &self.pipe,
            layout,
            Grid::Groups([1, 1, 1]),
            &[("Counters", counters)],
        );
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.pipe.destroy(ctx);
    }
}

crate::impl_destroy!(BandPipelines, JobList);

#[cfg(test)]
mod tests {
    use super::*;

    /// Twice the list, at most one buffer's; at that most, an error
    /// naming the pass.
    #[test]
    fn job_lists_grow_twofold_up_to_one_buffer() {
        assert_eq!(grown_jobs(16, 1 << 24, "x").unwrap(), 32);
        assert_eq!(grown_jobs(0, 1 << 24, "x").unwrap(), 2);
        assert_eq!(grown_jobs(9 << 20, 1 << 24, "x").unwrap(), 1 << 24);
        let e = grown_jobs(1 << 24, 1 << 24, "the raster")
            .unwrap_err()
            .to_string();
        assert!(e.contains("the raster") && e.contains("16777216"), "{e}");
    }
}
