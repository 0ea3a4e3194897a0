//! Reconstruction `svgf`: spatiotemporal variance-guided filtering (C. Schied et al.,
//! "Spatiotemporal Variance-Guided Filtering: Real-Time Reconstruction for Path-Traced
//! Global Illumination", HPG 2017): the visibility ratio of the primary hit's local light
//! (Heitz, Hill and McGuire, I3D 2018) is accumulated over the frames of a camera path
//! (`[render] path_frames`), reprojected from frame to frame with the disoccluded
//! history rejected, its variance estimated from the accumulated moments, and then
//! filtered by the a-trous passes of [`super::atrous`].
//!
//! Contract (the f64 reference; `shaders/reconstruction_svgf.wgsl` is its f32 twin):
//! - Input at a pixel `p` that `PrimaryPixel::filtered` accepts: its visibility `c_p`,
//!   `l_p = lum(c_p)`, G-buffer `n_p`, `z_p`, `m_p`, and its hit
//!   `x_p = eye + z_p d_p` (`PrimaryLayers::position`: `d_p` through the pixel centre).
//! - Reprojection into the previous frame's history `H` (camera `eye'`, `forward'`,
//!   `right'`, `up'`, `t' = tan(vfov'/2)`; same image size, else no history): with
//!   `v = x_p - eye'` and `f = v . forward' > 0`, `sx = v . right' / (f t' aspect)`,
//!   `sy = v . up' / (f t')`, the continuous pixel `u = (sx + 1) w / 2 - 1/2`,
//!   `t = (1 - sy) h / 2 - 1/2`. Its four bilinear taps `q` (weights
//!   `(1 - fu | fu) (1 - ft | ft)`) are read when inside the image, kept by `H`, of the
//!   same material, `n_p . n_q >= normal_tolerance` and
//!   `|(x_p - x_q) . n_q| <= depth_tolerance z_q` (the hit on the tap's tangent plane;
//!   `x_q` from `H`'s camera and the tap's centre ray). With the read weights' sum `W >=`
//!   [`MIN_HISTORY_WEIGHT`], the history is their normalised mixture of accumulated
//!   visibility `C`, moments `M` and length `n`; otherwise there is none (a
//!   disocclusion: the history restarts). The length is mixed about the first read
//!   tap's `n_0`, as `n_0 + sum w_q (n_q - n_0) / W`: the same mixture, but exactly
//!   `n_0` where the taps' lengths are equal, in f32 as in f64. Summed plainly, taps of
//!   length 3 mixed to 2.9999999 in one precision and 3 in the other, and the variance
//!   below switched at `TEMPORAL_FRAMES` on 2.5 % of the pixels of a path's fourth
//!   frame on one tracer and not the other.
//! - Accumulation: with history, `n' = n + 1`, `a = max(alpha, 1 / n')`,
//!   `c' = C + a (c_p - C)`, `M' = M + a ([l_p, l_p^2] - M)`; without, `c' = c_p`,
//!   `M' = [l_p, l_p^2]`, `n' = 1`. With `alpha = 0` a static camera's `c'` is the mean
//!   of the path's frames. The new history is `c'`, `M'`, `n'` and the G-buffer: the
//!   accumulated signal, not the first a-trous level's output that Schied et al. feed
//!   back, so that what accumulates is the unbiased mean of the frames.
//! - Variance: with `N = min(n', (2 - alpha) / alpha)` (the samples an exponential
//!   moving average of weight `alpha` is worth; `n'` for `alpha = 0`), from
//!   `N >= atrous::TEMPORAL_FRAMES` the temporal `(M'_2 - M'_1^2) / N` (zero at most
//!   `atrous::VARIANCE_FLOOR` `M'_2`); before, the
//!   spatial estimate of the a-trous filter over the accumulated signal (not divided:
//!   the accumulated values are the estimates whose spread it measures).
//! - Then the a-trous passes of [`super::atrous`] (its contract) over `c'`, with this
//!   reconstruction's first four settings. Without history (one frame, or a path's
//!   first) the result is `atrous`'s at one frame.

