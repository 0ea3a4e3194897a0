//! Materials: the seed's Table 1 is the built-in palette.

use glam::DVec3;

/// Smallest kt used to derive the default absorption, so an opaque material
/// (kt = 0) gets a large but finite sigma (`src/trace_contract.md`).
pub const MIN_KT_FOR_SIGMA: f64 = 1e-4;

/// Shininess of the seed's implementation (`src/trace_contract.md`, baseline constants).
pub const SEED_SHININESS: f64 = 150.0;

#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub albedo: DVec3,
    /// Diffusivity.
    pub kd: f64,
    /// Specularity.
    pub ks: f64,
    pub shininess: f64,
    /// Reflectivity: weight of the reflection ray.
    pub kr: f64,
    /// Refractivity: weight of the refraction ray and the `min-kt` shadow transmittance.
    pub kt: f64,
    /// Index of refraction.
    pub ior: f64,
    /// Absorption per world unit (RGB) for distance-weighted transmittance; `None`
    /// takes the default that makes one voxel transmit `kt`.
    pub sigma: Option<DVec3>,
    /// Emitted radiance (RGB), added to the local term of a hit: C += emission.
    /// Zero for every non-emissive material (MagicaVoxel `_emit` sets it).
    pub emission: DVec3,
}

impl Material {
    /// Absorption coefficient used by `beer-lambert`: the explicit sigma, or
    /// `-ln(max(kt, 1e-4)) / voxel_size` so a slab one voxel thick transmits `kt`.
    pub fn absorption(&self, voxel_size: f64) -> DVec3 {
        self.sigma
            .unwrap_or_else(|| DVec3::splat(-self.kt.max(MIN_KT_FOR_SIGMA).ln() / voxel_size))
    }

    /// Whether a hit on this material is lit by the lights (diffuse or specular term).
    pub(crate) fn is_lit(&self) -> bool {
        self.kd > 0.0 || self.ks > 0.0
    }

    fn seed(name: &str, albedo: DVec3, kd: f64, ks: f64, kr: f64, kt: f64, ior: f64) -> Self {
        Self {
            name: name.to_string(),
            albedo,
            kd,
            ks,
            shininess: SEED_SHININESS,
            kr,
            kt,
            ior,
            sigma: None,
            emission: DVec3::ZERO,
        }
    }
}

/// Indices of the seed palette.
pub mod seed_ids {
    pub const VOID: u8 = 0;
    pub const GLASS: u8 = 1;
    pub const SEMI_SOLID: u8 = 2;
    pub const SOLID: u8 = 3;
}

/// The seed's Table 1: void, glass, semi-solid, solid.
pub fn seed_palette() -> Vec<Material> {
    vec![
        Material::seed("void", DVec3::ZERO, 0.0, 0.0, 0.0, 1.0, 1.0),
        Material::seed("glass", DVec3::ONE, 0.2, 0.7, 0.3, 0.8, 1.5),
        Material::seed("semi-solid", DVec3::ONE, 0.5, 0.7, 0.3, 0.2, 1.5),
        Material::seed("solid", DVec3::ONE, 0.6, 0.5, 0.2, 0.0, 1.0),
    ]
}
