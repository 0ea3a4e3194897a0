//! Reconstruction `atrous`: the edge-avoiding a-trous wavelet filter of H. Dammertz,
//! D. Sewtz, J. Hanika and H. Lensch ("Edge-Avoiding A-Trous Wavelet Transform for
//! fast Global Illumination Filtering", HPG 2010), with the edge-stopping functions and
//! the variance guide of C. Schied et al. ("Spatiotemporal Variance-Guided Filtering",
//! HPG 2017, section 4, without the temporal history), applied to the visibility ratio
//! of the primary hit's local light (Heitz, Hill and McGuire, I3D 2018).
//!
//! Contract (the f64 reference; `shaders/reconstruction_atrous.wgsl` is its f32 twin on
//! the device):
//! - Input at pixel `p` (`crate::frame::PrimaryLayers`): the visibility `c_p` (per
//!   channel, `PrimaryPixel::visibility`), its luminance `l_p = lum(c_p)`, the normal
//!   `n_p`, the depth `z_p` (hit distance) and the material `m_p`. A pixel that
//!   `PrimaryPixel::filtered` rejects is neither filtered nor read.
//! - The variance `var_p` of the input: with at least [`TEMPORAL_FRAMES`] frames the
//!   temporal one, `(m2 - m1^2) / N` from the frames' moments (the variance of a mean of
//!   `N`); with fewer, the variance of `l` over the 7x7 pixels around `p`, weighted by
//!   `w_z w_n w_m` below (Schied et al. 4.2, their bilateral estimate before four frames
//!   of history), divided by `N`. Either is `m2 - m1^2` of a mean `m1` and mean square
//!   `m2`, taken as zero where it is at most [`VARIANCE_FLOOR`] `m2` (rounding, not
//!   spread).
//! - The depth gradient `g_p`: per axis, of the one-sided differences of `z` towards the
//!   two neighbours the filter reads, the smaller in magnitude (0 where it reads none).
//! - Iteration `i = 0 .. iterations - 1`, step `s = 2^i`, over `q = p + s (dx, dy)`,
//!   `dx, dy` in `-2..=2`, inside the image and read:
//!   `c'_p = sum w c_q / sum w` and `var'_p = sum w^2 var_q / (sum w)^2`, with
//!   `w = h(dx) h(dy) w_z w_n w_l w_m`, `h` the B3 spline `(1, 4, 6, 4, 1) / 16`,
//!   `w_z = exp(-|z_p - z_q| / (sigma_depth |g_p . s (dx, dy)| + EPS_DEPTH z_p))`,
//!   `w_n = max(0, n_p . n_q)^sigma_normal`,
//!   `w_l = exp(-|l_p - l_q| / (sigma_luminance sqrt(G(var)_p) + EPS_LUMINANCE))`
//!   (`G` the 3x3 Gaussian `(1, 2, 1) / 4` per axis over the pixels read,
//!   renormalised), `w_m = [m_p = m_q]`. `l` is recomputed from each iteration's `c`.
//! - The filtered visibility is the last iteration's `c`. At `p` itself `w = h(0)^2`, so
//!   a constant input is returned unchanged, and a pixel none of whose neighbours pass
//!   the edge stops keeps its value.

use glam::DVec3;
use rayon::prelude::*;

use super::{Kind, Reconstruction, Setting};
use crate::frame::{PrimaryLayers, luminance};

pub(crate) const SETTINGS: &[Setting] = &[
    Setting {
        key: "iterations",
        kind: Kind::Int { min: 1, max: 8 },
        default: 5.0,
        unit: "",
        doc: "a-trous passes, the n-th reading pixels 2^(n-1) apart (5: a 61-pixel footprint)",
        sweep: &[1.0, 2.0, 3.0, 4.0, 5.0],
    },
    Setting::new(
        "sigma_normal",
        Kind::closed(0.0, 1024.0),
        128.0,
        "",
        "exponent of the normal weight max(0, n_p . n_q)^sigma (0: normals ignored)",
    ),
    Setting::new(
        "sigma_depth",
        Kind::closed(0.0, 1e6),
        1.0,
        "",
        "depth weight: differences beyond this many times the depth gradient's stop the filter",
    ),
    Setting::new(
        "sigma_luminance",
        Kind::closed(0.0, 1e6),
        4.0,
        "",
        "luminance weight: differences beyond this many standard deviations stop the filter",
    ),
];

pub const RECONSTRUCTION: Reconstruction = Reconstruction {
    name: "atrous",
    summary: "edge-avoiding a-trous wavelet filter of the visibility ratio, guided by normal, \
              depth, material and variance (Dammertz et al. 2010; Schied et al. 2017, \
              section 4)",
    title: "a-trous filter",
    settings: SETTINGS,
    cpu: Some(filter),
    wgsl: Some((
        "shaders/reconstruction_atrous.wgsl",
        include_str!("../../shaders/reconstruction_atrous.wgsl"),
    )),
    gpu_passes: |values| values[0] as u32,
    reach: |values| reach(values[0] as u32),
    label: "RECONSTRUCTION(atrous)",
    temporal: false,
    wgsl_imports: &[ATROUS_WGSL],
};

