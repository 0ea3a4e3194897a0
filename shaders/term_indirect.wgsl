// One bounce of diffuse light by voxel cones (src/technique/indirect.rs): the radiance
// the hemisphere cones gather from the radiance pyramid (shaders/cone.wgsl), at hits of
// diffuse materials.
#define_import_path voxlab::term::indirect

#import voxlab::types::Material
#import voxlab::cone::{cone, indirect_light}

fn term(p: vec3<f32>, n: vec3<f32>, s: Material) -> vec3<f32> {
    if !(s.kd > 0.0) {
        return vec3<f32>(0.0);
    }
    return cone.indirect_strength * s.albedo * s.kd * indirect_light(p, n);
}
