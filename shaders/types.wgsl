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
}

struct Material {
    albedo: vec3<f32>,
    kd: f32,
    ks: f32,
    shininess: f32,
    kr: f32,
    kt: f32,
    ior: f32,
    pad_a: f32,
    pad_b: f32,
    pad_c: f32,
    // Radiance the voxel emits towards the viewer (seen, not cast).
    emission: vec3<f32>,
    pad_d: f32,
}

struct PointLight {
    position: vec3<f32>,
    pad_a: f32,
    // colour * intensity, multiplied on the host.
    radiance: vec3<f32>,
    pad_b: f32,
}
