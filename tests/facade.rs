//! The library's facade: one error type that keeps each failure's kind and place, and a
//! session that renders on either tracer with the same image and the record the
//! command line stores.

use std::path::{Path, PathBuf};

use voxlab::{Backend, Error, ErrorKind, Experiment, Session};

fn temp_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn from_text(text: &str) -> Error {
    Experiment::from_str(text, "facade.toml")
        .map(|_| ())
        .map_err(Error::from)
        .expect_err("the text is refused")
}

#[test]
fn every_failure_converts_to_one_error_with_its_kind_and_place() {
    let missing = Experiment::load("no/such/experiment.toml").unwrap_err();
    let e = Error::from(missing);
    assert_eq!(e.kind(), ErrorKind::Io);
    assert_eq!(e.file(), Some("no/such/experiment.toml"));
    assert_eq!(e.line(), None);

    let e = from_text("[render\nwidth = 8\n");
    assert_eq!(e.kind(), ErrorKind::Syntax);
    assert_eq!(e.line(), Some(1));

    let e = from_text("[render]\nwidht = 8\n");
    assert_eq!(e.kind(), ErrorKind::UnknownKey);
    assert_eq!((e.line(), e.key()), (Some(2), Some("render.widht")));
    assert!(e.message().contains("allowed keys here"), "{e}");

    let e = from_text("[camera]\n\npitch_deg = 90.5\n");
    assert_eq!(e.kind(), ErrorKind::Invalid);
    assert_eq!((e.file(), e.line()), (Some("facade.toml"), Some(3)));
    assert_eq!(e.key(), Some("camera.pitch_deg"));
    assert_eq!(
        e.to_string(),
        "facade.toml:3: camera.pitch_deg = 90.5: must be a finite number in [-90, 90] (degrees)"
    );

    // A scene file that is not what its name says.
    let dir = temp_dir("facade_errors");
    let vox = dir.join("not.vox");
    std::fs::write(&vox, "plain text").unwrap();
    let e = Error::from(voxlab::scene::load_vox(&vox, None).unwrap_err());
    assert_eq!(e.kind(), ErrorKind::Scene);
    assert_eq!(e.file(), Some(vox.display().to_string().as_str()));

    // What reports through anyhow keeps a voxlab error's kind inside it.
    let inner = from_text("[render]\nspp = 0\n");
    let e = Error::from(anyhow::Error::new(inner).context("while sweeping"));
    assert_eq!(e.kind(), ErrorKind::Invalid);
    assert_eq!(e.key(), Some("render.spp"));
}

/// The same experiment on both tracers through the facade: the images agree as the
/// GPU = CPU tests require, and each record names its backend.
#[test]
fn one_session_per_backend_renders_the_same_image() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/baseline.toml");
    let overrides = [
        "render.width=24".parse().unwrap(),
        "render.height=16".parse().unwrap(),
    ];
    let e = Experiment::load_with(&path, &overrides).unwrap();
    let mut cpu = Session::new(Backend::Cpu).unwrap();
    let mut gpu = Session::new(Backend::Gpu).expect("the suite needs a GPU adapter (lavapipe)");
    let reference = cpu.render(&e).unwrap();
    // The CPU reference counts its rays (the kernel only when asked: `render_counted`).
    assert_eq!(reference.stats.primary, 24 * 16);
    for _ in 0..2 {
        // The second render reuses the session's pipelines and uploads.
        let image = gpu.render(&e).unwrap();
        assert_eq!((image.width(), image.height()), (24, 16));
        let diff = voxlab::metrics::compare(
            &image.frame,
            &reference.frame,
            voxlab::metrics::Domain::Display,
            2.0 / 255.0,
        )
        .unwrap();
        assert!(diff.pixels_over <= 2, "GPU vs CPU: {diff}");
    }
    let display = voxlab::render::DisplayTransform {
        encoding: voxlab::render::DisplayEncoding::Linear,
        exposure: 0.0,
    };
    let record = reference.provenance(&e, &overrides, display, None).unwrap();
    assert_eq!(record["width"], 24);
    assert_eq!(record["overrides"][0], "render.width=24");
    assert!(
        record["backend"].as_str().unwrap().starts_with("CPU"),
        "{record}"
    );
    // The resolved experiment in the record renders the same experiment again.
    let text = record["resolved_experiment"].as_str().unwrap();
    let again = Experiment::from_str(text, &path).unwrap();
    assert_eq!(again.scene, e.scene);
    assert_eq!(again.settings, e.settings);
}
