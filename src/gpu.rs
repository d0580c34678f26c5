//! Every struct that crosses to the GPU, mirrored in `glsl/shared.glsl`.
//! Sizes are asserted here at compile time; tests/gpu_layout.rs checks the
//! field offsets on the device through `glsl/test/layout_probe.comp`.

use bytemuck::{Pod, Zeroable};

/// A view (camera or key light). See `View` in glsl/shared.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuView {
    /// xyz view centre; w pixels per world unit on the view plane (H / h).
    pub center: [f32; 4],
    /// xyz right axis; w image width in pixels.
    pub right: [f32; 4],
    /// xyz up axis; w image height in pixels.
    pub up: [f32; 4],
    /// xyz view direction; w eye distance (0 = orthographic).
    pub dir: [f32; 4],
    /// x depth offset added to orthographic depths so keys stay positive.
    pub depth: [f32; 4],
    /// x width, y height.
    pub dims: [u32; 4],
}

/// Per-frame constants, bound as a uniform buffer at binding 0 of every pass.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Globals {
    pub cam: GpuView,
    pub light: GpuView,
    /// xyz normalised key-light direction (from the light toward the scene).
    pub light_dir: [f32; 4],
    pub background: [f32; 4],
    /// x sphere count, y half-resolution width, z half-resolution height,
    /// w 1 when the scene has no region hierarchy (each sphere is its own
    /// region for semantic SSDO).
    pub counts: [u32; 4],
    /// The active rectangle [x0, y0, x1, y1) of the buffer (tiles: the kept
    /// tile and the blur's reach; else the whole buffer), glsl ACTIVE_RECT.
    pub params: [f32; 4],
    /// Parameters of the active shadow technique's lookup (glsl/lookup_*.glsl
    /// say which field is what).
    pub shadow_f0: [f32; 4],
    pub shadow_f1: [f32; 4],
    pub shadow_u: [u32; 4],
    /// Instanced scenes' region levels (glsl/scene.glsl `scene_region`):
    /// x the number of tree levels (they come first), y the chain stride
    /// (chain region = instance * y + chain), z the molecule level's index,
    /// w the chain level's (NO_LEVEL: none).
    pub scene: [u32; 4],
    /// x: `--opacity`, multiplying every sphere's alpha (its colour's A
    /// byte / 255; glsl/scene.glsl `scene_alpha`).
    pub alpha: [f32; 4],
}

/// Per-sphere attributes used after visibility: the regions (SSDO, the
/// region AOV). Colours are a separate RGBA8 word per sphere: a pixel's
/// colour and a block's regions were each a random fetch, and a 16-byte
/// texel keeps the regions' fetch to half the bytes of a shared 32-byte one.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct SphereAttr {
    /// Region ids per hierarchy level, outermost first.
    pub region: [u32; 4],
}

/// Geometry as the rasterizer reads it: centre xyz, radius w.
pub type GpuSphere = [f32; 4];

/// A batch of an instanced scene (glsl/scene.glsl): x the instance, y its
/// first atom (index into the molecule atoms), z the expanded index of
/// that atom, w the atom count (1..=2^shift) | molecule type << 8.
pub type GpuBatch = [u32; 4];

/// Visibility-buffer value of a pixel no sphere covers.
pub const VIS_EMPTY: u64 = u64::MAX;

const _: () = assert!(std::mem::size_of::<GpuView>() == 96);
const _: () = assert!(std::mem::size_of::<Globals>() == 2 * 96 + 9 * 16);
const _: () = assert!(std::mem::size_of::<SphereAttr>() == 16);
const _: () = assert!(std::mem::size_of::<GpuSphere>() == 16);

