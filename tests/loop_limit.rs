//! The software driver's loop limit (shaders/counters.wgsl): a render whose loops it
//! cuts is refused with an error that says so, never returned wrong. Cases that load
//! each kind of loop the tracer has (cone marches and their cones, light samples, the
//! ray tree and its walks) past the limit on lavapipe; on a hardware GPU nothing is cut
//! and every image must agree with the reference.

mod common;

use common::{assert_agree, experiment, tracer};
use voxlab::experiment::Experiment;

fn small(mut e: Experiment, side: u32) -> Experiment {
    e.settings.width = side;
    e.settings.height = side;
    e
}

fn cones(file: &str, step_factor: f64, ao_cones: u32) -> (String, Experiment) {
    let mut e = small(experiment(file), 16);
    e.settings.cones.step_factor = step_factor;
    e.settings.cones.ao_cones = ao_cones;
    (
        format!("{file} step_factor {step_factor} ao_cones {ao_cones}"),
        e,
    )
}

/// Before `loop_guard`, the cone marches of a step of 1e-4 to 5e-4 came back from
/// lavapipe wrong on a third of the pixels with no cut reported: each march loop left
/// only by `break if done`, so Mesa's optimiser took `done` as proven after it and
/// dropped the check that reports the cut.
#[test]
fn a_render_the_loop_limit_cuts_is_refused_never_wrong() {
    let mut cases = vec![
        cones("ambient_occlusion.toml", 1e-4, 8),
        cones("ambient_occlusion.toml", 2e-4, 2),
        cones("ambient_occlusion.toml", 5e-4, 4),
        cones("ambient_occlusion.toml", 2e-4, 5),
        cones("indirect.toml", 1e-4, 8),
        cones("cone_shadows.toml", 1e-4, 8),
    ];
    for file in ["area_lights.toml", "ratio.toml", "solid_angle.toml"] {
        let mut e = small(experiment(file), 12);
        e.settings.light_samples = 512;
        cases.push((format!("{file} light_samples 512"), e));
    }
    for depth in [12, 16] {
        let mut e = small(experiment("baseline.toml"), 16);
        e.settings.max_reflection_depth = depth;
        e.settings.max_refraction_depth = depth;
        cases.push((format!("baseline.toml depth {depth}/{depth}"), e));
    }
    let mut gpu = tracer();
    let mut refused = Vec::new();
    for (name, e) in &cases {
        match gpu.render(&e.scene, &e.settings) {
            Ok(g) => {
                let c = voxlab::cpu::render(&e.scene, &e.settings);
                assert_agree(name, &g.frame, &c.frame);
            }
            Err(err) => {
                let message = format!("{err:#}");
                assert!(
                    message.contains("cut short by the driver"),
                    "{name}: refused for another reason: {message}"
                );
                refused.push(name.clone());
            }
        }
    }
    eprintln!("refused as cut: {refused:?}");
    // The refusal names what would lower the cone case's loops: its march's settings.
    let (_, e) = &cases[0];
    if let Err(err) = gpu.render(&e.scene, &e.settings) {
        let message = format!("{err:#}");
        assert!(
            message.contains("cones.step_factor") && message.contains("cones.ao_cones"),
            "{message}"
        );
    }
    if gpu.adapter_info().device_type == wgpu::DeviceType::Cpu {
        // The cases are meant to reach the limit there: a test none of whose renders is
        // cut would hold nothing against the check.
        assert!(
            refused
                .iter()
                .any(|n| n.starts_with("ambient_occlusion.toml step_factor 0.0001")),
            "lavapipe refused {refused:?}"
        );
    }
}

/// What the refusal offers beyond the depth limits and samples: the settings of the
/// techniques the plan composed, and the shared table they read, nothing for the
/// baseline.
#[test]
fn a_plans_technique_settings_are_those_of_what_it_composed() {
    use voxlab::plan::Plan;
    let settings_of = |file: &str| {
        let e = experiment(file);
        Plan::new(&e.scene, &e.settings).technique_settings()
    };
    assert!(settings_of("baseline.toml").is_empty());
    let ao = settings_of("ambient_occlusion.toml");
    for key in ["cones.ao_cones", "cones.step_factor", "cones.levels"] {
        assert!(ao.contains(&key.to_string()), "{ao:?}");
    }
    let sdf = settings_of("sdf.toml");
    assert!(
        sdf.iter().all(|k| k.starts_with("techniques.sdf.")),
        "{sdf:?}"
    );
    assert!(!sdf.is_empty());
}
