//! GPU = CPU with identical samples over the space of settings that change how the kernel
//! runs, not only the defaults: frames per dispatch from 1 to 4096 (small images make
//! many frames per dispatch; 128x128 splits a render into several dispatches), light
//! samples 1 to 8, lights of every kind together, every shadow and transmittance model,
//! image sizes from 8x8 to 128x128, both sets of rules and total depth limits, on
//! generated scenes.
//!
//! This is the test that would have caught the images that went wrong only when one
//! dispatch accumulated many frames: Mesa's software driver ends every loop of a SIMD
//! vector of invocations after 65535 iterations in all, and the frames of a dispatch
//! used to be a loop in one invocation (shaders/counters.wgsl).

mod common;

use common::DENSE_WALK;
use common::{assert_agree, tracer};
use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::render::{RenderSettings, Rules, Transmittance, Traversal};
use voxlab::scene::seed::seed_camera;
use voxlab::scene::{AreaLight, AreaShape, Grid, Light, PointLight, Scene, seed_palette};

/// A random scene of `dims`: glass, semi-solid and solid voxels (boxes, so there are
/// faces to shade and shadows to cast) on a solid floor, with `lights` lights of
/// rotating kinds (point, rectangle, disk, sphere) around the grid.
fn random_scene(rng: &mut StdRng, dims: UVec3, lights: usize) -> Scene {
    let mut grid = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
    let d = dims.as_ivec3();
    for x in 0..d.x {
        for z in 0..d.z {
            grid.set(IVec3::new(x, 0, z), 3);
        }
    }
    for _ in 0..4 {
        let lo = IVec3::new(
            rng.random_range(0..d.x),
            rng.random_range(1..d.y),
            rng.random_range(0..d.z),
        );
        let size = IVec3::new(
            rng.random_range(1..4),
            rng.random_range(1..4),
            rng.random_range(1..4),
        );
        let m = rng.random_range(1..4u8);
        for x in lo.x..(lo.x + size.x).min(d.x) {
            for y in lo.y..(lo.y + size.y).min(d.y) {
                for z in lo.z..(lo.z + size.z).min(d.z) {
                    grid.set(IVec3::new(x, y, z), m);
                }
            }
        }
    }
    let c = grid.centre();
    let w = grid.width();
    let mut all = Vec::new();
    for k in 0..lights {
        let position = c + w * DVec3::new(
            rng.random_range(-0.9..0.9),
            rng.random_range(0.5..1.2),
            rng.random_range(-0.9..0.9),
        );
        let color = DVec3::new(
            rng.random_range(0.5..1.0),
            rng.random_range(0.5..1.0),
            rng.random_range(0.5..1.0),
        );
        let intensity = w * w * rng.random_range(0.5..1.5);
        let size = rng.random_range(0.5..3.0);
        let shape = match k % 4 {
            0 => None,
            1 => Some(AreaShape::Rect {
                width: size,
                height: 0.5 * size,
            }),
            2 => Some(AreaShape::Disk { radius: size }),
            _ => Some(AreaShape::Sphere { radius: size }),
        };
        all.push(match shape {
            None => Light::Point(PointLight {
                position,
                color,
                intensity,
            }),
            Some(shape) => Light::Area(AreaLight {
                emission: Default::default(),
                shape,
                position,
                normal: (c - position).normalize(),
                rotation: rng.random_range(0.0..1.0),
                color,
                intensity,
            }),
        });
    }
    Scene {
        grid,
        materials: seed_palette(),
        lights: all,
        camera: seed_camera(c, w),
        ambient: DVec3::new(0.05, 0.075, 0.1),
        mesh: None,
    }
}

struct Case {
    side: u32,
    spp: u32,
    light_samples: u32,
    lights: usize,
    transmittance: Transmittance,
    rules: Rules,
    depth: (u32, u32, Option<u32>),
}

fn run(i: usize, case: &Case, rng: &mut StdRng, gpu: &mut voxlab::gpu::GpuTracer) {
    let dims = UVec3::new(
        rng.random_range(5..10),
        rng.random_range(4..8),
        rng.random_range(5..10),
    );
    let scene = random_scene(rng, dims, case.lights);
    let mut settings = RenderSettings {
        width: case.side,
        height: case.side,
        spp: case.spp,
        light_samples: case.light_samples,
        max_reflection_depth: case.depth.0,
        max_refraction_depth: case.depth.1,
        max_depth: case.depth.2,
        rules: case.rules,
        seed: rng.random_range(0..u32::MAX),
        ..Default::default()
    };
    settings.features.shadow_model = &voxlab::technique::area::MODEL;
    settings.features.transmittance = case.transmittance;
    // Every registered walk.
    for traversal in Traversal::walks() {
        settings.traversal = traversal;
        run_walk(i, case, dims, &scene, &settings, gpu);
    }
}

