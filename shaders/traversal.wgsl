// Ray casting through the voxel grid: ray/box entry by slabs, then the 3D DDA of
// Amanatides & Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics 1987.
// Follows src/trace_contract.md, "cast", step by step; the CPU reference does the same in
// f64, so both must change together.
#define_import_path voxlab::traversal

#import voxlab::types::{BIG, Region}
#import voxlab::bindings::{params, voxel_inside}
#import voxlab::counters::{count_step, loop_cut, loop_guard}
#import voxlab::regions::{RegionCursor, REGIONS_ARE_VOXELS, region_cursor, region_at}
#import voxlab::triangles::{is_cell, cell_range, watertight_ray, next_transition, transition_normals}

struct Hit {
    hit: bool,
    t: f32,
    // The shading normal, facing the ray.
    normal: vec3<f32>,
    // Material past the surface: the hit voxel's, or void when leaving into void.
    material: u32,
    // The surface's own normal, facing the ray, along which secondary and shadow rays
    // start off it: a voxel face's normal, or a triangle's (TRIANGLES).
    geometric: vec3<f32>,
}

// Where a ray starts its walk: the voxel, its ray parameter, and for a ray that enters
// the box from outside the entry face's axis (-1 when the origin is inside).
struct Entry {
    valid: bool,
    voxel: vec3<i32>,
    t: f32,
    axis: i32,
}

// State of the DDA (contract step 2).
struct Dda {
    voxel: vec3<i32>,
    step: vec3<i32>,
    t_max: vec3<f32>,
    t_delta: vec3<f32>,
    // 1 / dir, 1 on axes the ray does not move along (their planes are never taken).
    inv_dir: vec3<f32>,
    // The ray, so tMax can be taken from the next boundary plane at every step.
    origin: vec3<f32>,
    dir: vec3<f32>,
    // What the traversal (voxlab::regions) keeps between region look-ups.
    cursor: RegionCursor,
    // TRIANGLES: the walk stopped at a cell entered at cell_t. A step only stops there;
    // the loop around the steps tests the cell's triangles, so that code is written
    // once, not once per unrolled step (the software driver's code grows with each
    // copy, and its time with it).
    at_cell: bool,
    cell_t: f32,
}

fn origin_inside(o: vec3<f32>) -> bool {
    return all(o >= vec3<f32>(0.0)) && all(o < vec3<f32>(params.dims));
}

// Whether a ray from o along d starts outside the grid and does not move towards it on
// some axis: its slab on that axis lies behind it, so `enter` finds no entry and the ray
// hits nothing. The tracer counts such a ray without tracing it (trace.wgsl, spawn).
fn leaves_grid(o: vec3<f32>, d: vec3<f32>) -> bool {
    let zero = vec3<f32>(0.0);
    let hi = vec3<f32>(params.dims);
    return any(((o < zero) & (d <= zero)) | ((o > hi) & (d >= zero)));
}

// Contract step 1: the start voxel of a ray from o along d (unit).
fn enter(o: vec3<f32>, d: vec3<f32>) -> Entry {
    var e: Entry;
    if origin_inside(o) {
        e.valid = true;
        e.voxel = vec3<i32>(floor(o));
        e.t = 0.0;
        e.axis = -1;
        return e;
    }
    // Among these: an axis the ray does not move along is a slab of everything or
    // nothing (no 0 * inf below).
    if leaves_grid(o, d) {
        e.valid = false;
        return e;
    }
    let hi = vec3<f32>(params.dims);
    // Written on whole vectors, without a loop over the axes: per component the same
    // operations as the contract's, and no loop for the driver's limiter to cut.
    let parallel = d == vec3<f32>(0.0);
    let safe = select(d, vec3<f32>(1.0), parallel);
    let t0 = (vec3<f32>(0.0) - o) / safe;
    let t1 = (hi - o) / safe;
    let near = select(min(t0, t1), vec3<f32>(-BIG), parallel);
    let far = select(max(t0, t1), vec3<f32>(BIG), parallel);
    let t_enter = max(max(near.x, near.y), max(near.z, 0.0));
    let t_exit = min(far.x, min(far.y, far.z));
    if t_enter > t_exit {
        e.valid = false;
        return e;
    }
    // The entry face: the largest near distance, ties to the lowest axis.
    var axis = 0;
    if near.y > near[axis] {
        axis = 1;
    }
    if near.z > near[axis] {
        axis = 2;
    }
    e.valid = true;
    e.voxel = clamp(vec3<i32>(floor(o + t_enter * d)), vec3<i32>(0), vec3<i32>(params.dims) - 1);
    e.t = t_enter;
    e.axis = axis;
    return e;
}

