//! What every shadow model (`voxlab::technique::SHADOW_MODELS`) gets without
//! writing a test of its own: its declaration is sound; it is in the experiment files
//! (parsed, written back), the viewer's lists, `voxlab ablate`'s curves and the stress
//! suite; off is the golden baseline; a light of size 0 gives exactly the hard shadow
//! and a vanishing one converges to it; GPU = CPU over image sizes, frames, sample
//! counts and depth limits. The table of docs/techniques.md is the registry's.
//!
//! Tolerances: GPU against CPU those of tests/gpu_agreement.rs (`assert_agree`: fewer
//! than 0.5 % of pixels over 2/255, mean below 1e-3); the vanishing light against the
//! hard shadow: RMSE below 2e-3 of linear radiance at a light of 1e-4 voxels.

mod common;

use common::{assert_agree, assert_matches_golden, experiment, rmse, tracer};
use glam::DVec3;
use voxlab::experiment::{Experiment, write};
use voxlab::plan::Plan;
use voxlab::scene::{AreaLight, AreaShape, Light, Scene, seed_scene};
use voxlab::technique::{self, Kind, SHADOW_MODELS, ShadowModel};
use voxlab::{RenderSettings, cpu};

/// The seed scene at 16^3 with its point lights as rectangle lights of side `size`
/// facing the grid's centre.
fn scene(size: f64) -> Scene {
    scene_at(16, size)
}

/// [`scene`] on the seed scene at `n`^3.
fn scene_at(n: u32, size: f64) -> Scene {
    let mut s = seed_scene(n).unwrap();
    let c = s.grid.centre();
    for l in &mut s.lights {
        let Light::Point(p) = l.clone() else { continue };
        *l = Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Rect {
                width: size,
                height: 0.75 * size,
            },
            position: p.position,
            normal: (c - p.position).normalize(),
            rotation: 0.4,
            color: p.color,
            intensity: p.intensity,
        });
    }
    s
}

fn settings(m: &ShadowModel, side: u32) -> RenderSettings {
    let mut s = RenderSettings {
        width: side,
        height: side,
        light_samples: 4,
        spp: 2,
        ..Default::default()
    };
    assert!(s.features.set_shadow_model(m.name));
    s
}

#[test]
fn declarations_are_sound() {
    let names = technique::shadow_model_names();
    let mut seen = std::collections::HashSet::new();
    for n in &names {
        assert!(seen.insert(*n), "shadow model {n} registered twice");
    }
    let mut titles = std::collections::HashSet::new();
    for m in SHADOW_MODELS {
        assert!(!m.summary.is_empty() && m.summary.len() < 200, "{}", m.name);
        // Every setting reaches the kernel through params.technique, in declared order.
        assert!(
            m.settings.len() <= technique::MAX_GPU_SETTINGS,
            "{}: {} settings, params.technique holds {}",
            m.name,
            m.settings.len(),
            technique::MAX_GPU_SETTINGS
        );
        let mut s = RenderSettings::default();
        for (i, st) in m.settings.iter().enumerate() {
            s.technique_params
                .set(m.name, st.key, st.default + 1.0 + i as f64);
        }
        let packed = m.gpu_settings(&s);
        for (i, st) in m.settings.iter().enumerate() {
            assert_eq!(
                packed[i],
                (st.default + 1.0 + i as f64) as f32,
                "{}.{}",
                m.name,
                st.key
            );
        }
        assert!(packed[m.settings.len()..].iter().all(|&v| v == 0.0));
        // The data's inputs are its own settings, and only a model with data has any.
        for key in m.data_settings {
            assert!(
                m.gpu_data.is_some() && m.settings.iter().any(|st| st.key == *key),
                "{}: data_settings names {key}, not a setting its gpu_data reads",
                m.name
            );
        }
        assert!(
            !m.title.is_empty() && m.title.len() < 40 && titles.insert(m.title),
            "{}: the viewer lists it by a short title of its own",
            m.name
        );
        assert!(
            m.wgsl
                .1
                .contains("#define_import_path voxlab::shadow_model"),
            "{}'s WGSL module must fill the slot voxlab::shadow_model",
            m.name
        );
        assert!(!m.ablate.is_empty(), "{}: no ablation curve", m.name);
        for k in m.shared_settings {
            assert!(
                technique::get_shared(&RenderSettings::default(), k).is_some(),
                "{}: reports cannot read its shared setting {k}",
                m.name
            );
        }
        for curve in m.ablate {
            match curve.knob {
                technique::Knob::Own(key) => assert!(
                    m.setting(key).is_some_and(|s| !s.sweep.is_empty()),
                    "{}: its curve sweeps {key}, which it does not declare with a sweep",
                    m.name
                ),
                technique::Knob::Shared { key, default, .. } => {
                    let s = technique::shared_setting(key)
                        .unwrap_or_else(|| panic!("{}: no shared setting {key}", m.name));
                    for &v in default {
                        assert_eq!(s.check(v), Ok(v), "{}: {key} = {v}", m.name);
                    }
                }
                technique::Knob::Spp | technique::Knob::Transmittance => {}
            }
        }
        for s in m.settings {
            assert_eq!(
                s.check(s.default),
                Ok(s.default),
                "{}.{} default",
                m.name,
                s.key
            );
            for &v in s.sweep {
                assert_eq!(s.check(v), Ok(v), "{}.{} sweep value {v}", m.name, s.key);
            }
            let (lo, hi) = match s.kind {
                Kind::Int { min, max } => (min as f64 - 1.0, max as f64 + 1.0),
                Kind::Float { min, max, .. } => (min - 1.0, max + 1.0),
            };
            assert!(s.check(lo).is_err() && s.check(hi).is_err() && s.check(f64::NAN).is_err());
        }
    }
}

