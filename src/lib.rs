//! sphereshade: a Vulkan compute renderer for millions of spheres.
//!
//! `vk` wraps the device, `scene` reads structures and builds procedural
//! scenes, `passes` holds one file per GPU pass, `render` is the frame graph,
//! `reference` the independent CPU references the tests compare against.

// `!(x > 0.0)` is used on purpose: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod app;
pub mod bench;
pub mod camera;
pub mod chart;
pub mod cli;
pub mod error;
pub mod gpu;
pub mod output;
pub mod passes;
pub mod reference;
pub mod render;
pub mod scene;
pub mod semantic;
pub mod settings;
pub mod vk;

pub use error::{Error, Result};
