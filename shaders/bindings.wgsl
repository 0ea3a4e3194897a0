// Every resource of the tracer. The host's bind group layout lists all of them; a
// variant that leaves code out simply does not reference some.
#define_import_path voxlab::bindings

#import voxlab::types::{Params, Material, Light}

@group(0) @binding(0) var<uniform> params: Params;
// One material index per voxel, four to a word, x-fastest (the dense walk's grid; a
// placeholder when the plan walks the tree). A storage buffer rather than a 3D
// texture: on Mesa's llvmpipe the seed scene renders 1.18x (16^3) to 1.77x (256^3) as
// fast (README "Sparse traversal").
@group(0) @binding(1) var<storage, read> voxels: array<u32>;
// The whole material table (scene::MAX_MATERIALS entries, unused ones zero; a test in
// src/gpu/compose.rs keeps the length) in a uniform buffer: Mesa's llvmpipe reads a
// storage buffer at a per-lane index in a loop over the lanes with a branch each, a
// uniform buffer by an unrolled gather (its JIT code under perf), and the shadow walk
// reads a material every step (README "Where a step's time goes on lavapipe").
@group(0) @binding(2) var<uniform> materials: array<Material, 256>;
@group(0) @binding(3) var<storage, read> lights: array<Light>;
// Linear radiance per pixel, rows from the top; w is unused. With ACCUMULATE, one such
// image per frame of the dispatch, frame by frame (shaders/accumulate.wgsl sums them).
@group(0) @binding(4) var<storage, read_write> output: array<vec4<f32>>;
// Ray counters as 64-bit (lo, hi) pairs: primary, secondary, shadow, voxel steps; then
// the invocations whose loops the driver cut short (shaders/counters.wgsl, loop_cut),
// one unused word, and the pair of the secondary rays counted untraced.
@group(0) @binding(5) var<storage, read_write> counters: array<atomic<u32>, 12>;
// What a plug-in technique reads (src/technique/, `ShadowModel::gpu_data`): made on the
// host when the plan uses the technique, a placeholder otherwise.
@group(0) @binding(6) var<storage, read> technique_data: array<f32>;
// What a traversal with data of its own walks in place of the voxel buffer
// (src/technique/, `TraversalModel::data`): the sparse tree (shaders/
// traversal_sparse.wgsl, src/sparse.rs), say; a placeholder otherwise.
@group(0) @binding(7) var<storage, read> walk_data: array<vec4<u32>>;
// The triangle surfaces (TRIANGLES; src/triangles.rs, shaders/triangles.wgsl), a
// placeholder otherwise.
@group(0) @binding(8) var<storage, read> surface: array<vec4<u32>>;
// A walk's words beyond `walk_data` (`Regions::device_more_words`: the sparse octant
// walk's codes), one array laid over three bindings of params.walk_part_words words
// each, so that a walk's data may outgrow one binding (lavapipe binds 128 MiB; the codes
// of a grid of voxel noise, whose blocks are nearly all distinct, can take more).
// Placeholders where the walk has fewer.
@group(0) @binding(9) var<storage, read> walk_more_0: array<u32>;
@group(0) @binding(10) var<storage, read> walk_more_1: array<u32>;
@group(0) @binding(11) var<storage, read> walk_more_2: array<u32>;

// Word i of the walk's further words. Only the WALK_MORE_BINDINGS bindings the data
// takes are read (crate::plan::Plan::walk_more_bindings): on a software driver each
// binding's read is a loop over the lanes whatever branch they take
// (docs/sparse-traversal.md, "Codes past one binding").
fn walk_more_word(i: u32) -> u32 {
#if WALK_MORE_BINDINGS >= 2
    let n = params.walk_part_words;
#if WALK_MORE_BINDINGS >= 3
    if i >= 2u * n {
        return walk_more_2[i - 2u * n];
    }
#endif
    if i >= n {
        return walk_more_1[i - n];
    }
#endif
#if WALK_MORE_BINDINGS >= 1
    return walk_more_0[i];
#else
    return 0u;
#endif
}
fn voxel_material(v: vec3<i32>) -> u32 {
    let u = vec3<u32>(v);
    let i = u.x + params.dims.x * (u.y + params.dims.y * u.z);
    return (voxels[i >> 2u] >> (8u * (i & 3u))) & 255u;
}

// Setting `i` (declared order) of the plan's shadow model: every setting a model
// declares arrives here, packed by the host (src/technique/mod.rs, gpu_settings).
fn technique_setting(i: u32) -> f32 {
    return params.technique[i];
}

fn voxel_inside(v: vec3<i32>) -> bool {
    return all(v >= vec3<i32>(0)) && all(v < vec3<i32>(params.dims));
}
