//! Cone features in whole images: composition of every cone variant, the baseline when
//! they are off, GPU against the CPU reference, vanishing cones against the hard
//! shadow, and cone soft shadows against the converged stochastic area light.

mod common;

use common::{display, experiment, golden_dir, linear, rmse, tracer};

use voxlab::experiment::Experiment;
use voxlab::gpu::{GpuTracer, compose_shader};
use voxlab::output::read_png;
use voxlab::plan::Plan;
use voxlab::{Frame, RenderSettings};

fn small(e: &mut Experiment, side: u32) {
    e.settings.width = side;
    e.settings.height = side;
}

#[test]
fn every_cone_variant_composes() {
    // Each combination of the lighting terms and the shadow models that read the
    // pyramids (and the default) with the base flags all off, shadows alone, and all on
    // (see src/plan.rs on why not the full product).
    use voxlab::technique::{LIGHTING_TERMS, SHADOW_MODELS, default_shadow_model};
    let base = Plan::all_variants(9);
    let mut bases = vec![base[0].clone(), base.last().unwrap().clone()];
    let mut shadows = base[0].clone();
    shadows.set_flag("SHADOWS", true);
    bases.push(shadows);
    let models = SHADOW_MODELS
        .iter()
        .copied()
        .filter(|m| m.pyramid || *m == default_shadow_model());
    let layout =
        voxlab::technique::cones::pyramid::PyramidLayout::new(glam::UVec3::new(16, 9, 5), 3);
    let mut composed = 0;
    for b in bases {
        for model in models.clone() {
            for bits in 0..1u32 << LIGHTING_TERMS.len() {
                let mut p = b.clone();
                p.shadow_model = model;
                p.terms = (0..LIGHTING_TERMS.len())
                    .filter(|i| bits & (1 << i) != 0)
                    .map(|i| LIGHTING_TERMS[i])
                    .collect();
                let cones = model.pyramid || p.terms.iter().any(|t| t.pyramid);
                p.pyramid = cones.then_some(layout);
                compose_shader(&p).unwrap_or_else(|e| panic!("{p}: {e}"));
                composed += 1;
            }
        }
    }
    assert_eq!(composed, 3 * 2 * (1 << LIGHTING_TERMS.len()));
}

/// With the features off, cone knobs change nothing: the golden image (tolerance of
/// tests/gpu_golden.rs: at most 0.2 % of pixels off by more than 2/255, mean below
/// 0.5/255), and bit for bit the same image as the untouched baseline.
#[test]
fn cone_features_off_give_the_golden_baseline() {
    let mut gpu = tracer();
    let mut e = experiment("baseline.toml");
    small(&mut e, 128);
    e.settings.max_reflection_depth = 0;
    e.settings.max_refraction_depth = 0;
    let plain = gpu.render(&e.scene, &e.settings).unwrap().frame;
    e.settings.cones = voxlab::render::ConeSettings {
        levels: 3,
        step_factor: 0.25,
        aperture_deg: 30.0,
        start_offset: 2.0,
        ao_cones: 3,
        ao_range: 2.0,
        indirect_strength: 5.0,
    };
    let plan = Plan::new(&e.scene, &e.settings);
    assert!(plan.pyramid.is_none(), "{plan}");
    let knobs = gpu.render(&e.scene, &e.settings).unwrap().frame;
    assert_eq!(plain, knobs);
    let golden = read_png(golden_dir().join("baseline_depth0_128.png")).unwrap();
    let d = display(&knobs, &golden, 2.0 / 255.0);
    assert!(
        d.fraction_over() <= 0.002 && d.mean_abs < 0.5 / 255.0,
        "{d:?}"
    );
}

