//! Ray counting, odd grid sizes and device limits on the GPU tracer.

mod common;

use common::tracer;
use glam::{DVec3, IVec3, UVec3};
use voxlab::scene::{Grid, seed_ids, seed_scene, seed_scene_dims};
use voxlab::{RayStats, RenderSettings};

fn small(w: u32, h: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        ..Default::default()
    }
}

#[test]
fn primary_only_counts_one_ray_per_pixel() {
    let mut scene = seed_scene(16).unwrap();
    scene.lights.clear();
    let settings = RenderSettings {
        max_reflection_depth: 0,
        max_refraction_depth: 0,
        ..small(100, 60)
    };
    let mut gpu = tracer();
    let out = gpu.render_counted(&scene, &settings).unwrap();
    println!("{}\n{:?}", gpu.last_plan().unwrap(), out.stats);
    assert_eq!(out.stats.primary, 100 * 60);
    assert_eq!(out.stats.secondary, 0);
    assert_eq!(out.stats.shadow, 0);
    assert!(out.stats.voxel_steps > 0);
    // Without counting compiled in, the stats are zero.
    let plain = gpu.render(&scene, &settings).unwrap();
    assert_eq!(plain.stats, RayStats::default());
    assert_eq!(plain.frame, out.frame, "counting must not change the image");
}

fn close(name: &str, gpu: u64, cpu: u64, rel: f64) {
    let d = gpu.abs_diff(cpu) as f64;
    assert!(
        d <= rel * cpu as f64,
        "{name}: GPU {gpu}, CPU {cpu} (differ by {:.4} %, limit {} %)",
        100.0 * d / cpu.max(1) as f64,
        100.0 * rel
    );
}

#[test]
fn seed_counts_match_the_cpu() {
    let scene = seed_scene(16).unwrap();
    let settings = small(96, 96);
    let mut gpu = tracer();
    let g = gpu.render_counted(&scene, &settings).unwrap().stats;
    let c = voxlab::cpu::render(&scene, &settings).stats;
    println!("GPU {g:?}\nCPU {c:?}");
    assert_eq!(g.primary, c.primary);
    assert_eq!(g.primary, 96 * 96);
    // f32 against f64 may send a handful of rays another way at voxel edges.
    close("secondary", g.secondary, c.secondary, 0.002);
    close("shadow", g.shadow, c.shadow, 0.002);
    close("voxel steps", g.voxel_steps, c.voxel_steps, 0.005);
}

/// The secondary rays that leave the grid where they start are counted untraced alike:
/// the kernel counts them without tracing them, the reference traces them to nothing and
/// tells them by the same test in f64. Under voxlab's rules most are refracted out of
/// the seed's panes on its boundary; under either rules, and without refraction, the
/// reflections off the grid's outer faces leave it too.
#[test]
fn both_tracers_count_the_rays_the_kernel_leaves_untraced() {
    let scene = seed_scene(16).unwrap();
    let mut gpu = tracer();
    for (name, settings) in [
        ("default rules", small(96, 96)),
        (
            "seed rules",
            RenderSettings {
                rules: voxlab::render::Rules::Seed,
                ..small(96, 96)
            },
        ),
        (
            "no refraction",
            RenderSettings {
                max_refraction_depth: 0,
                ..small(96, 96)
            },
        ),
    ] {
        let g = gpu.render_counted(&scene, &settings).unwrap().stats;
        let c = voxlab::cpu::render(&scene, &settings).stats;
        println!("{name}: GPU {g:?}\nCPU {c:?}");
        close("untraced", g.untraced, c.untraced, 0.002);
        assert!(c.untraced <= c.secondary);
        assert!(c.untraced > 0, "{name}: {c:?}");
    }
}

/// A shadow ray is cast only towards a light that can light the hit (contract,
/// "Shading a hit"): a light behind every lit face casts none, on both tracers, and one
/// in front casts one per hit. A floor of one solid layer under a camera above it; the
/// floor's faces are axis-aligned and the lights far from their planes, so f32 and f64
/// agree on every sign and the counts are exact.
#[test]
fn only_a_light_in_front_of_a_surface_casts_shadow_rays() {
    let mut scene = seed_scene(8).unwrap();
    scene.grid.data_mut().fill(0);
    for z in 0..8 {
        for x in 0..8 {
            scene.grid.set(IVec3::new(x, 0, z), seed_ids::SOLID);
        }
    }
    scene.camera.pitch = 1.2;
    let settings = RenderSettings {
        max_reflection_depth: 0,
        max_refraction_depth: 0,
        ..small(24, 24)
    };
    let mut gpu = tracer();
    for (y, lit) in [(-6.0, false), (9.0, true)] {
        let light = voxlab::scene::PointLight {
            position: DVec3::new(4.0, y, 4.0),
            color: DVec3::ONE,
            intensity: 50.0,
        };
        scene.lights = vec![voxlab::scene::Light::Point(light)];
        let g = gpu.render_counted(&scene, &settings).unwrap().stats;
        let c = voxlab::cpu::render(&scene, &settings);
        println!("light at y {y}: GPU {g:?}, CPU {:?}", c.stats);
        // The pixels the light lights: with nothing to cast a shadow, those of the
        // faces it is in front of.
        let lit_pixels = c
            .frame
            .pixels
            .iter()
            .filter(|p| p[0] != scene.ambient.x as f32)
            .count() as u64;
        assert_eq!(g.shadow, c.stats.shadow, "light at y {y}");
        if lit {
            assert!(lit_pixels > 100, "the floor must fill much of the image");
            assert_eq!(c.stats.shadow, lit_pixels);
        } else {
            assert_eq!((lit_pixels, c.stats.shadow), (0, 0));
        }
    }
}

