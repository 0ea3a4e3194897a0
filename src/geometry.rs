//! Convex polygons in 3D, shared by the techniques' closed forms and the export.

use glam::DVec3;

/// The convex polygon `corners` clipped to the half-space `side(x) >= 0`, where `side`
/// is affine (a plane's signed distance, scaled): Sutherland and Hodgman, "Reentrant
/// polygon clipping", CACM 1974, against one plane. The order is kept; an empty result
/// means the polygon lies wholly outside.
pub fn clip_convex(corners: &[DVec3], side: impl Fn(DVec3) -> f64) -> Vec<DVec3> {
    let mut poly = Vec::with_capacity(corners.len() + 1);
    for (i, &a) in corners.iter().enumerate() {
        let b = corners[(i + 1) % corners.len()];
        let (da, db) = (side(a), side(b));
        if da >= 0.0 {
            poly.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            poly.push(a + da / (da - db) * (b - a));
        }
    }
    poly
}
