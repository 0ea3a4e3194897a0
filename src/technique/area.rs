//! Sampled area lights: soft shadows by sampling each light over its shape, stratified,
//! and accumulating frames (R. Cook, T. Porter and L. Carpenter, "Distributed Ray
//! Tracing", SIGGRAPH 1984). The converged reference of `voxlab ablate`.
//!
//! Contract (both tracers; `src/trace_contract.md`, "Area lights", gives the sampling
//! sequence and the shapes):
//! - An area light of non-zero size (`Light::is_area`) with `n = render.light_samples`
//!   contributes `(1/n) sum_k point(x_k)`: `point(x)` the hard model's term for an
//!   emitter at `x` with the light's whole radiance (shadow ray from `q`, falloff,
//!   diffuse and specular per sample), `x_k = AreaLight::sample_point(s, t)` with
//!   `(s, t) = light_sample(seed, pixel, frame, j, k, n)`. Each sample counts one
//!   shadow ray. Frames draw new samples, so `render.spp` frames are accumulated.
//! - Every other light (point lights, area lights of size 0) is the hard model's, on its
//!   exact code path: a vanishing light gives the hard shadow bit for bit.

use glam::DVec3;

use super::{AblateCurve, CpuShadow, Knob, LightQuery, ShadowModel};
use crate::frame::RayStats;
use crate::render::RenderSettings;
use crate::sampling::light_sample;
use crate::scene::{Light, Scene};

pub const MODEL: ShadowModel = ShadowModel {
    name: "area",
    summary: "area lights sampled over their shape, stratified, accumulated over frames \
              (Cook, Porter and Carpenter 1984)",
    title: "area lights, sampled",
    settings: &[],
    stochastic: true,
    plan: needs_area_light,
    wgsl: (
        "shaders/shadow_area.wgsl",
        include_str!("../../shaders/shadow_area.wgsl"),
    ),
    gpu_data: None,
    data_settings: &[],
    cpu: |_, _| Box::new(Area),
    ablate: &[AblateCurve {
        label: "stochastic",
        knob: Knob::Spp,
        lights_as_points: false,
        about: "the area light sampled over its shape, over the frames accumulated: the model the reference converges.",
    }],
    describe: None,
    label: "AREA_LIGHTS",
    switch: Some("area_lights"),
    shared_settings: &["render.light_samples", "render.spp"],
    shadow_rays: true,
    pyramid: false,
};

/// The plan rule of models that integrate area lights: some light of non-zero size.
pub(crate) fn needs_area_light(scene: &Scene, _: &RenderSettings) -> Result<(), String> {
    if scene.lights.iter().any(Light::is_area) {
        Ok(())
    } else {
        Err("no area light of non-zero size: every light is a point".to_string())
    }
}

struct Area;

impl CpuShadow for Area {
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3 {
        sampled(at, stats)
    }
}

/// The area model's light term: an area light of non-zero size over its samples, any
/// other light at its centre.
pub fn sampled(at: &LightQuery, stats: &mut RayStats) -> DVec3 {
    match at.light {
        Light::Area(a) if at.light.is_area() => {
            let s = at.settings;
            let count = s.light_samples.max(1);
            let mut sum = DVec3::ZERO;
            for k in 0..count {
                let (u, v) = light_sample(s.seed, at.key.pixel, at.key.frame, at.index, k, count);
                let x = a.sample_point(u, v);
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
                    at.light.radiance_towards(x, at.p),
                    stats,
                );
            }
            sum / count as f64
        }
        _ => super::hard::at_centre(at, stats),
    }
}
