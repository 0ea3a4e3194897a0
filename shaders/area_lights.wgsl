// Area lights for the shadow models that sample them: the point of a light for sample
// coordinates (s, t) in [0, 1)^2, uniform in area, as AreaLight::sample_point does in
// f64 (the axes come scaled by the light's size, in voxel units: types.wgsl, `Light`),
// and the sampled estimate of a light. Contract: "Area lights".
#define_import_path voxlab::area_lights

#import voxlab::types::{Material, Light, LIGHT_POINT, LIGHT_RECT, LIGHT_DISK}
#import voxlab::bindings::params
#import voxlab::counters::{loop_cut, loop_guard}
#import voxlab::sampling::{SampleKey, light_sample}
#import voxlab::phong::point_contribution
#import voxlab::emission::emitted

const TAU: f32 = 6.283185307179586;

fn sample_point(light: Light, st: vec2<f32>) -> vec3<f32> {
    let c = light.position;
    if light.kind == LIGHT_RECT {
        // c + (s - 1/2) w u + (t - 1/2) h v
        return c + (st.x - 0.5) * light.axis_u + (st.y - 0.5) * light.axis_v;
    }
    let phi = TAU * st.y;
    if light.kind == LIGHT_DISK {
        // Polar mapping: r = R sqrt(s), phi = 2 pi t.
        return c + sqrt(st.x) * (cos(phi) * light.axis_u + sin(phi) * light.axis_v);
    }
    // Sphere surface (Archimedes' hat-box theorem): z = 1 - 2 s, phi = 2 pi t.
    let z = 1.0 - 2.0 * st.x;
    let r = sqrt(max(1.0 - z * z, 0.0));
    return c + r * cos(phi) * light.axis_u + r * sin(phi) * light.axis_v + z * light.axis_n;
}

// Light j as the area model estimates it (src/technique/area.rs `sampled`): an area
// light of non-zero size is `light_samples` emitters at its sample points, each shaded
// in full and sharing the light's radiance equally; a point light is one emitter at its
// centre. The ratio estimator takes it for lights it has no closed form of.
fn sampled_light(
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
        return point_contribution(q, p, n, d, light.position, emitted(light, light.position, p), s);
    }
    let count = max(params.light_samples, 1u);
    var sum = vec3<f32>(0.0);
    var k = 0u;
    // count >= 1: the exit is tested at the bottom (shaders/counters.wgsl).
    loop {
        let st = light_sample(params.seed, key, j, k, count);
        let x = sample_point(light, st);
        sum += point_contribution(q, p, n, d, x, emitted(light, x, p), s);
        continuing {
            k++;
            break if k >= count || loop_guard();
        }
    }
    // Only the driver's loop limit ends it early (shaders/counters.wgsl).
    if k < count {
        loop_cut();
    }
    return sum / f32(count);
}