/// `voxlab::atrous`: the passes on the device, which `svgf` runs too.
pub(crate) const ATROUS_WGSL: (&str, &str) = (
    "shaders/atrous.wgsl",
    include_str!("../../shaders/atrous.wgsl"),
);

/// Frames from which the variance is the frames' own, not the neighbourhood's (Schied
/// et al. 2017, section 4.2: four frames of history).
pub const TEMPORAL_FRAMES: u32 = 4;

/// The depth weight's floor, relative to the depth: differences below single-precision
/// rounding of the depth never stop the filter on a plane seen edge on.
const EPS_DEPTH: f64 = 1e-6;

/// The luminance weight's floor: where the variance is zero only equal values pass.
const EPS_LUMINANCE: f64 = 1e-10;

/// The variance floor, relative to the mean square: `m2 - m1^2` below it is rounding,
/// not spread, and counts as zero. In f32 the moments of equal values (a pixel lit in
/// every frame, the bilinear mixture of equal taps) leave a few units in the last place
/// of `m2`, about 1e-7 of it; under a large `sigma_luminance` that residue alone opened
/// the luminance weight on the device (`sigma_luminance = 1e5`: pixels 1.4/255 off the
/// f64 reference, whose residue is 1e-16). A real spread this small is a standard
/// deviation of 0.3 % of the values' root mean square.
pub const VARIANCE_FLOOR: f64 = 1e-5;

/// The variance of values of mean `m1` and mean square `m2`, zero below the floor.
pub(crate) fn moments_variance(m1: f64, m2: f64) -> f64 {
    let v = m2 - m1 * m1;
    if v > VARIANCE_FLOOR * m2 { v } else { 0.0 }
}

