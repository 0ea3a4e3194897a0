//! LDR-FLIP on floating-point sRGB values: P. Andersson, J. Nilsson, T. Akenine-Möller,
//! M. Oskarsson, K. Åström and M. D. Fairchild, "FLIP: A Difference Evaluator for
//! Alternating Images", Proc. ACM Comput. Graph. Interact. Tech. 3(2), 2020.
//!
//! NVIDIA's implementation (through `nv-flip`) takes 8-bit images; quantising a
//! rendered image to 8 bits before measuring it adds an error of its own, which raises
//! small FLIP values (5-12 % at 4-16 spp on the seed scene). This is the same
//! computation, step for step and in `f32` like the reference C++ (`FLIP::image::FLIP`
//! of flip 1.2 as nv-flip-sys 0.1.1 ships it), on the unquantised display values.
//! `tests/flip.rs` holds it to `nv-flip` on 8-bit inputs.
//!
//! Ported from the C++ reference, whose notice follows.
//!
//! Copyright (c) 2020-2022, NVIDIA CORPORATION & AFFILIATES. All rights reserved.
//!
//! Redistribution and use in source and binary forms, with or without modification,
//! are permitted provided that the following conditions are met:
//!
//! 1. Redistributions of source code must retain the above copyright notice, this list
//!    of conditions and the following disclaimer.
//! 2. Redistributions in binary form must reproduce the above copyright notice, this
//!    list of conditions and the following disclaimer in the documentation and/or
//!    other materials provided with the distribution.
//! 3. Neither the name of the copyright holder nor the names of its contributors may be
//!    used to endorse or promote products derived from this software without specific
//!    prior written permission.
//!
//! THIS SOFTWARE IS PROVIDED BY THE COPYRIGHT HOLDERS AND CONTRIBUTORS "AS IS" AND ANY
//! EXPRESS OR IMPLIED WARRANTIES, INCLUDING, BUT NOT LIMITED TO, THE IMPLIED WARRANTIES
//! OF MERCHANTABILITY AND FITNESS FOR A PARTICULAR PURPOSE ARE DISCLAIMED. IN NO EVENT
//! SHALL THE COPYRIGHT HOLDER OR CONTRIBUTORS BE LIABLE FOR ANY DIRECT, INDIRECT,
//! INCIDENTAL, SPECIAL, EXEMPLARY, OR CONSEQUENTIAL DAMAGES (INCLUDING, BUT NOT LIMITED
//! TO, PROCUREMENT OF SUBSTITUTE GOODS OR SERVICES; LOSS OF USE, DATA, OR PROFITS; OR
//! BUSINESS INTERRUPTION) HOWEVER CAUSED AND ON ANY THEORY OF LIABILITY, WHETHER IN
//! CONTRACT, STRICT LIABILITY, OR TORT (INCLUDING NEGLIGENCE OR OTHERWISE) ARISING IN
//! ANY WAY OUT OF THE USE OF THIS SOFTWARE, EVEN IF ADVISED OF THE POSSIBILITY OF SUCH
//! DAMAGE.
//!
//! SPDX-License-Identifier: BSD-3-Clause

use std::f32::consts::PI;

type C3 = [f32; 3];

// The paper's constants (`FLIPConstants`, `GaussianConstants` of sharedflip.h).
const GQC: f32 = 0.7;
const GPC: f32 = 0.4;
const GPT: f32 = 0.95;
const GW: f32 = 0.082;
const GQF: f32 = 0.5;
const A1: C3 = [1.0, 1.0, 34.1];
const B1: C3 = [0.0047, 0.0053, 0.04];
const A2: C3 = [0.0, 0.0, 13.5];
const B2: C3 = [1.0e-5, 1.0e-5, 0.025];

/// D65, and its inverse, as the reference writes them (its literals, so the same f32).
#[allow(clippy::excessive_precision)]
const ILLUMINANT: C3 = [0.950428545, 1.000000000, 1.088900371];
#[allow(clippy::excessive_precision)]
const INV_ILLUMINANT: C3 = [1.052156925, 1.000000000, 0.918357670];

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_rgb_to_xyz(c: C3) -> C3 {
    let a11 = 10135552.0f32 / 24577794.0;
    let a12 = 8788810.0f32 / 24577794.0;
    let a13 = 4435075.0f32 / 24577794.0;
    let a21 = 2613072.0f32 / 12288897.0;
    let a22 = 8788810.0f32 / 12288897.0;
    let a23 = 887015.0f32 / 12288897.0;
    let a31 = 1425312.0f32 / 73733382.0;
    let a32 = 8788810.0f32 / 73733382.0;
    let a33 = 70074185.0f32 / 73733382.0;
    [
        a11 * c[0] + a12 * c[1] + a13 * c[2],
        a21 * c[0] + a22 * c[1] + a23 * c[2],
        a31 * c[0] + a32 * c[1] + a33 * c[2],
    ]
}

