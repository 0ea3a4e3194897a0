//! voxlab: a research sandbox for ray tracing in voxel space.
//!
//! The rendering model (`src/trace_contract.md`) is implemented twice: by the wgpu
//! compute kernel (`gpu`, WGSL under `shaders/`) and by the f64 reference (`cpu`), the
//! oracle of the tests.
//!
//! # The facade
//!
//! A program built on voxlab needs five names: an [`Experiment`] (a scene, its render
//! settings and the techniques chosen, from a TOML file or built in code), a [`Grid`]
//! of voxels inside its [`Scene`], a [`Session`] (one tracer kept open across renders),
//! the [`Image`] a render gives, and one [`Error`] type.
//!
//! ```
//! use voxlab::{Backend, Experiment, Session};
//!
//! // The experiment files' parser, with `--set`'s overrides.
//! let path = concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/area_lights.toml");
//! let overrides = ["render.width=24".parse()?, "render.height=16".parse()?];
//! let e = Experiment::load_with(path, &overrides)?;
//!
//! // Two shadow models on one session: the CPU reference here, `Backend::Gpu` for the
//! // kernel.
//! let mut session = Session::new(Backend::Cpu)?;
//! let sampled = session.render(&e)?;
//! let mut hard = e.clone();
//! assert!(hard.settings.features.set_shadow_model("hard"));
//! let hard = session.render(&hard)?;
//! let diff = voxlab::metrics::compare(&sampled.frame, &hard.frame, voxlab::metrics::Domain::Linear, 0.0);
//! assert!(diff.unwrap().rmse > 0.0, "soft and hard shadows differ");
//! # Ok::<(), voxlab::Error>(())
//! ```
//!
//! A scene from voxels of one's own:
//!
//! ```
//! use glam::{DVec3, IVec3, UVec3};
//! use voxlab::{Experiment, Grid};
//!
//! let mut grid = Grid::new(UVec3::new(8, 4, 8), 1.0, DVec3::ZERO)?;
//! for x in 0..8 {
//!     for z in 0..8 {
//!         grid.set(IVec3::new(x, 0, z), voxlab::scene::seed_ids::SOLID);
//!     }
//! }
//! let mut e = Experiment::seed_default();
//! e.scene.grid = grid;
//! e.scene.validate()?;
//! # Ok::<(), voxlab::Error>(())
//! ```
//!
//! Every error converts into [`Error`], which keeps the file, line and key of a bad
//! setting ([`Error::key`]) next to the message the command line prints.
//!
//! The modules below the facade are public for the tests, the benchmarks and for
//! research code that needs them (a technique of one's own, see
//! `docs/adding-a-technique.md`); they change more often than the facade. What nothing
//! outside the crate uses (the tests, the command line, the Python bindings, the
//! examples in these docs) is `pub(crate)`.

pub mod ablate;
mod accumulation;
pub mod bench;
pub mod cpu;
pub mod dda;
pub mod device;
pub mod error;
pub mod experiment;
pub mod export;
pub mod frame;
pub mod geometry;
pub mod gpu;
pub mod info;
pub mod input;
pub mod metrics;
pub mod output;
pub mod plan;
pub mod progress;
pub mod ray_cutoff;
pub mod render;
pub mod revision;
pub mod sampling;
pub mod scene;
pub mod session;
pub mod settings;
pub mod sparse;
pub mod stress;
pub mod surface;
pub mod technique;
pub mod triangles;
#[cfg(feature = "viewer")]
pub mod viewer;

pub use error::{Error, ErrorKind, Result};
pub use experiment::Experiment;
pub use frame::{Frame, RayStats, RenderOutput};
pub use render::{Features, RenderSettings, Transmittance};
pub use scene::{Grid, Scene};
pub use session::{Backend, Image, Session};
