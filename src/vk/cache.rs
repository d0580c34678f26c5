//! The pipeline cache on disk: `$SPHERESHADE_CACHE_DIR`, else
//! `$XDG_CACHE_HOME/sphereshade`, else `~/.cache/sphereshade`, one file per
//! device and driver (vendor, device id, pipelineCacheUUID), so a second
//! start skips the shader compiles (lavapipe compiles each pipeline with
//! LLVM). Best effort: an unreadable or stale file only costs the compile;
//! `SPHERESHADE_CACHE_DIR=off` disables it. Saved atomically (temporary
//! name + rename) when the device is destroyed.

use ash::vk;
use std::path::{Path, PathBuf};

fn cache_dir() -> Option<PathBuf> {
    match std::env::var_os("SPHERESHADE_CACHE_DIR") {
        Some(d) if d == "off" => return None,
        Some(d) if !d.is_empty() => return Some(PathBuf::from(d)),
        _ => {}
    }
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|x| !x.is_empty()) {
        return Some(PathBuf::from(x).join("sphereshade"));
    }
    std::env::var_os("HOME")
        .filter(|h| !h.is_empty())
        .map(|h| PathBuf::from(h).join(".cache").join("sphereshade"))
}

/// The cache file for this device, if caching is on.
pub fn file_for(props: &vk::PhysicalDeviceProperties) -> Option<PathBuf> {
    let uuid: String = props
        .pipeline_cache_uuid
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    cache_dir().map(|d| {
        d.join(format!(
            "pipelines-{:04x}-{:04x}-{uuid}.bin",
            props.vendor_id, props.device_id
        ))
    })
}

/// Creates the pipeline cache, seeded from the file when it has one (the
/// driver checks the header and ignores data that is not its own).
pub fn load(
    device: &ash::Device,
    props: &vk::PhysicalDeviceProperties,
) -> (vk::PipelineCache, Option<PathBuf>) {
    let file = file_for(props);
    let data = file
        .as_deref()
        .and_then(|f| std::fs::read(f).ok())
        .unwrap_or_default();
    let with_data = vk::PipelineCacheCreateInfo::default().initial_data(&data);
    // SAFETY: plain create calls; data is any byte string (validated by the driver).
    let cache = unsafe { device.create_pipeline_cache(&with_data, None) }
        .or_else(|_| unsafe {
            device.create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None)
        })
        .unwrap_or(vk::PipelineCache::null());
    if !data.is_empty() {
        log::info!("pipeline cache: {} bytes from {:?}", data.len(), file);
    }
    (cache, file)
}

/// Writes the cache's data to `file` (temporary name, then rename).
pub fn save(device: &ash::Device, cache: vk::PipelineCache, file: Option<&Path>) {
    let Some(file) = file else { return };
    if cache == vk::PipelineCache::null() {
        return;
    }
    // SAFETY: the cache is live until the caller destroys it after this.
    let Ok(data) = (unsafe { device.get_pipeline_cache_data(cache) }) else {
        return;
    };
    if data.is_empty() {
        return;
    }
    if std::fs::read(file).is_ok_and(|old| old == data) {
        return;
    }
    let Some(dir) = file.parent() else { return };
    if std::fs::create_dir_all(dir).is_err() {
        return;
    }
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        file.file_name()
            .map(|n| n.to_string_lossy())
            .unwrap_or_default(),
        std::process::id()
    ));
    if std::fs::write(&tmp, &data).is_err() || std::fs::rename(&tmp, file).is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
}
