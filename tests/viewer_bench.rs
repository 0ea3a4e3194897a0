//! `voxlab bench --adaptive`: runs on the viewer's tracer and prints a row per
//! experiment with a scale the controller can choose and the size it traced.
#![cfg(feature = "viewer")]

use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;
use voxlab::viewer::bench::{adaptive_table, bench_adaptive};
use voxlab::viewer::state::{SCALES, scaled_size};

#[test]
fn adaptive_bench_reports_a_controller_scale_and_its_traced_size() {
    let mut e = Experiment::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/area_lights.toml"
    ))
    .unwrap();
    e.settings.width = 96;
    e.settings.height = 64;
    let mut gpu = GpuTracer::new().expect("a GPU adapter (lavapipe in CI)");
    let rows = bench_adaptive(&mut gpu, &[e], 1).unwrap();
    assert_eq!(rows.len(), 1);
    let r = &rows[0];
    assert_eq!(r.full, (96, 64));
    assert!(SCALES.contains(&r.scale), "scale {}", r.scale);
    assert_eq!(r.scaled, scaled_size(96, 64, r.scale));
    assert!(r.full_ms > 0.0 && r.scaled_ms > 0.0);
    let table = adaptive_table(&rows);
    assert!(table.contains("| area_lights | 96x64 |"), "{table}");
    assert_eq!(table.lines().count(), 3, "{table}");
}
