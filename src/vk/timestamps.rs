//! Pass scopes: `begin(cmd, "raster")` ... `end(cmd)` brackets a pass with a
//! debug label and a pair of timestamps. Slots are assigned in recording
//! order, never by hand; names must be unique within a frame.

use super::Context;
use crate::error::{Error, Result, VkContext};
use ash::vk;

/// Per-pass milliseconds of one frame in recording order, and the frame's
/// GPU time from its first to its last timestamp (not a sum of scopes:
/// barriers and gaps between passes count, overlaps do not).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PassTimes {
    pub passes: Vec<(&'static str, f64)>,
    pub total_ms: f64,
}

impl PassTimes {
    /// Adds `other`'s times (by pass name, new names in order of
    /// appearance): the cost of an image made of several frames (tiles,
    /// sub-pixel samples).
    pub fn add(&mut self, other: &PassTimes) {
        for &(name, ms) in &other.passes {
            match self.passes.iter_mut().find(|(n, _)| *n == name) {
                Some(e) => e.1 += ms,
                None => self.passes.push((name, ms)),
            }
        }
        self.total_ms += other.total_ms;
    }
}

impl<'a> IntoIterator for &'a PassTimes {
    type Item = &'a (&'static str, f64);
    type IntoIter = std::slice::Iter<'a, (&'static str, f64)>;
    fn into_iter(self) -> Self::IntoIter {
        self.passes.iter()
    }
}

impl std::ops::Deref for PassTimes {
    type Target = [(&'static str, f64)];
    fn deref(&self) -> &Self::Target {
        &self.passes
    }
}

pub struct Profiler {
    pool: vk::QueryPool,
    capacity: u32,
    names: Vec<&'static str>,
    open: Option<usize>,
    period_ns: f64,
    valid_mask: u64,
}

impl Profiler {
    pub fn new(ctx: &Context, max_scopes: u32) -> Result<Self> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(2 * max_scopes);
        let pool = unsafe { ctx.device.create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        ctx.name(pool, "pass timestamps");
        let families = unsafe {
            ctx.instance
                .get_physical_device_queue_family_properties(ctx.physical)
        };
        let bits = families[ctx.queue_family as usize].timestamp_valid_bits;
        Ok(Profiler {
            pool,
            capacity: max_scopes,
            names: Vec::new(),
            open: None,
            period_ns: ctx.props.limits.timestamp_period as f64,
            valid_mask: if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
            },
        })
    }

    /// Starts a frame: resets the queries (recorded into `cmd`).
    pub fn begin_frame(&mut self, ctx: &Context, cmd: vk::CommandBuffer) {
        // SAFETY: the command buffer is in the recording state; the handles are live.
        unsafe {
            ctx.device
                .cmd_reset_query_pool(cmd, self.pool, 0, 2 * self.capacity)
        };
        self.names.clear();
        self.open = None;
    }

    /// Opens the scope of pass `name`.
    pub fn begin(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        name: &'static str,
    ) -> Result<()> {
        if self.open.is_some() {
            return Err(Error::Internal(format!(
                "pass scope '{name}' opened inside another"
            )));
        }
        if self.names.contains(&name) {
            return Err(Error::Internal(format!(
                "pass name '{name}' used twice in one frame"
            )));
        }
        if self.names.len() as u32 >= self.capacity {
            return Err(Error::Internal("too many pass scopes in one frame".into()));
        }
        let slot = self.names.len();
        self.names.push(name);
        self.open = Some(slot);
        ctx.begin_label(cmd, name);
        // SAFETY: the command buffer is in the recording state; the handles are live.
        unsafe {
            ctx.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * slot as u32,
            )
        };
        Ok(())
    }

    pub fn end(&mut self, ctx: &Context, cmd: vk::CommandBuffer) -> Result<()> {
        let slot = self
            .open
            .take()
            .ok_or_else(|| Error::Internal("pass scope closed twice".into()))?;
        // SAFETY: the command buffer is in the recording state; the handles are live.
        unsafe {
            ctx.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                2 * slot as u32 + 1,
            )
        };
        ctx.end_label(cmd);
        Ok(())
    }

    /// Milliseconds per pass of the last submitted frame (after its fence).
    pub fn results(&self, ctx: &Context) -> Result<PassTimes> {
        let n = self.names.len();
        if n == 0 {
            return Ok(PassTimes::default());
        }
        let mut data = vec![0u64; 2 * n];
        // SAFETY: the queries were written by the finished frame (its fence), 2n of them.
        unsafe {
            ctx.device.get_query_pool_results(
                self.pool,
                0,
                &mut data,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        let ms = |t0: u64, t1: u64| {
            (t1 & self.valid_mask).wrapping_sub(t0 & self.valid_mask) as f64 * self.period_ns * 1e-6
        };
        Ok(PassTimes {
            passes: self
                .names
                .iter()
                .enumerate()
                .map(|(i, &name)| (name, ms(data[2 * i], data[2 * i + 1])))
                .collect(),
            total_ms: ms(data[0], data[2 * n - 1]),
        })
    }

    /// Destroys the query pool; a second call does nothing.
    pub fn destroy(&mut self, ctx: &Context) {
        if self.pool != vk::QueryPool::null() {
            // SAFETY: called after the last frame using the pool finished.
            unsafe { ctx.device.destroy_query_pool(self.pool, None) };
            self.pool = vk::QueryPool::null();
        }
    }
}
