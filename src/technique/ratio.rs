//! The ratio estimator of E. Heitz, S. Hill and M. McGuire, "Combining Analytic Direct
//! Illumination and Stochastic Shadows", I3D 2018: the unshadowed diffuse light of an
//! area light in closed form, times the stochastic ratio of shadowed to unshadowed
//! sampled light, `L = U (sum_k V_k f_k) / (sum_k f_k)` (their equation 4, per light).
//!
//! Contract (both tracers):
//! - A rectangle light of width and height > 0, with inverse-square falloff on: the
//!   samples `x_k` are the area model's (`sampling::light_sample`, the same stratified
//!   points), `V_k` the shadow transmittance from `q` to `x_k` under the experiment's
//!   transmittance model, and `f_k = max(n.l_k, 0) / max(d_k^2, d_min^2)` each sample's
//!   unshadowed diffuse weight. The diffuse light is `kd U R` with
//!   `U = (I c / A) n . F`, `F = int (x - p) / |x - p|^3 dA` over the part of the
//!   rectangle in front of the surface (the rectangle clipped by the tangent plane of
//!   `p`), and `R = sum V_k f_k / sum f_k` (the mean `V_k` when every `f_k` is 0). `F`
//!   in closed form for a convex polygon: its normal part `sign(h) Omega n_e` (`Omega`
//!   the solid angle, A. van Oosterom and J. Strackee, IEEE TBME 30(2), 1983, per fan
//!   triangle), its in-plane part `-sum_edges m_e ln((r_a + r_b + L) / (r_a + r_b - L))`
//!   (the divergence theorem on `grad 1/r`; `m_e` the edge's outward normal in the
//!   plane). voxlab's area light emits isotropically (no cosine at the emitter), so
//!   this is the field integral of the emitter, not Lambert's form factor; both are
//!   polygon formulas of the same kind. `d_min` (`falloff_min_distance`) is not in the
//!   closed form: it matters only within `d_min` of the light.
//! - A Lambertian rectangle (`emission = "lambertian"`, radiance `I / A` from its front):
//!   `f_k` takes the emitter's cosine too, `f_k = cos_e,k max(n.l_k, 0) / max(d_k^2,
//!   d_min^2)`, and so does each sample's specular term; `U = (I c / A) P`, with `P` the
//!   projected solid angle of the clipped rectangle, Lambert's polygon formula
//!   `P = 1/2 |sum_edges gamma_e n . (a x b) / |a x b||` (`gamma_e` the angle the edge
//!   `a b` subtends; J. Arvo, "The Irradiance Jacobian for Partially Occluded
//!   Polyhedral Sources", SIGGRAPH 1994, equation 9), 0 behind the light.
//! - A rectangle seen at under `SMALL_LIGHT` (size over distance) takes the samples'
//!   mean `sum f_k / N` for `U`, which makes it exactly the area model: a vanishing
//!   light reaches the hard shadow.
//! - The specular term stays sampled: `ks` Phong of each sample times `V_k`, averaged.
//! - Any other area light (disk, sphere, a rectangle of zero width or height, or every
//!   light with falloff off) is sampled exactly as the `area` model samples it; a point
//!   light, or an area light of size 0, is the hard shadow at its centre.
//!
//! Where nothing occludes (`V_k = 1`) the diffuse light is `U`, free of noise. `R` is a
//! ratio of two means, so the estimator is biased for a finite sample count and
//! consistent as `light_samples` grows (Heitz et al., section 3); averaging frames
//! (`spp`) does not remove the bias of each frame's ratio.

use glam::DVec3;

use super::{AblateCurve, CpuShadow, Knob, LightQuery, ShadowModel};
use crate::frame::RayStats;
use crate::sampling::light_sample;
use crate::scene::{AreaShape, Emission, Light};
use crate::technique::shading::shadow_transmittance;

pub const MODEL: ShadowModel = ShadowModel {
    name: "ratio",
    summary: "closed-form unshadowed diffuse light of rect lights times the sampled ratio of \
              shadowed to unshadowed light (Heitz, Hill and McGuire, I3D 2018)",
    title: "ratio estimator",
    settings: &[],
    stochastic: true,
    // As the area model's: it needs a light of non-zero size.
    plan: super::area::needs_area_light,
    wgsl: (
        "shaders/shadow_ratio.wgsl",
        include_str!("../../shaders/shadow_ratio.wgsl"),
    ),
    gpu_data: None,
    data_settings: &[],
    cpu: |_, _| Box::new(Ratio),
    ablate: &[AblateCurve {
        label: "ratio",
        knob: Knob::Spp,
        lights_as_points: false,
        about: "",
    }],
    describe: None,
    label: "SHADOW_MODEL(ratio)",
    switch: None,
    shared_settings: &["render.light_samples", "render.spp"],
    shadow_rays: true,
    pyramid: false,
};

struct Ratio;