use glam::DVec3;
use rayon::prelude::*;

use super::{Kind, Reconstruction, Setting, atrous};
use crate::frame::{History, HistoryPixel, PrimaryLayers, luminance};

const SETTINGS: &[Setting] = &[
    atrous::SETTINGS[0],
    atrous::SETTINGS[1],
    atrous::SETTINGS[2],
    atrous::SETTINGS[3],
    Setting::new(
        "alpha",
        Kind::closed(0.0, 1.0),
        0.2,
        "",
        "least weight of a new frame in the temporal accumulation (Schied et al.: 0.2; 0: the mean of the path's frames)",
    ),
    // Bounded away from the values where single precision decides otherwise than f64
    // (a tolerance below f32's rounding of a reprojected point, a cosine of exactly 1):
    // there the device and the reference would reject different taps.
    Setting::new(
        "depth_tolerance",
        Kind::closed(1e-4, 1.0),
        0.005,
        "of the depth",
        "history is rejected where the hit lies farther than this from the tap's tangent plane",
    ),
    Setting::new(
        "normal_tolerance",
        Kind::closed(-1.0, 0.9999),
        0.9,
        "cosine",
        "history is rejected where the normals' cosine is below this",
    ),
];

pub const RECONSTRUCTION: Reconstruction = Reconstruction {
    name: "svgf",
    summary: "spatiotemporal variance-guided filter: the visibility ratio accumulated over a \
              camera path with reprojection and disocclusion rejection, then the a-trous \
              passes (Schied et al. 2017)",
    title: "SVGF (temporal + a-trous)",
    settings: SETTINGS,
    cpu: Some(filter),
    wgsl: Some((
        "shaders/reconstruction_svgf.wgsl",
        include_str!("../../shaders/reconstruction_svgf.wgsl"),
    )),
    wgsl_imports: &[atrous::ATROUS_WGSL],
    // The temporal accumulation, the a-trous preparation, then its passes.
    gpu_passes: |values| values[0] as u32 + 1,
    // The history may come from anywhere in the image.
    reach: |_| u32::MAX,
    label: "RECONSTRUCTION(svgf)",
    temporal: true,
};

/// The least sum of the read taps' bilinear weights for the history to be used
/// (Schied et al.'s reference code: 0.01).
pub const MIN_HISTORY_WEIGHT: f64 = 0.01;

/// The history at pixel (x, y) of `layers`, reprojected from `h` (module
/// documentation): accumulated visibility, moments and length, or `None`.
fn reproject(
    h: &History,
    layers: &PrimaryLayers,
    x: u32,
    y: u32,
    depth_tolerance: f64,
    normal_tolerance: f64,
) -> Option<(DVec3, [f64; 2], f64)> {
    let p = layers.get(x, y);
    let position = layers.position(x, y);
    let cam = &h.camera;
    let (w, hh) = (h.width as f64, h.height as f64);
    let v = position - cam.eye;
    let f = v.dot(cam.forward);
    if f.is_nan() || f <= 0.0 {
        return None;
    }
    let sx = v.dot(cam.right) / (f * cam.tan_half_vfov * (w / hh));
    let sy = v.dot(cam.up) / (f * cam.tan_half_vfov);
    let u = (sx + 1.0) * 0.5 * w - 0.5;
    let t = (1.0 - sy) * 0.5 * hh - 0.5;
    if !u.is_finite() || !t.is_finite() {
        return None;
    }
    let (u0, t0) = (u.floor(), t.floor());
    let (fu, ft) = (u - u0, t - t0);
    let (mut sw, mut sc, mut sm, mut sn) = (0.0, DVec3::ZERO, [0.0; 2], 0.0);
    // The lengths are mixed about the first read tap's (module documentation).
    let mut base = None;
    for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        let (qx, qy) = (u0 + dx, t0 + dy);
        if qx < 0.0 || qy < 0.0 || qx >= w || qy >= hh {
            continue;
        }
        let (qx, qy) = (qx as u32, qy as u32);
        let q = &h.pixels[(qy * h.width + qx) as usize];
        if !q.kept || q.material != p.material || p.normal.dot(q.normal) < normal_tolerance {
            continue;
        }
        let xq = cam.eye + q.depth * cam.primary_dir(qx, qy, h.width, h.height);
        if (position - xq).dot(q.normal).abs() > depth_tolerance * q.depth {
            continue;
        }
        let weight =
            (if dx > 0.0 { fu } else { 1.0 - fu }) * (if dy > 0.0 { ft } else { 1.0 - ft });
        sw += weight;
        sc += weight * q.visibility;
        sm[0] += weight * q.moments[0];
        sm[1] += weight * q.moments[1];
        let n0 = *base.get_or_insert(q.length);
        sn += weight * (q.length - n0);
    }
    let n0 = base.unwrap_or(0.0);
    (sw >= MIN_HISTORY_WEIGHT).then(|| (sc / sw, [sm[0] / sw, sm[1] / sw], n0 + sn / sw))
}

