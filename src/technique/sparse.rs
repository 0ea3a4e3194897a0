//! The sparse traversal, the seed's O2: the DDA over the grid's 64-tree of uniform
//! regions (`crate::sparse`), leaving every region of the ray's medium whole, at the
//! voxel, distance and face where the dense DDA leaves it (`src/trace_contract.md`,
//! "Sparse traversal"; the structure and why a 64-tree: docs/sparse-traversal.md).
//!
//! It walks every grid, on demand (`render.traversal = "sparse"`): under `"auto"` the
//! sparse octant walk ([`super::sparse_octant`], the same tree with an octant field over
//! its cubes) takes the grids this walk would, in fewer steps.

use super::TraversalModel;

/// The grid side from which `render.traversal = "auto"` walks the tree (the sparse
/// octant walk, [`super::sparse_octant`], which claims it). Below it the dense walk's
/// one load per step costs less than the tree's descent and region skip per step, for
/// all the steps the tree saves: on lavapipe the seed scene rendered at 0.80x the dense
/// walk's speed with this walk at 256^3 and at 2.03x at 512^3, the bunny voxelized at
/// 512 at 2.11x (`voxlab bench --sizes 256,512 --experiments experiments/bunny_512.toml`,
/// docs/sparse-traversal.md). Below 512 the octant field is at least as fast as both
/// tree walks (256^3, seed rules, 256x256: 65.1 ms against 66.0 for the sparse octant
/// walk, "A descent's reads"; 90 against 427 before its codes). A grid
/// larger than the device binds as one buffer is walked through the tree whatever its
/// side (`crate::gpu`).
pub const SPARSE_FROM_SIDE: u32 = 512;

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
