//! Cone marching through the pre-filtered pyramids (`super::pyramid`), in f64: the
//! reference of `shaders/cone.wgsl`, which does the same steps in f32. After C. Crassin
//! et al., "Interactive Indirect Illumination Using Voxel Cone Tracing", Computer
//! Graphics Forum 30(7), 2011, section 4 (cone tracing by volume ray casting with
//! pre-filtered samples, front-to-back compositing).
//!
//! Everything here is in grid-local units (one voxel = 1). A cone starts at
//! `o = p + start_offset n`, runs along the unit direction `w` with aperture `theta`,
//! and at distance `t` from `o` samples the pyramid at `o + t w`:
//! - footprint `d = max(1, 2 t tan(theta / 2))`, level `lod = log2(d)` (clamped to the
//!   pyramid), quadrilinear sample (trilinear in the two levels around `lod`, linear
//!   between them);
//! - step `dt = step_factor d`. A texel's opacity is that of a slab one texel (`d`)
//!   thick, so a step crossing `dt / d = step_factor` texels uses the corrected opacity
//!   `a' = 1 - (1 - a)^step_factor` (the standard correction of volume rendering for a
//!   changed sampling distance), and premultiplied colour scales by `a' / a`;
//! - front to back: `C += (1 - occ) c'`, `occ += (1 - occ) a'`.
//! - the march ends when the next sample lies at or beyond `max_dist`, when the sample
//!   leaves the grid far enough that every later sample is empty (exact, no effect on the
//!   result), or when `occ >= OCCLUSION_CUTOFF`, which then snaps `occ` to 1. The cut-off
//!   makes visibility discontinuous by at most `1 - OCCLUSION_CUTOFF` = 0.01 (a hard
//!   edge at the 99 % contour); it buys a visibility of exactly 0 in full shadow, so a
//!   vanishing cone can reach the hard shadow's 0.
//!
//! The sample positions are a step function of `max_dist` too (the last sample is the
//! last one before `max_dist`), another small discontinuity, documented rather than hidden.

use glam::DVec3;

use super::pyramid::Pyramid;

/// Occlusion at which a cone stops and counts as fully blocked.
pub const OCCLUSION_CUTOFF: f64 = 0.99;

/// Guard against a march that does not end (it always does: steps grow geometrically).
pub(crate) const MAX_CONE_STEPS: u32 = 4096;

/// The knobs of a march.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConeParams {
    /// Step length in footprints (`dt = step_factor d`), > 0.
    pub step_factor: f64,
    /// Distance (voxels) along the normal from the surface point to the cone's apex.
    pub start_offset: f64,
}

/// What a march accumulated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ConeResult {
    /// Front-to-back occlusion in [0, 1].
    pub occlusion: f64,
    /// Radiance gathered (zero unless the radiance pyramid was marched).
    pub radiance: DVec3,
    pub steps: u32,
}

/// Whether every sample from `x` on along `w` is empty: some axis has the point beyond
/// the grid by more than the largest footprint the pyramid resolves (half a coarsest
/// texel is enough; `2^levels` is safe) and moving away.
pub fn leaving(x: DVec3, w: DVec3, dims: DVec3, margin: f64) -> bool {
    (0..3).any(|a| (x[a] < -margin && w[a] <= 0.0) || (x[a] > dims[a] + margin && w[a] >= 0.0))
}

/// Marches one cone from apex `o` (already offset) along unit `w` with `tan(theta/2)`
/// = `tan_half`, up to `max_dist` (voxels), gathering radiance when `gather` is set.
pub fn march(
    pyr: &Pyramid,
    params: &ConeParams,
    o: DVec3,
    w: DVec3,
    tan_half: f64,
    max_dist: f64,
    gather: bool,
) -> ConeResult {
    let layout = &pyr.layout;
    let dims = layout.dims.as_dvec3();
    let margin = (1u64 << layout.levels) as f64;
    let k = params.step_factor;
    let mut r = ConeResult::default();
    let mut t = 0.0f64;
    while t < max_dist && r.steps < MAX_CONE_STEPS {
        let d = (2.0 * t * tan_half).max(1.0);
        let x = o + t * w;
        if leaving(x, w, dims, margin) {
            break;
        }
        let lod = d.log2();
        r.steps += 1;
        let (a, c) = if gather {
            let s = pyr.radiance_at(x, lod);
            (s[3], DVec3::new(s[0], s[1], s[2]))
        } else {
            (pyr.opacity_at(x, lod), DVec3::ZERO)
        };
        let a = a.clamp(0.0, 1.0);
        let ac = 1.0 - (1.0 - a).powf(k);
        if gather {
            // c' = c a'/a; as a -> 0, a'/a -> step_factor.
            let ratio = if a > 1e-4 { ac / a } else { k };
            r.radiance += (1.0 - r.occlusion) * c * ratio;
        }
        r.occlusion += (1.0 - r.occlusion) * ac;
        if r.occlusion >= OCCLUSION_CUTOFF {
            r.occlusion = 1.0;
            break;
        }
        t += k * d;
    }
    r
}

/// An orthonormal tangent frame around unit `n`, the same on CPU and GPU.
pub(crate) fn tangent_frame(n: DVec3) -> (DVec3, DVec3) {
    let helper = if n.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t1 = helper.cross(n).normalize();
    (t1, n.cross(t1))
}

/// The golden angle (radians) that spreads the hemisphere cones in a spiral.
pub(crate) const GOLDEN_ANGLE: f64 = 2.399_963_229_728_653;

