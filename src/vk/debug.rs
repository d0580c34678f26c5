//! Validation-layer messages: counted (warnings and errors), logged, and kept
//! for test failure reports.

use ash::vk;
use std::ffi::CStr;
use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering};

/// Messages the debug messenger saw. Lives in a Box whose address is the
/// messenger's user data, so it must outlive the messenger.
#[derive(Default)]
pub struct MessageLog {
    count: AtomicU32,
    messages: Mutex<Vec<String>>,
}

impl MessageLog {
    /// Warnings and errors reported so far.
    pub fn count(&self) -> u32 {
        self.count.load(Ordering::SeqCst)
    }

    /// Texts of the counted messages (at most the first 64).
    pub fn messages(&self) -> Vec<String> {
        self.messages.lock().map(|m| m.clone()).unwrap_or_default()
    }

    fn record(&self, text: String) {
        self.count.fetch_add(1, Ordering::SeqCst);
        if let Ok(mut m) = self.messages.lock()
            && m.len() < 64
        {
            m.push(text);
        }
    }
}

/// # Safety
/// Called by the Vulkan loader only, with `user` = the context's `MessageLog`.
pub unsafe extern "system" fn messenger_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut std::ffi::c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes valid callback data for the call's duration;
    // `user` is the MessageLog box owned by the Context.
    let (text, log) = unsafe {
        let d = &*data;
        let text = if d.p_message.is_null() {
            String::from("(no message)")
        } else {
            CStr::from_ptr(d.p_message).to_string_lossy().into_owned()
        };
        (text, &*(user as *const MessageLog))
    };
    if severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
            | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
    ) {
        log::warn!("validation: {text}");
        log.record(text);
    } else {
        log::debug!("validation: {text}");
    }
    vk::FALSE
}
