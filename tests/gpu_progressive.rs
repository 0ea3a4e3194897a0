//! Progressive accumulation across calls (`GpuTracer::render_frames`): an image
//! accumulated in several calls is bit for bit the image of one render with `spp` = the
//! frames accumulated so far, so an interactive viewer can export its state as a
//! `voxlab render` experiment. Continuing anything but the tracer's own previous call
//! (other inputs, another render in between, skipped frames, past the cap) is an error
//! that says why, never a silently wrong image.
//!
//! Bitwise: images are compared by the bits of every f32 channel, no tolerance.
//!
//! Runs on whatever adapter wgpu finds (lavapipe in CI); a missing adapter fails.

mod common;

use std::ops::Range;
use std::time::Duration;

use common::{experiment, tracer};
use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;
use voxlab::plan::Plan;
use voxlab::scene::{AreaLight, AreaShape, Light, Scene, seed_scene};
use voxlab::{Frame, RenderSettings};

/// The seed's scene with its point lights turned into rectangle lights 4 voxels wide,
/// area lights sampled (2 samples per light and frame), 64x48.
fn area_scene(spp: u32) -> (Scene, RenderSettings) {
    let mut scene = seed_scene(16).unwrap();
    let c = scene.grid.centre();
    for l in &mut scene.lights {
        let Light::Point(p) = l.clone() else { continue };
        *l = Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Rect {
                width: 4.0,
                height: 3.0,
            },
            position: p.position,
            normal: (c - p.position).normalize(),
            rotation: 0.4,
            color: p.color,
            intensity: p.intensity,
        });
    }
    let settings = RenderSettings {
        width: 64,
        height: 48,
        light_samples: 2,
        spp,
        seed: 3,
        features: voxlab::Features {
            shadow_model: &voxlab::technique::area::MODEL,
            ..Default::default()
        },
        ..Default::default()
    };
    (scene, settings)
}

/// `soft_coloured_shadows.toml` (a disk light over amber glass with coloured
/// Beer-Lambert absorption) at 64x48.
fn beer_lambert_scene(spp: u32) -> Experiment {
    let mut e = experiment("soft_coloured_shadows.toml");
    e.settings.width = 64;
    e.settings.height = 48;
    e.settings.spp = spp;
    e
}

/// The bits of every channel: equal bits, not merely equal floats.
fn bits(f: &Frame) -> (u32, u32, Vec<[u32; 3]>) {
    (
        f.width,
        f.height,
        f.pixels.iter().map(|p| p.map(f32::to_bits)).collect(),
    )
}

#[track_caller]
fn assert_bitwise(name: &str, a: &Frame, b: &Frame) {
    assert!(a.all_finite(), "{name}: NaN or inf");
    let (wa, ha, pa) = bits(a);
    let (wb, hb, pb) = bits(b);
    assert_eq!((wa, ha), (wb, hb), "{name}: sizes differ");
    let differ = pa.iter().zip(&pb).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{name}: {differ} of {} pixels differ", pa.len());
}

/// `render` with `spp` frames: what `voxlab render` with that spp computes.
fn reference(gpu: &mut GpuTracer, scene: &Scene, settings: &RenderSettings, spp: u32) -> Frame {
    let s = RenderSettings {
        spp,
        ..settings.clone()
    };
    gpu.render(scene, &s).unwrap().frame
}

