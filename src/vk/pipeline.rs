//! Compute pipelines. Each pass declares a pipeline's bindings once, by the
//! GLSL block name and access (`ro("Spheres")`, `rw("Vis")`, ...); at
//! creation they are checked against the shader's SPIR-V ([`super::reflect`]):
//! a missing, extra, mistyped or differently qualified binding is an error
//! naming the shader, the binding and both types. Dispatches then bind
//! buffers by name (a swapped pair cannot compile into a wrong frame), with
//! typed push constants whose size is checked against the shader too. The
//! workgroup size is specialization constant 0 (`local_size_x_id = 0`);
//! further constants (mode switches) are ids 1, 2, ...

use super::barrier::{Stage, Use};
use super::descriptors::DescriptorArena;
use super::grid::Grid;
use super::reflect::{self, Access};
use super::{Buffer, Context};
use crate::error::{Error, Result, VkContext};
use crate::gpu::consts::{MAX_GROUPS_X, SCENE_KIND_ID};
use ash::vk;

/// A shader embedded by build.rs.
#[derive(Clone, Copy, Debug)]
pub struct Shader {
    /// File name under glsl/ (for messages).
    pub file: &'static str,
    pub spirv: &'static [u8],
}

/// One declared binding: the GLSL block name (a texel buffer's variable
/// name), how the shader uses it, and for texel buffers the view format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Binding {
    pub name: &'static str,
    pub access: Access,
    pub format: vk::Format,
}

const fn binding(name: &'static str, access: Access, format: vk::Format) -> Binding {
    Binding {
        name,
        access,
        format,
    }
}

pub const fn uniform(name: &'static str) -> Binding {
    binding(name, Access::Uniform, vk::Format::UNDEFINED)
}
/// A `readonly` storage buffer.
pub const fn ro(name: &'static str) -> Binding {
    binding(name, Access::Read, vk::Format::UNDEFINED)
}
/// A `writeonly` storage buffer.
pub const fn wo(name: &'static str) -> Binding {
    binding(name, Access::Write, vk::Format::UNDEFINED)
}
/// A storage buffer without qualifiers (read, written or atomics).
pub const fn rw(name: &'static str) -> Binding {
    binding(name, Access::ReadWrite, vk::Format::UNDEFINED)
}
/// A uniform texel buffer read through a view of this format.
pub const fn texel(name: &'static str, format: vk::Format) -> Binding {
    binding(name, Access::Texel, format)
}
/// A `writeonly` storage texel buffer of this format.
pub const fn image_wo(name: &'static str, format: vk::Format) -> Binding {
    binding(name, Access::ImageWrite, format)
}
/// A `readonly` storage texel buffer of this format.
pub const fn image_ro(name: &'static str, format: vk::Format) -> Binding {
    binding(name, Access::ImageRead, format)
}

/// What a compute pipeline is made of.
pub struct PipelineDesc<'a> {
    /// Debug name (object names, errors).
    pub name: &'a str,
    pub shader: Shader,
    pub bindings: &'a [Binding],
    pub push_size: u32,
    /// Workgroup size for shaders using `local_size_x_id = 0`; give the
    /// shader's fixed size for the others.
    pub local_size: u32,
    /// Further specialization constants, ids 1, 2, ... in order.
    pub constants: &'a [u32],
    /// The scene's SCENE_SPEC (kind and batch shift), specialization constant SCENE_KIND_ID of shaders
    /// that include glsl/scene.glsl (src/passes/scene.rs; 0 = plain).
    pub scene: u32,
}

pub struct ComputePipeline {
    pub name: String,
    pub pipeline: vk::Pipeline,
    pub layout: vk::PipelineLayout,
    pub set_layout: vk::DescriptorSetLayout,
    /// Invocations per workgroup along x.
    pub local_size: u32,
    pub push_size: u32,
    /// Declared bindings with their binding numbers (None: declared but
    /// removed from the SPIR-V by the optimizer because unused).
    bindings: Vec<(Binding, Option<u32>)>,
}

