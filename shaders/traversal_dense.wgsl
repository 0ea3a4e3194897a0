// The dense traversal (src/technique/dense.rs): every region is one voxel, read from the
// voxel buffer, so the walk visits the grid voxel by voxel (Amanatides & Woo 1987) and
// never skips. The walks' generic code (traversal.wgsl) asks this module for regions.
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::bindings::voxel_material

// Every region is a voxel: traversal.wgsl's dda_skip folds to nothing.
const REGIONS_ARE_VOXELS: bool = true;

// Nothing is remembered between look-ups (WGSL has no empty struct).
struct RegionCursor {
    unused: u32,
}

fn region_cursor(step: vec3<i32>) -> RegionCursor {
    return RegionCursor(0u);
}

// The region of voxel v (inside the grid): the voxel.
fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region {
    return Region(voxel_material(v), v, v + vec3<i32>(1));
}
