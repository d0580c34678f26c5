//! Vulkan core: instance, validation, device selection with feature checks,
//! memory, pipelines, timestamps. Everything above this module speaks in
//! buffers, pipelines and pass scopes.

pub mod barrier;
pub mod buffer;
pub mod cache;
pub mod debug;
pub mod descriptors;
pub mod grid;
pub mod guard;
pub mod pipeline;
pub mod record;
pub mod reflect;
pub mod timestamps;

use crate::error::{Error, Result, VkContext};
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{CStr, CString, c_char};
use std::mem::ManuallyDrop;
use std::sync::Mutex;

pub use buffer::Buffer;
pub use debug::MessageLog;
pub use grid::Grid;
pub use pipeline::ComputePipeline;
pub use record::{PassBuilder, Recorder};
pub use timestamps::{PassTimes, Profiler};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Enable the Khronos validation layer with GPU-assisted and
    /// synchronization validation, counting warnings and errors.
    pub validate: bool,
    /// Index into the enumerated physical devices, overriding the preference
    /// discrete > integrated > virtual > CPU.
    pub device_index: Option<usize>,
    /// Extra instance extensions (window surfaces).
    pub instance_extensions: Vec<CString>,
    /// Enable VK_KHR_swapchain on the device.
    pub swapchain: bool,
}

/// Summary of one physical device for `sphereshade info` and the JSON.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub kind: String,
    pub api_version: String,
    pub driver: String,
    pub missing_features: Vec<&'static str>,
}

pub struct Context {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    debug_instance: Option<ash::ext::debug_utils::Instance>,
    messenger: vk::DebugUtilsMessengerEXT,
    pub debug_device: Option<ash::ext::debug_utils::Device>,
    pub physical: vk::PhysicalDevice,
    pub props: vk::PhysicalDeviceProperties,
    pub info: DeviceInfo,
    pub device: ash::Device,
    /// Pipeline cache, loaded from and saved to the user's cache directory
    /// (see [`cache`]), so a second start creates pipelines quickly.
    pub pipeline_cache: vk::PipelineCache,
    cache_file: Option<std::path::PathBuf>,
    /// Compute pipelines made on this device, kept until it is destroyed
    /// and handed to every later renderer asking for the same one
    /// ([`pipeline::PipelineKey`]): a pipeline compiles once per context
    /// (lavapipe compiles each with LLVM, and with GPU-assisted validation
    /// each instrumented copy again: ~1 s a pipeline).
    pub(crate) pipelines: Mutex<pipeline::Pool>,
    /// [`Context::pipelines_compiled`].
    pub(crate) compiled: std::sync::atomic::AtomicU64,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub allocator: ManuallyDrop<Mutex<Allocator>>,
    pub command_pool: vk::CommandPool,
    /// Warnings and errors from the validation layer (boxed: its address is
    /// the messenger's user data).
    pub messages: Box<MessageLog>,
    pub validation: bool,
    device_destroyed: bool,
}

fn device_kind(t: vk::PhysicalDeviceType) -> (&'static str, u32) {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => ("discrete", 0),
        vk::PhysicalDeviceType::INTEGRATED_GPU => ("integrated", 1),
        vk::PhysicalDeviceType::VIRTUAL_GPU => ("virtual", 2),
        vk::PhysicalDeviceType::CPU => ("cpu", 3),
        _ => ("other", 4),
    }
}

fn version_string(v: u32) -> String {
    format!(
        "{}.{}.{}",
        vk::api_version_major(v),
        vk::api_version_minor(v),
        vk::api_version_patch(v)
    )
}

/// Features the renderer cannot work without, checked per device.
fn missing_features(instance: &ash::Instance, pd: vk::PhysicalDevice) -> Vec<&'static str> {
    let mut missing = Vec::new();
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f12);
    // SAFETY: pd comes from this instance.
    unsafe { instance.get_physical_device_features2(pd, &mut f2) };
    if f2.features.shader_int64 == vk::FALSE {
        missing.push("shaderInt64");
    }
    if f12.shader_buffer_int64_atomics == vk::FALSE {
        missing.push("shaderBufferInt64Atomics");
    }
    let props = unsafe { instance.get_physical_device_properties(pd) };
    // synchronization2 and dynamic rendering are used as Vulkan 1.3 core.
    if props.api_version < vk::API_VERSION_1_3 {
        missing.push("Vulkan 1.3");
    }
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut f2b = vk::PhysicalDeviceFeatures2::default().push_next(&mut f13);
    unsafe { instance.get_physical_device_features2(pd, &mut f2b) };
    if f13.synchronization2 == vk::FALSE {
        missing.push("synchronization2");
    }
    if f13.dynamic_rendering == vk::FALSE {
        missing.push("dynamicRendering");
    }
    if compute_queue_family(instance, pd).is_none() {
        missing.push("a compute queue with timestamps (timestampValidBits > 0)");
    }
    // Test seam: pretend the device lacks a feature, so the failure path can
    // be exercised on lavapipe (which has them all).
    if let Ok(denied) = std::env::var("SPHERESHADE_DENY_FEATURE") {
        for name in [
            "shaderInt64",
            "shaderBufferInt64Atomics",
            "synchronization2",
        ] {
            if denied.split(',').any(|d| d == name) && !missing.contains(&name) {
                missing.push(name);
            }
        }
    }
    missing
}

