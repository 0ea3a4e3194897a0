//! Every declared number of an experiment file (`voxlab::settings` and the techniques'
//! declarations): the parser accepts exactly the declared range, and a value at each end
//! survives the writer, and opening in the viewer and export, unchanged (egui clamps a
//! value to its widget's range when it shows it: a widget narrower than the file once
//! rendered `vfov_deg = 0.5` as 1).

use std::path::{Path, PathBuf};

use voxlab::experiment::{Experiment, to_toml};
use voxlab::settings::{self, Kind, Setting};

/// A TOML literal of `v` (TOML spells the non-finite values `inf` and `nan`).
fn literal(setting: &Setting, v: f64) -> String {
    match setting.kind {
        Kind::Int { .. } if v.fract() == 0.0 && v.abs() < 9e18 => format!("{}", v as i64),
        _ if v.is_nan() => "nan".to_string(),
        _ if v.is_infinite() => if v > 0.0 { "inf" } else { "-inf" }.to_string(),
        // `{:?}` writes a decimal point or an exponent: a TOML float, shortest round trip.
        _ => format!("{v:?}"),
    }
}

/// The values at the two ends of the declared range that the range holds.
fn ends(setting: &Setting) -> [f64; 2] {
    match setting.kind {
        Kind::Int { min, max } => [min as f64, max as f64],
        Kind::Float {
            min,
            max,
            min_open,
            max_open,
        } => [
            if min_open { min.next_up() } else { min },
            if max_open { max.next_down() } else { max },
        ],
    }
}

/// Values just outside the declared range, and the non-finite ones.
fn outside(setting: &Setting) -> Vec<f64> {
    match setting.kind {
        Kind::Int { min, max } => vec![min as f64 - 1.0, max as f64 + 1.0, 0.5 + min as f64],
        Kind::Float {
            min,
            max,
            min_open,
            max_open,
        } => vec![
            if min_open { min } else { min.next_down() },
            if max_open { max } else { max.next_up() },
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ],
    }
}

/// A file that sets `table`'s `key` to `value` and nothing else it does not need.
fn file_with(table: &str, key: &str, value: &str) -> String {
    match (table, key) {
        ("materials", _) => format!("[[materials]]\nname = \"glass\"\n{key} = {value}\n"),
        ("lights", "intensity") => {
            format!("[[lights]]\ntype = \"point\"\nposition = [1, 2, 3]\nintensity = {value}\n")
        }
        ("lights", "size") => format!(
            "[[lights]]\ntype = \"rect\"\nposition = [1, 2, 3]\nintensity = 1\nsize = [{value}, {value}]\n"
        ),
        ("lights", "radius") => format!(
            "[[lights]]\ntype = \"disk\"\nposition = [1, 2, 3]\nintensity = 1\nradius = {value}\n"
        ),
        ("lights", "rotation_deg") => format!(
            "[[lights]]\ntype = \"rect\"\nposition = [1, 2, 3]\nintensity = 1\nsize = [1, 1]\nrotation_deg = {value}\n"
        ),
        _ => format!("[{table}]\n{key} = {value}\n"),
    }
}

/// Every declared number: the model's tables and the shared technique groups.
fn every_setting() -> Vec<(&'static str, Setting)> {
    let mut all: Vec<(&str, Setting)> = settings::model_settings()
        .into_iter()
        .flat_map(|(table, s)| s.into_iter().map(move |s| (table, s)))
        .collect();
    for g in voxlab::technique::SETTING_GROUPS {
        all.extend(g.settings.iter().map(|f| (g.table, f.setting)));
    }
    assert!(all.len() >= 25, "{} settings", all.len());
    all
}

fn parse(text: &str) -> Result<Experiment, String> {
    Experiment::from_str(text, Path::new("probe.toml")).map_err(|e| e.to_string())
}

/// The experiment written and parsed again.
fn rewritten(e: &Experiment) -> Experiment {
    let text = to_toml(e, &toml::Table::new()).expect("a parsed experiment writes");
    parse(&text).unwrap_or_else(|err| panic!("the written file parses: {err}\n{text}"))
}

