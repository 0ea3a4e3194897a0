//! Pre-filtered voxel pyramids for cone tracing (C. Crassin et al., "Interactive
//! Indirect Illumination Using Voxel Cone Tracing", Computer Graphics Forum 30(7), 2011,
//! section 3), built in f64: the reference the GPU builder (`src/gpu/pyramid.rs`,
//! `shaders/inject.wgsl`, `shaders/mip_build.wgsl`) is tested against, and what the CPU
//! cone tracer (`super::march`) samples.
//!
//! Two pyramids over the same layout:
//! - opacity: level 0 holds each voxel's opacity `alpha = 1 - T1`, with `T1` the
//!   transmittance of a one-voxel slab under the active transmittance model: `kt` for
//!   `min-kt`; `exp(-mean_rgb(sigma) voxel_size)` for `beer-lambert` (which is `kt`
//!   again under the default sigma). Void is 0, `kt = 0` is opaque (1). The cone march
//!   composites these as slabs one texel thick, so with the step correction a level-0
//!   path of length s through one material transmits `T1^s`, Beer-Lambert's law.
//! - radiance: level 0 holds the voxel's diffuse outgoing radiance under direct light,
//!   premultiplied by its opacity, in RGB, and the opacity in A (see [`inject_voxel`]).
//!
//! Filter: level `l + 1` has dims `ceil(dims_l / 2)`; a parent is the plain mean of its
//! 2x2x2 children, children outside level `l`'s dims counting as empty (0), so the sum
//! over a level times its texel volume `8^l` is the same at every level (opacity mass
//! is conserved), odd sizes included. Texel `i` of level `l` covers base voxels
//! `[i 2^l, (i + 1) 2^l)` on each axis.
//!
//! On the GPU the levels are the mip levels of one 3D texture. wgpu sizes mip `l` as
//! `floor(size / 2^l)`, not `ceil`, so the texture's base is padded with empty voxels
//! to a multiple of `2^(levels - 1)` on each axis ([`PyramidLayout::padded`]); padding
//! holds zeros, which is exactly "outside counts as empty". Sampling treats everything
//! outside the texture as empty too (see [`sample_level`]).

use glam::{DVec3, IVec3, UVec3};
use rayon::prelude::*;

use crate::frame::RayStats;
use crate::render::{RenderSettings, Transmittance};
use crate::scene::{Material, Scene, VOID};

/// Most levels a pyramid may have (coarsest texel 2^15 voxels).
pub const MAX_LEVELS: u32 = 16;

/// Automatic level choice stops before the texture's padding makes it larger than this
/// many times the grid (padding only arises for sides that are not multiples of 2^(L-1)).
pub const AUTO_MAX_PADDING: f64 = 2.0;

/// Automatic level choice never goes beyond this many levels (coarsest texel 128 voxels).
pub const AUTO_MAX_LEVELS: u32 = 8;

/// Bytes per texel: R16Float opacity, RGBA16Float radiance.
pub(crate) const OPACITY_TEXEL_BYTES: u64 = 2;
pub(crate) const RADIANCE_TEXEL_BYTES: u64 = 8;

/// Sizes of a pyramid over a grid of `dims`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PyramidLayout {
    /// The grid's dims (level 0).
    pub dims: UVec3,
    pub levels: u32,
    /// The texture's level-0 dims: `dims` rounded up to a multiple of `2^(levels - 1)`.
    pub padded: UVec3,
}

/// Most levels possible for `dims`: the coarsest texel is at most the grid's largest side.
fn full_levels(dims: UVec3) -> u32 {
    32 - dims.max_element().leading_zeros()
}

fn pad(dims: UVec3, levels: u32) -> UVec3 {
    let m = 1u32 << (levels - 1);
    UVec3::new(
        dims.x.div_ceil(m) * m,
        dims.y.div_ceil(m) * m,
        dims.z.div_ceil(m) * m,
    )
}

fn volume(d: UVec3) -> u64 {
    d.x as u64 * d.y as u64 * d.z as u64
}

impl PyramidLayout {
    /// `levels = 0` chooses automatically: the most levels (up to [`AUTO_MAX_LEVELS`])
    /// whose padded texture stays within [`AUTO_MAX_PADDING`] times the grid. A requested
    /// count is capped at what the grid allows (coarsest texel no larger than its largest
    /// side) and at [`MAX_LEVELS`].
    pub fn new(dims: UVec3, levels: u32) -> Self {
        let full = full_levels(dims).min(MAX_LEVELS);
        let levels = if levels == 0 {
            (1..=full.min(AUTO_MAX_LEVELS))
                .rev()
                .find(|&l| volume(pad(dims, l)) as f64 <= AUTO_MAX_PADDING * volume(dims) as f64)
                .unwrap_or(1)
        } else {
            levels.min(full)
        };
        Self {
            dims,
            levels,
            padded: pad(dims, levels),
        }
    }

