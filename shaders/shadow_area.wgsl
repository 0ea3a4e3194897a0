// Sampled area lights (src/technique/area.rs): every light as shaders/area_lights.wgsl
// `sampled_light` estimates it. Contract: "Area lights".
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light}
#import voxlab::sampling::SampleKey
#import voxlab::area_lights::sampled_light

fn light_term(
    q: vec3<f32>,
    p: vec3<f32>,
    n: vec3<f32>,
    d: vec3<f32>,
    light: Light,
    j: u32,
    s: Material,
    key: SampleKey,
) -> vec3<f32> {
    return sampled_light(q, p, n, d, light, j, s, key);
}
