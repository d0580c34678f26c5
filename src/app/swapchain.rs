//! Window surface + swapchain: creation, recreation on resize or
//! out-of-date, and presenting a colour buffer by copying it into the
//! acquired image (transfer, with the layout transitions around it).

use crate::error::{Error, Result, VkContext};
use crate::vk::{Buffer, Context};
use ash::vk;

pub struct Swapchain {
    loader: ash::khr::swapchain::Device,
    pub surface_loader: ash::khr::surface::Instance,
    pub surface: vk::SurfaceKHR,
    pub swapchain: vk::SwapchainKHR,
    pub images: Vec<vk::Image>,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    /// Per frame in flight.
    frames: Vec<FrameSync>,
    /// Per swapchain image: signalled when its copy is done (present waits).
    render_done: Vec<vk::Semaphore>,
    frame: usize,
    /// Semaphores and swapchains replaced by a recreation, with the number of
    /// presents still to make before they are destroyed: a present of the
    /// old swapchain may still wait on its semaphore (no fence covers a
    /// present), and presents on one queue complete in order, so once every
    /// image of the new swapchain was acquired again the old ones are done.
    retired: Vec<Retired>,
}

struct Retired {
    presents_left: usize,
    semaphores: Vec<vk::Semaphore>,
    swapchain: vk::SwapchainKHR,
}

struct FrameSync {
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    acquired: vk::Semaphore,
}

/// Frames the CPU may record ahead of the GPU.
pub const FRAMES_IN_FLIGHT: usize = 2;

pub enum Present {
    Ok,
    /// The swapchain must be recreated (resize, out of date, suboptimal).
    Recreate,
}

