// Triangle surfaces found through the voxels they overlap (TRIANGLES; the seed's O6):
// the cells' triangle lists, the watertight ray/triangle test of Woop, Benthin and Wald
// ("Watertight Ray/Triangle Intersection", JCGT 2(1), 2013) and the medium rule. As
// crate::triangles, which says why each rule is what it is; the walks call
// is_cell and next_transition, which without TRIANGLES are never reached.
#define_import_path voxlab::triangles

#import voxlab::types::BIG
#import voxlab::bindings::{params, surface}
#import voxlab::counters::{loop_cut, loop_guard}

// The material the walks read for a cell (triangles::SURFACE_TAG).
const SURFACE_TAG: u32 = 255u;
// Voxel units: a cell's ray interval is grown by it, and crossings closer than it are
// one (triangles::CELL_TOLERANCE).
const CELL_TOLERANCE: f32 = 1e-3;

// The medium where shadow segments start: the tracer sets it at each hit (the side the
// hit was seen from), the shadow walk reads it.
var<private> shadow_medium: u32;

// A ray set up for the watertight test: its axes permuted so it runs along z, and the
// shear that makes it the z axis.
struct WatertightRay {
    origin: vec3<f32>,
    k: vec3<i32>,
    shear: vec3<f32>,
}

struct Crossing {
    hit: bool,
    t: f32,
    weights: vec3<f32>,
}

// The next crossing group in a cell (triangles::Transition).
struct Transition {
    found: bool,
    t: f32,
    medium: u32,
    triangle: u32,
    weights: vec3<f32>,
}

// Whether a region is a cell: never without TRIANGLES, where no region is.
fn is_cell(material: u32) -> bool {
#ifdef TRIANGLES
    return material == SURFACE_TAG;
#else
    return false;
#endif
}

fn watertight_ray(o: vec3<f32>, d: vec3<f32>) -> WatertightRay {
    let a = abs(d);
    var kz = 2;
    if a.x >= a.y && a.x >= a.z {
        kz = 0;
    } else if a.y >= a.z {
        kz = 1;
    }
    var kx = (kz + 1) % 3;
    var ky = (kx + 1) % 3;
    if d[kz] < 0.0 {
        let swap = kx;
        kx = ky;
        ky = swap;
    }
    var r: WatertightRay;
    r.origin = o;
    r.k = vec3<i32>(kx, ky, kz);
    r.shear = vec3<f32>(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    return r;
}

// Layout of `surface` (crate::triangles::SurfaceTrace::gpu_words): a header (the hash
// table's log2 size, and where the table, references and triangles start, in vec4s), the
// cells' hash table (a vec4 per slot: voxel index or EMPTY_SLOT, first reference,
// count), the references four to a vec4, six vec4s per triangle (three vertices in voxel
// units, the first's w its material; three shading normals).
const EMPTY_SLOT: u32 = 0xffffffffu;

fn tri_vertex(t: u32, k: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(surface[surface[0].w + 6u * t + k].xyz);
}

fn tri_normal(t: u32, k: u32) -> vec3<f32> {
    return bitcast<vec3<f32>>(surface[surface[0].w + 6u * t + 3u + k].xyz);
}

fn tri_material(t: u32) -> u32 {
    return surface[surface[0].w + 6u * t].w;
}

// The references of the cell at v: (first, count), count 0 when it is not a cell. An
// open-addressing table at most half full (Fibonacci hashing, linear probing), so a
// look-up reads one or two slots where a binary search over the cells would read ~17.
fn cell_range(v: vec3<i32>) -> vec2<u32> {
    let header = surface[0];
    let u = vec3<u32>(v);
    let key = u.x + params.dims.x * (u.y + params.dims.y * u.z);
    let size = 1u << header.x;
    var slot = (key * 2654435769u) >> (32u - header.x);
    // Most look-ups end at their home slot: that one is read before the loop, whose
    // back edges the software driver counts (shaders/counters.wgsl).
    let home = surface[header.y + slot];
    if home.x == key {
        return home.yz;
    }
    if home.x == EMPTY_SLOT {
        return vec2<u32>(0u);
    }
    slot = (slot + 1u) & (size - 1u);
    // The table always has an empty slot: the bound only guards a corrupt one.
    var i = 1u;
    for (; i < size; i++) {
        let c = surface[header.y + slot];
        if c.x == key {
            return c.yz;
        }
        if c.x == EMPTY_SLOT {
            return vec2<u32>(0u);
        }
        slot = (slot + 1u) & (size - 1u);
    }
    // Any other way out is the driver's loop limit (shaders/counters.wgsl).
    if i < size {
        loop_cut();
    }
    return vec2<u32>(0u);
}

fn tri_ref(i: u32) -> u32 {
    return surface[surface[0].z + i / 4u][i % 4u];
}

// The crossing of ray r with triangle t, either side (Woop et al. 2013, without the
// double-precision fallback: an edge function of 0 counts as inside for both triangles
// that share the edge, so a ray through it is never lost).
fn intersect(r: WatertightRay, t: u32) -> Crossing {
    var c: Crossing;
    c.hit = false;
    let a = tri_vertex(t, 0u) - r.origin;
    let b = tri_vertex(t, 1u) - r.origin;
    let cc = tri_vertex(t, 2u) - r.origin;
    let kx = r.k.x;
    let ky = r.k.y;
    let kz = r.k.z;
    let ax = a[kx] - r.shear.x * a[kz];
    let ay = a[ky] - r.shear.y * a[kz];
    let bx = b[kx] - r.shear.x * b[kz];
    let by = b[ky] - r.shear.y * b[kz];
    let cx = cc[kx] - r.shear.x * cc[kz];
    let cy = cc[ky] - r.shear.y * cc[kz];
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return c;
    }
    let det = u + v + w;
    if det == 0.0 {
        return c;
    }
    let tt = (u * r.shear.z * a[kz] + v * r.shear.z * b[kz] + w * r.shear.z * cc[kz]) / det;
    if !(abs(tt) < BIG) {
        return c;
    }
    c.hit = true;
    c.t = tt;
    c.weights = vec3<f32>(u, v, w) / det;
    return c;
}

