// Shadow visibility, `min-kt` transmittance (the seed's O1 compromise as its code does
// it): the smallest kt of the voxels a shadow segment crosses; void transmits fully and
// nothing outside the grid absorbs. Contract: "Shading a hit", shadow ray.
#define_import_path voxlab::shadow

#import voxlab::bindings::{materials, voxel_inside}
#import voxlab::traversal::{Dda, enter, dda_init, dda_axis, dda_advance, dda_skip, dda_region, max_steps}
#import voxlab::counters::loop_cut

fn kt_of(m: u32) -> f32 {
    if m == 0u {
        return 1.0;
    }
    return materials[m].kt;
}

// One step of the walk: true when it is over (past the segment, out of the grid, or
// fully shadowed), v the smallest kt so far.
fn min_kt_step(s: ptr<function, Dda>, v: ptr<function, f32>, len: f32) -> bool {
    let a = dda_axis((*s).t_max);
    if !((*s).t_max[a] < len) {
        return true;
    }
    dda_advance(s, a);
    if !voxel_inside((*s).voxel) {
        return true;
    }
    // A uniform region's kt counts once; the walk leaves it whole.
    let r = dda_region(s);
    *v = min(*v, kt_of(r.material));
    if *v <= 0.0 {
        return true;
    }
    dda_skip(s, r);
    return false;
}

// Transmittance of the segment from q along d (unit) of length len > 0: every voxel
// whose entry distance is below len counts, the start voxel included.
fn transmittance(q: vec3<f32>, d: vec3<f32>, len: f32) -> f32 {
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return 1.0;
    }
    var s = dda_init(q, d, e.voxel);
    let r = dda_region(&s);
    var v = kt_of(r.material);
    if v <= 0.0 {
        return 0.0;
    }
    dda_skip(&s, r);
    let n = max_steps();
    // DDA_UNROLL steps per loop iteration, as cast_ray (shaders/traversal.wgsl).
    var done = false;
    var i = 0u;
    for (; i < n && !done; i += #{DDA_UNROLL}u) {
        done = min_kt_step(&s, &v, len);
#if DDA_UNROLL >= 2
        if !done { done = min_kt_step(&s, &v, len); }
#endif
#if DDA_UNROLL >= 4
        if !done { done = min_kt_step(&s, &v, len); }
        if !done { done = min_kt_step(&s, &v, len); }
#endif
#if DDA_UNROLL >= 8
        if !done { done = min_kt_step(&s, &v, len); }
        if !done { done = min_kt_step(&s, &v, len); }
        if !done { done = min_kt_step(&s, &v, len); }
        if !done { done = min_kt_step(&s, &v, len); }
#endif
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if !done && i < n {
        loop_cut();
    }
    return v;
}
