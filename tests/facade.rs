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
    let display = voxlab::frame::DisplayTransform {
        encoding: voxlab::frame::DisplayEncoding::Linear,
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

/// A thread that stops `watch`'s render once it has started (reported some progress).
fn stop_once_started(
    watch: &std::sync::Arc<voxlab::progress::Watch>,
) -> std::thread::JoinHandle<()> {
    let watch = watch.clone();
    std::thread::spawn(move || {
        while watch.done().1 == 0 {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        watch.stop();
    })
}

/// A watched render stopped from another thread ends with `Interrupted` and no image,
/// on both tracers, and the session renders again afterwards.
#[test]
fn a_watched_render_stops_on_request_and_the_session_goes_on() {
    use voxlab::progress::Watch;
    let mut e = Experiment::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/area_lights.toml"
    ))
    .unwrap();
    (e.settings.width, e.settings.height, e.settings.spp) = (64, 64, 256);
    for backend in [Backend::Cpu, Backend::Gpu] {
        let mut session = Session::new(backend).expect("the suite needs a GPU adapter");
        let watch = Watch::new();
        let stopper = stop_once_started(&watch);
        let err = session.render_watched(&e, &watch).unwrap_err();
        stopper.join().unwrap();
        // More passes than a timestamp query set holds (4096 frames at 256x256, one
        // frame per dispatch when watched): timed by the wall clock, never a panic. (The
        // CPU reference would take minutes to report its first row of it.)
        if backend == Backend::Gpu {
            let mut many = e.clone();
            (many.settings.width, many.settings.height, many.settings.spp) = (256, 256, 4096);
            let big = Watch::new();
            let stopper_big = stop_once_started(&big);
            let stopped = session.render_watched(&many, &big).unwrap_err();
            stopper_big.join().unwrap();
            assert_eq!(
                stopped.kind(),
                ErrorKind::Interrupted,
                "{backend:?}: {stopped}"
            );
        }
        assert_eq!(err.kind(), ErrorKind::Interrupted, "{backend:?}: {err}");
        let (done, total) = watch.done();
        assert!(done < total, "{backend:?}: stopped after {done} of {total}");
        // Nothing of the stopped render survives into the next.
        let mut small = e.clone();
        (
            small.settings.width,
            small.settings.height,
            small.settings.spp,
        ) = (8, 8, 2);
        let watch = Watch::new();
        let image = session.render_watched(&small, &watch).unwrap();
        assert_eq!(watch.done().0, watch.done().1);
        let again = session.render(&small).unwrap();
        assert_eq!(image.frame.pixels, again.frame.pixels, "{backend:?}");
    }
}

/// `Experiment::set_grid`: what the file left to the seed follows the new grid, what it
/// set stays; a palette that does not cover the voxels is refused.
#[test]
fn a_grid_of_ones_own_replaces_the_scene() {
    use glam::{DVec3, UVec3};
    use voxlab::scene::seed::{seed_camera, seed_lights};
    let mut grid = voxlab::Grid::new(UVec3::new(4, 2, 6), 0.5, DVec3::new(1.0, 0.0, -2.0)).unwrap();
    grid.set(glam::IVec3::new(1, 0, 1), 3);
    let mut e = Experiment::seed_default();
    e.set_grid(grid.clone(), voxlab::scene::seed_palette())
        .unwrap();
    let (c, w) = (grid.centre(), grid.width());
    assert_eq!(e.scene.camera.target, c);
    assert_eq!(e.scene.camera.distance, seed_camera(c, w).distance);
    assert_eq!(e.scene.lights, seed_lights(c, w));
    assert!(e.source_path.is_none());

    let mut set = Experiment::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/area_lights.toml"
    ))
    .unwrap();
    let lights = set.scene.lights.clone();
    set.set_grid(grid.clone(), voxlab::scene::seed_palette())
        .unwrap();
    assert_eq!(set.scene.lights, lights, "the file's lights stay");
    assert!(set.source_path.is_none());

    let err = e
        .set_grid(grid, voxlab::scene::seed_palette()[..2].to_vec())
        .unwrap_err();
    assert_eq!(err.kind(), ErrorKind::Scene);
    assert!(err.to_string().contains("material 3"), "{err}");
}

