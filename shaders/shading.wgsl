// Local lighting of a hit: Phong with inverse-square falloff, each light weighted by its
// shadow transmittance. A point light is one emitter at its centre; with AREA_LIGHTS a
// sampled area light is `light_samples` emitters at its sample points, each shaded in
// full (diffuse, specular, falloff, shadow) and sharing the light's intensity equally.
// Contract: "Shading a hit", local light, and "Area lights".
#define_import_path voxlab::shading

#import voxlab::types::{Material, Light, LIGHT_POINT}
#import voxlab::bindings::{params, lights}
#import voxlab::counters::{count_shadow, loop_cut}
#import voxlab::sampling::SampleKey
#import voxlab::phong::{point_contribution, unshadowed}
#ifdef SHADOW_MODEL
#import voxlab::shadow_model::light_term
#endif
#ifdef CONE_SHADOWS
#import voxlab::cone::light_visibility
#endif
#ifdef AREA_LIGHTS
#import voxlab::sampling::light_sample
#import voxlab::area_lights::sample_point
#endif

// The unweighted local radiance at p (shading normal n, the surface's own normal ng,
// ray direction d) of shading material s, for the primary ray of `key` (which picks the
// area-light samples). Shadow rays start off the surface along ng.
fn local_light(p: vec3<f32>, n: vec3<f32>, ng: vec3<f32>, d: vec3<f32>, s: Material, key: SampleKey) -> vec3<f32> {
    var local = vec3<f32>(0.0);
    if !(s.kd > 0.0 || s.ks > 0.0) {
        return local;
    }
    let q = p + params.eps * ng;
    var j = 0u;
    for (; j < params.num_lights; j++) {
        let light = lights[j];
#ifdef SHADOW_MODEL
        // A plug-in shadow model shades the whole light (src/technique/).
        local += light_term(q, p, n, d, light, j, s, key);
        continue;
#endif
#ifdef CONE_SHADOWS
        // One cone to the light's centre replaces the shadow ray and the area samples
        // (src/cpu/mod.rs direct_light).
        count_shadow();
        let v = light_visibility(p, n, light.position, j);
        if v > 0.0 {
            local += v * unshadowed(p, n, d, light.position, light.radiance, s);
        }
        continue;
#endif
#ifdef AREA_LIGHTS
        if light.kind != LIGHT_POINT {
            let count = max(params.light_samples, 1u);
            var sum = vec3<f32>(0.0);
            var k = 0u;
            for (; k < count; k++) {
                let st = light_sample(params.seed, key, j, k, count);
                let x = sample_point(light, st);
                sum += point_contribution(q, p, n, d, x, light.radiance, s);
            }
            // Only the driver's loop limit ends it early (shaders/counters.wgsl).
            if k < count {
                loop_cut();
            }
            local += sum / f32(count);
            continue;
        }
#endif
        local += point_contribution(q, p, n, d, light.position, light.radiance, s);
    }
    if j < params.num_lights {
        loop_cut();
    }
    return local * s.albedo;
}
