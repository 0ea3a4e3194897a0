//! The scene model: grid, materials, lights, camera, and the seed scene generator.

mod camera;
mod grid;
mod light;
mod material;
pub mod mesh;
pub mod seed;
pub mod vox;
pub mod voxelize;

pub use camera::{CameraFrame, OrbitCamera};
pub use grid::{
    DENSE_MAX_VOXELS, FACES, Grid, MAX_SPARSE_SIDE, MAX_VOXEL_SIZE, MAX_VOXELS, MIN_VOXEL_SIZE,
    Storage, VOID,
};
pub use light::{AreaLight, AreaShape, Emission, Light, PointLight};
pub use material::{
    Dielectric, MIN_KT_FOR_SIGMA, Material, SEED_SHININESS, fresnel_dielectric,
    fresnel_dielectric_at, seed_ids, seed_palette,
};
pub use mesh::{Resolution, VoxelizeOptions, Voxelized, load_mesh, voxelize_mesh};
pub use seed::{seed_scene, seed_scene_dims};
pub use vox::{LoadError, LoadErrorKind, VoxScene, load_vox, load_vox_as, write_vox};

use glam::DVec3;

/// The most materials a scene defines: a voxel holds its material's index in one byte.
pub const MAX_MATERIALS: usize = 256;

/// A scene error in plain words; the experiment loader adds file, line and key.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct SceneError(pub String);

impl SceneError {
    pub fn new(msg: impl Into<String>) -> Self {
        Self(msg.into())
    }
}

/// Everything that is rendered: geometry, materials, lights, camera and ambient colour.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub grid: Grid,
    /// Index 0 is void; every index used by the grid must have an entry.
    pub materials: Vec<Material>,
    pub lights: Vec<Light>,
    pub camera: OrbitCamera,
    /// Added once to every pixel: the background colour of a miss.
    pub ambient: DVec3,
    /// The triangles the grid was voxelized from, in world coordinates, with the
    /// scene's material indices (`scene.mesh`); what `render.surface = "mesh"` traces.
    pub mesh: Option<std::sync::Arc<crate::surface::SurfaceMesh>>,
}

impl Scene {
    /// Checks the invariants the tracers rely on.
    pub fn validate(&self) -> Result<(), SceneError> {
        let max = self.grid.max_material() as usize;
        if max >= self.materials.len() {
            return Err(SceneError::new(format!(
                "the grid uses material {max} but only {} materials are defined (0..={})",
                self.materials.len(),
                self.materials.len().saturating_sub(1)
            )));
        }
        if self.materials.len() > MAX_MATERIALS {
            return Err(SceneError::new(format!(
                "{} materials defined; at most {MAX_MATERIALS} (u8 indices)",
                self.materials.len()
            )));
        }
        Ok(())
    }

    /// The material a ray starts in at world point `p` (void outside the grid).
    pub fn medium_at(&self, p: DVec3) -> u8 {
        self.grid.material_at(p)
    }
}