#[allow(clippy::excessive_precision)]
fn xyz_to_linear_rgb(c: C3) -> C3 {
    let (a11, a12, a13) = (3.241003275f32, -1.537398934f32, -0.498615861f32);
    let (a21, a22, a23) = (-0.969224334f32, 1.875930071f32, 0.041554224f32);
    let (a31, a32, a33) = (0.055639423f32, -0.204011202f32, 1.057148933f32);
    [
        a11 * c[0] + a12 * c[1] + a13 * c[2],
        a21 * c[0] + a22 * c[1] + a23 * c[2],
        a31 * c[0] + a32 * c[1] + a33 * c[2],
    ]
}

fn mul(a: C3, b: C3) -> C3 {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

fn xyz_to_ycxcz(c: C3) -> C3 {
    let c = mul(c, INV_ILLUMINANT);
    [
        116.0 * c[1] - 16.0,
        500.0 * (c[0] - c[1]),
        200.0 * (c[1] - c[2]),
    ]
}

fn ycxcz_to_xyz(c: C3) -> C3 {
    let y = (c[0] + 16.0) / 116.0;
    let cx = c[1] / 500.0;
    let cz = c[2] / 200.0;
    mul([y + cx, y, y - cz], ILLUMINANT)
}

fn xyz_to_lab(c: C3) -> C3 {
    let delta = 6.0f32 / 29.0;
    let delta_square = delta * delta;
    let delta_cube = delta * delta_square;
    let factor = 1.0 / (3.0 * delta_square);
    let term = 4.0f32 / 29.0;
    let c = mul(c, INV_ILLUMINANT);
    let f = |v: f32| {
        if v > delta_cube {
            v.powf(1.0 / 3.0)
        } else {
            factor * v + term
        }
    };
    let (x, y, z) = (f(c[0]), f(c[1]), f(c[2]));
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

fn hunt(luminance: f32, chrominance: f32) -> f32 {
    0.01 * luminance * chrominance
}

fn hyab(a: C3, b: C3) -> f32 {
    (a[0] - b[0]).abs() + ((a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2])).sqrt()
}

fn hunt_lab(lab: C3) -> C3 {
    [lab[0], hunt(lab[0], lab[1]), hunt(lab[0], lab[2])]
}

fn max_distance() -> f32 {
    let green = hunt_lab(xyz_to_lab(linear_rgb_to_xyz([0.0, 1.0, 0.0])));
    let blue = hunt_lab(xyz_to_lab(linear_rgb_to_xyz([0.0, 0.0, 1.0])));
    hyab(green, blue).powf(GQC)
}

fn gaussian_ab(x2: f32, a: f32, b: f32) -> f32 {
    a * (PI / b).sqrt() * (-(PI * PI) * x2 / b).exp()
}

fn gaussian_sqrt(x2: f32, a: f32, b: f32) -> f32 {
    (a * (PI / b).sqrt()).sqrt() * (-(PI * PI) * x2 / b).exp()
}

fn gaussian(x: f32, sigma: f32) -> f32 {
    (-(x * x) / (2.0 * sigma * sigma)).exp()
}

fn spatial_radius(ppd: f32) -> i32 {
    let max_scale = B1[0].max(B1[1]).max(B1[2].max(B2[0])).max(B2[1].max(B2[2]));
    (3.0 * (max_scale / (2.0 * PI * PI)).sqrt() * ppd).ceil() as i32
}

/// The separated CSF filters: (Y, Cx) weights and the two Cz Gaussians.
fn spatial_filters(ppd: f32) -> (Vec<[f32; 2]>, Vec<[f32; 2]>) {
    let r = spatial_radius(ppd);
    let dx = 1.0 / ppd;
    let mut ycx = Vec::new();
    let mut cz = Vec::new();
    let (mut sum_ycx, mut sum_cz) = ([0.0f32; 2], [0.0f32; 2]);
    for x in 0..(2 * r + 1) {
        let ix = (x - r) as f32 * dx;
        let ix2 = ix * ix;
        let v = [
            gaussian_ab(ix2, A1[0], B1[0]),
            gaussian_ab(ix2, A1[1], B1[1]),
        ];
        let w = [
            gaussian_sqrt(ix2, A1[2], B1[2]),
            gaussian_sqrt(ix2, A2[2], B2[2]),
        ];
        sum_ycx = [sum_ycx[0] + v[0], sum_ycx[1] + v[1]];
        sum_cz = [sum_cz[0] + w[0], sum_cz[1] + w[1]];
        ycx.push(v);
        cz.push(w);
    }
    let norm_ycx = [1.0 / sum_ycx[0], 1.0 / sum_ycx[1]];
    let norm_cz = 1.0 / (sum_cz[0] * sum_cz[0] + sum_cz[1] * sum_cz[1]).sqrt();
    for v in &mut ycx {
        *v = [v[0] * norm_ycx[0], v[1] * norm_ycx[1]];
    }
    for w in &mut cz {
        *w = [w[0] * norm_cz, w[1] * norm_cz];
    }
    (ycx, cz)
}

/// The edge and point detectors: Gaussian, its first and its second derivative.
fn feature_filter(ppd: f32) -> Vec<C3> {
    let sd = 0.5 * GW * ppd;
    let r = (3.0 * sd).ceil() as i32;
    let mut f = Vec::new();
    let (mut g_sum, mut dg_neg, mut dg_pos, mut ddg_neg, mut ddg_pos) =
        (0.0f32, 0.0, 0.0, 0.0, 0.0);
    for x in 0..(2 * r + 1) {
        let xx = (x - r) as f32;
        let g = gaussian(xx, sd);
        g_sum += g;
        let dg = -xx * g;
        if dg > 0.0 {
            dg_pos += dg;
        } else {
            dg_neg -= dg;
        }
        let ddg = (xx * xx / (sd * sd) - 1.0) * g;
        if ddg > 0.0 {
            ddg_pos += ddg;
        } else {
            ddg_neg -= ddg;
        }
        f.push([g, dg, ddg]);
    }
    for p in &mut f {
        *p = [
            p[0] / g_sum,
            p[1] / if p[1] > 0.0 { dg_pos } else { dg_neg },
            p[2] / if p[2] > 0.0 { ddg_pos } else { ddg_neg },
        ];
    }
    f
}

/// The FLIP error map of `test` against `reference`, both `w` x `h` sRGB-encoded values
/// in [0, 1] (row-major), at `ppd` pixels per degree.
pub fn flip_map(reference: &[C3], test: &[C3], w: usize, h: usize, ppd: f32) -> Vec<f32> {
    assert_eq!(reference.len(), w * h);
    assert_eq!(test.len(), w * h);
    let to_ycxcz = |img: &[C3]| -> Vec<C3> {
        img.iter()
            .map(|c| {
                xyz_to_ycxcz(linear_rgb_to_xyz([
                    srgb_to_linear(c[0]),
                    srgb_to_linear(c[1]),
                    srgb_to_linear(c[2]),
                ]))
            })
            .collect()
    };
    let (r, t) = (to_ycxcz(reference), to_ycxcz(test));
    let colour = colour_difference(&r, &t, w, h, ppd);
    feature_difference_and_error(&r, &t, colour, w, h, ppd)
}

fn clamp_index(i: i32, n: usize) -> usize {
    i.clamp(0, n as i32 - 1) as usize
}

fn colour_difference(r: &[C3], t: &[C3], w: usize, h: usize, ppd: f32) -> Vec<f32> {
    let cmax = max_distance();
    let pccmax = GPC * cmax;
    let (ycx, cz) = spatial_filters(ppd);
    let half = (ycx.len() / 2) as i32;
    // Filter in x: (Y, Cx) and the two Cz Gaussians, for both images.
    let mut inter = vec![[[0.0f32; 2]; 4]; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [[0.0f32; 2]; 4];
            for ix in -half..=half {
                let xx = clamp_index(x as i32 + ix, w);
                let wy = ycx[(ix + half) as usize];
                let wz = cz[(ix + half) as usize];
                let (rc, tc) = (r[y * w + xx], t[y * w + xx]);
                acc[0] = [acc[0][0] + wy[0] * rc[0], acc[0][1] + wy[1] * rc[1]];
                acc[1] = [acc[1][0] + wy[0] * tc[0], acc[1][1] + wy[1] * tc[1]];
                acc[2] = [acc[2][0] + wz[0] * rc[2], acc[2][1] + wz[1] * rc[2]];
                acc[3] = [acc[3][0] + wz[0] * tc[2], acc[3][1] + wz[1] * tc[2]];
            }
            inter[y * w + x] = acc;
        }
    }
    let mut out = vec![0.0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [[0.0f32; 2]; 4];
            for iy in -half..=half {
                let yy = clamp_index(y as i32 + iy, h);
                let wy = ycx[(iy + half) as usize];
                let wz = cz[(iy + half) as usize];
                let i = inter[yy * w + x];
                acc[0] = [acc[0][0] + wy[0] * i[0][0], acc[0][1] + wy[1] * i[0][1]];
                acc[1] = [acc[1][0] + wy[0] * i[1][0], acc[1][1] + wy[1] * i[1][1]];
                acc[2] = [acc[2][0] + wz[0] * i[2][0], acc[2][1] + wz[1] * i[2][1]];
                acc[3] = [acc[3][0] + wz[0] * i[3][0], acc[3][1] + wz[1] * i[3][1]];
            }
            let lab = |ycx: [f32; 2], cz: [f32; 2]| {
                let rgb = xyz_to_linear_rgb(ycxcz_to_xyz([ycx[0], ycx[1], cz[0] + cz[1]]));
                let rgb = rgb.map(|v| v.clamp(0.0, 1.0));
                hunt_lab(xyz_to_lab(linear_rgb_to_xyz(rgb)))
            };
            let d = hyab(lab(acc[0], acc[2]), lab(acc[1], acc[3])).powf(GQC);
            // Errors below pccmax map to [0, gpt], the rest to (gpt, 1].
            out[y * w + x] = if d < pccmax {
                d * (GPT / pccmax)
            } else {
                GPT + ((d - pccmax) / (cmax - pccmax)) * (1.0 - GPT)
            };
        }
    }
    out
}

