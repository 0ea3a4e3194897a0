// Cone shadows (src/technique/cone.rs): one cone per light through the opacity pyramid
// (shaders/cone.wgsl) replaces the shadow ray. Its aperture is the angle the light
// subtends, tan(theta / 2) = radius / distance, or the set aperture for point lights.
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light}
#import voxlab::counters::count_shadow
#import voxlab::sampling::SampleKey
#import voxlab::phong::unshadowed
#import voxlab::emission::emitted
#import voxlab::cone::{cone, light_radius, shadow_visibility}

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
    count_shadow();
    let r = light_radius[j];
    var th = cone.point_tan_half;
    if r > 0.0 {
        let dist = length(light.position - p);
        th = 1.0e30;
        if dist > 0.0 {
            th = r / dist;
        }
    }
    let v = shadow_visibility(p, n, light.position, th);
    if v > 0.0 {
        return v * unshadowed(p, n, d, light.position, emitted(light, light.position, p), s);
    }
    return vec3<f32>(0.0);
}
