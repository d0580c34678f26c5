//! `--raster graphics`: the vertex/fragment impostor baseline with the same
//! output as the compute rasterizer (same pixel rectangles, same exact test,
//! same 64-bit atomicMin into the visibility buffer), drawn with dynamic
//! rendering and no attachments.

use super::compute::RasterIo;
use crate::error::{Error, Result, VkContext};
use crate::passes::spirv;
use crate::vk::barrier::{Stage, Use};
use crate::vk::descriptors::DescriptorArena;
use crate::vk::{Buffer, Context, PassBuilder};
use ash::vk;

pub struct GraphicsRasterPass {
    pipeline: vk::Pipeline,
    layout: vk::PipelineLayout,
    set_layout: vk::DescriptorSetLayout,
}

fn module(ctx: &Context, shader: crate::vk::pipeline::Shader) -> Result<vk::ShaderModule> {
    let name = shader.file;
    let words = ash::util::read_spv(&mut std::io::Cursor::new(shader.spirv))
        .map_err(|e| Error::Internal(format!("shader {name}: bad SPIR-V: {e}")))?;
    let m = unsafe {
        ctx.device
            .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
    }
    .vk("vkCreateShaderModule")?;
    ctx.name(m, name);
    Ok(m)
}

impl GraphicsRasterPass {
    pub fn new(ctx: &Context) -> Result<Self> {
        let dev = &ctx.device;
        let stages = vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT;
        let types = [
            vk::DescriptorType::UNIFORM_BUFFER,
            vk::DescriptorType::STORAGE_BUFFER,
            vk::DescriptorType::STORAGE_BUFFER,
        ];
        let bindings: Vec<_> = types
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(i as u32)
                    .descriptor_type(t)
                    .descriptor_count(1)
                    .stage_flags(stages)
            })
            .collect();
        let set_layout = unsafe {
            dev.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
        }
        .vk("vkCreateDescriptorSetLayout")?;
        ctx.name(set_layout, "raster graphics");
        let ranges = [vk::PushConstantRange {
            stage_flags: stages,
            offset: 0,
            size: 4,
        }];
        let sets = [set_layout];
        let layout = unsafe {
            dev.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&sets)
                    .push_constant_ranges(&ranges),
                None,
            )
        }
        .vk("vkCreatePipelineLayout")?;
        ctx.name(layout, "raster graphics");

        let vs = module(ctx, spirv::RASTER_IMPOSTOR_VERT)?;
        let fs = module(ctx, spirv::RASTER_IMPOSTOR_FRAG)?;
        let stage_info = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(vs)
                .name(c"main"),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(fs)
                .name(c"main"),
        ];
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default();
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(vk::CullModeFlags::NONE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let blend = vk::PipelineColorBlendStateCreateInfo::default();
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        // No attachments: fragments only have the atomicMin side effect.
        let mut rendering = vk::PipelineRenderingCreateInfo::default();
        let info = [vk::GraphicsPipelineCreateInfo::default()
            .stages(&stage_info)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(layout)
            .push_next(&mut rendering)];
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        let created = unsafe { dev.create_graphics_pipelines(ctx.pipeline_cache, &info, None) };
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe {
            dev.destroy_shader_module(vs, None);
            dev.destroy_shader_module(fs, None);
        }
        let pipeline = created.map_err(|(_, result)| Error::Vk {
            call: "vkCreateGraphicsPipelines",
            result,
        })?[0];
        ctx.name(pipeline, "raster graphics");
        Ok(GraphicsRasterPass {
            pipeline,
            layout,
            set_layout,
        })
    }

    /// Steps of the `raster` pass: clear `vis`, draw every sphere of view 0
    /// (the camera) at `w`x`h`.
    pub fn steps<'b>(&'b self, p: &mut PassBuilder<'b>, io: &RasterIo<'b>, (w, h): (u32, u32)) {
        let RasterIo {
            globals,
            scene,
            target: vis,
            ..
        } = *io;
        // (plain scenes only: the renderer refuses instanced ones with
        // --raster graphics)
        let (spheres, sphere_count) = (&scene.spheres, scene.slots);
        p.fill(vis, w as u64 * h as u64 * 8, u32::MAX);
        let uses = vec![
            Use {
                buffer: globals.raw,
                stage: Stage::Graphics,
                read: true,
                write: false,
            },
            Use {
                buffer: spheres.raw,
                stage: Stage::Graphics,
                read: true,
                write: false,
            },
            Use {
                buffer: vis.raw,
                stage: Stage::Graphics,
                read: true,
                write: true,
            },
        ];
        p.raw("raster graphics draw", uses, move |ctx, cmd, arena| {
            self.draw(
                ctx,
                cmd,
                arena,
                [globals, spheres, vis],
                sphere_count,
                (w, h),
            )
        });
    }

    fn draw(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        arena: &mut DescriptorArena,
        [globals, spheres, vis]: [&Buffer; 3],
        sphere_count: u32,
        (w, h): (u32, u32),
    ) -> Result<()> {
        let dev = &ctx.device;
        let set = arena.allocate(ctx, self.set_layout)?;
        let infos = [
            [globals.descriptor()],
            [spheres.descriptor()],
            [vis.descriptor()],
        ];
        let types = [
            vk::DescriptorType::UNIFORM_BUFFER,
            vk::DescriptorType::STORAGE_BUFFER,
            vk::DescriptorType::STORAGE_BUFFER,
        ];
        let writes: Vec<_> = infos
            .iter()
            .zip(types)
            .enumerate()
            .map(|(i, (info, t))| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(i as u32)
                    .descriptor_type(t)
                    .buffer_info(info)
            })
            .collect();
        let area = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: vk::Extent2D {
                width: w,
                height: h,
            },
        };
        let rendering = vk::RenderingInfo::default()
            .render_area(area)
            .layer_count(1);
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: w as f32,
            height: h as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        // SAFETY: set, pipeline and buffers are live; cmd is recording
        // outside a render pass.
        unsafe {
            dev.update_descriptor_sets(&writes, &[]);
            dev.cmd_begin_rendering(cmd, &rendering);
            dev.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, self.pipeline);
            dev.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::GRAPHICS,
                self.layout,
                0,
                &[set],
                &[],
            );
            dev.cmd_push_constants(
                cmd,
                self.layout,
                vk::ShaderStageFlags::VERTEX | vk::ShaderStageFlags::FRAGMENT,
                0,
                &0u32.to_le_bytes(),
            );
            dev.cmd_set_viewport(cmd, 0, &[viewport]);
            dev.cmd_set_scissor(cmd, 0, &[area]);
            dev.cmd_draw(cmd, 6 * sphere_count, 1, 0, 0);
            dev.cmd_end_rendering(cmd);
        }
        Ok(())
    }

    /// Destroys the pipeline objects; a second call does nothing.
    pub fn destroy(&mut self, ctx: &Context) {
        crate::vk::pipeline::destroy_pipeline_objects(
            ctx,
            &mut self.pipeline,
            &mut self.layout,
            &mut self.set_layout,
        );
    }
}
crate::impl_destroy!(GraphicsRasterPass);