fn run_walk(
    i: usize,
    case: &Case,
    dims: UVec3,
    scene: &Scene,
    settings: &RenderSettings,
    gpu: &mut voxlab::gpu::GpuTracer,
) {
    let g = gpu.render(scene, settings).expect("GPU render");
    assert_eq!(
        Traversal::Walk(gpu.last_plan().unwrap().traversal),
        settings.traversal
    );
    let c = voxlab::cpu::render(scene, settings);
    let pixels = (case.side * case.side) as u64;
    let per_dispatch = voxlab::gpu::frames_per_dispatch(pixels, case.spp);
    let name = format!(
        "case {i}: {0}x{0}, {1} spp ({per_dispatch} frames per dispatch, {2} dispatches), \
         {3} light samples, {4} lights, {5}, rules {6}, depth {7:?}, grid {dims}, {8} walk",
        case.side,
        case.spp,
        case.spp.div_ceil(per_dispatch),
        case.light_samples,
        case.lights,
        case.transmittance.name(),
        case.rules.name(),
        case.depth,
        settings.traversal.name(),
    );
    let d = assert_agree(&name, &g.frame, &c.frame);
    // Identical samples: the sums agree to float error, not only within the tolerance.
    assert!(d.mean_abs < 2e-4, "{name}: mean |d| {}", d.mean_abs);
}

#[test]
fn gpu_equals_cpu_over_frames_per_dispatch_samples_lights_and_sizes() {
    let mut rng = StdRng::seed_from_u64(13);
    let mut gpu = tracer();
    let models = [
        voxlab::technique::min_kt::ID,
        voxlab::technique::beer_lambert::ID,
    ];
    let mut cases = Vec::new();
    // Frames per dispatch 1 .. 256 at 8x8 (up to 4096 frames fit one dispatch there).
    for (k, spp) in [1u32, 2, 5, 16, 33, 64, 128, 256].into_iter().enumerate() {
        cases.push(Case {
            side: 8,
            spp,
            light_samples: [1, 2, 4, 8][k % 4],
            lights: 1 + k % 4,
            transmittance: models[k % 2],
            rules: Rules::Consistent,
            depth: (4, 4, None),
        });
    }
    // Other sizes, each a different number of frames per dispatch.
    for (k, (side, spp)) in [(16u32, 48u32), (24, 20), (40, 12)].into_iter().enumerate() {
        cases.push(Case {
            side,
            spp,
            light_samples: 3 + k as u32,
            lights: 4,
            transmittance: models[k % 2],
            rules: [Rules::Consistent, Rules::Seed][k % 2],
            depth: [(4, 4, None), (3, 2, Some(3)), (2, 4, Some(4))][k],
        });
    }
    // 128x128: 64 frames per dispatch, so 70 frames take two dispatches.
    cases.push(Case {
        side: 128,
        spp: 70,
        light_samples: 1,
        lights: 2,
        transmittance: voxlab::technique::min_kt::ID,
        rules: Rules::Consistent,
        depth: (1, 1, None),
    });
    for (i, case) in cases.iter().enumerate() {
        run(i, case, &mut rng, &mut gpu);
    }
}

/// A frame rendered in pieces (the viewer's one frame per batch) equals the same
/// frames in one render (many per dispatch), bit for bit.
#[test]
fn frames_in_pieces_equal_frames_in_one_dispatch() {
    let mut rng = StdRng::seed_from_u64(7);
    let scene = random_scene(&mut rng, UVec3::new(8, 6, 8), 4);
    let mut settings = RenderSettings {
        width: 16,
        height: 16,
        spp: 96,
        light_samples: 4,
        ..Default::default()
    };
    settings.features.shadow_model = &voxlab::technique::area::MODEL;
    let mut gpu = tracer();
    let whole = gpu.render(&scene, &settings).expect("one render").frame;
    let mut pieces = None;
    for f in 0..settings.spp {
        pieces = Some(
            gpu.render_frames(&scene, &settings, f..f + 1)
                .expect("a frame"),
        );
    }
    assert_eq!(pieces.unwrap().frame, whole);
}