/// The B3 spline's taps.
const B3: [f64; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// How far a filtered pixel reads (pixels per axis) after `iterations` passes: the
/// spatial variance (3) and the depth gradients of its pixels (1), then per pass the
/// variance's Gaussian (1) and the taps (2 steps).
pub fn reach(iterations: u32) -> u32 {
    4 + iterations + 2 * ((1 << iterations) - 1)
}

/// The edge-stopping settings.
struct Sigmas {
    normal: f64,
    depth: f64,
    luminance: f64,
}

/// What the filter reads of a pixel, `None` where it reads nothing.
#[derive(Clone, Copy)]
struct Guide {
    normal: DVec3,
    depth: f64,
    material: u8,
    gradient: [f64; 2],
}

/// The visibility of every pixel of `layers`, filtered (module documentation);
/// `values` are the settings in declared order; it keeps no history.
pub fn filter(
    layers: &PrimaryLayers,
    values: &[f64],
    _history: &mut Option<crate::frame::History>,
) -> Vec<DVec3> {
    let visibility = layers.pixels.iter().map(|p| p.visibility()).collect();
    let frames = layers.frames.max(1) as f64;
    let variance = |k: usize| {
        let p = &layers.pixels[k];
        let temporal = (p.ratio_frames >= TEMPORAL_FRAMES).then(|| {
            let [m1, m2] = p.ratio_moments;
            moments_variance(m1, m2) / p.ratio_frames as f64
        });
        (temporal, frames)
    };
    filter_signal(layers, visibility, variance, &values[..4])
}

/// The a-trous passes over the signal `c` (a visibility per pixel of `layers`, which
/// guide them), for a reconstruction that prepares its own signal (svgf's temporal
/// accumulation): `variance(k)` gives pixel `k`'s temporal variance where it has one
/// (the variance of its mean) and the samples its value is a mean of (the spatial
/// estimate's divisor); `values` are the four settings of [`SETTINGS`], in order.
pub(crate) fn filter_signal(
    layers: &PrimaryLayers,
    mut c: Vec<DVec3>,
    variance: impl Fn(usize) -> (Option<f64>, f64) + Sync,
    values: &[f64],
) -> Vec<DVec3> {
    let (w, h) = (layers.width as i64, layers.height as i64);
    let iterations = values[0] as u32;
    let sigmas = Sigmas {
        normal: values[1],
        depth: values[2],
        luminance: values[3],
    };
    let at = |x: i64, y: i64| (y * w + x) as usize;
    // Every pixel's coordinates, rows from the top; each pass computes every pixel on
    // its own, so in parallel (the values do not depend on the threads).
    let pixels = || (0..w * h).into_par_iter().map(move |k| (k % w, k / w));
    let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h;
    let read = |x: i64, y: i64| inside(x, y) && layers.pixels[at(x, y)].filtered();

    // The guide: G-buffer and depth gradient of every pixel read.
    let guide: Vec<Option<Guide>> = pixels()
        .map(|(x, y)| {
            if !read(x, y) {
                return None;
            }
            let p = &layers.pixels[at(x, y)];
            let slope = |dx: i64, dy: i64| {
                [1, -1]
                    .into_iter()
                    .filter(|&s| read(x + s * dx, y + s * dy))
                    .map(|s| {
                        let q = &layers.pixels[at(x + s * dx, y + s * dy)];
                        (q.depth - p.depth) * s as f64
                    })
                    .min_by(|a, b| a.abs().total_cmp(&b.abs()))
                    .unwrap_or(0.0)
            };
            Some(Guide {
                normal: p.normal,
                depth: p.depth,
                material: p.material,
                gradient: [slope(1, 0), slope(0, 1)],
            })
        })
        .collect();

    // The edge stops of geometry between p and q = p + offset: w_z w_n w_m.
    let geometric = |p: &Guide, q: &Guide, offset: [i64; 2]| {
        if p.material != q.material {
            return 0.0;
        }
        let along = p.gradient[0] * offset[0] as f64 + p.gradient[1] * offset[1] as f64;
        let wz = (-(p.depth - q.depth).abs()
            / (sigmas.depth * along.abs() + EPS_DEPTH * p.depth.abs()).max(f64::MIN_POSITIVE))
        .exp();
        let wn = p.normal.dot(q.normal).max(0.0).powf(sigmas.normal);
        wz * wn
    };

    // The input's variance: temporal from enough frames, else spatial.
    let mut var: Vec<f64> = pixels()
        .map(|(x, y)| {
            let Some(g) = guide[at(x, y)] else {
                return 0.0;
            };
            let (temporal, samples) = variance(at(x, y));
            if let Some(v) = temporal {
                return v;
            }
            let (mut sw, mut s1, mut s2) = (0.0, 0.0, 0.0);
            for dy in -3..=3 {
                for dx in -3..=3 {
                    if !inside(x + dx, y + dy) {
                        continue;
                    }
                    let Some(q) = &guide[at(x + dx, y + dy)] else {
                        continue;
                    };
                    let wq = geometric(&g, q, [dx, dy]);
                    let l = luminance(c[at(x + dx, y + dy)]);
                    sw += wq;
                    s1 += wq * l;
                    s2 += wq * l * l;
                }
            }
            moments_variance(s1 / sw, s2 / sw) / samples
        })
        .collect();

    for i in 0..iterations {
        let step = 1i64 << i;
        // G(var): the variance's 3x3 Gaussian over the pixels read.
        let blurred: Vec<f64> = pixels()
            .map(|(x, y)| {
                if guide[at(x, y)].is_none() {
                    return 0.0;
                }
                let (mut sw, mut sv) = (0.0, 0.0);
                for dy in -1..=1i64 {
                    for dx in -1..=1i64 {
                        if read(x + dx, y + dy) {
                            let k = [0.25, 0.5, 0.25][(dx + 1) as usize]
                                * [0.25, 0.5, 0.25][(dy + 1) as usize];
                            sw += k;
                            sv += k * var[at(x + dx, y + dy)];
                        }
                    }
                }
                sv / sw
            })
            .collect();
        let next: Vec<(DVec3, f64)> = pixels()
            .map(|(x, y)| {
                let Some(g) = guide[at(x, y)] else {
                    return (c[at(x, y)], var[at(x, y)]);
                };
                let lp = luminance(c[at(x, y)]);
                let spread = sigmas.luminance * blurred[at(x, y)].sqrt() + EPS_LUMINANCE;
                let (mut sw, mut sc, mut sv) = (0.0, DVec3::ZERO, 0.0);
                for (ty, hy) in B3.iter().enumerate() {
                    for (tx, hx) in B3.iter().enumerate() {
                        let offset = [(tx as i64 - 2) * step, (ty as i64 - 2) * step];
                        let (qx, qy) = (x + offset[0], y + offset[1]);
                        if !read(qx, qy) {
                            continue;
                        }
                        let q = guide[at(qx, qy)].expect("read");
                        let cq = c[at(qx, qy)];
                        let wl = (-(lp - luminance(cq)).abs() / spread).exp();
                        let wq = hx * hy * geometric(&g, &q, offset) * wl;
                        sw += wq;
                        sc += wq * cq;
                        sv += wq * wq * var[at(qx, qy)];
                    }
                }
                // The centre's own weight, h(0)^2 > 0, keeps sw above zero.
                (sc / sw, sv / (sw * sw))
            })
            .collect();
        let (next_c, next_var): (Vec<DVec3>, Vec<f64>) = next.into_iter().unzip();
        c = next_c;
        var = next_var;
    }
    c
}
