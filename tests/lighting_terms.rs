//! What every lighting term (`voxlab::technique::LIGHTING_TERMS`) gets without a test of
//! its own: it is declared soundly and listed; its switch parses and writes back and its
//! name and short name are in the viewer's lists; the stress suite runs it; off, the
//! golden baseline whatever the cone knobs say; the plan leaves it out, with a reason,
//! where its rule says so (and on a grid held sparse when it reads the pyramids); and
//! GPU = CPU over image sizes, grid sizes, depth limits and with every other term and
//! the cone shadow model beside it.
//!
//! Tolerances: those of tests/gpu_agreement.rs (`assert_agree`).

mod common;

use common::{assert_agree, assert_matches_golden, experiment, tracer};
use voxlab::experiment::{Experiment, write};
use voxlab::plan::Plan;
use voxlab::scene::{Scene, seed_scene};
use voxlab::technique::{self, LIGHTING_TERMS, LightingTerm, Slot};
use voxlab::{RenderSettings, cpu};

fn settings(terms: &[&'static LightingTerm], side: u32) -> RenderSettings {
    let mut s = RenderSettings {
        width: side,
        height: side,
        ..Default::default()
    };
    for t in terms {
        assert!(s.features.set_term(t.name, true));
    }
    s
}

#[test]
fn every_term_is_declared_listed_parsed_and_offered() {
    let listing = technique::listing();
    let cases = voxlab::stress::generated_cases(&voxlab::stress::SuiteOptions::default()).unwrap();
    let mut names = std::collections::HashSet::new();
    for t in LIGHTING_TERMS {
        assert!(names.insert(t.name) && names.insert(t.short) || t.short == t.name);
        assert!(!t.summary.is_empty() && t.summary.len() < 200, "{}", t.name);
        assert!(!t.label.is_empty(), "{}: plans print it", t.name);
        let path = format!("#define_import_path voxlab::term::{}", t.name);
        assert!(t.wgsl.1.contains(&path), "{}: its module is {path}", t.name);
        assert!(
            t.wgsl
                .1
                .contains("fn term(p: vec3<f32>, n: vec3<f32>, s: Material)"),
            "{}: the slot's function",
            t.name
        );
        assert!(!t.radiance_pyramid || t.pyramid, "{}", t.name);
        assert!(
            listing
                .iter()
                .any(|r| r.name == t.name && r.slot == Slot::Lighting),
            "{} not listed",
            t.name
        );
        // The switch parses, writes back, and `false` leaves it off.
        let text = format!("[features]\n{} = true\n", t.name);
        let e = Experiment::from_str(&text, "x.toml").unwrap();
        assert_eq!(e.settings.features.terms, vec![*t]);
        let written = write::to_toml(&e, &toml::Table::new()).unwrap();
        let back = Experiment::from_str(&written, "x.toml").unwrap();
        assert_eq!(back.settings.features, e.settings.features, "{written}");
        let off = Experiment::from_str(&format!("[features]\n{} = false\n", t.name), "x.toml");
        assert!(off.unwrap().settings.features.terms.is_empty());
        let err = Experiment::from_str(&format!("[features]\n{} = 1\n", t.name), "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("bad.toml:2:")
                && err.contains(&format!("features.{}", t.name))
                && err.contains("true or false"),
            "{err}"
        );
        // Both names choose it in the viewer's lists.
        #[cfg(feature = "viewer")]
        for name in [t.name, t.short] {
            let e = Experiment::seed_default();
            let mut side = voxlab::viewer::state::SideSettings::from_settings(&e.settings, 4);
            side.parse_list(name).unwrap();
            assert!(side.features.term(t.name), "{name}");
        }
        assert!(
            cases.iter().any(|c| c.settings.features.term(t.name)),
            "the stress suite has no case of {}",
            t.name
        );
    }
    // Any set of terms keeps the registry's order, whatever order it was switched in.
    let mut f = voxlab::Features::default();
    for t in LIGHTING_TERMS.iter().rev() {
        f.set_term(t.name, true);
    }
    assert_eq!(f.terms, LIGHTING_TERMS.to_vec());
    assert!(!f.set_term("nope", true));
}

/// Off: the golden baseline, whatever the cone knobs say (GPU).
#[test]
fn off_is_the_golden_baseline() {
    let mut gpu = tracer();
    let mut e = experiment("baseline.toml");
    e.settings.width = 160;
    e.settings.height = 160;
    e.settings.cones.ao_cones = 3;
    e.settings.cones.ao_range = 2.0;
    e.settings.cones.indirect_strength = 7.0;
    assert!(Plan::new(&e.scene, &e.settings).terms.is_empty());
    let out = gpu.render(&e.scene, &e.settings).unwrap();
    assert_matches_golden("terms off", &out.frame, "baseline_160.png");
}

/// Where its rule fails the term is left out with a reason naming it, and the kernel
/// composes without it; a term that reads the pyramids is left out of a grid held
/// sparse, and the loader refuses it naming `features`.
#[test]
fn the_plan_leaves_a_term_out_with_a_reason() {
    for t in LIGHTING_TERMS {
        // No diffuse material: every term's rule here is about diffuse reflection.
        let mut s = seed_scene(16).unwrap();
        for m in s.materials.iter_mut() {
            m.kd = 0.0;
        }
        let p = Plan::new(&s, &settings(&[t], 8));
        assert!(p.terms.is_empty(), "{p}");
        assert!(
            p.to_string().contains(&format!("lighting term {}", t.name)),
            "{p}"
        );
        voxlab::gpu::compose_shader(&p).unwrap();
        let p = Plan::new(&seed_scene(16).unwrap(), &settings(&[t], 8));
        assert_eq!(p.terms, vec![*t], "{p}");
        assert!(p.to_string().contains(t.label), "{p}");
        assert_eq!(p.pyramid.is_some(), t.pyramid);
        assert_eq!(p.radiance_pyramid(), t.radiance_pyramid);
        voxlab::gpu::compose_shader(&p).unwrap();
        if t.pyramid {
            let dense = seed_scene(16).unwrap();
            let g = &dense.grid;
            let sparse = Scene {
                grid: voxlab::scene::seed::seed_grid_as(
                    g.dims(),
                    g.voxel_size(),
                    g.origin(),
                    voxlab::scene::Storage::Sparse,
                )
                .unwrap(),
                ..dense.clone()
            };
            assert!(sparse.grid.is_sparse());
            let p = Plan::new(&sparse, &settings(&[t], 8));
            assert!(p.terms.is_empty() && p.pyramid.is_none(), "{p}");
            let err = voxlab::plan::check_sparse_grid(&sparse, &settings(&[t], 8)).unwrap_err();
            assert_eq!(err.0, "features");
            assert!(err.1.contains(&format!("{} = true", t.name)), "{}", err.1);
        }
    }
}

/// GPU = CPU for each term alone, all together, and beside cone shadows, over image
/// sizes (odd ones), grid sizes and depth limits.
#[test]
fn gpu_agrees_with_cpu_over_the_space() {
    let mut gpu = tracer();
    let mut sets: Vec<(String, Vec<&'static LightingTerm>, bool)> = LIGHTING_TERMS
        .iter()
        .map(|t| (t.name.to_string(), vec![*t], false))
        .collect();
    sets.push(("all".into(), LIGHTING_TERMS.to_vec(), false));
    sets.push(("all + cone shadows".into(), LIGHTING_TERMS.to_vec(), true));
    for (name, terms, cone) in &sets {
        for (side, grid, depth) in [(24, 16, 4), (33, 7, 2), (20, 24, 0), (17, 16, 1)] {
            let s = seed_scene(grid).unwrap();
            let mut st = settings(terms, side);
            st.max_reflection_depth = depth;
            st.max_refraction_depth = depth;
            if *cone {
                st.features.shadow_model = &technique::cone::MODEL;
            }
            let plan = Plan::new(&s, &st);
            assert_eq!(&plan.terms, terms, "{plan}");
            let g = gpu.render(&s, &st).unwrap().frame;
            let c = cpu::render(&s, &st).frame;
            assert_agree(
                &format!("{name} {side}px grid {grid} depth {depth}"),
                &g,
                &c,
            );
        }
    }
}

/// Lights that send out nothing (intensity 0, color 0) inject nothing: each term that
/// reads the radiance pyramid is left out with a reason, and the kernel planned for the
/// same scene lit (the term, its pyramid and the shading code composed in, the dark
/// lights injected) renders the same image.
#[test]
fn dark_lights_leave_the_injected_terms_out() {
    let mut gpu = tracer();
    for t in LIGHTING_TERMS.iter().filter(|t| t.radiance_pyramid) {
        let st = settings(&[t], 24);
        let lit = seed_scene(16).unwrap();
        let mut dark = lit.clone();
        for (i, l) in dark.lights.iter_mut().enumerate() {
            match l {
                voxlab::scene::Light::Point(p) if i % 2 == 0 => p.intensity = 0.0,
                voxlab::scene::Light::Point(p) => p.color = glam::DVec3::ZERO,
                voxlab::scene::Light::Area(a) => a.intensity = 0.0,
            }
        }
        let planned = Plan::new(&dark, &st);
        assert!(planned.terms.is_empty() && !planned.shadows, "{planned}");
        assert!(
            planned.to_string().contains("every light dark"),
            "{planned}"
        );
        let full = Plan::new(&lit, &st);
        assert_eq!(full.terms, vec![*t], "{full}");
        let a = gpu.render_plan(&dark, &st, planned).unwrap().frame;
        let b = gpu.render_plan(&dark, &st, full).unwrap().frame;
        let max = common::linear(&a, &b, 0.0).max_abs;
        assert!(
            max <= 1e-6,
            "{}: leaving it out changed the image by {max}",
            t.name
        );
    }
}
