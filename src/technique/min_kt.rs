//! Transmittance `min-kt`: the smallest `kt` of the materials a shadow segment passes
//! through, the start's included; void transmits fully and nothing outside the grid
//! absorbs (the seed's O1 compromise as its code does it; `src/trace_contract.md`, trace
//! contract "Shading a hit", shadow ray). The default transmittance.

use glam::DVec3;

use super::{AbsorbState, TransmittanceModel};
use crate::render::Transmittance;
use crate::scene::{Material, VOID};

/// This model, as `[features] transmittance` names it.
pub const ID: Transmittance = Transmittance(&MODEL);

pub const MODEL: TransmittanceModel = TransmittanceModel {
    name: "min-kt",
    summary: "the smallest kt of the voxels a shadow segment crosses (the seed's O1)",
    settings: &[],
    plan: |_, _| Ok(()),
    wgsl: (
        "shaders/transmittance_min_kt.wgsl",
        include_str!("../../shaders/transmittance_min_kt.wgsl"),
    ),
    start: || AbsorbState {
        value: DVec3::ONE,
        ..Default::default()
    },
    pass,
    result: |s, _| s.value,
    voxel_transmittance: |m, _| m.kt,
    // kt is per crossing, not per distance: no medium holds it.
    interior_extinction: |_, _| None,
};

/// The smallest kt so far (every channel alike); over once it reaches 0.
fn pass(s: &mut AbsorbState, _t: f64, index: u8, m: &Material, _voxel_size: f64) -> bool {
    if index != VOID {
        s.value = s.value.min(DVec3::splat(m.kt));
    }
    s.value.x <= 0.0
}

/// `min-kt` transmittance of the segment from `q` to `light` over the voxels (the seed's
/// O1 as its code does it): the smallest kt of the voxels visited, the start included.
pub fn shadow_min_kt(
    scene: &crate::scene::Scene,
    q: DVec3,
    light: DVec3,
    stats: &mut crate::frame::RayStats,
) -> f64 {
    shadow_min_kt_over(scene, None, q, light, stats)
}

/// [`shadow_min_kt`] over the grid as `tree` holds it: a uniform region counts once.
pub fn shadow_min_kt_over(
    scene: &crate::scene::Scene,
    regions: Option<&dyn crate::sparse::Regions>,
    q: DVec3,
    light: DVec3,
    stats: &mut crate::frame::RayStats,
) -> f64 {
    crate::technique::shading::shadow_transmittance_over(scene, regions, ID, q, light, stats).x
}