    /// Dims of level `l`: `ceil(dims / 2^l)`.
    pub fn level_dims(&self, l: u32) -> UVec3 {
        let s = 1u32 << l;
        UVec3::new(
            self.dims.x.div_ceil(s),
            self.dims.y.div_ceil(s),
            self.dims.z.div_ceil(s),
        )
    }

    /// Dims of mip `l` of the (padded) texture: `padded / 2^l`, exact.
    pub fn texture_dims(&self, l: u32) -> UVec3 {
        self.padded >> l
    }

    /// Bytes of a texture of this layout with `texel_bytes` per texel, all mips.
    pub(crate) fn texture_bytes(&self, texel_bytes: u64) -> u64 {
        (0..self.levels)
            .map(|l| volume(self.texture_dims(l)) * texel_bytes)
            .sum()
    }

    /// Bytes per voxel of the grid (not of the padded texture).
    pub fn bytes_per_voxel(&self, texel_bytes: u64) -> f64 {
        self.texture_bytes(texel_bytes) as f64 / volume(self.dims) as f64
    }
}

/// Largest pyramid memory a render may ask for on either backend: the f64 CPU
/// reference's (8 bytes of opacity and 32 of radiance per texel) is the larger. A grid
/// of 1290^3 with cone shadows asked for 17 GB; it is refused before anything is built.
pub(crate) const MAX_PYRAMID_BYTES: u64 = 4 << 30;

/// Bytes the CPU reference's pyramids of `layout` take (radiance with `indirect`).
pub(crate) fn cpu_pyramid_bytes(layout: &PyramidLayout, indirect: bool) -> u64 {
    layout.texture_bytes(8)
        + if indirect {
            layout.texture_bytes(32)
        } else {
            0
        }
}

/// Pyramid memory in words: one line for the plan printout.
pub fn memory_line(layout: &PyramidLayout, radiance: bool) -> String {
    let op = layout.texture_bytes(OPACITY_TEXEL_BYTES);
    let rad = if radiance {
        layout.texture_bytes(RADIANCE_TEXEL_BYTES)
    } else {
        0
    };
    let vox = volume(layout.dims) as f64;
    format!(
        "pyramids: {} levels, texture {}x{}x{} for grid {}x{}x{}; opacity R16Float {:.2} MiB \
         ({:.3} B/voxel){}; total {:.3} B/voxel",
        layout.levels,
        layout.padded.x,
        layout.padded.y,
        layout.padded.z,
        layout.dims.x,
        layout.dims.y,
        layout.dims.z,
        op as f64 / 1048576.0,
        op as f64 / vox,
        if radiance {
            format!(
                ", radiance RGBA16Float {:.2} MiB ({:.3} B/voxel)",
                rad as f64 / 1048576.0,
                rad as f64 / vox
            )
        } else {
            String::new()
        },
        (op + rad) as f64 / vox
    )
}

/// Opacity of one voxel of material `m` (see the module notes). Void is 0.
pub fn material_alpha(m: &Material, is_void: bool, model: Transmittance, voxel_size: f64) -> f64 {
    if is_void {
        return 0.0;
    }
    (1.0 - (model.model().voxel_transmittance)(m, voxel_size)).clamp(0.0, 1.0)
}

/// Per-material opacity table (index = material index).
pub(crate) fn alpha_table(scene: &Scene, model: Transmittance) -> Vec<f64> {
    let vs = scene.grid.voxel_size();
    scene
        .materials
        .iter()
        .enumerate()
        .map(|(i, m)| material_alpha(m, i == VOID as usize, model, vs))
        .collect()
}

use crate::scene::FACES;