fn axis_vec(a: i32) -> vec3<f32> {
    var v = vec3<f32>(0.0);
    v[a] = 1.0;
    return v;
}

// Contract step 2. tMax is the ray parameter of the next boundary measured from o, so it
// is comparable with t_enter and t_limit; in voxel units tDelta = 1 / |d|.
fn dda_init(o: vec3<f32>, d: vec3<f32>, v: vec3<i32>) -> Dda {
    var s: Dda;
    s.voxel = v;
    s.origin = o;
    s.dir = d;
    s.at_cell = false;
    s.cell_t = 0.0;
    // Per axis as the contract says, on whole vectors (no loop: see enter).
    let parallel = d == vec3<f32>(0.0);
    let positive = d > vec3<f32>(0.0);
    let safe = select(d, vec3<f32>(1.0), parallel);
    s.step = select(select(vec3<i32>(-1), vec3<i32>(1), positive), vec3<i32>(0), parallel);
    s.cursor = region_cursor(s.step);
    let boundary = vec3<f32>(v + select(vec3<i32>(0), vec3<i32>(1), positive));
    s.inv_dir = 1.0 / safe;
    s.t_max = select(min((boundary - o) * s.inv_dir, vec3<f32>(BIG)), vec3<f32>(BIG), parallel);
    s.t_delta = select(min(abs(s.inv_dir), vec3<f32>(BIG)), vec3<f32>(BIG), parallel);
    return s;
}

// The axis of the smallest tMax, ties to the lowest axis: x before y before z.
fn dda_axis(t_max: vec3<f32>) -> i32 {
    if t_max.x <= t_max.y && t_max.x <= t_max.z {
        return 0;
    }
    if t_max.y <= t_max.z {
        return 1;
    }
    return 2;
}

// Moves to the next voxel along axis a (contract step 3) and counts the step. tMax is
// (plane - o) / d from the next boundary plane, not tMax += tDelta: in f32 the sum
// drifts by about one ulp of t per step (0.03 voxels after 500 steps at t ~ 1000),
// more than the ray offset, so hits on large grids landed off their faces and their
// secondary rays started on the wrong side (seed scene at 256^3: 4 % of pixels off).
// Mathematically the same tMax; the f64 reference's sum drifts by ~1e-13 only. The
// division is a product with 1 / d, computed once (Dda::inv_dir), here, in dda_init and
// in dda_skip alike: every plane distance of a walk is rounded the same way, so a skip
// and the voxel steps it stands for break ties alike, and dda_skip's nine divisions
// become products (on lavapipe, seed scene at 256x256, two runs each alternating: the
// proximity walk 1.10x as fast at 64^3 and 1.03x at 256^3, the sparse walk 1.06x and
// 1.11x; the dense walk unchanged).
fn dda_advance(s: ptr<function, Dda>, a: i32) {
    let step = (*s).step[a];
    (*s).voxel[a] += step;
    let boundary = f32((*s).voxel[a] + select(0, 1, step > 0));
    (*s).t_max[a] = min((boundary - (*s).origin[a]) * (*s).inv_dir[a], BIG);
    count_step();
}

