//! What a scene and its settings need from the tracer (`docs/plan.md`).
//!
//! A [`Plan`] decides which code the GPU kernel is composed with: code a scene cannot
//! reach is left out of the shader (not branched around), and the ray stack is sized to
//! the depth limits. Leaving code out must never change the image, so every rule below
//! errs on the side of keeping code: a flag is dropped only when the dropped code provably
//! contributes nothing for this scene and these settings.
//!
//! A shadow or transmittance model brings its own plan rule (`crate::technique`); the
//! plan calls it and composes the model's module. To add a feature of the kernel itself:
//! add a field, decide it in [`Plan::new`] with a reason when it is left out, and add
//! its row to [`KERNEL_FLAGS`] (its shader def, printed name and whether the
//! composition test enumerates it): the shader defs, the printing and the tests read it.
//!
//! Lighting terms, like shadow and transmittance models, bring their plan rules; every
//! combination of them with every combination of [`Plan::FLAGS`] would be 4 times as
//! many kernels to compose in the test, so `tests/cone_render.rs` composes each
//! combination of terms with the base flags all on, all off and shadows alone.

use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;

use naga_oil::compose::ShaderDefValue;

use crate::render::RenderSettings;
pub use crate::render::{Surface, Traversal};
use crate::scene::{Dielectric, Material, Scene, VOID};
use crate::technique::cones::pyramid::{PyramidLayout, memory_line};
use crate::technique::{LightingTerm, ShadowModel, TRAVERSALS, TransmittanceModel, TraversalModel};

/// [`Plan::layer_slices`] with the primary layers: the radiance and four planes.
pub const PRIMARY_LAYER_SLICES: u32 = 5;

/// Shader defs of one kernel variant, ordered so they can key a pipeline cache.
pub(crate) type ShaderDefs = BTreeMap<String, ShaderDefValue>;

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plan {
    /// Reflection rays (`REFLECTION`): some lit-or-not material reflects (kr > 0), or
    /// transmits where total internal reflection is possible (TIR adds kt to the
    /// reflection weight), and the reflection depth limit is above 0.
    pub reflection: bool,
    /// Refraction rays (`REFRACTION`): some material transmits and the refraction depth
    /// limit is above 0.
    pub refraction: bool,
    /// Local lighting with shadow rays (`SHADOWS`): some material is lit and there is a
    /// light. Without it the local term is zero for every hit, so it is left out whole.
    pub shadows: bool,
    /// Emission (`EMISSION`): some material in the grid emits. Adding zero changes
    /// nothing, so it is left out when none does.
    pub emission: bool,
    /// The Fresnel split (`FRESNEL`, shaders/dielectric.wgsl): some transmitting
    /// material splits its hits by Fresnel's equations, and secondary rays are in. Every
    /// other split is the material's fixed kr and kt, and the software driver runs the
    /// equations for every lane of every hit whether or not they are asked for
    /// (docs/benchmarks.md, "Code a scene does not need").
    pub fresnel: bool,
    /// Lambertian emitters (`LAMBERTIAN_LIGHTS`, shaders/emission.wgsl): some light sends
    /// out the emitter's cosine, and the scene is shaded. Without one every light's
    /// share is 1, and the cosine is left out of every light term.
    pub lambertian_lights: bool,
    /// The shadow model composed in (`voxlab::shadow_model`, printed by its label): the
    /// one `features.shadow_model` names when shadow rays are in and its plan rule keeps
    /// it, else the default (hard shadows at the light centres).
    pub shadow_model: &'static ShadowModel,
    /// The shadow transmittance model composed in (`voxlab::transmittance`): the one
    /// `features.transmittance` names when the shadow model casts shadow rays and the
    /// model's plan rule keeps it, else the default (listed, when not the default, by its
    /// name in capitals).
    pub transmittance: &'static TransmittanceModel,
    /// The reconstruction that filters the shadow term (`crate::technique::Reconstruction`):
    /// the one `features.reconstruction` names when the shadow model in force samples its
    /// shadow rays (a stochastic model that casts them), else none. It changes what the
    /// tracer keeps of the primary hits, not the kernel's flags.
    pub reconstruction: &'static crate::technique::Reconstruction,
    /// Progressive accumulation over frames (`ACCUMULATE`): the shadow model samples or
    /// the pixel filter moves the primary rays, and `spp > 1`. Allocates the
    /// compensation buffer. Without sampling every frame is the same image, so one frame
    /// is rendered whatever `spp` says.
    pub accumulate: bool,
    /// The lighting terms composed in (`voxlab::lighting_terms`, each printed by its
    /// label): those switched on whose plan rules keep them, in registry order.
    pub terms: Vec<&'static LightingTerm>,
    /// Primary rays spread over the pixel by the pixel filter (`PIXEL_FILTER`), a new
    /// position each frame: `render.pixel_filter` is not "none".
    pub pixel_filter: bool,
    /// The ray cutoff (`RAY_CUTOFF`, `crate::ray_cutoff`): `render.ray_cutoff` is above 0
    /// in f32. At 0 it cuts nothing, so it is left out and the tree is the exact one.
    pub ray_cutoff: bool,
    /// The seed's ray-tree rules (`SEED_RULES`: `render.rules = "seed"`), compiled in
    /// rather than read from a uniform: the software driver runs both sides of every
    /// branch (shaders/counters.wgsl), so the rules not in force would cost time in
    /// every walk step and ray (docs/sparse-traversal.md, "What each change to the kernel bought").
    pub seed_rules: bool,
    /// The pyramids' layout, when the shadow model or a lighting term reads them (the
    /// radiance pyramid only when a term reads it: [`Plan::radiance_pyramid`]).
    pub pyramid: Option<PyramidLayout>,
    /// Ray counters (`COUNT_RAYS`): chosen by the caller, not by the scene.
    pub count_rays: bool,
    /// Entries of the explicit ray stack (`RAY_STACK_SIZE`).
    pub ray_stack_size: u32,
    /// Voxel steps per iteration of the walks' loops (`DDA_UNROLL`: 1, 2, 4 or 8). Not
    /// the scene's choice but the device's (`GpuTracer` sets it): it changes no image,
    /// only how often a loop takes its back edge, which Mesa's software driver limits
    /// (shaders/counters.wgsl).
    pub dda_unroll: u32,
    /// The bindings of the walk's further words the kernel reads (`WALK_MORE_BINDINGS`,
    /// 0 up to [`crate::technique::WALK_MORE_BINDINGS`]; shaders/bindings.wgsl,
    /// `walk_more_word`). Not the scene's choice but the walk's data's on the device
    /// (`GpuTracer` sets it once the data is built): Mesa's software driver runs every
    /// binding's read for every lane, so a kernel reads only the bindings the data
    /// takes (the sparse octant walk at 256^3 on lavapipe: 15 % slower with all three
    /// read, docs/sparse-traversal.md, "Codes past one binding").
    pub walk_more_bindings: u32,
    /// The kernel of the walk's data (`WALK_VARIANT`,
    /// [`crate::sparse::Regions::kernel_variant`]): like `walk_more_bindings`, the
    /// data's on the device, set by `GpuTracer` once it is built.
    pub walk_variant: u32,
    /// What the walk's data holds where the walk chose it within its budget
    /// ([`crate::sparse::Regions::summary`]), printed on its own line: set by each
    /// tracer once the data is built (None before, and for walks that have no choice).
    pub walk_data: Option<String>,
    /// How rays walk the grid: the traversal whose module `voxlab::regions` is composed
    /// in (`TRAVERSAL_ID`, with `TREE_LEVELS` the tree's depth for one that walks the
    /// tree). Only the data it walks is built and uploaded: the tree, or the voxel buffer.
    pub traversal: &'static TraversalModel,
    /// The most levels of the sparse tree one descent takes (`TREE_LEVELS`): the tree's
    /// depth, or fewer for a walk whose descents start below the root (0 for a
    /// traversal that does not walk the tree).
    pub tree_levels: u32,
    /// Why this traversal, in plain words.
    pub traversal_reason: String,
    /// What rays hit (`TRIANGLES` unless voxels): voxel faces, or the triangles of the
    /// scene's mesh or of its smooth surface (`crate::triangles`).
    pub surface: Surface,
    /// Why triangles were asked for but not planned; empty otherwise.
    pub surface_reason: String,
    /// What was left out and why, in plain words.
    pub reasons: Vec<String>,
    /// Where the f32 kernel may part from the f64 reference on this scene and these
    /// settings ([`check_ray_offset`]): set by `GpuTracer` for what it renders, empty
    /// for the CPU reference. Not part of the Display, which says what the kernel is
    /// composed of: each front end shows them as warnings.
    pub warnings: Vec<String>,
}

