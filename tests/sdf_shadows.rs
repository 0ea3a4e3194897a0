//! Distance-field soft shadows (src/technique/sdf.rs) beyond what tests/shadow_models.rs
//! holds every shadow model to: the distance transform against brute force, the field's
//! definition, `softness = 0` as the hard shadow on both tracers, and penumbrae that
//! only lighten towards the hard shadow's lit side.

mod common;

use common::tracer;
use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::scene::{AreaLight, AreaShape, Grid, Light, Scene, seed_palette, seed_scene};
use voxlab::technique::sdf::{distance_field, squared_edt};
use voxlab::{RenderSettings, cpu};

/// The separable transform equals the brute-force minimum over all sites, on random
/// grids of random shapes and densities (none, one, many sites).
#[test]
fn the_transform_is_exact() {
    let mut rng = StdRng::seed_from_u64(3);
    for case in 0..200 {
        let dims = UVec3::new(
            rng.random_range(1..10),
            rng.random_range(1..10),
            rng.random_range(1..10),
        );
        let n = (dims.x * dims.y * dims.z) as usize;
        let density = [0.0, 0.02, 0.2, 0.7][case % 4];
        let sites: Vec<bool> = (0..n)
            .map(|_| rng.random_range(0.0..1.0) < density)
            .collect();
        let mut f: Vec<f64> = sites
            .iter()
            .map(|&s| if s { 0.0 } else { f64::INFINITY })
            .collect();
        squared_edt(&mut f, dims);
        let at = |i: usize| {
            let x = i % dims.x as usize;
            let y = (i / dims.x as usize) % dims.y as usize;
            let z = i / (dims.x * dims.y) as usize;
            IVec3::new(x as i32, y as i32, z as i32)
        };
        for (i, &transformed) in f.iter().enumerate() {
            let brute = (0..n)
                .filter(|&j| sites[j])
                .map(|j| (at(i) - at(j)).length_squared() as f64)
                .fold(f64::INFINITY, f64::min);
            assert_eq!(
                transformed,
                brute,
                "case {case}, dims {dims}, voxel {}",
                at(i)
            );
        }
    }
}

/// `D` is 0 on opaque voxels, 1/2 next to one, `sqrt(2) - 1/2` diagonally, and
/// transparent voxels (kt > 0) are not occluders.
#[test]
fn the_field_measures_from_opaque_voxels() {
    let mut scene = seed_scene(4).unwrap();
    let mut grid = Grid::new(UVec3::new(5, 5, 5), 1.0, DVec3::ZERO).unwrap();
    let palette = seed_palette();
    let opaque = palette
        .iter()
        .position(|m| m.kt <= 0.0 && m.name != "void")
        .unwrap() as u8;
    let glass = palette
        .iter()
        .position(|m| m.kt > 0.0 && m.kt < 1.0)
        .unwrap() as u8;
    grid.set(IVec3::new(2, 2, 2), opaque);
    grid.set(IVec3::new(0, 0, 0), glass);
    scene.grid = grid;
    scene.materials = palette;
    let d = distance_field(&scene);
    let at = |x: usize, y: usize, z: usize| d[x + 5 * (y + 5 * z)];
    assert_eq!(at(2, 2, 2), 0.0);
    assert_eq!(at(3, 2, 2), 0.5);
    assert_eq!(at(3, 3, 2), 2f64.sqrt() - 0.5);
    assert_eq!(at(0, 0, 0), 12f64.sqrt() - 0.5, "glass is no occluder");
}

/// A floor and a pillar of diffuse voxels under a rectangle light, seen from above.
fn pillar_scene() -> Scene {
    let mut palette = seed_palette();
    for m in palette.iter_mut().skip(1) {
        (m.kd, m.ks, m.kr, m.kt) = (1.0, 0.0, 0.0, 0.0);
    }
    let mut grid = Grid::new(UVec3::new(24, 12, 24), 1.0, DVec3::ZERO).unwrap();
    for z in 0..24 {
        for x in 0..24 {
            grid.set(IVec3::new(x, 0, z), 1);
        }
    }
    for y in 1..8 {
        for z in 10..14 {
            for x in 10..12 {
                grid.set(IVec3::new(x, y, z), 1);
            }
        }
    }
    let mut scene = seed_scene(16).unwrap();
    scene = Scene {
        grid,
        materials: palette,
        lights: vec![Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Rect {
                width: 4.0,
                height: 4.0,
            },
            position: DVec3::new(2.0, 11.5, 12.0),
            normal: DVec3::new(1.0, -1.0, 0.0).normalize(),
            rotation: 0.0,
            color: DVec3::ONE,
            intensity: 100.0,
        })],
        ..scene
    };
    scene.camera.target = DVec3::new(12.0, 0.0, 12.0);
    scene.camera.distance = 30.0;
    scene.camera.pitch = 1.2;
    scene
}