/// The GPU kernel's cone features against the f64 reference on the seed scene. They
/// differ by f16 pyramid storage, the hardware's filter weights and f32 positions, which
/// move a cone's samples slightly, and by the 0.99 cut-off snapping on one side only:
/// mean |difference| below 2e-3 and at most 1 % of pixels beyond 0.02 (linear values).
#[test]
fn gpu_cone_images_match_the_cpu_reference() {
    let mut gpu = tracer();
    for (file, side) in [
        ("cone_shadows.toml", 64),
        ("ambient_occlusion.toml", 64),
        ("indirect.toml", 48),
    ] {
        let mut e = experiment(file);
        small(&mut e, side);
        let g = gpu.render(&e.scene, &e.settings).unwrap().frame;
        let c = voxlab::cpu::render(&e.scene, &e.settings).frame;
        let d = linear(&g, &c, 0.02);
        println!("{file}: {d:?}");
        assert!(g.all_finite());
        assert!(
            d.mean_abs < 2e-3 && d.fraction_over() <= 0.01,
            "{file}: GPU against CPU {d:?}"
        );
    }
}

fn hard_and_cone(gpu: &mut GpuTracer, e: &Experiment, deg: f64) -> (Frame, Frame) {
    let hard = gpu.render(&e.scene, &e.settings).unwrap().frame;
    let mut s: RenderSettings = e.settings.clone();
    s.features.shadow_model = &voxlab::technique::cone::MODEL;
    s.cones.aperture_deg = deg;
    (hard, gpu.render(&e.scene, &s).unwrap().frame)
}

/// As the point lights' cone aperture shrinks the cone-shadow image approaches the
/// hard-shadow image: the RMSE falls at each of five apertures (40 to 2.5 degrees).
/// It does not reach 0: a one-voxel cone still samples trilinearly filtered opacity.
#[test]
fn vanishing_cones_approach_the_hard_shadow_image() {
    let mut gpu = tracer();
    let mut e = experiment("baseline.toml");
    small(&mut e, 96);
    let mut errs = Vec::new();
    for deg in [40.0, 20.0, 10.0, 5.0, 2.5] {
        let (hard, cone) = hard_and_cone(&mut gpu, &e, deg);
        errs.push((deg, rmse(&cone, &hard)));
    }
    println!("aperture (deg), RMSE against the hard-shadow image: {errs:?}");
    for w in errs.windows(2) {
        assert!(w[1].1 < w[0].1, "RMSE did not fall: {errs:?}");
    }
}

/// Cone soft shadows of the rectangle light of experiments/area_lights.toml against the
/// converged stochastic image of the same light alone (CPU reference, 4096 samples per
/// pixel), 48x48, primary hits only so the shadows are what differs. The cone's
/// RMSE is bounded (measured 0.0099 on lavapipe, hard shadow 0.0114; bound 0.015) and
/// below the
/// hard shadow's (the light as a point at its centre).
#[test]
fn cone_soft_shadows_against_the_converged_area_light() {
    let mut gpu = tracer();
    let mut e = experiment("area_lights.toml");
    // The rectangle alone: the point lights would get cones in one image and hard
    // shadows in the other.
    e.scene.lights.truncate(1);
    small(&mut e, 48);
    e.settings.max_reflection_depth = 0;
    e.settings.max_refraction_depth = 0;
    let mut reference = e.settings.clone();
    reference.light_samples = 64;
    reference.spp = 64;
    let truth = voxlab::cpu::render(&e.scene, &reference).frame;
    let mut hard = e.settings.clone();
    hard.features.shadow_model = voxlab::technique::default_shadow_model();
    let hard = gpu.render(&e.scene, &hard).unwrap().frame;
    let mut cone = e.settings.clone();
    cone.features.shadow_model = &voxlab::technique::cone::MODEL;
    let cone = gpu.render(&e.scene, &cone).unwrap().frame;
    let (ec, eh) = (rmse(&cone, &truth), rmse(&hard, &truth));
    println!("RMSE against the converged area light: cone {ec:.4}, hard {eh:.4}");
    assert!(ec < 0.015, "cone soft shadows: RMSE {ec}");
    assert!(ec < eh, "cone {ec} not closer than the hard shadow {eh}");
}
