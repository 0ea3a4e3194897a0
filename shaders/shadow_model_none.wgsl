// The shadow-model slot without a plug-in (src/technique/): naga_oil resolves the import
// of shading.wgsl even where `#ifdef SHADOW_MODEL` leaves its use out, so this module
// stands in for it. Its function is never called: without SHADOW_MODEL the built-in
// models shade every light.
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light}
#import voxlab::sampling::SampleKey

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
    return vec3<f32>(0.0);
}