fn compute_queue_family(instance: &ash::Instance, pd: vk::PhysicalDevice) -> Option<u32> {
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    // Prefer a graphics+compute family (the viewer presents from it too).
    let ok = |f: &vk::QueueFamilyProperties| {
        f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.timestamp_valid_bits > 0
    };
    families
        .iter()
        .position(|f| ok(f) && f.queue_flags.contains(vk::QueueFlags::GRAPHICS))
        .or_else(|| families.iter().position(ok))
        .map(|i| i as u32)
}

fn driver_string(instance: &ash::Instance, pd: vk::PhysicalDevice) -> String {
    let mut drv = vk::PhysicalDeviceDriverProperties::default();
    let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut drv);
    unsafe { instance.get_physical_device_properties2(pd, &mut p2) };
    let name = drv
        .driver_name_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let info = drv
        .driver_info_as_c_str()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!("{name} {info}").trim().to_string()
}

/// Loads the Vulkan loader and creates an instance (without a device): used by
/// `sphereshade info` and by `Context::new`.
fn create_instance(
    entry: &ash::Entry,
    opts: &ContextOptions,
) -> Result<(ash::Instance, bool /*debug utils*/)> {
    let layers = unsafe { entry.enumerate_instance_layer_properties() }
        .vk("vkEnumerateInstanceLayerProperties")?;
    let has_validation = layers
        .iter()
        .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
    if opts.validate && !has_validation {
        return Err(Error::NoValidationLayer);
    }
    let exts = unsafe { entry.enumerate_instance_extension_properties(None) }
        .vk("vkEnumerateInstanceExtensionProperties")?;
    let has_ext = |n: &CStr| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(n));
    // The validation layer provides debug utils itself.
    let debug_utils = opts.validate || has_ext(ash::ext::debug_utils::NAME);

    let mut ext_names: Vec<*const c_char> = opts
        .instance_extensions
        .iter()
        .map(|e| e.as_ptr())
        .collect();
    if debug_utils {
        ext_names.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    if opts.validate {
        ext_names.push(ash::ext::validation_features::NAME.as_ptr());
    }
    let layer_names: Vec<*const c_char> = if opts.validate {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        vec![]
    };

    let app = vk::ApplicationInfo::default()
        .application_name(c"sphereshade")
        .engine_name(c"sphereshade")
        .api_version(vk::API_VERSION_1_3);
    let enables = [
        vk::ValidationFeatureEnableEXT::GPU_ASSISTED,
        vk::ValidationFeatureEnableEXT::GPU_ASSISTED_RESERVE_BINDING_SLOT,
        vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION,
    ];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layer_names)
        .enabled_extension_names(&ext_names);
    if opts.validate {
        info = info.push_next(&mut features);
    }
    // SAFETY: `info` and everything it points to outlive the call.
    let instance = match unsafe { entry.create_instance(&info, None) } {
        // (the loader found no driver manifest it could use)
        Err(vk::Result::ERROR_INCOMPATIBLE_DRIVER) => return Err(Error::NoDevice),
        r => r.vk("vkCreateInstance")?,
    };
    Ok((instance, debug_utils))
}

fn load_entry() -> Result<ash::Entry> {
    // SAFETY: loading the system Vulkan loader library.
    // (the loader's own text may span lines: its first line is enough)
    unsafe { ash::Entry::load() }.map_err(|e| {
        Error::Loader(
            e.to_string()
                .lines()
                .next()
                .unwrap_or("not found")
                .to_string(),
        )
    })
}

