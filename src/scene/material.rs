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
    /// How a refracting hit (`kt > 0`) splits its ray between reflection and refraction.
    pub dielectric: Dielectric,
}

/// How a refracting material (`kt > 0`) weights the reflected and the refracted ray at
/// a hit; `[[materials]] dielectric`. Materials with `kt = 0` reflect `kr` either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Dielectric {
    /// The seed's Whitted weights: `kr` and `kt` whatever the angle (under voxlab's
    /// rules, total internal reflection moves `kt` to the reflection).
    #[default]
    Fixed,
    /// A smooth dielectric: reflection `kr F` and refraction `kt (1 - F)`, with `F` the
    /// unpolarised Fresnel reflectance of the interface ([`fresnel_dielectric`]; 1 under
    /// total internal reflection), so `kr` and `kt` scale the two lobes as Mitsuba 3's
    /// `dielectric` `specular_reflectance` and `specular_transmittance` and pbrt-v4's
    /// `DielectricMaterial` (with both 1) do. The radiance scaling by `(n_t/n_i)^2` at a
    /// refraction is left out: it cancels on every path that leaves the medium it
    /// entered, which is every path the Whitted tree lights (docs/mitsuba.md).
    Fresnel,
}

impl Dielectric {
    /// The names `[[materials]] dielectric` takes, in the order of the variants.
    pub const NAMES: [&'static str; 2] = ["fixed", "fresnel"];

    pub fn name(self) -> &'static str {
        match self {
            Dielectric::Fixed => Self::NAMES[0],
            Dielectric::Fresnel => Self::NAMES[1],
        }
    }

    pub(crate) fn from_name(name: &str) -> Option<Dielectric> {
        match name {
            "fixed" => Some(Dielectric::Fixed),
            "fresnel" => Some(Dielectric::Fresnel),
            _ => None,
        }
    }

    /// Its code in the kernel's `Material.dielectric` (`shaders/types.wgsl`).
    pub(crate) fn code(self) -> u32 {
        self as u32
    }
}

/// The unpolarised Fresnel reflectance of a smooth interface between dielectrics, for
/// a ray arriving at `cos_i = cos(theta_i) >= 0` from the side of index `n_i` onto index
/// `n_t`, with `eta = n_i / n_t` (the ratio Snell's law in [`crate::cpu::refract`]
/// takes): `F = (r_s^2 + r_p^2) / 2`, `r_s = (n_i cos_i - n_t cos_t) / (n_i cos_i + n_t
/// cos_t)`, `r_p = (n_t cos_i - n_i cos_t) / (n_t cos_i + n_i cos_t)` (Hecht, Optics,
/// 4th ed., section 4.6.2; pbrt-v4 section 9.5.1 `FrDielectric`), and 1 under total
/// internal reflection (`sin_t > 1`).
pub fn fresnel_dielectric(cos_i: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    fresnel_dielectric_at(cos_i, eta * (1.0 - cos_i * cos_i).sqrt(), eta)
}

/// [`fresnel_dielectric`] given `sin_t = eta sin_i` as well, as the tracers have it:
/// from the ray's part along the surface, not `1 - cos_i^2`, which has no digits left
/// for a near-normal ray's `sin^2` below about 1e-16 (f64), where the critical angle
/// of an `eta` past 1e8 lies ([`crate::cpu::refract`]).
pub fn fresnel_dielectric_at(cos_i: f64, sin_t: f64, eta: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = sin_t * sin_t;
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    // Divided through by n_t: n_i / n_t = eta.
    let r_s = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    let r_p = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    0.5 * (r_s * r_s + r_p * r_p)
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
            dielectric: Dielectric::Fixed,
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
