//! The seed scene (seed report section 3.2, `src/trace_contract.md`) at any grid size.

use glam::{DVec3, IVec3, UVec3};

use super::material::seed_ids::{GLASS, SEMI_SOLID, SOLID, VOID};
use super::{
    Grid, Light, MAX_SPARSE_SIDE, OrbitCamera, PointLight, Scene, SceneError, Storage, seed_palette,
};
use crate::sparse::{SparseTree, VoxelSource};

/// Grid side of the seed scene (`[scene] size` when neither `size` nor `dims` is given).
pub const SEED_SIZE: u32 = 16;

/// Ambient colour of the seed's implementation.
pub(crate) const SEED_AMBIENT: DVec3 = DVec3::new(0.05, 0.075, 0.1);

/// Fills a grid of `dims` by the seed's rules. All radii are fractions of the grid's
/// half-extent along each axis, measured at voxel centres with a strict `<`:
/// - the outer layer holds glass panes of radius 87.5 % in a solid frame;
/// - each pane has a void hole of radius 25 %;
/// - the front face (z = max) has no pane: the frame stays, the pane area is void;
/// - the interior is void but for a semi-solid cube of radius 12.5 % at the centre.
///
/// Beyond [`crate::scene::DENSE_MAX_VOXELS`] voxels the grid is built as its sparse
/// tree straight from these rules ([`SeedSource`]), never densely.
pub fn seed_grid(dims: UVec3, voxel_size: f64, origin: DVec3) -> Result<Grid, SceneError> {
    seed_grid_as(dims, voxel_size, origin, Storage::Auto)
}

/// [`seed_grid`] held as `storage` says.
pub fn seed_grid_as(
    dims: UVec3,
    voxel_size: f64,
    origin: DVec3,
    storage: Storage,
) -> Result<Grid, SceneError> {
    if dims.min_element() == 0 {
        // Grid::new words the error.
        return Grid::new(dims, voxel_size, origin);
    }
    let source = SeedSource::new(dims);
    if storage.is_sparse_for(dims.as_u64vec3().element_product()) {
        if dims.max_element() > MAX_SPARSE_SIDE {
            return Err(SceneError::new(format!(
                "grid dimensions {}x{}x{}: a sparse grid's sides are at most {MAX_SPARSE_SIDE}",
                dims.x, dims.y, dims.z
            )));
        }
        let tree = SparseTree::build(&source, crate::sparse::GPU_LOG_BRANCH);
        return Grid::from_tree(tree, voxel_size, origin);
    }
    let mut grid = Grid::new(dims, voxel_size, origin)?;
    let (nx, ny) = (dims.x as usize, dims.y as usize);
    for (i, m) in grid.data_mut().iter_mut().enumerate() {
        let (x, y, z) = (i % nx, i / nx % ny, i / (nx * ny));
        *m = source.material(IVec3::new(x as i32, y as i32, z as i32));
    }
    Ok(grid)
}

/// The seed scene's voxels by its rules ([`seed_grid`]), a source the sparse tree is
/// built from without a dense grid: the interior away from the outer layer is void or
/// the semi-solid cube, so the builder reads voxels only near the faces.
pub struct SeedSource {
    dims: UVec3,
    /// Per axis, the first and one-past-last voxel of the semi-solid cube's slab (the
    /// voxels whose centres are within 12.5 % of the half-extent of the centre).
    cube: [(i32, i32); 3],
}

impl SeedSource {
    pub fn new(dims: UVec3) -> Self {
        let cube = [0, 1, 2].map(|a| {
            let n = dims[a];
            let inside = |v: u32| Self::normalised(v, n).abs() < 0.125;
            let lo = (0..n).find(|&v| inside(v)).unwrap_or(n);
            let hi = (lo..n).find(|&v| !inside(v)).unwrap_or(n);
            (lo as i32, hi as i32)
        });
        Self { dims, cube }
    }

    /// The voxel centre's coordinate in (-1, 1) along an axis of `n` voxels.
    fn normalised(v: u32, n: u32) -> f64 {
        let half = f64::from(n) * 0.5;
        ((f64::from(v) + 0.5) - half) / half
    }
}

impl VoxelSource for SeedSource {
    fn dims(&self) -> UVec3 {
        self.dims
    }

