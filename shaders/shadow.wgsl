// Shadow transmittance over the voxels: the walk of a shadow segment through the grid
// (or its sparse tree), each uniform region passed to the plan's transmittance model
// (voxlab::transmittance: src/technique/<name>.rs and shaders/transmittance_<name>.wgsl);
// nothing outside the grid absorbs. As crate::cpu::shadow_transmittance. Contract:
// "Shading a hit", shadow ray.
#define_import_path voxlab::shadow

#import voxlab::bindings::voxel_inside
#import voxlab::traversal::{Dda, enter, dda_init, dda_axis, dda_advance, dda_skip, dda_region, max_steps}
#import voxlab::counters::{loop_cut, loop_guard}
#import voxlab::transmittance::{Absorb, absorb_start, absorb_pass, absorb_result}

// The walk's state beside the model's (a variable of its own: the model's functions
// take a pointer to a whole variable): where it ended, whether nothing more passes.
struct Walk {
    t_end: f32,
    opaque: bool,
}

// One step: true when the walk is over (past the segment, out of the grid, or opaque).
fn shadow_step(s: ptr<function, Dda>, w: ptr<function, Walk>, absorb: ptr<function, Absorb>, len: f32) -> bool {
    let a = dda_axis((*s).t_max);
    let t = (*s).t_max[a];
    if !(t < len) {
        (*w).t_end = len;
        return true;
    }
    dda_advance(s, a);
    if !voxel_inside((*s).voxel) {
        (*w).t_end = t;
        return true;
    }
    // A uniform region passes at once: the walk leaves it whole.
    let r = dda_region(s);
    if absorb_pass(absorb, t, r.material) {
        (*w).opaque = true;
        return true;
    }
    dda_skip(s, r);
    return false;
}

// Transmittance (RGB) of the segment from q along d (unit) of length len > 0: every
// voxel whose entry distance is below len counts, the start voxel included.
fn transmittance(q: vec3<f32>, d: vec3<f32>, len: f32) -> vec3<f32> {
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return vec3<f32>(1.0);
    }
    var s = dda_init(q, d, e.voxel);
    let r = dda_region(&s);
    var w: Walk;
    w.t_end = e.t;
    w.opaque = false;
    var absorb = absorb_start();
    if absorb_pass(&absorb, e.t, r.material) {
        return vec3<f32>(0.0);
    }
    dda_skip(&s, r);
    let n = max_steps();
    // DDA_UNROLL steps per loop iteration, exit tested at the bottom, as cast_ray
    // (shaders/traversal.wgsl).
    var done = false;
    var i = 0u;
    loop {
        #walk_steps done = shadow_step(&s, &w, &absorb, len);
        continuing {
            i += #{DDA_UNROLL}u;
            break if done || i >= n || loop_guard();
        }
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if !done && i < n {
        loop_cut();
    }
    if w.opaque {
        return vec3<f32>(0.0);
    }
    return absorb_result(absorb, min(w.t_end, len));
}
