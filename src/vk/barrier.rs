//! Barriers derived from declared accesses. Every step a pass records (a
//! fill, a dispatch, a draw) states which buffers it touches, in which
//! pipeline stage, reading or writing (for dispatches: from the pipeline's
//! bindings, which are checked against the SPIR-V). [`Tracker`] remembers,
//! per buffer, the last write and the reads since, and returns the one
//! narrow memory barrier the next step needs (compute -> compute, compute ->
//! indirect, transfer -> compute, ...), or none. So no pass can forget a
//! barrier, and atomic-only hazards (which synchronization validation does
//! not see) are covered by construction. [`check_hazards`] is an
//! independent replay that tests use to prove every hazard was covered.

use ash::vk;
use std::collections::HashMap;

/// A pipeline stage a step runs in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    /// vkCmdFillBuffer / vkCmdCopyBuffer.
    Transfer,
    /// Compute shader storage/uniform accesses.
    Compute,
    /// vkCmdDispatchIndirect reading its arguments.
    Indirect,
    /// Vertex and fragment shaders (the graphics raster baseline).
    Graphics,
}

impl Stage {
    pub fn flags(self) -> vk::PipelineStageFlags2 {
        match self {
            Stage::Transfer => vk::PipelineStageFlags2::TRANSFER,
            Stage::Compute => vk::PipelineStageFlags2::COMPUTE_SHADER,
            Stage::Indirect => vk::PipelineStageFlags2::DRAW_INDIRECT,
            Stage::Graphics => {
                vk::PipelineStageFlags2::VERTEX_SHADER | vk::PipelineStageFlags2::FRAGMENT_SHADER
            }
        }
    }

    fn read_access(self) -> vk::AccessFlags2 {
        match self {
            Stage::Transfer => vk::AccessFlags2::TRANSFER_READ,
            Stage::Compute | Stage::Graphics => {
                vk::AccessFlags2::SHADER_STORAGE_READ
                    | vk::AccessFlags2::UNIFORM_READ
                    | vk::AccessFlags2::SHADER_SAMPLED_READ
            }
            Stage::Indirect => vk::AccessFlags2::INDIRECT_COMMAND_READ,
        }
    }

    fn write_access(self) -> vk::AccessFlags2 {
        match self {
            Stage::Transfer => vk::AccessFlags2::TRANSFER_WRITE,
            Stage::Compute | Stage::Graphics => vk::AccessFlags2::SHADER_STORAGE_WRITE,
            // Indirect arguments are only read.
            Stage::Indirect => vk::AccessFlags2::NONE,
        }
    }
}

/// One buffer access of a step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Use {
    /// The buffer (its raw handle).
    pub buffer: vk::Buffer,
    pub stage: Stage,
    pub read: bool,
    pub write: bool,
}

/// A global memory barrier (src stages/accesses -> dst stages/accesses).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Barrier {
    pub src_stage: vk::PipelineStageFlags2,
    pub src_access: vk::AccessFlags2,
    pub dst_stage: vk::PipelineStageFlags2,
    pub dst_access: vk::AccessFlags2,
}

impl Barrier {
    pub fn is_empty(&self) -> bool {
        self.src_stage.is_empty() && self.dst_stage.is_empty()
    }

    fn add(
        &mut self,
        src: Stage,
        src_access: vk::AccessFlags2,
        dst: Stage,
        dst_access: vk::AccessFlags2,
    ) {
        self.src_stage |= src.flags();
        self.src_access |= src_access;
        self.dst_stage |= dst.flags();
        self.dst_access |= dst_access;
    }

    pub fn record(&self, device: &ash::Device, cmd: vk::CommandBuffer) {
        let mb = [vk::MemoryBarrier2::default()
            .src_stage_mask(self.src_stage)
            .src_access_mask(self.src_access)
            .dst_stage_mask(self.dst_stage)
            .dst_access_mask(self.dst_access)];
        let dep = vk::DependencyInfo::default().memory_barriers(&mb);
        // SAFETY: cmd is in the recording state (the recorder owns it).
        unsafe { device.cmd_pipeline_barrier2(cmd, &dep) };
    }

    /// Transfers (a copy into a readback buffer) made visible to the host
    /// read after the submission's fence.
    pub fn transfer_to_host() -> Barrier {
        Barrier {
            src_stage: vk::PipelineStageFlags2::TRANSFER,
            src_access: vk::AccessFlags2::TRANSFER_WRITE,
            dst_stage: vk::PipelineStageFlags2::HOST,
            dst_access: vk::AccessFlags2::HOST_READ,
        }
    }

