// Hard shadows (src/technique/hard.rs): every light, point or area, is one point emitter
// at its centre, behind one shadow ray.
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light}
#import voxlab::sampling::SampleKey
#import voxlab::phong::point_contribution
#import voxlab::emission::emitted

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
    return point_contribution(q, p, n, d, light.position, emitted(light, light.position, p), s);
}