#[test]
fn one_voxel_and_non_power_of_two_grids() {
    let mut gpu = tracer();
    for dims in [
        UVec3::new(1, 1, 1),
        UVec3::new(2, 3, 5),
        UVec3::new(31, 7, 13),
    ] {
        let scene = seed_scene_dims(dims).unwrap();
        let out = gpu.render_counted(&scene, &small(40, 24)).unwrap();
        assert!(out.frame.all_finite(), "{dims}: non-finite pixels");
        assert_eq!(out.stats.primary, 40 * 24);
        let cpu = voxlab::cpu::render(&scene, &small(40, 24));
        let worst = out
            .frame
            .pixels
            .iter()
            .zip(&cpu.frame.pixels)
            .filter(|(a, b)| (0..3).any(|c| (a[c] - b[c]).abs() > 2.0 / 255.0))
            .count();
        println!("{dims}: {worst} of {} pixels differ by > 2/255", 40 * 24);
        assert!(worst <= 10, "{dims}: {worst} pixels differ from the CPU");
    }
    // A single solid voxel must be visible: some pixel brighter than the ambient.
    let mut scene = seed_scene_dims(UVec3::ONE).unwrap();
    scene.grid.set(IVec3::ZERO, seed_ids::SOLID);
    let out = gpu.render(&scene, &small(40, 24)).unwrap();
    let ambient = scene.ambient.x as f32;
    assert!(out.frame.pixels.iter().any(|p| p[0] > ambient + 0.01));
}

#[test]
fn grid_changes_are_uploaded_and_repeats_are_stable() {
    let mut gpu = tracer();
    let mut scene = seed_scene(16).unwrap();
    let s = small(48, 48);
    let a = gpu.render(&scene, &s).unwrap();
    let b = gpu.render(&scene, &s).unwrap();
    assert_eq!(a.frame, b.frame, "the same scene twice");
    // Fill the open front so the interior disappears: the image must change.
    for y in 0..16 {
        for x in 0..16 {
            scene.grid.set(IVec3::new(x, y, 15), seed_ids::SOLID);
        }
    }
    let c = gpu.render(&scene, &s).unwrap();
    assert_ne!(a.frame, c.frame, "an edited grid must be re-uploaded");
    let cpu = voxlab::cpu::render(&scene, &s);
    let bad = c
        .frame
        .pixels
        .iter()
        .zip(&cpu.frame.pixels)
        .filter(|(p, q)| (0..3).any(|k| (p[k] - q[k]).abs() > 2.0 / 255.0))
        .count();
    assert!(bad <= 12, "{bad} pixels differ from the CPU after the edit");
}

#[test]
fn too_large_grid_is_a_clear_error() {
    let gpu = tracer();
    let side = gpu.max_grid_side();
    println!("{}: max grid side {side}", gpu.adapter_summary());
    assert!(side >= 256);
    // A grid one voxel too long in x (thin, so it is cheap to allocate).
    let mut grid = Grid::new(UVec3::new(side + 1, 1, 1), 1.0, DVec3::ZERO).unwrap();
    // A lit voxel, so that cone shadows are planned.
    grid.set(glam::IVec3::ZERO, voxlab::scene::seed_ids::SOLID);
    let mut scene = seed_scene(4).unwrap();
    scene.grid = grid;
    let mut gpu = gpu;
    // The cone pyramids need the grid as a texture; the walks read buffers
    // (tests/stress_limits.rs).
    let mut settings = small(8, 8);
    settings.features.shadow_model = &voxlab::technique::cone::MODEL;
    let err = gpu.render(&scene, &settings).unwrap_err().to_string();
    assert!(
        err.contains("max_texture_dimension_3d") && err.contains(&side.to_string()),
        "{err}"
    );
}
