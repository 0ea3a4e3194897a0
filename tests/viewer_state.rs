//! The viewer's model without a window: the TOML round trip that makes exports exact,
//! the orbit camera, the side feature lists and the adaptive resolution.
#![cfg(feature = "viewer")]

use voxlab::experiment::Experiment;
use voxlab::viewer::state::{AdaptiveScale, SCALES, ShadowModel, SideSettings, scaled_size};
use voxlab::viewer::{Side, ViewOptions, ViewerState, load_state};

fn experiment(name: &str) -> ViewOptions {
    ViewOptions {
        experiment: Some(format!("{}/experiments/{name}", env!("CARGO_MANIFEST_DIR")).into()),
        ..Default::default()
    }
}

fn seed_state() -> ViewerState {
    ViewerState::new(Experiment::seed_default(), None, None).unwrap()
}

#[test]
fn export_parses_to_exactly_what_the_side_renders() {
    let mut s = load_state(&experiment("area_lights.toml")).unwrap();
    s.orbit_degrees(17.25, -8.5).unwrap();
    s.zoom(1.5).unwrap();
    for side in Side::BOTH {
        let rendered = s.rendered(side).as_ref().clone();
        for (spp, w, h) in [(1, 512, 512), (7, 128, 128), (37, 64, 48)] {
            let (text, parsed) = s.export(side, spp, w, h, None).unwrap();
            let mut want = rendered.clone();
            want.settings.spp = spp;
            want.settings.width = w;
            want.settings.height = h;
            assert_eq!(parsed.scene, want.scene, "{side:?} spp {spp}");
            assert_eq!(parsed.settings, want.settings, "{side:?} spp {spp}");
            // And the text itself is what the file on disk will hold.
            let reparsed = Experiment::from_str(&text, "export.toml").unwrap();
            assert_eq!(reparsed.scene, want.scene);
            assert_eq!(reparsed.settings, want.settings);
        }
    }
}

#[test]
fn export_relocates_scene_files_next_to_the_export() {
    // A .vox scene: its path must still resolve from the export's directory.
    let opts = experiment("deer_area_light.toml");
    let mut s = load_state(&opts).unwrap();
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("viewer-state-export");
    std::fs::create_dir_all(&dir).unwrap();
    let (text, parsed) = s.export(Side::Left, 3, 64, 64, Some(&dir)).unwrap();
    let file = dir.join("deer.toml");
    std::fs::write(&file, &text).unwrap();
    let loaded = Experiment::load(&file).unwrap();
    assert_eq!(loaded.scene, parsed.scene);
    assert_eq!(loaded.settings, parsed.settings);
}

