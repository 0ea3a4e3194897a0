//! Every experiment file under experiments/ loads and renders: a tiny image on both
//! backends, every pixel finite, the two within the GPU-vs-CPU tolerance. Keeps the
//! example files from rotting as the format grows.

use std::path::{Path, PathBuf};

use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;
use voxlab::metrics::{Domain, compare};

fn experiment_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            experiment_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "toml") {
            out.push(p);
        }
    }
}

#[test]
fn every_experiment_file_renders_on_both_backends() {
    let mut files = Vec::new();
    experiment_files(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("experiments"),
        &mut files,
    );
    files.sort();
    assert!(files.len() >= 3, "found only {files:?}");
    let mut gpu = GpuTracer::new().unwrap_or_else(|e| {
        panic!("no GPU adapter: {e:#}. GPU tests need one (lavapipe: mesa-vulkan-drivers)")
    });
    for f in &files {
        let mut e = Experiment::load(f).unwrap_or_else(|err| panic!("{err}"));
        // Tiny and few samples: this checks that the file works, not the picture.
        e.settings.width = 24;
        e.settings.height = 24;
        e.settings.spp = e.settings.spp.min(2);
        let cpu = voxlab::cpu::render(&e.scene, &e.settings).frame;
        let g = gpu
            .render(&e.scene, &e.settings)
            .unwrap_or_else(|err| panic!("{}: {err:#}", f.display()))
            .frame;
        assert!(
            cpu.all_finite() && g.all_finite(),
            "{}: non-finite pixels",
            f.display()
        );
        let d = compare(&g, &cpu, Domain::Display, 2.0 / 255.0).unwrap();
        eprintln!("{}: GPU vs CPU {d}", f.display());
        // The stress cases are extreme on purpose; `voxlab stress` and
        // tests/stress_*.rs hold them to their own stated tolerances.
        if f.components().any(|c| c.as_os_str() == "stress") {
            continue;
        }
        assert!(
            d.fraction_over() < 0.02 && d.mean_abs < 2e-3,
            "{}: GPU and CPU differ: {d}",
            f.display()
        );
    }
}
