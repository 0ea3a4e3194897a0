//! The sparse traversal, the seed's O2: the DDA over the grid's 64-tree of uniform
//! regions (`crate::sparse`), leaving every region of the ray's medium whole, at the
//! voxel, distance and face where the dense DDA leaves it (`src/trace_contract.md`,
//! "Sparse traversal"; the structure and why a 64-tree: docs/sparse-traversal.md).
//!
//! It walks every grid. Under `render.traversal = "auto"` it takes grids of
//! [`SPARSE_FROM_SIDE`] voxels a side or more, and every grid held only as its tree.

use super::TraversalModel;

/// The grid side from which `render.traversal = "auto"` walks the sparse tree. Below it
/// the dense walk's one load per step costs less than the tree's descent and region
/// skip per step, for all the steps the tree saves: on lavapipe the seed scene renders
/// at 0.80x the dense walk's speed with the tree at 256^3 and at 2.03x at 512^3, the
/// bunny voxelized at 512 at 2.11x (`voxlab bench --sizes 256,512 --experiments
/// experiments/bunny_512.toml`, docs/sparse-traversal.md). A grid larger than the
/// device binds as one buffer is walked sparse whatever its side (`crate::gpu`).
pub const SPARSE_FROM_SIDE: u32 = 512;

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "sparse",
    summary: "the DDA over a 64-tree of uniform regions, skipping each region of the \
              ray's medium whole (the seed's O2)",
    label: "sparse 64-tree",
    plan: |_, _| Ok(()),
    auto: Some(|scene| {
        if scene.grid.is_sparse() {
            return Ok("the grid is held only as its sparse tree".into());
        }
        super::claim_from_side(scene, SPARSE_FROM_SIDE)
    }),
    wgsl: (
        "shaders/traversal_sparse.wgsl",
        include_str!("../../shaders/traversal_sparse.wgsl"),
    ),
    walks_tree: true,
    data: Some(|grid| grid.tree(crate::sparse::GPU_LOG_BRANCH)),
    device_bytes: None,
};