#[test]
fn default_sides_compare_the_file_with_a_soft_shadow_model() {
    // An area light in the scene: the right side samples it with Beer-Lambert.
    let s = load_state(&experiment("baseline.toml")).unwrap();
    assert_eq!(ShadowModel::of(&s.sides[0].features), ShadowModel("hard"));
    // The seed has point lights only: cones soften them, sampling would not.
    assert_eq!(ShadowModel::of(&s.sides[1].features), ShadowModel("cone"));
    let mut e = Experiment::load(format!(
        "{}/experiments/area_lights.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    e.settings.features.shadow_model = voxlab::technique::default_shadow_model();
    let s = ViewerState::new(e, None, None).unwrap();
    assert_eq!(ShadowModel::of(&s.sides[1].features), ShadowModel("area"));
    assert_eq!(
        s.sides[1].features.transmittance,
        voxlab::technique::beer_lambert::ID
    );
}

#[test]
fn orbit_turns_clamps_pitch_and_resets() {
    let mut s = seed_state();
    let home = s.base.scene.camera.clone();
    let g = s.generation;
    s.orbit_degrees(10.0, 5.0).unwrap();
    let c = &s.base.scene.camera;
    assert!((c.yaw.to_degrees() - home.yaw.to_degrees() - 10.0).abs() < 1e-6);
    assert!((c.pitch.to_degrees() - home.pitch.to_degrees() - 5.0).abs() < 1e-6);
    assert!(
        s.generation[0] > g[0] && s.generation[1] > g[1],
        "both sides restart"
    );
    s.orbit_degrees(0.0, 500.0).unwrap();
    assert!((s.base.scene.camera.pitch.to_degrees() - 89.0).abs() < 1e-9);
    s.orbit_degrees(-1000.0, -500.0).unwrap();
    let c = &s.base.scene.camera;
    assert!((c.pitch.to_degrees() + 89.0).abs() < 1e-9);
    assert!((0.0..360.0).contains(&c.yaw.to_degrees()));
    // A drag right turns the camera the other way round the target (yaw decreases).
    let before = s.base.scene.camera.yaw;
    s.orbit_pixels(10.0, 0.0).unwrap();
    let after = s.base.scene.camera.yaw;
    let turned = (after - before).to_degrees().rem_euclid(360.0);
    assert!((turned - 356.0).abs() < 1e-6, "turned {turned}");
    s.reset_camera().unwrap();
    assert_eq!(s.base.scene.camera, home);
}

#[test]
fn zoom_moves_closer_and_stays_bounded() {
    let mut s = seed_state();
    let d0 = s.base.scene.camera.distance;
    s.zoom(1.0).unwrap();
    assert!((s.base.scene.camera.distance - 0.9 * d0).abs() < 1e-9);
    s.zoom(-2.0).unwrap();
    assert!(s.base.scene.camera.distance > d0);
    s.zoom(1e6).unwrap();
    let d = s.base.scene.camera.distance;
    assert!(d > 0.0 && d.is_finite(), "zoomed to {d}");
    s.zoom(-1e6).unwrap();
    let d = s.base.scene.camera.distance;
    assert!(d.is_finite() && d <= 1e3 * s.base.scene.grid.width() + 1e-9);
}

/// The limits of a zoom and a turn stop the user's motion; a file's valid camera beyond
/// them (a distance of 1e6 grid widths, a pitch of 90 degrees) is moved from where it
/// is, never to the limit.
#[test]
fn limits_stop_motion_and_never_move_a_files_camera() {
    let mut e = Experiment::seed_default();
    let w = e.scene.grid.width();
    e.scene.camera.distance = 1e6 * w;
    e.scene.camera.pitch = std::f64::consts::FRAC_PI_2;
    let mut s = ViewerState::new(e, None, None).unwrap();
    s.zoom(1.0).unwrap();
    let d = s.base.scene.camera.distance;
    assert!((d - 0.9e6 * w).abs() < 1e-6 * d, "zoomed in to {d}");
    // Further out than the limit does not go (the home camera is one reset away).
    s.zoom(-1.0).unwrap();
    let d = s.base.scene.camera.distance;
    assert!((d - 0.9e6 * w).abs() < 1e-6 * d, "zoomed out to {d}");
    // A yaw turn and a turn further up leave the pole; a turn down leaves it.
    s.orbit_degrees(30.0, 0.0).unwrap();
    assert_eq!(s.base.scene.camera.pitch.to_degrees(), 90.0);
    s.orbit_degrees(0.0, 5.0).unwrap();
    assert_eq!(s.base.scene.camera.pitch.to_degrees(), 90.0);
    s.orbit_degrees(0.0, -5.0).unwrap();
    assert!((s.base.scene.camera.pitch.to_degrees() - 85.0).abs() < 1e-9);
    s.orbit_degrees(0.0, 10.0).unwrap();
    assert!((s.base.scene.camera.pitch.to_degrees() - 89.0).abs() < 1e-9);
}

#[test]
fn side_feature_lists_parse_and_reject_with_the_allowed_items() {
    let mut side = SideSettings::from_settings(&Default::default(), 16);
    side.parse_list("area, beer-lambert,ao,samples=3").unwrap();
    assert!((side.features.shadow_model.name == "area") && side.features.term("ambient_occlusion"));
    assert_eq!(
        side.features.transmittance,
        voxlab::technique::beer_lambert::ID
    );
    assert_eq!(side.light_samples, 3);
    side.parse_list("cone").unwrap();
    assert!(
        (side.features.shadow_model.name == "cone") && side.features.shadow_model.name != "area"
    );
    side.parse_list("ratio,atrous").unwrap();
    assert_eq!(side.features.reconstruction.name, "atrous");
    side.parse_list("none").unwrap();
    assert_eq!(side.features.reconstruction.name, "none");
    let e = side.parse_list("soft").unwrap_err().to_string();
    assert!(
        e.contains("`soft`") && e.contains("beer-lambert") && e.contains("atrous"),
        "{e}"
    );
    let e = side.parse_list("samples=0").unwrap_err().to_string();
    assert!(e.contains("1..=65536"), "{e}");
}

#[test]
fn a_rejected_edit_changes_nothing() {
    let mut s = seed_state();
    let g = s.generation;
    let rendered = s.rendered(Side::Right).clone();
    s.sides[1].light_samples = 0;
    let e = s.commit(&[Side::Right]).unwrap_err().to_string();
    assert!(e.contains("render.light_samples"), "{e}");
    assert_eq!(s.generation, g);
    assert_eq!(s.rendered(Side::Right), &rendered);
}

#[test]
fn adaptive_scale_fits_the_budget_while_moving_and_is_full_when_still() {
    let mut a = AdaptiveScale::default();
    let pixels = 512 * 512;
    assert_eq!(a.scale(pixels, false), 1.0);
    assert_eq!(
        a.scale(pixels, true),
        0.25,
        "a quarter before any measurement"
    );
    // 1000 ns per pixel: 262 ms at full size, so 50 ms needs a scale <= 0.437.
    a.observe(pixels, 262.144);
    let s = a.scale(pixels, true);
    assert_eq!(s, 0.375);
    assert!(SCALES.contains(&s));
    // A fast device goes to full size.
    let mut fast = AdaptiveScale::default();
    fast.observe(pixels, 5.0);
    assert_eq!(fast.scale(pixels, true), 1.0);
    // Off: always full size. Garbage measurements are ignored.
    a.enabled = false;
    assert_eq!(a.scale(pixels, true), 1.0);
    let mut g = AdaptiveScale::default();
    g.observe(0, 10.0);
    g.observe(100, f64::NAN);
    assert_eq!(g.cost_ns_per_pixel(), None);
    assert_eq!(scaled_size(512, 384, 0.375), (192, 144));
    assert_eq!(scaled_size(3, 1, 0.125), (1, 1));
}

#[test]
fn lights_are_added_converted_and_removed_through_the_file_format() {
    use voxlab::scene::{AreaShape, Light};
    use voxlab::viewer::state::LightKind;
    let mut s = seed_state();
    let n = s.base.scene.lights.len();
    let g = s.generation;
    s.add_light(LightKind::Rect).unwrap();
    assert_eq!(s.base.scene.lights.len(), n + 1);
    assert!(s.generation[0] > g[0] && s.generation[1] > g[1]);
    let Light::Area(a) = &s.base.scene.lights[n] else {
        panic!("a rect light was added as {:?}", s.base.scene.lights[n]);
    };
    assert_eq!(
        a.shape,
        AreaShape::Rect {
            width: 4.0,
            height: 4.0
        }
    );
    assert!(
        (a.normal - glam::DVec3::NEG_Y).length() < 1e-12,
        "faces the grid"
    );
    // The side that samples area lights now has one to sample.
    let rendered = s.rendered(voxlab::viewer::Side::Right);
    assert_eq!(rendered.scene.lights, s.base.scene.lights);
    // Converting keeps the light's place, colour, power and extent.
    let disk = LightKind::Disk.convert(&s.base.scene.lights[n], glam::DVec3::ZERO, 1.0);
    let Light::Area(d) = &disk else { panic!() };
    assert_eq!(d.shape, AreaShape::Disk { radius: 2.0 });
    assert_eq!(disk.position(), s.base.scene.lights[n].position());
    assert_eq!(disk.intensity(), s.base.scene.lights[n].intensity());
    let point = LightKind::Point.convert(&disk, glam::DVec3::ZERO, 1.0);
    assert!(matches!(point, Light::Point(_)));
    let back = LightKind::Rect.convert(&point, glam::DVec3::ZERO, 3.0);
    let Light::Area(r) = &back else { panic!() };
    assert_eq!(
        r.shape,
        AreaShape::Rect {
            width: 3.0,
            height: 3.0
        }
    );
    assert!(
        (r.normal + point.position().normalize()).length() < 1e-12,
        "faces `toward`"
    );
    s.remove_light(0).unwrap();
    assert_eq!(s.base.scene.lights.len(), n);
    // Removing every light leaves a scene without lights, not the seed's lights.
    while !s.base.scene.lights.is_empty() {
        s.remove_light(0).unwrap();
    }
    assert!(
        s.rendered(voxlab::viewer::Side::Left)
            .scene
            .lights
            .is_empty()
    );
}

/// `voxlab view --set`: the overrides reach the experiment both sides render and its
/// exports.
#[test]
fn view_takes_overrides() {
    let mut opts = experiment("sdf.toml");
    opts.overrides = ["techniques.sdf.softness=0.25", "render.width=40"]
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    let s = load_state(&opts).unwrap();
    assert_eq!(s.base.settings.width, 40);
    assert_eq!(
        s.base.settings.technique_params.get(
            "sdf",
            voxlab::technique::sdf::MODEL.setting("softness").unwrap()
        ),
        0.25
    );
    opts.overrides = vec!["render.width=0".parse().unwrap()];
    let Err(err) = load_state(&opts) else {
        panic!("render.width = 0 accepted")
    };
    let err = format!("{err:#}");
    assert!(err.contains("--set render.width=0"), "{err}");
}

#[test]
fn the_experiments_spp_caps_the_accumulation_of_both_sides() {
    // area_lights.toml asks for more than one frame: that is the cap.
    let e = Experiment::load(format!(
        "{}/experiments/area_lights.toml",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    assert!(e.settings.spp > 1);
    let s = load_state(&experiment("area_lights.toml")).unwrap();
    for side in Side::BOTH {
        assert_eq!(s.sides[side.index()].max_spp, e.settings.spp);
    }
    // An override too.
    let mut opts = experiment("area_lights.toml");
    opts.overrides = vec!["render.spp=37".parse().unwrap()];
    let s = load_state(&opts).unwrap();
    assert_eq!(s.sides[0].max_spp, 37);
    assert_eq!(s.rendered(Side::Right).settings.spp, 37);
    // Every spp a file takes, up to the largest, is the cap it asks for: the viewer
    // once held any past 4096 at 4096 without a word.
    let most = voxlab::render::MAX_SAMPLES;
    for spp in [4097, most] {
        opts.overrides = vec![format!("render.spp={spp}").parse().unwrap()];
        let s = load_state(&opts).unwrap();
        for side in Side::BOTH {
            assert_eq!(s.sides[side.index()].max_spp, spp);
            assert_eq!(s.rendered(side).settings.spp, spp);
        }
    }
    // The default spp of 1 leaves the viewer's own cap.
    let s = seed_state();
    assert_eq!(s.sides[0].max_spp, voxlab::viewer::state::DEFAULT_VIEW_SPP);
}

/// The default sides are described in one place: `voxlab view --help` and
/// docs/viewer.md both give `DEFAULT_RIGHT_SIDE`'s words, which the test above holds
/// to the behaviour.
#[test]
fn the_documented_default_sides_are_the_code_s() {
    use voxlab::viewer::state::DEFAULT_RIGHT_SIDE;
    let flat = |s: &str| s.split_whitespace().collect::<Vec<_>>().join(" ");
    let docs =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/viewer.md")).unwrap();
    assert!(
        flat(&docs).contains(&format!("the right side is {}.", flat(DEFAULT_RIGHT_SIDE))),
        "docs/viewer.md does not give DEFAULT_RIGHT_SIDE"
    );
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["view", "--help"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    assert!(flat(&help).contains(&flat(DEFAULT_RIGHT_SIDE)), "{help}");
}
