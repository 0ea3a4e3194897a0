// Shadow transmittance through triangle surfaces (TRIANGLES): the segment's medium is
// followed through every crossing, from the medium at its start (shadow_medium, set by
// the tracer); a voxel outside the cells sets it to its material. Each medium passes to
// the plan's transmittance model (voxlab::transmittance), as the voxel walk's regions
// do. As crate::triangles::SurfaceTrace::transmittance. Contract: "Triangle surfaces".
#define_import_path voxlab::shadow_surface

#import voxlab::bindings::voxel_inside
#import voxlab::traversal::{Dda, enter, dda_init, dda_axis, dda_advance, dda_skip, dda_region, walk_bound}
#import voxlab::triangles::{WatertightRay, watertight_ray, cell_range, next_transition, is_cell, CELL_TOLERANCE}
#import voxlab::counters::{loop_cut, loop_guard}
#import voxlab::transmittance::{Absorb, absorb_start, absorb_pass, absorb_result}

// The media so far: the current one and where it began, the last crossing taken, and
// whether nothing more passes (the model's state is a variable of its own, `absorb`:
// its functions take a pointer to a whole variable).
struct Media {
    medium: u32,
    t: f32,
    after: f32,
    opaque: bool,
}

// The segment passes into medium `next` at t.
fn pass_into(w: ptr<function, Media>, absorb: ptr<function, Absorb>, t: f32, next: u32) {
    (*w).medium = next;
    (*w).t = t;
    if absorb_pass(absorb, t, next) {
        (*w).opaque = true;
    }
}

// The crossings of the cell the walk is in, entered at t_enter, up to len.
fn pass_cell(s: ptr<function, Dda>, w: ptr<function, Media>, absorb: ptr<function, Absorb>, r: WatertightRay, t_enter: f32, len: f32) {
    let t_exit = min(min((*s).t_max.x, min((*s).t_max.y, (*s).t_max.z)), len);
    let range = cell_range((*s).voxel);
    // One crossing per pass, looked for at the top of the pass, the exit tested at the
    // bottom: a cell without crossings (most) takes one pass and no idle one after it
    // (shaders/counters.wgsl); at most one crossing per triangle.
    var k = 0u;
    var more = false;
    loop {
        let tr = next_transition(range, r, t_enter, t_exit, (*w).after, (*w).medium);
        more = k < range.y && tr.found && tr.t < len;
        if more {
            pass_into(w, absorb, tr.t, tr.medium);
            (*w).after = tr.t + CELL_TOLERANCE;
            if (*w).opaque {
                return;
            }
        }
        continuing {
            k++;
            break if !more || loop_guard();
        }
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if more {
        loop_cut();
    }
}

// One step: true when the walk is over (past the segment, out of the grid, or opaque).
fn surface_step(s: ptr<function, Dda>, w: ptr<function, Media>, absorb: ptr<function, Absorb>, r: WatertightRay, len: f32) -> bool {
    let a = dda_axis((*s).t_max);
    let t = (*s).t_max[a];
    if !(t < len) {
        pass_into(w, absorb, max(len, (*w).t), 0u);
        return true;
    }
    dda_advance(s, a);
    if !voxel_inside((*s).voxel) {
        pass_into(w, absorb, max(t, (*w).t), 0u);
        return true;
    }
    let reg = dda_region(s);
    if is_cell(reg.material) {
        // Its crossings are taken in surface_transmittance's loop (see Dda::at_cell).
        (*s).at_cell = true;
        (*s).cell_t = t;
        return true;
    }
    pass_into(w, absorb, max(t, (*w).t), reg.material);
    dda_skip(s, reg);
    return (*w).opaque;
}

// Transmittance (RGB) of the segment from q along d (unit) of length len > 0, starting
// in shadow_medium.
fn surface_transmittance(q: vec3<f32>, d: vec3<f32>, len: f32, medium: u32) -> vec3<f32> {
    var w: Media;
    w.medium = 0u;
    w.t = 0.0;
    w.after = 0.0;
    w.opaque = false;
    var absorb = absorb_start();
    // The medium at q counts, as the start voxel does for voxels.
    pass_into(&w, &absorb, 0.0, medium);
    if w.opaque {
        return vec3<f32>(0.0);
    }
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return result(w, absorb);
    }
    let r = watertight_ray(q, d);
    var s = dda_init(q, d, e.voxel);
    let reg = dda_region(&s);
    if is_cell(reg.material) {
        pass_cell(&s, &w, &absorb, r, e.t, len);
    } else {
        pass_into(&w, &absorb, e.t, reg.material);
        dda_skip(&s, reg);
    }
    let n = walk_bound();
    // DDA_UNROLL steps per loop iteration, exit tested at the bottom, as cast_ray
    // (shaders/traversal.wgsl).
    var done = w.opaque;
    var i = 0u;
    if !done {
        loop {
            #walk_steps done = surface_step(&s, &w, &absorb, r, len);
            if s.at_cell {
                s.at_cell = false;
                pass_cell(&s, &w, &absorb, r, s.cell_t, len);
                done = w.opaque;
            }
            continuing {
                i += #{DDA_UNROLL}u;
                break if done || i >= n || loop_guard();
            }
        }
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if !done && i < n {
        loop_cut();
    }
    return result(w, absorb);
}

// Past the segment or the grid nothing more absorbs: the last medium ends where the
// walk did.
fn result(w: Media, absorb: Absorb) -> vec3<f32> {
    if w.opaque {
        return vec3<f32>(0.0);
    }
    return absorb_result(absorb, w.t);
}
