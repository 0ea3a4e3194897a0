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
#ifdef BEER_LAMBERT
#import voxlab::shadow_beer_lambert::transmittance_rgb
#else
#import voxlab::shadow::transmittance
#endif
#ifdef CONE_SHADOWS
#import voxlab::cone::light_visibility
#endif
#ifdef AREA_LIGHTS
#import voxlab::sampling::light_sample
#import voxlab::area_lights::sample_point
#endif

// Transmittance (RGB) of the shadow segment from q to the emitter at x.
fn shadow_to(q: vec3<f32>, x: vec3<f32>) -> vec3<f32> {
    let to_light = x - q;
    let len = length(to_light);
    if !(len > 0.0) {
        return vec3<f32>(1.0);
    }
#ifdef BEER_LAMBERT
    return transmittance_rgb(q, to_light / len, len);
#else
    return vec3<f32>(transmittance(q, to_light / len, len));
#endif
}

// One point emitter at x of radiance `radiance` seen from the hit p (normal n, ray
// direction d; shadow ray from q): V E (kd diffuse + ks specular), before albedo. As
// crate::cpu::point_contribution.
fn point_contribution(
    q: vec3<f32>,
    p: vec3<f32>,
    n: vec3<f32>,
    d: vec3<f32>,
    x: vec3<f32>,
    radiance: vec3<f32>,
    s: Material,
) -> vec3<f32> {
    count_shadow();
    let vis = shadow_to(q, x);
    if all(vis == vec3<f32>(0.0)) {
        return vec3<f32>(0.0);
    }
    return vis * unshadowed(p, n, d, x, radiance, s);
}

// E (kd diffuse + ks specular) of a point emitter at x seen from p, before visibility
// and albedo. As crate::cpu::unshadowed.
fn unshadowed(
    p: vec3<f32>,
    n: vec3<f32>,
    d: vec3<f32>,
    x: vec3<f32>,
    radiance: vec3<f32>,
    s: Material,
) -> vec3<f32> {
    let lp = x - p;
    let dl = length(lp);
    var l = n;
    if dl > 0.0 {
        l = lp / dl;
    }
    var e = radiance;
    if params.falloff != 0u {
        // dl is in voxels; the falloff distance is in world units.
        let vs2 = params.voxel_size * params.voxel_size;
        e = e / max(dl * dl * vs2, params.falloff_min_dist_sq);
    }
    let nl = dot(n, l);
    let diffuse = max(0.0, nl);
    // No highlight from a light behind the surface (textbook Phong's n.l > 0 gate).
    let r = l - 2.0 * nl * n;
    let rd = select(0.0, dot(r, d), nl > 0.0);
    var spec = 0.0;
    if rd > 0.0 {
        spec = pow(rd, s.shininess);
    }
    return e * (s.kd * diffuse + s.ks * spec);
}

// The unweighted local radiance at p (normal n, ray direction d) of shading material s,
// for the primary ray of `key` (which picks the area-light samples).
fn local_light(p: vec3<f32>, n: vec3<f32>, d: vec3<f32>, s: Material, key: SampleKey) -> vec3<f32> {
    var local = vec3<f32>(0.0);
    if !(s.kd > 0.0 || s.ks > 0.0) {
        return local;
    }
    let q = p + params.eps * n;
    var j = 0u;
    for (; j < params.num_lights; j++) {
        let light = lights[j];
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
