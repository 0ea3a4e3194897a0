// Runs voxlab::cone on a list of queries, so tests can hold the WGSL cone march against
// src/cpu/cone.rs directly, without the tracer around it (src/gpu/pyramid.rs).

#import voxlab::cone::{march, ambient_occlusion, shadow_visibility}
#ifdef RADIANCE_PYRAMID
#import voxlab::cone::indirect_light
#endif

struct Query {
    // mode 0: march from origin along dir (x = occlusion); 1: march gathering radiance
    // (xyz = radiance, w = occlusion); 2: AO at origin with normal dir (x = AO);
    // 3: indirect light at origin with normal dir (xyz); 4: shadow visibility from
    // origin with normal dir towards the point `target` (x).
    origin: vec3<f32>,
    mode: u32,
    dir: vec3<f32>,
    tan_half: f32,
    target_point: vec3<f32>,
    max_dist: f32,
}

@group(0) @binding(0) var<storage, read> queries: array<Query>;
@group(0) @binding(1) var<storage, read_write> results: array<vec4<f32>>;

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&queries) {
        return;
    }
    let q = queries[i];
    var out = vec4<f32>(0.0);
    switch q.mode {
        case 0u: {
            out.x = march(q.origin, q.dir, q.tan_half, q.max_dist, false).occlusion;
        }
        case 1u: {
            let r = march(q.origin, q.dir, q.tan_half, q.max_dist, true);
            out = vec4<f32>(r.radiance, r.occlusion);
        }
        case 2u: {
            out.x = ambient_occlusion(q.origin, q.dir);
        }
        case 3u: {
#ifdef RADIANCE_PYRAMID
            out = vec4<f32>(indirect_light(q.origin, q.dir), 0.0);
#endif
        }
        default: {
            out.x = shadow_visibility(q.origin, q.dir, q.target_point, q.tan_half);
        }
    }
    results[i] = out;
}
