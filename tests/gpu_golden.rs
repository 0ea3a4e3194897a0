//! Golden baseline images: `experiments/baseline.toml` rendered by the GPU kernel must
//! match the committed PNGs under `tests/golden/`.
//!
//! Tolerance, on the displayed 8-bit image: at most 0.2 % of pixels may differ by more
//! than 2/255 in any channel (drivers differ in the last bits of f32 arithmetic, which
//! flips a few rays that graze voxel edges), and the mean absolute difference stays
//! below 0.5/255.
//!
//! The goldens are rewritten only on purpose: `VOXLAB_UPDATE_GOLDEN=1 cargo test --release
//! --test gpu_golden`, never in CI (the test refuses when `CI` is set). A failing
//! comparison writes `NAME.actual.png` and `NAME.diff.png` next to the golden.

mod common;

use common::{display, experiment, golden_dir, golden_ok, quantised, tracer};

use voxlab::experiment::Experiment;
use voxlab::metrics::difference_image;
use voxlab::output::{read_png, write_frame};

const BAD_DIFF: f64 = 2.0 / 255.0;

/// (golden name, width, height, reflection depth, refraction depth): the baseline at
/// its own depth limits, non-square, and with secondary rays off.
const CASES: &[(&str, u32, u32, u32, u32)] = &[
    ("baseline_160", 160, 160, 4, 4),
    ("baseline_200x120", 200, 120, 4, 4),
    ("baseline_depth0_128", 128, 128, 0, 0),
];

pub fn baseline(width: u32, height: u32, refl: u32, refr: u32) -> Experiment {
    let mut e = experiment("baseline.toml");
    e.settings.width = width;
    e.settings.height = height;
    e.settings.max_reflection_depth = refl;
    e.settings.max_refraction_depth = refr;
    e
}

#[test]
fn baseline_matches_golden_images() {
    let update = std::env::var_os("VOXLAB_UPDATE_GOLDEN").is_some();
    assert!(
        !(update && std::env::var_os("CI").is_some()),
        "VOXLAB_UPDATE_GOLDEN is set in CI: golden images are rewritten only on purpose"
    );
    let mut gpu = tracer();
    let mut failures = Vec::new();
    for &(name, w, h, refl, refr) in CASES {
        let e = baseline(w, h, refl, refr);
        let frame = gpu.render(&e.scene, &e.settings).unwrap().frame;
        let path = golden_dir().join(format!("{name}.png"));
        if update {
            write_frame(&frame, &path).unwrap();
            eprintln!("rewrote {}", path.display());
            continue;
        }
        let golden = read_png(&path).unwrap_or_else(|err| {
            panic!("{err}: run with VOXLAB_UPDATE_GOLDEN=1 to create the golden images")
        });
        // Quantise as the PNG does before comparing, so only real differences count.
        let d = display(&quantised(&frame), &golden, BAD_DIFF);
        eprintln!("{name}: {d}");
        if !golden_ok(&d) {
            let actual = golden_dir().join(format!("{name}.actual.png"));
            let diff = golden_dir().join(format!("{name}.diff.png"));
            write_frame(&frame, &actual).unwrap();
            write_frame(&difference_image(&frame, &golden, 16.0), &diff).unwrap();
            failures.push(format!(
                "{name}: {d}; wrote {} and {}",
                actual.display(),
                diff.display()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "golden mismatch:\n{}",
        failures.join("\n")
    );
}

/// The CPU reference renders the same baseline within the GPU-vs-CPU tolerance, so the
/// goldens are pinned to the oracle too, not only to one driver's output.
#[test]
fn golden_images_agree_with_the_cpu_reference() {
    let (name, w, h, refl, refr) = CASES[0];
    let e = baseline(w, h, refl, refr);
    let cpu = voxlab::cpu::render(&e.scene, &e.settings).frame;
    let golden = read_png(golden_dir().join(format!("{name}.png"))).unwrap();
    let d = display(&cpu, &golden, BAD_DIFF);
    eprintln!("{name} vs CPU reference: {d}");
    assert!(
        d.fraction_over() < 0.005 && d.mean_abs < 1e-3 + 0.5 / 255.0,
        "{d}"
    );
}
