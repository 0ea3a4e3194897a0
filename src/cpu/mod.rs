//! The CPU reference tracer: the model of DESIGN section 1, implemented independently
//! of the WGSL kernel, in f64, parallel over rows with rayon. It is the oracle of the
//! tests and the fallback renderer when no GPU adapter exists. It follows
//! `src/trace_contract.md` to the letter.

pub mod dda;

use std::time::Instant;

use glam::DVec3;
use rayon::prelude::*;

pub use dda::{Dda, Hit, Visit, cast};

use crate::render::{Frame, RayStats, RenderOutput, RenderSettings};
use crate::scene::{Light, Scene};

/// What the CPU backend is, for printing next to a GPU adapter's name.
pub fn backend_summary() -> String {
    format!(
        "CPU reference (f64, rayon, {} threads)",
        rayon::current_num_threads()
    )
}

/// Renders the scene; every pixel is traced independently, so the image does not depend
/// on the thread count.
pub fn render(scene: &Scene, settings: &RenderSettings) -> RenderOutput {
    let start = Instant::now();
    let frame_cam = scene.camera.frame();
    let (w, h) = (settings.width, settings.height);
    let rows: Vec<(Vec<[f32; 3]>, RayStats)> = (0..h)
        .into_par_iter()
        .map(|j| {
            let mut stats = RayStats::default();
            let row = (0..w)
                .map(|i| {
                    let dir = frame_cam.primary_dir(i, j, w, h);
                    let c = trace_ray(scene, settings, frame_cam.eye, dir, &mut stats);
                    [c.x as f32, c.y as f32, c.z as f32]
                })
                .collect();
            (row, stats)
        })
        .collect();
    let mut frame = Frame::new(w, h);
    let mut stats = RayStats::default();
    for (j, (row, s)) in rows.into_iter().enumerate() {
        let at = j * w as usize;
        frame.pixels[at..at + w as usize].copy_from_slice(&row);
        stats += s;
    }
    RenderOutput {
        frame,
        stats,
        trace_time: start.elapsed(),
    }
}

/// One entry of the explicit ray stack (the recursion of Whitted's model unrolled).
struct StackRay {
    origin: DVec3,
    dir: DVec3,
    throughput: DVec3,
    reflection_depth: u32,
    refraction_depth: u32,
    medium: u8,
}

/// Radiance seen along a primary ray from `eye` in direction `dir` (unit), ambient included.
pub fn trace_ray(
    scene: &Scene,
    settings: &RenderSettings,
    eye: DVec3,
    dir: DVec3,
    stats: &mut RayStats,
) -> DVec3 {
    let grid = &scene.grid;
    let eps = settings.ray_offset * grid.voxel_size();
    let mut color = scene.ambient;
    let mut stack = Vec::with_capacity(settings.ray_stack_size() as usize);
    stack.push(StackRay {
        origin: eye,
        dir,
        throughput: DVec3::ONE,
        reflection_depth: 0,
        refraction_depth: 0,
        medium: scene.medium_at(eye),
    });
    stats.primary += 1;

    while let Some(ray) = stack.pop() {
        let (hit, steps) = cast(grid, ray.origin, ray.dir, ray.medium);
        stats.voxel_steps += steps;
        let Some(hit) = hit else { continue };

        let p = ray.origin + hit.t * ray.dir;
        let n = hit.normal;
        let shade_id = if hit.material == crate::scene::VOID {
            ray.medium
        } else {
            hit.material
        };
        let m = &scene.materials[shade_id as usize];

        // Emission is seen, not cast: emissive voxels light nothing else.
        color += ray.throughput * m.emission;
        if m.is_lit() {
            let local = direct_light(scene, settings, p, n, ray.dir, shade_id, stats);
            color += ray.throughput * local;
        }

        let mut reflection_weight = m.kr;
        if m.kt > 0.0 {
            let eta = scene.materials[ray.medium as usize].ior
                / scene.materials[hit.material as usize].ior;
            match refract(ray.dir, n, eta) {
                // Total internal reflection: the refracted share goes to the reflection.
                None => reflection_weight += m.kt,
                Some(_) if ray.refraction_depth >= settings.max_refraction_depth => {}
                Some(refracted) => {
                    stats.secondary += 1;
                    stack.push(StackRay {
                        origin: p - eps * n,
                        dir: refracted,
                        throughput: ray.throughput * m.kt,
                        reflection_depth: ray.reflection_depth,
                        refraction_depth: ray.refraction_depth + 1,
                        medium: hit.material,
                    });
                }
            }
        }
        if reflection_weight > 0.0 && ray.reflection_depth < settings.max_reflection_depth {
            stats.secondary += 1;
            stack.push(StackRay {
                origin: p + eps * n,
                dir: ray.dir - 2.0 * ray.dir.dot(n) * n,
                throughput: ray.throughput * reflection_weight,
                reflection_depth: ray.reflection_depth + 1,
                refraction_depth: ray.refraction_depth,
                medium: ray.medium,
            });
        }
    }
    color
}

/// Snell's law in vector form (`sin t1 / sin t2 = n2 / n1`, `eta = n1 / n2`) for a unit
/// direction `d` and a unit normal `n` facing against it; `None` under total internal
/// reflection.
pub fn refract(d: DVec3, n: DVec3, eta: f64) -> Option<DVec3> {
    let c = -n.dot(d);
    let k = 1.0 - eta * eta * (1.0 - c * c);
    (k >= 0.0).then(|| (eta * d + (eta * c - k.sqrt()) * n).normalize())
}

/// Phong with inverse-square falloff, summed over the lights, times the albedo.
fn direct_light(
    scene: &Scene,
    settings: &RenderSettings,
    p: DVec3,
    n: DVec3,
    d: DVec3,
    shade_id: u8,
    stats: &mut RayStats,
) -> DVec3 {
    let m = &scene.materials[shade_id as usize];
    let eps = settings.ray_offset * scene.grid.voxel_size();
    let q = p + eps * n;
    let mut sum = DVec3::ZERO;
    for light in &scene.lights {
        let Light::Point(pl) = light;
        stats.shadow += 1;
        let v = shadow_min_kt(scene, q, pl.position, stats);
        if v == 0.0 {
            continue;
        }
        let to_light = pl.position - p;
        let dl = to_light.length();
        let l = if dl > 0.0 { to_light / dl } else { n };
        let radiance = pl.color * pl.intensity;
        let e = if settings.falloff {
            radiance / (dl * dl).max(settings.falloff_min_distance.powi(2))
        } else {
            radiance
        };
        let diffuse = n.dot(l).max(0.0);
        let r = l - 2.0 * n.dot(l) * n;
        let rd = r.dot(d);
        let spec = if rd > 0.0 { rd.powf(m.shininess) } else { 0.0 };
        sum += v * e * (m.kd * diffuse + m.ks * spec);
    }
    m.albedo * sum
}

/// `min-kt` transmittance of the segment from `q` to `light` (the seed's O1 as its code
/// does it): the smallest kt of the voxels visited, the start voxel included.
pub fn shadow_min_kt(scene: &Scene, q: DVec3, light: DVec3, stats: &mut RayStats) -> f64 {
    let to_light = light - q;
    let len = to_light.length();
    if len == 0.0 {
        return 1.0;
    }
    let mut dda = Dda::new(&scene.grid, q, to_light / len, len);
    let mut t = 1.0f64;
    for v in dda.by_ref() {
        t = t.min(scene.materials[scene.grid.get(v.voxel) as usize].kt);
        if t <= 0.0 {
            break;
        }
    }
    stats.voxel_steps += dda.steps;
    t
}
