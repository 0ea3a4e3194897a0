//! Lambertian area emitters (`[[lights]] emission = "lambertian"`, src/scene/light.rs):
//! the ratio estimator's closed form against quadrature, both tracers against the exact
//! irradiance of a disk over a plane, GPU = CPU over light shapes, sizes and every
//! shadow model, and the file's key refused where it means nothing.
//!
//! Runs on whatever adapter wgpu finds (lavapipe in CI); a missing adapter fails.

mod common;

use common::{assert_agree, tracer};
use glam::{DVec3, IVec3, UVec3};
use rand::{RngExt, SeedableRng};
use voxlab::RenderSettings;
use voxlab::experiment::Experiment;
use voxlab::experiment::write::to_toml;
use voxlab::frame::Frame;
use voxlab::scene::{AreaLight, AreaShape, Emission, Grid, Light, Scene, seed_palette, seed_scene};
use voxlab::technique::ratio::projected_solid_angle;

/// `int cos_e max(n.l, 0) / r^2 dA` over the rectangle by the midpoint rule, the
/// emitter's cosine taken from its front (`ne`).
fn quadrature(p: DVec3, n: DVec3, c: DVec3, u: DVec3, v: DVec3, k: usize) -> f64 {
    let ne = u.cross(v).normalize();
    let da = u.cross(v).length() / (k * k) as f64;
    let mut sum = 0.0;
    for i in 0..k {
        for j in 0..k {
            let s = (i as f64 + 0.5) / k as f64 - 0.5;
            let t = (j as f64 + 0.5) / k as f64 - 0.5;
            let x = c + s * u + t * v;
            let to = x - p;
            let r = to.length();
            let cos_s = (n.dot(to) / r).max(0.0);
            let cos_e = (-ne.dot(to) / r).max(0.0);
            sum += cos_e * cos_s / (r * r) * da;
        }
    }
    sum
}

/// Lambert's polygon formula equals quadrature for random rectangles, points and
/// normals, in front of the light (behind it the ratio model takes 0 without the
/// formula), including rectangles cut by the tangent plane.
#[test]
fn projected_solid_angle_is_the_integral() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut unit = || {
        DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize()
    };
    let mut rng2 = rand::rngs::StdRng::seed_from_u64(12);
    let (mut checked, mut cut) = (0, 0);
    for case in 0..600 {
        let ne = unit();
        let n = unit();
        let c = 3.0 * unit();
        let p = unit() * rng2.random_range(0.0..1.0);
        if (p - c).dot(ne) < 0.3 {
            continue; // behind, or too close for the quadrature
        }
        let helper = if ne.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let u0 = helper.cross(ne).normalize();
        let v0 = ne.cross(u0);
        let (u, v) = (
            u0 * rng2.random_range(0.1..3.0),
            v0 * rng2.random_range(0.1..3.0),
        );
        let corners = [
            c - 0.5 * u - 0.5 * v,
            c + 0.5 * u - 0.5 * v,
            c + 0.5 * u + 0.5 * v,
            c - 0.5 * u + 0.5 * v,
        ];
        let signs: Vec<bool> = corners.iter().map(|&x| n.dot(x - p) >= 0.0).collect();
        if signs.iter().any(|&s| s) && signs.iter().any(|&s| !s) {
            cut += 1;
        }
        let exact = projected_solid_angle(p, n, &corners);
        // Either winding gives the same answer.
        let mut reversed = corners;
        reversed.reverse();
        assert!((projected_solid_angle(p, n, &reversed) - exact).abs() <= 1e-12 * (1.0 + exact));
        let numeric = quadrature(p, n, c, u, v, 500);
        assert!(
            (exact - numeric).abs() <= 1e-3 * numeric + 1e-6,
            "case {case}: Lambert {exact}, quadrature {numeric}"
        );
        checked += 1;
    }
    assert!(checked > 200 && cut > 40, "{checked} cases, {cut} cut");
}

const FLOOR: u32 = 24;
const HEIGHT: f64 = 5.0;
const RADIUS: f64 = 3.0;
const INTENSITY: f64 = 30.0;

