//! A frame in flight: its command buffer, fence, timestamp queries,
//! uniform buffer and descriptor pools, so a frame can be recorded while the
//! previous one still runs (the viewer keeps two). Render targets are
//! shared: frames on the one queue run in order, and each frame starts with
//! a barrier against everything submitted before it.

use crate::error::{Result, VkContext};
use crate::gpu::Globals;
use crate::vk::descriptors::DescriptorArena;
use crate::vk::{Buffer, Context, Profiler};
use ash::vk;
use gpu_allocator::MemoryLocation;

pub struct FrameSlot {
    pub cmd: vk::CommandBuffer,
    /// Signalled when the frame that last used this slot finished.
    pub fence: vk::Fence,
    pub profiler: Profiler,
    pub globals: Buffer,
    /// Descriptor sets of this slot's frame (reset when its fence signalled).
    pub arena: DescriptorArena,
    /// A frame was submitted with this slot and its results not yet read.
    pub pending: bool,
}

impl FrameSlot {
    pub fn new(ctx: &Context, i: usize) -> Result<Self> {
        let globals = ctx.guard(Buffer::new(
            ctx,
            &format!("globals {i}"),
            std::mem::size_of::<Globals>() as u64,
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            MemoryLocation::CpuToGpu,
        )?);
        let profiler = ctx.guard(Profiler::new(ctx, 32)?);
        let cmd = ctx.command_buffer(&format!("frame {i}"))?;
        let info = vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED);
        // SAFETY: plain create call; the fence is destroyed in `destroy`.
        let fence = match unsafe { ctx.device.create_fence(&info, None) }.vk("vkCreateFence") {
            Ok(f) => f,
            Err(e) => {
                // SAFETY: the command buffer was never submitted.
                unsafe { ctx.device.free_command_buffers(ctx.command_pool, &[cmd]) };
                return Err(e);
            }
        };
        ctx.name(fence, &format!("frame fence {i}"));
        Ok(FrameSlot {
            cmd,
            fence,
            profiler: profiler.keep(),
            globals: globals.keep(),
            arena: DescriptorArena::default(),
            pending: false,
        })
    }

    /// Waits until the GPU finished this slot's last frame.
    pub fn wait(&self, ctx: &Context) -> Result<()> {
        // SAFETY: the fence is a live object of this device.
        unsafe { ctx.device.wait_for_fences(&[self.fence], true, u64::MAX) }.vk("vkWaitForFences")
    }

    pub fn destroy(&mut self, ctx: &Context) {
        if self.fence == vk::Fence::null() {
            return;
        }
        // SAFETY: the renderer waited for the device to be idle.
        unsafe {
            ctx.device.destroy_fence(self.fence, None);
            ctx.device
                .free_command_buffers(ctx.command_pool, &[self.cmd]);
        }
        self.fence = vk::Fence::null();
        self.profiler.destroy(ctx);
        self.globals.destroy(ctx);
        self.arena.destroy(ctx);
    }
}

crate::impl_destroy!(FrameSlot);
