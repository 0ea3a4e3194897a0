// Shadow transmittance over the voxels: the walk of a shadow segment through the grid
// (or its sparse tree), each run of one material passed to the plan's transmittance
// model (voxlab::transmittance: src/technique/<name>.rs and
// shaders/transmittance_<name>.wgsl); nothing outside the grid absorbs. As
// crate::cpu::shadow_transmittance. Contract: "Shading a hit", shadow ray.
#define_import_path voxlab::shadow

#import voxlab::types::Region
#import voxlab::bindings::voxel_inside
#import voxlab::traversal::{Dda, enter, dda_init, dda_axis, dda_advance, dda_skip, dda_region, max_steps}
#import voxlab::counters::loop_cut
#import voxlab::transmittance::{Absorb, absorb_start, absorb_pass, absorb_result}

// What a step of the walk found: nothing yet, the segment's end (past its length or
// out of the grid), or a region of another material than the run before it.
const WALK_ON: u32 = 0u;
const WALK_END: u32 = 1u;
const WALK_CHANGE: u32 = 2u;

// Where the walk is between steps (a variable of its own: the model's functions take
// a pointer to a whole variable): where the segment ends, and the latest region with
// its entry distance.
struct Walk {
    t_end: f32,
    t: f32,
    region: Region,
}

// One step, within a run of material `run`: the next region, left whole when it is of
// that material too.
fn shadow_step(s: ptr<function, Dda>, w: ptr<function, Walk>, len: f32, run: u32) -> u32 {
    let a = dda_axis((*s).t_max);
    let t = (*s).t_max[a];
    if !(t < len) {
        (*w).t_end = len;
        return WALK_END;
    }
    dda_advance(s, a);
    if !voxel_inside((*s).voxel) {
        (*w).t_end = t;
        return WALK_END;
    }
    let r = dda_region(s);
    if r.material != run {
        (*w).t = t;
        (*w).region = r;
        return WALK_CHANGE;
    }
    dda_skip(s, r);
    return WALK_ON;
}

// Transmittance (RGB) of the segment from q along d (unit) of length len > 0: every
// voxel whose entry distance is below len counts, the start voxel included.
//
// The model sees where the material changes, not every voxel: a run of one material
// absorbs as its voxels one by one would (the smallest kt of equal kts; Beer-Lambert's
// sigma times the run's length, the sum of its voxels' lengths), so the walk steps
// through a run in an inner loop that reads no material. On Mesa's llvmpipe, where
// both sides of a branch run for every SIMD lane and only loops end early, that keeps
// the model's material read out of most steps (seed_rules at 512x512, dense walk,
// medians of five alternated runs: 16^3 98 to 96 ms per frame, 64^3 246 to 235 ms).
// Contract: "Traversals".
fn transmittance(q: vec3<f32>, d: vec3<f32>, len: f32) -> vec3<f32> {
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return vec3<f32>(1.0);
    }
    var s = dda_init(q, d, e.voxel);
    let start = dda_region(&s);
    var absorb = absorb_start();
    if absorb_pass(&absorb, e.t, start.material) {
        return vec3<f32>(0.0);
    }
    dda_skip(&s, start);
    var w: Walk;
    w.t_end = len;
    var run = start.material;
    let n = max_steps();
    var i = 0u;
    // Set on every way out but the driver's loop limit (shaders/counters.wgsl).
    var finished = false;
    var opaque = false;
    loop {
        // DDA_UNROLL steps per iteration, as cast_ray (shaders/traversal.wgsl).
        var k = WALK_ON;
        for (; i < n; i += #{DDA_UNROLL}u) {
            k = shadow_step(&s, &w, len, run);
#if DDA_UNROLL >= 2
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
#endif
#if DDA_UNROLL >= 4
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
#endif
#if DDA_UNROLL >= 8
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
            if k == WALK_ON { k = shadow_step(&s, &w, len, run); }
#endif
            if k != WALK_ON {
                break;
            }
        }
        if k != WALK_CHANGE {
            // The segment's end, max_steps spent, or the driver's limit (i < n).
            finished = k == WALK_END || i >= n;
            break;
        }
        if absorb_pass(&absorb, w.t, w.region.material) {
            opaque = true;
            finished = true;
            break;
        }
        run = w.region.material;
        dda_skip(&s, w.region);
        // The step that found the change counts, so the bound holds across runs.
        i += 1u;
    }
    if !finished {
        loop_cut();
    }
    if opaque {
        return vec3<f32>(0.0);
    }
    return absorb_result(absorb, min(w.t_end, len));
}