/// What makes two compute pipelines the same: the shader's SPIR-V, the
/// layout (declared bindings, whose numbers the SPIR-V gives, and push
/// size) and the specialization (debug name included: object names stay
/// right).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct PipelineKey {
    name: String,
    spirv: (usize, usize),
    bindings: Vec<Binding>,
    push_size: u32,
    local_size: u32,
    constants: Vec<u32>,
    scene: u32,
}

/// A context's compute pipelines by key: the pipeline, its layout and its
/// descriptor set layout ([`Context::pipelines`]).
pub type Pool = std::collections::HashMap<
    PipelineKey,
    (vk::Pipeline, vk::PipelineLayout, vk::DescriptorSetLayout),
>;

/// Checks declared bindings against the reflected ones; returns each
/// declared binding's number.
pub fn check_bindings(
    desc_name: &str,
    shader: &Shader,
    declared: &[Binding],
    push_size: u32,
    found: &reflect::Reflection,
) -> Result<Vec<Option<u32>>> {
    let err = |m: String| Err(Error::Internal(format!("shader {}: {m}", shader.file)));
    for (i, b) in declared.iter().enumerate() {
        if declared[..i].iter().any(|d| d.name == b.name) {
            return err(format!(
                "pipeline '{desc_name}' declares binding '{}' twice",
                b.name
            ));
        }
    }
    for d in &found.descriptors {
        if d.set != 0 {
            return err(format!(
                "binding '{}' is in descriptor set {}, only set 0 is used",
                d.name, d.set
            ));
        }
        match declared.iter().find(|b| b.name == d.name) {
            None => {
                return err(format!(
                    "binding {} '{}' ({}) is not declared by pipeline '{desc_name}'",
                    d.binding,
                    d.name,
                    d.access.describe()
                ));
            }
            Some(b) if b.access != d.access => {
                return err(format!(
                    "binding {} '{}' is a {} in the SPIR-V, pipeline '{desc_name}' declares a {}",
                    d.binding,
                    d.name,
                    d.access.describe(),
                    b.access.describe()
                ));
            }
            Some(_) => {}
        }
    }
    // An optimizing build may drop unused bindings and push blocks; a
    // debug build (the tests) keeps everything, so names are checked there.
    let strict = cfg!(debug_assertions);
    let mut numbers = Vec::new();
    for b in declared {
        let n = found
            .descriptors
            .iter()
            .find(|d| d.name == b.name)
            .map(|d| d.binding);
        if n.is_none() && strict {
            return err(format!(
                "pipeline '{desc_name}' declares binding '{}' ({}) that the shader does not have",
                b.name,
                b.access.describe()
            ));
        }
        numbers.push(n);
    }
    if found.push_size != push_size && (strict || found.push_size != 0) {
        return err(format!(
            "push constants are {} bytes in the SPIR-V, pipeline '{desc_name}' declares {push_size}",
            found.push_size
        ));
    }
    Ok(numbers)
}

