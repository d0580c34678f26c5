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

/// The layout of a frame slot's readback words (u32): what the host
/// checks after each frame.
pub mod readback {
    use crate::gpu::consts::{LOD_VIEWS, LOD_WORDS};
    /// The raster's band-overflow flag (R_BANDS_FULL, camera and light).
    pub const RASTER_BANDS: usize = 0;
    /// The shadow technique's words (`ShadowTechnique::readback`: the deep
    /// lists' counters, the opacity maps' band flag), else 0.
    pub const LIGHT: usize = 1;
    pub const LIGHT_COUNT: usize = 32;
    /// The see-through fragments' counters, when the frame drew them.
    pub const SEE_THROUGH: usize = LIGHT + LIGHT_COUNT;
    pub const SEE_THROUGH_COUNT: usize = 32;
    /// The LOD lists' counters (LOD_VIEWS x LOD_WORDS) when the frame drew
    /// them, else 0.
    pub const LOD: usize = SEE_THROUGH + SEE_THROUGH_COUNT;
    pub const LOD_COUNT: usize = (LOD_VIEWS * LOD_WORDS) as usize;
    pub const WORDS: usize = LOD + LOD_COUNT;

    // (a section shorter than the counters it copies would cut them)
    const _: () = assert!(
        crate::stages::shadows::deep::COUNTER_WORDS as usize <= LIGHT_COUNT
            && crate::stages::see_through::COUNTER_WORDS as usize <= SEE_THROUGH_COUNT
    );
}

pub struct FrameSlot {
    pub cmd: vk::CommandBuffer,
    /// Signalled when the frame that last used this slot finished.
    pub fence: vk::Fence,
    pub profiler: Profiler,
    pub globals: Buffer,
    /// The words the host checks after the frame ([`readback`]), copied
    /// there at its end: read when the fence signals, no round trip.
    pub readback: Buffer,
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
        let readback = ctx.guard(Buffer::new(
            ctx,
            &format!("readback {i}"),
            readback::WORDS as u64 * 4,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
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
            readback: readback.keep(),
            arena: DescriptorArena::default(),
            pending: false,
        })
    }

    /// The words of this slot's last frame (after its fence).
    pub fn readback(&self) -> Result<[u32; readback::WORDS]> {
        let m = self
            .readback
            .mapped()
            .ok_or_else(|| crate::Error::Internal("readback buffer not mapped".into()))?;
        let mut w = [0u32; readback::WORDS];
        bytemuck::cast_slice_mut::<u32, u8>(&mut w).copy_from_slice(&m[..readback::WORDS * 4]);
        Ok(w)
    }

    /// Zeroes the words before a frame (a word no pass copies reads 0), or
    /// after they were acted on.
    pub fn clear_readback(&mut self) -> Result<()> {
        let m = self
            .readback
            .mapped_mut()
            .ok_or_else(|| crate::Error::Internal("readback buffer not mapped".into()))?;
        m.fill(0);
        Ok(())
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
        self.readback.destroy(ctx);
        self.arena.destroy(ctx);
    }
}

crate::impl_destroy!(FrameSlot);
