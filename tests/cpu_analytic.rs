//! Closed-form checks of the f64 reference: an empty grid, a lit unoccluded point against
//! the Phong formula of `src/trace_contract.md`, Snell's law, and total internal reflection.

use glam::{DVec3, IVec3, UVec3};
use voxlab::cpu::{SampleKey, refract, trace_ray};
use voxlab::scene::{Grid, Light, Material, OrbitCamera, PointLight, Scene, seed_scene};
use voxlab::{RayStats, RenderSettings};

fn material(name: &str, kd: f64, ks: f64, kr: f64, kt: f64, ior: f64) -> Material {
    Material {
        name: name.into(),
        albedo: DVec3::new(0.9, 0.6, 0.3),
        kd,
        ks,
        shininess: 20.0,
        kr,
        kt,
        ior,
        sigma: None,
        ..voxlab::scene::seed_palette()[0].clone()
    }
}

fn rel_err(a: DVec3, b: DVec3) -> f64 {
    ((a - b).abs() / b.abs().max(DVec3::splat(1e-300))).max_element()
}

#[test]
fn empty_grid_is_ambient_everywhere() {
    let mut scene = seed_scene(16).unwrap();
    scene.grid.data_mut().fill(0);
    let settings = RenderSettings {
        width: 48,
        height: 32,
        ..RenderSettings::default()
    };
    let out = voxlab::cpu::render(&scene, &settings);
    let ambient = scene.ambient.as_vec3().to_array();
    assert!(out.frame.pixels.iter().all(|p| *p == ambient));
    // No hit, so no shadow or secondary ray was traced.
    assert_eq!(out.stats.primary, 48 * 32);
    assert_eq!(out.stats.secondary + out.stats.shadow, 0);
}

/// A 5x1x5 floor of one opaque voxel layer, lit by one point light; the camera looks
/// down at it from an angle so the hit point, normal and light direction are generic.
fn floor_scene(falloff_light: DVec3) -> Scene {
    let mut grid = Grid::new(UVec3::new(5, 1, 5), 0.5, DVec3::new(-1.25, -0.5, -1.25)).unwrap();
    for z in 0..5 {
        for x in 0..5 {
            grid.set(IVec3::new(x, 0, z), 1);
        }
    }
    Scene {
        grid,
        materials: vec![
            voxlab::scene::seed_palette()[0].clone(),
            material("floor", 0.7, 0.4, 0.0, 0.0, 1.0),
        ],
        lights: vec![Light::Point(PointLight {
            position: falloff_light,
            color: DVec3::new(1.0, 0.8, 0.6),
            intensity: 3.0,
        })],
        camera: OrbitCamera {
            target: DVec3::ZERO,
            distance: 4.0,
            yaw: 0.3,
            pitch: 0.9,
            vfov: 0.8,
        },
        ambient: DVec3::new(0.05, 0.075, 0.1),
        mesh: None,
    }
}

#[test]
fn lit_unoccluded_point_equals_closed_form_phong() {
    for falloff in [true, false] {
        let light = DVec3::new(0.4, 1.7, -0.3);
        let scene = floor_scene(light);
        let settings = RenderSettings {
            falloff,
            ..RenderSettings::default()
        };
        let frame = scene.camera.frame();
        // Aim at a generic point of the floor's top face (y = 0).
        let target = DVec3::new(0.31, 0.0, 0.17);
        let d = (target - frame.eye).normalize();
        let mut stats = RayStats::default();
        let c = trace_ray(
            &scene,
            &settings,
            SampleKey::default(),
            frame.eye,
            d,
            &mut stats,
        );

        // `src/trace_contract.md`, by hand.
        let m = &scene.materials[1];
        let n = DVec3::Y;
        let to_l = light - target;
        let dist = to_l.length();
        let l = to_l / dist;
        let e = DVec3::new(1.0, 0.8, 0.6) * 3.0 / if falloff { dist * dist } else { 1.0 };
        let r = l - 2.0 * n.dot(l) * n;
        let expected = scene.ambient
            + m.albedo * e * (m.kd * n.dot(l) + m.ks * r.dot(d).max(0.0).powf(m.shininess));
        let err = rel_err(c, expected);
        assert!(
            err < 1e-9,
            "falloff {falloff}: {c} vs {expected}, relative error {err}"
        );
        assert!(r.dot(d) > 0.5, "the test must exercise the specular term");
        assert_eq!((stats.primary, stats.shadow, stats.secondary), (1, 1, 0));
    }
}

#[test]
fn light_behind_the_surface_gives_ambient_only_and_no_shadow_ray() {
    // The light is under the floor, behind the face the camera sees: n.l < 0, so the
    // face's Phong term is zero and no shadow ray is cast (contract, "Shading a hit").
    let scene = floor_scene(DVec3::new(0.4, -1.7, -0.3));
    let frame = scene.camera.frame();
    let d = (DVec3::new(0.31, 0.0, 0.17) - frame.eye).normalize();
    let mut stats = RayStats::default();
    let c = trace_ray(
        &scene,
        &RenderSettings::default(),
        SampleKey::default(),
        frame.eye,
        d,
        &mut stats,
    );
    assert_eq!(c, scene.ambient);
    assert_eq!((stats.primary, stats.shadow, stats.secondary), (1, 0, 0));
}

