// The sparse 64-tree of uniform regions (SPARSE; src/sparse.rs builds it and documents
// its layout): the region around a voxel, found by descending from the root. The walks
// (traversal.wgsl, shadow.wgsl, shadow_surface.wgsl) leave a region whole with
// dda_skip; the f64 reference does the same with crate::sparse::SparseTree::region.
#define_import_path voxlab::sparse

#import voxlab::bindings::{params, tree, voxel_material}

#ifdef SPARSE
// The tree as vec4s: the header, then 5 per node: (mask of child nodes, low and high
// 32 children; index of the first child node; 0), then 16 words of materials.
const NODE_VEC4S: u32 = 5u;

// A uniform region: its material and its cube `lo + [0, size)^3`, clipped to the grid.
struct Region {
    material: u32,
    lo: vec3<i32>,
    hi: vec3<i32>,
}

// The descent's state: the node, the shift of its children's side (2 per level), and
// the material once a uniform child holds the voxel.
struct Descent {
    node: u32,
    shift: u32,
    found: bool,
    material: u32,
}

// One level: the child of the current node that holds v is either uniform (found) or
// the node to descend into. Written once and repeated SPARSE_LEVELS times in
// region_below rather than looped: Mesa's software driver limits back edges, not work
// (shaders/counters.wgsl).
fn descend(v: vec3<u32>, d: ptr<function, Descent>) {
    let c = (v >> vec3<u32>((*d).shift)) & vec3<u32>(3u);
    let i = c.x | (c.y << 2u) | (c.z << 4u);
    let base = 1u + (*d).node * NODE_VEC4S;
    // Mask and first child in one load.
    let head = tree[base];
    let word = select(head.x, head.y, i >= 32u);
    let bit = 1u << (i & 31u);
    if (word & bit) == 0u {
        (*d).found = true;
        let m = tree[base + 1u + (i >> 4u)][(i >> 2u) & 3u];
        (*d).material = (m >> (8u * (i & 3u))) & 255u;
        return;
    }
    let below = countOneBits(word & (bit - 1u)) + select(0u, countOneBits(head.x), i >= 32u);
    (*d).node = head.z + below;
    (*d).shift -= 2u;
}

// The shift of the root's children: the root's cube is 4^SPARSE_LEVELS a side.
const ROOT_SHIFT: u32 = 2u * (#{SPARSE_LEVELS}u - 1u);

// What a descent found: the region, and the node and children's shift it ended at (the
// start of the next descent when the next voxel lies in that node's cube).
struct Found {
    region: Region,
    node: u32,
    shift: u32,
}

// The uniform region holding voxel v (inside the grid), descending from `node`, whose
// children are 2^shift a side and whose cube holds v.
fn region_below(v: vec3<i32>, node: u32, shift: u32) -> Found {
    let u = vec3<u32>(v);
    var d: Descent;
    d.node = node;
    d.shift = shift;
    d.found = false;
    descend(u, &d);
#if SPARSE_LEVELS >= 2
    if !d.found { descend(u, &d); }
#endif
#if SPARSE_LEVELS >= 3
    if !d.found { descend(u, &d); }
#endif
#if SPARSE_LEVELS >= 4
    if !d.found { descend(u, &d); }
#endif
#if SPARSE_LEVELS >= 5
    if !d.found { descend(u, &d); }
#endif
#if SPARSE_LEVELS >= 6
    if !d.found { descend(u, &d); }
#endif
#if SPARSE_LEVELS >= 7
    if !d.found { descend(u, &d); }
#endif
#if SPARSE_LEVELS >= 8
    if !d.found { descend(u, &d); }
#endif
    var f: Found;
    f.region.material = d.material;
    f.region.lo = vec3<i32>((u >> vec3<u32>(d.shift)) << vec3<u32>(d.shift));
    f.region.hi = min(f.region.lo + vec3<i32>(1 << d.shift), vec3<i32>(params.dims));
    f.node = d.node;
    f.shift = d.shift;
    return f;
}

// The uniform region holding voxel v, from the root.
fn voxel_region(v: vec3<i32>) -> Region {
    return region_below(v, 0u, ROOT_SHIFT).region;
}
#else
// Without SPARSE nothing calls it (naga_oil still resolves the module): the dense
// grid's region of a voxel is the voxel.
struct Region {
    material: u32,
    lo: vec3<i32>,
    hi: vec3<i32>,
}

fn voxel_region(v: vec3<i32>) -> Region {
    return Region(voxel_material(v), v, v + vec3<i32>(1));
}

const ROOT_SHIFT: u32 = 0u;

struct Found {
    region: Region,
    node: u32,
    shift: u32,
}

fn region_below(v: vec3<i32>, node: u32, shift: u32) -> Found {
    return Found(voxel_region(v), node, shift);
}
#endif