impl ComputePipeline {
    pub fn new(ctx: &Context, desc: &PipelineDesc) -> Result<Self> {
        let dev = &ctx.device;
        let words =
            ash::util::read_spv(&mut std::io::Cursor::new(desc.shader.spirv)).map_err(|e| {
                Error::Internal(format!("shader {}: bad SPIR-V: {e}", desc.shader.file))
            })?;
        let found = reflect::reflect(&words)
            .map_err(|e| Error::Internal(format!("shader {}: {e}", desc.shader.file)))?;
        let numbers = check_bindings(
            desc.name,
            &desc.shader,
            desc.bindings,
            desc.push_size,
            &found,
        )?;
        if cfg!(debug_assertions) {
            for id in 1..=desc.constants.len() as u32 {
                if !found.spec_ids.contains(&id) {
                    return Err(Error::Internal(format!(
                        "shader {}: pipeline '{}' sets specialization constant {id}, which the shader does not declare",
                        desc.shader.file, desc.name
                    )));
                }
            }
        }

        let key = PipelineKey {
            name: desc.name.to_string(),
            spirv: (desc.shader.spirv.as_ptr() as usize, desc.shader.spirv.len()),
            bindings: desc.bindings.to_vec(),
            push_size: desc.push_size,
            local_size: desc.local_size,
            constants: desc.constants.to_vec(),
            scene: desc.scene,
        };
        let made = |(pipeline, layout, set_layout)| ComputePipeline {
            name: desc.name.to_string(),
            pipeline,
            layout,
            set_layout,
            local_size: desc.local_size,
            push_size: desc.push_size,
            bindings: desc.bindings.iter().copied().zip(numbers.clone()).collect(),
        };
        let pool = || ctx.pipelines.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(&objects) = pool().get(&key) {
            return Ok(made(objects));
        }

        let layout_bindings: Vec<_> = desc
            .bindings
            .iter()
            .zip(&numbers)
            .filter_map(|(b, n)| n.map(|n| (b, n)))
            .map(|(b, n)| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(n)
                    .descriptor_type(descriptor_type(b.access))
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings);
        // SAFETY: plain create calls with checked arguments; every object is
        // destroyed below on failure or by `destroy`.
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
        let layout = match unsafe { dev.create_pipeline_layout(&layout_info, None) } {
            Ok(l) => l,
            Err(result) => {
                // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
                unsafe { dev.destroy_descriptor_set_layout(set_layout, None) };
                return Err(Error::Vk {
                    call: "vkCreatePipelineLayout",
                    result,
                });
            }
        };
        ctx.name(layout, desc.name);

        let module = match unsafe {
            dev.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None)
        } {
            Ok(m) => m,
            Err(result) => {
                // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
                unsafe {
                    dev.destroy_pipeline_layout(layout, None);
                    dev.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(Error::Vk {
                    call: "vkCreateShaderModule",
                    result,
                });
            }
        };
        ctx.name(module, desc.name);
        let mut values = vec![desc.local_size];
        values.extend_from_slice(desc.constants);
        let mut entries: Vec<_> = (0..values.len())
            .map(|i| vk::SpecializationMapEntry {
                constant_id: i as u32,
                offset: 4 * i as u32,
                size: 4,
            })
            .collect();
        if found.spec_ids.contains(&SCENE_KIND_ID) {
            entries.push(vk::SpecializationMapEntry {
                constant_id: SCENE_KIND_ID,
                offset: 4 * values.len() as u32,
                size: 4,
            });
            values.push(desc.scene);
        } else if desc.scene != 0 {
            return Err(Error::Internal(format!(
                "shader {}: pipeline '{}' is given a scene kind, but the shader does not read the scene",
                desc.shader.file, desc.name
            )));
        }
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
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        let created = unsafe { dev.create_compute_pipelines(ctx.pipeline_cache, &info, None) };
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe { dev.destroy_shader_module(module, None) };
        let pipeline = match created {
            Ok(p) => p[0],
            Err((_, result)) => {
                // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
                unsafe {
                    dev.destroy_pipeline_layout(layout, None);
                    dev.destroy_descriptor_set_layout(set_layout, None);
                }
                return Err(Error::Vk {
                    call: "vkCreateComputePipelines",
                    result,
                });
            }
        };
        ctx.name(pipeline, desc.name);
        ctx.compiled
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut pool = pool();
        if let Some(&objects) = pool.get(&key) {
            // (another thread made the same one meanwhile)
            let (mut p, mut l, mut s) = (pipeline, layout, set_layout);
            destroy_pipeline_objects(ctx, &mut p, &mut l, &mut s);
            return Ok(made(objects));
        }
        pool.insert(key, (pipeline, layout, set_layout));
        Ok(made((pipeline, layout, set_layout)))
    }

