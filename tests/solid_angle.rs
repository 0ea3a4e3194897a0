//! Solid-angle sampling of rectangle lights (src/technique/solid_angle.rs): the
//! parametrization is uniform in solid angle and stays on the rectangle, the model has
//! the area model's expectation with less noise on a near Lambertian light, and the GPU
//! draws the CPU's samples.
//!
//! Runs on whatever adapter wgpu finds (lavapipe in CI); a missing adapter fails.

mod common;

use common::{assert_agree, rmse, tracer};
use glam::DVec3;
use glam::{IVec3, UVec3};
use rand::{RngExt, SeedableRng};
use voxlab::RenderSettings;
use voxlab::sampling::light_sample;
use voxlab::scene::{AreaLight, AreaShape, Emission, Grid, Light, Scene, seed_palette, seed_scene};
use voxlab::technique::solid_angle::SphericalRect;

/// `int g dA cos_e / r^2` over the rectangle by the midpoint rule.
fn quadrature(o: DVec3, corner: DVec3, ex: DVec3, ey: DVec3, g: &dyn Fn(DVec3) -> f64) -> f64 {
    let k = 400;
    let ne = ex.cross(ey).normalize();
    let da = ex.cross(ey).length() / (k * k) as f64;
    let mut sum = 0.0;
    for i in 0..k {
        for j in 0..k {
            let x = corner + (i as f64 + 0.5) / k as f64 * ex + (j as f64 + 0.5) / k as f64 * ey;
            let to = x - o;
            let r = to.length();
            sum += g(x) * (ne.dot(to) / r).abs() / (r * r) * da;
        }
    }
    sum
}

/// For random rectangles and points: every sample lies on the rectangle, and `S` times
/// the samples' mean of a smooth function equals its solid-angle integral (by
/// quadrature in area with the Jacobian `cos_e / r^2`) to 0.5 %: the density is `1/S`.
#[test]
fn samples_are_uniform_in_solid_angle_on_the_rectangle() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let mut checked = 0;
    for case in 0..120 {
        let mut v3 = || {
            DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
        };
        let ne = v3().normalize();
        let o = v3() * 2.0;
        let helper = if ne.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let u = helper.cross(ne).normalize();
        let v = ne.cross(u);
        let centre = v3() * 3.0;
        let (w, h) = (0.3 + v3().x.abs() * 3.0, 0.3 + v3().y.abs() * 3.0);
        let (ex, ey) = (u * w, v * h);
        let corner = centre - 0.5 * ex - 0.5 * ey;
        if ne.dot(o - centre).abs() < 0.2 {
            continue; // the quadrature needs the plane kept away
        }
        let Some(r) = SphericalRect::new(o, corner, ex, ey) else {
            panic!("case {case}: no spherical rectangle")
        };
        let g = |x: DVec3| {
            let d = (x - o).normalize();
            1.0 + 0.5 * d.x + 0.3 * d.y * d.z
        };
        let n = 4096;
        let mut mean = 0.0;
        for k in 0..n {
            let (s, t) = light_sample(3, case, 0, 0, k, n);
            let x = r.sample(s, t);
            let rel = x - corner;
            let (a, b) = (rel.dot(ex) / (w * w), rel.dot(ey) / (h * h));
            assert!(
                (-1e-9..=1.0 + 1e-9).contains(&a) && (-1e-9..=1.0 + 1e-9).contains(&b),
                "case {case}: sample {k} off the rectangle at ({a}, {b})"
            );
            assert!(rel.dot(ne).abs() < 1e-9 * (1.0 + rel.length()));
            mean += g(x) / n as f64;
        }
        let estimate = r.s * mean;
        let exact = quadrature(o, corner, ex, ey, &g);
        assert!(
            (estimate - exact).abs() <= 5e-3 * exact.abs(),
            "case {case}: S mean g {estimate}, quadrature {exact}"
        );
        checked += 1;
    }
    assert!(checked > 80, "{checked}");
}

/// The seed scene's lights as rectangles facing the grid's centre (`emission`, size).
fn rect_lights(emission: Emission, size: f64) -> Scene {
    let mut scene = seed_scene(16).unwrap();
    let c = scene.grid.centre();
    for l in &mut scene.lights {
        let Light::Point(p) = l.clone() else { continue };
        *l = Light::Area(AreaLight {
            emission,
            shape: AreaShape::Rect {
                width: size,
                height: 0.7 * size,
            },
            position: p.position,
            normal: (c - p.position).normalize(),
            rotation: 0.3,
            color: p.color,
            intensity: p.intensity,
        });
    }
    scene
}