/// Diffuse outgoing radiance of voxel `v` under direct light (the injection of
/// Crassin et al. section 3.2, here from the lights themselves rather than a light-view
/// render): `albedo kd (1/|F|) sum_{f in F} sum_j V_j E_j max(0, n_f . l_j)`, over the
/// exposed faces F (neighbour void or outside the grid), each lit at its centre `c_f`
/// with `l_j` towards the light's centre (area lights as their centre), `E_j` with the
/// settings' falloff, and `V_j` the baseline `min-kt` shadow ray from `c_f + eps n_f`.
/// No specular (view-dependent) and no emission (emission is seen, not cast). Zero for
/// void, unlit materials, and voxels without an exposed face.
pub fn inject_voxel(scene: &Scene, settings: &RenderSettings, v: IVec3) -> DVec3 {
    let grid = &scene.grid;
    let id = grid.get(v);
    if id == VOID {
        return DVec3::ZERO;
    }
    let m = &scene.materials[id as usize];
    if m.kd <= 0.0 {
        return DVec3::ZERO;
    }
    let vs = grid.voxel_size();
    let eps = settings.ray_offset * vs;
    let centre = grid.to_world(v.as_dvec3() + 0.5);
    let mut faces = 0u32;
    let mut sum = DVec3::ZERO;
    let mut stats = RayStats::default();
    for f in FACES {
        if grid.get(v + f) != VOID {
            continue;
        }
        faces += 1;
        let n = f.as_dvec3();
        let c = centre + 0.5 * vs * n;
        let q = c + eps * n;
        for light in &scene.lights {
            let lp = light.position();
            let to = lp - c;
            let dl = to.length();
            let l = if dl > 0.0 { to / dl } else { n };
            let nl = n.dot(l);
            if nl <= 0.0 {
                continue;
            }
            let vis = crate::technique::min_kt::shadow_min_kt(scene, q, lp, &mut stats);
            if vis <= 0.0 {
                continue;
            }
            let radiance = light.radiance_towards(lp, c);
            let e = if settings.falloff {
                radiance / (dl * dl).max(settings.falloff_min_distance.powi(2))
            } else {
                radiance
            };
            sum += vis * e * nl;
        }
    }
    if faces == 0 {
        return DVec3::ZERO;
    }
    m.albedo * m.kd * sum / faces as f64
}

/// A pyramid in f64, levels in x-fastest order at their own (unpadded) dims.
#[derive(Clone, Debug)]
pub struct Pyramid {
    pub layout: PyramidLayout,
    pub opacity: Vec<Vec<f64>>,
    /// Premultiplied radiance (RGB) and opacity (A), when built.
    pub radiance: Option<Vec<Vec<[f64; 4]>>>,
}

fn index(d: UVec3, v: UVec3) -> usize {
    v.x as usize + d.x as usize * (v.y as usize + d.y as usize * v.z as usize)
}

/// One box-filter reduction: each parent is the sum of its in-range children over 8.
fn reduce<T: Copy + Send + Sync>(
    src: &[T],
    sd: UVec3,
    dd: UVec3,
    zero: T,
    add: impl Fn(T, T) -> T + Sync,
    scale: impl Fn(T, f64) -> T + Sync,
) -> Vec<T> {
    (0..volume(dd) as usize)
        .into_par_iter()
        .map(|i| {
            let p = UVec3::new(
                i as u32 % dd.x,
                (i as u32 / dd.x) % dd.y,
                i as u32 / (dd.x * dd.y),
            );
            let mut s = zero;
            for c in 0..8u32 {
                let ch = 2 * p + UVec3::new(c & 1, (c >> 1) & 1, c >> 2);
                if ch.x < sd.x && ch.y < sd.y && ch.z < sd.z {
                    s = add(s, src[index(sd, ch)]);
                }
            }
            scale(s, 0.125)
        })
        .collect()
}