// The uniform region of the walk's current voxel, as the planned traversal finds it
// (voxlab::regions: the voxel itself for the dense walk, the tree's region for the
// sparse one). Every walk reads its voxels through this and dda_skip, so all
// traversals share one walk.
fn dda_region(s: ptr<function, Dda>) -> Region {
    // Through a local: naga's SPIR-V writer cannot pass a pointer to a member of a
    // pointed-to struct as an argument ("Expression is not cached").
    var cursor = (*s).cursor;
    let r = region_at(&cursor, (*s).voxel);
    (*s).cursor = cursor;
    return r;
}

// Moves the walk to the last voxel of region r (which holds the current voxel) through
// which the ray leaves it, as if it had stepped through every voxel between, so that
// the next dda_advance leaves the region where the dense walk leaves it: at the earliest
// exit plane (t*, a*), ties to the lowest axis, every other axis past the planes that
// come before it in that order. As crate::cpu::Dda::skip_region. The estimate from the
// exit point, moved half a voxel ahead, is the right voxel or the one after it (the
// point's error is far below half a voxel), so one check of the plane behind it, on
// whole vectors and without branches, settles every axis. Where every region is one
// voxel (the dense walk) the constant condition leaves the rest out of the kernel.
fn dda_skip(s: ptr<function, Dda>, r: Region) {
    if REGIONS_ARE_VOXELS || all(r.hi - r.lo == vec3<i32>(1)) {
        return;
    }
    let step = (*s).step;
    let positive = step > vec3<i32>(0);
    let parallel = step == vec3<i32>(0);
    let inv = (*s).inv_dir;
    let o = (*s).origin;
    let edge = select(r.lo, r.hi, positive);
    let t_exit = select(min((vec3<f32>(edge) - o) * inv, vec3<f32>(BIG)), vec3<f32>(BIG), parallel);
    let a_star = dda_axis(t_exit);
    let t_star = t_exit[a_star];
    let p = o + t_star * (*s).dir + 0.5 * vec3<f32>(step);
    let last = select(r.lo, r.hi - 1, positive);
    let v = (*s).voxel;
    let ahead = select(vec3<i32>(0), vec3<i32>(1), positive);
    var c = clamp(vec3<i32>(floor(p)), min(v, last), max(v, last));
    // The plane into c: crossed before (t*, a*) in the walk's order, or c is one too far.
    let t_in = min((vec3<f32>(c - step + ahead) - o) * inv, vec3<f32>(BIG));
    let axis = vec3<i32>(0, 1, 2);
    let crossed = (t_in < vec3<f32>(t_star)) | ((t_in == vec3<f32>(t_star)) & (axis < vec3<i32>(a_star)));
    c = select(c, c - step, (c != v) & !crossed);
    (*s).voxel = select(c, v, parallel);
    let t_next = min((vec3<f32>((*s).voxel + ahead) - o) * inv, vec3<f32>(BIG));
    (*s).t_max = select(t_next, vec3<f32>(BIG), parallel);
}

// A ray visits at most nx + ny + nz voxels; the bound only guards against a hang
// should float error ever stall the walk, it never ends a correct one.
fn max_steps() -> u32 {
    return params.dims.x + params.dims.y + params.dims.z + 3u;
}

// The bound of a walk's loop counter, which counts DDA_UNROLL a loop iteration: with
// TRIANGLES an iteration ends at every cell (Dda::at_cell), after as little as one step,
// so the bound is max_steps iterations, not max_steps counted steps (which ended walks
// through many cells early: a bug of the first version, seen with DDA_UNROLL 8).
fn walk_bound() -> u32 {
#ifdef TRIANGLES
    return max_steps() * #{DDA_UNROLL}u;
#else
    return max_steps();
#endif
}

// The first crossing in the cell the walk is in, entered at t_enter (TRIANGLES): with
// one, h is the hit and the walk is over.
fn cell_hit(s: ptr<function, Dda>, h: ptr<function, Hit>, medium: u32, t_enter: f32) -> bool {
    let t_exit = min((*s).t_max.x, min((*s).t_max.y, (*s).t_max.z));
    let r = watertight_ray((*s).origin, (*s).dir);
    let tr = next_transition(cell_range((*s).voxel), r, t_enter, t_exit, 0.0, medium);
    if !tr.found {
        return false;
    }
    let n = transition_normals(tr, (*s).dir);
    (*h).hit = true;
    (*h).t = tr.t;
    (*h).normal = n[0];
    (*h).geometric = n[1];
    (*h).material = tr.medium;
    return true;
}

