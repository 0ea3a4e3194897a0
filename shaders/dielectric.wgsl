// How a refracting hit splits its ray between reflection and refraction: the f32 twin
// of crate::scene::Dielectric and crate::scene::fresnel_dielectric (src/scene/material.rs,
// which cites the equations). trace.wgsl's spawn asks it.
#define_import_path voxlab::dielectric

#import voxlab::types::{Material, DIELECTRIC_FRESNEL}

// Unpolarised Fresnel reflectance for cos(theta_i) = cos_i >= 0, sin(theta_t) = sin_t
// = eta sin(theta_i) (trace.wgsl's spawn takes sin_i from the ray's tangential part, not
// 1 - c^2) and eta = n_i / n_t; 1 under total internal reflection. As
// crate::scene::fresnel_dielectric_at.
fn fresnel_dielectric(cos_i: f32, sin_t: f32, eta: f32) -> f32 {
    let c = clamp(cos_i, 0.0, 1.0);
    let sin2_t = sin_t * sin_t;
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = sqrt(1.0 - sin2_t);
    let r_s = (eta * c - cos_t) / (eta * c + cos_t);
    let r_p = (c - eta * cos_t) / (c + eta * cos_t);
    return 0.5 * (r_s * r_s + r_p * r_p);
}

// The (reflection, refraction) weights of a hit on material s (kt > 0) whose ray meets
// the interface at cos_i (sin_t = eta sin_i, the refracted ray's sine) with eta = n_i /
// n_t; tir: Snell's law has no refracted ray.
// Only where some material splits by Fresnel (FRESNEL, crate::plan::Plan::fresnel) is
// its branch composed in: the software driver runs both sides of a branch for every
// lane, so the equations would cost every hit of a scene with none.
fn split_weights(s: Material, cos_i: f32, sin_t: f32, eta: f32, tir: bool) -> vec2<f32> {
#ifdef FRESNEL
    if s.dielectric == DIELECTRIC_FRESNEL {
        let f = fresnel_dielectric(cos_i, sin_t, eta);
        return vec2<f32>(s.kr * f, s.kt * (1.0 - f));
    }
#endif
    if tir {
        // The refracted share goes to the reflection; under the seed's rules it is
        // lost (GLSL's refract gives the zero vector).
#ifdef SEED_RULES
        return vec2<f32>(s.kr, 0.0);
#else
        return vec2<f32>(s.kr + s.kt, 0.0);
#endif
    }
    return vec2<f32>(s.kr, s.kt);
}
