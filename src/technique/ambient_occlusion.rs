//! Ambient occlusion by voxel cones: the ambient light a hit receives, times the mean
//! visibility of cosine-weighted hemisphere cones through the opacity pyramid (C.
//! Crassin et al., "Interactive Indirect Illumination Using Voxel Cone Tracing", CGF
//! 30(7), 2011, section 4; the march is `crate::technique::cones::march`'s).
//!
//! Contract (both tracers): at a hit of a material with `kd > 0` it adds
//! `ambient * albedo * kd * AO`, `AO` the mean visibility `1 - occ` of `cones.ao_cones`
//! hemisphere cones (Malley's method on a golden spiral about the shading normal) of
//! range `cones.ao_range` voxels from the grid-local hit (`crate::technique::cones::march::
//! ambient_occlusion`). Off, nothing is added: the baseline's ambient stays the
//! per-pixel background term.

use glam::DVec3;

use super::{LightingTerm, TermQuery};

pub(crate) const TERM: LightingTerm = LightingTerm {
    name: "ambient_occlusion",
    short: "ao",
    summary: "ambient times the visibility of cosine-weighted hemisphere cones \
              (Crassin et al. 2011)",
    label: "AMBIENT_OCCLUSION",
    shared_settings: &["cones.ao_cones", "cones.ao_range"],
    plan: |scene, _| {
        if crate::plan::diffuse_in_grid(scene) {
            Ok(())
        } else {
            Err("no diffuse material in the grid".to_string())
        }
    },
    pyramid: true,
    radiance_pyramid: false,
    wgsl: (
        "shaders/term_ambient_occlusion.wgsl",
        include_str!("../../shaders/term_ambient_occlusion.wgsl"),
    ),
    cpu: term,
    // AO is a visibility in [0, 1].
    bound: |b| b.ambient * b.diffuse,
};

fn term(at: &TermQuery) -> DVec3 {
    let Some((c, pl)) = at.diffuse_cone_hit() else {
        return DVec3::ZERO;
    };
    let m = at.material;
    let ao = crate::technique::cones::march::ambient_occlusion(
        &c.pyramid, &c.params, pl, at.n, c.ao_cones, c.ao_range,
    );
    at.scene.ambient * m.albedo * m.kd * ao
}
