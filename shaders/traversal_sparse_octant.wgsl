// The sparse octant traversal (src/technique/sparse_octant.rs): the box field over the
// 64-tree's cubes of 2^log_cell voxels. In a cell the tree holds as one material the
// region is the walk's octant's box of such cells (as traversal_boxes.wgsl's box of
// voxels); in a cell the tree holds as a node, the uniform child the tree's descent from
// that node finds (shaders/tree.wgsl), and where the walk has codes, the child's box of
// its node's children toward the walk's octant. A walk without codes, one with them and
// one with them whose cells hold their nodes' heads are three kernels (WALK_VARIANT 0,
// 1, 2: crate::sparse::Regions::kernel_variant), each without the others' reads. The f64
// reference: crate::technique::sparse_octant::SparseOctant.
#define_import_path voxlab::regions

#import voxlab::types::Region
#import voxlab::bindings::{params, walk_data, walk_more_word}
#import voxlab::box_codes::{box_reach, plane_shift}
#import voxlab::tree::{Descent, NODE_VEC4S, descend_from, region_below}

// Regions are boxes of any size: dda_skip leaves them whole.
const REGIONS_ARE_VOXELS: bool = false;

// Read once a walk: the walk's octant (which word of a uniform cell and which plane of a
// node's block hold its box's code, where in the word, the axes it heads down), the cut
// (its first cell's vec4, log2 of a cell's side, its dims) and the codes below it (the
// first node with its children's codes, their first vec4 where they follow the cut, and
// where their distinct blocks of 256 words start after the nodes' block indices).
struct RegionCursor {
    plane: u32,
    box_shift: u32,
    child_shift: u32,
    down: vec3<i32>,
    cells: u32,
    log_cell: u32,
    cut_dims: vec3<u32>,
    coded_first: u32,
    codes: u32,
    blocks: u32,
}

// An axis of step 0 takes the positive side (crate::technique::octant::octant).
fn region_cursor(step: vec3<i32>) -> RegionCursor {
    let down = select(vec3<i32>(0), vec3<i32>(1), step < vec3<i32>(0));
    let o = u32(down.x) | (u32(down.y) << 1u) | (u32(down.z) << 2u);
    // After the tree: its header vec4 and five vec4s a node (voxlab::tree), or a header
    // of no nodes where this kernel reads none of it (SparseOctant::reads_tree).
    let at = 1u + walk_data[0].z * NODE_VEC4S;
    let cut = walk_data[at];
    let coded = walk_data[at + 1u];
    return RegionCursor(o >> 1u, 12u * (o & 1u), plane_shift(o), down, at + 2u, cut.x, cut.yzw, coded.x, at + coded.z, coded.w);
}

#if WALK_VARIANT >= 1
// Word i of the codes: after the cut where the walk's data fits one binding, else in
// the walk's further bindings (crate::technique::sparse_octant::CodesAt).
fn code_word(c: ptr<function, RegionCursor>, i: u32) -> u32 {
#if WALK_MORE_BINDINGS >= 1
    return walk_more_word(i);
#else
    let w = 4u * (*c).codes + i;
    return walk_data[w >> 2u][w & 3u];
#endif
}
#endif

// A cell's fourth word has this bit where the cell is uniform (a node's cell holds an
// index there; crate::technique::sparse_octant::UNIFORM_CELL).
const UNIFORM_CELL: u32 = 0x80000000u;

// The box of material `material` toward the walk's octant with `cell` (of 2^log voxels
// a side) as its corner, reaching `reach` cells along each axis
// (crate::technique::octant::corner_box), in voxels, clipped to the grid.
fn corner_region(c: ptr<function, RegionCursor>, cell: vec3<i32>, material: u32, reach: vec3<i32>, log: u32) -> Region {
    let lo = (cell - reach * (*c).down) << vec3<u32>(log);
    let hi = (cell + 1 + reach * (1 - (*c).down)) << vec3<u32>(log);
    return Region(material, max(lo, vec3<i32>(0)), min(hi, vec3<i32>(params.dims)));
}

