//! Transmittance `opaque`: every material but void stops a shadow segment, whatever its
//! `kt`; void transmits fully. What the shadow rays of a path tracer see of a smooth
//! dielectric under a point light or an area light sampled by next-event estimation
//! (Mitsuba 3's `path`, pbrt-v4's `PathIntegrator`: a glass surface is an occluder, and
//! the light it refracts is a caustic those estimators do not find), so a scene with
//! glass can be compared with them exactly (docs/mitsuba.md). The seed's semi-transparent
//! shadows are `min-kt`.

use glam::DVec3;

use super::{AbsorbState, TransmittanceModel};
use crate::render::Transmittance;
use crate::scene::{Material, Scene, VOID};

/// This model, as `[features] transmittance` names it.
pub const ID: Transmittance = Transmittance(&MODEL);

pub const MODEL: TransmittanceModel = TransmittanceModel {
    name: "opaque",
    summary: "any non-void voxel stops a shadow segment (a path tracer's shadow rays at glass)",
    settings: &[],
    plan: |scene, _| {
        if transmits(scene) {
            Ok(())
        } else {
            Err(
                "no material a shadow ray can cross has kt > 0, where min-kt gives the same 0"
                    .into(),
            )
        }
    },
    wgsl: (
        "shaders/transmittance_opaque.wgsl",
        include_str!("../../shaders/transmittance_opaque.wgsl"),
    ),
    start: || AbsorbState {
        value: DVec3::ONE,
        ..Default::default()
    },
    pass,
    result: |s, _| s.value,
    voxel_transmittance: |_, _| 0.0,
    interior_extinction: |_, _| None,
};

/// Nothing passes a non-void voxel.
fn pass(s: &mut AbsorbState, _t: f64, index: u8, _m: &Material, _voxel_size: f64) -> bool {
    if index != VOID {
        s.value = DVec3::ZERO;
    }
    index != VOID
}

/// Whether `opaque` can differ from `min-kt`: some material the grid uses lets light
/// through (`kt > 0`).
fn transmits(scene: &Scene) -> bool {
    let used = scene.grid.materials_used();
    scene
        .materials
        .iter()
        .enumerate()
        .any(|(i, m)| i != VOID as usize && used[i] && m.kt > 0.0)
}