/// The traversal of `scene` under `settings`, and why: the one asked for when it can
/// walk the scene (its plan rule), else the `auto` choice, with the reason.
fn choose_traversal(scene: &Scene, settings: &RenderSettings) -> (&'static TraversalModel, String) {
    match settings.traversal {
        Traversal::Walk(t) => match (t.plan)(scene, settings) {
            Ok(()) => (t, format!("render.traversal = \"{}\"", t.name)),
            Err(why) => {
                let (chosen, reason) = auto_traversal(scene, settings);
                (
                    chosen,
                    format!(
                        "{reason} (render.traversal = \"{}\" cannot be followed: {why})",
                        t.name
                    ),
                )
            }
        },
        Traversal::Auto => auto_traversal(scene, settings),
    }
}

/// `render.traversal = "auto"`: of the traversals that can walk the scene, the last one
/// that claims it, else the default when it can, else the last registered that can.
fn auto_traversal(scene: &Scene, settings: &RenderSettings) -> (&'static TraversalModel, String) {
    let (t, why) = auto_traversal_within(scene, settings, |_| true);
    (t, format!("auto: {why}"))
}

/// The `"auto"` traversal's choice among the traversals `fits` allows (those whose data a device
/// binds; the tree walk binds any grid), with the reason.
pub fn auto_traversal_within(
    scene: &Scene,
    settings: &RenderSettings,
    fits: impl Fn(&TraversalModel) -> bool,
) -> (&'static TraversalModel, String) {
    let able: Vec<_> = TRAVERSALS
        .iter()
        .copied()
        .filter(|t| (t.plan)(scene, settings).is_ok() && fits(t))
        .collect();
    let mut declined = Vec::new();
    for t in able.iter().rev() {
        match t.auto.map(|claim| claim(scene)) {
            Some(Ok(why)) => return (t, why),
            Some(Err(why)) => declined.push(why),
            None => {}
        }
    }
    // The default where it can walk the scene, else the last registered that can (of
    // the tree walks, which walk every scene and fit every device, the faster).
    let default = crate::technique::default_traversal();
    let chosen = if able.contains(&default) {
        default
    } else {
        *able
            .last()
            .expect("some traversal walks every scene and fits every device (the tree walks)")
    };
    let why = if declined.is_empty() {
        "the default".to_string()
    } else {
        declined.join("; ")
    };
    (chosen, why)
}

/// The surface `settings` ask for, when `scene` can have it: its own plan rule, and
/// for a triangle surface the limits every one shares: at most 255 materials, so that
/// the cells' tag is free (`crate::triangles`), a dense grid of at most 2^32 voxels.
/// Why not, otherwise.
pub fn check_surface(scene: &Scene, settings: &RenderSettings) -> Result<(), String> {
    use crate::triangles::SURFACE_TAG;
    let surface = settings.surface;
    let name = surface.name;
    if surface.traces_triangles() {
        if scene.materials.len() > SURFACE_TAG as usize {
            return Err(format!(
                "render.surface = \"{name}\" needs material index {SURFACE_TAG} free; the \
                 scene defines {} materials",
                scene.materials.len()
            ));
        }
        if scene.grid.is_sparse() {
            return Err(format!(
                "render.surface = \"{name}\": the grid is held only as its sparse tree, and \
                 triangle cells are listed in a dense grid"
            ));
        }
        let voxels = scene.grid.voxel_count() as u64;
        if voxels > u32::MAX as u64 {
            return Err(format!(
                "render.surface = \"{name}\": the grid has {voxels} voxels, more than 2^32"
            ));
        }
    }
    (surface.plan)(scene, settings)
}

/// Where the GPU kernel starts a pixel's primary ray, in grid-local coordinates:
/// `eye + advance * (sx * right_scaled + sy * up_scaled)`, a point `advance` along the
/// pixel's unnormalised direction `forward + sx * right_scaled + sy * up_scaled` from
/// the camera's eye, so `advance` times that direction's length is where its `t` starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimaryOrigin {
    /// The camera's eye moved `advance` along `forward`, in f64 before the kernel's one
    /// rounding to f32.
    pub eye: glam::DVec3,
    pub advance: f64,
}

/// Rebase the primary rays from an eye farther out than this many times the grid's
/// largest side; nearer, they start at the eye itself (`advance` 0), as they always
/// did, and the images are bit for bit those of the kernel before the rebase.
const REBASE_FROM_SIDES: f64 = 4.0;

/// The primary rays' origins for `scene` under `settings` ([`PrimaryOrigin`]). An eye
/// placed in f32 is only as precise as its ulp: 2e5 voxels out that is 0.016 voxel
/// widths, and with a view narrow enough for the grid to fill the image 1.6 % of the
/// pixels (along voxel edges) parted from the f64 reference's. A far eye's rays
/// therefore start at the grid's side of their way there instead: `advance` is the
/// eye's distance to the grid's box less one grid side, divided by the longest
/// unnormalised direction of a pixel sample (the image's corners, widened by the pixel
/// filter's reach), so that every sample's origin is still outside the box and about
/// a grid side short of it. Only the part across the view (`advance` times the
/// sample's offset from `forward`) is left to f32, where its error is relative.
pub fn primary_origin(scene: &Scene, settings: &RenderSettings) -> PrimaryOrigin {
    let g = &scene.grid;
    let cam = scene.camera.frame();
    let eye = g.to_local(cam.eye);
    let side = g.dims().max_element() as f64;
    if eye.abs().max_element() <= REBASE_FROM_SIDES * side {
        return PrimaryOrigin { eye, advance: 0.0 };
    }
    let dims = g.dims().as_dvec3();
    let outside = (-eye).max(eye - dims).max(glam::DVec3::ZERO);
    let (right, up) = primary_spans(&cam, settings);
    let reach = primary_reach(settings);
    // forward, right and up are orthogonal: a corner's length is the longest.
    let longest = (1.0 + reach * reach * (right.length_squared() + up.length_squared())).sqrt();
    let advance = ((outside.length() - side) / longest).max(0.0);
    if !advance.is_finite() {
        return PrimaryOrigin { eye, advance: 0.0 };
    }
    PrimaryOrigin {
        eye: eye + advance * cam.forward,
        advance,
    }
}

/// Whether the GPU kernel can hold `scene`'s primary rays in f32 ([`primary_origin`]):
/// an eye so far out (past about 3.4e38 voxels, f32's largest number) that where its
/// rays start, or how far apart across the view, overflows f32 would give rays of
/// infinities and NaN, an image of nothing the reference draws (`render --check` at
/// `camera.distance = 1e200`: every pixel apart). The f64 reference renders it; the GPU
/// tracer refuses it with this reason.
pub fn check_primary_origin(scene: &Scene, settings: &RenderSettings) -> Result<(), String> {
    let o = primary_origin(scene, settings);
    let (right, up) = primary_spans(&scene.camera.frame(), settings);
    let across = o.advance * primary_reach(settings) * (right.abs() + up.abs());
    let f32_max = f32::MAX as f64;
    let holds = |v: f64| v.abs() < f32_max;
    if o.eye.to_array().into_iter().all(holds)
        && holds(o.advance)
        && across.to_array().into_iter().all(holds)
    {
        return Ok(());
    }
    let eye = scene.grid.to_local(scene.camera.eye());
    Err(format!(
        "camera.distance = {} from camera.target = {} puts the eye {:.4e} voxels from the \
         grid's corner, where the GPU kernel cannot hold its rays in f32 (at most \
         {f32_max:.4e}): a nearer camera (or a wider voxel_size), or the CPU reference \
         (--backend cpu), which traces in f64",
        crate::input::short_number(scene.camera.distance),
        crate::input::short_vector(scene.camera.target),
        eye.abs().max_element()
    ))
}