// The medium past a crossing of a triangle of material m: every triangle separates void
// from its material.
fn crossed(medium: u32, m: u32) -> u32 {
    return select(0u, m, medium == 0u);
}

// The next crossing of ray r among the cell's triangles `range` (cell_range): the first
// at t > after within [t0, t1] grown by the tolerance. Crossings within the tolerance
// after it are the same crossing: the caller takes them with it by moving `after` to
// t + CELL_TOLERANCE (triangles::SurfaceTrace::next_transition).
fn next_transition(range: vec2<u32>, r: WatertightRay, t0: f32, t1: f32, after: f32, medium: u32) -> Transition {
    var tr: Transition;
    tr.found = false;
    let lo = t0 - CELL_TOLERANCE;
    let hi = t1 + CELL_TOLERANCE;
    tr.t = BIG;
    // Eight triangles per loop iteration, the exit tested at the bottom: the software
    // driver's loop limit counts passes (shaders/counters.wgsl), and a smooth surface's
    // cells list seven or eight on average (`voxlab bench --surfaces`), so most cells
    // take one pass, with no idle pass after it (a cell with no triangles takes one
    // pass that considers none).
    var j = 0u;
    loop {
        consider_eight(&tr, r, range, j, lo, hi, after);
        continuing {
            j += 8u;
            break if j >= range.y || loop_guard();
        }
    }
    if j < range.y {
        loop_cut();
    }
    if tr.found {
        tr.medium = crossed(medium, tri_material(tr.triangle));
    }
    return tr;
}

// consider() for references j .. j + 8 of range, those that exist; written out, not a
// loop of its own, whose iterations the driver would count.
fn consider_eight(tr: ptr<function, Transition>, r: WatertightRay, range: vec2<u32>, j: u32, lo: f32, hi: f32, after: f32) {
    if j + 0u < range.y {
        consider(tr, r, tri_ref(range.x + j + 0u), lo, hi, after);
    }
    if j + 1u < range.y {
        consider(tr, r, tri_ref(range.x + j + 1u), lo, hi, after);
    }
    if j + 2u < range.y {
        consider(tr, r, tri_ref(range.x + j + 2u), lo, hi, after);
    }
    if j + 3u < range.y {
        consider(tr, r, tri_ref(range.x + j + 3u), lo, hi, after);
    }
    if j + 4u < range.y {
        consider(tr, r, tri_ref(range.x + j + 4u), lo, hi, after);
    }
    if j + 5u < range.y {
        consider(tr, r, tri_ref(range.x + j + 5u), lo, hi, after);
    }
    if j + 6u < range.y {
        consider(tr, r, tri_ref(range.x + j + 6u), lo, hi, after);
    }
    if j + 7u < range.y {
        consider(tr, r, tri_ref(range.x + j + 7u), lo, hi, after);
    }
}

// Keeps triangle t's crossing in tr when it is inside [lo, hi], past `after` and the
// nearest so far.
fn consider(tr: ptr<function, Transition>, r: WatertightRay, t: u32, lo: f32, hi: f32, after: f32) {
    let c = intersect(r, t);
    if c.hit && c.t > after && c.t >= lo && c.t <= hi && c.t < (*tr).t {
        (*tr).t = c.t;
        (*tr).found = true;
        (*tr).triangle = t;
        (*tr).weights = c.weights;
    }
}

// The normals of a transition's hit for a ray along d: the shading normal interpolated
// from the vertices (the face's where they have none) and the face's own, both facing
// the ray (triangles::SurfaceTrace::hit). Returns (shading, geometric).
fn transition_normals(tr: Transition, d: vec3<f32>) -> array<vec3<f32>, 2> {
    let t = tr.triangle;
    let a = tri_vertex(t, 0u);
    var g = cross(tri_vertex(t, 1u) - a, tri_vertex(t, 2u) - a);
    let gl = length(g);
    g = select(vec3<f32>(0.0), g / gl, gl > 0.0);
    if dot(g, d) > 0.0 {
        g = -g;
    }
    let w = tr.weights;
    var n = w.x * tri_normal(t, 0u) + w.y * tri_normal(t, 1u) + w.z * tri_normal(t, 2u);
    let nl = length(n);
    if nl > 0.0 {
        n = n / nl;
        if dot(n, g) < 0.0 {
            n = -n;
        }
    } else {
        n = g;
    }
    return array<vec3<f32>, 2>(n, g);
}
