//! `--set KEY=VALUE`: any key of an experiment file overridden from the command line,
//! parsed and checked exactly like the file, errors located at the override.

use std::process::Command;

use voxlab::experiment::{Experiment, Override};

fn root() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn set(list: &[&str]) -> Vec<Override> {
    list.iter().map(|s| s.parse().unwrap()).collect()
}

/// Each kind of key (render, features by a bare word, a plug-in's table, [cones], an
/// entry of [[lights]], camera) gives what editing the file would give.
#[test]
fn overrides_equal_editing_the_file() {
    let path = root().join("experiments/area_lights.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let e = Experiment::from_str_with(
        &text,
        &path,
        &set(&[
            "render.width=40",
            "features.shadow_model=sdf",
            "techniques.sdf.softness=0.5",
            "cones.step_factor=1.5",
            "lights[0].intensity=200",
            "camera.distance=50",
        ]),
    )
    .unwrap();
    let mut expected = Experiment::from_str(&text, &path).unwrap();
    expected.settings.width = 40;
    expected.settings.features.set_shadow_model("sdf");
    expected
        .settings
        .technique_params
        .set("sdf", "softness", 0.5);
    expected.settings.cones.step_factor = 1.5;
    let voxlab::scene::Light::Area(a) = &mut expected.scene.lights[0] else {
        panic!("area_lights.toml's first light is a rectangle")
    };
    a.intensity = 200.0;
    expected.scene.camera.distance = 50.0;
    assert_eq!(e, expected);
    // The last override of a key wins.
    let e =
        Experiment::from_str_with(&text, &path, &set(&["render.spp=3", "render.spp=5"])).unwrap();
    assert_eq!(e.settings.spp, 5);
}

/// A key that gives the grid (or a mesh's voxels) another way replaces the file's: an
/// override of `scene.dims` on a file of `size`, and back; `scene.voxel_size` on a mesh
/// of `resolution`. Both given by overrides are still refused.
#[test]
fn an_alternative_key_replaces_the_files() {
    let load = |file: &str, list: &[&str]| {
        let path = root().join("experiments").join(file);
        let text = std::fs::read_to_string(&path).unwrap();
        Experiment::from_str_with(&text, &path, &set(list))
    };
    let e = load("seed_rules.toml", &["scene.dims=[24, 2, 9]"]).unwrap();
    assert_eq!(e.scene.grid.dims(), glam::UVec3::new(24, 2, 9));
    let e = load("deer_smooth.toml", &["scene.size=60"]).unwrap();
    assert_eq!(e.scene.grid.dims(), glam::UVec3::splat(60));
    let coarse = load("bunny_mesh.toml", &["scene.resolution=12"]).unwrap();
    let by_size = load("bunny_mesh.toml", &["scene.voxel_size=0.05"]).unwrap();
    assert_ne!(coarse.scene.grid.dims(), by_size.scene.grid.dims());
    for both in [
        &["scene.size=4", "scene.dims=[4, 4, 4]"][..],
        &["scene.dims=[4, 4, 4]", "scene.size=4"][..],
    ] {
        let err = load("seed_rules.toml", both).unwrap_err().to_string();
        assert!(err.contains("not both"), "{both:?}: {err}");
    }
    let err = load(
        "bunny_mesh.toml",
        &["scene.voxel_size=0.05", "scene.resolution=8"],
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("not both"), "{err}");
}

