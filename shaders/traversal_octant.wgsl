// The octant traversal (src/technique/octant.rs): beside each voxel's material, for each
// of the 8 octants a ray can head into, the code of the largest cube of that material
// with the voxel as its corner toward that octant, one word a voxel in `walk_data`. A
// walk reads its own octant's cube; traversal.wgsl's dda_skip leaves it whole. The f64
// reference reads the same field (crate::technique::octant::OctantField).
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::bindings::{params, walk_data}

// Regions are cubes of any size: dda_skip leaves them whole.
const REGIONS_ARE_VOXELS: bool = false;

// The walk's octant: where its code sits in a word, and the axes it heads down.
struct RegionCursor {
    shift: u32,
    down: vec3<i32>,
}

// An axis of step 0 takes the positive side (crate::technique::octant::octant).
fn region_cursor(step: vec3<i32>) -> RegionCursor {
    let down = select(vec3<i32>(0), vec3<i32>(1), step < vec3<i32>(0));
    let o = u32(down.x) | (u32(down.y) << 1u) | (u32(down.z) << 2u);
    return RegionCursor(8u + 3u * o, down);
}

// The cube of voxel v (inside the grid) toward the walk's octant, clipped to the grid:
// voxel i (x fastest) is word i, material in its low byte; code k stands for radius 0
// for k = 0, else 2^(k - 1): (1 << k) >> 1 (crate::technique::octant::RADII).
fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region {
    let u = vec3<u32>(v);
    let i = u.x + params.dims.x * (u.y + params.dims.y * u.z);
    let word = walk_data[i >> 2u][i & 3u];
    let k = (word >> (*c).shift) & 7u;
    let reach = vec3<i32>(i32((1u << k) >> 1u));
    let lo = v - reach * (*c).down;
    let hi = v + 1 + reach * (1 - (*c).down);
    return Region(word & 255u, max(lo, vec3<i32>(0)), min(hi, vec3<i32>(params.dims)));
}
