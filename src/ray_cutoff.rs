//! Adaptive depth control: the ray tree is pruned by what a pixel can still show
//! (R. Hall and D. Greenberg, "A Testbed for Realistic Image Synthesis", IEEE CG&A 3(8),
//! 1983, section "Adaptive tree depth control"; POV-Ray's `adc_bailout`).
//!
//! The rule (contract, "Ray cutoff"; both tracers, decided in f32 so that it is the same
//! bit for bit):
//!
//! - A ray's *weight* is the product of the factors it was spawned with, `kr`, `kt`, or
//!   `kr + kt` under total internal reflection, each rounded to f32 and multiplied in f32
//!   from 1 (the primary ray): the kernel's own throughput.
//! - A secondary ray whose weight is below `c = [render] ray_cutoff` (f32) is not traced
//!   (nor counted).
//! - At a hit of a ray of weight `w`, light `j` is not shaded (its shadow rays are not
//!   cast) when `w * B_j < c`, `B_j` the light's largest possible contribution at any hit
//!   ([`light_bound`], rounded up to f32).
//!
//! `c = 0` never cuts (no weight is below 0), and the kernel is then composed without
//! the rule (`RAY_CUTOFF`), so the image is the exact tree's bit for bit.
//!
//! What a cut can cost a pixel is bounded ([`Bounds`], printed by `voxlab render
//! --check`): a skipped light less than `c`; a cut ray less than `c` times the most a
//! ray can bring back from the rest of its tree, from the scene's brightest light.

use glam::DVec3;

use crate::render::RenderSettings;
use crate::scene::{Light, Scene, VOID};

/// The default cutoff (declared with the setting): 0.
pub use crate::settings::RAY_CUTOFF_DEFAULT as DEFAULT;

/// The largest cutoff at which every shipped experiment stays within 1/255 (max over
/// pixels, display values) of its exact tree, measured by `voxlab bench --cutoffs` at
/// 128x128 and 256x256 (docs/benchmarks.md, "Ray cutoff"); `tests/ray_cutoff.rs` holds
/// every experiment to it on both tracers.
pub const WITHIN_ONE_LEVEL: f64 = 2e-4;

/// The cutoff as both tracers compare it.
pub fn cutoff(settings: &RenderSettings) -> f32 {
    settings.ray_cutoff as f32
}

/// Whether a ray of weight `weight` is traced under cutoff `cutoff`.
pub fn traced(weight: f32, cutoff: f32) -> bool {
    weight >= cutoff
}

/// Whether a light of bound `bound` is shaded at a hit of a ray of weight `weight`.
pub(crate) fn light_shaded(weight: f32, bound: f32, cutoff: f32) -> bool {
    weight * bound >= cutoff
}

/// The f32 weight of a ray spawned from one of weight `parent` with factor `factor`
/// (`kr`, `kt` or `kr + kt`, each already f32), as the kernel multiplies.
pub fn spawned(parent: f32, factor: f32) -> f32 {
    parent * factor
}

/// The largest value (any channel) light `j`'s term can add at a hit, before the ray's
/// weight: `max(albedo) (kd + ks)` of the brightest shading material, times the light's
/// radiance `max(colour) intensity`, over `max(D, d_min)^2` with falloff, `D` the
/// distance from the light's extent to the nearest non-void voxel (every hit lies on the
/// box of one). Every shadow model's light term is at most this: its visibility is in
/// [0, 1], `diffuse` and `specular` are at most 1, and an area light's term is a mean
/// (or an integral normalised by its area) over points no nearer than `D`.
pub fn light_bound(scene: &Scene, settings: &RenderSettings, light: &Light) -> f64 {
    let material = crate::plan::shading_materials(scene)
        .iter()
        .filter(|(_, m)| m.is_lit())
        .map(|(_, m)| m.albedo.max_element() * (m.kd + m.ks))
        .fold(0.0, f64::max);
    let radiance = light.color().max_element() * light.intensity();
    let e = if settings.falloff {
        let d = nearest_surface(scene, settings, light);
        radiance / d.max(settings.falloff_min_distance).powi(2)
    } else {
        radiance
    };
    material * e
}