/// Whether the GPU kernel can hold `scene`'s lights in f32: each light's colour times
/// its intensity, an area light's extent in voxels, and the square of the light's
/// farthest distance from the grid (in voxels, for the length of the way to it, and
/// with the inverse-square falloff in world units, which the kernel divides by). Past f32's largest number (about 3.4e38) the kernel's light
/// is an infinity or its falloff divides by one (`render --check` with a light of
/// intensity 1e60 at 1e30: 53 % of the pixels apart, NaN among them; a light 1e30
/// voxels out without the falloff, 53 % too). Every such value is in its key's range, and the f64
/// reference renders it; the GPU tracer refuses it with the light and key named.
pub fn check_lights_f32(scene: &Scene, settings: &RenderSettings) -> Result<(), String> {
    use crate::scene::{AreaShape, Light};
    let g = &scene.grid;
    let vs = g.voxel_size();
    let max = f32::MAX as f64;
    let half = 0.5 * g.dims().as_dvec3();
    let past = |what: String| Err(past_f32(&what));
    for (i, light) in scene.lights.iter().enumerate() {
        let radiance = light.color() * light.intensity();
        if radiance.max_element() >= max {
            return past(format!(
                "lights[{i}].intensity = {:e}: times its color that is {:e}",
                light.intensity(),
                radiance.max_element()
            ));
        }
        let p = g.to_local(light.position());
        // Voxels from the light to the grid's farthest point, and in world units.
        let way = (p - half).abs() + half;
        // Scaled so that a light 1e300 out is as many voxels, not an infinity.
        let longest = way.max_element();
        let far = if longest > 0.0 && longest.is_finite() {
            longest * (way / longest).length()
        } else {
            way.length()
        };
        // The kernel squares it for the direction's length, and in world units for
        // the falloff's divisor.
        let squared = far * far < max && (!settings.falloff || (far * vs).powi(2) < max);
        if !squared {
            return past(format!(
                "lights[{i}].position = {}: {far:.4e} voxels from the grid's farthest \
                 point, whose square the kernel takes (the way to the light's length, \
                 the inverse-square falloff's divisor)",
                crate::input::short_vector(light.position())
            ));
        }
        if let Light::Area(a) = light {
            let (key, extent) = match a.shape {
                AreaShape::Rect { width, height } => ("size", width.max(height)),
                AreaShape::Disk { radius } | AreaShape::Sphere { radius } => ("radius", radius),
            };
            if extent / vs >= max {
                return past(format!(
                    "lights[{i}].{key} = {extent:e}: {:e} voxels across",
                    extent / vs
                ));
            }
        }
    }
    Ok(())
}

/// What a value the GPU kernel's f32 cannot hold gets on the GPU tracer: the reference
/// is the way to render it.
const REFERENCE_IN_F64: &str = "the CPU reference (--backend cpu) traces it in f64";

/// `what` is past f32's largest number, so the GPU tracer refuses it.
fn past_f32(what: &str) -> String {
    format!(
        "{what}, past what the GPU kernel's f32 holds (at most {:.4e}); {REFERENCE_IN_F64}",
        f32::MAX
    )
}

/// Whether the kernel's f32 holds the indices of refraction it divides: at a
/// transmitting hit `eta = ior(medium) / ior(hit)` over void and the materials the grid
/// uses. Each must be a normal f32 and their largest ratio below f32's largest number
/// (about 3.4e38), so that `eta` is finite: an ior of 1e39 is an infinity in f32, and
/// `eta sin_i` of an infinite `eta` at normal incidence is NaN where the f64 reference
/// refracts the ray straight on. Every such value is in the key's range (`> 0`), and
/// the reference renders it; the GPU tracer refuses it with the material and key named.
/// A scene where nothing transmits reads no ior.
pub fn check_iors_f32(scene: &Scene) -> Result<(), String> {
    let used = scene.grid.materials_used();
    if !shading_materials(scene).iter().any(|(_, m)| m.kt > 0.0) {
        return Ok(());
    }
    let media: Vec<(usize, f64)> = (0..scene.materials.len())
        .filter(|&i| i == VOID as usize || used[i])
        .map(|i| (i, scene.materials[i].ior))
        .collect();
    let name = |i: usize| format!("materials[{}].ior", scene.materials[i].name);
    let (lo, hi) = (f64::from(f32::MIN_POSITIVE), f64::from(f32::MAX));
    if let Some(&(i, ior)) = media.iter().find(|(_, ior)| !(lo..hi).contains(ior)) {
        return Err(format!(
            "{} = {ior:e}: outside what the GPU kernel's f32 holds as a normal number \
             ({lo:.4e} to {hi:.4e}); {REFERENCE_IN_F64}",
            name(i)
        ));
    }
    let (min, max) = media
        .iter()
        .fold(((0, f64::INFINITY), (0, 0.0)), |(min, max), &(i, v)| {
            (
                if v < min.1 { (i, v) } else { min },
                if v > max.1 { (i, v) } else { max },
            )
        });
    if max.1 / min.1 >= hi {
        return Err(past_f32(&format!(
            "{} = {:e} over {} = {:e}: a ratio of indices of refraction of {:e}",
            name(max.0),
            max.1,
            name(min.0),
            min.1,
            max.1 / min.1
        )));
    }
    Ok(())
}

/// `right_scaled` and `up_scaled` of the kernel's params: the image's half-width and
/// half-height at unit distance along `forward`.
pub(crate) fn primary_spans(
    cam: &crate::scene::CameraFrame,
    settings: &RenderSettings,
) -> (glam::DVec3, glam::DVec3) {
    let aspect = settings.width as f64 / settings.height as f64;
    (
        cam.right * (cam.tan_half_vfov * aspect),
        cam.up * cam.tan_half_vfov,
    )
}

/// The largest `|sx|`, `|sy|` a pixel sample takes (1 at the image's edges), widened by
/// the pixel filter's reach: a box's half-width, or 6 sigma of the Gaussian (the
/// kernel's Box-Muller radius is at most 5.8 sigma, from the largest f32 below 1).
fn primary_reach(settings: &RenderSettings) -> f64 {
    use crate::render::PixelFilter;
    let pixels = match settings.pixel_filter {
        PixelFilter::None => 0.0,
        PixelFilter::Box => settings.filter_width,
        PixelFilter::Gaussian => 6.0 * settings.filter_width,
    };
    1.0 + 2.0 * pixels / settings.width.min(settings.height).max(1) as f64
}

/// The largest grid-local coordinate (voxels from the grid's corner) the kernel's f32
/// holds for `scene`: its grid's largest side, or the farthest a primary ray's origin
/// lies ([`primary_origin`]: the eye, or where a far eye's rays start). What the f32
/// positions of hits and offsets round to.
fn farthest_coordinate(scene: &Scene, settings: &RenderSettings) -> f64 {
    let side = scene.grid.dims().max_element() as f64;
    let o = primary_origin(scene, settings);
    let (right, up) = primary_spans(&scene.camera.frame(), settings);
    let reach = primary_reach(settings);
    // The origins fill a rectangle: its farthest coordinate is at a corner.
    let corners = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)]
        .into_iter()
        .map(|(x, y)| o.eye + o.advance * reach * (x * right + y * up))
        .fold(0.0f64, |far, p| far.max(p.abs().max_element()));
    // Only a ray that enters the box hits and offsets anything. It enters within
    // |eye - centre| + r of the eye (r the box's half-diagonal) and starts at least
    // `advance` along (its unnormalised direction is at least unit long), so its origin
    // is at most the difference from where it enters: a wide view from a far eye has
    // corners far across the view whose rays all miss.
    let dims = scene.grid.dims().as_dvec3();
    let eye = scene.grid.to_local(scene.camera.eye());
    let r = 0.5 * dims.length();
    let reaching = side + (eye - 0.5 * dims).length() + r - o.advance;
    side.max(corners.min(reaching))
}

