//! Recording with derived barriers and pass scopes. A pass is a name and a
//! short list of steps (fills, dispatches, a draw), built declaratively:
//!
//! ```ignore
//! rec.pass("issm_shadow", |p| {
//!     p.dispatch(&pipe, &push, Grid::Invocations(pixels),
//!                &[("GlobalsBlock", globals), ("Spheres", spheres), ("Shadow", shadow)])
//! })?;
//! ```
//!
//! [`Recorder::pass`] then, in one place, inserts before each step the
//! barrier its accesses need (see [`super::barrier`]), opens the debug
//! label and timestamp scope around the steps (name = label = JSON name),
//! and closes them. Dispatches bind buffers by binding name; the pipeline
//! knows from its declaration (checked against the SPIR-V) which it reads
//! and writes, so the barriers follow from the shaders themselves.

use super::barrier::{Barrier, Event, Stage, Tracker, Use};
use super::descriptors::DescriptorArena;
use super::grid::Grid;
use super::pipeline::ComputePipeline;
use super::{Buffer, Context, Profiler};
use crate::error::{Error, Result};
use ash::vk;

/// Work recorded by a closure (the graphics raster baseline), with the
/// buffers it touches declared.
type RawRecord<'b> =
    Box<dyn FnOnce(&Context, vk::CommandBuffer, &mut DescriptorArena) -> Result<()> + 'b>;

enum Step<'b> {
    Fill {
        buffer: &'b Buffer,
        offset: u64,
        size: u64,
        value: u32,
    },
    Copy {
        src: &'b Buffer,
        src_offset: u64,
        dst: &'b Buffer,
        dst_offset: u64,
        size: u64,
    },
    Dispatch {
        pipe: &'b ComputePipeline,
        bindings: Vec<(&'static str, &'b Buffer)>,
        push: Vec<u8>,
        grid: Grid<'b>,
    },
    Raw {
        what: &'static str,
        uses: Vec<Use>,
        record: RawRecord<'b>,
    },
}

/// The steps of one pass, in order.
#[derive(Default)]
pub struct PassBuilder<'b> {
    steps: Vec<Step<'b>>,
}

impl<'b> PassBuilder<'b> {
    /// Fills the first `size` bytes of `buffer` with the 32-bit `value`.
    pub fn fill(&mut self, buffer: &'b Buffer, size: u64, value: u32) {
        self.fill_at(buffer, 0, size, value);
    }

    pub fn fill_at(&mut self, buffer: &'b Buffer, offset: u64, size: u64, value: u32) {
        self.steps.push(Step::Fill {
            buffer,
            offset,
            size,
            value,
        });
    }

    /// Copies `size` bytes of `src` at `src_offset` to `dst` at
    /// `dst_offset`, made visible to the host once the submission's fence
    /// signals (`dst` is a host-visible readback buffer).
    pub fn copy_to_host(
        &mut self,
        src: &'b Buffer,
        src_offset: u64,
        dst: &'b Buffer,
        dst_offset: u64,
        size: u64,
    ) {
        self.steps.push(Step::Copy {
            src,
            src_offset,
            dst,
            dst_offset,
            size,
        });
    }

    /// A compute dispatch; `bindings` name every binding of the pipeline.
    pub fn dispatch<P: bytemuck::Pod>(
        &mut self,
        pipe: &'b ComputePipeline,
        push: &P,
        grid: Grid<'b>,
        bindings: &[(&'static str, &'b Buffer)],
    ) {
        self.steps.push(Step::Dispatch {
            pipe,
            bindings: bindings.to_vec(),
            push: bytemuck::bytes_of(push).to_vec(),
            grid,
        });
    }

    /// Commands recorded by `record`, touching exactly the declared buffers.
    pub fn raw(
        &mut self,
        what: &'static str,
        uses: Vec<Use>,
        record: impl FnOnce(&Context, vk::CommandBuffer, &mut DescriptorArena) -> Result<()> + 'b,
    ) {
        self.steps.push(Step::Raw {
            what,
            uses,
            record: Box::new(record),
        });
    }
}

/// Records passes into one command buffer.
pub struct Recorder<'a> {
    ctx: &'a Context,
    cmd: vk::CommandBuffer,
    arena: &'a mut DescriptorArena,
    profiler: Option<&'a mut Profiler>,
    tracker: Tracker,
    /// Pass names allowed (the frame graph's list); None = any.
    allowed: Option<&'a [&'static str]>,
    log: Option<Vec<Event>>,
    open: bool,
}

impl<'a> Recorder<'a> {
    /// Starts recording into `cmd` (already begun): records the barrier
    /// against everything earlier submissions did.
    pub fn new(
        ctx: &'a Context,
        cmd: vk::CommandBuffer,
        arena: &'a mut DescriptorArena,
        profiler: Option<&'a mut Profiler>,
    ) -> Self {
        Barrier::start_of_submission().record(&ctx.device, cmd);
        Recorder {
            ctx,
            cmd,
            arena,
            profiler,
            tracker: Tracker::default(),
            allowed: None,
            log: None,
            open: false,
        }
    }

