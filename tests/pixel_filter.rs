//! Anti-aliasing (`[render] pixel_filter`): primary rays jittered per frame from the
//! shared counter hash, distributed like the reconstruction filter. Off is the
//! baseline; the kernel draws the CPU's positions (GPU = CPU over filters, frames and
//! image sizes); accumulated box-filtered images converge to a supersampled one; the
//! offsets follow their filter.

mod common;

use common::{assert_agree, rmse, tracer};
use voxlab::experiment::Experiment;
use voxlab::plan::Plan;
use voxlab::render::PixelFilter;
use voxlab::scene::seed_scene;
use voxlab::{Frame, RenderSettings, cpu};

fn settings(filter: PixelFilter, w: u32, h: u32, spp: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        spp,
        pixel_filter: filter,
        ..Default::default()
    }
}

#[test]
fn off_is_one_frame_through_the_pixel_centres() {
    let scene = seed_scene(16).unwrap();
    let st = settings(PixelFilter::None, 24, 24, 8);
    let plan = Plan::new(&scene, &st);
    assert!(!plan.pixel_filter && !plan.accumulate, "{plan}");
    assert!(!plan.shader_defs().contains_key("PIXEL_FILTER"));
    let one = cpu::render(&scene, &settings(PixelFilter::None, 24, 24, 1)).frame;
    assert_eq!(cpu::render(&scene, &st).frame, one);
    let p = Plan::new(&scene, &settings(PixelFilter::Box, 24, 24, 8));
    assert!(p.pixel_filter && p.accumulate, "{p}");
}

#[test]
fn gpu_draws_the_cpu_positions() {
    let mut gpu = tracer();
    let scene = seed_scene(16).unwrap();
    for filter in [PixelFilter::Box, PixelFilter::Gaussian] {
        for (w, h, spp, width) in [(13, 9, 1, 0.5), (32, 32, 7, 1.0), (8, 8, 300, 0.5)] {
            let mut st = settings(filter, w, h, spp);
            st.filter_width = width;
            st.max_reflection_depth = 2;
            st.max_refraction_depth = 2;
            let g = gpu.render(&scene, &st).unwrap().frame;
            let c = cpu::render(&scene, &st).frame;
            assert_agree(&format!("{} {w}x{h} spp {spp}", filter.name()), &g, &c);
        }
    }
}

/// Box filter of the pixel's own width: the mean over many frames approaches the mean
/// of an 8 x 8 supersampled render, and more frames come closer.
#[test]
fn box_filtered_frames_converge_to_the_supersampled_image() {
    let scene = seed_scene(16).unwrap();
    let (w, h, k) = (16u32, 16u32, 8u32);
    let mut fine = settings(PixelFilter::None, w * k, h * k, 1);
    fine.max_reflection_depth = 2;
    fine.max_refraction_depth = 2;
    let big = cpu::render(&scene, &fine).frame;
    let mut reference = Frame::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f64; 3];
            for dy in 0..k {
                for dx in 0..k {
                    let p = big.get(x * k + dx, y * k + dy);
                    for c in 0..3 {
                        sum[c] += p[c] as f64;
                    }
                }
            }
            reference.pixels[(y * w + x) as usize] = sum.map(|s| (s / (k * k) as f64) as f32);
        }
    }
    let errors: Vec<f64> = [1, 16, 256]
        .iter()
        .map(|&spp| {
            let mut st = settings(PixelFilter::Box, w, h, spp);
            st.max_reflection_depth = 2;
            st.max_refraction_depth = 2;
            rmse(&cpu::render(&scene, &st).frame, &reference)
        })
        .collect();
    println!("box filter against 8x8 supersampling, RMSE at 1, 16, 256 frames: {errors:?}");
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    assert!(errors[2] < 0.25 * errors[0], "{errors:?}");
}

#[test]
fn offsets_follow_their_filter() {
    let n = 20000u32;
    let (mut sum, mut sq, mut max) = ([0.0f64; 2], [0.0f64; 2], 0.0f64);
    for i in 0..n {
        let (x, y) = PixelFilter::Box.offset(0.5, 3, i % 97, i / 97);
        max = max.max(x.abs()).max(y.abs());
        sum[0] += x;
        sum[1] += y;
    }
    assert!(max <= 0.5 && (sum[0] / n as f64).abs() < 0.01 && (sum[1] / n as f64).abs() < 0.01);
    sum = [0.0; 2];
    for i in 0..n {
        let (x, y) = PixelFilter::Gaussian.offset(0.7, 3, i % 97, i / 97);
        for (d, v) in [x, y].into_iter().enumerate() {
            sum[d] += v;
            sq[d] += v * v;
        }
    }
    for d in 0..2 {
        let mean = sum[d] / n as f64;
        let var = sq[d] / n as f64 - mean * mean;
        assert!(
            mean.abs() < 0.02 && (var.sqrt() - 0.7).abs() < 0.02,
            "axis {d}: {mean} {var}"
        );
    }
    assert_eq!(PixelFilter::None.offset(1.0, 3, 5, 7), (0.0, 0.0));
}

#[test]
fn the_file_names_the_filter() {
    let e = Experiment::from_str(
        "[render]\npixel_filter = \"gaussian\"\nfilter_width = 0.8\n",
        "x.toml",
    )
    .unwrap();
    assert_eq!(
        (e.settings.pixel_filter, e.settings.filter_width),
        (PixelFilter::Gaussian, 0.8)
    );
    let err = Experiment::from_str("[render]\npixel_filter = \"lanczos\"\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("x.toml:2:") && err.contains("\"box\""),
        "{err}"
    );
    let err = Experiment::from_str("[render]\nfilter_width = 0\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("render.filter_width") && err.contains("(0, 4]"),
        "{err}"
    );
}
