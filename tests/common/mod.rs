//! Helpers shared by the GPU test files (`mod common;`): the tracer they all need, and
//! image comparisons through the library's own metric (`voxlab::metrics::compare`).

// Every test file is a crate of its own and uses only some of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use glam::DVec3;
use voxlab::scene::mesh::TriangleMesh;
use voxlab::scene::{Material, Scene};

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

/// The CPU reference's render walking the walk data `gpu` keeps for it where that is
/// the build it would make (`render --check` does so): for large grids, whose data
/// takes tens of seconds to build (tests/gpu_cache.rs holds that the image and counts
/// are those of the reference's own build).
pub fn cpu_render_reusing(
    gpu: &GpuTracer,
    scene: &voxlab::scene::Scene,
    settings: &voxlab::RenderSettings,
) -> voxlab::RenderOutput {
    let (w, h) = (settings.width, settings.height);
    voxlab::cpu::render_region_reusing(scene, settings, 0..w, 0..h, &|k| gpu.kept_walk_data(k))
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

/// [`assert_agree`] of a counted GPU render and the CPU's, and the same decisions: their
/// secondary-ray counts within 1 % (a grazing ray may take another path in f32), and so
/// the counts of those the kernel leaves untraced (they leave the grid where they start).
#[track_caller]
pub fn assert_same_tree(name: &str, g: &voxlab::RenderOutput, c: &voxlab::RenderOutput) {
    assert_agree(name, &g.frame, &c.frame);
    for (what, gs, cs) in [
        ("secondary", g.stats.secondary, c.stats.secondary),
        ("untraced", g.stats.untraced, c.stats.untraced),
    ] {
        let (gs, cs) = (gs as f64, cs as f64);
        assert!(
            (gs - cs).abs() <= 0.01 * cs.max(100.0),
            "{name}: {what} rays GPU {gs} against CPU {cs}"
        );
    }
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

/// `e` read again from its file with `sets` (`key=value`) applied, as `--set` applies
/// them; its source path kept.
pub fn overridden(e: &Experiment, sets: &[&str]) -> Experiment {
    let path = e.source_path.as_ref().expect("loaded from a file");
    let text = std::fs::read_to_string(path).unwrap();
    let overrides: Vec<voxlab::experiment::Override> =
        sets.iter().map(|s| s.parse().unwrap()).collect();
    let mut out = Experiment::from_str_with(&text, path, &overrides)
        .unwrap_or_else(|err| panic!("{sets:?}: {err}"));
    out.source_path = e.source_path.clone();
    out
}

/// A real model from `experiments/data/` (made by others; its README gives sources and
/// licences); a missing file fails the test with where it was looked for.
pub fn example_data(name: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("experiments/data")
        .join(name);
    assert!(p.exists(), "example data {} is missing", p.display());
    p
}

/// A unit icosphere subdivided `k` times, counter-clockwise outward, as a soup. Shared
/// edges are split at the same point from both sides (the midpoint is symmetric), so the
/// soup is watertight.
pub fn icosphere(k: u32) -> Vec<[DVec3; 3]> {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let v: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let faces = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let mut tris: Vec<[DVec3; 3]> = faces.iter().map(|f| f.map(|i| v[i])).collect();
    for _ in 0..k {
        tris = tris
            .iter()
            .flat_map(|&[a, b, c]| {
                let m = |p: DVec3, q: DVec3| ((p + q) * 0.5).normalize();
                let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
                [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
            })
            .collect();
    }
    tris
}

/// The scene of a triangle soup voxelized at `resolution` in material `m`, with the
/// seed's lights and camera, keeping the triangles (and `normals`, per triangle, if
/// given).
pub fn mesh_scene(
    tris: Vec<[DVec3; 3]>,
    normals: Vec<[DVec3; 3]>,
    m: Material,
    resolution: u32,
) -> Scene {
    let mesh = TriangleMesh {
        material_of: vec![0; tris.len()],
        materials: vec![m.clone()],
        triangles: tris,
        normals,
        warnings: vec![],
    };
    voxlab::scene::mesh::seed_lit_scene(&mesh, resolution, m).unwrap()
}

/// The registered traversals and surfaces the tests name.
pub const DENSE_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::dense::TRAVERSAL);
pub const SPARSE_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::sparse::TRAVERSAL);
pub const PROXIMITY_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::proximity::TRAVERSAL);
pub const OCTANT_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::octant::TRAVERSAL);
pub const BOXES_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::boxes::TRAVERSAL);
pub const SPARSE_OCTANT_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::sparse_octant::TRAVERSAL);
pub const VOXELS_SURFACE: voxlab::render::Surface =
    voxlab::render::Surface(&voxlab::technique::voxels::SURFACE);
pub const MESH_SURFACE: voxlab::render::Surface =
    voxlab::render::Surface(&voxlab::technique::mesh::SURFACE);
pub const SMOOTH_SURFACE: voxlab::render::Surface =
    voxlab::render::Surface(&voxlab::technique::smooth::SURFACE);
