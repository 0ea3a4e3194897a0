//! The sparse traversal, the seed's O2: the DDA over the grid's 64-tree of uniform
//! regions (`crate::sparse`), leaving every region of the ray's medium whole, at the
//! voxel, distance and face where the dense DDA leaves it (`src/trace_contract.md`,
//! "Sparse traversal"; the structure and why a 64-tree: docs/sparse-traversal.md).
//!
//! It walks every grid, on demand (`render.traversal = "sparse"`): under `"auto"` the
//! sparse octant walk ([`super::sparse_octant`], the same tree with a box field over its
//! cubes and their children) takes the grids this walk would, in fewer steps.

use super::TraversalModel;

/// The grid side from which `render.traversal = "auto"` walks the tree (the sparse
/// octant walk, [`super::sparse_octant`], which claims it). Below it the dense walk's
/// one load per step costs less than the tree's descent and region skip per step, for
/// all the steps the tree saves: on lavapipe the seed scene rendered at 0.80x the dense
/// walk's speed with this walk at 256^3 and at 2.03x at 512^3, the bunny voxelized at
/// 512 at 2.11x (`voxlab bench --sizes 256,512 --experiments experiments/bunny_512.toml`,
/// docs/sparse-traversal.md). Since its kernel with codes leaves out the tree's material
/// reads it is faster than the octant field from 256^3, in an eighth of its memory, and
/// slower below 240^3 (seed rules, 256x256, three runs of `voxlab bench --sizes
/// 16,64,128,192,256 --size 256 --gpu-runs 5 --no-cpu --rules seed --traversal
/// octant,sparse_octant` and of `--sizes 208,224,240`: 55.2 to 57.7 ms against 61.4 to
/// 64.6 at 256^3, 54.4 to 56.4 against 53.4 to 56.2 at 240^3, 50.0 to 50.6 against 47.0
/// to 48.3 at 192^3; the bunny voxelized at 256, 166.6 and 173.4 against 150.8 and 179.1),
/// so it takes the grid from 256 (320 before, 512 before that: from 320 up to 512 "auto"
/// took on lavapipe the proximity field, 384^3: 157 ms, or, past its two bytes a voxel,
/// the dense DDA, 448^3: 1691 ms, where this walk takes 86 ms and 85 ms). A grid of a
/// smaller side has at most 16.6 M voxels, whose octant field lavapipe binds
/// (docs/sparse-traversal.md, "Where auto walks the tree").
pub const SPARSE_FROM_SIDE: u32 = 256;

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "sparse",
    summary: "the DDA over a 64-tree of uniform regions, skipping each region of the \
              ray's medium whole (the seed's O2)",
    label: "sparse 64-tree",
    plan: |_, _| Ok(()),
    auto: None,
    wgsl: (
        "shaders/traversal_sparse.wgsl",
        include_str!("../../shaders/traversal_sparse.wgsl"),
    ),
    walks_tree: true,
    descent_levels: None,
    data: Some(|grid, _| grid.tree(crate::sparse::GPU_LOG_BRANCH)),
    device_bytes: None,
};
