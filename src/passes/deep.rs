//! Deep shadow lists (seed 002). Placeholder interface; implementation in progress.

use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::output::DeepStats;
use crate::vk::{Buffer, Context, Profiler};
use ash::vk;

pub struct DeepShadows {
    pub light: Camera,
}

impl DeepShadows {
    pub fn new(_ctx: &Context, light: Camera, _sphere_count: u32, _pool_chunks: Option<u32>) -> Result<Self> {
        let _ = light;
        Err(Error::Invalid("--shadows deep: not implemented yet".into()))
    }

    #[allow(clippy::too_many_arguments)]
    pub fn record(
        &self,
        _ctx: &Context,
        _cmd: vk::CommandBuffer,
        _prof: &mut Profiler,
        _globals: &Buffer,
        _spheres: &Buffer,
        _vis: &Buffer,
        _gpos: &Buffer,
        _shadow: &Buffer,
        _opacity: f32,
        _pixels: u64,
    ) -> Result<()> {
        Err(Error::Invalid("--shadows deep: not implemented yet".into()))
    }

    pub fn read_stats(&self, _ctx: &Context) -> Result<DeepStats> {
        Err(Error::Invalid("--shadows deep: not implemented yet".into()))
    }

    pub fn grow(&mut self, _ctx: &Context, _needed_chunks: u64) -> Result<()> {
        Ok(())
    }

    pub fn memory_bytes(&self) -> u64 {
        0
    }

    pub fn destroy(&mut self, _ctx: &Context) {}
}
