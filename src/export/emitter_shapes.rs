//! Where Mitsuba's emitter shapes may stand in the way of rays voxlab lets through.
//!
//! voxlab's lights are not in the scene's geometry: no ray meets them. Mitsuba's area
//! emitters are shapes (`rectangle`, `disk`, `sphere`) that rays meet. Its `path`
//! integrator with `hide_emitters` lets the camera's rays through them (measured on
//! Mitsuba 3.9.1: a lit plane behind a hidden rectangle renders as without it), but a
//! shadow ray toward another light is stopped by one, so the light behind it casts a
//! shadow voxlab's does not. Mitsuba has no shape that rays pass through: an export
//! where a light's shape may stop another light's shadow rays is approximated
//! (`voxlab.mitsuba.Whitted` passes through emitter shapes).
//!
//! The test is conservative: the shadow rays toward light `k` run from the surfaces to
//! light `k`, so they lie in the convex hull of the surfaces' vertices and light `k`'s
//! outline (the union of the segments between two convex sets is the hull of their
//! union). A shape that misses a polytope bounding that hull (a k-DOP: the extent of the
//! points along a fixed set of directions) meets none of them. Rays reflected or
//! refracted off the scene meet shapes too (Mitsuba adds the emission they see, which
//! voxlab does not); such scenes are approximated under `path` already (it follows
//! them with the diffuse interreflection).

use glam::DVec3;

use crate::scene::{AreaShape, Light};

/// Directions of the bounding polytope: the axes, the diagonals of the cube's faces and
/// of the cube itself, and a Fibonacci spiral over the hemisphere (each direction bounds
/// both its sides).
fn directions() -> Vec<DVec3> {
    const SPIRAL: usize = 48;
    let mut d = vec![DVec3::X, DVec3::Y, DVec3::Z];
    for (a, b) in [
        (DVec3::X, DVec3::Y),
        (DVec3::Y, DVec3::Z),
        (DVec3::Z, DVec3::X),
    ] {
        d.push((a + b).normalize());
        d.push((a - b).normalize());
    }
    for s in [DVec3::new(1.0, 1.0, 1.0), DVec3::new(1.0, 1.0, -1.0)] {
        d.push(s.normalize());
        d.push(DVec3::new(s.x, -s.y, s.z).normalize());
    }
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..SPIRAL {
        let z = 1.0 - (i as f64 + 0.5) / SPIRAL as f64;
        let r = (1.0 - z * z).sqrt();
        let (s, c) = (golden * i as f64).sin_cos();
        d.push(DVec3::new(r * c, r * s, z));
    }
    d
}

/// A convex polytope bounding a set of points: their least and greatest projection on
/// each of `directions()`.
#[derive(Clone, Debug)]
pub(super) struct Bounds {
    dirs: Vec<DVec3>,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl Bounds {
    pub(super) fn of(points: impl IntoIterator<Item = DVec3>) -> Self {
        let dirs = directions();
        let mut b = Bounds {
            lo: vec![f64::INFINITY; dirs.len()],
            hi: vec![f64::NEG_INFINITY; dirs.len()],
            dirs,
        };
        for p in points {
            b.add(p);
        }
        b
    }

    fn add(&mut self, p: DVec3) {
        for (k, d) in self.dirs.iter().enumerate() {
            let t = d.dot(p);
            self.lo[k] = self.lo[k].min(t);
            self.hi[k] = self.hi[k].max(t);
        }
    }

    /// The bounds as half-spaces `n . x <= m`, each widened by `slack`.
    fn halfspaces(&self, slack: f64) -> Vec<(DVec3, f64)> {
        self.dirs
            .iter()
            .zip(self.lo.iter().zip(&self.hi))
            .flat_map(|(&d, (&lo, &hi))| [(d, hi + slack), (-d, -lo + slack)])
            .collect()
    }
}

/// Points whose convex hull holds light `light` (its shape, or its point).
pub(super) fn outline(light: &Light) -> Vec<DVec3> {
    let Light::Area(a) = light else {
        return vec![light.position()];
    };
    let (u, v, _) = a.frame();
    let c = a.position;
    match a.shape {
        AreaShape::Rect { width, height } => {
            let (x, y) = (0.5 * width * u, 0.5 * height * v);
            vec![c - x - y, c + x - y, c + x + y, c - x + y]
        }
        AreaShape::Disk { radius } => {
            // The polygon of 32 sides around the disk.
            const SIDES: usize = 32;
            let r = radius / (std::f64::consts::PI / SIDES as f64).cos();
            (0..SIDES)
                .map(|i| {
                    let (s, co) = (std::f64::consts::TAU * i as f64 / SIDES as f64).sin_cos();
                    c + r * (co * u + s * v)
                })
                .collect()
        }
        AreaShape::Sphere { radius } => {
            let r = DVec3::splat(radius);
            (0..8)
                .map(|i| {
                    let s = DVec3::new(
                        if i & 1 == 0 { -1.0 } else { 1.0 },
                        if i & 2 == 0 { -1.0 } else { 1.0 },
                        if i & 4 == 0 { -1.0 } else { 1.0 },
                    );
                    c + s * r
                })
                .collect()
        }
    }
}

/// Whether light `light`'s shape may meet the polytope of `planes` (`n . x <= m`): a
/// rectangle's or disk's polygon clipped by each half-space in turn
/// (`geometry::clip_convex`) keeps some part; a sphere is within
/// every plane's reach of its centre (which a sphere near an edge of the polytope passes
/// without meeting it: conservative).
fn may_meet(light: &Light, planes: &[(DVec3, f64)]) -> bool {
    let Light::Area(a) = light else {
        return false;
    };
    if let AreaShape::Sphere { radius } = a.shape {
        return planes
            .iter()
            .all(|&(n, m)| n.dot(a.position) - radius * n.length() <= m);
    }
    let mut polygon = outline(light);
    for &(n, m) in planes {
        polygon = crate::geometry::clip_convex(&polygon, |x| m - n.dot(x));
        if polygon.is_empty() {
            return false;
        }
    }
    true
}

/// The other lights whose shadow rays light `j`'s shape may meet (by index; the
/// surfaces' bounds with each such light's outline meet the shape).
pub(super) fn in_the_way(j: usize, lights: &[Light], surfaces: &Bounds, slack: f64) -> Vec<usize> {
    lights
        .iter()
        .enumerate()
        .filter(|&(k, other)| {
            if k == j {
                return false;
            }
            let mut b = surfaces.clone();
            for p in outline(other) {
                b.add(p);
            }
            may_meet(&lights[j], &b.halfspaces(slack))
        })
        .map(|(k, _)| k)
        .collect()
}