/// A white diffuse floor (kd 1, albedo 1, no highlight, no ambient), one voxel thick,
/// under a downward Lambertian disk light; the camera looks straight down.
fn disk_over_floor() -> Scene {
    let mut palette = seed_palette();
    let m = &mut palette[1];
    (m.albedo, m.kd, m.ks, m.kr, m.kt) = (DVec3::ONE, 1.0, 0.0, 0.0, 0.0);
    let mut grid = Grid::new(UVec3::new(FLOOR, 2, FLOOR), 1.0, DVec3::ZERO).unwrap();
    for z in 0..FLOOR as i32 {
        for x in 0..FLOOR as i32 {
            grid.set(IVec3::new(x, 0, z), 1);
        }
    }
    let mut scene = seed_scene(16).unwrap();
    let mid = FLOOR as f64 / 2.0;
    scene = Scene {
        grid,
        materials: palette,
        ambient: DVec3::ZERO,
        lights: vec![Light::Area(AreaLight {
            emission: Emission::Lambertian,
            shape: AreaShape::Disk { radius: RADIUS },
            position: DVec3::new(mid, 1.0 + HEIGHT, mid),
            normal: -DVec3::Y,
            rotation: 0.0,
            color: DVec3::ONE,
            intensity: INTENSITY,
        })],
        ..scene
    };
    scene.camera.target = DVec3::new(mid, 1.0, mid);
    scene.camera.pitch = std::f64::consts::FRAC_PI_2 - 1e-3;
    scene.camera.yaw = 0.0;
    scene.camera.distance = 30.0;
    scene
}

/// Irradiance at lateral offset `rho` on a plane at distance `h` below a parallel
/// Lambertian disk of radius `r` and radiance `L = I / (pi r^2)`: the exact
/// `E = (pi L / 2) (1 - (h^2 + rho^2 - r^2) / sqrt((h^2 + rho^2 + r^2)^2 - 4 rho^2 r^2))`
/// (the view factor of a coaxial disk to a parallel differential area, e.g. Howell's
/// catalogue of configuration factors, B-13).
fn disk_irradiance(rho: f64) -> f64 {
    let (h2, r2, rho2) = (HEIGHT * HEIGHT, RADIUS * RADIUS, rho * rho);
    let l = INTENSITY / (std::f64::consts::PI * r2);
    let s = ((h2 + rho2 + r2).powi(2) - 4.0 * rho2 * r2).sqrt();
    0.5 * std::f64::consts::PI * l * (1.0 - (h2 + rho2 - r2) / s)
}

/// The largest relative error of `frame` against the exact irradiance over pixels whose
/// primary ray hits the floor's top at least a voxel from its edge.
fn worst_against_exact(scene: &Scene, frame: &Frame, name: &str) -> f64 {
    let (w, h) = (frame.width, frame.height);
    let frame_of_camera = scene.camera.frame();
    let eye = frame_of_camera.eye;
    let mid = FLOOR as f64 / 2.0;
    let (mut worst, mut counted) = (0.0f64, 0);
    for j in 0..h {
        for i in 0..w {
            let d = frame_of_camera.primary_dir(i, j, w, h);
            let t = (1.0 - eye.y) / d.y;
            let x = eye + t * d;
            if (x.x - mid).abs() > mid - 1.0 || (x.z - mid).abs() > mid - 1.0 {
                continue;
            }
            let rho = ((x.x - mid).powi(2) + (x.z - mid).powi(2)).sqrt();
            let exact = disk_irradiance(rho);
            let got = frame.pixels[(j * w + i) as usize];
            for c in got {
                worst = worst.max((c as f64 - exact).abs() / exact);
            }
            counted += 1;
        }
    }
    assert!(
        counted > (w * h / 4) as usize,
        "{name}: {counted} floor pixels"
    );
    eprintln!("{name}: worst relative error {worst:.2e} over {counted} pixels");
    worst
}

/// Both tracers render the disk's exact irradiance on the floor (the area model,
/// 1024 stratified samples, one frame), to 1 %; and dropping the emitter's cosine
/// (isotropic emission of the same intensity) is far off.
#[test]
fn disk_over_a_plane_is_the_exact_irradiance() {
    let scene = disk_over_floor();
    let mut settings = RenderSettings {
        width: 20,
        height: 20,
        light_samples: 1024,
        spp: 1,
        ..Default::default()
    };
    settings.features.set_shadow_model("area");
    settings.falloff_min_distance = 1e-3;
    let cpu = voxlab::cpu::render(&scene, &settings).frame;
    assert!(worst_against_exact(&scene, &cpu, "cpu") < 0.01);
    let gpu = tracer().render(&scene, &settings).unwrap().frame;
    assert!(worst_against_exact(&scene, &gpu, "gpu") < 0.01);

    let mut isotropic = scene.clone();
    if let Light::Area(a) = &mut isotropic.lights[0] {
        a.emission = Emission::Isotropic;
    }
    let wrong = voxlab::cpu::render(&isotropic, &settings).frame;
    assert!(worst_against_exact(&isotropic, &wrong, "isotropic") > 0.1);
}