impl CpuShadow for Ratio {
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3 {
        let (scene, s, m) = (at.scene, at.settings, at.material);
        let radiance = at.light.color() * at.light.intensity();
        // Rectangles with falloff in closed form; every other light as the area model
        // shades it (sampled, or at its centre).
        let rect = match at.light {
            Light::Area(a) if at.light.is_area() => match a.shape {
                AreaShape::Rect { width, height } if width > 0.0 && height > 0.0 && s.falloff => {
                    let (u, v, _) = a.frame();
                    Some((a, u * width, v * height))
                }
                _ => None,
            },
            _ => None,
        };
        let Some((a, axis_u, axis_v)) = rect else {
            return super::area::sampled(at, stats);
        };
        let count = s.light_samples.max(1);
        let sample = |k: u32| {
            let (u, v) = light_sample(s.seed, at.key.pixel, at.key.frame, at.index, k, count);
            a.sample_point(u, v)
        };
        let (mut shadowed, mut free, mut specular, mut visible) =
            (DVec3::ZERO, 0.0, DVec3::ZERO, DVec3::ZERO);
        for k in 0..count {
            let x = sample(k);
            stats.shadow += 1;
            let vis =
                shadow_transmittance(scene, &at.walk, s.features.transmittance, at.q, x, stats);
            let to = x - at.p;
            let dl = to.length();
            let l = if dl > 0.0 { to / dl } else { at.n };
            let e =
                at.light.emitted_towards(x, at.p) / (dl * dl).max(s.falloff_min_distance.powi(2));
            let nl = at.n.dot(l);
            let f = e * nl.max(0.0);
            let rd = (l - 2.0 * nl * at.n).dot(at.d);
            if nl > 0.0 && rd > 0.0 {
                specular += vis * e * m.ks * rd.powf(m.shininess);
            }
            shadowed += vis * f;
            free += f;
            visible += vis;
        }
        let ratio = if free > 0.0 {
            shadowed / free
        } else {
            visible / count as f64
        };
        // A light seen at under SMALL_LIGHT radians: its samples' mean is the integral
        // to that order, and the closed form loses its digits to cancellation.
        if (axis_u + axis_v).length() < SMALL_LIGHT * (a.position - at.p).length() {
            return radiance * (m.kd * shadowed + specular) / count as f64;
        }
        let area = axis_u.cross(axis_v).length();
        let corners = [
            a.position - 0.5 * axis_u - 0.5 * axis_v,
            a.position + 0.5 * axis_u - 0.5 * axis_v,
            a.position + 0.5 * axis_u + 0.5 * axis_v,
            a.position - 0.5 * axis_u + 0.5 * axis_v,
        ];
        let normal = axis_u.cross(axis_v).normalize();
        let irradiance = match a.emission {
            Emission::Isotropic => clipped_field(at.p, at.n, &corners, normal),
            Emission::Lambertian if normal.dot(at.p - a.position) > 0.0 => {
                projected_solid_angle(at.p, at.n, &corners)
            }
            Emission::Lambertian => 0.0,
        } / area;
        radiance * (m.kd * irradiance * ratio + specular / count as f64)
    }
}

/// Size over distance below which a rectangle light is shaded by its samples' mean
/// instead of the closed form: the edge terms cancel down to the light's solid angle,
/// and f32 (the kernel, which expands them about the light's centre to keep what it
/// can: shaders/shadow_ratio.wgsl) would lose the rest on a light this small, while the
/// samples' mean differs from the integral by the relative variation of `1/r^2` across
/// the light, ~1e-3.
pub const SMALL_LIGHT: f64 = 1e-3;

/// `n . int (x - p) / |x - p|^3 dA` over the convex polygon `corners` (counter-clockwise
/// about its unit normal `normal`) clipped to the half-space `n . (x - p) >= 0`: the
/// closed form of `int max(n . l, 0) / r^2 dA` (module documentation).
pub fn clipped_field(p: DVec3, n: DVec3, corners: &[DVec3], normal: DVec3) -> f64 {
    let poly = clip_to_hemisphere(p, n, corners);
    if poly.len() < 3 {
        return 0.0;
    }
    let h = normal.dot(poly[0]);
    let solid_angle: f64 = (1..poly.len() - 1)
        .map(|i| triangle_solid_angle(poly[0], poly[i], poly[i + 1]))
        .sum();
    let mut field = h.signum() * solid_angle * normal;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let edge = b - a;
        let len = edge.length();
        if len == 0.0 {
            continue;
        }
        let outward = edge.cross(normal) / len;
        field -= outward * edge_log(a, b, len);
    }
    n.dot(field)
}

/// The convex polygon `corners`, relative to `p`, clipped to `n . x >= 0`.
fn clip_to_hemisphere(p: DVec3, n: DVec3, corners: &[DVec3]) -> Vec<DVec3> {
    let relative: Vec<DVec3> = corners.iter().map(|&c| c - p).collect();
    crate::geometry::clip_convex(&relative, |a| n.dot(a))
}

/// `int cos_e max(n . l, 0) / r^2 dA` over the convex polygon `corners` as seen from `p`
/// with normal `n`: the projected solid angle of the polygon clipped to the
/// hemisphere of `n`, by Lambert's formula (module documentation). Either winding.
pub fn projected_solid_angle(p: DVec3, n: DVec3, corners: &[DVec3]) -> f64 {
    let poly = clip_to_hemisphere(p, n, corners);
    if poly.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0;
    for i in 0..poly.len() {
        let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
        let g = a.cross(b);
        let len = g.length();
        if len > 0.0 {
            sum += len.atan2(a.dot(b)) * n.dot(g) / len;
        }
    }
    0.5 * sum.abs()
}

/// `int ds / r` along the segment from `a` to `b` (relative to the point):
/// `ln((r_a + r_b + L) / (r_a + r_b - L))`, with `(r_a + r_b)^2 - L^2 = 2 (r_a r_b + a.b)`
/// so the denominator does not cancel away from the segment.
fn edge_log(a: DVec3, b: DVec3, len: f64) -> f64 {
    let (ra, rb) = (a.length(), b.length());
    let sum = ra + rb + len;
    let gap = (2.0 * (ra * rb + a.dot(b))).max(1e-300);
    2.0 * sum.ln() - gap.ln()
}

/// Solid angle of the triangle `a b c` seen from the origin (van Oosterom and Strackee).
fn triangle_solid_angle(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c)).abs();
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    2.0 * num.atan2(den)
}
