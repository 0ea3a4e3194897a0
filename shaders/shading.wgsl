// Local lighting of a hit: Phong with inverse-square falloff, each light weighted by its
// shadow visibility. Contract: "Shading a hit", local light.
#define_import_path voxlab::shading

#import voxlab::types::Material
#import voxlab::bindings::{params, lights}
#import voxlab::shadow::transmittance
#import voxlab::counters::count_shadow

// The unweighted local radiance at p (normal n, ray direction d) of shading material s.
fn local_light(p: vec3<f32>, n: vec3<f32>, d: vec3<f32>, s: Material) -> vec3<f32> {
    var local = vec3<f32>(0.0);
    if !(s.kd > 0.0 || s.ks > 0.0) {
        return local;
    }
    let q = p + params.eps * n;
    let vs2 = params.voxel_size * params.voxel_size;
    for (var j = 0u; j < params.num_lights; j++) {
        let light = lights[j];
        let to_light = light.position - q;
        let len = length(to_light);
        count_shadow();
        var vis = 1.0;
        if len > 0.0 {
            vis = transmittance(q, to_light / len, len);
        }
        let lp = light.position - p;
        let dl = length(lp);
        var l = n;
        if dl > 0.0 {
            l = lp / dl;
        }
        var e = light.radiance;
        if params.falloff != 0u {
            // dl is in voxels; the falloff distance is in world units.
            e = e / max(dl * dl * vs2, params.falloff_min_dist_sq);
        }
        let nl = dot(n, l);
        let diffuse = max(0.0, nl);
        let r = l - 2.0 * nl * n;
        let rd = dot(r, d);
        var spec = 0.0;
        if rd > 0.0 {
            spec = pow(rd, s.shininess);
        }
        local += vis * e * (s.kd * diffuse + s.ks * spec);
    }
    return local * s.albedo;
}
