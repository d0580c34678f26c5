//! How many workgroups a dispatch runs: what a pass asks the recorder for
//! and what a compute pipeline turns into group counts; a leaf, so the
//! recorder and the pipeline need not import each other.

use super::Buffer;

/// How many workgroups a dispatch runs.
#[derive(Clone, Copy)]
pub enum Grid<'b> {
    /// Enough groups for this many invocations along x (folded into y
    /// beyond [`crate::gpu::consts::MAX_GROUPS_X`] groups).
    Invocations(u64),
    /// Exactly these group counts.
    Groups([u32; 3]),
    /// Group counts read by the GPU from a buffer at a byte offset.
    Indirect(&'b Buffer, u64),
}
