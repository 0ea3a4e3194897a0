// Shadow visibility, `beer-lambert` transmittance (BEER_LAMBERT): T = exp(-sum sigma_m
// len_m) per RGB channel, with len_m the exact length of the segment inside each voxel
// from the DDA (no fixed-step marching). The optical depth is summed first and
// exponentiated once, so a huge depth gives exactly 0 and never a negative or NaN value;
// a material with kt = 0 is opaque. As crate::cpu::shadow_beer_lambert; the walk is
// shadow.wgsl's (same voxels, same limits). Contract: "Shading a hit", shadow ray.
#define_import_path voxlab::shadow_beer_lambert

#import voxlab::bindings::{materials, voxel_inside}
#import voxlab::traversal::{Dda, enter, dda_init, dda_axis, dda_advance, dda_skip, dda_region, max_steps}
#import voxlab::counters::loop_cut

// Absorption per voxel unit; void's entry is uploaded too (zero unless it transmits
// less than fully, which the palette never allows).
fn sigma_of(m: u32) -> vec3<f32> {
    let mat = materials[m];
    return vec3<f32>(mat.sigma_r, mat.sigma_g, mat.sigma_b);
}

fn opaque(m: u32) -> bool {
    return materials[m].kt <= 0.0;
}

// The walk's state: the voxel being crossed (its absorption and where the segment
// entered it), the optical depth so far, where the walk ended, whether it met an
// opaque voxel.
struct Walk {
    sigma: vec3<f32>,
    t_in: f32,
    depth: vec3<f32>,
    t_end: f32,
    opaque: bool,
}

// One step: true when the walk is over (past the segment, out of the grid, or opaque).
fn beer_lambert_step(s: ptr<function, Dda>, w: ptr<function, Walk>, len: f32) -> bool {
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
    (*w).depth += (*w).sigma * (t - (*w).t_in);
    let r = dda_region(s);
    if opaque(r.material) {
        (*w).opaque = true;
        return true;
    }
    (*w).sigma = sigma_of(r.material);
    (*w).t_in = t;
    // One material over the region: its length counts at once, at the next step.
    dda_skip(s, r);
    return false;
}

// Transmittance of the segment from q along d (unit) of length len > 0.
fn transmittance_rgb(q: vec3<f32>, d: vec3<f32>, len: f32) -> vec3<f32> {
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return vec3<f32>(1.0);
    }
    var s = dda_init(q, d, e.voxel);
    let r = dda_region(&s);
    if opaque(r.material) {
        return vec3<f32>(0.0);
    }
    var w: Walk;
    w.sigma = sigma_of(r.material);
    w.t_in = e.t;
    w.t_end = e.t;
    w.depth = vec3<f32>(0.0);
    w.opaque = false;
    dda_skip(&s, r);
    let n = max_steps();
    // DDA_UNROLL steps per loop iteration, as cast_ray (shaders/traversal.wgsl).
    var done = false;
    var i = 0u;
    for (; i < n && !done; i += #{DDA_UNROLL}u) {
        done = beer_lambert_step(&s, &w, len);
#if DDA_UNROLL >= 2
        if !done { done = beer_lambert_step(&s, &w, len); }
#endif
#if DDA_UNROLL >= 4
        if !done { done = beer_lambert_step(&s, &w, len); }
        if !done { done = beer_lambert_step(&s, &w, len); }
#endif
#if DDA_UNROLL >= 8
        if !done { done = beer_lambert_step(&s, &w, len); }
        if !done { done = beer_lambert_step(&s, &w, len); }
        if !done { done = beer_lambert_step(&s, &w, len); }
        if !done { done = beer_lambert_step(&s, &w, len); }
#endif
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if !done && i < n {
        loop_cut();
    }
    if w.opaque {
        return vec3<f32>(0.0);
    }
    let depth = w.depth + w.sigma * max(min(w.t_end, len) - w.t_in, 0.0);
    return exp(-depth);
}