/// The temporal accumulation of `layers` onto `previous` (module documentation): the
/// new history, one pixel per pixel of `layers`.
pub fn accumulate(layers: &PrimaryLayers, previous: Option<&History>, values: &[f64]) -> History {
    let (alpha, depth_tolerance, normal_tolerance) = (values[4], values[5], values[6]);
    let previous = previous.filter(|h| h.width == layers.width && h.height == layers.height);
    let w = layers.width;
    let pixels = (0..layers.pixels.len())
        .into_par_iter()
        .map(|k| {
            let p = &layers.pixels[k];
            if !p.filtered() {
                return HistoryPixel::default();
            }
            let (x, y) = (k as u32 % w, k as u32 / w);
            let c = p.visibility();
            let l = luminance(c);
            let history = previous
                .and_then(|h| reproject(h, layers, x, y, depth_tolerance, normal_tolerance));
            let (visibility, moments, length) = match history {
                None => (c, [l, l * l], 1.0),
                Some((hc, hm, hn)) => {
                    let n = hn + 1.0;
                    let a = alpha.max(1.0 / n);
                    (
                        hc + a * (c - hc),
                        [hm[0] + a * (l - hm[0]), hm[1] + a * (l * l - hm[1])],
                        n,
                    )
                }
            };
            HistoryPixel {
                kept: true,
                normal: p.normal,
                depth: p.depth,
                material: p.material,
                visibility,
                moments,
                length,
            }
        })
        .collect();
    History {
        width: layers.width,
        height: layers.height,
        camera: layers.camera,
        pixels,
    }
}

/// The samples an accumulation of `length` frames with least weight `alpha` is worth
/// (module documentation).
pub fn effective_samples(length: f64, alpha: f64) -> f64 {
    if alpha > 0.0 {
        length.min((2.0 - alpha) / alpha)
    } else {
        length
    }
}

/// Every pixel's visibility, accumulated onto `history` and filtered (module
/// documentation); `history` becomes this frame's.
pub fn filter(layers: &PrimaryLayers, values: &[f64], history: &mut Option<History>) -> Vec<DVec3> {
    let accumulated = accumulate(layers, history.as_ref(), values);
    let alpha = values[4];
    let signal = accumulated.pixels.iter().map(|h| h.visibility).collect();
    let variance = |k: usize| {
        let h = &accumulated.pixels[k];
        let n = effective_samples(h.length, alpha);
        let [m1, m2] = h.moments;
        let temporal =
            (n >= atrous::TEMPORAL_FRAMES as f64).then(|| atrous::moments_variance(m1, m2) / n);
        (temporal, 1.0)
    };
    let out = atrous::filter_signal(layers, signal, variance, &values[..4]);
    *history = Some(accumulated);
    out
}
