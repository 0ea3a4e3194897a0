// Distance-field soft shadows (Quilez 2010) over the exact Euclidean distance field of
// the occluders, read from `technique_data` (x fastest, voxels). The contract:
// src/technique/sdf.rs. Grid-local units, so the distances need no scaling.
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light, LIGHT_POINT, LIGHT_RECT}
#import voxlab::bindings::{params, technique_data, technique_setting, voxel_inside}
#import voxlab::counters::{count_shadow, loop_cut, loop_guard}
#import voxlab::sampling::SampleKey
#import voxlab::phong::{shadow_to, unshadowed}
#import voxlab::emission::emitted
#import voxlab::traversal::{Dda, enter, dda_init, dda_axis, dda_advance, max_steps}

// `softness` of [techniques.sdf] (src/technique/sdf.rs): its first declared setting.
fn softness() -> f32 {
    return technique_setting(0u);
}

fn field(v: vec3<i32>) -> f32 {
    let d = vec3<i32>(params.dims);
    return technique_data[u32(v.x + d.x * (v.y + d.y * v.z))];
}

// The radius a light's penumbra is cast by (cpu::cone::light_radius): a rectangle's
// half-diagonal, a disk's or sphere's radius, 0 for a point.
fn light_radius(light: Light) -> f32 {
    if light.kind == LIGHT_POINT {
        return 0.0;
    }
    if light.kind == LIGHT_RECT {
        return 0.5 * length(light.axis_u + light.axis_v);
    }
    return length(light.axis_u);
}

// One voxel of the penumbra walk: its term, then the step to the next. True when the
// walk is over (past the segment, out of the grid, or fully dark).
fn penumbra_step(s: ptr<function, Dda>, t0: ptr<function, f32>, p: ptr<function, f32>, len: f32, k: f32) -> bool {
    let a = dda_axis((*s).t_max);
    let t1 = min((*s).t_max[a], len);
    let t = 0.5 * (*t0 + t1);
    if t > 0.0 {
        *p = min(*p, field((*s).voxel) * k / t);
    }
    if !((*s).t_max[a] < len) || *p <= 0.0 {
        return true;
    }
    *t0 = (*s).t_max[a];
    dda_advance(s, a);
    return !voxel_inside((*s).voxel);
}

// P of the segment from q along unit d of length len, k = len / (s R).
fn penumbra(q: vec3<f32>, d: vec3<f32>, len: f32, k: f32) -> f32 {
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return 1.0;
    }
    var s = dda_init(q, d, e.voxel);
    var t0 = e.t;
    var p = 1.0;
    let n = max_steps();
    // DDA_UNROLL steps per loop iteration, exit tested at the bottom, as cast_ray
    // (shaders/traversal.wgsl).
    var done = false;
    var i = 0u;
    loop {
        #walk_steps done = penumbra_step(&s, &t0, &p, len, k);
        continuing {
            i += #{DDA_UNROLL}u;
            break if done || i >= n || loop_guard();
        }
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if !done && i < n {
        loop_cut();
    }
    return clamp(p, 0.0, 1.0);
}

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
    let x = light.position;
    count_shadow();
    let t = shadow_to(q, x);
    if all(t == vec3<f32>(0.0)) {
        return vec3<f32>(0.0);
    }
    let to = x - q;
    let len = length(to);
    let r = softness() * light_radius(light);
    var pen = 1.0;
    if r > 0.0 && len > 0.0 {
        pen = penumbra(q, to / len, len, len / r);
    }
    if pen == 0.0 {
        return vec3<f32>(0.0);
    }
    return t * pen * unshadowed(p, n, d, x, emitted(light, x, p), s);
}