    /// The accesses of a dispatch with these named buffers (for barriers);
    /// every declared binding must be given exactly once.
    pub fn uses(&self, given: &[(&'static str, &Buffer)]) -> Result<Vec<Use>> {
        for (i, (name, _)) in given.iter().enumerate() {
            if !self.bindings.iter().any(|(b, _)| b.name == *name) {
                return Err(Error::Internal(format!(
                    "pipeline '{}' has no binding '{name}'",
                    self.name
                )));
            }
            if given[..i].iter().any(|(n, _)| n == name) {
                return Err(Error::Internal(format!(
                    "pipeline '{}': binding '{name}' given twice",
                    self.name
                )));
            }
        }
        self.bindings
            .iter()
            .map(|(b, _)| {
                let buf = given
                    .iter()
                    .find(|(n, _)| *n == b.name)
                    .map(|(_, buf)| *buf)
                    .ok_or_else(|| {
                        Error::Internal(format!(
                            "pipeline '{}': no buffer given for binding '{}'",
                            self.name, b.name
                        ))
                    })?;
                Ok(Use {
                    buffer: buf.raw,
                    stage: Stage::Compute,
                    read: b.access.reads(),
                    write: b.access.writes(),
                })
            })
            .collect()
    }

    /// Binds the pipeline, its buffers (by binding name) and push constants.
    pub fn bind(
        &self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        arena: &mut DescriptorArena,
        given: &[(&'static str, &Buffer)],
        push: &[u8],
    ) -> Result<()> {
        if push.len() as u32 != self.push_size {
            return Err(Error::Internal(format!(
                "{}: push constants are {} bytes, the pipeline declares {}",
                self.name,
                push.len(),
                self.push_size
            )));
        }
        self.uses(given)?;
        let mut infos: Vec<(u32, [vk::DescriptorBufferInfo; 1], Access)> = Vec::new();
        let mut views: Vec<(u32, [vk::BufferView; 1], Access)> = Vec::new();
        for (b, n) in &self.bindings {
            let (Some(n), Some((_, buf))) = (n, given.iter().find(|(g, _)| *g == b.name)) else {
                continue;
            };
            if b.access.is_texel() {
                views.push((*n, [buf.view(ctx, b.format)?], b.access));
            } else {
                infos.push((*n, [buf.descriptor()], b.access));
            }
        }
        let set = arena.allocate(ctx, self.set_layout)?;
        let mut writes: Vec<_> = infos
            .iter()
            .map(|(n, info, access)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(set)
                    .dst_binding(*n)
                    .descriptor_type(descriptor_type(*access))
                    .buffer_info(info)
            })
            .collect();
        writes.extend(views.iter().map(|(n, view, access)| {
            vk::WriteDescriptorSet::default()
                .dst_set(set)
                .dst_binding(*n)
                .descriptor_type(descriptor_type(*access))
                .texel_buffer_view(view)
        }));
        // SAFETY: the set, layout, pipeline and buffers are live; cmd records.
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
                    push,
                );
            }
        }
        Ok(())
    }

    /// Records the dispatch of a bound pipeline.
    pub fn dispatch_grid(&self, ctx: &Context, cmd: vk::CommandBuffer, grid: Grid) -> Result<()> {
        let groups = match grid {
            Grid::Invocations(n) => {
                let groups = n.div_ceil(self.local_size as u64);
                if groups == 0 {
                    return Ok(());
                }
                fold_groups(groups).ok_or_else(|| {
                    Error::Internal(format!(
                        "{}: {n} invocations is too many for one dispatch",
                        self.name
                    ))
                })?
            }
            Grid::Groups(g) => g,
            Grid::Indirect(args, offset) => {
                // SAFETY: args is a live indirect buffer; the offset is the pass's layout.
                unsafe { ctx.device.cmd_dispatch_indirect(cmd, args.raw, offset) };
                return Ok(());
            }
        };
        // SAFETY: a pipeline is bound; group counts are within the limits.
        unsafe {
            ctx.device
                .cmd_dispatch(cmd, groups[0], groups[1], groups[2])
        };
        Ok(())
    }

