//! Hard and soft shadows agree with the oracle at every depth limit from 0 to 8: point
//! lights under min-kt and beer-lambert, and a rectangle area light (soft shadows).

mod common;

use common::tracer;
use glam::DVec3;
use voxlab::RenderSettings;
use voxlab::scene::{AreaLight, AreaShape, Light, seed_scene};
use voxlab::stress::{StressCase, Verdict, run_case};

#[test]
fn shadows_agree_with_the_oracle_at_every_depth_limit() {
    let mut gpu = tracer();
    let hard = seed_scene(16).unwrap();
    let mut soft = seed_scene(16).unwrap();
    soft.lights.truncate(1);
    soft.lights.push(Light::Area(AreaLight {
        emission: Default::default(),
        shape: AreaShape::Rect {
            width: 8.0,
            height: 5.0,
        },
        position: DVec3::new(8.0, 24.0, 14.0),
        normal: DVec3::new(0.0, -1.0, -0.3),
        rotation: 0.4,
        color: DVec3::new(1.0, 0.9, 0.8),
        intensity: 400.0,
    }));
    for depth in 0..=8u32 {
        for (label, scene, transmittance, area) in [
            ("hard min-kt", &hard, voxlab::technique::min_kt::ID, false),
            (
                "hard beer-lambert",
                &hard,
                voxlab::technique::beer_lambert::ID,
                false,
            ),
            ("soft min-kt", &soft, voxlab::technique::min_kt::ID, true),
        ] {
            let mut settings = RenderSettings {
                width: 16,
                height: 16,
                max_reflection_depth: depth,
                max_refraction_depth: depth,
                light_samples: 4,
                ..Default::default()
            };
            settings.features.transmittance = transmittance;
            settings
                .features
                .set_shadow_model(if area { "area" } else { "hard" });
            let case = StressCase {
                name: format!("{label}, depth {depth}"),
                what: String::new(),
                source: "test".into(),
                scene: scene.clone(),
                settings,
                max_bad: 0.005,
            };
            let row = run_case(Some(&mut gpu), &case);
            assert_eq!(
                row.verdict(),
                Verdict::Pass,
                "{}: {:?}",
                case.name,
                row.verdict()
            );
        }
    }
}