/// Turns the shared constant list into `pub const`s (build.rs turns the same
/// list into glsl `constants.glsl`).
macro_rules! gpu_constants {
    ($($(#[doc = $doc:expr])* $name:ident : $ty:ty = $val:expr;)*) => {
        $( $(#[doc = $doc])* pub const $name: $ty = $val; )*
        /// Every shared constant as (name, value as f64), for tests.
        pub const ALL_CONSTANTS: &[(&str, f64)] = &[$((stringify!($name), { let v: $ty = $val; v as f64 })),*];
    };
}
pub mod consts {
    include!("gpu_consts.rs");
}

/// A knob between 0 and 1 (clap value parser of `gpu_knobs!` fields).
pub fn unit_interval(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}': expected a number between 0 and 1")),
    }
}

/// `Default` from the clap attributes, so that a knob's default is written
/// once, beside its flag, doc comment and range.
macro_rules! default_from_args {
    ($t:ty) => {
        impl Default for $t {
            fn default() -> Self {
                #[derive(clap::Parser)]
                struct Only {
                    #[command(flatten)]
                    v: $t,
                }
                match <Only as clap::Parser>::try_parse_from(["sphereshade"]) {
                    Ok(o) => o.v,
                    // (the attributes' own defaults: a test parses them)
                    Err(e) => panic!("{}: bad default: {e}", stringify!($t)),
                }
            }
        }
    };
}
pub(crate) use default_from_args;

/// Turns the shared knob structs into `#[repr(C)]` Pod structs that are also
/// clap arguments (defaults from their attributes); build.rs turns the same
/// list into `knobs/NAME.glsl` (a GLSL struct).
macro_rules! gpu_knobs {
    ($($(#[doc = $sdoc:expr])* $name:ident $file:literal {
        $($(#[doc = $doc:expr])* $(#[arg($($arg:tt)*)])* $field:ident : $ty:ty,)*
    })*) => {
        $(
            $(#[doc = $sdoc])*
            #[doc = concat!("\n\nGLSL: `#include \"knobs/", $file, ".glsl\"`.")]
            #[repr(C)]
            #[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable, clap::Args)]
            pub struct $name {
                $( $(#[doc = $doc])* $(#[arg($($arg)*)])* pub $field: $ty, )*
            }

            default_from_args!($name);
        )*
    };
}

/// Turns the shared push blocks into `#[repr(C)]` Pod structs (build.rs
/// turns the same list into `push/NAME.glsl`).
macro_rules! gpu_push {
    ($($(#[doc = $sdoc:expr])* $name:ident $file:literal {
        $($(#[doc = $doc:expr])* $field:ident : $ty:ty,)*
    })*) => {
        $(
            $(#[doc = $sdoc])*
            #[doc = concat!("\n\nGLSL: `#include \"push/", $file, ".glsl\"`.")]
            #[repr(C)]
            #[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
            pub struct $name {
                $( $(#[doc = $doc])* pub $field: $ty, )*
            }
        )*
    };
}

/// Turns the shared specialization blocks into structs whose
/// `constants()` are the values of constant ids 1, 2, ... (build.rs turns
/// the same list into `spec/NAME.glsl`).
macro_rules! gpu_spec {
    ($($(#[doc = $sdoc:expr])* $name:ident $file:literal {
        $($(#[doc = $doc:expr])* $field:ident : $ty:ty = $glsl:ident,)*
    })*) => {
        $(
            $(#[doc = $sdoc])*
            #[doc = concat!("\n\nGLSL: `#include \"spec/", $file, ".glsl\"`.")]
            #[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
            pub struct $name {
                $( $(#[doc = $doc])* #[doc = concat!("\n\nGLSL `", stringify!($glsl), "`.")] pub $field: $ty, )*
            }

            impl $name {
                /// The specialization constants, ids 1, 2, ... in field order.
                pub fn constants(&self) -> Vec<u32> {
                    vec![$(self.$field as u32),*]
                }
            }
        )*
    };
}

/// Push-constant blocks and specialization constants shared with GLSL.
pub mod blocks {
    use super::GpuView;
    include!("gpu_blocks.rs");

    // (the blocks that carry a view: within the 128 bytes every device
    // allows)
    const _: () = assert!(std::mem::size_of::<LodCullPush>() <= 128);
    const _: () = assert!(std::mem::size_of::<RasterPush>() <= 128);
}