/// Lists every physical device with its kind and missing required features.
pub fn enumerate_devices() -> Result<(Vec<DeviceInfo>, Vec<String>)> {
    let entry = load_entry()?;
    let (instance, _) = create_instance(&entry, &ContextOptions::default())?;
    let pds = unsafe { instance.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices");
    let mut out = Vec::new();
    let mut limits = Vec::new();
    if let Ok(pds) = &pds {
        for (i, &pd) in pds.iter().enumerate() {
            out.push(describe(&instance, pd, i));
            let p = unsafe { instance.get_physical_device_properties(pd) };
            let l = &p.limits;
            limits.push(format!(
                "maxComputeWorkGroupCount {:?}, maxComputeWorkGroupInvocations {}, maxComputeSharedMemorySize {}, \
                 maxStorageBufferRange {}, maxBoundDescriptorSets {}, timestampPeriod {} ns, maxPushConstantsSize {}",
                l.max_compute_work_group_count,
                l.max_compute_work_group_invocations,
                l.max_compute_shared_memory_size,
                l.max_storage_buffer_range,
                l.max_bound_descriptor_sets,
                l.timestamp_period,
                l.max_push_constants_size
            ));
        }
    }
    // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
    unsafe { instance.destroy_instance(None) };
    pds?;
    Ok((out, limits))
}

fn describe(instance: &ash::Instance, pd: vk::PhysicalDevice, index: usize) -> DeviceInfo {
    let p = unsafe { instance.get_physical_device_properties(pd) };
    DeviceInfo {
        index,
        name: p
            .device_name_as_c_str()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        kind: device_kind(p.device_type).0.to_string(),
        api_version: version_string(p.api_version),
        driver: driver_string(instance, pd),
        missing_features: missing_features(instance, pd),
    }
}

/// Held while a context is made or destroyed: instances and devices made
/// and destroyed on several threads at once (tests in parallel, each with
/// its own validated context) go through the loader's and the validation
/// layer's process-wide state. (A fresh-clone CI run once crashed with
/// SIGSEGV as a test binary's first contexts were made; not reproduced in
/// seven runs since: serialized here, a cost of nothing.)
static LIFECYCLE: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn lifecycle() -> std::sync::MutexGuard<'static, ()> {
    // (nothing it guards is left half-made by a panic elsewhere)
    LIFECYCLE.lock().unwrap_or_else(|e| e.into_inner())
}

impl Context {
    pub fn new(opts: &ContextOptions) -> Result<Self> {
        let _made = lifecycle();
        let entry = load_entry()?;
        let (instance, debug_utils) = create_instance(&entry, opts)?;
        // From here on, failures must destroy the instance.
        // `entry` must outlive the instance: dropping it unloads libvulkan.
        match Self::with_instance(entry.clone(), instance.clone(), debug_utils, opts) {
            Ok(ctx) => Ok(ctx),
            Err(e) => {
                // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
                unsafe { instance.destroy_instance(None) };
                Err(e)
            }
        }
    }

    fn with_instance(
        entry: ash::Entry,
        instance: ash::Instance,
        debug_utils: bool,
        opts: &ContextOptions,
    ) -> Result<Self> {
        let messages = Box::<MessageLog>::default();
        let (debug_instance, messenger) = if debug_utils {
            let di = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                        | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                        | vk::DebugUtilsMessageSeverityFlagsEXT::INFO,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(debug::messenger_callback))
                .user_data(&*messages as *const MessageLog as *mut std::ffi::c_void);
            let m = unsafe { di.create_debug_utils_messenger(&info, None) }
                .vk("vkCreateDebugUtilsMessengerEXT")?;
            (Some(di), m)
        } else {
            (None, vk::DebugUtilsMessengerEXT::null())
        };
        let destroy_messenger = |di: &Option<ash::ext::debug_utils::Instance>| {
            if let Some(di) = di {
                // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
                unsafe { di.destroy_debug_utils_messenger(messenger, None) };
            }
        };

