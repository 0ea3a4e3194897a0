//! Reconstruction `none`, the default: the image as traced, each pixel the mean of its
//! frames. The tracers make no primary layers for it, so it is today's image bit for
//! bit (tests/reconstruction.rs).

use super::Reconstruction;

pub const RECONSTRUCTION: Reconstruction = Reconstruction {
    name: "none",
    summary: "the image as traced: each pixel the mean of its frames, nothing filtered",
    title: "none",
    settings: &[],
    cpu: None,
    wgsl: None,
    gpu_passes: |_| 0,
    reach: |_| 0,
    label: "",
    temporal: false,
    wgsl_imports: &[],
};
