//! Area lights on the GPU kernel: switched off (or of size 0) they reproduce the golden
//! baseline images; sampled, the kernel draws the same samples as the f64 CPU reference
//! (the hash of `src/sampling.rs`, mirrored by `shaders/sampling.wgsl`), so the
//! stochastic images agree to float error.
//!
//! Tolerances:
//! - against the goldens: those of tests/gpu_golden.rs (at most 0.2 % of pixels over
//!   2/255 on the displayed 8-bit image, mean below 0.5/255);
//! - GPU against CPU on stochastic images: those of tests/gpu_agreement.rs (fewer than
//!   0.5 % of pixels over 2/255, mean below 1e-3). With the same samples, the images
//!   differ only where f32 moves a sample point or a shadow ray across a voxel edge;
//!   measured on lavapipe they agree to ~1e-6 (printed).
//!
//! Runs on whatever adapter wgpu finds (lavapipe in CI); a missing adapter fails.

mod common;

use common::{assert_agree, assert_matches_golden, experiment, linear, tracer};
use glam::DVec3;
use voxlab::RenderSettings;
use voxlab::experiment::Experiment;
use voxlab::plan::Plan;
use voxlab::scene::{AreaLight, AreaShape, Light, Scene, seed_scene};

fn baseline(width: u32, height: u32) -> Experiment {
    let mut e = experiment("baseline.toml");
    e.settings.width = width;
    e.settings.height = height;
    e
}

/// The seed's point lights re-expressed as area lights of `shape` with size `size`
/// (rectangles face the grid's centre).
fn as_area_lights(scene: &mut Scene, shape: fn(f64) -> AreaShape, size: f64) {
    let c = scene.grid.centre();
    for l in &mut scene.lights {
        let Light::Point(p) = l.clone() else { continue };
        *l = Light::Area(AreaLight {
            emission: Default::default(),
            shape: shape(size),
            position: p.position,
            normal: (c - p.position).normalize(),
            rotation: 0.4,
            color: p.color,
            intensity: p.intensity,
        });
    }
}

fn rect(s: f64) -> AreaShape {
    AreaShape::Rect {
        width: s,
        height: 0.75 * s,
    }
}
fn disk(s: f64) -> AreaShape {
    AreaShape::Disk { radius: s / 2.0 }
}
fn sphere(s: f64) -> AreaShape {
    AreaShape::Sphere { radius: s / 2.0 }
}

