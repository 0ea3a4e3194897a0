//! `voxlab bench --lanes` (src/bench/lanes.rs): the per-pixel counts are the reference's
//! own trees, and the efficiency is what a vector of 4x2 lanes runs.

use std::process::Command;

use voxlab::bench::lanes::{VECTOR_BLOCK, efficiency, passes, pixel_stats};
use voxlab::experiment::Experiment;

fn experiment(file: &str) -> Experiment {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    Experiment::load(dir.join(file)).unwrap()
}

/// Summed over the pixels, the counts are the CPU reference's frame: the same trees,
/// under both rule sets and with a pixel filter's offsets.
#[test]
fn the_pixels_sum_to_the_references_frame() {
    for (file, sets) in [
        ("baseline.toml", vec![]),
        ("seed_rules.toml", vec![]),
        ("baseline.toml", vec!["render.pixel_filter=\"gaussian\""]),
    ] {
        let mut e = experiment(file);
        if !sets.is_empty() {
            let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
            let overrides: Vec<_> = sets.iter().map(|s| s.parse().unwrap()).collect();
            e = Experiment::load_with(dir.join(file), &overrides).unwrap();
        }
        let (w, h) = (21, 14);
        let pixels = pixel_stats(&e, w, h, 0..h);
        // A band of rows is those rows of the whole.
        let band = pixel_stats(&e, w, h, 5..9);
        assert_eq!(band.len(), (4 * w) as usize);
        for (a, b) in band.iter().zip(&pixels[(5 * w) as usize..]) {
            assert_eq!(
                (a.primary, a.secondary, a.shadow),
                (b.primary, b.secondary, b.shadow)
            );
        }
        assert_eq!(pixels.len(), (w * h) as usize);
        let settings = voxlab::RenderSettings {
            width: w,
            height: h,
            spp: 1,
            ..e.settings.clone()
        };
        let frame = voxlab::cpu::render(&e.scene, &settings).stats;
        let sum = |f: fn(&voxlab::frame::RayStats) -> u64| pixels.iter().map(f).sum::<u64>();
        assert_eq!(sum(|s| s.primary), frame.primary, "{file} {sets:?}");
        assert_eq!(sum(|s| s.secondary), frame.secondary, "{file} {sets:?}");
        assert_eq!(sum(|s| s.shadow), frame.shadow, "{file} {sets:?}");
        assert_eq!(sum(|s| s.voxel_steps), frame.voxel_steps, "{file} {sets:?}");
        assert_eq!(sum(|s| s.untraced), frame.untraced, "{file} {sets:?}");
        assert!(frame.untraced > 0 && frame.untraced < frame.secondary);
        // The trees differ from pixel to pixel on the seed scene.
        let trees: Vec<u64> = pixels.iter().map(passes).collect();
        let e = efficiency(&trees, w, h);
        assert!(e > 0.2 && e < 1.0, "{file}: {e}");
    }
}

/// Traced a band of rows at a time, the figures are the whole image's.
#[test]
fn the_bands_add_up_to_the_image() {
    let e = experiment("baseline.toml");
    let side = 70;
    let pixels = pixel_stats(&e, side, side, 0..side);
    let row = &voxlab::bench::lanes::bench_lanes(std::slice::from_ref(&e), side)[0];
    let trees: Vec<u64> = pixels.iter().map(passes).collect();
    let shadows: Vec<u64> = pixels.iter().map(|s| s.shadow).collect();
    assert_eq!(row.tree_efficiency, efficiency(&trees, side, side));
    assert_eq!(row.shadow_efficiency, efficiency(&shadows, side, side));
    let steps: Vec<u64> = pixels.iter().map(|s| s.voxel_steps).collect();
    assert_eq!(row.steps_efficiency, efficiency(&steps, side, side));
    let mean = |v: &[u64]| v.iter().sum::<u64>() as f64 / f64::from(side * side);
    assert_eq!(row.tree_passes_per_pixel, mean(&trees));
    assert_eq!(row.steps_per_pixel, mean(&steps));
    let rays: Vec<u64> = pixels.iter().map(|s| s.primary + s.secondary).collect();
    assert_eq!(row.tree_rays_per_pixel, mean(&rays));
    // The kernel leaves some of the tree's rays untraced on the seed scene.
    assert!(row.tree_passes_per_pixel < row.tree_rays_per_pixel);
}

/// Each vector runs 8 lanes for as long as its largest count, also where the image's
/// edge cuts it.
#[test]
fn a_vector_runs_as_long_as_its_slowest_lane() {
    assert_eq!(VECTOR_BLOCK, (4, 2));
    assert_eq!(efficiency(&[0; 12], 4, 3), 1.0);
    assert_eq!(efficiency(&[5; 8], 4, 2), 1.0);
    // One slow lane of eight: 7 + 8 of 8 * 8.
    let mut v = [1u64; 8];
    v[5] = 8;
    assert_eq!(efficiency(&v, 4, 2), 15.0 / 64.0);
    // Two blocks side by side, each judged alone: rows [1 1 1 1 2 2 2 2] twice.
    let row = [1u64, 1, 1, 1, 2, 2, 2, 2];
    let two: Vec<u64> = row.iter().chain(row.iter()).copied().collect();
    assert_eq!(efficiency(&two, 8, 2), 1.0);
    // Transposed, each block holds 1s and 2s: 24 of 2 * 8 * 2.
    let cols: Vec<u64> = (0..16).map(|i| if i % 2 == 0 { 1 } else { 2 }).collect();
    assert_eq!(efficiency(&cols, 2, 8), 24.0 / 64.0);
    // A 5x3 image: blocks of 4x2, 1x2, 4x1 and 1x1, each a whole vector of 8 lanes.
    assert_eq!(efficiency(&[1; 15], 5, 3), 15.0 / 32.0);
}

/// The command prints one JSON row per experiment, named, with efficiencies in (0, 1].
#[test]
fn the_command_prints_a_row_per_experiment() {
    let out = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["bench", "--lanes", "--size", "16", "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: Vec<serde_json::Value> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["experiment"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["baseline", "seed_rules"]);
    for r in &rows {
        assert_eq!(r["bench"], "lanes");
        for k in ["tree_lane_efficiency", "shadow_lane_efficiency"] {
            let e = r[k].as_f64().unwrap();
            assert!(e > 0.0 && e <= 1.0, "{k}: {e}");
        }
        assert!(r["tree_rays_per_pixel"].as_f64().unwrap() >= 1.0);
        let passes = r["tree_passes_per_pixel"].as_f64().unwrap();
        assert!(passes >= 1.0 && passes <= r["tree_rays_per_pixel"].as_f64().unwrap());
    }
    // The seed's rules trace the smaller trees.
    assert!(rows[0]["tree_rays_per_pixel"].as_f64() > rows[1]["tree_rays_per_pixel"].as_f64());
}