/// The smallest `render.ray_offset` (voxel widths) the f32 kernel resolves on `scene`:
/// two f32 ulps of its farthest grid-local coordinate (the grid's largest side, or that
/// of the primary rays' origins, where a hit is as precise as its ray's origin). Below it `p + eps n`
/// rounds back onto or across the face in f32, where the f64 reference moves off it,
/// and the two tracers part at faces (`render --check` of experiments/area_lights.toml,
/// the seed scene at 16^3, at 32x32): an offset of 2e-6 voxel widths drew 1.3 % of the
/// pixels apart and 1e-9 39 %, 4e-6 none; at 256^3 (48x48) 3e-5 0.7 %, 6.2e-5 none.
/// (Before a far eye's rays started near the grid, the default 1e-3 at
/// `camera.distance = 1e5`, a view narrowed to the grid, drew 4.4 % apart; now none, at
/// 2e5 and 1e7 too.)
pub fn min_ray_offset(scene: &Scene, settings: &RenderSettings) -> f64 {
    // An f32 ulp at `far`, in f64 so that an eye past f32's range still has one.
    let far = farthest_coordinate(scene, settings).max(1.0);
    2.0 * 2f64.powf(far.log2().floor() - 23.0)
}

/// `render.ray_offset` against what the kernel resolves on `scene`
/// ([`min_ray_offset`]): `Err` says why the GPU image will part from the reference's.
/// Every value of the key's declared range is accepted (the grid and camera decide
/// this bound, not the key); the GPU tracer puts it in its plan's `warnings`, which
/// `voxlab render`, the viewer and Python's `Image.warnings` show.
pub fn check_ray_offset(scene: &Scene, settings: &RenderSettings) -> Result<(), String> {
    let min = min_ray_offset(scene, settings);
    if settings.ray_offset >= min {
        return Ok(());
    }
    let d = scene.grid.dims();
    let far = farthest_coordinate(scene, settings);
    let what = if far > d.max_element() as f64 {
        format!(
            "its primary rays start up to {far:.4e} voxels from the grid's corner (at \
             the eye, which camera.distance and camera.target place; a closer camera \
             allows a smaller offset)"
        )
    } else {
        format!(
            "its farthest face is {} voxels from its corner",
            d.max_element()
        )
    };
    Err(format!(
        "render.ray_offset = {} is below what the GPU kernel's f32 resolves on this \
         {}x{}x{} grid: {what}, where two f32 ulps are {min:.3e} voxel widths; an offset \
         below that can round away, and the GPU image then parts from the f64 reference's \
         at faces",
        settings.ray_offset, d.x, d.y, d.z
    ))
}

/// The traversal `settings` name, when it can walk `scene` (its plan rule); the
/// reason otherwise, for the experiment loader (the plan itself walks the scene with the
/// `auto` choice and says why).
pub(crate) fn check_traversal(scene: &Scene, settings: &RenderSettings) -> Result<(), String> {
    let Traversal::Walk(t) = settings.traversal else {
        return Ok(());
    };
    (t.plan)(scene, settings).map_err(|why| {
        let others: Vec<String> = Traversal::all()
            .into_iter()
            .filter(|o| *o != settings.traversal)
            .map(|o| format!("\"{}\"", o.name()))
            .collect();
        format!(
            "\"{}\" cannot walk this scene: {why}; use {}",
            t.name,
            others.join(" or ")
        )
    })
}

/// The most levels of the sparse tree one descent of `traversal` takes on a grid of
/// `dims` (the tree's depth unless its descents start below the root); 0 for one that
/// walks no tree.
pub fn tree_levels(traversal: &TraversalModel, dims: glam::UVec3) -> u32 {
    if !traversal.walks_tree {
        return 0;
    }
    let levels = match traversal.descent_levels {
        Some(levels) => levels(dims),
        None => crate::sparse::levels_for(dims, crate::sparse::GPU_LOG_BRANCH),
    };
    // The grid limits keep every tree within what the kernel unrolls.
    debug_assert!(levels <= crate::sparse::MAX_GPU_LEVELS);
    levels
}

/// What `settings` ask of a grid held only as its sparse tree that needs the dense grid:
/// the cone features (their pyramids are built from the dense grid).
/// The key that asks for it and why, for the experiment loader; the plan itself walks
/// the tree and leaves the cone features out.
pub fn check_sparse_grid(
    scene: &Scene,
    settings: &RenderSettings,
) -> Result<(), (&'static str, String)> {
    if !scene.grid.is_sparse() {
        return Ok(());
    }
    let d = scene.grid.dims();
    let held = format!(
        "this {}x{}x{} grid is held only as its sparse tree (more than {} voxels)",
        d.x,
        d.y,
        d.z,
        crate::scene::DENSE_MAX_VOXELS
    );
    let f = &settings.features;
    let asked: Vec<String> = f
        .shadow_model
        .pyramid
        .then(|| format!("shadow_model = \"{}\"", f.shadow_model.name))
        .into_iter()
        .chain(
            f.terms
                .iter()
                .filter(|t| t.pyramid)
                .map(|t| format!("{} = true", t.name)),
        )
        .collect();
    if !asked.is_empty() {
        return Err((
            "features",
            format!(
                "cone tracing ({}) builds its pyramids from the dense grid, and {held}: turn \
                 the cone features off or use a smaller grid",
                asked.join(", ")
            ),
        ));
    }
    Ok(())
}

/// Whether some light sends out anything (`color * intensity` not 0): a scene whose
/// lights are all dark lights nothing, and casts no shadow ray
/// (`crate::technique::shading::point_contribution` skips them where `lit` is 0).
pub(crate) fn some_light_emits(scene: &Scene) -> bool {
    scene.lights.iter().any(|l| !l.is_dark())
}

/// Whether some material the grid holds is diffuse (`kd > 0`): the lighting terms' plan
/// rules.
pub(crate) fn diffuse_in_grid(scene: &Scene) -> bool {
    shading_materials(scene).iter().any(|(_, m)| m.kd > 0.0)
}

/// The materials a hit can be shaded with: every non-void material in the grid (a hit
/// on void is shaded by its medium, never void itself).
pub(crate) fn shading_materials(scene: &Scene) -> Vec<(usize, &Material)> {
    let used = scene.grid.materials_used();
    scene
        .materials
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != VOID as usize && used[i])
        .collect()
}

/// Whether some hit could undergo total internal reflection: a transition from medium m
/// to hit material h with ior(m) > ior(h) (so eta > 1) whose shading material transmits.
/// Media are any used material or void; equal iors give eta = 1 and k = c^2 >= 0, never
/// TIR, in f32 as in f64.
fn tir_possible(scene: &Scene) -> bool {
    let used = scene.grid.materials_used();
    let ior = |i: usize| scene.materials.get(i).map_or(1.0, |m| m.ior);
    let kt = |i: usize| scene.materials.get(i).map_or(0.0, |m| m.kt);
    let media: Vec<usize> = (0..scene.materials.len())
        .filter(|&i| i == VOID as usize || used[i])
        .collect();
    media.iter().any(|&m| {
        media.iter().any(|&h| {
            let s = if h == VOID as usize { m } else { h };
            // A Fresnel dielectric reflects kr whether or not the ray is trapped.
            let fixed = scene.materials.get(s).map(|m| m.dielectric) == Some(Dielectric::Fixed);
            m != h && s != VOID as usize && kt(s) > 0.0 && fixed && ior(m) > ior(h)
        })
    })
}

