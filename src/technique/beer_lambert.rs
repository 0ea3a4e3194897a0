//! Transmittance `beer-lambert`: `T = exp(-sum_m sigma_m len_m)` per RGB channel, with
//! `len_m` the exact length of the segment inside each material from the walk (no
//! fixed-step marching, so any sigma is exact and stable; Beer-Lambert law, e.g. Pharr,
//! Jakob and Humphreys, PBRT 3rd ed., section 11.1.3). The optical depth is summed first
//! and exponentiated once, so a huge depth gives exactly 0, never a negative or NaN
//! value; a material with `kt = 0` is opaque; void absorbs nothing. `sigma` per
//! material is `[[materials]] sigma`, or derived from `kt` (`src/trace_contract.md`).

use glam::DVec3;

use super::{AbsorbState, TransmittanceModel};
use crate::render::Transmittance;
use crate::scene::{Material, Scene, VOID};

/// This model, as `[features] transmittance` names it.
pub const ID: Transmittance = Transmittance(&MODEL);

pub const MODEL: TransmittanceModel = TransmittanceModel {
    name: "beer-lambert",
    summary: "exp(-sum sigma_m len_m) with each voxel's exact length (Beer-Lambert law)",
    settings: &["materials.sigma"],
    plan: |scene, _| {
        if attenuates_by_distance(scene) {
            Ok(())
        } else {
            Err(
                "every material a shadow ray can cross is opaque or fully transparent \
                 without absorption, where min-kt gives the same 0 or 1"
                    .into(),
            )
        }
    },
    wgsl: (
        "shaders/transmittance_beer_lambert.wgsl",
        include_str!("../../shaders/transmittance_beer_lambert.wgsl"),
    ),
    start: AbsorbState::default,
    pass,
    result,
    // T = exp(-sigma len): a homogeneous medium of extinction sigma, absorbing only.
    interior_extinction: |m, voxel_size| Some(m.absorption(voxel_size)),
    voxel_transmittance: |m, voxel_size| {
        if m.kt <= 0.0 {
            0.0
        } else {
            let s = m.absorption(voxel_size);
            (-(s.x + s.y + s.z) / 3.0 * voxel_size).exp()
        }
    },
};

/// `value` the optical depth so far, `sigma` the current material's absorption and `t`
/// where the segment entered it.
fn pass(s: &mut AbsorbState, t: f64, index: u8, m: &Material, voxel_size: f64) -> bool {
    s.value += s.sigma * (t - s.t).max(0.0);
    s.t = t;
    if index == VOID {
        s.sigma = DVec3::ZERO;
        return false;
    }
    if m.kt <= 0.0 {
        return true;
    }
    s.sigma = m.absorption(voxel_size);
    false
}

fn result(s: &AbsorbState, t_end: f64) -> DVec3 {
    (-(s.value + s.sigma * (t_end - s.t).max(0.0))).exp()
}

/// Whether Beer-Lambert can differ from min-kt: some material a shadow segment can
/// cross (any used by the grid, and void) is neither opaque (kt <= 0: both give 0) nor
/// fully transparent without absorption (kt >= 1 and sigma = 0: both give 1).
fn attenuates_by_distance(scene: &Scene) -> bool {
    let used = scene.grid.materials_used();
    let vs = scene.grid.voxel_size();
    scene.materials.iter().enumerate().any(|(i, m)| {
        (used[i] || i == VOID as usize)
            && m.kt > 0.0
            && (m.kt < 1.0 || m.absorption(vs) != DVec3::ZERO)
    })
}

/// Beer-Lambert transmittance of the segment from `q` to `light` over the voxels.
pub fn shadow_beer_lambert(
    scene: &Scene,
    q: DVec3,
    light: DVec3,
    stats: &mut crate::frame::RayStats,
) -> DVec3 {
    shadow_beer_lambert_over(scene, None, q, light, stats)
}

/// [`shadow_beer_lambert`] over the grid as `tree` holds it: a uniform region's length
/// counts at once (the per-voxel lengths telescope to it).
pub fn shadow_beer_lambert_over(
    scene: &Scene,
    regions: Option<&dyn crate::sparse::Regions>,
    q: DVec3,
    light: DVec3,
    stats: &mut crate::frame::RayStats,
) -> DVec3 {
    crate::technique::shading::shadow_transmittance_over(scene, regions, ID, q, light, stats)
}
