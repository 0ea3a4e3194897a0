//! Rectangle lights sampled uniformly in the solid angle they subtend: J. Ureña, M.
//! Fajardo and A. King, "An Area-Preserving Parametrization for Spherical Rectangles",
//! EGSR 2013 (CGF 32(4)), section 3 and its Algorithm 1. The area model samples a
//! rectangle uniformly in area; this one maps the same stratified `(s, t)` onto the
//! spherical rectangle the light covers as seen from the hit, so a light that is large
//! or close, where `1 / r^2` varies most across it, is sampled where it matters.
//!
//! Contract (both tracers):
//! - A rectangle light of width and height > 0, seen from the hit `p` at a size over
//!   distance of at least `SMALL_RECT` and from at least `EDGE_ON` times its size off
//!   its plane: the
//!   sample `x_k` is the point of the spherical rectangle for `(s, t) = light_sample(seed,
//!   pixel, frame, j, k, n)` (the area model's numbers), of density `1 / S` in solid
//!   angle (`S` the rectangle's solid angle), `d A / d omega = r^2 / |cos_e|`; so each
//!   sample is the area model's point term at `x_k` times `w_k = r_k^2 S / (A |cos_e,k|)
//!   = r_k^3 S / (A h)` (`h` the distance of `p` from the light's plane, `A` its area),
//!   and the light is `(1/n) sum_k w_k point(x_k)`: the same expectation as the area
//!   model (`tests/solid_angle.rs`). A Lambertian light's `cos_e` cancels, leaving
//!   `w_k cos_e = r_k^2 S / A`, bounded; an isotropic light keeps `1 / |cos_e|`, which
//!   grows without bound toward the light's plane: solid-angle sampling suits Lambertian
//!   lights (docs/experiments.md, the ablation).
//! - Every other light, a rectangle too small or too edge-on for the parametrization's
//!   arithmetic (its solid angle is a difference of angles near `2 pi`; in f32 it would
//!   lose its digits), or a point: the area model's estimate, on its code path.

use glam::DVec3;

use super::{AblateCurve, CpuShadow, Knob, LightQuery, ShadowModel};
use crate::frame::RayStats;
use crate::sampling::light_sample;
use crate::scene::{AreaShape, Light};

pub const MODEL: ShadowModel = ShadowModel {
    name: "solid-angle",
    summary: "rect lights sampled uniformly in the solid angle they subtend (Urena, Fajardo \
              and King, EGSR 2013); other lights as the area model samples them",
    title: "area lights, solid-angle sampled",
    settings: &[],
    stochastic: true,
    plan: super::area::needs_area_light,
    wgsl: (
        "shaders/shadow_solid_angle.wgsl",
        include_str!("../../shaders/shadow_solid_angle.wgsl"),
    ),
    gpu_data: None,
    data_settings: &[],
    cpu: |_, _| Box::new(SolidAngle),
    ablate: &[AblateCurve {
        label: "solid-angle",
        knob: Knob::Spp,
        lights_as_points: false,
        about: "rect lights sampled uniformly in solid angle: the area model's expectation, \
                another variance.",
    }],
    describe: None,
    label: "SHADOW_MODEL(solid-angle)",
    switch: None,
    shared_settings: &["render.light_samples", "render.spp"],
    shadow_rays: true,
    pyramid: false,
};

/// Size (diagonal) over distance below which a rectangle is sampled in area instead:
/// the parametrization's trigonometry is ill-conditioned for small solid angles (a
/// difference of angles near `2 pi`, and `cos(a_u) b_0 - b_1` cancelling), so in the
/// kernel's f32 its sample points drift from the f64 reference's as the light shrinks;
/// from this ratio up the GPU still draws the CPU's samples to the agreement tolerance
/// (`tests/solid_angle.rs`, `tests/shadow_models.rs`; at 0.03 it did not), and below
/// it `1 / r^2` varies by under ~30 % across the light, where solid-angle sampling
/// gains little.
pub const SMALL_RECT: f64 = 0.3;
/// Distance off the light's plane over its size below which a rectangle is sampled in
/// area instead: the spherical rectangle degenerates toward a great-circle arc there.
pub const EDGE_ON: f64 = 0.1;

/// A rectangle as seen from a point, set up for sampling (Urena et al. 2013, section 3:
/// the local frame with the rectangle at `z = z0 < 0`, its extent `[x0, x1] x [y0, y1]`,
/// and the spherical rectangle's solid angle `s`).
#[derive(Clone, Copy, Debug)]
pub struct SphericalRect {
    pub o: DVec3,
    pub x: DVec3,
    pub y: DVec3,
    pub z: DVec3,
    pub z0: f64,
    pub x0: f64,
    pub y0: f64,
    pub x1: f64,
    pub y1: f64,
    b0: f64,
    /// `1 - b0^2`, from `n0`'s in-plane components.
    b0_plane_sq: f64,
    b1: f64,
    k: f64,
    /// The solid angle.
    pub s: f64,
}