#[test]
fn the_parser_accepts_exactly_each_declared_range_and_the_ends_survive_the_writer() {
    for (table, s) in every_setting() {
        for v in ends(&s) {
            let text = file_with(table, s.key, &literal(&s, v));
            let e = parse(&text).unwrap_or_else(|err| {
                panic!("{table}.{} = {v:?} is in its declared range: {err}", s.key)
            });
            assert_eq!(
                rewritten(&e),
                e,
                "{table}.{} = {v:?} does not survive the writer",
                s.key
            );
        }
        for v in outside(&s) {
            let text = file_with(table, s.key, &literal(&s, v));
            let err = parse(&text).expect_err(&format!(
                "{table}.{} = {v:?} is outside its declared range",
                s.key
            ));
            assert!(err.contains(&format!(".{}", s.key)), "{err}");
            assert!(err.starts_with("probe.toml:"), "{err}");
            // Out-of-type values (a float for an integer) get serde's words.
            if v.is_finite() && (v.fract() == 0.0 || matches!(s.kind, Kind::Float { .. })) {
                assert!(
                    err.contains(&s.range_text()),
                    "{err}\nwant {}",
                    s.range_text()
                );
            }
        }
    }
}

#[test]
fn declared_defaults_are_the_defaults_of_the_model() {
    let d = voxlab::RenderSettings::default();
    for f in settings::RENDER {
        assert_eq!((f.get)(&d), f.setting.default, "render.{}", f.key());
        f.setting
            .check(f.setting.default)
            .expect("a default in its range");
    }
    let seed = Experiment::seed_default();
    for f in settings::CAMERA
        .iter()
        .filter(|f| !f.setting.default.is_nan())
    {
        assert_eq!(
            (f.get)(&seed.scene.camera),
            f.setting.default,
            "camera.{}",
            f.key()
        );
    }
}

/// The seed scene with every number of the camera, render settings, the glass material,
/// a rect and a disk light at one end (`end` 0: low, 1: high) of its declared range.
#[cfg(feature = "viewer")]
fn at_the_ends(end: usize) -> String {
    let mut text = String::new();
    let mut table = |name: &str, header: &str, fields: &[Setting], extra: &str| {
        text += &format!("{header}\n{extra}");
        for s in fields
            .iter()
            .filter(|s| !(name == "render" && s.key == "max_depth"))
        {
            // Images stay small: the viewer's state renders nothing here, but the test
            // should not depend on that.
            let v = match (name, s.key) {
                ("render", "width" | "height") => 8.0,
                ("render", "max_reflection_depth" | "max_refraction_depth") => 2.0,
                _ => ends(s)[end],
            };
            text += &format!("{} = {}\n", s.key, literal(s, v));
        }
    };
    let of = |t: &str| {
        settings::model_settings()
            .into_iter()
            .find(|(name, _)| *name == t)
            .map(|(_, s)| s)
            .expect("declared")
    };
    table("camera", "[camera]", &of("camera"), "");
    table(
        "render",
        "[render]",
        &of("render"),
        "pixel_filter = \"gaussian\"\n",
    );
    table(
        "materials",
        "[[materials]]",
        &of("materials"),
        "name = \"glass\"\n",
    );
    let light = |s: &Setting| format!("{} = {}\n", s.key, literal(s, ends(s)[end]));
    let side = literal(&settings::LIGHT_SIDE, ends(&settings::LIGHT_SIDE)[end]);
    text += &format!(
        "[[lights]]\ntype = \"rect\"\nposition = [8, 20, 8]\nsize = [{side}, {side}]\n{}{}",
        light(&settings::LIGHT_INTENSITY),
        light(&settings::LIGHT_ROTATION)
    );
    text += &format!(
        "[[lights]]\ntype = \"disk\"\nposition = [8, 20, 8]\nintensity = 1\n{}",
        light(&settings::LIGHT_RADIUS)
    );
    text
}

/// `got` has `want`'s camera, lights, materials and render settings; the message names
/// the part that differs (a whole scene's Debug holds every voxel).
#[cfg(feature = "viewer")]
fn same_model(got: &Experiment, want: &Experiment, what: &str) {
    let (g, w) = (&got.scene, &want.scene);
    assert_eq!(g.camera, w.camera, "{what}: the camera moved");
    assert_eq!(g.lights, w.lights, "{what}: a light moved");
    assert_eq!(g.materials, w.materials, "{what}: a material moved");
    assert_eq!(
        got.settings, want.settings,
        "{what}: a render setting moved"
    );
    assert!(g == w, "{what}: the scene moved");
}

