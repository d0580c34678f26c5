//! Buffers backed by gpu-allocator, each with a debug name. Device-local
//! buffers are filled and read through host-visible staging copies.

use super::Context;
use crate::error::{Error, Result, VkContext};
use ash::vk;
use gpu_allocator::MemoryLocation;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};

pub struct Buffer {
    pub raw: vk::Buffer,
    pub size: u64,
    pub name: String,
    allocation: Option<Allocation>,
    /// Texel-buffer views made so far, one per format (whole buffer).
    views: std::sync::Mutex<Vec<(vk::Format, vk::BufferView)>>,
    usage: vk::BufferUsageFlags,
}

/// What to change when the buffer `name` is too large: the setting that
/// sizes it.
fn advice(name: &str) -> &'static str {
    let light = ["deep", "issm", "shadow map", "osm", "light"];
    let scene = [
        "spheres",
        "sphere attributes",
        "sphere colours",
        "raster jobs",
    ];
    // an instanced scene's per-batch and per-atom tables
    let instanced = ["scene batches", "molecule atoms", "atom ", "LOD "];
    if light.iter().any(|k| name.contains(k)) {
        "lower the light-map size (--issm-size, --sm-size or --osm-size)"
    } else if scene.iter().any(|k| name.starts_with(k)) {
        "render fewer spheres"
    } else if instanced.iter().any(|k| name.starts_with(k)) {
        "represent fewer atoms (its batch table holds 4 bytes per 64 atoms of every instance)"
    } else {
        "lower the image size (--width/--height)"
    }
}

/// The most bytes one staging copy of [`Buffer::upload`] holds.
const UPLOAD_PIECE: usize = 32 << 20;