impl SphericalRect {
    /// The rectangle with corner `corner` and edges `ex`, `ey` (orthogonal) seen from
    /// `o`; `None` when `o` is in its plane or the solid angle is not positive.
    pub fn new(o: DVec3, corner: DVec3, ex: DVec3, ey: DVec3) -> Option<Self> {
        let (exl, eyl) = (ex.length(), ey.length());
        let (x, y) = (ex / exl, ey / eyl);
        let mut z = x.cross(y);
        let d = corner - o;
        let mut z0 = d.dot(z);
        if z0 > 0.0 {
            z = -z;
            z0 = -z0;
        }
        if z0 == 0.0 {
            return None;
        }
        let (x0, y0) = (d.dot(x), d.dot(y));
        let (x1, y1) = (x0 + exl, y0 + eyl);
        let v00 = DVec3::new(x0, y0, z0);
        let v01 = DVec3::new(x0, y1, z0);
        let v10 = DVec3::new(x1, y0, z0);
        let v11 = DVec3::new(x1, y1, z0);
        let n0 = v00.cross(v10).normalize();
        let n1 = v10.cross(v11).normalize();
        let n2 = v11.cross(v01).normalize();
        let n3 = v01.cross(v00).normalize();
        let angle = |a: DVec3, b: DVec3| (-a.dot(b)).clamp(-1.0, 1.0).acos();
        let (g0, g1, g2, g3) = (angle(n0, n1), angle(n1, n2), angle(n2, n3), angle(n3, n0));
        let k = std::f64::consts::TAU - g2 - g3;
        let s = g0 + g1 - k;
        (s > 0.0).then_some(Self {
            o,
            x,
            y,
            z,
            z0,
            x0,
            y0,
            x1,
            y1,
            b0: n0.z,
            b0_plane_sq: n0.x * n0.x + n0.y * n0.y,
            b1: n2.z,
            k,
            s,
        })
    }

    /// The point for `(u, v)` in [0, 1)^2, uniform in solid angle (Algorithm 1).
    pub fn sample(&self, u: f64, v: f64) -> DVec3 {
        let au = u * self.s + self.k;
        let fu = (au.cos() * self.b0 - self.b1) / au.sin();
        // The paper's cu = sign(fu) / sqrt(fu^2 + b0^2) and xu = -cu z0 / sqrt(1 - cu^2),
        // with 1 - cu^2 written out: xu = -sign(fu) z0 / sqrt(fu^2 - (1 - b0^2)), and
        // 1 - b0^2 as n0.x^2 + n0.y^2, which does not cancel where cu is near +-1.
        let q = (fu * fu - self.b0_plane_sq).max(0.0).sqrt();
        let xu = (-self.z0 / q).copysign(fu).clamp(self.x0, self.x1);
        let d = (xu * xu + self.z0 * self.z0).sqrt();
        let h0 = self.y0 / (d * d + self.y0 * self.y0).sqrt();
        let h1 = self.y1 / (d * d + self.y1 * self.y1).sqrt();
        let hv = h0 + v * (h1 - h0);
        let hv2 = hv * hv;
        let yv = if hv2 < 1.0 - 1e-6 {
            hv * d / (1.0 - hv2).sqrt()
        } else {
            self.y1
        };
        self.o + xu * self.x + yv * self.y + self.z0 * self.z
    }
}

/// The spherical rectangle of a rect light seen from `p`, when the contract samples it
/// in solid angle: its corner at `-u w / 2 - v h / 2` from the centre, edges `u w`, `v h`.
pub(crate) fn of_light(light: &Light, p: DVec3) -> Option<(SphericalRect, f64)> {
    let Light::Area(a) = light else { return None };
    let AreaShape::Rect { width, height } = a.shape else {
        return None;
    };
    if !(width > 0.0 && height > 0.0) {
        return None;
    }
    let (u, v, n) = a.frame();
    let (ex, ey) = (u * width, v * height);
    let size = (ex + ey).length();
    if size < SMALL_RECT * (a.position - p).length() || n.dot(p - a.position).abs() < EDGE_ON * size
    {
        return None;
    }
    let r = SphericalRect::new(p, a.position - 0.5 * ex - 0.5 * ey, ex, ey)?;
    Some((r, width * height))
}

struct SolidAngle;

impl CpuShadow for SolidAngle {
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3 {
        let Some((rect, area)) = of_light(at.light, at.p) else {
            return super::area::sampled(at, stats);
        };
        let s = at.settings;
        let count = s.light_samples.max(1);
        let h = -rect.z0;
        let mut sum = DVec3::ZERO;
        for k in 0..count {
            let (u, v) = light_sample(s.seed, at.key.pixel, at.key.frame, at.index, k, count);
            let x = rect.sample(u, v);
            let r = (x - at.p).length();
            let w = r * r * r * rect.s / (area * h);
            sum += crate::technique::shading::point_contribution(
                at.scene,
                &at.walk,
                s,
                at.material,
                at.q,
                at.p,
                at.n,
                at.d,
                x,
                at.light.radiance_towards(x, at.p) * w,
                stats,
            );
        }
        sum / count as f64
    }
}
