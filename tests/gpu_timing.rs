//! The GPU trace is timed on the device by timestamp queries where the adapter has them
//! (lavapipe does): the device time of the trace passes is positive and no longer than
//! the wall time around the same synchronised submissions.

mod common;

use voxlab::RenderSettings;
use voxlab::scene::seed_scene;

#[test]
fn timestamp_queries_time_the_trace_within_its_wall_time() {
    let mut gpu = common::tracer();
    let scene = seed_scene(16).unwrap();
    let settings = RenderSettings {
        width: 96,
        height: 96,
        ..Default::default()
    };
    let out = gpu.render(&scene, &settings).unwrap();
    match gpu.last_gpu_time() {
        Some(t) => {
            assert_eq!(gpu.timer_name(), "timestamp queries");
            println!("device {t:?}, wall {:?}", out.trace_time);
            assert!(!t.is_zero(), "a trace that takes no device time");
            assert!(
                t <= out.trace_time,
                "device {t:?} > wall {:?}",
                out.trace_time
            );
        }
        None => assert_eq!(gpu.timer_name(), "wall time around a synchronised submit"),
    }
    // Several dispatches (accumulated frames split across submissions) add up.
    let mut area = scene.clone();
    area.lights
        .push(voxlab::scene::Light::Area(voxlab::scene::AreaLight {
            emission: Default::default(),
            shape: voxlab::scene::AreaShape::Sphere { radius: 2.0 },
            position: glam::DVec3::new(8.0, 20.0, 12.0),
            normal: glam::DVec3::NEG_Y,
            rotation: 0.0,
            color: glam::DVec3::ONE,
            intensity: 200.0,
        }));
    let s = RenderSettings {
        spp: 4,
        features: voxlab::Features {
            shadow_model: &voxlab::technique::area::MODEL,
            ..Default::default()
        },
        ..settings
    };
    let out = gpu.render(&area, &s).unwrap();
    if let Some(t) = gpu.last_gpu_time() {
        assert!(!t.is_zero() && t <= out.trace_time);
    }
}
