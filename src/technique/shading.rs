//! The terms the shadow models build on, shared by the CPU reference and the techniques'
//! own f64 code: Phong with inverse-square falloff of one point emitter (contract:
//! "Shading a hit"), and the transmittance of a shadow segment through the voxels or
//! the triangle surfaces under the transmittance slot's model.

use glam::DVec3;

use crate::dda::Dda;
use crate::frame::RayStats;
use crate::render::{RenderSettings, Transmittance};
use crate::scene::{Material, Scene};
use crate::sparse::Regions;
use crate::triangles::Absorber;
use crate::triangles::SurfaceTrace;

/// How a shadow segment walks the scene: through the sparse tree and the triangle
/// surfaces when they are planned, starting in `medium` (the material at its start,
/// which only the triangle walk needs: the voxel walk reads it from the grid).
#[derive(Clone, Copy, Default)]
pub struct ShadowWalk<'a> {
    pub regions: Option<&'a dyn Regions>,
    pub surfaces: Option<&'a SurfaceTrace>,
    pub medium: u8,
    /// How far short of its light a segment ends (world units): the ray offset, so that
    /// a light on a voxel's face is seen from the face's open side, not by rounding
    /// (contract, "Shading a hit").
    pub end_offset: f64,
    /// Every segment passes whole (transmittance 1, nothing walked): the unshadowed
    /// estimate a reconstruction divides by (`crate::frame::PrimaryPixel::unshadowed`).
    pub clear: bool,
}

/// One point emitter at `x` of radiance `radiance` (colour times intensity) seen from the
/// hit point `p` (shadow ray from `q`): `V E (kd diffuse + ks specular)`, before albedo.
#[allow(clippy::too_many_arguments)]
pub fn point_contribution(
    scene: &Scene,
    walk: &ShadowWalk,
    settings: &RenderSettings,
    m: &Material,
    q: DVec3,
    p: DVec3,
    n: DVec3,
    d: DVec3,
    x: DVec3,
    radiance: DVec3,
    stats: &mut RayStats,
) -> DVec3 {
    // No shadow ray where nothing it could let through is seen (a light behind the
    // surface, say): `V` multiplies zero there. Contract: "Shading a hit".
    let lit = unshadowed(settings, m, p, n, d, x, radiance);
    if lit == DVec3::ZERO {
        return lit;
    }
    stats.shadow += 1;
    shadow_transmittance(scene, walk, settings.features.transmittance, q, x, stats) * lit
}

/// `E (kd diffuse + ks specular)` of a point emitter at `x` seen from `p`, before
/// visibility and albedo.
pub fn unshadowed(
    settings: &RenderSettings,
    m: &Material,
    p: DVec3,
    n: DVec3,
    d: DVec3,
    x: DVec3,
    radiance: DVec3,
) -> DVec3 {
    let to_light = x - p;
    let dl = to_light.length();
    let l = if dl > 0.0 { to_light / dl } else { n };
    let e = if settings.falloff {
        radiance / (dl * dl).max(settings.falloff_min_distance.powi(2))
    } else {
        radiance
    };
    let nl = n.dot(l);
    let diffuse = nl.max(0.0);
    // A light behind the surface gives no highlight: textbook Phong gates the specular
    // term by n.l > 0 (a transmitting face lets its own shadow ray through, so without
    // the gate glass lit from behind would glow towards the viewer).
    let r = l - 2.0 * nl * n;
    let rd = r.dot(d);
    let spec = if nl > 0.0 && rd > 0.0 {
        rd.powf(m.shininess)
    } else {
        0.0
    };
    e * (m.kd * diffuse + m.ks * spec)
}

/// Transmittance (RGB) of the shadow segment from `q` to `light` under `model`, over
/// the scene's grid as the walk's tree holds it when there is one (the same value), or
/// through its triangle surfaces (`crate::triangles::SurfaceTrace::transmittance`).
pub fn shadow_transmittance(
    scene: &Scene,
    walk: &ShadowWalk,
    model: Transmittance,
    q: DVec3,
    light: DVec3,
    stats: &mut RayStats,
) -> DVec3 {
    let to_light = light - q;
    let len = to_light.length();
    if walk.clear || len <= walk.end_offset {
        return DVec3::ONE;
    }
    let light = q + to_light * ((len - walk.end_offset) / len);
    let regions = walk.regions;
    if let Some(s) = walk.surfaces {
        let mut absorber = model.model().absorber();
        return s.transmittance(scene, regions, &mut absorber, q, light, walk.medium, stats);
    }
    shadow_transmittance_over(scene, regions, model, q, light, stats)
}

/// The transmittance of the segment from `q` to `light` over the voxels, as `tree`
/// holds them when given (a uniform region passes at once): every voxel visited, the
/// start voxel included, passes to `model` in order; nothing outside the grid absorbs.
pub fn shadow_transmittance_over(
    scene: &Scene,
    regions: Option<&dyn Regions>,
    model: Transmittance,
    q: DVec3,
    light: DVec3,
    stats: &mut RayStats,
) -> DVec3 {
    let to_light = light - q;
    let len = to_light.length();
    if len == 0.0 {
        return DVec3::ONE;
    }
    let grid = &scene.grid;
    let vs = grid.voxel_size();
    let mut dda = Dda::over(grid, regions, q, to_light / len, len);
    let mut absorber = model.model().absorber();
    let mut opaque = false;
    while let Some(v) = dda.next() {
        let material = &scene.materials[v.material as usize];
        if absorber.pass(v.t_enter, v.material, material, vs) {
            opaque = true;
            break;
        }
        dda.skip_region();
    }
    stats.voxel_steps += dda.steps;
    if opaque {
        return DVec3::ZERO;
    }
    absorber.result(dda.t_end.min(len))
}
