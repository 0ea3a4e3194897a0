// Ambient occlusion by voxel cones (src/technique/ambient_occlusion.rs): the ambient
// light times the visibility of the hemisphere cones (shaders/cone.wgsl), at hits of
// diffuse materials.
#define_import_path voxlab::term::ambient_occlusion

#import voxlab::types::Material
#import voxlab::bindings::params
#import voxlab::cone::ambient_occlusion

fn term(p: vec3<f32>, n: vec3<f32>, s: Material) -> vec3<f32> {
    if !(s.kd > 0.0) {
        return vec3<f32>(0.0);
    }
    return params.ambient * s.albedo * s.kd * ambient_occlusion(p, n);
}
