//! The stages of a frame. A stage owns its passes, its state (pipelines,
//! private buffers) and its knobs, computes its parameters once per frame,
//! and is recorded with named inputs and outputs; the frame graph (render::graph)
//! wires one stage's outputs to the next one's inputs.
//!
//! - [`raster`]: the camera's visibility buffer (compute or graphics
//!   rasterizer) and the tile lists of the covered regions;
//! - [`shadows`]: the key light's structure, one technique at a time;
//! - [`ssdo`]: semantic SSDO with one bounce, and its bilateral blur;
//! - [`see_through`]: the camera's fragment lists of see-through spheres;
//! - [`shading`]: three-point lighting into the colour buffer and the AOVs,
//!   compositing the see-through fragments.

pub mod raster;
pub mod see_through;
pub mod shading;
pub mod shadows;
pub mod ssdo;
