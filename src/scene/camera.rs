//! The orbit camera and its primary rays.

use glam::DVec3;

/// Orbits `target` at `distance`; `yaw` turns from +z towards +x, `pitch` lifts
/// above the horizon (+y up). At yaw = pitch = 0 the camera looks down -z.
#[derive(Clone, Debug, PartialEq)]
pub struct OrbitCamera {
    pub target: DVec3,
    pub distance: f64,
    pub yaw: f64,
    pub pitch: f64,
    /// Vertical field of view, radians.
    pub vfov: f64,
}

/// An orthonormal camera frame: primary ray for pixel `(i, j)` (row `j` from the top)
/// goes through the pixel centre:
/// `dir = normalize(forward + sx * tan(vfov/2) * aspect * right + sy * tan(vfov/2) * up)`
/// with `sx = 2 (i + 0.5) / w - 1`, `sy = 1 - 2 (j + 0.5) / h`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraFrame {
    pub eye: DVec3,
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
    pub tan_half_vfov: f64,
}

impl OrbitCamera {
    pub fn eye(&self) -> DVec3 {
        self.target + self.distance * self.backward()
    }

    /// The unit vector from the target to the eye.
    fn backward(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(sy * cp, sp, cy * cp)
    }

    pub fn frame(&self) -> CameraFrame {
        let eye = self.eye();
        // From the angles, not from `target - eye`: at a distance below the target's
        // ulp (1e-15 from a target at 8) the eye is the target, and their difference
        // normalised was NaN, which the two tracers drew differently.
        let forward = -self.backward();
        // Looking straight up or down: keep yaw's horizontal direction as "right".
        let right = {
            let r = forward.cross(DVec3::Y);
            if r.length_squared() > 1e-24 {
                r.normalize()
            } else {
                DVec3::new(self.yaw.cos(), 0.0, -self.yaw.sin())
            }
        };
        let up = right.cross(forward);
        CameraFrame {
            eye,
            forward,
            right,
            up,
            tan_half_vfov: (0.5 * self.vfov).tan(),
        }
    }
}

impl CameraFrame {
    /// The ray through the centre of pixel (i, j), rows from the top.
    pub fn primary_dir(&self, i: u32, j: u32, width: u32, height: u32) -> DVec3 {
        self.primary_dir_offset(i, j, width, height, (0.0, 0.0))
    }

    /// The ray through pixel (i, j)'s centre moved by `offset` pixels (x right, y down).
    pub(crate) fn primary_dir_offset(
        &self,
        i: u32,
        j: u32,
        width: u32,
        height: u32,
        offset: (f64, f64),
    ) -> DVec3 {
        let aspect = width as f64 / height as f64;
        let sx = 2.0 * (i as f64 + (0.5 + offset.0)) / width as f64 - 1.0;
        let sy = 1.0 - 2.0 * (j as f64 + (0.5 + offset.1)) / height as f64;
        (self.forward
            + (sx * self.tan_half_vfov * aspect) * self.right
            + (sy * self.tan_half_vfov) * self.up)
            .normalize()
    }
}