#[test]
fn snell_law_uses_sines() {
    for deg in [0.0f64, 10.0, 30.0, 45.0, 60.0, 85.0] {
        let t1 = deg.to_radians();
        let d = DVec3::new(t1.sin(), -t1.cos(), 0.0);
        let t = refract(d, DVec3::Y, 1.0 / 1.5).unwrap();
        let sin_t2 = t.x / t.length();
        // sin t1 / sin t2 = n2 / n1
        assert!((t1.sin() - 1.5 * sin_t2).abs() < 1e-12, "at {deg} degrees");
        assert!(
            t.y < 0.0,
            "the refracted ray continues into the second medium"
        );
    }
    // From glass into air beyond the critical angle asin(1/1.5) = 41.8 degrees: none.
    let t1 = 45f64.to_radians();
    assert!(refract(DVec3::new(t1.sin(), -t1.cos(), 0.0), DVec3::Y, 1.5).is_none());
    assert!(
        refract(
            DVec3::new(40f64.to_radians().sin(), -40f64.to_radians().cos(), 0.0),
            DVec3::Y,
            1.5
        )
        .is_some()
    );
}

/// Into a slab of a far larger index and out again, a ray leaves as it came (the two
/// refractions undo each other), however large the ratio: the reference took sin^2 as
/// `1 - c^2`, which in f64 has no digits for the near-normal ray inside the slab, and
/// left it along the normal (a glass ior of 1e8 drew a quarter of the seed scene's
/// pixels apart from the f32 kernel, the reference the wrong one); past 1e154 the
/// part along the surface squared is no f64.
#[test]
fn a_ray_through_a_slab_of_any_index_leaves_as_it_came() {
    for ratio in [1.5, 1e3, 1e8, 1e12, 1e30, 1e200] {
        for deg in [0.0f64, 1e-6, 10.0, 45.0, 89.0] {
            let t1 = deg.to_radians();
            let d = DVec3::new(t1.sin(), -t1.cos(), 0.0);
            let inside = refract(d, DVec3::Y, 1.0 / ratio).unwrap();
            // Snell's law inside: sin t2 = sin t1 / ratio.
            let sin_inside = inside.x / inside.length();
            assert!(
                (sin_inside * ratio - t1.sin()).abs() <= 1e-12 * t1.sin().max(1e-300),
                "ratio {ratio:e}, {deg} degrees: sin inside {sin_inside:e}"
            );
            let out = refract(inside, DVec3::Y, ratio).expect("leaves the slab");
            assert!(
                (out - d).length() < 1e-12,
                "ratio {ratio:e}, {deg} degrees: {d} became {out}"
            );
        }
    }
}

/// A glass block (unlit: kd = ks = 0) above an opaque lit floor. A ray inside the glass
/// meets the glass/void boundary at `deg` degrees from the normal.
fn tir_setup(deg: f64) -> (Scene, DVec3, DVec3) {
    let mut grid = Grid::new(UVec3::new(8, 4, 1), 1.0, DVec3::ZERO).unwrap();
    for x in 0..8 {
        grid.set(IVec3::new(x, 0, 0), 2); // floor
        for y in 1..3 {
            grid.set(IVec3::new(x, y, 0), 1); // glass, void above y = 3
        }
    }
    let scene = Scene {
        grid,
        materials: vec![
            voxlab::scene::seed_palette()[0].clone(),
            material("glass", 0.0, 0.0, 0.1, 0.9, 1.5),
            material("floor", 1.0, 0.0, 0.0, 0.0, 1.0),
        ],
        lights: vec![Light::Point(PointLight {
            position: DVec3::new(4.0, 3.5, 0.5),
            color: DVec3::ONE,
            intensity: 2.0,
        })],
        camera: seed_scene(4).unwrap().camera,
        ambient: DVec3::new(0.05, 0.075, 0.1),
        mesh: None,
    };
    let t = deg.to_radians();
    let d = DVec3::new(t.sin(), t.cos(), 0.0); // upwards, towards y = 3
    let eye = DVec3::new(3.0 - 0.5 * t.tan(), 2.5, 0.5); // hits y = 3 at x = 3
    (scene, eye, d)
}

#[test]
fn total_internal_reflection_sends_kt_to_the_reflection() {
    let settings = RenderSettings::default();
    // 60 degrees > critical angle 41.8: TIR. The only secondary ray is the reflection,
    // weighted kr + kt = 1: the pixel equals the reflected ray's own radiance.
    let (scene, eye, d) = tir_setup(60.0);
    let mut stats = RayStats::default();
    let c = trace_ray(&scene, &settings, SampleKey::default(), eye, d, &mut stats);
    assert_eq!(stats.secondary, 1, "TIR spawns no refraction ray");
    let p = eye + (0.5 / d.y) * d;
    let reflected = DVec3::new(d.x, -d.y, d.z);
    let eps = settings.ray_offset;
    let mut s2 = RayStats::default();
    let c_reflected = trace_ray(
        &scene,
        &settings,
        SampleKey::default(),
        p - eps * DVec3::Y,
        reflected,
        &mut s2,
    );
    let expected = scene.ambient + 1.0 * (c_reflected - scene.ambient);
    assert!(rel_err(c, expected) < 1e-12, "{c} vs {expected}");
    assert!(
        (c - scene.ambient).max_element() > 1e-3,
        "the reflection must see the lit floor"
    );

    // 20 degrees: below the critical angle, a refraction and a reflection ray (kr = 0.1).
    let (scene, eye, d) = tir_setup(20.0);
    let mut stats = RayStats::default();
    trace_ray(&scene, &settings, SampleKey::default(), eye, d, &mut stats);
    assert!(stats.secondary >= 2);
}
