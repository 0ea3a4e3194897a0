//! Hard shadows, the seed's and the default: one shadow ray to each light's centre
//! (T. Whitted, "An Improved Illumination Model for Shaded Display", CACM 23(6), 1980).
//!
//! Contract (both tracers): a light, point or area, is one point emitter at its centre
//! `x`: `T E (kd diffuse + ks specular)` (`crate::technique::shading::point_contribution`), `T` the
//! shadow transmittance of the segment from `q` to `x` under the experiment's
//! transmittance model. An area light's shape is ignored; every other model reaches this
//! one as its light vanishes.

use glam::DVec3;

use super::{AblateCurve, CpuShadow, Knob, LightQuery, ShadowModel};
use crate::frame::RayStats;

pub const MODEL: ShadowModel = ShadowModel {
    name: "hard",
    summary: "one shadow ray to each light's centre (the seed's hard shadows, Whitted 1980)",
    title: "hard (light centres)",
    settings: &[],
    stochastic: false,
    plan: |_, _| Ok(()),
    wgsl: (
        "shaders/shadow_hard.wgsl",
        include_str!("../../shaders/shadow_hard.wgsl"),
    ),
    gpu_data: None,
    data_settings: &[],
    cpu: |_, _| Box::new(Hard),
    // The fixed points every curve starts from, once per transmittance model.
    ablate: &[AblateCurve {
        label: "hard",
        knob: Knob::Transmittance,
        lights_as_points: false,
        about: "the area light as a point at its centre, once per transmittance model.",
    }],
    describe: None,
    label: "",
    switch: None,
    shared_settings: &[],
    shadow_rays: true,
    pyramid: false,
};

struct Hard;

impl CpuShadow for Hard {
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3 {
        at_centre(at, stats)
    }
}

/// The light at its centre, as one point emitter: the hard shadow, which the other
/// models fall back to for point lights.
pub(crate) fn at_centre(at: &LightQuery, stats: &mut RayStats) -> DVec3 {
    let x = at.light.position();
    crate::technique::shading::point_contribution(
        at.scene,
        &at.walk,
        at.settings,
        at.material,
        at.q,
        at.p,
        at.n,
        at.d,
        x,
        at.light.radiance_towards(x, at.p),
        stats,
    )
}