/// A large Lambertian rect close over a diffuse floor with a block on it: where `1/r^2`
/// varies most across the light, the case solid-angle sampling is for.
fn near_light() -> Scene {
    let mut palette = seed_palette();
    let m = &mut palette[1];
    (m.kd, m.ks, m.kr, m.kt) = (1.0, 0.0, 0.0, 0.0);
    let mut grid = Grid::new(UVec3::new(20, 8, 20), 1.0, DVec3::ZERO).unwrap();
    for z in 0..20 {
        for x in 0..20 {
            grid.set(IVec3::new(x, 0, z), 1);
        }
    }
    for z in 8..12 {
        for y in 1..3 {
            for x in 8..12 {
                grid.set(IVec3::new(x, y, z), 1);
            }
        }
    }
    let mut scene = seed_scene(16).unwrap();
    scene = Scene {
        grid,
        materials: palette,
        ambient: DVec3::ZERO,
        lights: vec![Light::Area(AreaLight {
            emission: Emission::Lambertian,
            shape: AreaShape::Rect {
                width: 10.0,
                height: 8.0,
            },
            position: DVec3::new(10.0, 5.0, 10.0),
            normal: -DVec3::Y,
            rotation: 0.2,
            color: DVec3::ONE,
            intensity: 60.0,
        })],
        ..scene
    };
    scene.camera.target = DVec3::new(10.0, 1.0, 10.0);
    scene.camera.distance = 30.0;
    scene.camera.pitch = 0.9;
    scene
}

fn settings(model: &str, samples: u32, spp: u32, seed: u32) -> RenderSettings {
    let mut s = RenderSettings {
        width: 32,
        height: 32,
        light_samples: samples,
        spp,
        seed,
        ..Default::default()
    };
    s.features.set_shadow_model(model);
    s
}

/// The same expectation as the area model: both converge to one image (RMSE of their
/// converged estimates within the two noises); and on large Lambertian lights, at equal
/// samples, solid-angle sampling is closer to that image than area sampling (printed).
#[test]
fn converges_to_the_area_model_with_less_noise_on_lambertian_lights() {
    let scene = near_light();
    let cpu = |model: &str, samples, spp, seed| {
        voxlab::cpu::render(&scene, &settings(model, samples, spp, seed)).frame
    };
    let reference = cpu("area", 16, 64, 101);
    let reference2 = cpu("area", 16, 64, 202);
    let noise = rmse(&reference, &reference2) / std::f64::consts::SQRT_2;
    let converged = cpu("solid-angle", 16, 64, 303);
    let d = rmse(&converged, &reference);
    println!("solid-angle vs area, converged: {d:.3e}; reference noise {noise:.3e}");
    assert!(d < 2.5 * noise, "{d} against noise {noise}");
    let (mut area, mut sa) = (0.0, 0.0);
    for seed in 0..4 {
        area += rmse(&cpu("area", 2, 2, seed), &reference) / 4.0;
        sa += rmse(&cpu("solid-angle", 2, 2, seed), &reference) / 4.0;
    }
    println!("RMSE at 2 samples x 2 frames: area {area:.3e}, solid-angle {sa:.3e}");
    assert!(sa < area, "solid-angle {sa} not below area {area}");
}

/// The GPU draws the CPU's samples: rects of several sizes, both emissions, 1x1 and
/// 4x2 samples, agree; small rects (area sampling) and point lights too.
#[test]
fn gpu_agrees_with_the_cpu() {
    let mut gpu = tracer();
    for emission in [Emission::Lambertian, Emission::Isotropic] {
        for size in [0.0, 0.2, 2.0, 8.0] {
            let scene = rect_lights(emission, size);
            for (samples, spp) in [(1, 1), (4, 2)] {
                let s = settings("solid-angle", samples, spp, 9);
                let name = format!("{emission:?} {size} {samples}x{spp}");
                let g = gpu.render(&scene, &s).unwrap();
                let c = voxlab::cpu::render(&scene, &s);
                assert_agree(&name, &g.frame, &c.frame);
            }
        }
    }
}