/// Renders `chunks` in order with render_frames, checking accumulated_frames after
/// each, then checks each partial image against a render with spp = its end.
fn check_chunks(name: &str, scene: &Scene, settings: &RenderSettings, chunks: &[Range<u32>]) {
    let mut gpu = tracer();
    let plan = Plan::new(scene, settings);
    assert!(plan.accumulate, "{name}: {plan}");
    let mut partial = Vec::new();
    for r in chunks {
        let out = gpu
            .render_frames(scene, settings, r.clone())
            .unwrap_or_else(|e| panic!("{name}: frames {r:?}: {e:#}"));
        assert_eq!(gpu.accumulated_frames(), r.end, "{name}: after {r:?}");
        partial.push((r.end, out.frame));
    }
    // The references come after the chunks: any render ends the accumulation.
    for (end, frame) in &partial {
        let want = reference(&mut gpu, scene, settings, *end);
        assert_bitwise(&format!("{name}: frames 0..{end}"), frame, &want);
    }
    assert_eq!(gpu.accumulated_frames(), 0, "{name}: render() ended it");
}

/// The brief's case: chunks 0..3, 3..7, 7..16 of spp 16 give exactly render() with
/// spp 16 (and 3 and 7 on the way); 0..5 is render() with spp 5 (then 5..6, spp 6);
/// one frame per call, too.
#[test]
fn chunks_equal_one_render() {
    let (scene, settings) = area_scene(16);
    check_chunks("area lights", &scene, &settings, &[0..3, 3..7, 7..16]);
    check_chunks("area lights 0..5", &scene, &settings, &[0..5, 5..6]);
    check_chunks(
        "one frame at a time",
        &scene,
        &settings,
        &(0..6).map(|i| i..i + 1).collect::<Vec<_>>(),
    );
}

/// A viewer's settings.spp is a cap far above the frames it has: frames 0..5 (and on to
/// 0..9) under spp 64 are the images of spp 5 and 9. The cap is not part of the sum.
#[test]
fn a_larger_cap_changes_nothing() {
    let (scene, settings) = area_scene(64);
    check_chunks("cap 64", &scene, &settings, &[0..5, 5..9]);
}

/// spp 1 makes a non-accumulating plan (no ACCUMULATE: the kernel writes the frame
/// itself, no sum). Frame 0..1 of an accumulating plan (cap 64) is the same image bit
/// for bit: a sum of one frame with zero compensation, divided by 1 in f64.
#[test]
fn one_accumulated_frame_is_the_non_accumulating_spp_1_image() {
    let mut gpu = tracer();
    let (scene, settings) = area_scene(64);
    let one = gpu.render_frames(&scene, &settings, 0..1).unwrap().frame;
    assert_eq!(gpu.accumulated_frames(), 1);
    let s1 = RenderSettings {
        spp: 1,
        ..settings.clone()
    };
    let plan = Plan::new(&scene, &s1);
    assert!(
        (plan.shadow_model.name == "area") && !plan.accumulate,
        "{plan}"
    );
    let want = gpu.render(&scene, &s1).unwrap().frame;
    assert_bitwise("frames 0..1 of cap 64 against spp 1", &one, &want);
    // And through render_frames with spp 1: only 0..1, not continued.
    let again = gpu.render_frames(&scene, &s1, 0..1).unwrap().frame;
    assert_bitwise("render_frames spp 1", &again, &want);
    assert_eq!(gpu.accumulated_frames(), 0);
}

/// Many frames per call are split over several dispatches, at other boundaries than
/// one render's: 256x128 pixels take 32 frames per dispatch (2^20 pixel-frames), so
/// 0..40 is 32 + 8 and 40..50 one dispatch, where render() of 50 splits 32 + 18.
#[test]
fn chunks_across_dispatches_equal_one_render() {
    let (scene, mut settings) = area_scene(50);
    settings.width = 256;
    settings.height = 128;
    settings.light_samples = 1;
    settings.max_reflection_depth = 1;
    settings.max_refraction_depth = 1;
    check_chunks("256x128", &scene, &settings, &[0..40, 40..50]);
}

/// Beer-Lambert transmittance under a sampled disk light.
#[test]
fn beer_lambert_chunks_equal_one_render() {
    let e = beer_lambert_scene(12);
    assert_eq!(
        e.settings.features.transmittance,
        voxlab::technique::beer_lambert::ID
    );
    let plan = Plan::new(&e.scene, &e.settings);
    assert!(
        plan.transmittance.name == "beer-lambert" && (plan.shadow_model.name == "area"),
        "{plan}"
    );
    check_chunks("beer-lambert", &e.scene, &e.settings, &[0..2, 2..7, 7..12]);
}

