// The descent through the grid's 64-tree (src/sparse.rs builds it and documents its
// layout), shared by the walks over it: the sparse traversal (traversal_sparse.wgsl)
// from the root or its cursor's node, the sparse octant traversal
// (traversal_sparse_octant.wgsl) from a cell's node. The f64 reference:
// crate::sparse::SparseTree::region_below.
#define_import_path voxlab::tree

#import voxlab::types::Region
#import voxlab::bindings::{params, walk_data}

// The tree as vec4s: the header, then 5 per node: (mask of child nodes, low and high
// 32 children; index of the first child node; 0), then 16 words of materials.
const NODE_VEC4S: u32 = 5u;

// The descent's state: the node, the shift of its children's side (2 per level), and
// whether the child that holds the voxel is uniform.
struct Descent {
    node: u32,
    shift: u32,
    found: bool,
}

// Which of a node's 64 children holds v, for children of 2^shift a side.
fn child_index(v: vec3<u32>, shift: u32) -> u32 {
    let c = (v >> vec3<u32>(shift)) & vec3<u32>(3u);
    return c.x | (c.y << 2u) | (c.z << 4u);
}

// One level above the last: the child of the current node that holds v is either
// uniform (found) or the node to descend into. Written once and repeated for the tree's
// levels in region_below rather than looped: Mesa's software driver limits back edges,
// not work (shaders/counters.wgsl). It reads the node's mask alone: the material is
// read once, for the child the descent ends at.
fn descend(v: vec3<u32>, d: ptr<function, Descent>) {
    // Mask and first child in one load.
    descend_from(walk_data[1u + (*d).node * NODE_VEC4S], v, d);
}

// The same from the node's head (mask and first child) read already: the sparse octant
// walk's cell holds its node's (traversal_sparse_octant.wgsl).
fn descend_from(head: vec4<u32>, v: vec3<u32>, d: ptr<function, Descent>) {
    let i = child_index(v, (*d).shift);
    let word = select(head.x, head.y, i >= 32u);
    let bit = 1u << (i & 31u);
    if (word & bit) == 0u {
        (*d).found = true;
        return;
    }
    let below = countOneBits(word & (bit - 1u)) + select(0u, countOneBits(head.x), i >= 32u);
    (*d).node = head.z + below;
    (*d).shift -= 2u;
}

// What a descent found: the region, and the node and children's shift it ended at (the
// start of the next descent when the next voxel lies in that node's cube).
struct Found {
    region: Region,
    node: u32,
    shift: u32,
}

// The uniform region holding voxel v (inside the grid), descending from `node`, whose
// children are 2^shift a side and whose cube holds v, at most TREE_LEVELS levels (the
// plan's: the tree's depth, or a cell's levels for a walk that starts at a cell). The
// last level's children are voxels, uniform whatever its mask says, so only the levels
// above it read a mask. The region's material is read only `with_material`: a walk that
// has the child's word from elsewhere (the sparse octant walk's codes) leaves it out,
// a storage read fewer for every lane of a step on a software driver, which runs a
// branch's reads whatever its lanes take.
fn region_below(v: vec3<i32>, node: u32, shift: u32, with_material: bool) -> Found {
    let u = vec3<u32>(v);
    var d: Descent;
    d.node = node;
    d.shift = shift;
    d.found = false;
#if TREE_LEVELS >= 2
    descend(u, &d);
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
    f.region.material = 0u;
    if with_material {
        // Four materials a word, sixteen a vec4, after the node's head.
        let i = child_index(u, d.shift);
        let m = walk_data[1u + d.node * NODE_VEC4S + 1u + (i >> 4u)][(i >> 2u) & 3u];
        f.region.material = (m >> (8u * (i & 3u))) & 255u;
    }
    f.region.lo = vec3<i32>((u >> vec3<u32>(d.shift)) << vec3<u32>(d.shift));
    f.region.hi = min(f.region.lo + vec3<i32>(1 << d.shift), vec3<i32>(params.dims));
    f.node = d.node;
    f.shift = d.shift;
    return f;
}
