//! voxlab's LDR-FLIP on float values (`metrics::flip`) against NVIDIA's implementation
//! (`nv-flip`, 8-bit input): on images whose values are 8-bit levels the two maps agree
//! pixel for pixel; on rendered values it measures without the quantisation's own error.

use voxlab::Frame;
use voxlab::metrics::{self, FLIP_PPD, flip::flip_map};

/// A deterministic image of 8-bit levels: gradients, an edge, a dot, and a hash's noise
/// of amplitude `noise` levels.
fn levels(w: u32, h: u32, seed: u32, noise: u32) -> Vec<[u8; 3]> {
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let hash = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663) ^ seed)
                .wrapping_mul(2_654_435_761);
            let n = |k: u32| ((hash >> (8 * k)) % (2 * noise + 1)) as i32 - noise as i32;
            let edge = if x > w / 2 { 60 } else { 0 };
            let dot = if (x as i32 - 10).pow(2) + (y as i32 - 12).pow(2) < 9 {
                90
            } else {
                0
            };
            let base = [
                (x * 255 / w) as i32,
                (y * 255 / h) as i32 + edge,
                128 + dot - edge,
            ];
            out.push(std::array::from_fn(|c| {
                (base[c] + n(c as u32)).clamp(0, 255) as u8
            }));
        }
    }
    out
}

fn floats(img: &[[u8; 3]]) -> Vec<[f32; 3]> {
    img.iter()
        .map(|p| p.map(|c| f32::from(c) / 255.0))
        .collect()
}

fn nv(reference: &[[u8; 3]], test: &[[u8; 3]], w: u32, h: u32) -> Vec<f32> {
    let r = nv_flip::FlipImageRgb8::with_data(w, h, reference.as_flattened());
    let t = nv_flip::FlipImageRgb8::with_data(w, h, test.as_flattened());
    nv_flip::flip(r, t, FLIP_PPD).to_vec()
}

#[test]
fn on_8bit_levels_the_map_is_nvidias() {
    for (w, h, noise, ppd_scale) in [(48, 40, 3, 1.0), (33, 57, 20, 1.0), (64, 16, 1, 0.5)] {
        let reference = levels(w, h, 1, 0);
        let test = levels(w, h, 7, noise);
        let ppd = FLIP_PPD * ppd_scale;
        let ours = flip_map(
            &floats(&reference),
            &floats(&test),
            w as usize,
            h as usize,
            ppd,
        );
        let theirs = {
            let r = nv_flip::FlipImageRgb8::with_data(w, h, reference.as_flattened());
            let t = nv_flip::FlipImageRgb8::with_data(w, h, test.as_flattened());
            nv_flip::flip(r, t, ppd).to_vec()
        };
        let worst = ours
            .iter()
            .zip(&theirs)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(worst < 2e-5, "{w}x{h}: max difference {worst}");
        let mean = |m: &[f32]| m.iter().map(|&v| f64::from(v)).sum::<f64>() / m.len() as f64;
        assert!((mean(&ours) - mean(&theirs)).abs() < 1e-6);
        assert!(mean(&ours) > 0.0);
    }
    // Equal images: no error anywhere.
    let a = levels(20, 20, 3, 5);
    assert!(
        flip_map(&floats(&a), &floats(&a), 20, 20, FLIP_PPD)
            .iter()
            .all(|&v| v == 0.0)
    );
    assert!(nv(&a, &a, 20, 20).iter().all(|&v| v == 0.0));
}

/// Two renders that differ by a little noise: quantising both to 8 bits adds an error
/// of its own, so the 8-bit FLIP is above the float FLIP, and the float FLIP of an
/// image against itself plus nothing is 0 where 8 bits cannot tell either.
#[test]
fn quantising_to_8_bits_raises_small_errors() {
    let (w, h) = (48u32, 48u32);
    let frame = |amp: f32, seed: u32| {
        let mut f = Frame::new(w, h);
        for (i, p) in f.pixels.iter_mut().enumerate() {
            let i = i as u32;
            let hash = (i ^ seed).wrapping_mul(2_654_435_761) >> 8;
            let n = (hash % 1000) as f32 / 1000.0 - 0.5;
            let v = 0.02 + 0.3 * (i % w) as f32 / w as f32;
            *p = [v + amp * n, v * 0.8 + amp * n, v * 0.5];
        }
        f
    };
    let reference = frame(0.0, 0);
    let test = frame(0.002, 9);
    let float = metrics::flip_mean(&reference, &test);
    let eight = metrics::flip_8bit(&reference, &test);
    assert!(float > 0.0, "{float}");
    assert!(eight > float, "8-bit {eight} against float {float}");
    assert_eq!(metrics::flip_mean(&reference, &reference), 0.0);
}
