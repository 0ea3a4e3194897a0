//! The dense traversal, the seed's and the default: the 3D DDA of J. Amanatides and A.
//! Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing" (Eurographics 1987), voxel by
//! voxel through the grid held as one byte a voxel.
//!
//! Contract: `src/trace_contract.md`, "cast"; every region is one voxel, so the walk
//! never skips. It cannot walk a grid held only as its sparse tree (a loaded scene too
//! large for the dense grid, `crate::scene::DENSE_MAX_VOXELS`).

use super::TraversalModel;

/// Bytes of the voxel buffer the dense walk reads for a grid of `dims`: one a voxel, in
/// whole vec4<u32>s.
pub(crate) fn voxel_buffer_bytes(dims: glam::UVec3) -> u64 {
    super::per_voxel_bytes(dims, 1)
}

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "dense",
    summary: "the 3D DDA voxel by voxel over the dense grid (the seed's; Amanatides and \
              Woo 1987)",
    label: "dense DDA",
    plan: |scene, _| super::dense_grid_only(scene, "the dense grid"),
    auto: None,
    wgsl: (
        "shaders/traversal_dense.wgsl",
        include_str!("../../shaders/traversal_dense.wgsl"),
    ),
    walks_tree: false,
    descent_levels: None,
    data: None,
    device_bytes: Some(voxel_buffer_bytes),
};