#[test]
fn the_docs_table_is_the_registry() {
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/techniques.md"))
        .unwrap();
    let begin = "<!-- techniques:begin (voxlab techniques --markdown) -->\n";
    let end = "<!-- techniques:end -->";
    let at = page
        .find(begin)
        .expect("docs/techniques.md has the techniques table")
        + begin.len();
    let table = &page[at..at + page[at..].find(end).expect("table end marker")];
    assert_eq!(
        table,
        technique::listing_markdown(),
        "docs/techniques.md's table differs from `voxlab techniques --markdown`"
    );
}

/// Selected by name, with every setting at a value other than its default: parsed,
/// written back and parsed again to the same experiment; a value out of range is an
/// error naming the file, line, key and range.
#[test]
fn experiment_files_take_every_model_and_setting() {
    for m in SHADOW_MODELS {
        let mut text = format!("[features]\nshadow_model = \"{}\"\n", m.name);
        if !m.settings.is_empty() {
            text += &format!("[techniques.{}]\n", m.name);
        }
        for s in m.settings {
            let v = s
                .sweep
                .iter()
                .copied()
                .find(|&v| v != s.default)
                .unwrap_or(s.default);
            text += &format!("{} = {}\n", s.key, s.toml_value(v));
        }
        let e = Experiment::from_str(&text, "x.toml").unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(e.settings.features.shadow_model, *m);
        let written = write::to_toml(&e, &toml::Table::new()).unwrap();
        let again = Experiment::from_str(&written, "x.toml").unwrap();
        assert_eq!(again.settings, e.settings, "{written}");
        for s in m.settings {
            let bad = format!("[techniques.{}]\n{} = 1e300\n", m.name, s.key);
            let err = Experiment::from_str(&bad, "bad.toml")
                .unwrap_err()
                .to_string();
            assert!(
                err.starts_with("bad.toml:2:")
                    && err.contains(&format!("techniques.{}.{}", m.name, s.key))
                    && err.contains(&s.range_text()),
                "{err}"
            );
        }
    }
    let err = Experiment::from_str("[features]\nshadow_model = \"nope\"\n", "n.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("n.toml:2:") && err.contains("hard, area, cone"),
        "{err}"
    );
    // A model's retired switch (`area_lights = true`) is an error at its line that gives
    // the line to write instead, true or false, alone or beside shadow_model; `--set
    // features.shadow_model=X` then works on every file, with one key for the choice.
    let switched: Vec<&ShadowModel> = SHADOW_MODELS
        .iter()
        .copied()
        .filter(|m| m.switch.is_some())
        .collect();
    assert!(!switched.is_empty());
    for m in &switched {
        let key = m.switch.unwrap();
        for (text, says) in [
            (
                format!("[features]\n{key} = true\n"),
                format!("features.shadow_model = \"{}\"", m.name),
            ),
            (
                format!("[features]\nshadow_model = \"hard\"\n{key} = true\n"),
                format!("features.shadow_model = \"{}\"", m.name),
            ),
            (
                format!("[features]\n{key} = false\n"),
                "remove the line".to_string(),
            ),
        ] {
            let err = Experiment::from_str(&text, "s.toml")
                .unwrap_err()
                .to_string();
            let line = text.lines().position(|l| l.starts_with(key)).unwrap() + 1;
            assert!(
                err.starts_with(&format!("s.toml:{line}: features.{key}"))
                    && err.contains("was replaced by")
                    && err.contains(&says),
                "{err}"
            );
        }
        assert!(!technique::feature_keys().contains(&key));
    }
    let err = Experiment::from_str("[techniques.nope]\nx = 1\n", "n.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("n.toml:1:") && err.contains("techniques.nope"),
        "{err}"
    );
}

/// The stress suite and `voxlab ablate`'s points name every model.
#[test]
fn every_model_is_offered_everywhere() {
    let e = Experiment {
        scene: scene(2.0),
        ..Experiment::seed_default()
    };
    let points = voxlab::ablate::points(&e, &voxlab::ablate::AblateConfig::default());
    let cases = voxlab::stress::generated_cases(&voxlab::stress::SuiteOptions::default()).unwrap();
    for m in SHADOW_MODELS {
        assert!(
            points
                .iter()
                .any(|p| p.settings.features.shadow_model == *m),
            "ablate has no curve of {}",
            m.name
        );
        assert!(
            cases.iter().any(|c| c.settings.features.shadow_model == *m),
            "the stress suite has no case of {}",
            m.name
        );
    }
}