    /// Everything an earlier submission on the queue may have written,
    /// made visible to everything this one does: frames and one-shot
    /// recordings start with it (queue order alone orders no memory).
    pub fn start_of_submission() -> Barrier {
        let all = vk::PipelineStageFlags2::TRANSFER
            | vk::PipelineStageFlags2::COMPUTE_SHADER
            | vk::PipelineStageFlags2::VERTEX_SHADER
            | vk::PipelineStageFlags2::FRAGMENT_SHADER;
        Barrier {
            src_stage: all,
            src_access: vk::AccessFlags2::TRANSFER_WRITE | vk::AccessFlags2::SHADER_STORAGE_WRITE,
            dst_stage: all | vk::PipelineStageFlags2::DRAW_INDIRECT,
            dst_access: vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE,
        }
    }
}

#[derive(Clone, Debug, Default)]
struct State {
    /// Stage of the last write, if any in this recording.
    write: Option<Stage>,
    /// Stages whose reads / writes the last write is ordered before and
    /// visible to (by some barrier recorded since).
    visible_read: Vec<Stage>,
    visible_write: Vec<Stage>,
    /// Reads since the last write: their stage and the stages a barrier has
    /// ordered after them.
    reads: Vec<(Stage, Vec<Stage>)>,
}

const STAGES: [Stage; 4] = [
    Stage::Transfer,
    Stage::Compute,
    Stage::Indirect,
    Stage::Graphics,
];

fn push_unique(v: &mut Vec<Stage>, s: Stage) {
    if !v.contains(&s) {
        v.push(s);
    }
}

/// Per-buffer access history of one recording.
#[derive(Default)]
pub struct Tracker {
    states: HashMap<vk::Buffer, State>,
}

impl Tracker {
    /// The barrier needed before a step with these uses (empty when none),
    /// and the state updated as if it was recorded and the step ran. A
    /// barrier is a global memory barrier, so it is applied to every
    /// buffer's history, not only to the buffers that asked for it: no
    /// barrier is recorded that an earlier one already provides.
    pub fn step(&mut self, uses: &[Use]) -> Barrier {
        let mut b = Barrier::default();
        for u in uses {
            let st = self.states.entry(u.buffer).or_default();
            if let Some(w) = st.write {
                let read_missing = u.read && !st.visible_read.contains(&u.stage);
                let write_missing = u.write && !st.visible_write.contains(&u.stage);
                if read_missing || write_missing {
                    // read-after-write / write-after-write
                    let mut dst = vk::AccessFlags2::NONE;
                    if u.read {
                        dst |= u.stage.read_access();
                    }
                    if u.write {
                        dst |= u.stage.write_access();
                    }
                    b.add(w, w.write_access(), u.stage, dst);
                }
            }
            if u.write {
                // write-after-read: an execution dependency suffices.
                for (r, ordered) in &st.reads {
                    if !ordered.contains(&u.stage) {
                        b.add(*r, vk::AccessFlags2::NONE, u.stage, vk::AccessFlags2::NONE);
                    }
                }
            }
        }
        if !b.is_empty() {
            self.apply(&b);
        }
        for u in uses {
            let st = self.states.entry(u.buffer).or_default();
            if u.write {
                *st = State {
                    write: Some(u.stage),
                    ..State::default()
                };
            }
        }
        for u in uses {
            let st = self.states.entry(u.buffer).or_default();
            if u.read && !u.write {
                // (a read again at a stage is ordered before nothing yet,
                // whatever barriers ordered its earlier reads)
                match st.reads.iter_mut().find(|(r, _)| *r == u.stage) {
                    Some((_, ordered)) => ordered.clear(),
                    None => st.reads.push((u.stage, Vec::new())),
                }
            }
        }
        b
    }

    /// What a recorded barrier provides, for every buffer.
    fn apply(&mut self, b: &Barrier) {
        for st in self.states.values_mut() {
            if let Some(w) = st.write
                && b.src_stage.contains(w.flags())
                && b.src_access.contains(w.write_access())
            {
                for x in STAGES {
                    if b.dst_stage.contains(x.flags()) {
                        if b.dst_access.contains(x.read_access()) {
                            push_unique(&mut st.visible_read, x);
                        }
                        if b.dst_access.contains(x.write_access()) {
                            push_unique(&mut st.visible_write, x);
                        }
                    }
                }
            }
            for (r, ordered) in &mut st.reads {
                if b.src_stage.contains(r.flags()) {
                    for x in STAGES {
                        if b.dst_stage.contains(x.flags()) {
                            push_unique(ordered, x);
                        }
                    }
                }
            }
        }
    }
}

/// What a recording did, in order (kept when a recorder logs, for tests).
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    Barrier(Barrier),
    Step {
        pass: &'static str,
        what: String,
        uses: Vec<Use>,
    },
}