    /// Only these pass names may be recorded (the one pass list).
    pub fn restrict_to(&mut self, names: &'a [&'static str]) {
        self.allowed = Some(names);
    }

    /// Keeps a log of steps and barriers (see [`super::barrier::check_hazards`]).
    pub fn keep_log(&mut self) {
        self.log = Some(Vec::new());
    }

    pub fn take_log(&mut self) -> Vec<Event> {
        self.log.take().unwrap_or_default()
    }

    pub fn cmd(&self) -> vk::CommandBuffer {
        self.cmd
    }

    pub fn ctx(&self) -> &'a Context {
        self.ctx
    }

    /// Records pass `name`: the steps `build` lists, each preceded by the
    /// barrier it needs, inside the pass's label and timestamp scope.
    pub fn pass<'b>(
        &mut self,
        name: &'static str,
        build: impl FnOnce(&mut PassBuilder<'b>) -> Result<()>,
    ) -> Result<()> {
        if let Some(allowed) = self.allowed
            && !allowed.contains(&name)
        {
            return Err(Error::Internal(format!(
                "pass '{name}' is not in the frame graph's pass list (src/render/graph.rs)"
            )));
        }
        let mut p = PassBuilder::default();
        build(&mut p)?;
        for (k, step) in p.steps.into_iter().enumerate() {
            let (what, uses) = self.uses(&step)?;
            let b = self.tracker.step(&uses);
            if !b.is_empty() {
                b.record(&self.ctx.device, self.cmd);
                if let Some(log) = &mut self.log {
                    log.push(Event::Barrier(b));
                }
            }
            if let Some(log) = &mut self.log {
                log.push(Event::Step {
                    pass: name,
                    what: what.clone(),
                    uses,
                });
            }
            if k == 0 {
                self.open_scope(name)?;
            }
            self.record_step(step)?;
        }
        if self.open {
            self.close_scope()?;
        }
        Ok(())
    }

    fn open_scope(&mut self, name: &'static str) -> Result<()> {
        self.open = true;
        match &mut self.profiler {
            Some(p) => p.begin(self.ctx, self.cmd, name),
            None => {
                self.ctx.begin_label(self.cmd, name);
                Ok(())
            }
        }
    }

    fn close_scope(&mut self) -> Result<()> {
        self.open = false;
        match &mut self.profiler {
            Some(p) => p.end(self.ctx, self.cmd),
            None => {
                self.ctx.end_label(self.cmd);
                Ok(())
            }
        }
    }

    fn uses(&self, step: &Step) -> Result<(String, Vec<Use>)> {
        Ok(match step {
            Step::Fill { buffer, .. } => (
                format!("fill {}", buffer.name),
                vec![Use {
                    buffer: buffer.raw,
                    stage: Stage::Transfer,
                    read: false,
                    write: true,
                }],
            ),
            Step::Copy { src, dst, .. } => (
                format!("copy {} to {}", src.name, dst.name),
                vec![
                    Use {
                        buffer: src.raw,
                        stage: Stage::Transfer,
                        read: true,
                        write: false,
                    },
                    Use {
                        buffer: dst.raw,
                        stage: Stage::Transfer,
                        read: false,
                        write: true,
                    },
                ],
            ),
            Step::Dispatch {
                pipe,
                bindings,
                grid,
                ..
            } => {
                let mut uses = pipe.uses(bindings)?;
                if let Grid::Indirect(args, _) = grid {
                    uses.push(Use {
                        buffer: args.raw,
                        stage: Stage::Indirect,
                        read: true,
                        write: false,
                    });
                }
                (pipe.name.clone(), uses)
            }
            Step::Raw { what, uses, .. } => (what.to_string(), uses.clone()),
        })
    }

    fn record_step(&mut self, step: Step) -> Result<()> {
        let (ctx, cmd) = (self.ctx, self.cmd);
        match step {
            Step::Fill {
                buffer,
                offset,
                size,
                value,
            } => {
                // SAFETY: the range lies inside the live buffer (checked here).
                if offset + size > buffer.size {
                    return Err(Error::Internal(format!(
                        "fill of '{}' past its end ({} + {size} > {})",
                        buffer.name, offset, buffer.size
                    )));
                }
                // SAFETY: the command buffer is in the recording state; the handles are live.
                unsafe {
                    ctx.device
                        .cmd_fill_buffer(cmd, buffer.raw, offset, size, value)
                };
                Ok(())
            }
            Step::Copy {
                src,
                src_offset,
                dst,
                dst_offset,
                size,
            } => {
                if src_offset + size > src.size || dst_offset + size > dst.size {
                    return Err(Error::Internal(format!(
                        "copy of '{}' to '{}' past an end",
                        src.name, dst.name
                    )));
                }
                let region = [vk::BufferCopy {
                    src_offset,
                    dst_offset,
                    size,
                }];
                // SAFETY: recording; both ranges lie inside live buffers
                // (checked above).
                unsafe { ctx.device.cmd_copy_buffer(cmd, src.raw, dst.raw, &region) };
                // The host reads it after the fence.
                Barrier::transfer_to_host().record(&ctx.device, cmd);
                Ok(())
            }
            Step::Dispatch {
                pipe,
                bindings,
                push,
                grid,
            } => {
                pipe.bind(ctx, cmd, self.arena, &bindings, &push)?;
                pipe.dispatch_grid(ctx, cmd, grid)
            }
            Step::Raw { record, .. } => record(ctx, cmd, self.arena),
        }
    }
}

impl Context {
    /// Records with `f` into a fresh command buffer (with derived barriers
    /// and a descriptor arena of its own), submits and waits.
    pub fn one_shot_passes<T>(
        &self,
        name: &str,
        f: impl FnOnce(&mut Recorder) -> Result<T>,
    ) -> Result<T> {
        let mut arena = DescriptorArena::default();
        let result = self.one_shot(name, |cmd| {
            let mut rec = Recorder::new(self, cmd, &mut arena, None);
            f(&mut rec)
        });
        arena.destroy(self);
        result
    }
}