/// A boolean feature of the kernel: its shader def and the [`Plan`] field that holds
/// it. [`KERNEL_FLAGS`] is the one table that the plan's printing, its shader defs (and
/// so the pipeline cache's key) and the tests' enumeration read.
#[derive(Clone, Copy)]
pub struct KernelFlag {
    /// The shader def (`#ifdef REFLECTION`) and the plan's printed name.
    pub name: &'static str,
    /// In [`Plan::FLAGS`]: the tests compose every combination of these
    /// ([`Plan::all_variants`]). The others select a small, separately tested piece
    /// (the pixel filter's jitter, the seed's rules, the ray cutoff, the Fresnel split,
    /// Lambertian emitters).
    pub enumerated: bool,
    /// The plan turns it off where the scene and settings need none of its code, and
    /// turning it on again changes no image, only the cost: [`Plan::with_all_code`] sets
    /// every such flag (the bench's full kernel, and the tests that the plan leaving
    /// code out never changes an image). The others pick a model or what is recorded.
    pub only_code: bool,
    get: fn(&Plan) -> bool,
    set: fn(&mut Plan, bool),
}

/// A row of [`KERNEL_FLAGS`]: the def's name, the `Plan` field that holds it, whether
/// the tests enumerate it, and whether it only leaves code out.
macro_rules! kernel_flag {
    ($name:literal, $field:ident, enumerated: $enumerated:expr, only_code: $only_code:expr) => {
        KernelFlag {
            name: $name,
            enumerated: $enumerated,
            only_code: $only_code,
            get: |p| p.$field,
            set: |p, on| p.$field = on,
        }
    };
}

/// Every kernel flag, in the order plans print them.
pub const KERNEL_FLAGS: [KernelFlag; 11] = [
    kernel_flag!("REFLECTION", reflection, enumerated: true, only_code: true),
    kernel_flag!("REFRACTION", refraction, enumerated: true, only_code: true),
    kernel_flag!("SHADOWS", shadows, enumerated: true, only_code: true),
    kernel_flag!("EMISSION", emission, enumerated: true, only_code: true),
    kernel_flag!("ACCUMULATE", accumulate, enumerated: true, only_code: true),
    // Changes no image either, but records what the timed frames must not.
    kernel_flag!("COUNT_RAYS", count_rays, enumerated: true, only_code: false),
    kernel_flag!("PIXEL_FILTER", pixel_filter, enumerated: false, only_code: false),
    kernel_flag!("SEED_RULES", seed_rules, enumerated: false, only_code: false),
    // Off at a cutoff of 0, which cuts nothing: the settings' choice of the exact tree.
    kernel_flag!("RAY_CUTOFF", ray_cutoff, enumerated: false, only_code: false),
    kernel_flag!("FRESNEL", fresnel, enumerated: false, only_code: true),
    kernel_flag!("LAMBERTIAN_LIGHTS", lambertian_lights, enumerated: false, only_code: true),
];

impl Plan {
    /// The enumerated flags of [`KERNEL_FLAGS`], in their order.
    pub const FLAGS: [&'static str; 6] = {
        let mut out = [""; 6];
        let (mut i, mut n) = (0, 0);
        while i < KERNEL_FLAGS.len() {
            if KERNEL_FLAGS[i].enumerated {
                out[n] = KERNEL_FLAGS[i].name;
                n += 1;
            }
            i += 1;
        }
        assert!(
            n == out.len(),
            "Plan::FLAGS holds every enumerated kernel flag"
        );
        out
    };

    /// The plan for rendering `scene` with `settings`, without ray counting.
    ///
    /// One function because each rule reads what the rules before it decided (shadows
    /// from the lit materials and lights, the shadow model from the shadows, the walk and
    /// stack from the grid and depths), and the reasons are collected in that order.
    pub fn new(scene: &Scene, settings: &RenderSettings) -> Self {
        let mats = shading_materials(scene);
        let mut reasons = Vec::new();

        let reflects = mats.iter().any(|(_, m)| m.kr > 0.0);
        let tir = tir_possible(scene);
        let reflection = if settings.max_reflection_depth == 0 {
            reasons.push("reflection: max_reflection_depth is 0".to_string());
            false
        } else if !reflects && !tir {
            reasons.push(
                "reflection: no material in the grid has kr > 0, and no transmitting \
                 material can meet total internal reflection"
                    .to_string(),
            );
            false
        } else {
            true
        };

        let transmits = mats.iter().any(|(_, m)| m.kt > 0.0);
        let refraction = if settings.max_refraction_depth == 0 {
            reasons.push("refraction: max_refraction_depth is 0".to_string());
            false
        } else if !transmits {
            reasons.push("refraction: no material in the grid has kt > 0".to_string());
            false
        } else {
            true
        };

        let lit = mats.iter().any(|(_, m)| m.is_lit());
        let shadows = if scene.lights.is_empty() {
            reasons.push("shadows and local lighting: the scene has no lights".to_string());
            false
        } else if !some_light_emits(scene) {
            reasons.push(
                "shadows and local lighting: every light has intensity 0 or color 0".to_string(),
            );
            false
        } else if !lit {
            reasons.push(
                "shadows and local lighting: no material in the grid has kd > 0 or ks > 0"
                    .to_string(),
            );
            false
        } else {
            true
        };

        let emission = mats.iter().any(|(_, m)| m.emission != glam::DVec3::ZERO);
        if !emission {
            reasons.push("emission: no material in the grid emits".to_string());
        }

        let fresnel = (reflection || refraction)
            && mats
                .iter()
                .any(|(_, m)| m.kt > 0.0 && m.dielectric == Dielectric::Fresnel);
        let lambertian_lights = shadows && scene.lights.iter().any(|l| l.is_lambertian());

        let default_model = crate::technique::default_shadow_model();
        let asked_model = settings.features.shadow_model;
        let shadow_model = if !shadows {
            if asked_model != default_model {
                reasons.push(format!("shadow model {}: no shadow rays", asked_model.name));
            }
            default_model
        } else {
            match (asked_model.plan)(scene, settings) {
                Ok(()) => asked_model,
                Err(why) => {
                    reasons.push(format!(
                        "shadow model {}: {why}; hard shadows at the light centres instead",
                        asked_model.name
                    ));
                    default_model
                }
            }
        };
        let sampled_lights = scene.lights.iter().filter(|l| l.is_area()).count();
        if shadows && shadow_model == default_model && sampled_lights > 0 {
            reasons.push(format!(
                "area lights: shadow model {}; {sampled_lights} area light(s) act as point \
                 lights at their centres",
                shadow_model.name
            ));
        }

        let default = crate::technique::TRANSMITTANCES[0];
        let asked = settings.features.transmittance.model();
        let transmittance = if asked.index() == 0 {
            default
        } else if !shadows {
            reasons.push(format!("{}: no shadow rays", asked.name));
            default
        } else if !shadow_model.shadow_rays {
            reasons.push(format!(
                "{}: shadow model {} casts no shadow rays",
                asked.name, shadow_model.name
            ));
            default
        } else {
            match (asked.plan)(scene, settings) {
                Ok(()) => asked,
                Err(why) => {
                    reasons.push(format!("{}: {why}", asked.name));
                    default
                }
            }
        };

        let no_filter = crate::technique::default_reconstruction();
        let asked_filter = settings.features.reconstruction;
        let reconstruction = if asked_filter == no_filter {
            no_filter
        } else if !(shadows && shadow_model.stochastic && shadow_model.shadow_rays) {
            reasons.push(format!(
                "reconstruction {}: {}; the image as traced",
                asked_filter.name,
                if shadows {
                    format!(
                        "the shadow model {} samples no shadow rays to filter",
                        shadow_model.name
                    )
                } else {
                    "no shadow rays".to_string()
                }
            ));
            no_filter
        } else {
            asked_filter
        };

        let pixel_filter = settings.pixel_filter != crate::render::PixelFilter::None;
        // A cutoff of 0 (the default) is no cut, not something left out: no reason.
        let ray_cutoff = if crate::ray_cutoff::cutoff(settings) <= 0.0 {
            false
        } else if !(reflection || refraction || shadows) {
            // Primary rays are never cut: with nothing after them there is nothing to cut.
            reasons.push("ray cutoff: no secondary or shadow rays to cut".to_string());
            false
        } else {
            true
        };
        let seed_rules = settings.rules == crate::render::Rules::Seed;
        let sampled = shadow_model.stochastic || pixel_filter;
        let accumulate = sampled && settings.spp > 1;
        if !sampled && settings.spp > 1 {
            reasons.push(format!(
                "accumulation: spp {} but nothing is sampled, so every frame is the same \
                 image; rendered once",
                settings.spp
            ));
        }

        // The stack holds refraction rays while reflections are traced first
        // (RenderSettings::ray_stack_size); one kind alone never holds more than one.
        let ray_stack_size = if reflection && refraction {
            settings.ray_stack_size()
        } else {
            if settings.ray_stack_size() > 1 {
                reasons.push(format!(
                    "ray stack: 1 entry instead of {} ({})",
                    settings.ray_stack_size(),
                    if reflection || refraction {
                        "only one kind of secondary ray"
                    } else {
                        "no secondary rays"
                    }
                ));
            }
            1
        };

        let mut terms = Vec::new();
        for &t in &settings.features.terms {
            let kept = if t.pyramid && scene.grid.is_sparse() {
                Err(
                    "the grid is held only as its sparse tree, and the cone pyramids are \
                     built from the dense grid"
                        .to_string(),
                )
            } else {
                (t.plan)(scene, settings)
            };
            match kept {
                Ok(()) => terms.push(t),
                Err(why) => reasons.push(format!("lighting term {}: {why}", t.name)),
            }
        }
        let pyramid = (shadow_model.pyramid || terms.iter().any(|t| t.pyramid))
            .then(|| PyramidLayout::new(scene.grid.dims(), settings.cones.levels));

        let (traversal, traversal_reason) = choose_traversal(scene, settings);
        let (surface, surface_reason) = match check_surface(scene, settings) {
            Ok(()) => (settings.surface, String::new()),
            Err(why) => (Surface::default(), format!("{why}; voxels instead")),
        };
        let tree_levels = tree_levels(traversal, scene.grid.dims());

        Self {
            traversal,
            tree_levels,
            traversal_reason,
            surface,
            surface_reason,
            reflection,
            refraction,
            shadows,
            emission,
            fresnel,
            lambertian_lights,
            shadow_model,
            transmittance,
            reconstruction,
            accumulate,
            terms,
            pixel_filter,
            ray_cutoff,
            seed_rules,
            pyramid,
            count_rays: false,
            ray_stack_size,
            dda_unroll: 1,
            walk_more_bindings: 0,
            walk_variant: 0,
            walk_data: None,
            reasons,
            warnings: Vec::new(),
        }
    }