/// The viewer's shadow list and its `--left`/`--right` lists offer every model.
#[cfg(feature = "viewer")]
#[test]
fn the_viewer_offers_every_model() {
    let e = Experiment::seed_default();
    for m in SHADOW_MODELS {
        let mut side = voxlab::viewer::state::SideSettings::from_settings(&e.settings, 4);
        side.parse_list(m.name).unwrap();
        assert_eq!(side.features.shadow_model, *m);
        assert!(
            voxlab::viewer::state::ShadowModel::all()
                .contains(&voxlab::viewer::state::ShadowModel(m.name))
        );
    }
}

/// Off: the golden baseline, whatever the models' settings say (GPU).
#[test]
fn off_is_the_golden_baseline() {
    let mut gpu = tracer();
    let mut e = experiment("baseline.toml");
    e.settings.width = 160;
    e.settings.height = 160;
    for m in SHADOW_MODELS {
        for s in m.settings {
            e.settings.technique_params.set(
                m.name,
                s.key,
                s.sweep.first().copied().unwrap_or(s.default),
            );
        }
    }
    let out = gpu.render(&e.scene, &e.settings).unwrap();
    assert_matches_golden("models off", &out.frame, "baseline_160.png");
}

/// A light of size 0 is the hard shadow exactly (CPU, every model that casts shadow
/// rays), and a light of 1e-4 voxels is within the stated RMSE of it. Cones cast none:
/// their visibility is the filtered pyramid's, whose degenerate setting
/// (tests/cone_render.rs, the stress suite's `cones-vanishing`) approaches the hard
/// shadow but does not reach it.
#[test]
fn a_vanishing_light_gives_the_hard_shadow() {
    for m in SHADOW_MODELS.iter().filter(|m| m.shadow_rays) {
        let hard_settings = RenderSettings {
            width: 40,
            height: 40,
            ..Default::default()
        };
        let hard = cpu::render(&scene(0.0), &hard_settings).frame;
        for (size, tol) in [(0.0, 0.0), (1e-4, 2e-3)] {
            let s = scene(size);
            let st = settings(m, 40);
            let img = cpu::render(&s, &st).frame;
            let r = rmse(&hard, &img);
            assert!(
                r <= tol,
                "{} with a light of {size}: RMSE {r} from the hard shadow",
                m.name
            );
        }
    }
}

/// GPU = CPU over image sizes (odd ones included), frames, sample counts, depth limits
/// and light sizes.
#[test]
fn gpu_agrees_with_cpu_over_the_space() {
    let mut gpu = tracer();
    for m in SHADOW_MODELS {
        for (side, spp, samples, depth, size, grid) in [
            (24, 1, 1, 4, 2.0, 16),
            (33, 3, 4, 2, 4.0, 16),
            (16, 64, 1, 1, 3.0, 16),
            (40, 2, 9, 3, 1.0, 16),
            // Deep trees with few samples: lavapipe's loop limit (shaders/counters.wgsl)
            // refuses 6/6 with 9 samples on each of 3 lights.
            (20, 2, 2, 6, 2.0, 16),
            // Grid sizes: odd and small, and larger (the sdf field's lines, longer walks).
            (24, 2, 2, 3, 1.5, 7),
            (24, 2, 2, 3, 6.0, 48),
        ] {
            let s = scene_at(grid, size);
            let mut st = settings(m, side);
            st.spp = spp;
            st.light_samples = samples;
            st.max_reflection_depth = depth;
            st.max_refraction_depth = depth;
            let plan = Plan::new(&s, &st);
            assert_eq!(plan.shadow_model, *m, "{plan}");
            let g = gpu.render(&s, &st).unwrap().frame;
            let c = cpu::render(&s, &st).frame;
            assert_agree(
                &format!(
                    "{} {side}px spp {spp} samples {samples} depth {depth} size {size} grid {grid}",
                    m.name
                ),
                &g,
                &c,
            );
        }
    }
}

/// The kernel of a scene whose model is left out (no lights) composes without it, and
/// the reason is printed.
#[test]
fn the_plan_leaves_a_model_out_with_a_reason() {
    let default = technique::default_shadow_model();
    for m in SHADOW_MODELS.iter().filter(|&&m| m != default) {
        let mut s = scene(2.0);
        s.lights.clear();
        let p = Plan::new(&s, &settings(m, 8));
        assert_eq!(p.shadow_model, default);
        assert!(
            p.to_string().contains(&format!("shadow model {}", m.name)),
            "{p}"
        );
        let p = Plan::new(&scene(2.0), &settings(m, 8));
        assert_eq!(p.shadow_model, *m);
        let defs = p.shader_defs();
        assert!(defs.contains_key("SHADOW_MODEL_ID"), "{p}");
        voxlab::gpu::compose_shader(&p).unwrap();
        let _ = DVec3::ZERO;
    }
}