/// The lights' bounds as both tracers read them: rounded up to f32, so the rounding
/// never makes a bound smaller than the f64 one.
pub(crate) fn light_bounds(scene: &Scene, settings: &RenderSettings) -> Vec<f32> {
    scene
        .lights
        .iter()
        .map(|l| round_up(light_bound(scene, settings, l)))
        .collect()
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

/// Distance (world units) from the nearest point of `light` to the nearest non-void
/// voxel's box, 0 when unknown: a surface traced as triangles (the triangles' voxels
/// are not the grid's), or a grid held as a sparse tree (its box instead).
fn nearest_surface(scene: &Scene, settings: &RenderSettings, light: &Light) -> f64 {
    let grid = &scene.grid;
    let extent = match light {
        Light::Point(_) => 0.0,
        Light::Area(a) => match a.shape {
            crate::scene::AreaShape::Rect { width, height } => 0.5 * width.hypot(height),
            crate::scene::AreaShape::Disk { radius }
            | crate::scene::AreaShape::Sphere { radius } => radius,
        },
    };
    // Light position in voxel units; distances scaled back at the end.
    let vs = grid.voxel_size();
    let l = grid.to_local(light.position());
    let dims = grid.dims();
    let box_distance = |lo: DVec3, hi: DVec3| (l - l.clamp(lo, hi)).length();
    let surface_traced = settings.surface.traces_triangles();
    let nearest = match grid.dense() {
        Some(voxels) if !surface_traced => {
            let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
            let mut best = f64::INFINITY;
            for z in 0..nz {
                let slab = box_distance(
                    DVec3::new(0.0, 0.0, z as f64),
                    DVec3::new(nx as f64, ny as f64, z as f64 + 1.0),
                );
                if slab >= best {
                    continue;
                }
                for y in 0..ny {
                    let row_lo = DVec3::new(0.0, y as f64, z as f64);
                    if box_distance(row_lo, row_lo + DVec3::new(nx as f64, 1.0, 1.0)) >= best {
                        continue;
                    }
                    let row = &voxels[(z * ny + y) * nx..][..nx];
                    for (x, &m) in row.iter().enumerate() {
                        if m != VOID {
                            let lo = DVec3::new(x as f64, y as f64, z as f64);
                            best = best.min(box_distance(lo, lo + 1.0));
                        }
                    }
                }
            }
            best
        }
        _ => box_distance(DVec3::ZERO, dims.as_dvec3()),
    };
    if !nearest.is_finite() {
        // No voxel at all: no hit, so nothing to bound; the grid's box is as good.
        return (box_distance(DVec3::ZERO, dims.as_dvec3()) * vs - extent).max(0.0);
    }
    (nearest * vs - extent).max(0.0)
}

/// What the cutoff can cost (`voxlab render --check`), each a radiance (display units
/// before clamping) in the worst case.
#[derive(Clone, Debug, PartialEq)]
pub struct Bounds {
    pub cutoff: f64,
    /// The most one hit can add before its ray's weight: the brightest emission, every
    /// light's bound, and the lighting terms' bounds.
    pub per_hit: f64,
    /// The most the weights of a ray's children can sum to, relative to its own: the
    /// largest `kr + kt` of a shading material (at least 1 for the sum below).
    pub growth: f64,
    /// Levels below a cut ray at most (the total depth limit).
    pub levels: u32,
    /// Error of one skipped light: below `cutoff`.
    pub per_light: f64,
    /// Error of one cut ray: below `cutoff * per_hit * sum_{k <= levels} growth^k`.
    pub per_ray: f64,
    /// Error of one pixel of one frame: every ray of the tree cut at the cutoff (at most
    /// `2^(levels+1)` rays and their lights) in the worst case; a bound, not an estimate.
    pub per_pixel: f64,
}

impl Bounds {
    pub fn new(scene: &Scene, settings: &RenderSettings, plan: &crate::plan::Plan) -> Self {
        let cutoff = settings.ray_cutoff;
        let materials = crate::plan::shading_materials(scene);
        let emission = materials
            .iter()
            .map(|(_, m)| m.emission.max_element())
            .fold(0.0, f64::max);
        let direct: f64 = scene
            .lights
            .iter()
            .map(|l| light_bound(scene, settings, l))
            .sum();
        let diffuse = materials
            .iter()
            .map(|(_, m)| m.albedo.max_element() * m.kd)
            .fold(0.0, f64::max);
        let at = crate::technique::TermBound {
            ambient: scene.ambient.max_element(),
            direct,
            diffuse,
            settings,
        };
        let terms: f64 = plan.terms.iter().map(|t| (t.bound)(&at)).sum();
        let per_hit = emission + direct + terms;
        let growth = materials
            .iter()
            .map(|(_, m)| m.kr + m.kt)
            .fold(1.0, f64::max);
        let levels = settings.total_depth_limit();
        let subtree: f64 = (0..=levels).map(|k| growth.powi(k as i32)).sum();
        let per_ray = cutoff * per_hit * subtree;
        let rays = 2f64.powi(levels as i32 + 1);
        let lights = scene.lights.len() as f64;
        Self {
            cutoff,
            per_hit,
            growth,
            levels,
            per_light: cutoff,
            per_ray,
            per_pixel: rays * (per_ray + lights * cutoff),
        }
    }
}

impl std::fmt::Display for Bounds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ray cutoff {}: a skipped light costs a pixel < {:.3e}, a cut ray < {:.3e} \
             (one hit adds <= {:.3e}, children weigh <= {:.3}x their parent, {} levels); \
             a pixel < {:.3e} in the worst case (display values: 1/255 = 3.92e-3)",
            self.cutoff,
            self.per_light,
            self.per_ray,
            self.per_hit,
            self.growth,
            self.levels,
            self.per_pixel
        )
    }
}
