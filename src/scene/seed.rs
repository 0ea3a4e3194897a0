//! The seed scene (seed report section 3.2, DESIGN section 1) at any grid size.

use glam::{DVec3, IVec3, UVec3};

use super::material::seed_ids::{GLASS, SEMI_SOLID, SOLID, VOID};
use super::{Grid, Light, OrbitCamera, PointLight, Scene, SceneError, seed_palette};

/// Ambient colour of the seed's implementation.
pub const SEED_AMBIENT: DVec3 = DVec3::new(0.05, 0.075, 0.1);

/// Fills a grid of `dims` by the seed's rules. All radii are fractions of the grid's
/// half-extent along each axis, measured at voxel centres with a strict `<`:
/// - the outer layer holds glass panes of radius 87.5 % in a solid frame;
/// - each pane has a void hole of radius 25 %;
/// - the front face (z = max) has no pane: the frame stays, the pane area is void;
/// - the interior is void but for a semi-solid cube of radius 12.5 % at the centre.
pub fn seed_grid(dims: UVec3, voxel_size: f64, origin: DVec3) -> Result<Grid, SceneError> {
    let mut grid = Grid::new(dims, voxel_size, origin)?;
    let half = dims.as_dvec3() * 0.5;
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let v = UVec3::new(x, y, z);
                // Normalised voxel-centre coordinates in (-1, 1).
                let u = ((v.as_dvec3() + 0.5) - half) / half;
                let boundary = [
                    x == 0 || x + 1 == dims.x,
                    y == 0 || y + 1 == dims.y,
                    z == 0 || z + 1 == dims.z,
                ];
                let m = if boundary.iter().any(|&b| b) {
                    // The pane lies on the first boundary axis; its radius is measured in
                    // the other two. Edges and corners are always frame.
                    let axis = boundary.iter().position(|&b| b).unwrap();
                    let r = (0..3)
                        .filter(|&a| a != axis)
                        .map(|a| u[a].abs())
                        .fold(0.0, f64::max);
                    let on_front = z + 1 == dims.z;
                    if r >= 0.875 || boundary.iter().filter(|&&b| b).count() > 1 {
                        SOLID
                    } else if on_front || r < 0.25 {
                        VOID
                    } else {
                        GLASS
                    }
                } else if u.abs().max_element() < 0.125 {
                    SEMI_SOLID
                } else {
                    VOID
                };
                grid.set(IVec3::new(x as i32, y as i32, z as i32), m);
            }
        }
    }
    Ok(grid)
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