type Shape = (&'static str, fn(f64) -> AreaShape);

const SHAPES: [Shape; 3] = [("rect", rect), ("disk", disk), ("sphere", sphere)];

/// Every combination of the area-light feature switched off reproduces the goldens:
/// the seed's lights as area lights of size 0 (sampling on), and as real area lights
/// with `area_lights = false`, at several `light_samples` and `spp` (nothing sampled,
/// so one frame is rendered and the plan says so).
#[test]
fn switched_off_reproduces_the_golden_images() {
    let mut gpu = tracer();
    for (shape_name, shape) in SHAPES {
        for (size, area_on) in [(0.0, true), (0.0, false), (3.0, false)] {
            for (samples, spp) in [(1, 1), (3, 4)] {
                let mut e = baseline(160, 160);
                as_area_lights(&mut e.scene, shape, size);
                e.settings
                    .features
                    .set_shadow_model(if area_on { "area" } else { "hard" });
                e.settings.light_samples = samples;
                e.settings.spp = spp;
                let name = format!(
                    "{shape_name} size {size} area_lights {area_on} samples {samples} spp {spp}"
                );
                let out = gpu.render(&e.scene, &e.settings).unwrap();
                let plan = gpu.last_plan().unwrap();
                assert!(
                    plan.shadow_model.name != "area" && !plan.accumulate,
                    "{name}: {plan}"
                );
                if spp > 1 {
                    assert!(
                        plan.reasons.iter().any(|r| r.contains("rendered once")),
                        "{name}: {plan}"
                    );
                }
                assert_matches_golden(&name, &out.frame, "baseline_160.png");
            }
        }
    }
}

/// The golden scene with a Beer-Lambert request that the plan can prove changes
/// nothing (every material opaque or void) renders the min-kt image exactly.
#[test]
fn beer_lambert_without_partial_materials_is_min_kt() {
    let mut gpu = tracer();
    let mut e = baseline(64, 64);
    for m in e.scene.materials.iter_mut().skip(1) {
        m.kt = 0.0;
    }
    let minkt = gpu.render(&e.scene, &e.settings).unwrap().frame;
    e.settings.features.transmittance = voxlab::technique::beer_lambert::ID;
    let bl = gpu.render(&e.scene, &e.settings).unwrap().frame;
    let plan = gpu.last_plan().unwrap();
    assert_ne!(plan.transmittance.name, "beer-lambert", "{plan}");
    assert_eq!(bl, minkt);
}

/// An area light of size 0 is the point light at its centre: on the GPU the same image
/// as the point light (the same code path), within the golden tolerance of the golden.
#[test]
fn size_zero_area_light_is_the_point_light() {
    let mut gpu = tracer();
    let e = baseline(160, 160);
    let point = gpu.render(&e.scene, &e.settings).unwrap().frame;
    for (name, shape) in SHAPES {
        let mut a = e.clone();
        as_area_lights(&mut a.scene, shape, 0.0);
        a.settings.features.shadow_model = &voxlab::technique::area::MODEL;
        a.settings.light_samples = 8;
        let f = gpu.render(&a.scene, &a.settings).unwrap().frame;
        assert_eq!(f, point, "{name} of size 0");
        assert_matches_golden(name, &f, "baseline_160.png");
    }
}

/// Sampled rectangle, disk and sphere lights: the GPU draws the CPU's samples, so the
/// stochastic images agree (light_samples 4, spp 2: two accumulated frames).
#[test]
fn stochastic_images_agree_with_the_cpu() {
    let mut gpu = tracer();
    for (name, shape) in SHAPES {
        let mut scene = seed_scene(16).unwrap();
        as_area_lights(&mut scene, shape, 5.0);
        let settings = RenderSettings {
            width: 64,
            height: 64,
            light_samples: 4,
            spp: 2,
            seed: 7,
            features: voxlab::render::Features {
                shadow_model: &voxlab::technique::area::MODEL,
                ..Default::default()
            },
            ..Default::default()
        };
        let g = gpu.render(&scene, &settings).unwrap();
        let plan = gpu.last_plan().unwrap().clone();
        assert!(
            (plan.shadow_model.name == "area") && plan.accumulate,
            "{plan}"
        );
        let c = voxlab::cpu::render(&scene, &settings);
        let d = assert_agree(name, &g.frame, &c.frame);
        // Same samples: far closer than two independent estimates would be.
        assert!(d.rmse < 1e-3, "{name}: {d}");

        // The samples really are stochastic: another seed changes the image.
        let other = RenderSettings {
            seed: 8,
            ..settings.clone()
        };
        let g2 = gpu.render(&scene, &other).unwrap();
        let d2 = linear(&g.frame, &g2.frame, 2.0 / 255.0);
        assert!(
            d2.rmse > 10.0 * d.rmse.max(1e-6),
            "{name}: seed 7 vs 8 {d2}"
        );
    }
}

/// Counted rays: one shadow ray per sample, every frame traced (spp frames of
/// light_samples per area light), the same counts as the CPU.
#[test]
fn sample_counts_match_the_cpu() {
    let mut gpu = tracer();
    let mut scene = seed_scene(16).unwrap();
    as_area_lights(&mut scene, rect, 4.0);
    let settings = RenderSettings {
        width: 24,
        height: 24,
        light_samples: 3,
        spp: 5,
        features: voxlab::render::Features {
            shadow_model: &voxlab::technique::area::MODEL,
            ..Default::default()
        },
        ..Default::default()
    };
    let g = gpu.render_counted(&scene, &settings).unwrap().stats;
    let c = voxlab::cpu::render(&scene, &settings).stats;
    assert_eq!(g.primary, 24 * 24 * 5);
    assert_eq!(g.primary, c.primary);
    for (what, a, b) in [
        ("secondary", g.secondary, c.secondary),
        ("shadow", g.shadow, c.shadow),
    ] {
        let rel = (a as f64 - b as f64).abs() / b.max(1) as f64;
        assert!(rel < 0.01, "{what}: GPU {a}, CPU {b}");
    }
}

/// Many frames are split over several dispatches (the sums carry over in the buffers):
/// a render of 48 frames equals, to float error, the CPU's average of 48 frames.
#[test]
fn accumulation_across_dispatches_matches_the_cpu() {
    let mut gpu = tracer();
    let mut scene = seed_scene(16).unwrap();
    as_area_lights(&mut scene, disk, 4.0);
    // 256x256 pixels: 16 frames per dispatch (2^20 pixel-frames), so 3 dispatches.
    let settings = RenderSettings {
        width: 256,
        height: 256,
        light_samples: 1,
        spp: 48,
        features: voxlab::render::Features {
            shadow_model: &voxlab::technique::area::MODEL,
            ..Default::default()
        },
        max_reflection_depth: 1,
        max_refraction_depth: 1,
        ..Default::default()
    };
    let g = gpu.render(&scene, &settings).unwrap().frame;
    let c = voxlab::cpu::render(&scene, &settings).frame;
    let d = assert_agree("48 frames", &g, &c);
    assert!(d.rmse < 1e-4, "{d}");
}

/// A sphere light whose centre sits inside an opaque voxel: samples inside opaque
/// voxels are shadowed (the shadow segment ends inside the voxel, which it visits), the
/// others light the scene; every pixel is finite on both backends and they agree.
#[test]
fn sphere_light_inside_an_opaque_voxel_is_finite() {
    let mut gpu = tracer();
    let mut scene = seed_scene(16).unwrap();
    // The seed's frame is solid along the grid's edges: (0.5, 0.5, 8) is inside one.
    let centre = DVec3::new(0.5, 0.5, 8.0);
    assert_eq!(
        scene.materials[scene.grid.material_at(centre) as usize].kt,
        0.0
    );
    scene.lights = vec![Light::Area(AreaLight {
        emission: Default::default(),
        // Radius 0.8: part of the sphere lies outside the voxel (and outside the grid).
        shape: AreaShape::Sphere { radius: 0.8 },
        position: centre,
        normal: DVec3::Y,
        rotation: 0.0,
        color: DVec3::ONE,
        intensity: 200.0,
    })];
    let settings = RenderSettings {
        width: 48,
        height: 48,
        light_samples: 4,
        spp: 2,
        features: voxlab::render::Features {
            shadow_model: &voxlab::technique::area::MODEL,
            ..Default::default()
        },
        ..Default::default()
    };
    let g = gpu.render(&scene, &settings).unwrap().frame;
    let c = voxlab::cpu::render(&scene, &settings).frame;
    assert_agree("sphere light in a solid voxel", &g, &c);
    let mut dark = scene.clone();
    dark.lights.clear();
    let unlit = voxlab::cpu::render(&dark, &settings).frame;
    let lit = linear(&c, &unlit, 1e-3);
    assert!(
        lit.pixels_over > 0,
        "the samples outside the voxel light nothing: {lit}"
    );
    // Entirely inside the voxel: every sample is shadowed, the image is the unlit one.
    scene.lights[0] = match &scene.lights[0] {
        Light::Area(a) => Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Sphere { radius: 0.2 },
            ..a.clone()
        }),
        l => l.clone(),
    };
    let g = gpu.render(&scene, &settings).unwrap().frame;
    assert!(g.all_finite());
    let d = linear(&g, &unlit, 1e-6);
    assert!(
        d.max_abs < 1e-6,
        "light sealed in a solid voxel lights something: {d}"
    );
}

