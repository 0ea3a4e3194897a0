//! The render plan of the seed scene with every feature off is the baseline kernel:
//! reflection, refraction and shadow rays with a stack of 5 (depth limits 4/4: the
//! chain of reflections' 5 hits, `RenderSettings::ray_stack_size`), nothing else
//! composed in.

use std::path::PathBuf;

use voxlab::experiment::Experiment;
use voxlab::gpu::{compose_shader, validate};
use voxlab::plan::Plan;

fn baseline() -> Experiment {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("experiments/baseline.toml");
    Experiment::load(&p).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn seed_scene_with_features_off_compiles_to_the_baseline_kernel() {
    let e = baseline();
    let plan = Plan::new(&e.scene, &e.settings);
    let on: Vec<&str> = Plan::FLAGS
        .iter()
        .copied()
        .filter(|f| plan.flag(f))
        .collect();
    assert_eq!(on, ["REFLECTION", "REFRACTION", "SHADOWS"], "{plan}");
    assert_eq!(plan.ray_stack_size, 5);
    // The built-in default (what `voxlab` renders) plans the same kernel.
    let d = Experiment::seed_default();
    assert_eq!(
        Plan::new(&d.scene, &d.settings).shader_defs(),
        plan.shader_defs()
    );
    let module = compose_shader(&plan).unwrap();
    validate(&module).unwrap();
}

#[test]
fn switches_that_the_scene_cannot_use_leave_the_baseline_kernel() {
    // Area-light sampling on, but the seed's lights are points: nothing to sample, so
    // the kernel is the baseline's and the plan says why.
    let mut e = baseline();
    let base = Plan::new(&e.scene, &e.settings).shader_defs();
    e.settings.features.shadow_model = &voxlab::technique::area::MODEL;
    e.settings.spp = 8;
    let plan = Plan::new(&e.scene, &e.settings);
    assert_eq!(plan.shader_defs(), base, "{plan}");
    assert!(plan.reasons.iter().any(|r| r.contains("area")), "{plan}");
}
