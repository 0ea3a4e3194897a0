// How a light's point sends its light out (src/scene/light.rs `Emission`): the same in
// every direction, or a Lambertian emitter's cosine from the side its normal faces.
// Imported by every kernel that shades a light (phong.wgsl, inject.wgsl).
#define_import_path voxlab::emission

#import voxlab::types::{Light, EMISSION_LAMBERTIAN}

// The share of a light's radiance that its point x sends toward p: 1, or a Lambertian
// emitter's cosine (0 at x itself). As crate::scene::Light::emitted_towards. The
// cosine is composed in only where some light is Lambertian (LAMBERTIAN_LIGHTS,
// crate::plan::Plan::lambertian_lights; the radiance injection always has it): the
// software driver runs both sides of a branch for every lane, so it would cost every
// light term of a scene with none.
fn emitted_share(light: Light, x: vec3<f32>, p: vec3<f32>) -> f32 {
#ifdef LAMBERTIAN_LIGHTS
    if light.emission != EMISSION_LAMBERTIAN {
        return 1.0;
    }
    let w = p - x;
    let len = length(w);
    if !(len > 0.0) {
        return 0.0;
    }
    return max(dot(normalize(light.axis_n), w) / len, 0.0);
#else
    return 1.0;
#endif
}

// The radiance of a point emitter at x standing for `light` (or for its share of it),
// as seen from p. As crate::scene::Light::radiance_towards.
fn emitted(light: Light, x: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    return light.radiance * emitted_share(light, x, p);
}
