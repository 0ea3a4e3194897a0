//! The triangles of the mesh the scene was voxelized from, traced through the voxels
//! they overlap: the seed's O6 (b), ray tracing against the polygons whose voxels were
//! hit (watertight ray/triangle test: S. Woop, C. Benthin and I. Wald, "Watertight
//! Ray/Triangle Intersection", JCGT 2(1), 2013; `crate::triangles`).
//!
//! Contract: `src/trace_contract.md`, "Triangle surfaces". It needs a scene made from a
//! mesh (`scene.mesh`) of at most `crate::triangles::MAX_TRIANGLES` triangles.

use super::SurfaceModel;

pub const SURFACE: SurfaceModel = SurfaceModel {
    name: "mesh",
    summary: "the triangles of the scene's own mesh, found through the voxels they \
              overlap (the seed's O6 b; Woop, Benthin and Wald 2013)",
    label: "triangles of the scene's mesh",
    plan: |scene, _| match &scene.mesh {
        None => Err("render.surface = \"mesh\" needs a scene made from a mesh (scene.mesh)".into()),
        Some(m) if m.triangles.len() > crate::triangles::MAX_TRIANGLES => Err(format!(
            "render.surface = \"mesh\": the mesh has {} triangles, at most {} are traced",
            m.triangles.len(),
            crate::triangles::MAX_TRIANGLES
        )),
        Some(_) => Ok(()),
    },
    triangles: Some(|scene| match &scene.mesh {
        Some(m) => Ok(std::borrow::Cow::Borrowed(m.as_ref())),
        None => Err("the scene has no mesh".into()),
    }),
    hash_inputs: |scene, h| {
        if let Some(m) = &scene.mesh {
            m.hash_into(h);
        }
    },
};
