//! Compute pipelines: each pass declares its bindings
//! once, then records `dispatch()` with typed push constants (size checked)
//! and the buffers for that dispatch. The workgroup size is specialization
//! constant 0 (`local_size_x_id = 0`), so Rust knows it without reflection.

use super::{Buffer, Context};
use crate::error::{Error, Result, VkContext};
use ash::vk;

pub struct ComputePipeline {
    pub name: String,
    pub pipeline: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    /// Invocations per workgroup along x.
    pub local_size: u32,
    pub push_size: u32,
    bindings: Vec<vk::DescriptorType>,
}

/// Builder-style description of a compute pipeline.
pub struct PipelineDesc<'a> {
    pub name: &'a str,
    pub spirv: &'a [u8],
    pub bindings: &'a [vk::DescriptorType],
    pub push_size: u32,
    /// Workgroup size for shaders using `local_size_x_id = 0`; give the
    /// shader's fixed size for the others.
    pub local_size: u32,
    /// Further specialization constants, ids 1, 2, ... in order.
    pub constants: &'a [u32],
}

pub const UNIFORM: vk::DescriptorType = vk::DescriptorType::UNIFORM_BUFFER;
pub const STORAGE: vk::DescriptorType = vk::DescriptorType::STORAGE_BUFFER;

impl ComputePipeline {
    pub fn new(ctx: &Context, desc: &PipelineDesc) -> Result<Self> {
        let dev = &ctx.device;
        let words = ash::util::read_spv(&mut std::io::Cursor::new(desc.spirv))
            .map_err(|e| Error::Invalid(format!("shader {}: bad SPIR-V: {e}", desc.name)))?;
        let module = unsafe {
            dev.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
        }
        .vk("vkCreateShaderModule")?;
        ctx.name(module, desc.name);

        let bindings: Vec<_> = desc
            .bindings
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i as u32)
                    .descriptor_type(t)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings);
        let set_layout = unsafe { dev.create_descriptor_set_layout(&set_info, None) }
            .vk("vkCreateDescriptorSetLayout")?;
        ctx.name(set_layout, desc.name);

        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::COMPUTE,
            offset: 0,
            size: desc.push_size,
        }];
        let set_layouts = [set_layout];
        let mut layout_info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        if desc.push_size > 0 {
            layout_info = layout_info.push_constant_ranges(&ranges);
        }
        let layout = unsafe { dev.create_pipeline_layout(&layout_info, None) }
            .vk("vkCreatePipelineLayout")?;
        ctx.name(layout, desc.name);

        let mut values = vec![desc.local_size];
        values.extend_from_slice(desc.constants);
        let entries: Vec<_> = (0..values.len())
            .map(|i| vk::SpecializationMapEntry {
                constant_id: i as u32,
                offset: 4 * i as u32,
                size: 4,
            })
            .collect();
        let spec = vk::SpecializationInfo::default()
            .map_entries(&entries)
            .data(bytemuck::cast_slice(&values));
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main")
            .specialization_info(&spec);
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(layout)];
        let created =
            unsafe { dev.create_compute_pipelines(vk::PipelineCache::null(), &info, None) };
        unsafe { dev.destroy_shader_module(module, None) };
        let pipeline = created.map_err(|(_, result)| Error::Vk {
            call: "vkCreateComputePipelines",
            result,
        })?[0];
        ctx.name(pipeline, desc.name);
        Ok(ComputePipeline {
            name: desc.name.to_string(),
            pipeline,
            layout,
            set_layout,
            local_size: desc.local_size,
            push_size: desc.push_size,
            bindings: desc.bindings.to_vec(),
        })
    }

    /// Binds the pipeline, its buffers (in binding order) and push constants.
    pub fn bind<P: bytemuck::Pod>(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        buffers: &[&Buffer],
        push: &P,
    ) -> Result<()> {
        if std::mem::size_of::<P>() as u32 != self.push_size {
            return Err(Error::Invalid(format!(
                "{}: push constants are {} bytes, the pipeline declares {}",
                self.name,
                std::mem::size_of::<P>(),
                self.push_size
            )));
        }
        if buffers.len() != self.bindings.len() {
            return Err(Error::Invalid(format!(
                "{}: {} buffers given for {} bindings",
                self.name,
                buffers.len(),
                self.bindings.len()
            )));
        }
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> =
            buffers.iter().map(|b| [b.descriptor()]).collect();
        let writes: Vec<_> = infos
            .iter()
            .enumerate()
            .map(|(i, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_binding(i as u32)
                    .descriptor_type(self.bindings[i])
                    .buffer_info(info)
            })
            .collect();
        let set = ctx.allocate_descriptor_set(self.set_layout)?;
        let writes: Vec<_> = writes.into_iter().map(|w| w.dst_set(set)).collect();
        unsafe {
            ctx.device.update_descriptor_sets(&writes, &[]);
            ctx.device
                .cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, self.pipeline);
            ctx.device.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.layout,
                0,
                &[set],
                &[],
            );
            if self.push_size > 0 {
                ctx.device.cmd_push_constants(
                    cmd,
                    self.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(push),
                );
            }
        }
        Ok(())
    }

    /// Dispatches enough workgroups for `invocations` along x, folding into y
    /// beyond 65535 groups (shaders index with `x + y * numGroups.x * size`).
    pub fn dispatch<P: bytemuck::Pod>(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        buffers: &[&Buffer],
        push: &P,
        invocations: u64,
    ) -> Result<()> {
        self.bind(ctx, cmd, buffers, push)?;
        let groups = invocations.div_ceil(self.local_size as u64);
        if groups == 0 {
            return Ok(());
        }
        let x = groups.min(65535);
        let y = groups.div_ceil(x);
        if y > 65535 {
            return Err(Error::Invalid(format!(
                "{}: {invocations} invocations is too many",
                self.name
            )));
        }
        unsafe { ctx.device.cmd_dispatch(cmd, x as u32, y as u32, 1) };
        Ok(())
    }

    /// Dispatches exactly the given workgroup counts.
    pub fn dispatch_groups<P: bytemuck::Pod>(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        buffers: &[&Buffer],
        push: &P,
        groups: [u32; 3],
    ) -> Result<()> {
        self.bind(ctx, cmd, buffers, push)?;
        unsafe {
            ctx.device
                .cmd_dispatch(cmd, groups[0], groups[1], groups[2])
        };
        Ok(())
    }

    /// Dispatches with workgroup counts read from `args` at `offset`.
    pub fn dispatch_indirect<P: bytemuck::Pod>(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        buffers: &[&Buffer],
        push: &P,
        args: &Buffer,
        offset: u64,
    ) -> Result<()> {
        self.bind(ctx, cmd, buffers, push)?;
        unsafe { ctx.device.cmd_dispatch_indirect(cmd, args.raw, offset) };
        Ok(())
    }

    pub fn destroy(&self, ctx: &Context) {
        unsafe {
            ctx.device.destroy_pipeline(self.pipeline, None);
            ctx.device.destroy_pipeline_layout(self.layout, None);
            ctx.device
                .destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}
