//! The voxels' own faces, the seed's surface and the default: a ray hits the first
//! voxel whose material differs from its medium, on the face it enters through
//! (`src/trace_contract.md`, "cast").

use super::SurfaceModel;

pub const SURFACE: SurfaceModel = SurfaceModel {
    name: "voxels",
    summary: "the faces of the first voxel whose material differs from the ray's medium \
              (the seed's)",
    label: "voxels",
    plan: |_, _| Ok(()),
    triangles: None,
    hash_inputs: |_, _| {},
};
