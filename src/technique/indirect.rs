//! One bounce of diffuse light by voxel cones: the direct light injected into the
//! radiance pyramid, gathered at each hit by cosine-weighted hemisphere cones (C.
//! Crassin et al., "Interactive Indirect Illumination Using Voxel Cone Tracing", CGF
//! 30(7), 2011, section 4.2; injection `crate::technique::cones::pyramid`, march `crate::technique::cones::march`).
//!
//! Contract (both tracers): at a hit of a material with `kd > 0` it adds
//! `indirect_strength * albedo * kd * L_ind`, `L_ind` the mean radiance `cones.ao_cones`
//! hemisphere cones gather from the radiance pyramid until they leave the grid
//! (`crate::technique::cones::march::indirect`, range `indirect_range`).

use glam::DVec3;

use super::{LightingTerm, TermQuery};

pub(crate) const TERM: LightingTerm = LightingTerm {
    name: "indirect",
    short: "indirect",
    summary: "one bounce of diffuse light gathered by hemisphere cones from the radiance \
              pyramid (Crassin et al. 2011, section 4.2)",
    label: "INDIRECT",
    shared_settings: &["cones.indirect_strength"],
    plan: |scene, _| {
        if !crate::plan::diffuse_in_grid(scene) {
            Err("no diffuse material in the grid".to_string())
        } else if !crate::plan::some_light_emits(scene) {
            Err("no light to inject (none, or every light dark)".to_string())
        } else {
            Ok(())
        }
    },
    pyramid: true,
    radiance_pyramid: true,
    wgsl: (
        "shaders/term_indirect.wgsl",
        include_str!("../../shaders/term_indirect.wgsl"),
    ),
    cpu: term,
    // The cones composite the injected radiance with weights that sum to at most 1, and
    // a voxel's injected radiance (albedo kd times the lights' irradiance at its faces)
    // is at most the lights' bound at a hit.
    bound: |b| b.settings.cones.indirect_strength * b.diffuse * b.direct,
};

fn term(at: &TermQuery) -> DVec3 {
    let Some((c, pl)) = at.diffuse_cone_hit() else {
        return DVec3::ZERO;
    };
    let m = at.material;
    let range = crate::technique::cones::march::indirect_range(&c.pyramid.layout);
    let l = crate::technique::cones::march::indirect(
        &c.pyramid, &c.params, pl, at.n, c.ao_cones, range,
    );
    c.indirect_strength * m.albedo * m.kd * l
}