    fn material(&self, v: IVec3) -> u8 {
        let dims = self.dims;
        let v = v.as_uvec3();
        let (x, y, z) = (v.x, v.y, v.z);
        let boundary = [
            x == 0 || x + 1 == dims.x,
            y == 0 || y + 1 == dims.y,
            z == 0 || z + 1 == dims.z,
        ];
        if boundary.iter().any(|&b| b) {
            // The pane lies on the first boundary axis; its radius is measured in the
            // other two. Edges and corners are always frame.
            let axis = boundary.iter().position(|&b| b).unwrap();
            let r = (0..3)
                .filter(|&a| a != axis)
                .map(|a| Self::normalised(v[a], dims[a]).abs())
                .fold(0.0, f64::max);
            let on_front = z + 1 == dims.z;
            if r >= 0.875 || boundary.iter().filter(|&&b| b).count() > 1 {
                SOLID
            } else if on_front || r < 0.25 {
                VOID
            } else {
                GLASS
            }
        } else if (0..3).all(|a| Self::normalised(v[a], dims[a]).abs() < 0.125) {
            SEMI_SOLID
        } else {
            VOID
        }
    }

    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        let d = self.dims.as_ivec3();
        let hi = (lo + IVec3::splat(size)).min(d);
        // Away from the outer layer the rules are the centre cube's alone.
        if lo.cmplt(IVec3::ONE).any() || hi.cmpgt(d - 1).any() {
            return None;
        }
        let inside = (0..3).all(|a| self.cube[a].0 <= lo[a] && hi[a] <= self.cube[a].1);
        let outside = (0..3).any(|a| hi[a] <= self.cube[a].0 || self.cube[a].1 <= lo[a]);
        match (inside, outside) {
            (true, _) => Some(SEMI_SOLID),
            (_, true) => Some(VOID),
            _ => None,
        }
    }
}

/// The seed's three point lights and orbit camera for a grid of width `W` centred at `c`.
pub fn seed_lights(c: DVec3, w: f64) -> Vec<Light> {
    let l = |offset: DVec3, color: DVec3, intensity: f64| {
        Light::Point(PointLight {
            position: c + offset,
            color,
            intensity,
        })
    };
    vec![
        l(
            w * DVec3::new(0.9, 0.8, 1.0),
            DVec3::new(1.0, 0.8, 0.7),
            1.5 * w * w,
        ),
        l(
            w * DVec3::new(-0.7, 0.6, 1.0),
            DVec3::new(0.7, 0.8, 1.0),
            w * w,
        ),
        l(
            (0.5 * w - 1.5) * DVec3::new(1.0, -0.4, 1.0),
            DVec3::new(0.75, 1.0, 0.75),
            0.5 * w * w,
        ),
    ]
}

/// The seed's camera for a grid of centre `c` and width `w`: it orbits `c` at 2.5 W and
/// then moves the eye a further 3 units back along the view axis (`VIEW_OFFSET 3.0`
/// in the seed's `camera.cpp`, applied in camera space after the orbit), so the eye
/// sits at 2.5 W + 3 from `c` (units as the seed's lights' `1.5`: world units, one voxel
/// width at the seed's size).
/// The seed's `VIEW_OFFSET`: how far the eye moves back from the orbit, world units.
pub const SEED_VIEW_OFFSET: f64 = 3.0;

pub fn seed_camera(c: DVec3, w: f64) -> OrbitCamera {
    OrbitCamera {
        target: c,
        distance: 2.5 * w + SEED_VIEW_OFFSET,
        yaw: 0.2 * std::f64::consts::PI,
        pitch: 0.125 * std::f64::consts::PI,
        vfov: 2.0 * (1.0f64 / 3.0).atan(),
    }
}

/// The seed's whole scene on an `n`^3 grid of unit voxels at the world origin.
pub fn seed_scene(n: u32) -> Result<Scene, SceneError> {
    seed_scene_dims(UVec3::splat(n))
}

/// The seed's scene on a grid of any dimensions (unit voxels at the world origin).
pub fn seed_scene_dims(dims: UVec3) -> Result<Scene, SceneError> {
    let grid = seed_grid(dims, 1.0, DVec3::ZERO)?;
    let c = grid.centre();
    let w = grid.width();
    Ok(Scene {
        materials: seed_palette(),
        lights: seed_lights(c, w),
        camera: seed_camera(c, w),
        ambient: SEED_AMBIENT,
        grid,
        mesh: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn count(g: &Grid, m: u8) -> usize {
        g.data().iter().filter(|&&v| v == m).count()
    }

    #[test]
    fn seed16_matches_the_report_rules() {
        let s = seed_scene(16).unwrap();
        let g = &s.grid;
        // Semi-solid cube of radius 12.5 % of 8 = 1 voxel: 2x2x2.
        assert_eq!(count(g, SEMI_SOLID), 8);
        // Five panes of 14x14 minus a 4x4 hole each.
        assert_eq!(count(g, GLASS), 5 * (14 * 14 - 16));
        // Frame: the 12 edges of a 16^3 cube hold 12*14 + 8 voxels; the front face keeps
        // its frame only.
        assert_eq!(count(g, SOLID), 12 * 14 + 8);
        // The front face is open, the back face has glass.
        assert_eq!(g.get(IVec3::new(4, 4, 15)), VOID);
        assert_eq!(g.get(IVec3::new(4, 4, 0)), GLASS);
        assert_eq!(g.get(IVec3::new(8, 8, 0)), VOID);
        assert_eq!(g.get(IVec3::new(7, 8, 8)), SEMI_SOLID);
    }

    #[test]
    fn any_size_down_to_one_voxel() {
        for dims in [
            UVec3::new(1, 1, 1),
            UVec3::new(2, 3, 5),
            UVec3::new(33, 33, 33),
            UVec3::new(17, 9, 24),
        ] {
            let s = seed_scene_dims(dims).unwrap();
            assert_eq!(s.grid.voxel_count(), (dims.x * dims.y * dims.z) as usize);
        }
    }
}