// One step of cast_ray's walk (contract "cast", step 3); true when the walk is over,
// with the hit, if any, in h.
fn cast_step(s: ptr<function, Dda>, h: ptr<function, Hit>, medium: u32, t_limit: f32) -> bool {
    let a = dda_axis((*s).t_max);
    let t = (*s).t_max[a];
    if t > t_limit {
        return true;
    }
    dda_advance(s, a);
    if !voxel_inside((*s).voxel) {
        // Outside the grid is void: leaving a non-void medium is a hit on void at the
        // exit face. The seed's rules make it a miss (SEED_RULES, compiled in: the
        // software driver would run this for every step whatever the rules).
#ifndef SEED_RULES
        if medium != 0u {
            (*h).hit = true;
            (*h).t = t;
            (*h).normal = -f32((*s).step[a]) * axis_vec(a);
            (*h).geometric = (*h).normal;
            (*h).material = 0u;
        }
#endif
        return true;
    }
    let r = dda_region(s);
    if is_cell(r.material) {
        // A cell is never skipped: its triangles decide, in cast_ray's loop.
        (*s).at_cell = true;
        (*s).cell_t = t;
        return true;
    }
    if r.material != medium {
        (*h).hit = true;
        (*h).t = t;
        (*h).normal = -f32((*s).step[a]) * axis_vec(a);
        (*h).geometric = (*h).normal;
        (*h).material = r.material;
        return true;
    }
    // A region of the ray's medium holds no hit: leave it whole.
    dda_skip(s, r);
    return false;
}

// cast(o, d, medium, t_limit) of the contract (`cast` is reserved in WGSL): the first voxel whose material differs
// from `medium`.
fn cast_ray(o: vec3<f32>, d: vec3<f32>, medium: u32, t_limit: f32) -> Hit {
    var h: Hit;
    h.hit = false;
    let e = enter(o, d);
    if !e.valid {
        return h;
    }
    var s = dda_init(o, d, e.voxel);
    let r = dda_region(&s);
    if is_cell(r.material) {
        if cell_hit(&s, &h, medium, e.t) {
            return h;
        }
    } else if e.axis >= 0 && r.material != medium {
        h.hit = true;
        h.t = e.t;
        h.normal = -sign(d[e.axis]) * axis_vec(e.axis);
        h.geometric = h.normal;
        h.material = r.material;
        return h;
    } else if r.material == medium {
        dda_skip(&s, r);
    }
    let n = walk_bound();
    // DDA_UNROLL steps (1, 2, 4 or 8; the host's choice per device, src/gpu/mod.rs) per
    // loop iteration: the software driver's loop limit counts back edges, not work
    // (shaders/counters.wgsl), so a walk of k voxels spends k / DDA_UNROLL of it. But
    // that driver runs every step written out whatever `done` says (its branches are
    // masks), so each walk also pays up to DDA_UNROLL - 1 idle steps. The exit is tested
    // at the bottom, so no pass runs after the last lane's walk is over (shaders/
    // counters.wgsl).
    // `#walk_steps` writes the unrolled steps (src/gpu/compose.rs, expand_walk_steps),
    // the one template of this walk and the shadow walks.
    var done = false;
    var i = 0u;
    loop {
        #walk_steps done = cast_step(&s, &h, medium, t_limit);
#ifdef TRIANGLES
        if s.at_cell {
            s.at_cell = false;
            done = cell_hit(&s, &h, medium, s.cell_t);
        }
#endif
        continuing {
            i += #{DDA_UNROLL}u;
            break if done || i >= n || loop_guard();
        }
    }
    // The walk ends by a step, or after max_steps; leaving the loop any other way is the
    // driver's loop limit (shaders/counters.wgsl, loop_cut).
    if !done && i < n {
        loop_cut();
    }
    return h;
}