    /// Whether the radiance pyramid is built: a planned term reads it.
    /// Whether this plan reads `key` of an experiment file, decided from the technique
    /// registry: a shadow model's own settings (`techniques.<model>.*`) are read only
    /// under that model, a shared group's (`cones.*`) only where its `used` rule says
    /// the features use it; every other key (scene, camera, lights, materials,
    /// `render.*`) by every plan. `Err` says which techniques would read it.
    pub fn reads(&self, key: &str, features: &crate::render::Features) -> Result<(), String> {
        use crate::technique::{LIGHTING_TERMS, SETTING_GROUPS, SHADOW_MODELS};
        if let Some(rest) = key.strip_prefix("techniques.") {
            let model = rest.split('.').next().unwrap_or(rest);
            if model == self.shadow_model.name {
                return Ok(());
            }
            if let Some(r) = crate::technique::reconstruction(model) {
                return if r == self.reconstruction {
                    Ok(())
                } else {
                    Err(format!(
                        "this experiment never reads {key}: it renders with the \
                         reconstruction \"{}\"; the reconstruction \"{model}\" would read it \
                         (features.reconstruction = \"{model}\", with a shadow model that \
                         samples)",
                        self.reconstruction.name
                    ))
                };
            }
            let known = SHADOW_MODELS.iter().any(|m| m.name == model);
            return Err(format!(
                "this experiment never reads {key}: it renders with the shadow model \"{}\"; {}",
                self.shadow_model.name,
                if known {
                    format!(
                        "the shadow model \"{model}\" would read it (features.shadow_model = \
                         \"{model}\")"
                    )
                } else {
                    format!("no registered shadow model is called \"{model}\"")
                }
            ));
        }
        let group = SETTING_GROUPS.iter().find(|g| {
            key.strip_prefix(g.table)
                .is_some_and(|r| r.starts_with('.'))
        });
        match group {
            Some(g) if !(g.used)(features) => {
                let prefix = format!("{}.", g.table);
                let readers: Vec<String> = SHADOW_MODELS
                    .iter()
                    .filter(|m| m.shared_settings.iter().any(|k| k.starts_with(&prefix)))
                    .map(|m| format!("the shadow model \"{}\"", m.name))
                    .chain(
                        LIGHTING_TERMS
                            .iter()
                            .filter(|t| t.shared_settings.iter().any(|k| k.starts_with(&prefix)))
                            .map(|t| format!("the lighting term \"{}\"", t.name)),
                    )
                    .collect();
                Err(format!(
                    "this experiment never reads {key}: no feature it renders with uses \
                     [{}]; {} would",
                    g.table,
                    readers.join(" or ")
                ))
            }
            _ => Ok(()),
        }
    }

    pub fn radiance_pyramid(&self) -> bool {
        self.terms.iter().any(|t| t.radiance_pyramid)
    }

    /// Frames the image is accumulated over: `spp` when something is sampled, else 1
    /// (every frame would be the same image). Both tracers render this many.
    pub fn frames(&self, settings: &RenderSettings) -> u32 {
        if self.accumulate {
            settings.spp.max(1)
        } else {
            1
        }
    }

    /// Whether `frames` is a range of this plan's accumulation: non-empty and within its
    /// frames; else why not.
    pub fn check_frames(
        &self,
        settings: &RenderSettings,
        frames: &Range<u32>,
    ) -> Result<(), String> {
        let (a, b) = (frames.start, frames.end);
        if a >= b {
            return Err(format!(
                "frames {a}..{b}: an empty range; render at least one frame"
            ));
        }
        let cap = self.frames(settings);
        if b <= cap {
            return Ok(());
        }
        if self.accumulate {
            return Err(format!(
                "frames {a}..{b}: past the end of the accumulation, {cap} frames \
                 (settings.spp = {} caps it)",
                settings.spp
            ));
        }
        let why = if settings.spp <= 1 {
            "settings.spp is 1".to_string()
        } else {
            format!(
                "nothing is sampled (shadow model {} draws no samples here and there is no \
                 pixel filter), so every frame is the same image",
                self.shadow_model.name
            )
        };
        Err(format!(
            "frames {a}..{b}: this plan does not accumulate ({why}); it renders one frame, \
             frames 0..1"
        ))
    }

    /// Planes of `vec4` per pixel and frame the kernel writes: the radiance, and with a
    /// reconstruction that filters (`PRIMARY_LAYERS`) four of the primary layers
    /// (`crate::frame::PrimaryLayers`; shaders/trace.wgsl says which).
    pub fn layer_slices(&self) -> u32 {
        if self.reconstruction.cpu.is_some() {
            PRIMARY_LAYER_SLICES
        } else {
            1
        }
    }

    /// The same plan with ray counting compiled in or out.
    pub(crate) fn with_counting(mut self, count_rays: bool) -> Self {
        self.count_rays = count_rays;
        self
    }