#[cfg(feature = "viewer")]
#[test]
fn values_at_each_end_survive_opening_in_the_viewer_and_export() {
    use std::sync::mpsc::channel;
    use std::sync::{Arc, Mutex};

    use egui_kittest::Harness;
    use egui_kittest::kittest::Queryable;
    use voxlab::viewer::{Outcome, Side, ViewerApp, ViewerState};

    for end in 0..2 {
        let text = at_the_ends(end);
        let e = parse(&text).unwrap_or_else(|err| panic!("{err}\n{text}"));
        let state = ViewerState::new(e.clone(), Some(&text), None).expect("the viewer opens it");
        let (left, _l) = channel();
        let (right, _r) = channel();
        let (reference, _f) = channel();
        let (_reports, reports_rx) = channel();
        let app = ViewerApp::new(
            state,
            [left, right, reference],
            reports_rx,
            None,
            Arc::new(Mutex::new(Outcome::default())),
        );
        let mut harness = Harness::builder()
            .with_size([1400.0, 2400.0])
            .build_ui_state(|ui, app: &mut ViewerApp| app.show(ui), app);
        harness.run_steps(2);
        // Open every panel that holds a declared number, so each widget is shown.
        for header in ["Materials", "1: glass", "light 1: disk"] {
            harness.get_by_label(header).click();
            harness.run_steps(2);
        }
        for key in ["vfov_deg", "ior", "radius", "filter_width", "rotation_deg"] {
            assert!(
                harness.query_all_by_label(key).next().is_some(),
                "the widget of {key} is shown (end {end})"
            );
        }
        let state = &mut harness.state_mut().state;
        same_model(&state.base, &e, &format!("end {end}: opened in the viewer"));
        let (_, exported) = state
            .export(
                Side::Left,
                e.settings.spp,
                e.settings.width,
                e.settings.height,
                None,
            )
            .expect("exports");
        same_model(&exported, &e, &format!("end {end}: exported"));
    }
}

#[test]
fn the_docs_table_is_the_declarations() {
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/experiments.md"))
        .unwrap();
    let begin = "<!-- settings:begin (voxlab settings --markdown) -->\n";
    let at = page.find(begin).expect("docs/experiments.md has the table") + begin.len();
    let end = page[at..]
        .find("<!-- settings:end -->")
        .expect("end marker");
    assert_eq!(
        &page[at..at + end],
        settings::markdown(),
        "docs/experiments.md's table differs from `voxlab settings --markdown`"
    );
}

/// The file that sets `[scene]`'s `key` to `value`, with the source the key needs: a
/// generator's empty grid (no voxels to fill at the largest sides), a thin triangle for
/// a mesh's resolution (65536 voxels along it, one across), the deer for a model.
fn scene_file(key: &str, value: &str) -> String {
    match key {
        "size" => format!("[scene]\ngenerator = \"empty\"\nsize = {value}\n"),
        "dims" => format!("[scene]\ngenerator = \"empty\"\ndims = [1, {value}, 1]\n"),
        "resolution" => format!("[scene]\nmesh = \"thin.obj\"\nresolution = {value}\n"),
        "model" => format!("[scene]\nvox = \"{}\"\nmodel = {value}\n", deer()),
        _ => format!("[scene]\n{key} = {value}\n"),
    }
}

fn deer() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/data/deer.vox").replace('\\', "/")
}