    /// Lets go of the pipeline: its objects stay in the context's pool for
    /// the next renderer (destroyed with the device); a second call does
    /// nothing.
    pub fn destroy(&mut self, _ctx: &Context) {
        // (the context's pool owns the objects: destroyed with the device)
        self.pipeline = vk::Pipeline::null();
        self.layout = vk::PipelineLayout::null();
        self.set_layout = vk::DescriptorSetLayout::null();
    }
}

/// Destroys a pipeline with its layout and descriptor set layout and nulls
/// the handles (the graphics raster baseline; a compute pipeline pooled
/// twice by racing threads); a
/// second call does nothing. The owner calls it after the last frame using
/// the pipeline finished.
pub fn destroy_pipeline_objects(
    ctx: &Context,
    pipeline: &mut vk::Pipeline,
    layout: &mut vk::PipelineLayout,
    set_layout: &mut vk::DescriptorSetLayout,
) {
    if *pipeline == vk::Pipeline::null() {
        return;
    }
    // SAFETY: no frame using the pipeline is in flight (the caller's
    // contract above); each handle is destroyed once, then nulled.
    unsafe {
        ctx.device.destroy_pipeline(*pipeline, None);
        ctx.device.destroy_pipeline_layout(*layout, None);
        ctx.device.destroy_descriptor_set_layout(*set_layout, None);
    }
    *pipeline = vk::Pipeline::null();
    *layout = vk::PipelineLayout::null();
    *set_layout = vk::DescriptorSetLayout::null();
}

fn descriptor_type(access: Access) -> vk::DescriptorType {
    match access {
        Access::Uniform => vk::DescriptorType::UNIFORM_BUFFER,
        Access::Read | Access::Write | Access::ReadWrite => vk::DescriptorType::STORAGE_BUFFER,
        Access::Texel => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
        Access::ImageRead | Access::ImageWrite | Access::ImageReadWrite => {
            vk::DescriptorType::STORAGE_TEXEL_BUFFER
        }
    }
}

/// Group counts for `groups` workgroups along a flat index (glsl/grid.glsl
/// `grid_of` folds the GPU's alike): one row up to MAX_GROUPS_X, past it
/// `rows` rows of groups / rows rounded up, so fewer than `rows` groups run
/// past the count (rows of MAX_GROUPS_X ran up to 65,534 empty workgroups,
/// ~1.3 us each on lavapipe). None past MAX_GROUPS_X rows.
pub fn fold_groups(groups: u64) -> Option<[u32; 3]> {
    let rows = groups.div_ceil(MAX_GROUPS_X as u64);
    if rows > MAX_GROUPS_X as u64 {
        return None;
    }
    Some([groups.div_ceil(rows.max(1)) as u32, rows as u32, 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every group count folds into rows that cover it with fewer than a
    /// row's count of groups past it, each row within the limit.
    #[test]
    fn group_counts_fold_into_rows_with_few_spare() {
        let max = MAX_GROUPS_X as u64;
        for groups in [
            1,
            max - 1,
            max,
            max + 1,
            209_000,
            262_140,
            3 * max + 7,
            max * max,
        ] {
            let [x, y, z] = fold_groups(groups).expect("fits");
            let (x, y) = (x as u64, y as u64);
            assert_eq!(z, 1);
            assert!(x <= max && y <= max, "{groups}: {x} x {y}");
            assert!(x * y >= groups && x * y - groups < y, "{groups}: {x} x {y}");
        }
        assert_eq!(fold_groups(0), Some([0, 0, 1]));
        assert_eq!(fold_groups(max * max + 1), None);
    }
}
