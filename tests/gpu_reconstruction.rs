//! The reconstruction on the GPU: the kernel writes the primary layers beside the
//! radiance (`PRIMARY_LAYERS`, shaders/trace.wgsl), summed over frames as the radiance
//! is, the filter runs on the device (src/gpu/reconstruct.rs, in f32), and the filtered
//! image agrees with the CPU reference's (f64) over generated cases: image
//! sizes 8 to 256, 1 to 5 iterations, 1 to 6 frames (spatial and temporal variance), the
//! shadow models that sample, both transmittance models, mirrors and glass (the
//! layers are the primary hit's alone), a smooth triangle surface, the walks, the pixel
//! filters, the ray cutoff and reflection depth limits, settings across their ranges;
//! one tracer renders them all in turn (its kept buffers resized between sizes). A range of frames
//! continued on the device gives the image of one render, and the unshadowed pass costs
//! no counted ray.
//!
//! Tolerance: tests/gpu_agreement.rs's (fewer than 0.5 % of pixels over 2/255, mean
//! below 1e-3). The filter's weights are continuous in its inputs except the luminance
//! stop where the variance is zero, and there the inputs are equal on both sides.
//!
//! Runs on whatever adapter wgpu finds (lavapipe in CI); a missing adapter fails.

mod common;

use common::{assert_agree, experiment, tracer};
use rand::{RngExt, SeedableRng};
use voxlab::experiment::{Experiment, Override};
use voxlab::plan::Plan;

fn with(path: &str, sets: &[String]) -> Experiment {
    let e = experiment(path);
    let file = e.source_path.clone().expect("loaded");
    let text = std::fs::read_to_string(&file).unwrap();
    let overrides: Vec<Override> = sets.iter().map(|s| s.parse().unwrap()).collect();
    Experiment::from_str_with(&text, &file, &overrides)
        .unwrap_or_else(|err| panic!("{path} {sets:?}: {err}"))
}

#[test]
fn gpu_equals_cpu_over_generated_cases() {
    let mut gpu = tracer();
    let mut rng = rand::rngs::StdRng::seed_from_u64(400);
    let scenes = [
        "mitsuba/rect_blocks.toml",
        "mitsuba/disk_blocks.toml",
        "area_lights.toml",
        "soft_coloured_shadows.toml",
        "solid_angle.toml",
        "deer_smooth.toml",
    ];
    let models = ["ratio", "area", "solid-angle"];
    let mut filtered = 0;
    for case in 0..18 {
        let path = scenes[case % scenes.len()];
        let model = models[rng.random_range(0..models.len())];
        // Two cases at the sizes a figure uses, the rest small.
        let (w, h) = if case % 8 == 7 {
            (rng.random_range(160..=256), rng.random_range(128..=256))
        } else {
            (rng.random_range(8..=64), rng.random_range(8..=48))
        };
        let sets = vec![
            format!("render.width={w}"),
            format!("render.height={h}"),
            format!("render.spp={}", rng.random_range(1..=6)),
            format!("render.light_samples={}", rng.random_range(1..=3)),
            format!("features.shadow_model={model}"),
            format!(
                "features.transmittance={}",
                ["min-kt", "beer-lambert"][rng.random_range(0..2)]
            ),
            "features.reconstruction=atrous".to_string(),
            format!("techniques.atrous.iterations={}", rng.random_range(1..=5)),
            format!(
                "render.traversal={}",
                ["auto", "dense", "sparse", "octant"][rng.random_range(0..4)]
            ),
            format!(
                "render.pixel_filter={}",
                ["none", "box", "gaussian"][rng.random_range(0..3)]
            ),
            format!(
                "render.ray_cutoff={}",
                [0.0, 0.001, 0.05][rng.random_range(0..3)]
            ),
            format!(
                "render.max_reflection_depth={}",
                [0, 1, 4][rng.random_range(0..3)]
            ),
            format!(
                "techniques.atrous.sigma_normal={}",
                [0.0, 16.0, 128.0][rng.random_range(0..3)]
            ),
            format!(
                "techniques.atrous.sigma_depth={}",
                [0.5, 1.0, 4.0][rng.random_range(0..3)]
            ),
            format!(
                "techniques.atrous.sigma_luminance={}",
                [1.0, 4.0, 1e6][rng.random_range(0..3)]
            ),
        ];
        let e = with(path, &sets);
        let plan = Plan::new(&e.scene, &e.settings);
        if plan.reconstruction.name != "atrous" {
            continue;
        }
        filtered += 1;
        let name = format!("case {case}: {path} {sets:?}");
        let g = gpu
            .render(&e.scene, &e.settings)
            .unwrap_or_else(|err| panic!("{name}: {err:#}"));
        let c = voxlab::cpu::render(&e.scene, &e.settings);
        assert_agree(&name, &g.frame, &c.frame);
    }
    assert!(filtered >= 10, "only {filtered} cases kept the filter");
}