fn feature_difference_and_error(
    r: &[C3],
    t: &[C3],
    mut colour: Vec<f32>,
    w: usize,
    h: usize,
    ppd: f32,
) -> Vec<f32> {
    let norm = 1.0 / 2.0f32.sqrt();
    let f = feature_filter(ppd);
    let half = (f.len() / 2) as i32;
    let (one_over_116, sixteen_over_116) = (1.0f32 / 116.0, 16.0f32 / 116.0);
    // In x: first and second derivative, and the Gaussian for the y pass.
    let mut inter = vec![[[0.0f32; 3]; 2]; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [[0.0f32; 3]; 2];
            for ix in -half..=half {
                let xx = clamp_index(x as i32 + ix, w);
                let k = f[(ix + half) as usize];
                for (a, img) in acc.iter_mut().zip([r, t]) {
                    let v = img[y * w + xx][0] * one_over_116 + sixteen_over_116;
                    a[0] += k[1] * v;
                    a[1] += k[2] * v;
                    a[2] += k[0] * v;
                }
            }
            inter[y * w + x] = acc;
        }
    }
    for y in 0..h {
        for x in 0..w {
            // dx, ddx, dy, ddy per image.
            let mut acc = [[0.0f32; 4]; 2];
            for iy in -half..=half {
                let yy = clamp_index(y as i32 + iy, h);
                let k = f[(iy + half) as usize];
                for (a, i) in acc.iter_mut().zip(inter[yy * w + x]) {
                    a[0] += k[0] * i[0];
                    a[1] += k[0] * i[1];
                    a[2] += k[1] * i[2];
                    a[3] += k[2] * i[2];
                }
            }
            let edge = |a: [f32; 4]| (a[0] * a[0] + a[2] * a[2]).sqrt();
            let point = |a: [f32; 4]| (a[1] * a[1] + a[3] * a[3]).sqrt();
            let edge_diff = (edge(acc[0]) - edge(acc[1])).abs();
            let point_diff = (point(acc[0]) - point(acc[1])).abs();
            let feature = (norm * edge_diff.max(point_diff)).powf(GQF);
            let c = &mut colour[y * w + x];
            *c = c.powf(1.0 - feature);
        }
    }
    colour
}