/// Ambient occlusion (a cone feature) keeps the area-light samples, so it accumulates
/// with its pyramid bound: chunks equal one render, and the pyramid is built once.
#[test]
fn ambient_occlusion_with_area_lights_chunks_equal_one_render() {
    let (scene, mut settings) = area_scene(10);
    settings.features.set_term("ambient_occlusion", true);
    let plan = Plan::new(&scene, &settings);
    assert!(
        plan.terms.iter().any(|t| t.name == "ambient_occlusion") && plan.pyramid.is_some(),
        "{plan}"
    );
    check_chunks("ambient occlusion", &scene, &settings, &[0..4, 4..10]);

    let mut gpu = tracer();
    gpu.render_frames(&scene, &settings, 0..4).unwrap();
    let builds = gpu.pyramid_builds();
    gpu.render_frames(&scene, &settings, 4..10).unwrap();
    assert_eq!(
        gpu.pyramid_builds(),
        builds,
        "the continuation rebuilt the pyramid"
    );
}

/// Cone shadows replace the area-light samples: the plan does not accumulate, so only
/// frames 0..1 exist (the render() image); more is an error that says so.
#[test]
fn cone_shadows_render_one_frame_only() {
    let mut gpu = tracer();
    let (scene, mut settings) = area_scene(16);
    settings.features.shadow_model = &voxlab::technique::cone::MODEL;
    let plan = Plan::new(&scene, &settings);
    assert!(
        (plan.shadow_model.name == "cone") && !plan.accumulate,
        "{plan}"
    );
    let one = gpu.render_frames(&scene, &settings, 0..1).unwrap().frame;
    assert_eq!(gpu.accumulated_frames(), 0);
    let want = gpu.render(&scene, &settings).unwrap().frame;
    assert_bitwise("cone shadows 0..1", &one, &want);
    for r in [0..2, 1..2, 0..16] {
        let e = gpu
            .render_frames(&scene, &settings, r.clone())
            .expect_err("cone shadows accumulate nothing");
        let msg = format!("{e:#}");
        assert!(
            msg.contains("does not accumulate") && msg.contains("shadow model cone"),
            "{r:?}: {msg}"
        );
    }
}

/// No sampled light: every frame is the same image; 0..1 is render(), 1..2 an error.
#[test]
fn a_deterministic_scene_has_frame_0_only() {
    let mut gpu = tracer();
    let mut e = experiment("baseline.toml");
    e.settings.width = 64;
    e.settings.height = 48;
    for spp in [1, 16] {
        e.settings.spp = spp;
        let plan = Plan::new(&e.scene, &e.settings);
        assert!(!plan.accumulate, "{plan}");
        let one = gpu
            .render_frames(&e.scene, &e.settings, 0..1)
            .unwrap()
            .frame;
        assert_eq!(gpu.accumulated_frames(), 0);
        let want = gpu.render(&e.scene, &e.settings).unwrap().frame;
        assert_bitwise(&format!("baseline spp {spp}"), &one, &want);
        gpu.render_frames(&e.scene, &e.settings, 0..1).unwrap();
        for r in [1..2, 0..2] {
            let err = gpu
                .render_frames(&e.scene, &e.settings, r.clone())
                .expect_err("a deterministic scene has one frame");
            let msg = format!("{err:#}");
            assert!(
                msg.contains("does not accumulate") && msg.contains("frames 0..1"),
                "spp {spp} {r:?}: {msg}"
            );
        }
    }
}