/// Replays a log and returns every hazard no barrier covers: for each
/// step, the last earlier write of each buffer it uses (and, for a write,
/// the reads since) must be followed, before this step, by one barrier
/// whose source stage and access include the earlier access and whose
/// destination includes this one. Written independently of [`Tracker`]
/// (pairwise over the log), so it can judge it.
pub fn check_hazards(log: &[Event]) -> Vec<String> {
    let steps: Vec<(usize, &'static str, &String, &Vec<Use>)> = log
        .iter()
        .enumerate()
        .filter_map(|(i, e)| match e {
            Event::Step { pass, what, uses } => Some((i, *pass, what, uses)),
            Event::Barrier(_) => None,
        })
        .collect();
    let covered = |from: usize,
                   to: usize,
                   src: Stage,
                   src_access: vk::AccessFlags2,
                   dst: Stage,
                   dst_access: vk::AccessFlags2| {
        log[from + 1..to].iter().any(|e| match e {
            Event::Barrier(b) => {
                b.src_stage.contains(src.flags())
                    && b.src_access.contains(src_access)
                    && b.dst_stage.contains(dst.flags())
                    && b.dst_access.contains(dst_access)
            }
            Event::Step { .. } => false,
        })
    };
    let mut problems = Vec::new();
    for (j, &(lj, pass_j, what_j, uses_j)) in steps.iter().enumerate() {
        for u in uses_j.iter() {
            // The most recent earlier write of this buffer.
            let last_write = steps[..j].iter().rev().find_map(|&(li, p, w, us)| {
                us.iter()
                    .find(|x| x.buffer == u.buffer && x.write)
                    .map(|x| (li, p, w, *x))
            });
            if let Some((li, p, w, x)) = last_write {
                let need = [
                    (u.read, u.stage.read_access(), "reads"),
                    (u.write, u.stage.write_access(), "writes"),
                ];
                for (_, access, verb) in need.into_iter().filter(|n| n.0) {
                    if !covered(li, lj, x.stage, x.stage.write_access(), u.stage, access) {
                        problems.push(format!(
                            "{pass_j}/{what_j} {verb} buffer {:?} written by {p}/{w} ({:?}) without a barrier {:?} -> {:?}",
                            u.buffer, x.stage, x.stage, u.stage
                        ));
                    }
                }
            }
            if u.write {
                let since = last_write.map(|(li, ..)| li).unwrap_or(0);
                for &(li, p, w, us) in &steps[..j] {
                    if li < since {
                        continue;
                    }
                    for x in us
                        .iter()
                        .filter(|x| x.buffer == u.buffer && x.read && !x.write)
                    {
                        if !covered(
                            li,
                            lj,
                            x.stage,
                            vk::AccessFlags2::NONE,
                            u.stage,
                            vk::AccessFlags2::NONE,
                        ) {
                            problems.push(format!(
                                "{pass_j}/{what_j} writes buffer {:?} read by {p}/{w} ({:?}) without a barrier",
                                u.buffer, x.stage
                            ));
                        }
                    }
                }
            }
        }
    }
    problems
}

#[cfg(test)]
mod tests {
    use super::*;
    use ash::vk::Handle;

    fn buf(n: u64) -> vk::Buffer {
        vk::Buffer::from_raw(n)
    }
    fn u(b: u64, stage: Stage, read: bool, write: bool) -> Use {
        Use {
            buffer: buf(b),
            stage,
            read,
            write,
        }
    }

    /// Runs steps through the tracker, logging like the recorder does.
    fn run(steps: &[Vec<Use>]) -> Vec<Event> {
        let mut t = Tracker::default();
        let mut log = Vec::new();
        for (i, s) in steps.iter().enumerate() {
            let b = t.step(s);
            if !b.is_empty() {
                log.push(Event::Barrier(b));
            }
            log.push(Event::Step {
                pass: "p",
                what: format!("step {i}"),
                uses: s.clone(),
            });
        }
        log
    }

    #[test]
    fn read_after_write_gets_a_compute_to_compute_barrier() {
        let log = run(&[
            vec![u(1, Stage::Compute, false, true)],
            vec![u(1, Stage::Compute, true, false)],
        ]);
        let Event::Barrier(b) = log[1] else {
            panic!("no barrier: {log:?}")
        };
        assert_eq!(b.src_stage, vk::PipelineStageFlags2::COMPUTE_SHADER);
        assert_eq!(b.dst_stage, vk::PipelineStageFlags2::COMPUTE_SHADER);
        assert!(
            b.src_access
                .contains(vk::AccessFlags2::SHADER_STORAGE_WRITE)
        );
        assert!(b.dst_access.contains(vk::AccessFlags2::SHADER_STORAGE_READ));
        assert!(check_hazards(&log).is_empty());
    }

    #[test]
    fn indirect_arguments_get_a_compute_to_indirect_barrier() {
        let log = run(&[
            vec![u(7, Stage::Compute, true, true)],
            vec![
                u(7, Stage::Indirect, true, false),
                u(7, Stage::Compute, true, false),
            ],
        ]);
        let Event::Barrier(b) = log[1] else {
            panic!("{log:?}")
        };
        assert!(b.dst_stage.contains(vk::PipelineStageFlags2::DRAW_INDIRECT));
        assert!(
            b.dst_access
                .contains(vk::AccessFlags2::INDIRECT_COMMAND_READ)
        );
        assert!(check_hazards(&log).is_empty());
    }

    #[test]
    fn independent_steps_need_no_barrier_and_fills_are_transfer_writes() {
        let log = run(&[
            vec![u(1, Stage::Transfer, false, true)],
            vec![u(2, Stage::Transfer, false, true)],
            vec![u(3, Stage::Compute, true, false)],
        ]);
        assert!(
            log.iter().all(|e| matches!(e, Event::Step { .. })),
            "{log:?}"
        );
        let log = run(&[
            vec![u(1, Stage::Transfer, false, true)],
            vec![u(1, Stage::Compute, true, true)],
        ]);
        let Event::Barrier(b) = log[1] else {
            panic!("{log:?}")
        };
        assert_eq!(b.src_stage, vk::PipelineStageFlags2::TRANSFER);
        assert!(check_hazards(&log).is_empty());
    }

    #[test]
    fn a_read_seen_once_needs_no_second_barrier_but_a_new_stage_does() {
        let log = run(&[
            vec![u(1, Stage::Compute, false, true)],
            vec![u(1, Stage::Compute, true, false)],
            vec![u(1, Stage::Compute, true, false)],
            vec![u(1, Stage::Indirect, true, false)],
        ]);
        let barriers: Vec<_> = log
            .iter()
            .filter(|e| matches!(e, Event::Barrier(_)))
            .collect();
        assert_eq!(barriers.len(), 2, "{log:?}");
        assert!(check_hazards(&log).is_empty());
    }

    #[test]
    fn write_after_read_gets_an_execution_dependency() {
        let log = run(&[
            vec![u(1, Stage::Compute, true, false)],
            vec![u(1, Stage::Transfer, false, true)],
        ]);
        let Event::Barrier(b) = log[1] else {
            panic!("{log:?}")
        };
        assert_eq!(b.src_stage, vk::PipelineStageFlags2::COMPUTE_SHADER);
        assert_eq!(b.dst_stage, vk::PipelineStageFlags2::TRANSFER);
        assert!(check_hazards(&log).is_empty());
    }

    /// A buffer read, a barrier another buffer's fill needed (it orders
    /// that read before transfers), the buffer read again, then filled:
    /// the second read still needs its own barrier (the LOD cull's light
    /// region, read by the camera's two culls, the lists filled between).
    #[test]
    fn a_read_again_after_a_barrier_is_not_ordered_by_it() {
        let log = run(&[
            vec![
                u(1, Stage::Compute, true, false),
                u(2, Stage::Compute, false, true),
            ],
            vec![u(2, Stage::Transfer, false, true)],
            vec![u(1, Stage::Compute, true, false)],
            vec![u(1, Stage::Transfer, false, true)],
        ]);
        assert!(matches!(log[log.len() - 2], Event::Barrier(_)), "{log:?}");
        assert!(check_hazards(&log).is_empty(), "{log:?}");
    }

    #[test]
    fn the_checker_rejects_a_log_with_a_barrier_removed() {
        let steps = [
            vec![u(1, Stage::Transfer, false, true)],
            vec![
                u(1, Stage::Compute, true, true),
                u(2, Stage::Compute, false, true),
            ],
            vec![
                u(2, Stage::Compute, true, false),
                u(3, Stage::Compute, false, true),
            ],
            vec![u(3, Stage::Indirect, true, false)],
        ];
        let log = run(&steps);
        assert!(check_hazards(&log).is_empty());
        let barriers: Vec<usize> = log
            .iter()
            .enumerate()
            .filter(|(_, e)| matches!(e, Event::Barrier(_)))
            .map(|(i, _)| i)
            .collect();
        assert_eq!(barriers.len(), 3);
        for &k in &barriers {
            let mut broken = log.clone();
            broken.remove(k);
            assert!(
                !check_hazards(&broken).is_empty(),
                "removing barrier {k} went unnoticed"
            );
        }
        // A barrier with the wrong destination stage does not count either.
        let mut wrong = log.clone();
        if let Event::Barrier(b) = &mut wrong[*barriers.last().unwrap()] {
            b.dst_stage = vk::PipelineStageFlags2::COMPUTE_SHADER;
        }
        assert!(!check_hazards(&wrong).is_empty());
    }
}
