// The proximity traversal (src/technique/proximity.rs): beside each voxel's material the
// radius of the largest cube around it of that material only (Cohen and Sheffer's
// proximity clouds), two bytes a voxel in `walk_data`. One load a step, as the dense
// walk; traversal.wgsl's dda_skip leaves a cube of the ray's medium whole. The f64
// reference reads the same field (crate::technique::proximity::ProximityField).
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::bindings::{params, walk_data}

// Regions are cubes of any size: dda_skip leaves them whole.
const REGIONS_ARE_VOXELS: bool = false;

// Nothing is remembered between look-ups (WGSL has no empty struct).
struct RegionCursor {
    unused: u32,
}

fn region_cursor(step: vec3<i32>) -> RegionCursor {
    return RegionCursor(0u);
}

// The cube of voxel v (inside the grid), clipped to the grid: voxel i (x fastest) is
// half i % 2 of word i / 2, material in its low byte, radius in its high byte.
fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region {
    let u = vec3<u32>(v);
    let i = u.x + params.dims.x * (u.y + params.dims.y * u.z);
    let half = (walk_data[i >> 3u][(i >> 1u) & 3u] >> (16u * (i & 1u))) & 0xffffu;
    let r = vec3<i32>(i32(half >> 8u));
    return Region(half & 255u, max(v - r, vec3<i32>(0)), min(v + r + 1, vec3<i32>(params.dims)));
}
