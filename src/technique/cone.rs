//! Cone shadows: one cone per light through the opacity pyramid replaces the shadow rays
//! (C. Crassin et al., "Interactive Indirect Illumination Using Voxel Cone Tracing",
//! CGF 30(7), 2011, section 4). The march and the pyramids are shared with ambient
//! occlusion and indirect light (`crate::technique::cones::march`, `shaders/cone.wgsl`); its knobs are
//! the `[cones]` table's ([`super::cones`]).
//!
//! Contract (both tracers): light j at centre `x` is `V E (kd diffuse + ks specular)`
//! (`crate::technique::shading::unshadowed`) at `x`, `V` the visibility `1 - occ` of one cone from the
//! hit (grid-local, apex `start_offset` along the normal) to `x`. Its aperture is the
//! angle the light subtends, `tan(theta / 2) = R / dist` with `R` its radius in voxels
//! (`crate::technique::cones::march::light_radius`: a rectangle's half-diagonal) and `dist` from the
//! hit to `x`; `cones.aperture_deg` for point lights. Each light counts one shadow ray.
//! A Lambertian light's `E` takes the emitter's cosine at the centre
//! (`Light::radiance_towards`): the cone approximates the light by a uniform disk.
//! It casts no shadow ray through the transmittance model: the pyramid's opacity
//! already holds the materials' transmittance, so the plan leaves the model out.

use glam::DVec3;

use super::{AblateCurve, CpuShadow, Knob, LightQuery, ShadowModel};
use crate::frame::RayStats;
use crate::render::RenderSettings;
use crate::scene::{Light, Scene};
use crate::technique::cones::march::{ConeScene, light_radius, shadow_visibility};

pub const MODEL: ShadowModel = ShadowModel {
    name: "cone",
    summary: "one cone per light through the opacity pyramid (Crassin et al. 2011, section 4)",
    title: "cone traced",
    settings: &[],
    stochastic: false,
    plan,
    wgsl: (
        "shaders/shadow_cone.wgsl",
        include_str!("../../shaders/shadow_cone.wgsl"),
    ),
    // The pyramids are the plan's (`Plan::pyramid`), shared with the lighting terms.
    gpu_data: None,
    data_settings: &[],
    cpu: |_, _| Box::new(Cone),
    // Over the step factor, each area light at the aperture it subtends; and, with
    // every area light as a point light at its centre (which the model shades it as
    // anyway), over the point lights' aperture: whether the subtended angle is the best.
    ablate: &[
        AblateCurve {
            label: "cone at light's aperture",
            knob: Knob::Shared {
                key: "cones.step_factor",
                list: "cone_step_factor",
                default: &[0.25, 0.5, 1.0, 2.0],
            },
            lights_as_points: false,
            about: "an area light's cone has the angle it subtends, over the step factor.",
        },
        AblateCurve {
            label: "cone at set aperture",
            knob: Knob::Shared {
                key: "cones.aperture_deg",
                list: "cone_aperture_deg",
                default: &[4.0, 8.0, 16.0, 32.0, 64.0],
            },
            lights_as_points: true,
            about: "each area light replaced by a point light at its centre (the cone model \
                    shades it there anyway), over the cone aperture, at the experiment's \
                    step factor.",
        },
    ],
    describe: Some(describe),
    label: "CONE_SHADOWS",
    switch: Some("cone_shadows"),
    shared_settings: &[
        "cones.levels",
        "cones.step_factor",
        "cones.aperture_deg",
        "cones.start_offset",
    ],
    shadow_rays: false,
    pyramid: true,
};

fn plan(scene: &Scene, _: &RenderSettings) -> Result<(), String> {
    if scene.grid.is_sparse() {
        Err(
            "the grid is held only as its sparse tree, and the cone pyramids are built \
             from the dense grid"
                .to_string(),
        )
    } else {
        Ok(())
    }
}

/// `tan(theta / 2)` of the shadow cone from grid-local `p` to `light` at distance
/// `dist`: the angle an area light subtends, `R / dist` (`radius_voxels` = R), the set
/// aperture (`point_tan_half`) for point lights and lights of radius 0.
pub fn light_tan_half(light: &Light, radius_voxels: f64, dist: f64, point_tan_half: f64) -> f64 {
    match light {
        Light::Area(_) if radius_voxels > 0.0 => {
            if dist > 0.0 {
                radius_voxels / dist
            } else {
                f64::MAX
            }
        }
        _ => point_tan_half,
    }
}

/// The aperture of the first area light's cone at the grid's centre, for reports.
fn describe(scene: &Scene, settings: &RenderSettings) -> Option<String> {
    let what = "Cone shadows replace the shadow rays and the area samples with one cone per \
                light and pixel";
    Some(match light_aperture_deg(scene) {
        Some(a) => {
            format!("{what}; an area light's cone subtends {a:.1} deg at the grid's centre.")
        }
        None => format!("{what}, of {} deg.", settings.cones.aperture_deg),
    })
}

/// The full angle (degrees) the first area light subtends at the grid's centre, the
/// aperture its shadow cones have there ([`light_tan_half`]).
pub(crate) fn light_aperture_deg(scene: &Scene) -> Option<f64> {
    let light = scene.lights.iter().find(|l| l.is_area())?;
    let g = &scene.grid;
    let centre = g.to_world(g.dims().as_dvec3() * 0.5);
    let dist = (light.position() - centre).length();
    let r = light_radius(light);
    (dist > 0.0).then(|| 2.0 * (r / dist).atan().to_degrees())
}

struct Cone;

impl CpuShadow for Cone {
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3 {
        let c: &ConeScene = at
            .cones
            .expect("the plan builds the pyramids for cone shadows");
        stats.shadow += 1;
        let g = &at.scene.grid;
        let (pl, ll) = (g.to_local(at.p), g.to_local(at.light.position()));
        let r = light_radius(at.light) / g.voxel_size();
        let th = light_tan_half(at.light, r, (ll - pl).length(), c.point_tan_half);
        let v = shadow_visibility(&c.pyramid, &c.params, pl, at.n, ll, th);
        if v > 0.0 {
            let radiance = at.light.radiance_towards(at.light.position(), at.p);
            v * crate::technique::shading::unshadowed(
                at.settings,
                at.material,
                at.p,
                at.n,
                at.d,
                at.light.position(),
                radiance,
            )
        } else {
            DVec3::ZERO
        }
    }
}
