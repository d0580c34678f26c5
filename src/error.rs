//! Library errors: typed, each with the one-line message the binary prints
//! (the binary adds nothing but the `sphereshade: error:` prefix, through
//! anyhow at its edge).

use ash::vk;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("cannot load the Vulkan loader (libvulkan.so.1): {0}; run tools/setup.sh")]
    Loader(String),
    #[error("no Vulkan device found (install mesa-vulkan-drivers for lavapipe: tools/setup.sh)")]
    NoDevice,
    #[error("--device {index}: only {count} Vulkan device(s) present (see `sphereshade info`)")]
    BadDeviceIndex { index: usize, count: usize },
    /// Every feature the device lacks, comma-separated.
    #[error("device '{device}' lacks required Vulkan feature(s): {feature}")]
    MissingFeature { device: String, feature: String },
    #[error(
        "--validate needs VK_LAYER_KHRONOS_validation (apt-get install vulkan-validationlayers)"
    )]
    NoValidationLayer,
    #[error("Vulkan call {call} failed: {result}")]
    Vk {
        call: &'static str,
        result: vk::Result,
    },
    #[error("GPU memory allocation for '{name}' failed: {source}")]
    Alloc {
        name: String,
        source: gpu_allocator::AllocationError,
    },
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    #[error(transparent)]
    Traj(#[from] crate::traj::TrajError),
    /// Bad input: a file, an option, a combination of them.
    #[error("{0}")]
    Input(String),
    /// The device cannot do it (a buffer over maxStorageBufferRange, ...).
    #[error("{0}")]
    DeviceLimit(String),
    /// A bug or a broken invariant inside sphereshade.
    #[error("internal error: {0}")]
    Internal(String),
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Adds the name of the failing Vulkan call to a `vk::Result`.
pub trait VkContext<T> {
    fn vk(self, call: &'static str) -> Result<T>;
}

impl<T> VkContext<T> for std::result::Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T> {
        self.map_err(|result| Error::Vk { call, result })
    }
}
