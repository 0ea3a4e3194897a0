// Data shared by the host (src/gpu/mod.rs, which mirrors these layouts) and the kernel.
// Everything geometric is in grid-local coordinates: voxel units, grid corner at 0.
#define_import_path voxlab::types

// Stands in for +infinity: WGSL has no infinity literal, and a finite sentinel keeps
// `tMax + tDelta` and `0 * BIG` free of inf and NaN.
const BIG: f32 = 1.0e30;

struct Params {
    eye: vec3<f32>,
    width: u32,
    forward: vec3<f32>,
    height: u32,
    // right * tan(vfov / 2) * aspect and up * tan(vfov / 2), scaled on the host in f64.
    right_scaled: vec3<f32>,
    num_lights: u32,
    up_scaled: vec3<f32>,
    max_reflection_depth: u32,
    dims: vec3<u32>,
    max_refraction_depth: u32,
    ambient: vec3<f32>,
    // Material at the eye, decided on the host in f64 like the CPU reference.
    eye_medium: u32,
    // Secondary and shadow rays start this far off the surface (voxel units).
    eps: f32,
    // World length of one voxel: falloff distances are in world units.
    voxel_size: f32,
    // d_min^2 in world units; falloff is off when this is negative.
    falloff_min_dist_sq: f32,
    falloff: u32,
    // Light sampling (shadow models that sample): samples per pixel, light and frame;
    // the hash seed.
    light_samples: u32,
    seed: u32,
    // The frames this dispatch traces: frame_begin .. frame_begin + frame_count, one per
    // invocation along the dispatch's z (ACCUMULATE), each written to its own slice of
    // `output`; shaders/accumulate.wgsl then adds them to the running sums in order.
    frame_begin: u32,
    frame_count: u32,
    // Total depth of the ray tree (RenderSettings::total_depth_limit).
    max_total_depth: u32,
    // Adaptive depth control (RAY_CUTOFF, crate::ray_cutoff): rays whose weight is below
    // it are not traced, lights whose bound times the weight is below it not shaded.
    ray_cutoff: f32,
    // PIXEL_FILTER_* (crate::render::PixelFilter) and its width in pixels (PIXEL_FILTER).
    pixel_filter: u32,
    filter_width: f32,
    // Words of each binding of a walk's further words (bindings::walk_more_word).
    walk_part_words: u32,
    // How far along its unnormalised direction a pixel's primary ray starts from `eye`
    // (crate::plan::primary_origin): 0, unless the eye is far out, when `eye` is already
    // moved that far along `forward` on the host in f64.
    primary_advance: f32,
    // Always 0, which no compiler can know: the tracer's loops leave on their own exit
    // condition or this (shaders/counters.wgsl, loop_guard).
    loop_guard: u32,
    // The plan's shadow model's settings in declared order (src/technique/mod.rs,
    // ShadowModel::gpu_settings); read them with bindings::technique_setting.
    technique: vec4<f32>,
}

// crate::render::PixelFilter::code.
const PIXEL_FILTER_BOX: u32 = 1u;
const PIXEL_FILTER_GAUSSIAN: u32 = 2u;

struct Material {
    albedo: vec3<f32>,
    kd: f32,
    ks: f32,
    shininess: f32,
    kr: f32,
    kt: f32,
    ior: f32,
    // Beer-Lambert absorption per voxel unit (sigma per world unit times voxel_size,
    // converted on the host), RGB; scalars so the 64-byte layout keeps its rows.
    sigma_r: f32,
    sigma_g: f32,
    sigma_b: f32,
    // Radiance the voxel emits towards the viewer (seen, not cast).
    emission: vec3<f32>,
    // crate::scene::Dielectric::code: how a refracting hit splits its ray (trace.wgsl).
    dielectric: u32,
}

// crate::scene::Dielectric::code.
const DIELECTRIC_FIXED: u32 = 0u;
const DIELECTRIC_FRESNEL: u32 = 1u;

// Light kinds: a point (also an area light of size 0), or a shape the shadow model may
// sample (shadow_area.wgsl) or integrate (shadow_ratio.wgsl); hard shadows take every
// light at its centre.
const LIGHT_POINT: u32 = 0u;
const LIGHT_RECT: u32 = 1u;
const LIGHT_DISK: u32 = 2u;
const LIGHT_SPHERE: u32 = 3u;

// Emission of a light's points: the same intensity every way, or Lambertian from the
// side axis_n faces (then axis_n is set even for a light of kind LIGHT_POINT).
const EMISSION_ISOTROPIC: u32 = 0u;
const EMISSION_LAMBERTIAN: u32 = 1u;

struct Light {
    // Centre.
    position: vec3<f32>,
    kind: u32,
    // colour * intensity, multiplied on the host.
    radiance: vec3<f32>,
    // The most the light adds at any hit (crate::ray_cutoff::light_bound; RAY_CUTOFF).
    bound: f32,
    // The shape's axes in voxel units, scaled by its size on the host in f64
    // (src/gpu/mod.rs, `GpuLight`): rectangle u * width and v * height; disk u * radius
    // and v * radius; sphere radius times the world axes x, y (and z in axis_n).
    axis_u: vec3<f32>,
    // EMISSION_*: how each point of a rect or disk emits (src/scene/light.rs `Emission`).
    emission: u32,
    axis_v: vec3<f32>,
    pad_c: f32,
    axis_n: vec3<f32>,
    pad_d: f32,
}

// A uniform region of the grid as a traversal (voxlab::regions) finds it around a
// voxel: its material and its box `[lo, hi)`, clipped to the grid. The dense walk's
// regions are single voxels.
struct Region {
    material: u32,
    lo: vec3<i32>,
    hi: vec3<i32>,
}
