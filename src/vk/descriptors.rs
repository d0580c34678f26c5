//! Descriptor sets for one frame (or one-shot recording): pools owned by
//! whoever records, reset when the GPU finished the work that used them.
//! (Push descriptors would be simpler, but GPU-assisted validation 1.3.239
//! reports them as uninitialized: KhronosGroup/Vulkan-ValidationLayers#5321.)

use super::Context;
use crate::error::{Result, VkContext};
use ash::vk;

#[derive(Default)]
pub struct DescriptorArena {
    pools: Vec<vk::DescriptorPool>,
    current: usize,
}

impl DescriptorArena {
    /// Allocates a set for one dispatch; it lives until [`Self::reset`].
    pub fn allocate(
        &mut self,
        ctx: &Context,
        layout: vk::DescriptorSetLayout,
    ) -> Result<vk::DescriptorSet> {
        loop {
            if let Some(&pool) = self.pools.get(self.current) {
                let layouts = [layout];
                let info = vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&layouts);
                // SAFETY: pool and layout are live objects of this device.
                match unsafe { ctx.device.allocate_descriptor_sets(&info) } {
                    Ok(sets) => return Ok(sets[0]),
                    Err(
                        vk::Result::ERROR_OUT_OF_POOL_MEMORY | vk::Result::ERROR_FRAGMENTED_POOL,
                    ) => {
                        self.current += 1;
                        continue;
                    }
                    Err(result) => {
                        return Err(crate::Error::Vk {
                            call: "vkAllocateDescriptorSets",
                            result,
                        });
                    }
                }
            }
            let sizes = [
                vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::STORAGE_BUFFER,
                    descriptor_count: 4096,
                },
                vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::UNIFORM_BUFFER,
                    descriptor_count: 512,
                },
                vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
                    descriptor_count: 1024,
                },
                vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::STORAGE_TEXEL_BUFFER,
                    descriptor_count: 1024,
                },
            ];
            let info = vk::DescriptorPoolCreateInfo::default()
                .max_sets(512)
                .pool_sizes(&sizes);
            let pool = unsafe { ctx.device.create_descriptor_pool(&info, None) }
                .vk("vkCreateDescriptorPool")?;
            ctx.name(pool, "frame descriptors");
            self.pools.push(pool);
            self.current = self.pools.len() - 1;
        }
    }

    /// Frees every set handed out: call only once the GPU finished the work
    /// recorded with them (the frame's fence).
    pub fn reset(&mut self, ctx: &Context) -> Result<()> {
        for &pool in &self.pools {
            // SAFETY: the caller waited for the work that used these sets.
            unsafe {
                ctx.device
                    .reset_descriptor_pool(pool, vk::DescriptorPoolResetFlags::empty())
            }
            .vk("vkResetDescriptorPool")?;
        }
        self.current = 0;
        Ok(())
    }

    pub fn destroy(&mut self, ctx: &Context) {
        for pool in self.pools.drain(..) {
            // SAFETY: the owner destroys the arena after its last frame finished.
            unsafe { ctx.device.destroy_descriptor_pool(pool, None) };
        }
        self.current = 0;
    }
}

crate::impl_destroy!(DescriptorArena);