/// Direction `k` of `count` hemisphere cones around `n`: cosine-weighted by Malley's
/// method (a stratified spiral on the unit disk, `r = sqrt((k + 1/2) / K)`, angle
/// `k` golden angles, lifted to the hemisphere), so the plain mean of the cones'
/// values estimates `(1/pi) int V cos` over the hemisphere.
pub(crate) fn hemisphere_dir(n: DVec3, k: u32, count: u32) -> DVec3 {
    let (t1, t2) = tangent_frame(n);
    let r = ((k as f64 + 0.5) / count as f64).sqrt();
    let phi = k as f64 * GOLDEN_ANGLE;
    let z = (1.0 - r * r).max(0.0).sqrt();
    (r * phi.cos() * t1 + r * phi.sin() * t2 + z * n).normalize()
}

/// `tan(theta/2)` of hemisphere cones: `count` cones share the hemisphere's solid angle,
/// `2 pi (1 - cos(theta/2)) = 2 pi / K`, capped at 120 degrees (K = 1, 2).
pub(crate) fn hemisphere_tan_half(count: u32) -> f64 {
    let c = 1.0 - 1.0 / count.max(1) as f64;
    let half = c.acos().min(60f64.to_radians());
    half.tan()
}

/// Ambient occlusion at surface point `p` (grid-local) with unit normal `n`: the mean
/// visibility `1 - occ` of `count` cosine-weighted hemisphere cones of range `range`
/// voxels. 1 in empty space.
pub fn ambient_occlusion(
    pyr: &Pyramid,
    params: &ConeParams,
    p: DVec3,
    n: DVec3,
    count: u32,
    range: f64,
) -> f64 {
    let o = p + params.start_offset * n;
    let th = hemisphere_tan_half(count);
    let sum: f64 = (0..count)
        .map(|k| {
            1.0 - march(
                pyr,
                params,
                o,
                hemisphere_dir(n, k, count),
                th,
                range,
                false,
            )
            .occlusion
        })
        .sum();
    sum / count as f64
}

/// One-bounce diffuse light arriving at `p`: the mean radiance gathered by the
/// hemisphere cones from the radiance pyramid, up to `max_dist` voxels.
pub fn indirect(
    pyr: &Pyramid,
    params: &ConeParams,
    p: DVec3,
    n: DVec3,
    count: u32,
    max_dist: f64,
) -> DVec3 {
    let o = p + params.start_offset * n;
    let th = hemisphere_tan_half(count);
    let sum: DVec3 = (0..count)
        .map(|k| {
            march(
                pyr,
                params,
                o,
                hemisphere_dir(n, k, count),
                th,
                max_dist,
                true,
            )
            .radiance
        })
        .sum();
    sum / count as f64
}

/// Cone visibility `1 - occ` from surface point `p` (normal `n`) towards a light at `l`
/// (grid-local), aperture `tan_half`: the cone runs from `o = p + start_offset n` to
/// the light, `max_dist = |l - o|`.
pub fn shadow_visibility(
    pyr: &Pyramid,
    params: &ConeParams,
    p: DVec3,
    n: DVec3,
    l: DVec3,
    tan_half: f64,
) -> f64 {
    let o = p + params.start_offset * n;
    let to = l - o;
    let len = to.length();
    if len == 0.0 {
        return 1.0;
    }
    1.0 - march(pyr, params, o, to / len, tan_half, len, false).occlusion
}

/// What the CPU tracer needs for the cone features of one render: the pyramids (built
/// once) and the knobs. Built from the render's [`crate::plan::Plan`], so the CPU
/// leaves out what the GPU leaves out.
pub struct ConeScene {
    pub pyramid: Pyramid,
    pub params: ConeParams,
    /// `tan(aperture / 2)` of point lights' shadow cones.
    pub point_tan_half: f64,
    pub ao_cones: u32,
    pub ao_range: f64,
    pub indirect_strength: f64,
}

impl ConeScene {
    /// `None` when the plan has no cone feature.
    pub fn new(
        scene: &crate::scene::Scene,
        settings: &crate::render::RenderSettings,
        plan: &crate::plan::Plan,
    ) -> Option<Self> {
        let layout = plan.pyramid?;
        let c = &settings.cones;
        Some(Self {
            pyramid: Pyramid::build(scene, settings, layout, plan.radiance_pyramid()),
            params: ConeParams {
                step_factor: c.step_factor,
                start_offset: c.start_offset,
            },
            point_tan_half: (c.aperture_deg.to_radians() / 2.0).tan(),
            ao_cones: c.ao_cones.max(1),
            ao_range: c.ao_range,
            indirect_strength: c.indirect_strength,
        })
    }
}

/// The radius an area light's shadow cone must cover (world units; a rectangle's
/// half-diagonal), 0 for point lights.
pub fn light_radius(light: &crate::scene::Light) -> f64 {
    use crate::scene::{AreaShape, Light};
    match light {
        Light::Point(_) => 0.0,
        Light::Area(a) => match a.shape {
            AreaShape::Rect { width, height } => 0.5 * (width * width + height * height).sqrt(),
            AreaShape::Disk { radius } | AreaShape::Sphere { radius } => radius,
        },
    }
}

/// Indirect cones run until they leave the grid: its diagonal bounds every path inside.
pub fn indirect_range(layout: &super::pyramid::PyramidLayout) -> f64 {
    layout.dims.as_dvec3().length()
}