    /// The kernel's flags that are on, in the order plans are printed: [`Plan::FLAGS`],
    /// with the shadow model's label (`AREA_LIGHTS`) and the transmittance model, when
    /// not the default, by its name in capitals (`BEER_LAMBERT`), after `EMISSION`, and
    /// the lighting terms' labels (`AMBIENT_OCCLUSION`) last.
    pub(crate) fn flags_on(&self) -> Vec<String> {
        let at = Self::FLAGS
            .iter()
            .position(|&n| n == "ACCUMULATE")
            .unwrap_or(0);
        let shadow_model =
            (!self.shadow_model.label.is_empty()).then(|| self.shadow_model.label.to_string());
        let transmittance = (self.transmittance.index() != 0)
            .then(|| self.transmittance.name.to_uppercase().replace('-', "_"));
        Self::FLAGS[..at]
            .iter()
            .filter(|n| self.flag(n))
            .map(|n| n.to_string())
            .chain(shadow_model)
            .chain(transmittance)
            .chain(
                Self::FLAGS[at..]
                    .iter()
                    .filter(|n| self.flag(n))
                    .map(|n| n.to_string()),
            )
            .chain(self.terms.iter().map(|t| t.label.to_string()))
            .collect()
    }

    /// The settings of the shadow model and lighting terms the plan composed, as `voxlab
    /// techniques` lists them, and every setting of a shared table one of them reads
    /// (each once, in order): what else a render the driver's loop limit cuts could
    /// change (a cone march's step and its cones, say).
    pub fn technique_settings(&self) -> Vec<String> {
        use crate::technique::Slot;
        let mut keys = Vec::new();
        for row in crate::technique::listing() {
            let composed = match row.slot {
                Slot::Shadow => row.name == self.shadow_model.name,
                Slot::Lighting => self.terms.iter().any(|t| t.name == row.name),
                _ => false,
            };
            if composed {
                for key in row.settings {
                    if !keys.contains(&key) {
                        keys.push(key);
                    }
                }
            }
        }
        for group in crate::technique::SETTING_GROUPS {
            let prefix = format!("{}.", group.table);
            if keys.iter().any(|k| k.starts_with(&prefix)) {
                for s in group.settings {
                    let key = format!("{prefix}{}", s.key());
                    if !keys.contains(&key) {
                        keys.push(key);
                    }
                }
            }
        }
        keys
    }

    /// The value of a flag of [`KERNEL_FLAGS`] by name (false for a name it lacks).
    pub fn flag(&self, name: &str) -> bool {
        KERNEL_FLAGS
            .iter()
            .find(|f| f.name == name)
            .is_some_and(|f| (f.get)(self))
    }

    /// The kernel with none of the code the plan leaves out: every
    /// [`KernelFlag::only_code`] flag on, the settings' own stack size, and the cone
    /// pyramids built. The shadow model, the lighting terms and the rules stay the plan's:
    /// they are choices, not code left out. Rendered with `scene` and `settings` it gives
    /// the plan's image (tests/gpu_extremes.rs), at the cost `voxlab bench --plan` prints.
    pub fn with_all_code(&self, scene: &Scene, settings: &RenderSettings) -> Plan {
        let mut full = self.clone();
        for f in KERNEL_FLAGS.iter().filter(|f| f.only_code) {
            (f.set)(&mut full, true);
        }
        full.ray_stack_size = settings.ray_stack_size();
        full.pyramid = Some(PyramidLayout::new(scene.grid.dims(), settings.cones.levels));
        full.reasons.clear();
        full
    }

    /// Sets a flag of [`KERNEL_FLAGS`] by name (for tests that enumerate variants).
    pub fn set_flag(&mut self, name: &str, on: bool) {
        let f = KERNEL_FLAGS
            .iter()
            .find(|f| f.name == name)
            .unwrap_or_else(|| panic!("unknown plan flag {name}"));
        (f.set)(self, on);
    }

    /// Every combination of flags and transmittance models with the given stack size
    /// (2^FLAGS times the models), with the default shadow model; `tests/shadow_models.rs`
    /// composes every shadow model apart.
    pub fn all_variants(ray_stack_size: u32) -> Vec<Plan> {
        let models = crate::technique::TRANSMITTANCES.len() as u32;
        (0..models << Self::FLAGS.len())
            .map(|code| {
                let bits = code & ((1 << Self::FLAGS.len()) - 1);
                let transmittance =
                    crate::technique::TRANSMITTANCES[(code >> Self::FLAGS.len()) as usize];
                let mut p = Plan {
                    reflection: false,
                    refraction: false,
                    shadows: false,
                    emission: false,
                    fresnel: false,
                    lambertian_lights: false,
                    shadow_model: crate::technique::default_shadow_model(),
                    transmittance,
                    reconstruction: crate::technique::default_reconstruction(),
                    accumulate: false,
                    terms: Vec::new(),
                    pixel_filter: false,
                    ray_cutoff: false,
                    seed_rules: false,
                    pyramid: None,
                    count_rays: false,
                    ray_stack_size,
                    dda_unroll: 1,
                    walk_more_bindings: 0,
                    walk_variant: 0,
                    walk_data: None,
                    traversal: crate::technique::default_traversal(),
                    tree_levels: 0,
                    traversal_reason: String::new(),
                    surface: Surface::default(),
                    surface_reason: String::new(),
                    reasons: Vec::new(),
                    warnings: Vec::new(),
                };
                for (i, f) in Self::FLAGS.iter().enumerate() {
                    p.set_flag(f, bits & (1 << i) != 0);
                }
                p
            })
            .collect()
    }

    /// The naga_oil shader defs of this variant: one boolean def per flag that is on,
    /// and the stack size as an integer def. Also the key of the pipeline cache.
    pub fn shader_defs(&self) -> ShaderDefs {
        let mut defs = ShaderDefs::new();
        for f in KERNEL_FLAGS.iter().filter(|f| (f.get)(self)) {
            defs.insert(f.name.to_string(), ShaderDefValue::Bool(true));
        }
        // The transmittance model's module is composed in; a model other than the
        // default keys the cache by its index.
        if self.transmittance.index() != 0 {
            defs.insert(
                "TRANSMITTANCE_ID".to_string(),
                ShaderDefValue::UInt(self.transmittance.index()),
            );
        }
        // The shadow model's module is composed in; a model other than the default keys
        // the cache by its index.
        if self.shadow_model.index() != 0 {
            defs.insert(
                "SHADOW_MODEL_ID".to_string(),
                ShaderDefValue::UInt(self.shadow_model.index()),
            );
        }
        // A reconstruction's filter reads the primary layers the kernel then writes
        // beside the radiance (Plan::layer_slices).
        if self.layer_slices() > 1 {
            defs.insert("PRIMARY_LAYERS".to_string(), ShaderDefValue::Bool(true));
        }
        // Any cone feature: the pyramids' bindings and the cone module are in; the
        // radiance pyramid's only when a term reads it.
        if self.pyramid.is_some() {
            defs.insert("CONES".to_string(), ShaderDefValue::Bool(true));
        }
        if self.radiance_pyramid() {
            defs.insert("RADIANCE_PYRAMID".to_string(), ShaderDefValue::Bool(true));
        }
        // The lighting terms' modules are composed in (crate::gpu::compose); their set
        // keys the cache.
        if !self.terms.is_empty() {
            defs.insert("LIGHTING_TERMS".to_string(), ShaderDefValue::Bool(true));
            defs.insert(
                "LIGHTING_TERMS_MASK".to_string(),
                ShaderDefValue::UInt(self.terms.iter().map(|t| 1 << t.index()).sum()),
            );
        }
        // The traversal's module is composed in; one other than the default keys the
        // cache by its index, a tree walk by the tree's depth too.
        if self.traversal.index() != 0 {
            defs.insert(
                "TRAVERSAL_ID".to_string(),
                ShaderDefValue::UInt(self.traversal.index()),
            );
        }
        if self.traversal.walks_tree {
            defs.insert(
                "TREE_LEVELS".to_string(),
                ShaderDefValue::UInt(self.tree_levels),
            );
        }
        if self.surface.traces_triangles() {
            defs.insert("TRIANGLES".to_string(), ShaderDefValue::Bool(true));
        }
        defs.insert(
            "DDA_UNROLL".to_string(),
            ShaderDefValue::UInt(self.dda_unroll),
        );
        defs.insert(
            "WALK_MORE_BINDINGS".to_string(),
            ShaderDefValue::UInt(self.walk_more_bindings),
        );
        defs.insert(
            "WALK_VARIANT".to_string(),
            ShaderDefValue::UInt(self.walk_variant),
        );
        defs.insert(
            "RAY_STACK_SIZE".to_string(),
            ShaderDefValue::UInt(self.ray_stack_size.max(1)),
        );
        defs
    }
}

