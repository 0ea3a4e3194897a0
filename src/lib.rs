//! voxlab: a research sandbox for ray tracing in voxel space.
//!
//! The rendering model is fixed by DESIGN section 1 and implemented twice: by the wgpu
//! compute kernel (`gpu`, WGSL under `shaders/`) and by the f64 reference (`cpu`), the
//! oracle of the tests.

pub mod ablate;
pub mod bench;
pub mod cpu;
pub mod experiment;
pub mod gpu;
pub mod info;
pub mod input;
pub mod metrics;
pub mod output;
pub mod plan;
pub mod progress;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod settings;
pub mod sparse;
pub mod stress;
pub mod surface;
pub mod technique;
pub mod triangles;
#[cfg(feature = "viewer")]
pub mod viewer;

pub use render::{Features, Frame, RayStats, RenderOutput, RenderSettings, Transmittance};
pub use scene::Scene;
