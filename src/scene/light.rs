//! Light sources: point lights (the baseline) and area lights (rectangle, disk, sphere).

use glam::DVec3;

#[derive(Clone, Debug, PartialEq)]
pub struct PointLight {
    pub position: DVec3,
    pub color: DVec3,
    pub intensity: f64,
}

/// The shape of an area light, in its own frame (`u`, `v` span the plane of a rectangle
/// or disk; `n` is its normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AreaShape {
    /// Full side lengths along `u` and `v`.
    Rect {
        width: f64,
        height: f64,
    },
    Disk {
        radius: f64,
    },
    Sphere {
        radius: f64,
    },
}

/// How each point of a rectangle or disk light sends its light out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Emission {
    /// The same intensity in every direction, to both sides (no cosine at the emitter):
    /// a light of size 0 is exactly the point light at its centre, the seed's baseline
    /// light, which is why this stays the default (README, "Area lights").
    #[default]
    Isotropic,
    /// Uniform radiance `L = I / A` leaving the side the normal faces, none behind it:
    /// the diffuse area emitter of pbrt-v4 (`DiffuseAreaLight`) and Mitsuba 3 (`area`).
    /// The light's intensity along its normal is `I`, at angle `theta` it is
    /// `I cos(theta)`, and its power `pi I` (an isotropic light's is `4 pi I`).
    Lambertian,
}

impl Emission {
    /// The names `[[lights]] emission` takes, in the order of the variants.
    pub const NAMES: [&'static str; 2] = ["isotropic", "lambertian"];

    pub fn name(self) -> &'static str {
        match self {
            Emission::Isotropic => Self::NAMES[0],
            Emission::Lambertian => Self::NAMES[1],
        }
    }

    pub(crate) fn from_name(name: &str) -> Option<Emission> {
        match name {
            "isotropic" => Some(Emission::Isotropic),
            "lambertian" => Some(Emission::Lambertian),
            _ => None,
        }
    }
}

/// An area light: a point light spread uniformly over a shape, each point emitting as
/// `emission` says, and `intensity` the whole light's, shared equally by its samples.
/// An isotropic light of size 0 is exactly the point light at its centre (the
/// contract's degenerate setting); a Lambertian one is that point with the emitter's
/// cosine.
#[derive(Clone, Debug, PartialEq)]
pub struct AreaLight {
    pub shape: AreaShape,
    /// Rectangles and disks only: a sphere light is isotropic (the parser refuses a
    /// Lambertian sphere).
    pub emission: Emission,
    pub position: DVec3,
    /// Normal of a rectangle or disk (unit); ignored by spheres.
    pub normal: DVec3,
    /// Turn of the rectangle about its normal, radians, from the default frame.
    pub rotation: f64,
    pub color: DVec3,
    pub intensity: f64,
}

/// Every light kind voxlab knows.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    Point(PointLight),
    Area(AreaLight),
}

impl Light {
    /// The light's centre.
    pub fn position(&self) -> DVec3 {
        match self {
            Light::Point(p) => p.position,
            Light::Area(a) => a.position,
        }
    }
    pub fn color(&self) -> DVec3 {
        match self {
            Light::Point(p) => p.color,
            Light::Area(a) => a.color,
        }
    }
    pub fn intensity(&self) -> f64 {
        match self {
            Light::Point(p) => p.intensity,
            Light::Area(a) => a.intensity,
        }
    }
    /// The share of the light's `color * intensity` that its point `x` sends toward `p`:
    /// 1 for point lights and isotropic area lights; for a Lambertian one the emitter's
    /// cosine `max(n . (p - x) / |p - x|, 0)` (0 at `x` itself).
    pub fn emitted_towards(&self, x: DVec3, p: DVec3) -> f64 {
        match self {
            Light::Area(a) if self.is_lambertian() => {
                let w = p - x;
                let len = w.length();
                if len > 0.0 {
                    (a.normal.normalize().dot(w) / len).max(0.0)
                } else {
                    0.0
                }
            }
            _ => 1.0,
        }
    }
    /// `color * intensity` times `emitted_towards(x, p)`: what a point emitter at `x`
    /// standing for the light (or for its share of it) sends toward `p`.
    pub fn radiance_towards(&self, x: DVec3, p: DVec3) -> DVec3 {
        self.color() * self.intensity() * self.emitted_towards(x, p)
    }
    /// A light that sends out nothing: intensity 0 or color 0 (both non-negative, as
    /// parsed), whatever its shape and emission.
    pub fn is_dark(&self) -> bool {
        self.intensity() == 0.0 || self.color() == DVec3::ZERO
    }
    /// A light whose points send out the emitter's cosine (`emitted_towards` is not 1
    /// everywhere): an area light of Lambertian emission, whatever its size.
    pub fn is_lambertian(&self) -> bool {
        matches!(self, Light::Area(a) if a.emission == Emission::Lambertian)
    }
    /// An area light with a non-zero extent (one that needs sampling).
    pub fn is_area(&self) -> bool {
        matches!(self, Light::Area(a) if !a.is_degenerate())
    }
}

impl AreaLight {
    /// The default tangent frame of a normal: `u = normalize(helper x n)`, `v = n x u`,
    /// with helper +y unless the normal is nearly parallel to it (then +x), turned by
    /// `rotation` about `n`.
    pub fn frame(&self) -> (DVec3, DVec3, DVec3) {
        let n = self.normal.normalize();
        let helper = if n.y.abs() < 0.999 {
            DVec3::Y
        } else {
            DVec3::X
        };
        let u0 = helper.cross(n).normalize();
        let v0 = n.cross(u0);
        let (s, c) = self.rotation.sin_cos();
        (c * u0 + s * v0, -s * u0 + c * v0, n)
    }

    /// Size 0: the light is its centre.
    pub(crate) fn is_degenerate(&self) -> bool {
        match self.shape {
            AreaShape::Rect { width, height } => width == 0.0 && height == 0.0,
            AreaShape::Disk { radius } | AreaShape::Sphere { radius } => radius == 0.0,
        }
    }

    /// The point for sample coordinates `(s, t)` in [0, 1)^2, uniform in area:
    /// rectangle `c + (s - 1/2) w u + (t - 1/2) h v`; disk by polar mapping
    /// `r = R sqrt(s)`, `phi = 2 pi t`; sphere surface by `z = 1 - 2 s`, `phi = 2 pi t`
    /// (Archimedes' hat-box theorem) in world axes.
    pub fn sample_point(&self, s: f64, t: f64) -> DVec3 {
        let c = self.position;
        match self.shape {
            AreaShape::Rect { width, height } => {
                let (u, v, _) = self.frame();
                c + (s - 0.5) * width * u + (t - 0.5) * height * v
            }
            AreaShape::Disk { radius } => {
                let (u, v, _) = self.frame();
                let r = radius * s.sqrt();
                let (sp, cp) = (std::f64::consts::TAU * t).sin_cos();
                c + r * (cp * u + sp * v)
            }
            AreaShape::Sphere { radius } => {
                let z = 1.0 - 2.0 * s;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let (sp, cp) = (std::f64::consts::TAU * t).sin_cos();
                c + radius * DVec3::new(r * cp, r * sp, z)
            }
        }
    }
}