impl fmt::Display for Plan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let unenumerated = KERNEL_FLAGS
            .iter()
            .filter(|f| !f.enumerated && (f.get)(self))
            .map(|f| f.name.to_string());
        let on: Vec<String> = self.flags_on().into_iter().chain(unenumerated).collect();
        write!(
            f,
            "plan: [{}] ray stack {}",
            if on.is_empty() {
                "primary only".to_string()
            } else {
                on.join(", ")
            },
            self.ray_stack_size
        )?;
        write!(f, "\n  traversal: {}", self.traversal.label)?;
        if self.traversal.walks_tree {
            let s = if self.tree_levels == 1 { "" } else { "s" };
            write!(f, ", descents of {} level{s}", self.tree_levels)?;
        }
        write!(f, " ({})", self.traversal_reason)?;
        if let Some(data) = &self.walk_data {
            write!(f, "\n  walk data: {data}")?;
        }
        if self.surface.traces_triangles() {
            write!(
                f,
                "\n  surface: {} (render.surface = \"{}\")",
                self.surface.label, self.surface.name
            )?;
        } else if !self.surface_reason.is_empty() {
            write!(
                f,
                "\n  surface: {} ({})",
                self.surface.label, self.surface_reason
            )?;
        }
        if let Some(layout) = &self.pyramid {
            write!(f, "\n  {}", memory_line(layout, self.radiance_pyramid()))?;
        }
        if !self.reconstruction.label.is_empty() {
            write!(f, "\n  reconstruction: {}", self.reconstruction.label)?;
        }
        for r in &self.reasons {
            write!(f, "\n  left out: {r}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Rules;
    use crate::scene::{Light, seed_ids, seed_scene};

    #[test]
    fn seed_scene_needs_everything() {
        let s = seed_scene(16).unwrap();
        let p = Plan::new(&s, &RenderSettings::default());
        assert!(p.reflection && p.refraction && p.shadows && !p.count_rays);
        // Depth limits 4/4: the chain of reflections has 5 hits (RenderSettings::ray_stack_size).
        assert_eq!(p.ray_stack_size, 5);
        assert!(!p.emission);
        assert_eq!(p.reasons.len(), 1, "{p}");
    }

    #[test]
    fn depth_zero_and_no_lights_leave_everything_out() {
        let mut s = seed_scene(16).unwrap();
        s.lights.clear();
        let settings = RenderSettings {
            max_reflection_depth: 0,
            max_refraction_depth: 0,
            ..Default::default()
        };
        let p = Plan::new(&s, &settings);
        assert!(!p.reflection && !p.refraction && !p.shadows);
        assert_eq!(p.ray_stack_size, 1);
        // Depth 0/0 needs one stack entry anyway: no stack note.
        assert_eq!(p.reasons.len(), 4, "{p}");
        // RAY_STACK_SIZE, DDA_UNROLL, WALK_MORE_BINDINGS and WALK_VARIANT, always defined, and the walk's id where
        // `"auto"` takes a walk other than the default (the box walk from side 12).
        let names: Vec<String> = p.shader_defs().into_keys().collect();
        for n in &names {
            assert!(
                [
                    "RAY_STACK_SIZE",
                    "DDA_UNROLL",
                    "WALK_MORE_BINDINGS",
                    "WALK_VARIANT",
                    "TRAVERSAL_ID"
                ]
                .contains(&n.as_str()),
                "{names:?}"
            );
        }
        assert_eq!(
            names.len(),
            4 + usize::from(p.traversal.index() != 0),
            "{names:?}"
        );
    }

    /// The seed's rules are compiled in only when asked for, and printed with the plan:
    /// voxlab's own rules compose no code of the seed's, and the other way round.
    #[test]
    fn the_seed_rules_are_composed_only_under_the_seed_rules() {
        let s = seed_scene(16).unwrap();
        for (rules, on) in [(Rules::Consistent, false), (Rules::Seed, true)] {
            let settings = RenderSettings {
                rules,
                ..Default::default()
            };
            let p = Plan::new(&s, &settings);
            assert_eq!(p.seed_rules, on);
            assert_eq!(p.shader_defs().contains_key("SEED_RULES"), on, "{p}");
            assert_eq!(p.to_string().contains("SEED_RULES"), on, "{p}");
        }
    }

    #[test]
    fn transmission_keeps_reflection_for_tir() {
        // No material reflects, but glass (ior 1.5) meets void (ior 1): TIR adds kt to
        // the reflection weight, so the reflection path must stay.
        let mut s = seed_scene(16).unwrap();
        for m in &mut s.materials {
            m.kr = 0.0;
        }
        let p = Plan::new(&s, &RenderSettings::default());
        assert!(p.reflection, "{p}");

        // With every ior equal TIR is impossible and no reflection remains.
        for m in &mut s.materials {
            m.ior = 1.0;
        }
        let p = Plan::new(&s, &RenderSettings::default());
        assert!(!p.reflection && p.refraction, "{p}");
        assert_eq!(p.ray_stack_size, 1);
    }

    #[test]
    fn only_materials_in_the_grid_count() {
        let mut s = seed_scene(16).unwrap();
        for v in s.grid.data_mut() {
            if *v != seed_ids::SOLID {
                *v = VOID;
            }
        }
        let p = Plan::new(&s, &RenderSettings::default());
        // Solid reflects (kr 0.2) but has kt 0.
        assert!(p.reflection && !p.refraction && p.shadows, "{p}");
        s.lights.retain(|l| !matches!(l, Light::Point(_)));
        assert!(!Plan::new(&s, &RenderSettings::default()).shadows);
    }

    /// Dark lights (intensity 0 or color 0, of every kind) light nothing: with only
    /// those, no shading code; one light that emits brings it back.
    #[test]
    fn dark_lights_leave_the_shading_out() {
        let mut s = seed_scene(16).unwrap();
        let lights = s.lights.clone();
        for (i, l) in s.lights.iter_mut().enumerate() {
            match l {
                Light::Point(p) if i % 2 == 0 => p.intensity = 0.0,
                Light::Point(p) => p.color = glam::DVec3::ZERO,
                Light::Area(a) => a.intensity = 0.0,
            }
        }
        s.lights.push(Light::Area(crate::scene::AreaLight {
            shape: crate::scene::AreaShape::Sphere { radius: 1.0 },
            emission: Default::default(),
            position: glam::DVec3::ZERO,
            normal: glam::DVec3::Y,
            rotation: 0.0,
            color: glam::DVec3::ZERO,
            intensity: 5.0,
        }));
        let p = Plan::new(&s, &RenderSettings::default());
        assert!(!p.shadows && p.reflection && p.refraction, "{p}");
        assert!(p.reasons.iter().any(|r| r.contains("intensity 0")), "{p}");
        s.lights.push(lights[0].clone());
        assert!(Plan::new(&s, &RenderSettings::default()).shadows);
    }

    #[test]
    fn all_variants_are_distinct() {
        let v = Plan::all_variants(3);
        let n = (1 << Plan::FLAGS.len()) * crate::technique::TRANSMITTANCES.len();
        assert_eq!(v.len(), n);
        let keys: std::collections::HashSet<_> = v.iter().map(|p| p.shader_defs()).collect();
        assert_eq!(keys.len(), n);
    }
}