type Shape = (&'static str, fn(f64) -> AreaShape);

/// The seed scene's lights as Lambertian rectangles and disks facing the grid's centre,
/// of size 0 (the centre with its cosine) and of several sizes, under every shadow
/// model that shades area lights and at several sample counts: the GPU draws the
/// CPU's samples and agrees with it.
#[test]
fn gpu_agrees_with_the_cpu() {
    let mut gpu = tracer();
    let shapes: [Shape; 2] = [
        ("rect", |s| AreaShape::Rect {
            width: s,
            height: 0.6 * s,
        }),
        ("disk", |s| AreaShape::Disk { radius: s / 2.0 }),
    ];
    for (shape_name, shape) in shapes {
        for size in [0.0, 1.5, 5.0] {
            let mut scene = seed_scene(16).unwrap();
            let c = scene.grid.centre();
            for l in &mut scene.lights {
                let Light::Point(p) = l.clone() else { continue };
                *l = Light::Area(AreaLight {
                    emission: Emission::Lambertian,
                    shape: shape(size),
                    position: p.position,
                    // Off the centre, so the cosine varies across the grid.
                    normal: (c + DVec3::new(3.0, -2.0, 1.0) - p.position).normalize(),
                    rotation: 0.7,
                    color: p.color,
                    intensity: p.intensity,
                });
            }
            for model in ["hard", "area", "ratio", "sdf", "cone"] {
                for (samples, spp) in [(1, 1), (4, 2)] {
                    let mut settings = RenderSettings {
                        width: 32,
                        height: 32,
                        light_samples: samples,
                        spp,
                        seed: 5,
                        ..Default::default()
                    };
                    settings.features.set_shadow_model(model);
                    let name = format!("{shape_name} {size} {model} {samples}x{spp}");
                    let g = gpu.render(&scene, &settings).unwrap();
                    let cpu = voxlab::cpu::render(&scene, &settings);
                    assert_agree(&name, &g.frame, &cpu.frame);
                }
            }
        }
    }
}

/// The emitter's cosine changes the image against the isotropic light of the same
/// intensity, and a Lambertian light lights nothing behind it.
#[test]
fn lambertian_lights_nothing_behind_it() {
    let mut scene = disk_over_floor();
    if let Light::Area(a) = &mut scene.lights[0] {
        a.normal = DVec3::Y; // facing away from the floor
    }
    for model in ["hard", "area", "ratio"] {
        let mut settings = RenderSettings {
            width: 16,
            height: 16,
            light_samples: 4,
            ..Default::default()
        };
        settings.features.set_shadow_model(model);
        let f = voxlab::cpu::render(&scene, &settings).frame;
        assert!(
            f.pixels.iter().all(|p| p.iter().all(|&c| c == 0.0)),
            "{model}: light behind a Lambertian disk"
        );
    }
}

fn light_file(extra: &str) -> String {
    format!("[[lights]]\ntype = {extra}\nposition = [8.0, 20.0, 8.0]\nintensity = 100.0\n")
}

/// The key: both names parse on rects and disks, round-trip through the writer, and
/// anything else is an error that names the key and the allowed values; a sphere
/// refuses it.
#[test]
fn emission_key_is_checked() {
    for (kind, shape) in [("rect", "size = [2.0, 1.0]"), ("disk", "radius = 1.0")] {
        for name in Emission::NAMES {
            let text = light_file(&format!("\"{kind}\"\n{shape}\nemission = \"{name}\""));
            let e = Experiment::from_str(&text, "x.toml").unwrap();
            let Light::Area(a) = &e.scene.lights[0] else {
                panic!("{kind}: not an area light")
            };
            assert_eq!(a.emission.name(), name);
            let written = to_toml(&e, &toml::Table::new()).unwrap();
            let again = Experiment::from_str(&written, "y.toml").unwrap();
            assert_eq!(again.scene.lights, e.scene.lights);
        }
        let text = light_file(&format!("\"{kind}\"\n{shape}\nemission = \"cosine\""));
        let msg = Experiment::from_str(&text, "x.toml")
            .unwrap_err()
            .to_string();
        for part in [
            "x.toml",
            "lights[0].emission",
            "isotropic",
            "lambertian",
            "cosine",
        ] {
            assert!(msg.contains(part), "{msg:?} lacks {part:?}");
        }
    }
    let text = light_file("\"sphere\"\nradius = 1.0\nemission = \"lambertian\"");
    let msg = Experiment::from_str(&text, "x.toml")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("emission"), "{msg}");
}