/// Frames rendered in ranges on one tracer (the sums and the layers continued on the
/// device) give the image of one render of them all; the counted rays are those of the
/// same render without the filter (the unshadowed pass traces nothing).
#[test]
fn ranges_and_counts_are_those_of_one_render() {
    let mut gpu = tracer();
    let sets: Vec<String> = [
        "render.width=32",
        "render.height=24",
        "render.spp=5",
        "render.light_samples=1",
        "features.shadow_model=ratio",
        "features.reconstruction=atrous",
        "techniques.atrous.iterations=3",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    let e = with("mitsuba/rect_blocks.toml", &sets);
    let whole = gpu.render(&e.scene, &e.settings).unwrap();
    let mut last = None;
    for r in [0..2, 2..3, 3..5] {
        last = Some(gpu.render_frames(&e.scene, &e.settings, r).unwrap());
    }
    assert_eq!(last.unwrap().frame, whole.frame);

    let counted = gpu.render_counted(&e.scene, &e.settings).unwrap();
    let mut unfiltered = e.settings.clone();
    unfiltered.features.reconstruction = voxlab::technique::default_reconstruction();
    let plain = gpu.render_counted(&e.scene, &unfiltered).unwrap();
    assert_eq!(counted.stats, plain.stats);
    let cpu = voxlab::cpu::render(&e.scene, &e.settings);
    assert_eq!(cpu.stats.shadow, counted.stats.shadow);
}

/// `voxlab bench --reconstruction`'s rows: one per reconstruction and size, the filter's
/// passes timed inside the filtered frame; an experiment whose shadow model samples
/// nothing is refused with the reason, not measured unfiltered.
#[test]
fn the_benchmark_times_the_filter_inside_the_frame() {
    use voxlab::bench::reconstruction::{bench_reconstructions, filter_table};
    let mut gpu = tracer();
    let e = with("mitsuba/rect_blocks.toml", &[]);
    let filters = &voxlab::technique::RECONSTRUCTIONS[1..];
    let rows = bench_reconstructions(&mut gpu, &e, filters, &[16, 24], 1).unwrap();
    assert_eq!(rows.len(), 2 * filters.len());
    for r in &rows {
        assert!(r.plain_ms > 0.0 && r.filter_ms > 0.0, "{r:?}");
        assert!(r.filtered_ms >= r.filter_ms, "{r:?}");
    }
    assert!(filter_table(&rows).contains("| atrous | 16x16 |"));
    let hard = with(
        "mitsuba/rect_blocks.toml",
        &["features.shadow_model=hard".to_string()],
    );
    let err = bench_reconstructions(&mut gpu, &hard, filters, &[16], 1).unwrap_err();
    assert!(
        format!("{err:#}").contains("leaves the reconstruction atrous out"),
        "{err:#}"
    );
}

/// An image whose radiance and layer planes exceed what the device binds is refused
/// before anything is allocated, and the error says the planes are the reason.
#[test]
fn an_image_too_large_for_its_planes_is_refused_with_the_reason() {
    let mut gpu = tracer();
    let e = with(
        "mitsuba/rect_blocks.toml",
        &[
            "render.width=8192".to_string(),
            "render.height=8192".to_string(),
            "features.shadow_model=ratio".to_string(),
            "features.reconstruction=atrous".to_string(),
        ],
    );
    let err = gpu.render(&e.scene, &e.settings).unwrap_err();
    let m = format!("{err:#}");
    assert!(m.contains("planes of the primary layers"), "{m}");
}

/// `svgf` over camera paths: the temporal accumulation (reprojection, rejection,
/// exponential average) and the a-trous passes after it, on the device against the
/// reference, the whole path rendered by a session on each backend. Generated cases:
/// image sizes 8 to 256, paths of 1 to 6 frames, static and orbiting cameras both ways,
/// alphas from the mean of all frames to mostly the new one, the tolerances and the
/// luminance stop across their ranges, 1 to 4 passes, 1 to 3 frames per pose, the sampling models.
#[test]
fn svgf_gpu_equals_cpu_over_generated_paths() {
    let mut gpu = voxlab::Session::new(voxlab::Backend::Gpu).expect("a GPU adapter");
    let mut cpu = voxlab::Session::new(voxlab::Backend::Cpu).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(41);
    let scenes = [
        "reconstruction.toml",
        "mitsuba/rect_blocks.toml",
        "deer_smooth.toml",
        "soft_coloured_shadows.toml",
    ];
    let mut filtered = 0;
    for case in 0..10 {
        let path = scenes[case % scenes.len()];
        let (w, h) = if case == 9 {
            (256, 192)
        } else {
            (rng.random_range(8..=64), rng.random_range(8..=48))
        };
        let sets = vec![
            format!("render.width={w}"),
            format!("render.height={h}"),
            format!("render.spp={}", rng.random_range(1..=3)),
            "render.light_samples=1".to_string(),
            format!(
                "features.shadow_model={}",
                ["ratio", "area", "solid-angle"][rng.random_range(0..3)]
            ),
            "features.reconstruction=svgf".to_string(),
            format!("render.path_frames={}", rng.random_range(1..=6)),
            format!(
                "render.orbit_deg={}",
                [0.0, 0.5, -3.0, 10.0][rng.random_range(0..4)]
            ),
            format!("techniques.svgf.iterations={}", rng.random_range(1..=4)),
            format!(
                "techniques.svgf.alpha={}",
                [0.0, 0.2, 0.6][rng.random_range(0..3)]
            ),
            format!(
                "techniques.svgf.depth_tolerance={}",
                [1e-4, 0.005, 0.05][rng.random_range(0..3)]
            ),
            format!(
                "techniques.svgf.normal_tolerance={}",
                [-1.0, 0.9, 0.9999][rng.random_range(0..3)]
            ),
            format!(
                "techniques.svgf.sigma_luminance={}",
                [1.0, 4.0, 1e6][rng.random_range(0..3)]
            ),
        ];
        let e = with(path, &sets);
        let plan = Plan::new(&e.scene, &e.settings);
        if plan.reconstruction.name != "svgf" {
            continue;
        }
        filtered += 1;
        let name = format!("case {case}: {path} {sets:?}");
        let g = gpu.render(&e).unwrap_or_else(|err| panic!("{name}: {err}"));
        let c = cpu.render(&e).unwrap();
        assert_agree(&name, &g.frame, &c.frame);
    }
    assert!(filtered >= 8, "only {filtered} cases kept the filter");
}

/// A wide luminance stop (`sigma_luminance` up to its 1e6) opens the luminance weight to
/// whatever variance a pixel has, so the f32 rounding of equal values' moments (about
/// 1e-7 of them: a pixel lit in every frame, the bilinear mixture of equal taps) must
/// count as no variance, as the f64 reference's 1e-16 does (`atrous::VARIANCE_FLOOR`).
/// Before the floor, `render --check` of `reconstruction.toml` at 16x16 and
/// `sigma_luminance = 1e5` had pixels 1.4/255 off (3e-6 at 4), inside the tolerance of
/// [`assert_agree`] but a thousand times the filter's own f32 error there: the largest
/// difference is bounded here. Temporal variance of svgf's moments and of atrous'
/// frames, and the spatial estimate (svgf before four frames).
#[test]
fn a_wide_luminance_stop_sees_no_rounding_as_variance() {
    let mut gpu = voxlab::Session::new(voxlab::Backend::Gpu).expect("a GPU adapter");
    let mut cpu = voxlab::Session::new(voxlab::Backend::Cpu).unwrap();
    let cases: [&[&str]; 4] = [
        &["render.path_frames=8"],
        &["render.path_frames=8", "techniques.svgf.iterations=1"],
        &["render.path_frames=3"],
        &["features.reconstruction=atrous", "render.spp=8"],
    ];
    for case in cases {
        for sigma in [4.0, 1e3, 1e5, 1e6] {
            for (w, h) in [(16, 16), (24, 20)] {
                let mut sets: Vec<String> = case.iter().map(|s| s.to_string()).collect();
                sets.push(format!("render.width={w}"));
                sets.push(format!("render.height={h}"));
                for t in ["svgf", "atrous"] {
                    sets.push(format!("techniques.{t}.sigma_luminance={sigma}"));
                }
                let e = with("reconstruction.toml", &sets);
                let name = format!("{sets:?}");
                let g = gpu.render(&e).unwrap_or_else(|err| panic!("{name}: {err}"));
                let c = cpu.render(&e).unwrap();
                let d = common::display(&g.frame, &c.frame, 2.0 / 255.0);
                // At sigma 4 the filter's own f32 error reaches 1.7e-3 here; without the
                // floor the wide stops gave 2.2e-3 to 5.6e-3, with it at most 1.6e-3.
                assert!(d.max_abs < 2.5e-3, "{name}: GPU vs CPU {d}");
            }
        }
    }
}

/// An `svgf` path seen from far out, with a view narrowed to the grid: the kernel
/// reprojects in the cameras' bases with the depths less their origin (the primary
/// rays' advance), where in world coordinates in f32 a far eye's hits and its narrow
/// view's rays kept few digits (`render --check` drew 1.6 % of a 24x24 image apart at
/// 3e5 voxels, 2 % at 1e6 and 11 % at 1e8, the camera still; 14 % at 1e8 orbiting 40
/// degrees a frame). Generated: distances 1e3 to 1e9 voxels, still and orbiting
/// cameras up to 40 degrees a frame, 4 to 8 frames (the temporal variance), the
/// shadow models that sample, the grid filling the view or a part of it.
#[test]
fn svgf_from_a_far_eye_agrees() {
    let mut gpu = voxlab::Session::new(voxlab::Backend::Gpu).expect("a GPU adapter");
    let mut cpu = voxlab::Session::new(voxlab::Backend::Cpu).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(77);
    for case in 0..8 {
        let distance: f64 = 10f64.powf(rng.random_range(3.0..9.0));
        // The grid's half-width (12 voxels) to twice it at the view's half-height.
        let half = rng.random_range(12.0..24.0);
        let vfov = (2.0 * (half / distance).atan().to_degrees()).max(1e-6);
        let (w, h) = (rng.random_range(16..=32), rng.random_range(16..=32));
        let sets = vec![
            format!("render.width={w}"),
            format!("render.height={h}"),
            format!("camera.distance={distance:e}"),
            format!("camera.vfov_deg={vfov:e}"),
            format!("camera.yaw_deg={}", rng.random_range(-180.0..180.0)),
            format!("camera.pitch_deg={}", rng.random_range(10.0..80.0)),
            format!(
                "features.shadow_model={}",
                ["ratio", "area", "solid-angle"][rng.random_range(0..3)]
            ),
            "features.reconstruction=svgf".to_string(),
            format!("render.path_frames={}", rng.random_range(4..=8)),
            format!("render.orbit_deg={}", [0.0, 0.5, 3.0, -40.0][case % 4]),
        ];
        let e = with("reconstruction.toml", &sets);
        let name = format!("case {case}: {sets:?}");
        let g = gpu.render(&e).unwrap_or_else(|err| panic!("{name}: {err}"));
        let c = cpu.render(&e).unwrap();
        assert_agree(&name, &g.frame, &c.frame);
    }
}

/// A display's own camera path (`Session::render_frames` from frame 0, the history
/// kept between calls) through images of other shapes: a frame of another width and
/// height starts the history afresh on both tracers, also where it has as many pixels
/// (the GPU kept its history by the pixels' count, and read a 32x16 history as 16x32:
/// 13 % of the pixels off). Generated: shapes of 512 pixels in four aspects and two
/// other sizes, the camera orbiting or still, each frame GPU = CPU.
#[test]
fn a_display_path_through_other_shapes_agrees_frame_by_frame() {
    let mut gpu = voxlab::Session::new(voxlab::Backend::Gpu).expect("a GPU adapter");
    let mut cpu = voxlab::Session::new(voxlab::Backend::Cpu).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let shapes = [(32, 16), (16, 32), (64, 8), (8, 64), (24, 24), (20, 12)];
    let mut last: Option<(u32, u32)> = None;
    let mut reshaped_alike = 0;
    for step in 0..12 {
        let (w, h) = shapes[rng.random_range(0..shapes.len())];
        let yaw = [0.0, 2.0][rng.random_range(0..2)] * step as f64;
        let mut e = with(
            "reconstruction.toml",
            &[
                format!("render.width={w}"),
                format!("render.height={h}"),
                "render.spp=1".to_string(),
                "render.path_frames=1".to_string(),
                "features.reconstruction=svgf".to_string(),
            ],
        );
        e.scene.camera.yaw += yaw.to_radians();
        if let Some(l) = last
            && l != (w, h)
            && l.0 * l.1 == w * h
        {
            reshaped_alike += 1;
        }
        last = Some((w, h));
        let name = format!("step {step}: {w}x{h}, yaw +{yaw} degrees");
        let g = gpu
            .render_frames(&e.scene, &e.settings, 0..1)
            .unwrap_or_else(|err| panic!("{name}: {err}"));
        let c = cpu.render_frames(&e.scene, &e.settings, 0..1).unwrap();
        assert_agree(&name, &g.frame, &c.frame);
    }
    assert!(
        reshaped_alike >= 2,
        "{reshaped_alike} changes of shape alone"
    );
}

/// Display paths that hold the camera still for 1 to 6 frames (refined in ranges of
/// frames or not), then turn it: the first frame after the turn mixes taps that all
/// hold the same length, and the variance switches from the spatial to the temporal
/// estimate at `TEMPORAL_FRAMES`. Both tracers must see that integer: summed plainly,
/// the mixture of taps of length 3 was 2.9999999 in one precision and 3 in the other, and
/// 2.5 % of the pixels of the turned frame differed by up to 0.037. Generated: the still
/// frames, their ranges, the turn and alpha; each frame GPU = CPU.
#[test]
fn a_turn_after_a_still_camera_agrees_whatever_the_history_length() {
    let mut gpu = voxlab::Session::new(voxlab::Backend::Gpu).expect("a GPU adapter");
    let mut cpu = voxlab::Session::new(voxlab::Backend::Cpu).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    for still in 1..=6u32 {
        let turn = [3.0, -2.0, 6.0][rng.random_range(0..3)];
        let alpha = [0.0, 0.2][rng.random_range(0..2)];
        let e = |yaw: f64| {
            let mut e = with(
                "reconstruction.toml",
                &[
                    "render.width=40".to_string(),
                    "render.height=24".to_string(),
                    "render.spp=8".to_string(),
                    "render.path_frames=1".to_string(),
                    "features.reconstruction=svgf".to_string(),
                    format!("techniques.svgf.alpha={alpha}"),
                ],
            );
            e.scene.camera.yaw += f64::to_radians(yaw);
            e
        };
        gpu.reset_history();
        cpu.reset_history();
        let mut steps: Vec<(f64, std::ops::Range<u32>)> = Vec::new();
        for k in 0..still {
            // A refinement continues the frame before it, or the path starts one anew.
            let refine = k > 0 && rng.random_bool(0.5);
            let start = match steps.last() {
                Some((_, r)) if refine => r.end,
                _ => 0,
            };
            steps.push((0.0, start..start + 1));
        }
        steps.push((turn, 0..1));
        steps.push((turn, 1..3));
        for (i, (yaw, frames)) in steps.iter().enumerate() {
            let e = e(*yaw);
            let name = format!(
                "{still} still frames, alpha {alpha}, step {i}: yaw +{yaw}, frames {frames:?} \
                 (path {steps:?})"
            );
            let g = gpu
                .render_frames(&e.scene, &e.settings, frames.clone())
                .unwrap_or_else(|err| panic!("{name}: {err}"));
            let c = cpu
                .render_frames(&e.scene, &e.settings, frames.clone())
                .unwrap();
            assert_agree(&name, &g.frame, &c.frame);
        }
    }
}
