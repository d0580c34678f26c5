//! sphereshade: a Vulkan compute renderer for millions of spheres.
//!
//! Arrows point one way: `cli` → `app` | `bench` → `run` → `render` (the
//! frame graph) → `stages` (each feature's passes, state and knobs) →
//! `passes` (what the stages share) → `vk`; `scene`, `camera`, `settings`, `gpu` are
//! leaves (`traj` reads trajectory frames on top of `scene`). `reference` holds the independent CPU references the tests
//! compare against.

// `!(x > 0.0)` is used on purpose: unlike `x <= 0.0` it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod app;
pub mod bench;
pub mod camera;
pub mod cli;
pub mod error;
pub mod gpu;
pub mod movie;
pub mod output;
pub mod passes;
pub mod reference;
pub mod render;
pub mod run;
pub mod scene;
pub mod semantic;
pub mod settings;
pub mod stages;
pub mod tachyon;
pub mod traj;
pub mod vk;

pub use error::{Error, Result};