        let result = Self::create_device(&instance, opts);
        let (physical, info, device, queue_family) = match result {
            Ok(v) => v,
            Err(e) => {
                destroy_messenger(&debug_instance);
                return Err(e);
            }
        };
        let props = unsafe { instance.get_physical_device_properties(physical) };
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let debug_device =
            debug_utils.then(|| ash::ext::debug_utils::Device::new(&instance, &device));

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|source| Error::Alloc {
            name: "allocator".into(),
            source,
        })?;

        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let command_pool =
            unsafe { device.create_command_pool(&pool_info, None) }.vk("vkCreateCommandPool")?;

        let (pipeline_cache, cache_file) = cache::load(&device, &props);
        let ctx = Context {
            entry,
            instance,
            debug_instance,
            messenger,
            debug_device,
            physical,
            props,
            info,
            device,
            pipeline_cache,
            cache_file,
            pipelines: Mutex::new(pipeline::Pool::default()),
            compiled: Default::default(),
            queue,
            queue_family,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            command_pool,
            messages,
            validation: opts.validate,
            device_destroyed: false,
        };
        ctx.name(ctx.queue, "main queue");
        ctx.name(ctx.command_pool, "main command pool");
        ctx.name(ctx.device.handle(), "sphereshade device");
        Ok(ctx)
    }

    fn create_device(
        instance: &ash::Instance,
        opts: &ContextOptions,
    ) -> Result<(vk::PhysicalDevice, DeviceInfo, ash::Device, u32)> {
        let pds =
            unsafe { instance.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
        if pds.is_empty() {
            return Err(Error::NoDevice);
        }
        let index = match opts.device_index {
            Some(i) if i >= pds.len() => {
                return Err(Error::BadDeviceIndex {
                    index: i,
                    count: pds.len(),
                });
            }
            Some(i) => i,
            None => {
                // Best kind first; among equals, a device with everything we need.
                let mut order: Vec<usize> = (0..pds.len()).collect();
                order.sort_by_key(|&i| {
                    let p = unsafe { instance.get_physical_device_properties(pds[i]) };
                    (
                        !missing_features(instance, pds[i]).is_empty(),
                        device_kind(p.device_type).1,
                    )
                });
                order[0]
            }
        };
        let pd = pds[index];
        let info = describe(instance, pd, index);
        if !info.missing_features.is_empty() {
            return Err(Error::MissingFeature {
                device: info.name.clone(),
                feature: info.missing_features.join(", "),
            });
        }
        let queue_family =
            compute_queue_family(instance, pd).ok_or_else(|| Error::MissingFeature {
                device: info.name.clone(),
                feature: "compute queue with timestamps".into(),
            })?;

        let mut f12 =
            vk::PhysicalDeviceVulkan12Features::default().shader_buffer_int64_atomics(true);
        let mut sup12 = vk::PhysicalDeviceVulkan12Features::default();
        let sup_base = {
            let mut sup = vk::PhysicalDeviceFeatures2::default().push_next(&mut sup12);
            unsafe { instance.get_physical_device_features2(pd, &mut sup) };
            sup.features
        };
        // Optional features that later passes and the validation layer use when present.
        f12 = f12
            .shader_shared_int64_atomics(sup12.shader_shared_int64_atomics == vk::TRUE)
            .host_query_reset(sup12.host_query_reset == vk::TRUE)
            .shader_float16(sup12.shader_float16 == vk::TRUE);
        let base = vk::PhysicalDeviceFeatures::default()
            .shader_int64(true)
            .fragment_stores_and_atomics(sup_base.fragment_stores_and_atomics == vk::TRUE)
            .vertex_pipeline_stores_and_atomics(
                sup_base.vertex_pipeline_stores_and_atomics == vk::TRUE,
            );
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
            .synchronization2(true)
            .dynamic_rendering(true);
        let mut f2 = vk::PhysicalDeviceFeatures2::default()
            .features(base)
            .push_next(&mut f12)
            .push_next(&mut f13);

        let mut exts: Vec<*const c_char> = vec![];
        if opts.swapchain {
            exts.push(ash::khr::swapchain::NAME.as_ptr());
        }
        let prio = [1.0f32];
        let qinfo = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&prio)];
        let dinfo = vk::DeviceCreateInfo::default()
            .queue_create_infos(&qinfo)
            .enabled_extension_names(&exts)
            .push_next(&mut f2);
        let device = unsafe { instance.create_device(pd, &dinfo, None) }.vk("vkCreateDevice")?;
        Ok((pd, info, device, queue_family))
    }

    /// Attaches a debug name to any Vulkan handle (no-op without debug utils).
    pub fn name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(dd) = &self.debug_device {
            let Ok(cname) = CString::new(name) else {
                return;
            };
            let info = vk::DebugUtilsObjectNameInfoEXT::default()
                .object_handle(handle)
                .object_name(&cname);
            // Naming is best effort: a failure only loses a label.
            let _ = unsafe { dd.set_debug_utils_object_name(&info) };
        }
    }

    pub fn begin_label(&self, cmd: vk::CommandBuffer, name: &str) {
        if let Some(dd) = &self.debug_device {
            let Ok(cname) = CString::new(name) else {
                return;
            };
            let label = vk::DebugUtilsLabelEXT::default().label_name(&cname);
            // SAFETY: the command buffer is in the recording state; the handles are live.
            unsafe { dd.cmd_begin_debug_utils_label(cmd, &label) };
        }
    }

    pub fn end_label(&self, cmd: vk::CommandBuffer) {
        if let Some(dd) = &self.debug_device {
            // SAFETY: the command buffer is in the recording state; the handles are live.
            unsafe { dd.cmd_end_debug_utils_label(cmd) };
        }
    }

    /// Validation warnings and errors counted so far.
    pub fn validation_messages(&self) -> u32 {
        self.messages.count()
    }

    /// Allocates a primary command buffer from the context's pool.
    pub fn command_buffer(&self, name: &str) -> Result<vk::CommandBuffer> {
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        let cmd = unsafe { self.device.allocate_command_buffers(&info) }
            .vk("vkAllocateCommandBuffers")?[0];
        self.name(cmd, name);
        Ok(cmd)
    }

    /// Records with `f` into a fresh command buffer, submits and waits.
    pub fn one_shot<T>(
        &self,
        name: &str,
        f: impl FnOnce(vk::CommandBuffer) -> Result<T>,
    ) -> Result<T> {
        let cmd = self.command_buffer(name)?;
        let fence = unsafe {
            self.device
                .create_fence(&vk::FenceCreateInfo::default(), None)
        }
        .vk("vkCreateFence")?;
        self.name(fence, name);
        let result = (|| {
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            // SAFETY: the command buffer belongs to this device and is not pending.
            unsafe { self.device.begin_command_buffer(cmd, &begin) }.vk("vkBeginCommandBuffer")?;
            let value = f(cmd)?;
            // SAFETY: the command buffer belongs to this device and is not pending.
            unsafe { self.device.end_command_buffer(cmd) }.vk("vkEndCommandBuffer")?;
            let cmds = [cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            // SAFETY: the command buffers are recorded, the semaphores and fence are unsignalled and not in use.
            unsafe { self.device.queue_submit(self.queue, &submit, fence) }.vk("vkQueueSubmit")?;
            // SAFETY: the fences are live objects of this device.
            unsafe { self.device.wait_for_fences(&[fence], true, u64::MAX) }
                .vk("vkWaitForFences")?;
            Ok(value)
        })();
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe {
            self.device.destroy_fence(fence, None);
            self.device.free_command_buffers(self.command_pool, &[cmd]);
        }
        result
    }

    /// Total bytes of device memory the allocator holds for us.
    pub fn allocated_bytes(&self) -> u64 {
        self.allocator
            .lock()
            .map(|a| a.generate_report().total_allocated_bytes)
            .unwrap_or(0)
    }

    pub fn wait_idle(&self) {
        // Nothing useful to do on failure here: the device is lost or gone.
        // SAFETY: the fences are live objects of this device.
        let _ = unsafe { self.device.device_wait_idle() };
    }
}