#[test]
fn errors_name_the_override() {
    let path = root().join("experiments/baseline.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let err = |list: &[&str]| {
        Experiment::from_str_with(&text, &path, &set(list))
            .unwrap_err()
            .to_string()
    };
    let e = err(&["render.width=0"]);
    assert!(
        e.starts_with("--set render.width=0: render.width") && e.contains("1..=16384"),
        "{e}"
    );
    let e = err(&["techniques.sdf.soft=1"]);
    assert!(
        e.starts_with("--set techniques.sdf.soft=1:") && e.contains("softness"),
        "{e}"
    );
    let e = err(&["features.shadow_model=soft"]);
    assert!(
        e.contains("--set features.shadow_model=soft") && e.contains("hard, area, cone"),
        "{e}"
    );
    let e = err(&["lights[3].intensity=1"]);
    assert!(e.starts_with("--set lights[3].intensity=1:"), "{e}");
    let e = err(&["render=1"]);
    assert!(e.contains("expected a table"), "{e}");
    for bad in [
        "render.width",
        "=3",
        "render..width=1",
        "lights[x].intensity=1",
    ] {
        assert!(bad.parse::<Override>().is_err(), "{bad}");
    }
    // A huge value is cut in the message (as a file's values are): 200 KB of stderr
    // otherwise.
    let huge = format!("render.width=\"{}\"", "w".repeat(200_000));
    let e = err(&[huge.as_str()]);
    assert!(
        e.len() < 2_000 && e.contains("more characters"),
        "{} bytes",
        e.len()
    );
    let huge_key = format!("{}!=1", "k".repeat(200_000));
    let e = huge_key.parse::<Override>().map(|_| ()).unwrap_err();
    assert!(e.len() < 2_000, "{} bytes", e.len());
    // A key too deep to name any setting is refused as the override's fault, not the
    // file's.
    let deep = format!("{}=1", vec!["a"; 5_000].join("."));
    let e = deep.parse::<Override>().map(|_| ()).unwrap_err();
    assert!(e.contains("5000 dotted parts") && e.len() < 500, "{e}");
    // An entry of an array override is the override's too.
    let e = err(&["scene.dims=[4, 2.5, 4]"]);
    assert!(
        e.starts_with("--set scene.dims=[4, 2.5, 4]: scene.dims[1] = 2.5")
            && e.contains("1..=268435456"),
        "{e}"
    );
    // A number 64 bits cannot hold is the number the user wrote, named with its key and
    // range as in a file, not a bare word taken as a string ("invalid type: string").
    for (value, shown, range) in [
        (
            "99999999999999999999",
            "render.width = 99999999999999999999",
            "1..=16384",
        ),
        (
            "9223372036854775808",
            "render.width = 9223372036854775808",
            "1..=16384",
        ),
        (
            "-9223372036854775809",
            "render.width = -9223372036854775809",
            "1..=16384",
        ),
        ("1e400", "render.width = 1e400", "1..=16384"),
        (
            "0xFFFFFFFFFFFFFFFFFFFF",
            "render.width = 0xFFFFFFFFFFFFFFFFFFFF",
            "1..=16384",
        ),
        ("[1, 1e400]", "render.width[1] = 1e400", ""),
    ] {
        let e = err(&[format!("render.width={value}").as_str()]);
        assert!(
            e.starts_with(&format!(
                "--set render.width={value}: {shown}: past what 64 bits hold"
            )) && e.contains(range)
                && !e.contains("string"),
            "{e}"
        );
    }
    let e = err(&["scene.dims=[4, 1e400, 4]"]);
    assert!(
        e.starts_with("--set scene.dims=[4, 1e400, 4]: scene.dims[1] = 1e400: past what 64 bits")
            && e.contains("1..=268435456"),
        "{e}"
    );
    // What is not a number stays a string, and another override that holds the mark's
    // text keeps its own value.
    let e = err(&["render.width=12abc"]);
    assert!(e.contains("invalid type: string \"12abc\""), "{e}");
    let e = err(&["name=voxlab-raw-0", "render.width=1e400"]);
    assert!(
        e.starts_with("--set render.width=1e400: render.width = 1e400"),
        "{e}"
    );
    let ok = Experiment::from_str_with(&text, &path, &set(&["name=voxlab-raw-0"])).unwrap();
    assert_eq!(ok.name, "voxlab-raw-0");
    // The file's own errors keep its line.
    let e = Experiment::from_str_with("[render]\nwidth = -1\n", "f.toml", &set(&["render.spp=2"]))
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("f.toml:2:"), "{e}");
}

#[test]
fn the_command_line_takes_overrides() {
    let out = std::env::temp_dir().join(format!("voxlab-set-{}.png", std::process::id()));
    let run = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args([
            "render",
            "experiments/baseline.toml",
            "--backend",
            "cpu",
            "--set",
        ])
        .args([
            "render.width=12",
            "--set",
            "render.height=8",
            "--set",
            "features.shadow_model=ratio",
        ])
        .arg("--out")
        .arg(&out)
        .current_dir(root())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("image:      12x8"), "{stdout}");
    // The seed's point lights leave the ratio estimator out, and the plan says why.
    assert!(
        stdout.contains("shadow model ratio: no area light"),
        "{stdout}"
    );
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (12, 8));
    let _ = std::fs::remove_file(&out);
    let bad = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args([
            "render",
            "experiments/baseline.toml",
            "--set",
            "render.width=0",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--set render.width=0"));
}

/// Several experiment files in one invocation, on one tracer, each to out/<name>.png,
/// the overrides applied to each; --out with several, or two outputs of one name, are
/// refused before anything renders.
#[test]
fn one_invocation_renders_several_experiments() {
    let dir = std::env::temp_dir().join(format!("voxlab-many-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let exp = |f: &str| root().join("experiments").join(f);
    let run = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .arg("render")
        .args([exp("baseline.toml"), exp("sdf.toml")])
        .args(["--backend", "cpu", "--width", "8", "--height", "6"])
        .args(["--set", "render.spp=1"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert_eq!(stdout.matches("experiment: ").count(), 2, "{stdout}");
    for name in ["baseline", "sdf"] {
        let img = image::open(dir.join("out").join(format!("{name}.png"))).unwrap();
        assert_eq!((img.width(), img.height()), (8, 6));
    }
    for args in [
        vec!["--out".to_string(), dir.join("x.png").display().to_string()],
        vec![exp("baseline.toml").display().to_string()],
    ] {
        let bad = Command::new(env!("CARGO_BIN_EXE_voxlab"))
            .arg("render")
            .args([exp("baseline.toml"), exp("sdf.toml")])
            .args(&args)
            .args(["--backend", "cpu"])
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(!bad.status.success());
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            err.contains("--out names one output") || err.contains("two experiments"),
            "{err}"
        );
        assert!(!String::from_utf8_lossy(&bad.stdout).contains("experiment: "));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// One switch per choice: every shipped experiment takes every registered shadow model
/// by `--set features.shadow_model=NAME` (none uses an older switch that would clash).
#[test]
fn every_shipped_experiment_takes_every_shadow_model_by_set() {
    let mut files: Vec<std::path::PathBuf> = std::fs::read_dir(root().join("experiments"))
        .unwrap()
        .chain(std::fs::read_dir(root().join("experiments/stress")).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 20);
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let mut cache = voxlab::experiment::SceneCache::new();
        for m in voxlab::technique::SHADOW_MODELS {
            let o = set(&[&format!("features.shadow_model={}", m.name)]);
            let e = Experiment::from_str_with_cache(&text, f, &o, &mut cache)
                .unwrap_or_else(|e| panic!("{}: {}: {e}", f.display(), m.name));
            assert_eq!(
                e.settings.features.shadow_model.name,
                m.name,
                "{}",
                f.display()
            );
        }
    }
}