/// The error of `render_frames`, which must mention every one of `words`.
#[track_caller]
fn assert_refused(
    gpu: &mut GpuTracer,
    scene: &Scene,
    settings: &RenderSettings,
    frames: Range<u32>,
    words: &[&str],
) {
    let held = gpu.accumulated_frames();
    let err = match gpu.render_frames(scene, settings, frames.clone()) {
        Ok(_) => panic!("frames {frames:?} continued a wrong accumulation"),
        Err(e) => format!("{e:#}"),
    };
    eprintln!("frames {frames:?}: {err}");
    for w in words {
        assert!(
            err.contains(w),
            "frames {frames:?}: {err:?} does not say {w:?}"
        );
    }
    // A refused call changes nothing on the device: the accumulation stays.
    assert_eq!(gpu.accumulated_frames(), held, "{err}");
}

#[test]
fn wrong_continuations_are_errors_that_say_why() {
    let mut gpu = tracer();
    let (scene, settings) = area_scene(16);

    // Nothing rendered yet.
    assert_refused(&mut gpu, &scene, &settings, 3..5, &["no accumulation"]);
    gpu.render_frames(&scene, &settings, 0..3).unwrap();

    // Past the cap, empty, skipping frames, repeating frames.
    assert_refused(
        &mut gpu,
        &scene,
        &settings,
        3..17,
        &["past the end", "spp = 16"],
    );
    assert_refused(&mut gpu, &scene, &settings, 3..3, &["empty"]);
    assert_refused(
        &mut gpu,
        &scene,
        &settings,
        4..7,
        &["skip frames 3..4", "start at 3"],
    );
    assert_refused(
        &mut gpu,
        &scene,
        &settings,
        2..7,
        &["already accumulated", "start at 3"],
    );

    // Other inputs: a light, a material, the camera, the settings (seed, spp cap, size),
    // the voxels.
    let mut moved = scene.clone();
    if let Light::Area(a) = &mut moved.lights[0] {
        a.intensity *= 1.5;
    }
    assert_refused(
        &mut gpu,
        &moved,
        &settings,
        3..7,
        &["other inputs", "changed: lights"],
    );
    let mut shiny = scene.clone();
    shiny.materials[1].ks += 0.1;
    assert_refused(&mut gpu, &shiny, &settings, 3..7, &["changed: materials"]);
    let mut turned = scene.clone();
    turned.camera.yaw += 0.1;
    assert_refused(&mut gpu, &turned, &settings, 3..7, &["changed: camera"]);
    for other in [
        RenderSettings {
            seed: 4,
            ..settings.clone()
        },
        RenderSettings {
            spp: 32,
            ..settings.clone()
        },
        RenderSettings {
            width: 48,
            ..settings.clone()
        },
    ] {
        assert_refused(
            &mut gpu,
            &scene,
            &other,
            3..7,
            &["changed: render settings"],
        );
    }

    // Every refusal left the accumulation intact: it continues exactly.
    let seven = gpu.render_frames(&scene, &settings, 3..7).unwrap().frame;
    assert_eq!(gpu.accumulated_frames(), 7);

    // The voxels: other voxels are refused before they are uploaded, so the
    // accumulation goes on with the first ones (and is the render of 9 frames).
    let mut carved = scene.clone();
    carved.grid.data_mut()[0] = 0;
    assert_ne!(carved.grid.data(), scene.grid.data());
    assert_refused(&mut gpu, &carved, &settings, 7..9, &["voxel grid"]);
    let nine = gpu.render_frames(&scene, &settings, 7..9).unwrap().frame;
    assert_bitwise(
        "7..9 after other voxels were refused",
        &nine,
        &reference(&mut gpu, &scene, &settings, 9),
    );
    // Another grid's render of its own ends it; coming back to the first does not
    // bring it back.
    gpu.render_frames(&scene, &settings, 0..7).unwrap();
    gpu.render(&carved, &settings).unwrap();
    assert_refused(&mut gpu, &scene, &settings, 7..9, &["no accumulation"]);
    gpu.render_frames(&scene, &settings, 0..7).unwrap();

    // Any other render in between ends it, even of the same scene and settings.
    gpu.render(&scene, &settings).unwrap();
    assert_eq!(gpu.accumulated_frames(), 0);
    assert_refused(
        &mut gpu,
        &scene,
        &settings,
        7..9,
        &["no accumulation", "other render"],
    );
    gpu.render_frames(&scene, &settings, 0..7).unwrap();
    gpu.render_counted(&scene, &settings).unwrap();
    assert_refused(&mut gpu, &scene, &settings, 7..9, &["no accumulation"]);

    // So does a render_frames of other inputs (it starts its own).
    gpu.render_frames(&scene, &settings, 0..7).unwrap();
    gpu.render_frames(&moved, &settings, 0..2).unwrap();
    assert_refused(&mut gpu, &scene, &settings, 7..9, &["changed: lights"]);

    assert_bitwise(
        "0..7 after the refusals",
        &seven,
        &reference(&mut gpu, &scene, &settings, 7),
    );
}

