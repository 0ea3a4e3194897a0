//! Helpers shared by the GPU test files (`mod common;`): the tracer they all need, and
//! image comparisons through the library's own metric (`voxlab::metrics::compare`).

// Every test file is a crate of its own and uses only some of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use voxlab::Frame;
use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;
use voxlab::metrics::{Domain, ImageDiff, compare};

/// A GPU tracer on whatever adapter wgpu finds; a missing adapter fails the test (never
/// a skip).
pub fn tracer() -> GpuTracer {
    GpuTracer::new().unwrap_or_else(|e| {
        panic!("no GPU adapter: {e:#}. GPU tests need one (lavapipe: mesa-vulkan-drivers)")
    })
}

/// `compare` of two frames that must have the same size.
#[track_caller]
pub fn diff(a: &Frame, b: &Frame, domain: Domain, threshold: f64) -> ImageDiff {
    compare(a, b, domain, threshold).unwrap_or_else(|| {
        panic!(
            "images of different sizes: {}x{} and {}x{}",
            a.width, a.height, b.width, b.height
        )
    })
}

/// Linear radiance as traced, pixels over `threshold` counted.
#[track_caller]
pub fn linear(a: &Frame, b: &Frame, threshold: f64) -> ImageDiff {
    diff(a, b, Domain::Linear, threshold)
}

/// Displayed values (clamped to [0, 1]), pixels over `threshold` counted.
#[track_caller]
pub fn display(a: &Frame, b: &Frame, threshold: f64) -> ImageDiff {
    diff(a, b, Domain::Display, threshold)
}

/// RMSE of the linear radiance.
#[track_caller]
pub fn rmse(a: &Frame, b: &Frame) -> f64 {
    linear(a, b, 0.0).rmse
}

/// The displayed image as the 8-bit PNG stores it.
pub fn quantised(frame: &Frame) -> Frame {
    let mut shown = frame.clone();
    for p in &mut shown.pixels {
        *p = p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() / 255.0);
    }
    shown
}

/// GPU against CPU reference (f32 against f64), on the displayed image: f32 flips a
/// few rays that graze voxel edges or corners, so fewer than `max_fraction` of the
/// pixels may differ by more than 2/255 in a channel, and the mean absolute difference
/// bounds everything else below 1e-3. Both images must be finite.
#[track_caller]
pub fn assert_agree_within(name: &str, g: &Frame, c: &Frame, max_fraction: f64) -> ImageDiff {
    assert!(g.all_finite(), "{name}: GPU image has NaN or inf");
    assert!(c.all_finite(), "{name}: CPU image has NaN or inf");
    let d = display(g, c, 2.0 / 255.0);
    eprintln!("{name}: GPU vs CPU {d}");
    assert!(
        d.fraction_over() < max_fraction && d.mean_abs < 1e-3,
        "{name}: GPU and CPU differ (at most {} % of pixels over 2/255, mean below 1e-3): {d}",
        100.0 * max_fraction
    );
    d
}

/// [`assert_agree_within`] with 0.5 % of the pixels, the tolerance of
/// tests/gpu_agreement.rs.
#[track_caller]
pub fn assert_agree(name: &str, g: &Frame, c: &Frame) -> ImageDiff {
    assert_agree_within(name, g, c, 0.005)
}

pub fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

/// The tolerance of tests/gpu_golden.rs: quantised as the PNG is, at most 0.2 % of the
/// pixels off by more than 2/255 and a mean absolute difference of at most 0.5/255.
pub fn golden_ok(d: &ImageDiff) -> bool {
    d.fraction_over() <= 0.002 && d.mean_abs <= 0.5 / 255.0
}

/// `frame` against the golden PNG `file` of tests/golden with [`golden_ok`].
#[track_caller]
pub fn assert_matches_golden(name: &str, frame: &Frame, file: &str) {
    let path = golden_dir().join(file);
    let golden = voxlab::output::read_png(&path).unwrap_or_else(|e| panic!("{e}"));
    let d = display(&quantised(frame), &golden, 2.0 / 255.0);
    eprintln!("{name}: {d}");
    assert!(
        golden_ok(&d),
        "{name}: differs from the golden {}: {d}",
        path.display()
    );
}

/// An experiment of experiments/ by file name.
pub fn experiment(file: impl AsRef<Path>) -> Experiment {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("experiments")
        .join(file);
    Experiment::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

/// A real test file from `../shared/data/` (beside the repository, in CI too); a
/// missing file fails the test with where it was looked for.
pub fn shared_data(name: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(name);
    assert!(
        p.exists(),
        "test data {} is missing: the repository's parent must hold shared/data/ \
         (see shared/data/README.md)",
        p.display()
    );
    p
}
