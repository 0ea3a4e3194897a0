// Phong with inverse-square falloff for one point emitter, weighted by the shadow
// transmittance of the segment to it: what every shadow model shades a light with
// (shading.wgsl and the plug-in shadow models, src/technique/). Contract: "Shading a
// hit", local light.
#define_import_path voxlab::phong

#import voxlab::types::Material
#import voxlab::bindings::params
#import voxlab::counters::{count_shadow, shadows_clear}
#ifdef TRIANGLES
#import voxlab::shadow_surface::surface_transmittance
#import voxlab::triangles::shadow_medium
#else
#import voxlab::shadow::transmittance
#endif

// Transmittance (RGB) of the shadow segment from q to the emitter at x. It ends eps
// short of the emitter (as it starts eps off the surface): a light on a voxel's face is
// seen from the face's open side, not by rounding. As shading::shadow_transmittance,
// which a clear walk (ShadowWalk::clear) likewise passes whole.
fn shadow_to(q: vec3<f32>, x: vec3<f32>) -> vec3<f32> {
#ifdef PRIMARY_LAYERS
    // The unshadowed pass of the primary layers (shaders/counters.wgsl).
    if shadows_clear {
        return vec3<f32>(1.0);
    }
#endif
    let to_light = x - q;
    let dist = length(to_light);
    let len = dist - params.eps;
    if !(len > 0.0) {
        return vec3<f32>(1.0);
    }
#ifdef TRIANGLES
    // Through the triangle surfaces.
    return surface_transmittance(q, to_light / dist, len, shadow_medium);
#else
    return transmittance(q, to_light / dist, len);
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
    // No shadow ray where nothing it could let through is seen (a light behind the
    // surface, say): V multiplies zero there. Contract: "Shading a hit".
    let lit = unshadowed(p, n, d, x, radiance, s);
    if all(lit == vec3<f32>(0.0)) {
        return lit;
    }
    count_shadow();
    return shadow_to(q, x) * lit;
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
