//! Image error measures shared by the tests, the golden-image checks and the reports.

pub mod flip;

use crate::frame::Frame;

/// How two images differ, per channel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImageDiff {
    pub rmse: f64,
    /// `10 log10(1 / mse)`: peak 1, the displayed range. Infinite for equal images.
    pub psnr: f64,
    pub mean_abs: f64,
    pub max_abs: f64,
    /// Pixels whose largest channel difference exceeds the threshold given to `compare`.
    pub pixels_over: usize,
    pub pixel_count: usize,
    pub threshold: f64,
}

impl ImageDiff {
    pub fn fraction_over(&self) -> f64 {
        self.pixels_over as f64 / self.pixel_count.max(1) as f64
    }
}

impl std::fmt::Display for ImageDiff {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "rmse {:.3e}, psnr {:.2} dB, mean |d| {:.3e}, max |d| {:.3e}, {} of {} pixels ({:.3} %) over {:.4}",
            self.rmse,
            self.psnr,
            self.mean_abs,
            self.max_abs,
            self.pixels_over,
            self.pixel_count,
            100.0 * self.fraction_over(),
            self.threshold
        )
    }
}

/// Which values are compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Domain {
    /// Linear radiance as traced.
    Linear,
    /// The displayed value, clamped to [0, 1] as in the PNG output.
    Display,
}

/// Compares two frames of the same size; `None` if the sizes differ.
pub fn compare(a: &Frame, b: &Frame, domain: Domain, threshold: f64) -> Option<ImageDiff> {
    if (a.width, a.height) != (b.width, b.height) {
        return None;
    }
    let map = |c: f32| match domain {
        Domain::Linear => c as f64,
        Domain::Display => (c as f64).clamp(0.0, 1.0),
    };
    let (mut sq, mut abs, mut max) = (0.0f64, 0.0f64, 0.0f64);
    let mut over = 0;
    for (pa, pb) in a.pixels.iter().zip(&b.pixels) {
        let mut pixel_max = 0.0f64;
        for c in 0..3 {
            let d = (map(pa[c]) - map(pb[c])).abs();
            // NaN must count as the largest difference, never vanish in a max().
            let d = if d.is_nan() { f64::INFINITY } else { d };
            sq += d * d;
            abs += d;
            pixel_max = pixel_max.max(d);
        }
        max = max.max(pixel_max);
        if pixel_max > threshold {
            over += 1;
        }
    }
    let n = (a.pixels.len() * 3).max(1) as f64;
    let mse = sq / n;
    Some(ImageDiff {
        rmse: mse.sqrt(),
        psnr: 10.0 * (1.0 / mse).log10(),
        mean_abs: abs / n,
        max_abs: max,
        pixels_over: over,
        pixel_count: a.pixels.len(),
        threshold,
    })
}

/// A visual difference image: |a - b| per channel of the displayed values, scaled by
/// `gain` so small differences are visible.
pub fn difference_image(a: &Frame, b: &Frame, gain: f32) -> Frame {
    let mut out = Frame::new(a.width, a.height);
    for ((o, pa), pb) in out.pixels.iter_mut().zip(&a.pixels).zip(&b.pixels) {
        for c in 0..3 {
            o[c] = ((pa[c].clamp(0.0, 1.0) - pb[c].clamp(0.0, 1.0)).abs() * gain).min(1.0);
        }
    }
    out
}

/// FLIP's pixels per degree by default: a 0.7 m wide 4K monitor seen from 0.7 m.
pub const FLIP_PPD: f32 = 67.0;

/// The display values FLIP compares: radiance clamped to [0, 1] and sRGB-encoded
/// (`--display srgb`), unquantised. (The PNGs voxlab writes by default are the seed's
/// linear framebuffer; fed to FLIP as if sRGB they would weigh dark errors wrongly.)
fn display_srgb(f: &Frame) -> Vec<[f32; 3]> {
    f.pixels
        .iter()
        .map(|p| p.map(|c| crate::frame::srgb_encode(c.clamp(0.0, 1.0))))
        .collect()
}

/// The magma colouring of a FLIP map (FLIP's own LUT).
fn magma(map: &[f32], w: u32, h: u32) -> image::RgbImage {
    let lut = nv_flip::magma_lut().to_vec();
    let bytes: Vec<u8> = map
        .iter()
        .flat_map(|&v| {
            let i = ((v * 255.0).round() as usize).min(255) * 3;
            [lut[i], lut[i + 1], lut[i + 2]]
        })
        .collect();
    image::RgbImage::from_raw(w, h, bytes).expect("FLIP map has w*h pixels")
}

