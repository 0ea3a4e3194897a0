//! The voxel grid: dimensions, placement in the world, and one material index per voxel.

use glam::{DVec3, IVec3, UVec3};

use super::SceneError;

/// Material index 0 is void (empty space) everywhere in voxlab.
pub const VOID: u8 = 0;

/// Upper bound on voxels a grid may hold before any device limit is consulted
/// (2^31 bytes): a guard against allocating without bound on malformed input.
pub const MAX_VOXELS: u64 = 1 << 31;

/// Smallest and largest voxel size a grid may have, world units. A voxel of 1e308 made
/// the camera distance overflow and the CPU walk revisit one voxel forever; within this
/// range every distance the tracers compute (up to 1e6 voxels times 1e6) is far from
/// overflow, and squared falloff distances stay finite.
pub const MIN_VOXEL_SIZE: f64 = 1e-6;
pub const MAX_VOXEL_SIZE: f64 = 1e6;

/// A dense voxel grid. Voxel `(x, y, z)` covers the world box
/// `origin + voxel_size * [x, x+1] x [y, y+1] x [z, z+1]`.
/// Storage is x-fastest, then y, then z (the layout of a 3D texture upload).
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    dims: UVec3,
    voxel_size: f64,
    origin: DVec3,
    data: Vec<u8>,
}

impl Grid {
    /// An all-void grid. Any dimensions from 1x1x1 up are accepted (no power-of-two rule).
    pub fn new(dims: UVec3, voxel_size: f64, origin: DVec3) -> Result<Self, SceneError> {
        if dims.min_element() == 0 {
            return Err(SceneError::new(format!(
                "grid dimensions {}x{}x{}: every dimension must be at least 1",
                dims.x, dims.y, dims.z
            )));
        }
        let count = dims.x as u64 * dims.y as u64 * dims.z as u64;
        if count > MAX_VOXELS {
            return Err(SceneError::new(format!(
                "grid dimensions {}x{}x{} hold {count} voxels; at most {MAX_VOXELS} are allowed",
                dims.x, dims.y, dims.z
            )));
        }
        if !(MIN_VOXEL_SIZE..=MAX_VOXEL_SIZE).contains(&voxel_size) {
            return Err(SceneError::new(format!(
                "voxel size {voxel_size}: must be in [{MIN_VOXEL_SIZE:e}, {MAX_VOXEL_SIZE:e}] \
                 (world units; beyond them camera distances and light falloff leave f64's \
                 range)"
            )));
        }
        if !origin.is_finite() {
            return Err(SceneError::new(format!(
                "grid origin {origin}: must be finite"
            )));
        }
        Ok(Self {
            dims,
            voxel_size,
            origin,
            data: vec![VOID; count as usize],
        })
    }

    pub fn dims(&self) -> UVec3 {
        self.dims
    }
    pub fn voxel_size(&self) -> f64 {
        self.voxel_size
    }
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    pub fn voxel_count(&self) -> usize {
        self.data.len()
    }
    /// Material indices, x-fastest.
    pub fn data(&self) -> &[u8] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    pub fn contains(&self, v: IVec3) -> bool {
        v.x >= 0
            && v.y >= 0
            && v.z >= 0
            && (v.x as u32) < self.dims.x
            && (v.y as u32) < self.dims.y
            && (v.z as u32) < self.dims.z
    }

    fn index(&self, v: IVec3) -> usize {
        v.x as usize + self.dims.x as usize * (v.y as usize + self.dims.y as usize * v.z as usize)
    }

    /// Material at voxel `v`; void outside the grid.
    pub fn get(&self, v: IVec3) -> u8 {
        if self.contains(v) {
            self.data[self.index(v)]
        } else {
            VOID
        }
    }

    /// Sets voxel `v`; panics if `v` is outside the grid (a programming error, not input).
    pub fn set(&mut self, v: IVec3, material: u8) {
        assert!(self.contains(v), "voxel {v} outside grid {}", self.dims);
        let i = self.index(v);
        self.data[i] = material;
    }

    /// World-space size of the grid.
    pub fn extent(&self) -> DVec3 {
        self.dims.as_dvec3() * self.voxel_size
    }
    pub fn world_min(&self) -> DVec3 {
        self.origin
    }
    pub fn world_max(&self) -> DVec3 {
        self.origin + self.extent()
    }
    pub fn centre(&self) -> DVec3 {
        self.origin + 0.5 * self.extent()
    }
    /// The grid's width `W` of DESIGN section 1: its largest world extent.
    pub fn width(&self) -> f64 {
        self.extent().max_element()
    }

    /// World point to grid-local coordinates (voxel units, grid corner at 0).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        (p - self.origin) / self.voxel_size
    }
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        self.origin + local * self.voxel_size
    }

    /// The voxel containing world point `p` (may lie outside the grid).
    pub fn voxel_at(&self, p: DVec3) -> IVec3 {
        self.to_local(p).floor().as_ivec3()
    }

    /// Material at world point `p` (void outside the grid).
    pub fn material_at(&self, p: DVec3) -> u8 {
        let l = self.to_local(p).floor();
        if l.x < 0.0 || l.y < 0.0 || l.z < 0.0 {
            return VOID;
        }
        self.get(l.as_ivec3())
    }

    /// Largest material index used (0 for an empty grid).
    pub fn max_material(&self) -> u8 {
        self.data.iter().copied().max().unwrap_or(VOID)
    }

    /// Which material indices occur in the grid.
    pub fn materials_used(&self) -> [bool; 256] {
        let mut used = [false; 256];
        for &m in &self.data {
            used[m as usize] = true;
        }
        used
    }
}
