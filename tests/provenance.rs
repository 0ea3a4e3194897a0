//! Provenance: every image `voxlab render` writes carries what made it (the resolved
//! experiment with its overrides, revision, backend, settings, plan, timings), in the
//! PNG's iTXt chunk and a JSON sidecar; `render --json` prints the same record; the
//! resolved experiment renders the same image again.

use std::process::Command;

use voxlab::experiment::{Experiment, Override};

#[test]
fn images_carry_what_made_them() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("voxlab-provenance-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("sdf.png");
    let set = [
        "techniques.sdf.softness=2",
        "render.pixel_filter=box",
        "render.spp=3",
    ];
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_voxlab"));
    cmd.args([
        "render",
        "experiments/sdf.toml",
        "--backend",
        "cpu",
        "--width",
        "10",
        "--height",
        "7",
    ]);
    for s in set {
        cmd.args(["--set", s]);
    }
    let run = cmd
        .arg("--json")
        .arg("--out")
        .arg(&out)
        .current_dir(&root)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    // --json: the record alone, one line.
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    let printed: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    let chunk = voxlab::output::read_png_provenance(&out)
        .unwrap()
        .expect("the iTXt chunk");
    let sidecar = std::fs::read_to_string(dir.join("sdf.png.json")).unwrap();
    let stored: serde_json::Value = serde_json::from_str(&chunk).unwrap();
    assert_eq!(
        stored,
        serde_json::from_str::<serde_json::Value>(&sidecar).unwrap()
    );
    assert_eq!(stored, printed);
    assert_eq!(stored["experiment"], "sdf");
    assert_eq!(stored["frames"], 3);
    assert_eq!(stored["pixel_filter"], "box");
    assert_eq!(stored["overrides"].as_array().unwrap().len(), 3);
    assert!(
        stored["plan"]
            .as_str()
            .unwrap()
            .contains("SHADOW_MODEL(sdf)")
    );
    assert!(
        stored["backend"]
            .as_str()
            .unwrap()
            .contains("CPU reference")
    );
    assert_eq!(stored["revision"], voxlab::revision::revision());
    // Every file the experiment read, with its content's hash.
    let sdf = std::fs::read(root.join("experiments/sdf.toml")).unwrap();
    assert_eq!(stored["assets"][0]["path"], "experiments/sdf.toml");
    assert_eq!(
        stored["assets"][0]["blake3"],
        blake3::hash(&sdf).to_hex().as_str()
    );
    // The resolved experiment is the one rendered: the file with its overrides and the
    // command line's size.
    let resolved = stored["resolved_experiment"].as_str().unwrap();
    let again = Experiment::from_str(resolved, "sdf.toml").unwrap();
    let overrides: Vec<Override> = set.iter().map(|s| s.parse().unwrap()).collect();
    let mut expected =
        Experiment::load_with(root.join("experiments/sdf.toml"), &overrides).unwrap();
    (expected.settings.width, expected.settings.height) = (10, 7);
    assert_eq!(again.settings, expected.settings);
    assert_eq!(again.scene, expected.scene);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A record quotes the files as they were read, not as they are when the image is
/// written: an experiment loaded, its file and its mesh then changed on disk (a user
/// editing while a render or a sweep runs, or between `voxlab.load` and a render in
/// Python), renders the scene it read, and its record names that scene and those
/// files' hashes (it re-read the file and hashed the mesh anew, so the record
/// reproduced another image).
#[test]
fn a_record_quotes_the_files_as_they_were_read() {
    let dir = std::env::temp_dir().join(format!("voxlab-provenance-read-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let tet = |s: f64| {
        format!("v 0 0 0\nv {s} 0 0\nv 0 {s} 0\nv 0 0 {s}\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    };
    let file = |yaw: f64| {
        format!(
            "[scene]\nmesh = \"tet.obj\"\nresolution = 8\nmaterial = \"solid\"\n\
             [camera]\nyaw_deg = {yaw}\n[render]\nwidth = 8\nheight = 8\n"
        )
    };
    let (path, mesh) = (dir.join("tet.toml"), dir.join("tet.obj"));
    std::fs::write(&path, file(10.0)).unwrap();
    std::fs::write(&mesh, tet(1.0)).unwrap();
    let set: Vec<Override> = vec!["render.spp=2".parse().unwrap()];
    let read = Experiment::load_with(&path, &set).unwrap();
    let (text_then, mesh_then) = (std::fs::read(&path).unwrap(), std::fs::read(&mesh).unwrap());
    // Changed on disk after it was read.
    std::fs::write(&path, file(70.0)).unwrap();
    std::fs::write(&mesh, tet(2.0)).unwrap();
    let mut session = voxlab::Session::cpu();
    let image = session.render(&read).unwrap();
    let record = image
        .provenance(
            &read,
            &set,
            voxlab::frame::DisplayTransform::default(),
            None,
        )
        .unwrap();
    let hashes: Vec<(String, String)> = record["assets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| {
            (
                a["path"].as_str().unwrap().to_string(),
                a["blake3"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    assert_eq!(
        hashes,
        vec![
            (
                path.display().to_string(),
                blake3::hash(&text_then).to_hex().to_string()
            ),
            (
                mesh.display().to_string(),
                blake3::hash(&mesh_then).to_hex().to_string()
            ),
        ]
    );
    // The resolved experiment is the one rendered (the mesh's voxels come with its
    // path, which now holds another mesh: the camera and settings are what it pins).
    let resolved = record["resolved_experiment"].as_str().unwrap();
    let again = Experiment::from_str(resolved, dir.join("again.toml")).unwrap();
    assert_eq!(again.scene.camera, read.scene.camera);
    assert_eq!(again.settings, read.settings);
    assert_eq!(read.scene.camera.yaw, 10f64.to_radians());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Text parsed without a file (the library's `from_str`, Python's dicts and text) is
/// recorded with its `[scene]`: the record's resolved experiment gave an empty one, so
/// it rendered the seed's 16^3 scene in place of the 8^3 one it claimed to render
/// exactly. Voxels set in memory have no `[scene]` table, and the record says so.
#[test]
fn a_record_of_text_gives_its_scene_and_one_of_voxels_in_memory_says_so() {
    let record = |e: &Experiment, set: &[Override]| {
        let image = voxlab::Session::cpu().render(e).unwrap();
        let r = image
            .provenance(e, set, voxlab::frame::DisplayTransform::default(), None)
            .unwrap();
        (image, r)
    };
    let text = "[scene]\ngenerator = \"seed\"\nsize = 8\n[render]\nwidth = 8\nheight = 8\n";
    let set: Vec<Override> = vec!["scene.voxel_size=0.5".parse().unwrap()];
    for (e, set) in [
        (Experiment::from_str(text, "<text>").unwrap(), vec![]),
        (
            Experiment::from_str_with(text, "<dict>", &set).unwrap(),
            set.clone(),
        ),
    ] {
        assert_eq!(e.source_path, None);
        let (image, r) = record(&e, &set);
        let resolved = r["resolved_experiment"].as_str().unwrap();
        assert!(resolved.contains("size = 8"), "{resolved}");
        let again = Experiment::from_str(resolved, "again.toml").unwrap();
        assert!(
            again.scene.grid == e.scene.grid,
            "the record renders other voxels"
        );
        let (image_again, _) = record(&again, &[]);
        assert_eq!(image_again.radiance(), image.radiance());
        // The text itself is the first input, by its hash.
        assert_eq!(
            r["assets"][0]["blake3"].as_str().unwrap(),
            blake3::hash(text.as_bytes()).to_hex().to_string()
        );
    }
    // The same voxels put in memory: the same [scene]-less record as the seed's own.
    let mut e = Experiment::from_str(text, "<text>").unwrap();
    let (grid, materials) = (e.scene.grid.clone(), e.scene.materials.clone());
    e.set_grid(grid, materials).unwrap();
    let (_, r) = record(&e, &[]);
    let resolved = r["resolved_experiment"].as_str().unwrap();
    assert!(
        resolved.starts_with(
            "# Written by voxlab from an experiment whose voxels were given in memory"
        ),
        "{resolved}"
    );
    let (_, r) = record(&Experiment::seed_default(), &[]);
    let resolved = r["resolved_experiment"].as_str().unwrap();
    assert!(resolved.contains("renders exactly this"), "{resolved}");
}

/// An experiment's description is the reader's, and the written experiment every
/// record quotes keeps it (it was dropped: a record of an ablation point said nothing of
/// what the file said it was for).
#[test]
fn a_record_keeps_the_experiments_description() {
    let text = "description = \"slab \\\"A\\\", sigma swept\\nsecond line\"\n\
                [scene]\nsize = 8\n[render]\nwidth = 4\nheight = 4\n";
    let e = Experiment::from_str(text, "described.toml").unwrap();
    assert_eq!(
        e.description.as_deref(),
        Some("slab \"A\", sigma swept\nsecond line")
    );
    let image = voxlab::Session::cpu().render(&e).unwrap();
    let r = image
        .provenance(&e, &[], voxlab::frame::DisplayTransform::default(), None)
        .unwrap();
    let again =
        Experiment::from_str(r["resolved_experiment"].as_str().unwrap(), "again.toml").unwrap();
    assert_eq!(again.description, e.description);
}

/// A text's record hashes its assets, and a parse that reuses a [`SceneCache`]'s voxels
/// reuses the hashes taken when they were read (a viewer's edits and a sweep's points
/// re-parse the text: a large mesh was read and hashed again for each). Its voxels and
/// its hashes are then of the same file, even after the file changed.
#[test]
fn a_text_records_its_assets_as_read_and_a_cached_parse_reuses_them() {
    let dir = std::env::temp_dir().join(format!("voxlab-provenance-assets-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mesh = dir.join("tet.obj");
    let tet = |s: f64| {
        format!("v 0 0 0\nv {s} 0 0\nv 0 {s} 0\nv 0 0 {s}\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    };
    std::fs::write(&mesh, tet(1.0)).unwrap();
    let hash_then = blake3::hash(tet(1.0).as_bytes()).to_hex().to_string();
    let text = format!(
        "[scene]\nmesh = {:?}\nresolution = 4\nmaterial = \"solid\"\n",
        mesh.display().to_string()
    );
    let hashes = |e: &Experiment| -> Vec<String> {
        e.source_record
            .as_ref()
            .unwrap()
            .inputs
            .iter()
            .map(|i| i["blake3"].as_str().unwrap().to_string())
            .collect()
    };
    let text_hash = blake3::hash(text.as_bytes()).to_hex().to_string();
    let want = vec![text_hash.clone(), hash_then.clone()];
    assert_eq!(
        hashes(&Experiment::from_str(&text, "<text>").unwrap()),
        want
    );
    let mut cache = voxlab::experiment::SceneCache::new();
    let first = Experiment::from_str_cached(&text, "<text>", &mut cache).unwrap();
    assert_eq!(hashes(&first), want);
    std::fs::write(&mesh, tet(2.0)).unwrap();
    let set: Vec<Override> = vec!["render.spp=2".parse().unwrap()];
    let again = Experiment::from_str_with_cache(&text, "<text>", &set, &mut cache).unwrap();
    assert_eq!(cache.hits(), 2, "the voxels came from the cache");
    assert!(again.scene.grid == first.scene.grid);
    assert_eq!(
        hashes(&again),
        want,
        "the hashes are of the voxels' file as read"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--display srgb` and `--exposure`: the PNG holds the sRGB encoding of 2^EV times the
/// radiance the EXR holds, and the record says so.
#[test]
fn display_and_exposure_shape_the_png_only() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = std::env::temp_dir().join(format!("voxlab-display-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let render = |out: &str, extra: &[&str]| {
        let run = Command::new(env!("CARGO_BIN_EXE_voxlab"))
            .args([
                "render",
                "experiments/baseline.toml",
                "--backend",
                "cpu",
                "--width",
                "12",
                "--height",
                "9",
            ])
            .args(extra)
            .arg("--out")
            .arg(dir.join(out))
            .current_dir(&root)
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
    };
    render("r.exr", &[]);
    render("s.png", &["--display", "srgb", "--exposure", "1.5"]);
    let radiance = voxlab::output::read_exr(dir.join("r.exr")).unwrap();
    let png = voxlab::output::read_png(dir.join("s.png")).unwrap();
    let scale = 2f32.powf(1.5);
    for (r, p) in radiance.pixels.iter().zip(&png.pixels) {
        for c in 0..3 {
            let want = voxlab::frame::srgb_encode((r[c] * scale).clamp(0.0, 1.0));
            assert!(
                (p[c] - want).abs() <= 0.5 / 255.0 + 1e-6,
                "{} against {want}",
                p[c]
            );
        }
    }
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("s.png.json")).unwrap()).unwrap();
    assert_eq!(
        (record["display"].as_str(), record["exposure"].as_f64()),
        (Some("srgb"), Some(1.5))
    );
    let bad = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["render", "experiments/baseline.toml", "--exposure", "nan"])
        .current_dir(&root)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The revision a binary records is the one it was built from, read when `build.rs`
/// ran: the binary, run where git cannot be found and outside the checkout, names the
/// checkout's HEAD (with `-dirty` exactly when the sources that make it differ).
#[test]
fn the_revision_is_the_builds_not_the_checkouts_at_run_time() {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let git = |args: &[&str]| {
        let out = Command::new("git")
            .arg("-C")
            .arg(&root)
            .args(args)
            .output()
            .expect("the test suite runs in a git checkout with git");
        assert!(out.status.success(), "git {args:?}");
        String::from_utf8(out.stdout).unwrap().trim().to_string()
    };
    let head = git(&["rev-parse", "HEAD"]);
    let dirty = !git(&[
        "status",
        "--porcelain",
        "--untracked-files=no",
        "--",
        "src",
        "shaders",
        "build.rs",
        "Cargo.toml",
        "Cargo.lock",
    ])
    .is_empty();
    let want = if dirty { format!("{head}-dirty") } else { head };
    assert_eq!(voxlab::revision::revision(), want);

    let dir = std::env::temp_dir().join(format!("voxlab-revision-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("probe.toml"), "[scene]\nsize = 4\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .current_dir(&dir)
        .env("PATH", "")
        .args(["render", "probe.toml", "--backend", "cpu"])
        .args(["--width", "4", "--height", "4", "--json"])
        .args(["--out", "seed.png"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    let record: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(record["revision"], want.as_str());
}