/// The plan: the area model only with a light of non-zero size, with a reason otherwise;
/// ACCUMULATE only when sampled and spp > 1.
#[test]
fn plan_flags_follow_the_scene() {
    let mut scene = seed_scene(16).unwrap();
    let mut settings = RenderSettings {
        spp: 4,
        ..Default::default()
    };
    settings.features.shadow_model = &voxlab::technique::area::MODEL;
    let p = Plan::new(&scene, &settings);
    assert!(p.shadow_model.name != "area" && !p.accumulate, "{p}");
    assert!(
        p.reasons
            .iter()
            .any(|r| r.contains("no area light of non-zero size")),
        "{p}"
    );
    assert_eq!(p.frames(&settings), 1);
    as_area_lights(&mut scene, rect, 2.0);
    let p = Plan::new(&scene, &settings);
    assert!((p.shadow_model.name == "area") && p.accumulate, "{p}");
    assert_eq!(p.frames(&settings), 4);
    settings.spp = 1;
    let p = Plan::new(&scene, &settings);
    assert!((p.shadow_model.name == "area") && !p.accumulate, "{p}");
    settings.features.shadow_model = voxlab::technique::default_shadow_model();
    let p = Plan::new(&scene, &settings);
    assert!(p.shadow_model.name != "area", "{p}");
    assert!(
        p.reasons
            .iter()
            .any(|r| r.contains("shadow model hard; 3 area light(s) act as point lights")),
        "{p}"
    );
}
