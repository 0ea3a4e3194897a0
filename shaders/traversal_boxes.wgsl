// The box traversal (src/technique/boxes.rs): beside each voxel's material, for each of
// the 8 octants a ray can head into, the codes of a box of that material with the voxel
// as its corner toward that octant, a reach per axis. Four planes of a word a voxel in
// `walk_data`, plane p holding octants 2p and 2p + 1, so a walk reads one word a step
// from its octant's plane; traversal.wgsl's dda_skip leaves the box whole. The f64
// reference reads the same field (crate::technique::boxes::BoxField).
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::bindings::{params, walk_data}
#import voxlab::box_codes::{box_reach, plane_shift}

// Regions are boxes of any size: dda_skip leaves them whole.
const REGIONS_ARE_VOXELS: bool = false;

// The walk's octant: the first word of its plane, where its box's code sits in a word,
// and the axes it heads down.
struct RegionCursor {
    plane: u32,
    shift: u32,
    down: vec3<i32>,
}

// An axis of step 0 takes the positive side (crate::technique::octant::octant).
fn region_cursor(step: vec3<i32>) -> RegionCursor {
    let down = select(vec3<i32>(0), vec3<i32>(1), step < vec3<i32>(0));
    let o = u32(down.x) | (u32(down.y) << 1u) | (u32(down.z) << 2u);
    let voxels = params.dims.x * params.dims.y * params.dims.z;
    return RegionCursor((o >> 1u) * voxels, plane_shift(o), down);
}

// The box of voxel v (inside the grid) toward the walk's octant, clipped to the grid.
fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region {
    let u = vec3<u32>(v);
    let i = (*c).plane + u.x + params.dims.x * (u.y + params.dims.y * u.z);
    let word = walk_data[i >> 2u][i & 3u];
    let reach = box_reach(word >> (*c).shift);
    let lo = v - reach * (*c).down;
    let hi = v + 1 + reach * (1 - (*c).down);
    return Region(word & 255u, max(lo, vec3<i32>(0)), min(hi, vec3<i32>(params.dims)));
}
