// Ray casting through the voxel grid: ray/box entry by slabs, then the 3D DDA of
// Amanatides & Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics 1987.
// Follows src/trace_contract.md, "cast", step by step; the CPU reference does the same in
// f64, so both must change together.
#define_import_path voxlab::traversal

#import voxlab::types::BIG
#import voxlab::bindings::{params, voxel_material, voxel_inside}
#import voxlab::counters::count_step

struct Hit {
    hit: bool,
    t: f32,
    normal: vec3<f32>,
    // Material index of the hit voxel.
    material: u32,
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
    // The ray, so tMax can be taken from the next boundary plane at every step.
    origin: vec3<f32>,
    dir: vec3<f32>,
}

fn origin_inside(o: vec3<f32>) -> bool {
    return all(o >= vec3<f32>(0.0)) && all(o < vec3<f32>(params.dims));
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
    let hi = vec3<f32>(params.dims);
    var near = vec3<f32>(-BIG);
    var far = vec3<f32>(BIG);
    for (var a = 0; a < 3; a++) {
        if d[a] == 0.0 {
            // An axis-parallel ray: the slab is everything or nothing (no 0 * inf).
            if o[a] < 0.0 || o[a] > hi[a] {
                e.valid = false;
                return e;
            }
        } else {
            let t0 = (0.0 - o[a]) / d[a];
            let t1 = (hi[a] - o[a]) / d[a];
            near[a] = min(t0, t1);
            far[a] = max(t0, t1);
        }
    }
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
    for (var a = 0; a < 3; a++) {
        if d[a] == 0.0 {
            s.step[a] = 0;
            s.t_max[a] = BIG;
            s.t_delta[a] = BIG;
        } else {
            let positive = d[a] > 0.0;
            s.step[a] = select(-1, 1, positive);
            let boundary = f32(v[a] + select(0, 1, positive));
            s.t_max[a] = min((boundary - o[a]) / d[a], BIG);
            s.t_delta[a] = min(1.0 / abs(d[a]), BIG);
        }
    }
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
// Mathematically the same tMax; the f64 reference's sum drifts by ~1e-13 only.
fn dda_advance(s: ptr<function, Dda>, a: i32) {
    let step = (*s).step[a];
    (*s).voxel[a] += step;
    let boundary = f32((*s).voxel[a] + select(0, 1, step > 0));
    (*s).t_max[a] = min((boundary - (*s).origin[a]) / (*s).dir[a], BIG);
    count_step();
}

// A ray visits at most nx + ny + nz voxels; the bound only guards against a hang
// should float error ever stall the walk, it never ends a correct one.
fn max_steps() -> u32 {
    return params.dims.x + params.dims.y + params.dims.z + 3u;
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
    if e.axis >= 0 {
        let m = voxel_material(e.voxel);
        if m != medium {
            h.hit = true;
            h.t = e.t;
            h.normal = -sign(d[e.axis]) * axis_vec(e.axis);
            h.material = m;
            return h;
        }
    }
    var s = dda_init(o, d, e.voxel);
    let n = max_steps();
    for (var i = 0u; i < n; i++) {
        let a = dda_axis(s.t_max);
        let t = s.t_max[a];
        if t > t_limit {
            return h;
        }
        dda_advance(&s, a);
        if !voxel_inside(s.voxel) {
            return h;
        }
        let m = voxel_material(s.voxel);
        if m != medium {
            h.hit = true;
            h.t = t;
            h.normal = -f32(s.step[a]) * axis_vec(a);
            h.material = m;
            return h;
        }
    }
    return h;
}