/// The steps a walk takes per loop iteration change no image: the same voxels in the
/// same order, on every shadow and transmittance model.
#[test]
fn steps_per_loop_iteration_change_nothing() {
    let mut rng = StdRng::seed_from_u64(11);
    let scene = random_scene(&mut rng, UVec3::new(9, 7, 9), 4);
    let mut gpu = tracer();
    for model in [
        voxlab::technique::min_kt::ID,
        voxlab::technique::beer_lambert::ID,
    ] {
        let mut settings = RenderSettings {
            width: 24,
            height: 24,
            spp: 3,
            light_samples: 2,
            ..Default::default()
        };
        settings.features.shadow_model = &voxlab::technique::area::MODEL;
        settings.features.transmittance = model;
        for traversal in Traversal::walks() {
            settings.traversal = traversal;
            let mut images = Vec::new();
            for n in [1, 2, 4, 8] {
                gpu.set_dda_unroll(n).unwrap();
                images.push(gpu.render(&scene, &settings).expect("GPU").frame);
            }
            for (k, image) in images.iter().enumerate().skip(1) {
                assert_eq!(
                    image,
                    &images[0],
                    "{} {}: unroll index {k}",
                    model.name(),
                    traversal.name()
                );
            }
        }
    }
    assert!(gpu.set_dda_unroll(3).is_err());
}

/// A render the software driver's loop limit cuts at one step per loop iteration is
/// rendered again with more (and right): the seed scene at 256^3 needs it on lavapipe.
/// On a hardware GPU nothing is cut and the first render stands.
#[test]
fn a_cut_render_is_rendered_again_with_more_steps_per_iteration() {
    let scene = voxlab::scene::seed_scene(256).unwrap();
    // The dense walk: the walks that skip take few enough steps that nothing is cut.
    let settings = RenderSettings {
        width: 32,
        height: 32,
        traversal: DENSE_WALK,
        ..Default::default()
    };
    let mut gpu = tracer();
    gpu.set_dda_unroll(1).unwrap();
    let g = gpu
        .render(&scene, &settings)
        .expect("rendered, if need be again");
    let c = voxlab::cpu::render(&scene, &settings);
    assert_agree("seed 256^3 after a retry", &g.frame, &c.frame);
    if gpu.adapter_info().device_type == wgpu::DeviceType::Cpu {
        assert_eq!(
            gpu.dda_unroll(),
            8,
            "lavapipe cuts this scene at one step per iteration"
        );
        // Kept for this grid's walk, not for another grid: a small scene after it
        // starts again from the device's choice.
        gpu.render(&scene, &settings).unwrap();
        assert_eq!(gpu.dda_unroll(), 8);
        let small = voxlab::scene::seed_scene(16).unwrap();
        gpu.render(&small, &settings).unwrap();
        assert_eq!(gpu.dda_unroll(), 1, "the small scene's walks need one step");
        gpu.render(&scene, &settings).unwrap();
        assert_eq!(gpu.dda_unroll(), 8, "raised again for the large one");
    }
}

/// A render that can be stopped (a `Watch`, as the Python bindings give every render)
/// splits its dispatches 16 ways and waits between them: the same image bit for bit, at
/// sizes and frame counts that give one dispatch, several, and one frame per dispatch.
#[test]
fn a_watched_render_equals_an_unwatched_one() {
    use std::sync::Arc;
    use voxlab::progress::{Progress, Watch};
    let mut rng = StdRng::seed_from_u64(19);
    let mut gpu = tracer();
    for (i, (side, spp)) in [(8, 96), (24, 40), (64, 300), (200, 7)]
        .into_iter()
        .enumerate()
    {
        let scene = random_scene(&mut rng, UVec3::new(7, 5, 9), 3);
        let mut settings = RenderSettings {
            width: side,
            height: side * 3 / 4,
            spp,
            light_samples: rng.random_range(1..4),
            ..Default::default()
        };
        settings.features.shadow_model = &voxlab::technique::area::MODEL;
        let plain = gpu.render(&scene, &settings).expect("render").frame;
        let watch = Watch::new();
        gpu.set_progress(Some(Arc::new(Progress::watched(watch.clone(), "frames"))));
        let watched = gpu.render(&scene, &settings).expect("watched render").frame;
        gpu.set_progress(None);
        assert_eq!(watch.done(), (u64::from(spp), u64::from(spp)), "case {i}");
        assert!(
            watched == plain,
            "case {i}: {side}x{} at {spp} frames differs",
            side * 3 / 4
        );
    }
}