/// A floor, a pillar and a rectangle light: `softness = 0` is the hard shadow exactly on
/// both tracers; soft, no pixel is darker than the hard shadow's (the estimate only
/// darkens the lit side), some penumbra pixels are darker than fully lit, and larger
/// softness never lightens a pixel.
#[test]
fn penumbrae_grow_from_the_hard_shadow() {
    let scene = pillar_scene();
    let render = |softness: Option<f64>| {
        let mut st = RenderSettings {
            width: 48,
            height: 48,
            ..Default::default()
        };
        if let Some(s) = softness {
            st.features.set_shadow_model("sdf");
            st.technique_params.set("sdf", "softness", s);
        }
        st
    };
    let hard = cpu::render(&scene, &render(None)).frame;
    let zero = cpu::render(&scene, &render(Some(0.0))).frame;
    assert_eq!(hard, zero, "softness 0 is the hard shadow (CPU)");
    let mut gpu = tracer();
    let g_hard = gpu.render(&scene, &render(None)).unwrap().frame;
    let g_zero = gpu.render(&scene, &render(Some(0.0))).unwrap().frame;
    assert_eq!(g_hard, g_zero, "softness 0 is the hard shadow (GPU)");

    let lum = |p: &[f32; 3]| p[0] + p[1] + p[2];
    let mut previous = hard.clone();
    for s in [0.5, 1.0, 2.0] {
        let soft = cpu::render(&scene, &render(Some(s))).frame;
        let mut darker = 0;
        for ((h, x), prev) in hard.pixels.iter().zip(&soft.pixels).zip(&previous.pixels) {
            // Lit in the hard image: never brighter, and darker in the penumbra.
            assert!(
                lum(x) <= lum(h) + 1e-6,
                "softness {s}: brighter than the hard image"
            );
            assert!(
                lum(x) <= lum(prev) + 1e-6,
                "softness {s}: lighter than a smaller softness"
            );
            // Shadowed in the hard image: stays as dark.
            if lum(h) <= 1e-6 {
                assert!(lum(x) <= 1e-6);
            }
            if lum(x) < lum(h) - 1e-3 {
                darker += 1;
            }
        }
        assert!(darker > 10, "softness {s}: only {darker} penumbra pixels");
        previous = soft;
    }
}

/// The device builds the same field as the CPU, value for value, on random grids of
/// random shapes (odd sides, one-voxel lines, no occluder at all).
#[test]
fn the_device_builds_the_same_field() {
    let mut gpu = tracer();
    let mut rng = StdRng::seed_from_u64(11);
    let palette = seed_palette();
    let opaque = palette
        .iter()
        .position(|m| m.kt <= 0.0 && m.name != "void")
        .unwrap() as u8;
    let glass = palette
        .iter()
        .position(|m| m.kt > 0.0 && m.kt < 1.0)
        .unwrap() as u8;
    for case in 0..24 {
        let dims = UVec3::new(
            rng.random_range(1..40),
            rng.random_range(1..24),
            rng.random_range(1..40),
        );
        let mut scene = seed_scene(16).unwrap();
        let mut grid = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
        let density = [0.0, 0.01, 0.1, 0.5][case % 4];
        for z in 0..dims.z as i32 {
            for y in 0..dims.y as i32 {
                for x in 0..dims.x as i32 {
                    let r: f64 = rng.random_range(0.0..1.0);
                    if r < density {
                        grid.set(IVec3::new(x, y, z), opaque);
                    } else if r < 2.0 * density {
                        grid.set(IVec3::new(x, y, z), glass);
                    }
                }
            }
        }
        // Something lit, so the plan keeps shadows (glass: no occluder).
        grid.set(IVec3::ZERO, glass);
        scene.grid = grid;
        scene.materials = palette.clone();
        let mut st = RenderSettings {
            width: 8,
            height: 8,
            ..Default::default()
        };
        st.features.set_shadow_model("sdf");
        st.technique_params.set("sdf", "softness", 1.5);
        gpu.render(&scene, &st).unwrap();
        let device = gpu.read_technique_data().unwrap().expect("the sdf field");
        let cpu: Vec<f32> = distance_field(&scene)
            .into_iter()
            .map(|d| d.min(f32::MAX as f64) as f32)
            .collect();
        assert_eq!(device.len(), cpu.len(), "case {case}");
        for (i, (g, c)) in device.iter().zip(&cpu).enumerate() {
            assert!(
                g == c || (g - c).abs() <= 1e-6 * c.abs(),
                "case {case}, dims {dims}, voxel {i}: device {g}, cpu {c}"
            );
        }
    }
}

/// The field depends on the occluders alone: a softness sweep on one tracer builds it
/// once and renders what a fresh tracer renders at each softness; another grid builds
/// it again.
#[test]
fn a_softness_sweep_keeps_the_field() {
    let scene = pillar_scene();
    let settings = |softness: f64| {
        let mut st = RenderSettings {
            width: 24,
            height: 24,
            ..Default::default()
        };
        st.features.set_shadow_model("sdf");
        st.technique_params.set("sdf", "softness", softness);
        st
    };
    let mut swept = tracer();
    for (i, softness) in [0.25, 1.0, 4.0].into_iter().enumerate() {
        let kept = swept.render(&scene, &settings(softness)).unwrap().frame;
        assert_eq!(
            swept.technique_data_builds(),
            1,
            "softness {softness} (render {i})"
        );
        let fresh = tracer().render(&scene, &settings(softness)).unwrap().frame;
        assert_eq!(kept, fresh, "softness {softness}: the kept field's image");
    }
    let mut other = scene.clone();
    other.grid.set(IVec3::new(3, 1, 3), 1);
    swept.render(&other, &settings(1.0)).unwrap();
    assert_eq!(
        swept.technique_data_builds(),
        2,
        "another grid builds the field again"
    );
}