impl Context {
    /// Compute pipelines compiled on this context (each kept for its
    /// later renderers: [`Context::pipelines`]).
    pub fn pipelines_compiled(&self) -> u64 {
        self.compiled.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Destroys the device (idempotent). The validation layer reports leaked
    /// objects here, so counts read afterwards include them.
    fn destroy_device(&mut self) {
        if self.device_destroyed {
            return;
        }
        self.device_destroyed = true;
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_command_pool(self.command_pool, None);
            let pool = std::mem::take(self.pipelines.get_mut().unwrap_or_else(|e| e.into_inner()));
            for (_, (pipeline, layout, set_layout)) in pool {
                self.device.destroy_pipeline(pipeline, None);
                self.device.destroy_pipeline_layout(layout, None);
                self.device.destroy_descriptor_set_layout(set_layout, None);
            }
            cache::save(
                &self.device,
                self.pipeline_cache,
                self.cache_file.as_deref(),
            );
            self.device
                .destroy_pipeline_cache(self.pipeline_cache, None);
            // The allocator frees its memory blocks; it must go before the device.
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
        }
    }

    /// Tears the device down and returns every validation warning/error
    /// counted, including leak reports made at device destruction.
    pub fn finish(mut self) -> (u32, Vec<String>) {
        {
            let _made = lifecycle();
            self.destroy_device();
        }
        (self.messages.count(), self.messages.messages())
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        let _made = lifecycle();
        self.destroy_device();
        // SAFETY: the object is not used by any pending GPU work (waited for above / by the owner).
        unsafe {
            if let Some(di) = &self.debug_instance {
                di.destroy_debug_utils_messenger(self.messenger, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// Frames that may be in flight at once (the renderer's frame slots).
pub const FRAME_SLOTS: usize = 2;