/// FLIP (Andersson et al. 2020, LDR-FLIP) of `test` against `reference` at FLIP's
/// default viewing (67 pixels per degree), on the display's sRGB values as floats
/// (`flip::flip_map`): its mean, and the error map coloured with FLIP's magma LUT.
/// [`flip_8bit`] is the same on 8-bit images.
pub fn flip(reference: &Frame, test: &Frame) -> (f64, image::RgbImage) {
    let (mean, map) = flip_at(reference, test, FLIP_PPD);
    (mean, magma(&map, reference.width, reference.height))
}

/// [`flip()`] at `ppd` pixels per degree: its mean and the per-pixel error in [0, 1],
/// row-major (the Python `flip()`). The frames must have one size.
pub fn flip_at(reference: &Frame, test: &Frame, ppd: f32) -> (f64, Vec<f32>) {
    let (w, h) = (reference.width, reference.height);
    let map = flip::flip_map(
        &display_srgb(reference),
        &display_srgb(test),
        w as usize,
        h as usize,
        ppd,
    );
    let mean = map.iter().map(|&v| f64::from(v)).sum::<f64>() / map.len().max(1) as f64;
    (mean, map)
}

/// The mean of [`flip()`].
pub fn flip_mean(reference: &Frame, test: &Frame) -> f64 {
    flip(reference, test).0
}

/// FLIP of the display images quantised to 8 bits, by NVIDIA's implementation
/// (`nv-flip`): what a FLIP of two PNGs measures. Quantising adds an error of its own,
/// so this is above [`flip()`] for small differences.
pub fn flip_8bit(reference: &Frame, test: &Frame) -> f64 {
    let (w, h) = (reference.width, reference.height);
    let srgb = crate::frame::DisplayTransform {
        encoding: crate::frame::DisplayEncoding::Srgb,
        exposure: 0.0,
    };
    let r = nv_flip::FlipImageRgb8::with_data(w, h, &reference.to_display_rgb8(srgb));
    let t = nv_flip::FlipImageRgb8::with_data(w, h, &test.to_display_rgb8(srgb));
    let map = nv_flip::flip(r, t, FLIP_PPD);
    nv_flip::FlipPool::from_image(&map).mean() as f64
}

/// Student's t at 0.975 for 1 to 30 degrees of freedom: the half-width of a 95 %
/// two-sided interval of a mean is `t s / sqrt(n)` (s the sample standard deviation).
const T_975: [f64; 30] = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
    2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
    2.052, 2.048, 2.045, 2.042,
];

/// Student's t at 0.975 for `df` degrees of freedom (`df >= 1`): the table to 30, then
/// `1.96 + 2.4 / df`, within 0.003 of the exact value from 31 up.
pub(crate) fn t_975(df: usize) -> f64 {
    match df {
        0 => f64::INFINITY,
        1..=30 => T_975[df - 1],
        _ => 1.96 + 2.4 / df as f64,
    }
}

/// The mean of `values` and the half-width of its 95 % interval (Student's t, the
/// values taken as independent draws); the half-width is 0 for one value (no interval
/// can be given) and the mean NaN for none.
pub fn mean_interval(values: &[f64]) -> (f64, f64) {
    let n = values.len();
    if n == 0 {
        return (f64::NAN, 0.0);
    }
    let mean = values.iter().sum::<f64>() / n as f64;
    if n == 1 {
        return (mean, 0.0);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    (mean, t_975(n - 1) * (var / n as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intervals_follow_students_t() {
        assert_eq!(mean_interval(&[2.0]), (2.0, 0.0));
        // Mean 2, s = 1, n = 3: 4.303 / sqrt(3).
        let (m, h) = mean_interval(&[1.0, 2.0, 3.0]);
        assert_eq!(m, 2.0);
        assert!((h - 4.303 / 3f64.sqrt()).abs() < 1e-12);
        // Past the table the approximation meets it and falls towards 1.96.
        assert!((t_975(31) - 2.040).abs() < 0.003);
        assert!((t_975(60) - 2.000).abs() < 0.003);
        assert!((t_975(120) - 1.980).abs() < 0.003);
    }

    #[test]
    fn measures_a_known_difference() {
        let a = Frame::new(2, 1);
        let mut b = Frame::new(2, 1);
        b.pixels[1] = [0.3, 0.0, 0.0];
        let d = compare(&a, &b, Domain::Linear, 0.1).unwrap();
        assert!((d.rmse - (0.09f64 / 6.0).sqrt()).abs() < 1e-7);
        assert!((d.max_abs - 0.3).abs() < 1e-7);
        assert_eq!((d.pixels_over, d.pixel_count), (1, 2));
        b.pixels[0] = [f32::NAN, 0.0, 0.0];
        let d = compare(&a, &b, Domain::Linear, 0.1).unwrap();
        assert_eq!(d.max_abs, f64::INFINITY);
        assert_eq!(d.pixels_over, 2);
        assert!(compare(&a, &Frame::new(1, 2), Domain::Linear, 0.1).is_none());
    }
}
