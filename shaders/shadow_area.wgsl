// Sampled area lights (src/technique/area.rs): an area light of non-zero size is
// `light_samples` emitters at its sample points, each shaded in full (diffuse, specular,
// falloff, shadow) and sharing the light's radiance equally; a point light is one
// emitter at its centre. Contract: "Area lights".
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light, LIGHT_POINT}
#import voxlab::bindings::params
#import voxlab::counters::loop_cut
#import voxlab::sampling::{SampleKey, light_sample}
#import voxlab::area_lights::sample_point
#import voxlab::phong::point_contribution

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
    if light.kind == LIGHT_POINT {
        return point_contribution(q, p, n, d, light.position, light.radiance, s);
    }
    let count = max(params.light_samples, 1u);
    var sum = vec3<f32>(0.0);
    var k = 0u;
    for (; k < count; k++) {
        let st = light_sample(params.seed, key, j, k, count);
        sum += point_contribution(q, p, n, d, sample_point(light, st), light.radiance, s);
    }
    // Only the driver's loop limit ends it early (shaders/counters.wgsl).
    if k < count {
        loop_cut();
    }
    return sum / f32(count);
}