/// Timing covers the frames of the call: a call of one frame after 14 takes far less
/// time than the 14 (the least of three tries each, against load from tests running
/// beside it). The stats of an uncounted render stay zero.
#[test]
fn each_call_times_its_own_frames() {
    let mut gpu = tracer();
    let (scene, settings) = area_scene(16);
    let (mut t_many, mut t_one) = (Duration::MAX, Duration::MAX);
    for _ in 0..3 {
        let many = gpu.render_frames(&scene, &settings, 0..14).unwrap();
        t_many = t_many.min(gpu.last_gpu_time().unwrap_or(many.trace_time));
        let one = gpu.render_frames(&scene, &settings, 14..15).unwrap();
        t_one = t_one.min(gpu.last_gpu_time().unwrap_or(one.trace_time));
        assert_eq!(one.stats, voxlab::RayStats::default());
    }
    eprintln!(
        "14 frames {t_many:?}, 1 frame {t_one:?} ({})",
        gpu.timer_name()
    );
    assert!(
        t_one * 2 < t_many,
        "14 frames {t_many:?}, 1 frame {t_one:?}"
    );
}

/// The triangles a mesh surface traces are an input of the accumulation like the
/// voxels: the same grid with the mesh's normals turned (the voxels unchanged) does not
/// continue it, and neither does the scene without its mesh (drawn as voxels).
#[test]
fn another_mesh_over_the_same_voxels_does_not_continue() {
    let mut gpu = tracer();
    let (area, mut settings) = area_scene(16);
    let mut scene = common::mesh_scene(
        common::icosphere(2)
            .into_iter()
            .map(|t| t.map(|p| p * 5.0 + glam::DVec3::splat(8.0)))
            .collect(),
        vec![],
        area.materials[1].clone(),
        16,
    );
    scene.lights = area.lights.clone();
    settings.surface = common::MESH_SURFACE;
    assert_eq!(
        Plan::new(&scene, &settings).surface.name(),
        "mesh",
        "the scene traces its triangles"
    );
    gpu.render_frames(&scene, &settings, 0..3).unwrap();
    let mut turned = scene.clone();
    let mut mesh = (**turned.mesh.as_ref().expect("a mesh scene")).clone();
    for n in &mut mesh.normals {
        *n = glam::DVec3::new(n.y, n.z, n.x);
    }
    turned.mesh = Some(std::sync::Arc::new(mesh));
    assert_eq!(turned.grid, scene.grid);
    assert_refused(&mut gpu, &turned, &settings, 3..7, &["changed: surface"]);
    let mut bare = scene.clone();
    bare.mesh = None;
    assert_refused(&mut gpu, &bare, &settings, 3..7, &["changed:"]);
    // The accumulation is intact: it continues.
    gpu.render_frames(&scene, &settings, 3..7).unwrap();
}