impl Pyramid {
    /// Builds the opacity pyramid, and the radiance pyramid when `radiance` is set.
    pub fn build(
        scene: &Scene,
        settings: &RenderSettings,
        layout: PyramidLayout,
        radiance: bool,
    ) -> Self {
        let grid = scene
            .grid
            .to_dense()
            .expect("the plan leaves cone tracing out for grids held sparse");
        let alpha = alpha_table(scene, settings.features.transmittance);
        let d0 = layout.dims;
        let base: Vec<f64> = grid.data().iter().map(|&m| alpha[m as usize]).collect();
        let mut opacity = vec![base];
        for l in 1..layout.levels {
            let next = reduce(
                &opacity[l as usize - 1],
                layout.level_dims(l - 1),
                layout.level_dims(l),
                0.0,
                |a, b| a + b,
                |a, s| a * s,
            );
            opacity.push(next);
        }
        let radiance = radiance.then(|| {
            let base: Vec<[f64; 4]> = (0..volume(d0) as usize)
                .into_par_iter()
                .map(|i| {
                    let v = UVec3::new(
                        i as u32 % d0.x,
                        (i as u32 / d0.x) % d0.y,
                        i as u32 / (d0.x * d0.y),
                    );
                    let a = opacity[0][i];
                    let c = inject_voxel(scene, settings, v.as_ivec3()) * a;
                    [c.x, c.y, c.z, a]
                })
                .collect();
            let mut levels = vec![base];
            for l in 1..layout.levels {
                let next = reduce(
                    &levels[l as usize - 1],
                    layout.level_dims(l - 1),
                    layout.level_dims(l),
                    [0.0; 4],
                    |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]],
                    |a, s| a.map(|x| x * s),
                );
                levels.push(next);
            }
            levels
        });
        Self {
            layout,
            opacity,
            radiance,
        }
    }

    /// Quadrilinear opacity at grid-local point `x` (voxel units) and level `lod`.
    pub(crate) fn opacity_at(&self, x: DVec3, lod: f64) -> f64 {
        quadrilinear(&self.layout, x, lod, |l, c| {
            sample_level(
                &self.opacity[l as usize],
                self.layout.level_dims(l),
                c,
                0.0,
                |a, w| a * w,
                |a, b| a + b,
            )
        })
    }

    /// Quadrilinear premultiplied radiance and opacity; panics without a radiance pyramid.
    pub(crate) fn radiance_at(&self, x: DVec3, lod: f64) -> [f64; 4] {
        let r = self.radiance.as_ref().expect("radiance pyramid built");
        quadrilinear(&self.layout, x, lod, |l, c| {
            sample_level(
                &r[l as usize],
                self.layout.level_dims(l),
                c,
                [0.0; 4],
                |a, w| a.map(|v| v * w),
                |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]],
            )
        })
    }
}

/// Interpolates between the two levels around `lod` (clamped to `[0, levels - 1]`),
/// each sampled trilinearly at `x / 2^l` in its own texel units: what the GPU does with
/// two `textureSampleLevel` calls at integer levels (`shaders/cone.wgsl`).
pub fn quadrilinear<T: Lerp>(
    layout: &PyramidLayout,
    x: DVec3,
    lod: f64,
    sample: impl Fn(u32, DVec3) -> T,
) -> T {
    let top = (layout.levels - 1) as f64;
    let lod = lod.clamp(0.0, top);
    let l0 = lod.floor();
    let f = lod - l0;
    let l0 = l0 as u32;
    let a = sample(l0, x / (1u32 << l0) as f64);
    if f == 0.0 {
        return a;
    }
    let l1 = l0 + 1;
    let b = sample(l1, x / (1u32 << l1) as f64);
    a.lerp_to(b, f)
}

pub trait Lerp {
    fn lerp_to(self, o: Self, f: f64) -> Self;
}
impl Lerp for f64 {
    fn lerp_to(self, o: Self, f: f64) -> Self {
        self + (o - self) * f
    }
}
impl Lerp for [f64; 4] {
    fn lerp_to(self, o: Self, f: f64) -> Self {
        std::array::from_fn(|i| self[i] + (o[i] - self[i]) * f)
    }
}

/// Trilinear sample of one level at texel coordinate `c` (texel `i` spans `[i, i + 1)`,
/// its centre at `i + 1/2`, as in WGSL's `textureSampleLevel` with a linear filter),
/// texels outside `dims` counting as empty (clamp-to-border with a zero border; the
/// GPU gets the same by clamp-to-edge sampling times a per-axis border weight).
pub fn sample_level<T: Copy>(
    data: &[T],
    dims: UVec3,
    c: DVec3,
    zero: T,
    scale: impl Fn(T, f64) -> T,
    add: impl Fn(T, T) -> T,
) -> T {
    let u = c - 0.5;
    let i0 = u.floor();
    let f = u - i0;
    let i0 = i0.as_ivec3();
    let mut s = zero;
    for k in 0..8 {
        let o = IVec3::new(k & 1, (k >> 1) & 1, k >> 2);
        let i = i0 + o;
        if i.x < 0
            || i.y < 0
            || i.z < 0
            || i.x >= dims.x as i32
            || i.y >= dims.y as i32
            || i.z >= dims.z as i32
        {
            continue;
        }
        let w = (if o.x == 1 { f.x } else { 1.0 - f.x })
            * (if o.y == 1 { f.y } else { 1.0 - f.y })
            * (if o.z == 1 { f.z } else { 1.0 - f.z });
        if w == 0.0 {
            continue;
        }
        s = add(s, scale(data[index(dims, i.as_uvec3())], w));
    }
    s
}