impl Buffer {
    pub fn new(
        ctx: &Context,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self> {
        let size = size.max(16);
        // Every storage buffer is bound whole, so it must fit the device's
        // range; saying so beats the allocator's bare "out of memory".
        let range = ctx.props.limits.max_storage_buffer_range as u64;
        if usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER) && size > range {
            return Err(Error::DeviceLimit(format!(
                "'{name}' needs {:.1} MiB, more than this device's maxStorageBufferRange ({} MiB): {}",
                size as f64 / (1u64 << 20) as f64,
                range >> 20,
                advice(name)
            )));
        }
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage | vk::BufferUsageFlags::TRANSFER_SRC | vk::BufferUsageFlags::TRANSFER_DST)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let raw = unsafe { ctx.device.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        let requirements = unsafe { ctx.device.get_buffer_memory_requirements(raw) };
        let alloc = ctx
            .allocator
            .lock()
            .map_err(|_| Error::Internal("allocator lock poisoned".into()))
            .and_then(|mut a| {
                a.allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location,
                    linear: true,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
                .map_err(|source| Error::Alloc {
                    name: name.to_string(),
                    source,
                })
            });
        let allocation = match alloc {
            Ok(a) => a,
            Err(e) => {
                // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
                unsafe { ctx.device.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        // SAFETY: the allocation is fresh, large enough and of a matching type.
        let bound = unsafe {
            ctx.device
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())
        };
        let mut buffer = Buffer {
            raw,
            size,
            name: name.to_string(),
            allocation: Some(allocation),
            views: Default::default(),
            usage,
        };
        if let Err(result) = bound {
            buffer.destroy(ctx);
            return Err(Error::Vk {
                call: "vkBindBufferMemory",
                result,
            });
        }
        ctx.name(raw, name);
        Ok(buffer)
    }

    /// A device-local buffer of `words` u32 followed by `guard` words of
    /// `pattern` that no pass may touch (GPU-AV does not check atomics:
    /// tests read the guards instead).
    pub fn guarded(
        ctx: &Context,
        name: &str,
        words: u64,
        guard: u64,
        pattern: u32,
        usage: vk::BufferUsageFlags,
    ) -> Result<Self> {
        let buf = Buffer::new(
            ctx,
            name,
            (words + guard) * 4,
            usage,
            MemoryLocation::GpuOnly,
        )?;
        let guard = vec![pattern; guard as usize];
        if let Err(e) = buf.upload(ctx, words * 4, bytemuck::cast_slice(&guard)) {
            let mut buf = buf;
            buf.destroy(ctx);
            return Err(e);
        }
        Ok(buf)
    }

    /// A device-local storage buffer (also readable as a uniform texel
    /// buffer and writable as a storage texel buffer, through views).
    pub fn storage(ctx: &Context, name: &str, size: u64) -> Result<Self> {
        Self::new(
            ctx,
            name,
            size,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                | vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER,
            MemoryLocation::GpuOnly,
        )
    }

    /// A device-local table the shaders only read, as uniform texels: not
    /// a storage buffer, so maxTexelBufferElements bounds it, not the
    /// storage range (lavapipe: 2^27 texels against 128 MiB; an instanced
    /// scene's batch table at 10^9 atoms is 86 MB, its atoms' tables at
    /// 10^10 would pass the range).
    pub fn table(ctx: &Context, name: &str, size: u64) -> Result<Self> {
        Self::new(
            ctx,
            name,
            size,
            vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            MemoryLocation::GpuOnly,
        )
    }

    /// A texel-buffer view of the whole buffer in `format` (made once,
    /// destroyed with the buffer).
    pub fn view(&self, ctx: &Context, format: vk::Format) -> Result<vk::BufferView> {
        let texel =
            vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER | vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER;
        if !self.usage.intersects(texel) {
            return Err(Error::Internal(format!(
                "'{}' was not created for texel-buffer views",
                self.name
            )));
        }
        let mut views = self
            .views
            .lock()
            .map_err(|_| Error::Internal("buffer view lock poisoned".into()))?;
        if let Some((_, v)) = views.iter().find(|(f, _)| *f == format) {
            return Ok(*v);
        }
        let texel_bytes = match format {
            vk::Format::R32_UINT | vk::Format::R32_SFLOAT => 4,
            vk::Format::R32G32_UINT | vk::Format::R32G32_SFLOAT => 8,
            _ => 16,
        };
        let elements = self.size / texel_bytes;
        let max = ctx.props.limits.max_texel_buffer_elements as u64;
        if elements > max {
            return Err(Error::DeviceLimit(format!(
                "'{}' holds {elements} texels of {format:?}, more than this device's \
                 {max} per texel buffer (maxTexelBufferElements)",
                self.name
            )));
        }
        let info = vk::BufferViewCreateInfo::default()
            .buffer(self.raw)
            .format(format)
            .offset(0)
            .range(vk::WHOLE_SIZE);
        let view =
            unsafe { ctx.device.create_buffer_view(&info, None) }.vk("vkCreateBufferView")?;
        ctx.name(view, &format!("{} {format:?}", self.name));
        views.push((format, view));
        Ok(view)
    }

    /// Host-visible bytes (mapped), if this buffer lives in host memory.
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..self.size as usize])
    }

    pub fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        let size = self.size as usize;
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .map(|s| &mut s[..size])
    }

    /// Copies `data` into this buffer at `offset` through a staging buffer.
    pub fn upload(&self, ctx: &Context, offset: u64, data: &[u8]) -> Result<()> {
        if data.is_empty() {
            return Ok(());
        }
        if offset + data.len() as u64 > self.size {
            return Err(Error::Internal(format!(
                "upload past the end of {}",
                self.name
            )));
        }
        // (in pieces through one staging buffer: a scene's tables reach
        // hundreds of MiB, and a whole-size staging copy would double the
        // peak host memory)
        let piece = data.len().min(UPLOAD_PIECE);
        let mut staging = Buffer::new(
            ctx,
            &format!("{} upload", self.name),
            piece as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        let result = (|| {
            for (k, chunk) in data.chunks(piece).enumerate() {
                let dst = staging
                    .mapped_mut()
                    .ok_or_else(|| Error::Internal("staging buffer not mapped".into()))?;
                dst[..chunk.len()].copy_from_slice(chunk);
                ctx.one_shot("upload", |cmd| {
                    let region = [vk::BufferCopy {
                        src_offset: 0,
                        dst_offset: offset + (k * piece) as u64,
                        size: chunk.len() as u64,
                    }];
                    // SAFETY: the command buffer is in the recording state; the handles are live.
                    unsafe {
                        ctx.device
                            .cmd_copy_buffer(cmd, staging.raw, self.raw, &region)
                    };
                    Ok(())
                })?;
            }
            Ok(())
        })();
        staging.destroy(ctx);
        result
    }

    /// [`upload`](Self::upload) through a caller-kept host-visible
    /// `staging` buffer (made or grown as needed): per-frame data such as
    /// trajectory positions allocates nothing after the first frame.
    pub fn upload_with(
        &self,
        ctx: &Context,
        data: &[u8],
        staging: &mut Option<Buffer>,
    ) -> Result<()> {
        if data.len() as u64 > self.size {
            return Err(Error::Internal(format!(
                "upload past the end of {}",
                self.name
            )));
        }
        if staging.as_ref().is_none_or(|s| s.size < data.len() as u64) {
            if let Some(mut old) = staging.take() {
                old.destroy(ctx);
            }
            *staging = Some(Buffer::new(
                ctx,
                &format!("{} staging", self.name),
                data.len() as u64,
                vk::BufferUsageFlags::TRANSFER_SRC,
                MemoryLocation::CpuToGpu,
            )?);
        }
        let st = staging
            .as_mut()
            .ok_or_else(|| Error::Internal("no staging buffer".into()))?;
        let dst = st
            .mapped_mut()
            .ok_or_else(|| Error::Internal("staging buffer not mapped".into()))?;
        dst[..data.len()].copy_from_slice(data);
        let src = st.raw;
        ctx.one_shot("upload", |cmd| {
            let region = [vk::BufferCopy {
                src_offset: 0,
                dst_offset: 0,
                size: data.len() as u64,
            }];
            // SAFETY: the command buffer is recording; both handles are live
            // and the caller waited for frames that read the destination.
            unsafe { ctx.device.cmd_copy_buffer(cmd, src, self.raw, &region) };
            Ok(())
        })
    }

    /// Reads `len` bytes at `offset` back to the host (waits for the queue).
    pub fn download(&self, ctx: &Context, offset: u64, len: u64) -> Result<Vec<u8>> {
        if offset + len > self.size {
            return Err(Error::Internal(format!(
                "download past the end of {}",
                self.name
            )));
        }
        let mut staging = Buffer::new(
            ctx,
            &format!("{} readback", self.name),
            len,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let result = ctx
            .one_shot("readback", |cmd| {
                super::barrier::Barrier::start_of_submission().record(&ctx.device, cmd);
                let region = [vk::BufferCopy {
                    src_offset: offset,
                    dst_offset: 0,
                    size: len,
                }];
                // SAFETY: both ranges lie inside live buffers (checked above).
                unsafe {
                    ctx.device
                        .cmd_copy_buffer(cmd, self.raw, staging.raw, &region)
                };
                // Make the copy visible to the host read after the fence.
                super::barrier::Barrier::transfer_to_host().record(&ctx.device, cmd);
                Ok(())
            })
            .and_then(|_| {
                staging
                    .mapped()
                    .map(|m| m[..len as usize].to_vec())
                    .ok_or_else(|| Error::Internal("readback buffer not mapped".into()))
            });
        staging.destroy(ctx);
        result
    }

    /// Reads the whole buffer as a vector of `T`.
    pub fn download_pod<T: bytemuck::Pod>(
        &self,
        ctx: &Context,
        first: u64,
        count: u64,
    ) -> Result<Vec<T>> {
        let sz = std::mem::size_of::<T>() as u64;
        let bytes = self.download(ctx, first * sz, count * sz)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }

    /// Whether the buffer can be bound as a storage buffer.
    pub fn is_storage(&self) -> bool {
        self.usage.contains(vk::BufferUsageFlags::STORAGE_BUFFER)
    }

    pub fn descriptor(&self) -> vk::DescriptorBufferInfo {
        vk::DescriptorBufferInfo {
            buffer: self.raw,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }
    }

    /// Frees the buffer; idempotent, so owners may call it from `Drop`.
    pub fn destroy(&mut self, ctx: &Context) {
        if let Ok(mut views) = self.views.lock() {
            for (_, v) in views.drain(..) {
                // SAFETY: the owner destroys the buffer after its last use.
                unsafe { ctx.device.destroy_buffer_view(v, None) };
            }
        }
        if let Some(a) = self.allocation.take() {
            if let Ok(mut alloc) = ctx.allocator.lock() {
                let _ = alloc.free(a);
            }
            // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
            unsafe { ctx.device.destroy_buffer(self.raw, None) };
        }
    }
}
