//! Light sources.

use glam::DVec3;

#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    pub position: DVec3,
    pub color: DVec3,
    pub intensity: f64,
}

/// Every light kind voxlab knows. Point lights are the baseline; area lights extend this.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    Point(PointLight),
}

impl Light {
    /// The light's centre.
    pub fn position(&self) -> DVec3 {
        match self {
            Light::Point(p) => p.position,
        }
    }
}