impl Swapchain {
    pub fn new(ctx: &Context, surface: vk::SurfaceKHR, width: u32, height: u32) -> Result<Self> {
        let surface_loader = ash::khr::surface::Instance::new(&ctx.entry, &ctx.instance);
        let supported = unsafe {
            surface_loader.get_physical_device_surface_support(
                ctx.physical,
                ctx.queue_family,
                surface,
            )
        }
        .vk("vkGetPhysicalDeviceSurfaceSupportKHR")?;
        if !supported {
            return Err(Error::Input(
                "the chosen queue cannot present to this window".into(),
            ));
        }
        let loader = ash::khr::swapchain::Device::new(&ctx.instance, &ctx.device);
        let mut frames = Vec::new();
        for i in 0..FRAMES_IN_FLIGHT {
            let cmd = ctx.command_buffer(&format!("present {i}"))?;
            let fence = unsafe {
                ctx.device.create_fence(
                    &vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED),
                    None,
                )
            }
            .vk("vkCreateFence")?;
            ctx.name(fence, &format!("present fence {i}"));
            let acquired = unsafe {
                ctx.device
                    .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
            }
            .vk("vkCreateSemaphore")?;
            ctx.name(acquired, &format!("image acquired {i}"));
            frames.push(FrameSync {
                cmd,
                fence,
                acquired,
            });
        }
        let mut sc = Swapchain {
            loader,
            surface_loader,
            surface,
            swapchain: vk::SwapchainKHR::null(),
            images: Vec::new(),
            format: vk::Format::B8G8R8A8_UNORM,
            extent: vk::Extent2D { width, height },
            frames,
            render_done: Vec::new(),
            frame: 0,
            retired: Vec::new(),
        };
        sc.recreate(ctx, width, height)?;
        Ok(sc)
    }

    /// True when the swapchain images are BGRA (the colour buffer must match).
    pub fn is_bgra(&self) -> bool {
        matches!(
            self.format,
            vk::Format::B8G8R8A8_UNORM | vk::Format::B8G8R8A8_SRGB
        )
    }

    pub fn recreate(&mut self, ctx: &Context, width: u32, height: u32) -> Result<()> {
        // Images may still be in use by a present or copy in flight.
        self.wait_frames(ctx)?;
        let caps = unsafe {
            self.surface_loader
                .get_physical_device_surface_capabilities(ctx.physical, self.surface)
        }
        .vk("vkGetPhysicalDeviceSurfaceCapabilitiesKHR")?;
        let formats = unsafe {
            self.surface_loader
                .get_physical_device_surface_formats(ctx.physical, self.surface)
        }
        .vk("vkGetPhysicalDeviceSurfaceFormatsKHR")?;
        // The colour buffer already holds sRGB-encoded bytes: take a UNORM format.
        let chosen = formats
            .iter()
            .find(|f| f.format == vk::Format::B8G8R8A8_UNORM)
            .or_else(|| {
                formats
                    .iter()
                    .find(|f| f.format == vk::Format::R8G8B8A8_UNORM)
            })
            .or(formats.first())
            .copied()
            .ok_or_else(|| Error::Input("the window surface offers no formats".into()))?;
        let extent = if caps.current_extent.width != u32::MAX {
            caps.current_extent
        } else {
            vk::Extent2D {
                width: width.clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: height.clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        };
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        let old = self.swapchain;
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(self.surface)
            .min_image_count(count)
            .image_format(chosen.format)
            .image_color_space(chosen.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
            .present_mode(vk::PresentModeKHR::FIFO)
            .clipped(true)
            .old_swapchain(old);
        // SAFETY: the surface is live; `old` is retired by this call.
        let swapchain =
            unsafe { self.loader.create_swapchain(&info, None) }.vk("vkCreateSwapchainKHR")?;
        ctx.name(swapchain, "swapchain");
        // SAFETY: the swapchain was just created.
        self.images =
            unsafe { self.loader.get_swapchain_images(swapchain) }.vk("vkGetSwapchainImagesKHR")?;
        // Pending presents of the old swapchain may wait on its semaphores:
        // destroy them only after the new one cycled through its images.
        self.retired.push(Retired {
            presents_left: self.images.len() + FRAMES_IN_FLIGHT,
            semaphores: std::mem::take(&mut self.render_done),
            swapchain: old,
        });
        for i in 0..self.images.len() {
            ctx.name(self.images[i], &format!("swapchain image {i}"));
            let s = unsafe {
                ctx.device
                    .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
            }
            .vk("vkCreateSemaphore")?;
            ctx.name(s, &format!("copy done {i}"));
            self.render_done.push(s);
        }
        self.swapchain = swapchain;
        self.format = chosen.format;
        self.extent = extent;
        Ok(())
    }

    fn wait_frames(&self, ctx: &Context) -> Result<()> {
        let fences: Vec<_> = self.frames.iter().map(|f| f.fence).collect();
        // SAFETY: the fences are live objects of this device.
        unsafe { ctx.device.wait_for_fences(&fences, true, u64::MAX) }.vk("vkWaitForFences")
    }

    /// Copies `color` (RGBA8/BGRA8 texels, extent-sized) into the next image
    /// and presents it. Waits only for the frame slot used two frames ago.
    pub fn present(&mut self, ctx: &Context, color: &Buffer) -> Result<Present> {
        let dev = &ctx.device;
        let f = &self.frames[self.frame];
        // SAFETY: the fences are live objects of this device.
        unsafe { dev.wait_for_fences(&[f.fence], true, u64::MAX) }.vk("vkWaitForFences")?;
        // A suboptimal image still holds the signalled semaphore: it must be
        // presented (not dropped), and the swapchain recreated after.
        // SAFETY: the semaphore is unsignalled: its last acquire was waited on by a finished submission.
        let (index, suboptimal) = match unsafe {
            self.loader
                .acquire_next_image(self.swapchain, u64::MAX, f.acquired, vk::Fence::null())
        } {
            Ok(v) => v,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => return Ok(Present::Recreate),
            Err(result) => {
                return Err(Error::Vk {
                    call: "vkAcquireNextImageKHR",
                    result,
                });
            }
        };
        // SAFETY: the fence / command buffer is not in use by pending work (waited for).
        unsafe { dev.reset_fences(&[f.fence]) }.vk("vkResetFences")?;
        let image = self.images[index as usize];
        let range = vk::ImageSubresourceRange {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        };
        // SAFETY: the fence / command buffer is not in use by pending work (waited for).
        unsafe {
            dev.reset_command_buffer(f.cmd, vk::CommandBufferResetFlags::empty())
                .vk("vkResetCommandBuffer")?;
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            dev.begin_command_buffer(f.cmd, &begin)
                .vk("vkBeginCommandBuffer")?;
            let to_dst = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                .dst_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .old_layout(vk::ImageLayout::UNDEFINED)
                .new_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .image(image)
                .subresource_range(range)];
            // The colour buffer was written by the frame's compute passes.
            let buf = [vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .src_access_mask(vk::AccessFlags2::MEMORY_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::COPY)
                .dst_access_mask(vk::AccessFlags2::TRANSFER_READ)];
            dev.cmd_pipeline_barrier2(
                f.cmd,
                &vk::DependencyInfo::default()
                    .image_memory_barriers(&to_dst)
                    .memory_barriers(&buf),
            );
            let region = [vk::BufferImageCopy {
                buffer_offset: 0,
                buffer_row_length: 0,
                buffer_image_height: 0,
                image_subresource: vk::ImageSubresourceLayers {
                    aspect_mask: vk::ImageAspectFlags::COLOR,
                    mip_level: 0,
                    base_array_layer: 0,
                    layer_count: 1,
                },
                image_offset: vk::Offset3D::default(),
                image_extent: vk::Extent3D {
                    width: self.extent.width,
                    height: self.extent.height,
                    depth: 1,
                },
            }];
            dev.cmd_copy_buffer_to_image(
                f.cmd,
                color.raw,
                image,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &region,
            );
            let to_present = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::COPY)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::NONE)
                .dst_access_mask(vk::AccessFlags2::NONE)
                .old_layout(vk::ImageLayout::TRANSFER_DST_OPTIMAL)
                .new_layout(vk::ImageLayout::PRESENT_SRC_KHR)
                .image(image)
                .subresource_range(range)];
            dev.cmd_pipeline_barrier2(
                f.cmd,
                &vk::DependencyInfo::default().image_memory_barriers(&to_present),
            );
            dev.end_command_buffer(f.cmd).vk("vkEndCommandBuffer")?;
            let wait = [vk::SemaphoreSubmitInfo::default()
                .semaphore(f.acquired)
                .stage_mask(vk::PipelineStageFlags2::COPY)];
            let signal = [vk::SemaphoreSubmitInfo::default()
                .semaphore(self.render_done[index as usize])
                .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
            let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(f.cmd)];
            let submit = [vk::SubmitInfo2::default()
                .wait_semaphore_infos(&wait)
                .signal_semaphore_infos(&signal)
                .command_buffer_infos(&cmds)];
            dev.queue_submit2(ctx.queue, &submit, f.fence)
                .vk("vkQueueSubmit2")?;
        }
        self.frame = (self.frame + 1) % FRAMES_IN_FLIGHT;
        self.release_retired(ctx, false);
        let waits = [self.render_done[index as usize]];
        let swapchains = [self.swapchain];
        let indices = [index];
        let info = vk::PresentInfoKHR::default()
            .wait_semaphores(&waits)
            .swapchains(&swapchains)
            .image_indices(&indices);
        // SAFETY: the command buffers are recorded, the semaphores and fence are unsignalled and not in use.
        match unsafe { self.loader.queue_present(ctx.queue, &info) } {
            Ok(false) if !suboptimal => Ok(Present::Ok),
            Ok(_) => Ok(Present::Recreate),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(Present::Recreate),
            Err(result) => Err(Error::Vk {
                call: "vkQueuePresentKHR",
                result,
            }),
        }
    }

    /// Counts a present against the retired objects and destroys those
    /// whose presents are done (all of them when `all`: device idle).
    fn release_retired(&mut self, ctx: &Context, all: bool) {
        for r in &mut self.retired {
            r.presents_left = r.presents_left.saturating_sub(1);
        }
        let (done, keep): (Vec<_>, Vec<_>) = std::mem::take(&mut self.retired)
            .into_iter()
            .partition(|r| all || r.presents_left == 0);
        self.retired = keep;
        for r in done {
            // SAFETY: every present that could wait on these has completed
            // (see `retired`), or the device is idle.
            unsafe {
                for s in r.semaphores {
                    ctx.device.destroy_semaphore(s, None);
                }
                if r.swapchain != vk::SwapchainKHR::null() {
                    self.loader.destroy_swapchain(r.swapchain, None);
                }
            }
        }
    }

    pub fn destroy(&mut self, ctx: &Context) {
        let _ = self.wait_frames(ctx);
        ctx.wait_idle();
        self.release_retired(ctx, true);
        // SAFETY: the device is idle; nothing uses these objects any more.
        unsafe {
            for f in &self.frames {
                ctx.device.destroy_fence(f.fence, None);
                ctx.device.destroy_semaphore(f.acquired, None);
                ctx.device.free_command_buffers(ctx.command_pool, &[f.cmd]);
            }
            for &s in &self.render_done {
                ctx.device.destroy_semaphore(s, None);
            }
            self.loader.destroy_swapchain(self.swapchain, None);
            self.surface_loader.destroy_surface(self.surface, None);
        }
        self.frames.clear();
        self.render_done.clear();
    }
}
