// The sparse traversal (src/technique/sparse.rs): the grid's 64-tree of uniform regions
// (src/sparse.rs builds it and documents its layout). The region around a voxel is
// found by descending from the root, or from the node of the previous look-up when the
// voxel lies in its cube, as most steps near surfaces do; the walks (traversal.wgsl)
// leave a region whole with dda_skip. The f64 reference does the same with
// crate::sparse::SparseTree::region and crate::cpu::Dda::skip_region.
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::bindings::{params, walk_data}

// Regions are the tree's uniform children: traversal.wgsl's dda_skip leaves them whole.
const REGIONS_ARE_VOXELS: bool = false;

// The tree as vec4s: the header, then 5 per node: (mask of child nodes, low and high
// 32 children; index of the first child node; 0), then 16 words of materials.
const NODE_VEC4S: u32 = 5u;

// The descent's state: the node, the shift of its children's side (2 per level), and
// the material once a uniform child holds the voxel.
struct Descent {
    node: u32,
    shift: u32,
    found: bool,
    material: u32,
}

// One level: the child of the current node that holds v is either uniform (found) or
// the node to descend into. Written once and repeated TREE_LEVELS times in
// region_below rather than looped: Mesa's software driver limits back edges, not work
// (shaders/counters.wgsl).
fn descend(v: vec3<u32>, d: ptr<function, Descent>) {
    let c = (v >> vec3<u32>((*d).shift)) & vec3<u32>(3u);
    let i = c.x | (c.y << 2u) | (c.z << 4u);
    let base = 1u + (*d).node * NODE_VEC4S;
    // Mask and first child in one load.
    let head = walk_data[base];
    let word = select(head.x, head.y, i >= 32u);
    let bit = 1u << (i & 31u);
    if (word & bit) == 0u {
        (*d).found = true;
        let m = walk_data[base + 1u + (i >> 4u)][(i >> 2u) & 3u];
        (*d).material = (m >> (8u * (i & 3u))) & 255u;
        return;
    }
    let below = countOneBits(word & (bit - 1u)) + select(0u, countOneBits(head.x), i >= 32u);
    (*d).node = head.z + below;
    (*d).shift -= 2u;
}

// The shift of the root's children: the root's cube is 4^TREE_LEVELS a side.
const ROOT_SHIFT: u32 = 2u * (#{TREE_LEVELS}u - 1u);

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
#if TREE_LEVELS >= 2
    if !d.found { descend(u, &d); }
#endif
#if TREE_LEVELS >= 3
    if !d.found { descend(u, &d); }
#endif
#if TREE_LEVELS >= 4
    if !d.found { descend(u, &d); }
#endif
#if TREE_LEVELS >= 5
    if !d.found { descend(u, &d); }
#endif
#if TREE_LEVELS >= 6
    if !d.found { descend(u, &d); }
#endif
#if TREE_LEVELS >= 7
    if !d.found { descend(u, &d); }
#endif
#if TREE_LEVELS >= 8
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

// The node the last region was found under, its children's shift and its cube
// (voxel >> (shift + 2)): where the next look-up starts when its voxel is in that cube.
struct RegionCursor {
    node: u32,
    shift: u32,
    key: vec3<u32>,
}

// The root's cube holds every voxel of the grid.
fn region_cursor(step: vec3<i32>) -> RegionCursor {
    return RegionCursor(0u, ROOT_SHIFT, vec3<u32>(0u));
}

// The uniform region holding voxel v (inside the grid).
fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region {
    let u = vec3<u32>(v);
    var node = 0u;
    var shift = ROOT_SHIFT;
    if all((u >> vec3<u32>((*c).shift + 2u)) == (*c).key) {
        node = (*c).node;
        shift = (*c).shift;
    }
    let f = region_below(v, node, shift);
    (*c).node = f.node;
    (*c).shift = f.shift;
    (*c).key = u >> vec3<u32>(f.shift + 2u);
    return f.region;
}
