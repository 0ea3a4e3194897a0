// Local lighting of a hit: Phong with inverse-square falloff, each light shaded by the
// plan's shadow model (`voxlab::shadow_model`, one of src/technique/'s: hard shadows,
// sampled area lights, cones, ...), which estimates its visibility. Contract: "Shading
// a hit", local light, and the shadow model's file.
#define_import_path voxlab::shading

#import voxlab::types::Material
#import voxlab::bindings::{params, lights}
#import voxlab::counters::{loop_cut, loop_guard}
#import voxlab::sampling::SampleKey
#import voxlab::shadow_model::light_term

// The unweighted local radiance at p (shading normal n, the surface's own normal ng,
// ray direction d) of shading material s, for the primary ray of `key` (which picks the
// shadow model's samples). Shadow rays start off the surface along ng. `weight` is the
// ray's (crate::ray_cutoff): under RAY_CUTOFF a light whose bound times it is below the
// cutoff is not shaded.
fn local_light(p: vec3<f32>, n: vec3<f32>, ng: vec3<f32>, d: vec3<f32>, s: Material, key: SampleKey, weight: f32) -> vec3<f32> {
    var local = vec3<f32>(0.0);
    if !(s.kd > 0.0 || s.ks > 0.0) {
        return local;
    }
    let q = p + params.eps * ng;
    var j = 0u;
    // Exit tested at the bottom: no idle light after the last (shaders/counters.wgsl).
    if params.num_lights > 0u {
        loop {
#ifdef RAY_CUTOFF
            if weight * lights[j].bound >= params.ray_cutoff {
                local += light_term(q, p, n, d, lights[j], j, s, key);
            }
#else
            local += light_term(q, p, n, d, lights[j], j, s, key);
#endif
            continuing {
                j++;
                break if j >= params.num_lights || loop_guard();
            }
        }
    }
    if j < params.num_lights {
        loop_cut();
    }
    return local * s.albedo;
}
