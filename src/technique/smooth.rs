//! A smooth surface extracted from the grid and traced as triangles: the seed's O6 (a).
//! Naive Surface Nets of each material, relaxed within their cells as Gibson's
//! constrained elastic surface nets do (S. F. F. Gibson, "Constrained Elastic Surface
//! Nets", MERL TR 1998), `crate::surface::DEFAULT_RELAX` passes (`crate::surface`),
//! then traced through the voxels the triangles overlap (`crate::triangles`).
//!
//! Contract: `src/trace_contract.md`, "Triangle surfaces". Extraction is bounded to
//! `crate::surface::MAX_SURFACE_VOXELS` voxels.

use super::SurfaceModel;

pub const SURFACE: SurfaceModel = SurfaceModel {
    name: "smooth",
    summary: "surface nets of each material extracted from the grid and relaxed within \
              their cells, traced as triangles (the seed's O6 a; Gibson 1998)",
    label: "triangles of the grid's smooth surface",
    plan: |scene, _| {
        let voxels = scene.grid.voxel_count() as u64;
        if voxels > crate::surface::MAX_SURFACE_VOXELS {
            return Err(format!(
                "render.surface = \"smooth\": the grid has {voxels} voxels; smooth surfaces \
                 are extracted from at most {} (surface::MAX_SURFACE_VOXELS)",
                crate::surface::MAX_SURFACE_VOXELS
            ));
        }
        Ok(())
    },
    triangles: Some(|scene| {
        crate::surface::extract_solid(&scene.grid, crate::surface::DEFAULT_RELAX)
            .map(std::borrow::Cow::Owned)
            .map_err(|e| e.to_string())
    }),
    hash_inputs: |_, _| {},
};