#if WALK_VARIANT >= 1
// The word of child p of a node whose block of codes is `block`: four planes of 64
// words, plane q the children's materials and the box codes of octants 2q and 2q + 1
// (crate::technique::sparse_octant::PLANES), so a step reads its octant's plane.
fn child_word(c: ptr<function, RegionCursor>, block: u32, p: vec3<u32>) -> u32 {
    return code_word(c, (*c).blocks + 256u * block + 64u * (*c).plane + p.x + 4u * p.y + 16u * p.z);
}
#endif

// The reaches of a uniform cell's box toward the walk's octant: four words a cell, word
// p holding octants 2p and 2p + 1 (twelve bits each), the first word the material in
// its top byte.
fn cell_reach(c: ptr<function, RegionCursor>, cell: vec4<u32>) -> vec3<i32> {
    return box_reach(cell[(*c).plane] >> (*c).box_shift);
}

// The uniform region holding voxel v (inside the grid), for the walk's octant.
fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region {
    let u = vec3<u32>(v);
    let cell = u >> vec3<u32>((*c).log_cell);
    let d = (*c).cut_dims;
    let i = cell.x + d.x * (cell.y + d.y * cell.z);
    // The node of the tree's level at or above the cell (src/sparse.rs, cut_node_log).
    let node_log = ((*c).log_cell + 1u) & ~1u;
    // A vec4 a cell: a uniform cell's material and box codes (cell_reach), or a node's
    // cell.
    let head = walk_data[(*c).cells + i];
    var at = cell;
    var material = head.x >> 24u;
    var reach = cell_reach(c, head);
    var log = (*c).log_cell;
#if WALK_VARIANT == 2
    // KERNEL_WITH_HEADS: the cells' nodes are nodes of 16 with codes. A node's cell holds
    // its node's head (the mask and first child the descent's first level reads) and one
    // more than its block index, so a step reads the cell and no tree; below the node of
    // 16 a leaf's children are voxels, whose words are its codes. The descent ends at the
    // cell's node (its block from the cell) or at a leaf (its block from the codes'
    // indices). One region for both sides, so the driver, which runs both sides of the
    // branch, builds one.
    if (head.w & UNIFORM_CELL) == 0u {
        var dn: Descent;
        dn.node = 0u;
        dn.shift = node_log - 2u;
        dn.found = false;
        descend_from(head, u, &dn);
        var block = head.w - 1u;
        if !dn.found {
            block = code_word(c, dn.node - (*c).coded_first);
        }
        at = u >> vec3<u32>(dn.shift);
        let p = at & vec3<u32>(3u);
        let code = child_word(c, block, p);
        material = code & 255u;
        reach = box_reach(code >> (*c).child_shift);
        log = dn.shift;
    }
    return corner_region(c, vec3<i32>(at), material, reach, log);
#else
    // A node's cell: its block index (0 without codes) and one more than its node's
    // index.
#if WALK_VARIANT == 1
    // With codes (KERNEL_WITH_CODES): every node below the cut has them (the tree's last
    // nodes), and a child's word holds its material. In a node's cell, the uniform
    // child's own box in children of the node the descent ends at; else the cell's box
    // of cells. One region for both, so the driver, which runs both sides of the branch,
    // builds one.
    if (head.w & UNIFORM_CELL) == 0u {
        let found = region_below(v, head.y - 1u, node_log - 2u, false);
        at = u >> vec3<u32>(found.shift);
        let p = at & vec3<u32>(3u);
        // The node's block of its children's words, shared by the nodes with the same
        // words (crate::technique::sparse_octant::SparseOctant::with_codes): a descent
        // of one level ends at the cell's node, whose index the cell holds.
#if TREE_LEVELS == 1
        let block = head.x;
#else
        let block = code_word(c, found.node - (*c).coded_first);
#endif
        let code = child_word(c, block, p);
        material = code & 255u;
        reach = box_reach(code >> (*c).child_shift);
        log = found.shift;
    }
    return corner_region(c, vec3<i32>(at), material, reach, log);
#else
    // Without codes: the uniform child itself, its material read from the tree.
    if (head.w & UNIFORM_CELL) == 0u {
        return region_below(v, head.y - 1u, node_log - 2u, true).region;
    }
    return corner_region(c, vec3<i32>(at), material, reach, log);
#endif
#endif
}
