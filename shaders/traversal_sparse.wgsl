// The sparse traversal (src/technique/sparse.rs): the grid's 64-tree of uniform regions
// (src/sparse.rs builds it and documents its layout). The region around a voxel is
// found by descending from the root, or from the node of the previous look-up when the
// voxel lies in its cube, as most steps near surfaces do; the walks (traversal.wgsl)
// leave a region whole with dda_skip. The f64 reference does the same with
// crate::sparse::SparseTree::region and crate::cpu::Dda::skip_region.
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::tree::region_below

// Regions are the tree's uniform children: traversal.wgsl's dda_skip leaves them whole.
const REGIONS_ARE_VOXELS: bool = false;

// The shift of the root's children: the root's cube is 4^TREE_LEVELS a side.
const ROOT_SHIFT: u32 = 2u * (#{TREE_LEVELS}u - 1u);

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
    let f = region_below(v, node, shift, true);
    (*c).node = f.node;
    (*c).shift = f.shift;
    (*c).key = u >> vec3<u32>(f.shift + 2u);
    return f.region;
}