/// A palette from `[[materials]]` alone: entry i is material i + 1, checked as a file's.
#[test]
fn a_palette_from_materials_tables() {
    let p = voxlab::experiment::palette_from_str(
        "[[materials]]\nname = \"a\"\nkd = 0.5\n[[materials]]\nname = \"b\"\nkr = 1.0\n",
        "palette",
    )
    .unwrap();
    let names: Vec<&str> = p.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["void", "a", "b"]);
    assert_eq!((p[1].kd, p[2].kr), (0.5, 1.0));
    let err = Error::from(
        voxlab::experiment::palette_from_str("[[materials]]\nname = \"a\"\nkd = -1\n", "palette")
            .unwrap_err(),
    );
    assert_eq!(err.key(), Some("materials[0].kd"));
    assert_eq!(err.line(), Some(3));
    let err = Error::from(
        voxlab::experiment::palette_from_str("[[materials]]\nname = \"void\"\n", "p").unwrap_err(),
    );
    assert!(err.to_string().contains("void"), "{err}");
}

/// `voxlab techniques --json`'s records carry every setting `--markdown` lists, with
/// its declared type and range.
#[test]
fn the_technique_records_match_the_listing() {
    let records = voxlab::technique::listing_json();
    let rows = voxlab::technique::listing();
    let records = records.as_array().unwrap();
    assert_eq!(records.len(), rows.len());
    for (r, row) in records.iter().zip(&rows) {
        assert_eq!(r["name"], row.name);
        assert_eq!(r["slot"], row.slot.name());
        let keys: Vec<&str> = r["settings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s["key"].as_str().unwrap())
            .collect();
        assert_eq!(
            keys,
            row.settings.iter().map(String::as_str).collect::<Vec<_>>()
        );
    }
    let area = records.iter().find(|r| r["name"] == "area").unwrap();
    let samples = area["settings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["key"] == "render.light_samples")
        .unwrap();
    assert_eq!(samples["type"], "int");
    assert_eq!(samples["min"], 1.0);
}

/// `Session::render_frames` refines an image in ranges of its accumulation: on either
/// backend the ranges end at the image of one render of that many frames, and a range
/// that is empty, past the accumulation's end, or (on the GPU) skips frames is refused
/// with an error of kind Invalid or Device that names the range.
#[test]
fn frames_in_ranges_give_the_image_of_one_render() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/area_lights.toml");
    let overrides = [
        "render.width=16".parse().unwrap(),
        "render.height=12".parse().unwrap(),
        "render.spp=4".parse().unwrap(),
    ];
    let e = Experiment::load_with(&path, &overrides).unwrap();
    let mut gpu = Session::new(Backend::Gpu).expect("the suite needs a GPU adapter (lavapipe)");
    let mut cpu = Session::cpu();
    for session in [&mut cpu, &mut gpu] {
        let whole = session.render(&e).unwrap();
        assert_eq!(whole.frames, 4);
        let mut last = None;
        for range in [0..1, 1..3, 3..4] {
            let image = session
                .render_frames(&e.scene, &e.settings, range.clone())
                .unwrap();
            assert_eq!(image.frames, range.end, "{}", session.label());
            // The CPU reference's call traces its own frames: the accumulation is
            // continued, not rendered again from frame 0 (the GPU kernel counts no rays
            // here).
            if session.gpu().is_none() {
                assert_eq!(
                    image.stats.primary,
                    16 * 12 * range.len() as u64,
                    "frames {range:?}"
                );
            }
            last = Some(image);
        }
        let last = last.unwrap();
        assert_eq!(
            last.frame.pixels,
            whole.frame.pixels,
            "{}: frames 0..4 in three ranges against one render of 4",
            session.label()
        );
        for bad in [2..2, 0..5] {
            let err = session
                .render_frames(&e.scene, &e.settings, bad.clone())
                .unwrap_err();
            assert!(
                matches!(err.kind(), ErrorKind::Invalid | ErrorKind::Device),
                "{err}"
            );
            assert!(
                err.message()
                    .contains(&format!("frames {}..{}", bad.start, bad.end)),
                "{}: {err}",
                session.label()
            );
        }
        // Each tracer continues its own accumulation only where it left off, and only
        // of the same inputs; any other render ends it.
        let label = session.label();
        let mut after = |range: std::ops::Range<u32>, e: &Experiment| {
            session.render_frames(&e.scene, &e.settings, range)
        };
        after(0..2, &e).unwrap();
        let err = after(3..4, &e).unwrap_err();
        assert!(
            err.message().contains("would skip frames 2..3"),
            "{label}: {err}"
        );
        let err = after(1..3, &e).unwrap_err();
        assert!(
            err.message()
                .contains("frames 1..2 are already accumulated"),
            "{label}: {err}"
        );
        let mut moved = e.clone();
        moved.scene.lights.pop();
        let err = after(2..3, &moved).unwrap_err();
        assert!(
            err.message().contains("cannot continue") && err.message().contains("changed: lights"),
            "{label}: {err}"
        );
        // The refused calls left the accumulation as it was.
        let image = after(2..4, &e).unwrap();
        assert_eq!(image.frame.pixels, whole.frame.pixels, "{label}");
        // Other voxels are refused before the GPU tracer uploads them: the
        // accumulation survives that refusal too.
        after(0..2, &e).unwrap();
        let mut carved = e.clone();
        let v = carved.scene.grid.dims().as_ivec3() / 2;
        let m = carved.scene.grid.get(v);
        carved.scene.grid.set(v, if m == 0 { 1 } else { 0 });
        let err = after(2..3, &carved).unwrap_err();
        assert!(err.message().contains("changed: voxel"), "{label}: {err}");
        let image = after(2..4, &e).unwrap();
        assert_eq!(
            image.frame.pixels, whole.frame.pixels,
            "{label}: after other voxels"
        );
        // Any other render ends it.
        session.render(&e).unwrap();
        let err = session
            .render_frames(&e.scene, &e.settings, 4..4)
            .unwrap_err();
        assert!(err.message().contains("empty range"), "{label}: {err}");
        let err = session
            .render_frames(&e.scene, &e.settings, 2..3)
            .unwrap_err();
        assert!(
            err.message().contains("no accumulation to continue"),
            "{label}: {err}"
        );
    }
}

/// A CPU session keeps the walks' data of its latest renders as the GPU tracer does: a
/// loop of renders of one grid builds it once, two walks alternate without building,
/// a third puts out the least recently rendered, and a changed grid builds again; every image is the one
/// a render of its own (`voxlab::cpu::render`) gives, bit for bit.
#[test]
fn a_cpu_session_keeps_its_walks_data_across_renders() {
    use voxlab::render::Traversal;
    let mut e = Experiment::seed_default();
    e.scene = voxlab::scene::seed::seed_scene(24).unwrap();
    (e.settings.width, e.settings.height) = (12, 10);
    let mut session = Session::cpu();
    let mut render = |e: &Experiment, walk: &str, builds: u64, what: &str| {
        let mut e = e.clone();
        e.settings.traversal = Traversal::named(walk).unwrap();
        let image = session.render(&e).unwrap();
        assert_eq!(session.walk_data_builds(), builds, "{what}");
        let own = voxlab::cpu::render(&e.scene, &e.settings);
        assert_eq!(image.frame.pixels, own.frame.pixels, "{what}: {walk}");
        assert_eq!(image.stats, own.stats, "{what}: {walk}");
        image
    };
    let first = render(&e, "sparse_octant", 1, "the first render builds");
    render(&e, "sparse_octant", 1, "the same grid and walk");
    render(&e, "octant", 2, "another walk builds");
    render(&e, "dense", 2, "the dense walk has no data of its own");
    render(&e, "sparse_octant", 2, "the first walk is kept");
    render(&e, "proximity", 3, "a third walk builds");
    render(&e, "sparse_octant", 3, "the latest walk before it is kept");
    render(&e, "octant", 4, "the oldest gave way");
    render(&e, "sparse_octant", 4, "kept, and the latest again");

    // A slab across the middle of the grid, in front of the camera: the image changes.
    let mut changed = e.clone();
    for x in 0..24 {
        for y in 0..24 {
            changed.scene.grid.set(glam::IVec3::new(x, y, 12), 1);
        }
    }
    let other = render(&changed, "sparse_octant", 5, "another grid builds again");
    render(&e, "sparse_octant", 5, "the first grid's build is kept");
    assert_ne!(other.frame.pixels, first.frame.pixels, "the slab is seen");
}

/// A CPU session continues its sums in f64 where the last range left off: the image of
/// frames in ranges is, bit for bit, one render's, also where a filter reads the
/// primary layers the frames sum (`features.reconstruction = "atrous"`) and where the
/// pixel filter moves each frame's primary rays.
#[test]
fn a_cpu_session_continues_its_sums_bit_for_bit() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let cases: [(&str, &[&str]); 3] = [
        ("area_lights.toml", &["render.pixel_filter=\"gaussian\""]),
        (
            "reconstruction.toml",
            &["features.reconstruction=\"atrous\"", "render.path_frames=1"],
        ),
        ("ratio.toml", &[]),
    ];
    for (file, sets) in cases {
        let mut overrides: Vec<voxlab::experiment::Override> =
            ["render.width=11", "render.height=7", "render.spp=7"]
                .iter()
                .chain(sets)
                .map(|s| s.parse().unwrap())
                .collect();
        overrides.dedup();
        let e = Experiment::load_with(dir.join(file), &overrides).unwrap();
        let whole = Session::cpu().render(&e).unwrap();
        let mut session = Session::cpu();
        let mut image = None;
        for range in [0..1, 1..2, 2..6, 6..7] {
            image = Some(
                session
                    .render_frames(&e.scene, &e.settings, range.clone())
                    .unwrap(),
            );
        }
        let image = image.unwrap();
        assert_eq!(image.frames, 7, "{file}");
        assert_eq!(image.frame.pixels, whole.frame.pixels, "{file}");
        assert_eq!(
            image.stats.primary,
            11 * 7,
            "{file}: only frames 6..7 traced"
        );
    }
}

/// A CPU session keeps the triangle surface it listed (as the GPU tracer keeps its
/// upload): renders of a mesh surface, the same with a voxel changed, and the first
/// again each give, bit for bit, the image a render of its own gives.
#[test]
fn a_cpu_session_keeps_its_surface_and_its_images_are_their_own() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let overrides: Vec<voxlab::experiment::Override> = ["render.width=12", "render.height=10"]
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    let e = Experiment::load_with(dir.join("bunny_mesh.toml"), &overrides).unwrap();
    let mut carved = e.clone();
    let v = carved.scene.grid.dims().as_ivec3() / 2;
    let m = carved.scene.grid.get(v);
    carved.scene.grid.set(v, if m == 0 { 1 } else { 0 });
    let mut session = Session::cpu();
    for (what, e) in [("first", &e), ("carved", &carved), ("first again", &e)] {
        let image = session.render(e).unwrap();
        let own = voxlab::cpu::render(&e.scene, &e.settings);
        assert_eq!(image.frame.pixels, own.frame.pixels, "{what}");
        assert_eq!(image.stats, own.stats, "{what}");
    }
}