/// `[scene]`'s and `[ablate]`'s numbers take exactly their declared ranges, and a value
/// outside is refused in the declaration's words under the key's name. The high end of
/// `scene.model` depends on the file's models (the deer has one), so only its low end is
/// accepted here.
#[test]
fn scene_and_ablate_numbers_take_exactly_their_declared_ranges() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("settings-scene");
    std::fs::create_dir_all(&dir).unwrap();
    // One unit long, a millionth across: at resolution 65536 a grid of 65536 x 1 x 1.
    std::fs::write(
        dir.join("thin.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 0.000001 0\nf 1 2 3\n",
    )
    .unwrap();
    let probe = dir.join("probe.toml");
    let all = settings::file_settings();
    let of = |t: &str| {
        all.iter()
            .find(|(name, _)| *name == t)
            .map(|(_, s)| s.clone())
            .expect("declared")
    };
    for s in of("scene") {
        for (i, v) in ends(&s).into_iter().enumerate() {
            if s.key == "model" && i == 1 {
                continue;
            }
            let text = scene_file(s.key, &literal(&s, v));
            Experiment::from_str(&text, &probe)
                .unwrap_or_else(|e| panic!("scene.{} = {v} is in its range: {e}", s.key));
        }
        for v in outside(&s) {
            let text = scene_file(s.key, &literal(&s, v));
            let err = Experiment::from_str(&text, &probe)
                .expect_err(&format!("scene.{} = {v} is outside its range", s.key))
                .to_string();
            assert!(err.contains(&format!("scene.{}", s.key)), "{err}");
            if v.is_finite() && (v.fract() == 0.0 || matches!(s.kind, Kind::Float { .. })) {
                assert!(
                    err.contains(&s.range_text()),
                    "{err}\nwant {}",
                    s.range_text()
                );
            }
        }
    }
    // A one-voxel .vox model (scale 16 fills a 16^3 grid) and the thin triangle
    // (resolution 65536 along a grid as long).
    let mut cube = voxlab::Grid::new(glam::UVec3::ONE, 1.0, glam::DVec3::ZERO).unwrap();
    cube.set(glam::IVec3::ZERO, 1);
    voxlab::scene::write_vox(
        dir.join("one.vox"),
        &cube,
        &voxlab::scene::seed_palette()[1..],
    )
    .unwrap();
    let model_file = |key: &str, value: &str| match key {
        "resolution" => format!(
            "[scene]\ngenerator = \"empty\"\ndims = [65536, 1, 1]\n\
             [[scene.models]]\nmesh = \"thin.obj\"\nmaterial = \"solid\"\nresolution = {value}\n"
        ),
        _ => format!(
            "[scene]\ngenerator = \"empty\"\nsize = 16\n[[scene.models]]\nvox = \"one.vox\"\n{key} = {value}\n"
        ),
    };
    for s in of("scene.models") {
        for (i, v) in ends(&s).into_iter().enumerate() {
            if s.key == "model" && i == 1 {
                continue;
            }
            let text = model_file(s.key, &literal(&s, v));
            Experiment::from_str(&text, &probe)
                .unwrap_or_else(|e| panic!("scene.models.{} = {v} is in its range: {e}", s.key));
        }
        for v in outside(&s) {
            let text = model_file(s.key, &literal(&s, v));
            let err = Experiment::from_str(&text, &probe)
                .expect_err(&format!(
                    "scene.models.{} = {v} is outside its range",
                    s.key
                ))
                .to_string();
            assert!(err.contains(&format!("scene.models[0].{}", s.key)), "{err}");
            if v.is_finite() && v.fract() == 0.0 {
                assert!(
                    err.contains(&s.range_text()),
                    "{err}\nwant {}",
                    s.range_text()
                );
            }
        }
    }
    // The reference takes at least the largest swept count.
    let ablate_file = |key: &str, value: &str| match key {
        "spp" => format!("[ablate]\nreference_spp = 65536\nspp = [{value}]\n"),
        "reference_spp" => format!("[ablate]\nspp = [1]\nreference_spp = {value}\n"),
        _ => format!("[ablate]\n{key} = {value}\n"),
    };
    for s in of("ablate") {
        for v in ends(&s) {
            let text = ablate_file(s.key, &literal(&s, v));
            let c = voxlab::ablate::AblateConfig::from_str(&text, &probe)
                .unwrap_or_else(|e| panic!("ablate.{} = {v} is in its range: {e}", s.key));
            let got = match s.key {
                "reference_spp" => c.reference_spp,
                "spp" => c.spp[0],
                "seeds" => c.seeds,
                "runs" => c.runs,
                "warmup" => c.warmup,
                k => panic!("ablate.{k} is not read here"),
            };
            assert_eq!(f64::from(got), v, "ablate.{}", s.key);
        }
        for v in outside(&s) {
            let text = ablate_file(s.key, &literal(&s, v));
            let err = voxlab::ablate::AblateConfig::from_str(&text, &probe)
                .expect_err(&format!("ablate.{} = {v} is outside its range", s.key))
                .to_string();
            assert!(err.contains(&format!("ablate.{}", s.key)), "{err}");
            if v.fract() == 0.0 {
                assert!(
                    err.contains(&s.range_text()),
                    "{err}\nwant {}",
                    s.range_text()
                );
            }
        }
    }
    // The defaults are the model's.
    let d = voxlab::ablate::AblateConfig::default();
    for s in of("ablate").iter().filter(|s| !s.default.is_nan()) {
        let got = match s.key {
            "reference_spp" => d.reference_spp,
            "seeds" => d.seeds,
            "runs" => d.runs,
            "warmup" => d.warmup,
            k => panic!("ablate.{k}'s default is not read here"),
        };
        assert_eq!(f64::from(got), s.default, "ablate.{}", s.key);
    }
    let seed = Experiment::seed_default();
    let size = of("scene")[0];
    assert_eq!(size.key, "size");
    assert_eq!(f64::from(seed.scene.grid.dims().x), size.default);
    // The dims' doc states the limits it cannot format.
    let side = of("scene")[1];
    assert!(side.doc.contains("2^28") && voxlab::scene::DENSE_MAX_VOXELS == 1 << 28);
    assert!(
        side.doc
            .contains(&voxlab::scene::MAX_SPARSE_SIDE.to_string())
    );
}
