//! Writing an experiment back to TOML (`experiment::write`): every experiment file and
//! the seed default survive write -> parse unchanged, the written text is a fixed point
//! (write -> parse -> write is byte-identical), odd values survive, a file exported to
//! another directory loads the same voxels, and the scene cache gives what `from_str`
//! gives without loading the voxels again.

mod common;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use glam::DVec3;
use toml::{Table, Value};
use voxlab::experiment::write::{
    WriteError, degrees, relocate_scene_source, scene_source, to_toml,
};
use voxlab::experiment::{Experiment, SceneCache};
use voxlab::scene::{AreaLight, AreaShape, Light, PointLight};

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `experiments/*.toml` and `experiments/stress/*.toml`, sorted.
fn experiment_files() -> Vec<PathBuf> {
    let mut files = Vec::new();
    for dir in ["experiments", "experiments/stress"] {
        for entry in std::fs::read_dir(manifest().join(dir)).unwrap() {
            let p = entry.unwrap().path();
            if p.extension().is_some_and(|e| e == "toml") {
                files.push(p);
            }
        }
    }
    files.sort();
    files
}

fn parse(text: &str, path: &Path) -> Experiment {
    Experiment::from_str(text, path).unwrap_or_else(|e| panic!("{e}\n--- text:\n{text}"))
}

fn write(e: &Experiment, source: &Table) -> String {
    to_toml(e, source).unwrap_or_else(|err| panic!("{err}"))
}

#[track_caller]
fn assert_same(a: &Experiment, b: &Experiment, what: &str) {
    assert_eq!(a.name, b.name, "{what}: name");
    assert_eq!(a.description, b.description, "{what}: description");
    assert_eq!(a.settings, b.settings, "{what}: settings");
    assert_eq!(a.scene.camera, b.scene.camera, "{what}: camera");
    assert_eq!(a.scene.lights, b.scene.lights, "{what}: lights");
    assert_eq!(a.scene.materials, b.scene.materials, "{what}: materials");
    assert_eq!(a.scene.ambient, b.scene.ambient, "{what}: ambient");
    // The grid last: its Debug output is large.
    assert!(a.scene.grid == b.scene.grid, "{what}: grids differ");
    assert!(a.scene == b.scene, "{what}: scenes differ");
}

/// write -> parse -> write -> parse: returns (first text, first parse); asserts that the
/// second text equals the first byte for byte and the second parse equals the first.
#[track_caller]
fn cycle(e: &Experiment, source: &Table, what: &str) -> (String, Experiment) {
    // Parsed under a path in another directory: the written file must not depend on
    // where it is read from (paths in [scene] are absolute).
    let elsewhere = Path::new("/nonexistent/elsewhere/written.toml");
    let t1 = write(e, source);
    let e1 = parse(&t1, elsewhere);
    let t2 = write(&e1, source);
    assert_eq!(t1, t2, "{what}: write(parse(write(e))) != write(e)");
    let e2 = parse(&t2, elsewhere);
    assert_same(&e2, &e1, &format!("{what}, second cycle"));
    (t1, e1)
}

#[test]
fn every_experiment_file_round_trips_exactly() {
    let files = experiment_files();
    assert!(files.len() >= 15, "found only {files:?}");
    // The files that load experiments/data fail clearly if it is missing.
    common::example_data("deer.vox");
    common::example_data("bunny.obj");
    for f in &files {
        let text = std::fs::read_to_string(f).unwrap();
        let e = parse(&text, f);
        let source = scene_source(&text, f).unwrap_or_else(|err| panic!("{err}"));
        let what = f.display().to_string();
        let (written, e1) = cycle(&e, &source, &what);
        // The files' angles are round numbers of degrees and their normals come out of
        // normalize(): the very first cycle is exact too.
        assert_same(&e1, &e, &format!("{what}, first cycle"));
        assert!(written.starts_with("# "), "{what}: no header:\n{written}");
        for section in ["[camera]", "[render]", "[features]", "[cones]"] {
            assert!(
                written.contains(section),
                "{what}: no {section}:\n{written}"
            );
        }
    }
}

#[test]
fn the_seed_default_round_trips_exactly() {
    let e = Experiment::seed_default();
    let (text, e1) = cycle(&e, &Table::new(), "seed default");
    assert_same(&e1, &e, "seed default, first cycle");
    assert!(text.contains("name = \"seed\""), "{text}");
    // The seed's three point lights and materials 1..=3 are written out.
    assert_eq!(text.matches("[[lights]]").count(), 3, "{text}");
    assert_eq!(text.matches("[[materials]]").count(), 3, "{text}");
    assert!(!text.contains("void"), "void is not written:\n{text}");
}

fn unit(v: DVec3) -> DVec3 {
    v.normalize()
}

/// The seed default with values a viewer may produce: nothing round about them.
fn odd_experiment() -> Experiment {
    let mut e = Experiment::seed_default();
    e.name = "odd-values_1.2".into();
    // Free text as a reader writes it: quotes of both kinds, runs of three, newlines, a
    // tab, a backslash at the end, letters outside ASCII.
    e.description = Some("a \"quoted\" 'word', \"\"\" and '''\nline two\tü ∑ 🦌\\".into());
    e.scene.lights = vec![
        Light::Point(PointLight {
            position: DVec3::new(-3.25, -1e-3, -7.0e5),
            color: DVec3::new(0.1, 0.2, 1.0 / 3.0),
            intensity: 123.456789,
        }),
        Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Rect {
                width: 0.1,
                height: 7.0,
            },
            position: DVec3::new(-1.0, 20.0, -0.5),
            normal: unit(DVec3::new(-0.21, -0.93, 0.37)),
            rotation: 0.123,
            color: DVec3::ONE,
            intensity: 1e-3,
        }),
        Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Disk { radius: 2.75 },
            position: DVec3::new(4.0, 18.0, -6.0),
            normal: unit(DVec3::new(0.3, -0.5, 0.2)),
            rotation: -2.0,
            color: DVec3::new(0.7, 0.8, 1.0),
            intensity: 256.0,
        }),
        Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Sphere { radius: 0.0 },
            position: DVec3::new(-1e-7, 5.0, 1e7),
            normal: -DVec3::Y,
            rotation: 0.0,
            color: DVec3::new(0.0, 0.5, 0.0),
            intensity: 0.0,
        }),
    ];
    let glass = &mut e.scene.materials[1];
    glass.sigma = Some(DVec3::new(0.5, 1e-6, 1e4));
    glass.albedo = DVec3::new(0.9, 1.0 / 7.0, 0.0);
    e.scene.materials[3].emission = DVec3::new(0.0, 2.5, 0.1);
    let mut extra = e.scene.materials[2].clone();
    extra.name = "a new material".into();
    extra.kt = 0.0;
    extra.ior = 2.417;
    e.scene.materials.push(extra);
    e.scene.camera.yaw = 2.5;
    e.scene.camera.pitch = -0.3;
    e.scene.camera.vfov = 0.9;
    e.scene.camera.target = DVec3::new(-8.0, 0.25, 1e-9);
    e.scene.ambient = DVec3::new(0.0, 0.01, 0.3);
    let s = &mut e.settings;
    s.spp = 37;
    s.seed = u32::MAX;
    s.light_samples = 5;
    s.width = 1;
    s.height = 16384;
    s.max_reflection_depth = 0;
    s.max_refraction_depth = 16;
    s.falloff = false;
    s.falloff_min_distance = 0.3;
    s.ray_offset = 0.0;
    s.features.shadow_model = &voxlab::technique::area::MODEL;
    s.features.transmittance = voxlab::technique::beer_lambert::ID;
    s.features.shadow_model = &voxlab::technique::cone::MODEL;
    s.features.set_term("ambient_occlusion", true);
    s.features.set_term("indirect", true);
    s.cones.levels = 3;
    s.cones.step_factor = 0.37;
    s.cones.aperture_deg = 12.5;
    s.cones.start_offset = 0.0;
    s.cones.ao_cones = 17;
    s.cones.ao_range = 1e6;
    s.cones.indirect_strength = 0.0;
    e
}

#[test]
fn odd_values_round_trip() {
    let e = odd_experiment();
    let (text, e1) = cycle(&e, &Table::new(), "odd values");
    // Everything but the angles is exact in the first cycle.
    let angles_equal = |a: &Experiment| {
        let mut a = a.clone();
        a.scene.camera = e.scene.camera.clone();
        for (l, orig) in a.scene.lights.iter_mut().zip(&e.scene.lights) {
            if let (Light::Area(x), Light::Area(y)) = (l, orig) {
                x.rotation = y.rotation;
            }
        }
        a
    };
    assert_same(&angles_equal(&e1), &e, "odd values, all but angles");
    // Angles within 1e-9 degrees.
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 / 180.0 * PI * 2.0;
    let (c, c1) = (&e.scene.camera, &e1.scene.camera);
    assert!(close(c.yaw, c1.yaw) && close(c.pitch, c1.pitch) && close(c.vfov, c1.vfov));
    for (a, b) in e.scene.lights.iter().zip(&e1.scene.lights) {
        if let (Light::Area(a), Light::Area(b)) = (a, b) {
            assert!(
                close(a.rotation, b.rotation),
                "{} {}",
                a.rotation,
                b.rotation
            );
        }
    }
    for part in [
        "spp = 37",
        "seed = 4294967295",
        "position = [-3.25, -0.001, -700000.0]",
        "sigma = [0.5, 0.000001, 10000.0]",
        "rotation_deg = -114.591559026",
        "transmittance = \"beer-lambert\"",
        "name = \"a new material\"",
        "height = 16384",
    ] {
        assert!(text.contains(part), "no {part:?} in:\n{text}");
    }
    // Keys by light type: a sphere has no normal or rotation, a point light only its
    // four keys.
    let doc: Table = toml::from_str(&text).unwrap();
    let lights = doc["lights"].as_array().unwrap();
    let keys = |i: usize| {
        let mut k: Vec<&str> = lights[i]
            .as_table()
            .unwrap()
            .keys()
            .map(String::as_str)
            .collect();
        k.sort();
        k.join(",")
    };
    assert_eq!(keys(0), "color,intensity,position,type");
    assert_eq!(
        keys(1),
        "color,emission,intensity,normal,position,rotation_deg,size,type"
    );
    assert_eq!(
        keys(2),
        "color,emission,intensity,normal,position,radius,rotation_deg,type"
    );
    assert_eq!(keys(3), "color,intensity,position,radius,type");
    // A material without sigma has no sigma key (absent: derived from kt).
    let mats = doc["materials"].as_array().unwrap();
    assert!(mats[0].get("sigma").is_some());
    assert!(mats[1].get("sigma").is_none());
}

#[test]
fn no_lights_is_written_as_an_empty_list() {
    let mut e = Experiment::seed_default();
    e.scene.lights.clear();
    let (text, e1) = cycle(&e, &Table::new(), "no lights");
    assert!(text.contains("lights = []"), "{text}");
    // Absent would have meant the seed's three lights.
    assert!(e1.scene.lights.is_empty());
    assert_same(&e1, &e, "no lights");
}

#[test]
fn normals_that_normalize_would_move_round_trip() {
    // normalize() is not idempotent in f64: find unit vectors it moves, and check the
    // file keeps them (the parser keeps a normal that is unit to rounding).
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut moved = 0;
    let mut e = Experiment::seed_default();
    e.scene.lights.clear();
    for _ in 0..200 {
        let n = DVec3::new(next(), next(), next()).normalize();
        if n.normalize() != n {
            moved += 1;
        }
        e.scene.lights.push(Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Disk { radius: 1.0 },
            position: DVec3::new(8.0, 20.0, 8.0),
            normal: n,
            rotation: 0.0,
            color: DVec3::ONE,
            intensity: 10.0,
        }));
    }
    assert!(
        moved > 0,
        "normalize moved no unit vector: the test proves nothing"
    );
    let (_, e1) = cycle(&e, &Table::new(), "normals");
    assert_eq!(e1.scene.lights, e.scene.lights);
    // Normals that are not unit are still normalized.
    let text = "[[lights]]\ntype = \"disk\"\nposition = [0.0, 9.0, 0.0]\nnormal = [0.0, -2.0, 0.0]\nradius = 1.0\nintensity = 1.0\n";
    let p = parse(text, Path::new("x.toml"));
    let Light::Area(a) = &p.scene.lights[0] else {
        panic!("not an area light")
    };
    assert_eq!(a.normal, -DVec3::Y);
}

#[test]
fn degrees_are_a_fixed_point_of_write_and_parse() {
    let rad = |deg: f64| deg / 180.0 * PI;
    for d in [
        0.0, 36.0, 25.0, -90.0, 90.0, 179.0, 0.1, 12.5, -359.999, 1e-9,
    ] {
        assert_eq!(degrees(rad(d)), d, "{d} degrees");
    }
    let mut x = 0.123_456_789_f64;
    let mut exact = 0;
    for i in 0..100_000 {
        x = (x * 9301.0 + 0.4927).fract();
        let r = (x - 0.5) * 2.0 * PI * f64::from(1 + i % 1000);
        let d1 = degrees(r);
        let d2 = degrees(rad(d1));
        assert_eq!(d1.to_bits(), d2.to_bits(), "{r} rad: {d1} then {d2}");
        assert!((rad(d1) - r).abs() <= 1e-9 / 180.0 * PI + 1e-12 * r.abs());
        exact += usize::from(rad(d1) == r);
    }
    // Most angles have an exact decimal (about three quarters; the rest move < 1e-9 deg).
    assert!(exact > 60_000, "only {exact} of 100000 angles exact");
}

#[test]
fn duplicate_material_names_are_refused() {
    let mut e = Experiment::seed_default();
    let mut copy = e.scene.materials[2].clone();
    copy.albedo = DVec3::new(1.0, 0.0, 0.0);
    e.scene.materials.push(copy);
    let err: WriteError = to_toml(&e, &Table::new()).unwrap_err();
    assert_eq!(err.key, "materials[4].name");
    assert!(err.to_string().contains("semi-solid"), "{err}");
    // Nor can a material take void's name.
    let mut e = Experiment::seed_default();
    e.scene.materials[3].name = "void".into();
    assert_eq!(
        to_toml(&e, &Table::new()).unwrap_err().key,
        "materials[3].name"
    );
    // A name the parser rejects, and a value that is not finite.
    let mut e = Experiment::seed_default();
    e.name = "has space".into();
    assert_eq!(to_toml(&e, &Table::new()).unwrap_err().key, "name");
    let mut e = Experiment::seed_default();
    e.scene.camera.target.y = f64::NAN;
    assert_eq!(to_toml(&e, &Table::new()).unwrap_err().key, "camera.target");
    let mut e = Experiment::seed_default();
    e.scene.materials[1].sigma = Some(DVec3::new(0.0, f64::INFINITY, 0.0));
    assert_eq!(
        to_toml(&e, &Table::new()).unwrap_err().key,
        "materials[0].sigma"
    );
}

#[test]
fn scene_source_resolves_paths_like_the_loader() {
    let deer = common::example_data("deer.vox").canonicalize().unwrap();
    // Relative experiment path (tests run in the package root), relative vox path.
    let rel = Path::new("experiments/deer_area_light.toml");
    let text = std::fs::read_to_string(manifest().join(rel)).unwrap();
    let src = scene_source(&text, rel).unwrap();
    let model = src["models"].as_array().unwrap()[0].as_table().unwrap();
    assert_eq!(model["vox"].as_str(), Some(deer.to_str().unwrap()));
    assert_eq!(src["dims"].as_array().unwrap().len(), 3, "{src:?}");
    // A scene's own vox path too.
    let text = "[scene]\nvox = \"data/deer.vox\"\n";
    let src = scene_source(text, rel).unwrap();
    assert_eq!(src["vox"].as_str(), Some(deer.to_str().unwrap()));
    assert_eq!(src.len(), 1, "{src:?}");
    // Absolute paths are kept as given; other keys verbatim; no [scene]: empty.
    let text = "[scene]\nmesh = \"/some/where/m.obj\"\nresolution = 12\nmaterial = \"glass\"\n";
    let src = scene_source(text, Path::new("a/b.toml")).unwrap();
    assert_eq!(src["mesh"].as_str(), Some("/some/where/m.obj"));
    assert_eq!(src["resolution"].as_integer(), Some(12));
    assert_eq!(src["material"].as_str(), Some("glass"));
    assert!(
        scene_source("name = \"x\"\n", Path::new("x.toml"))
            .unwrap()
            .is_empty()
    );
    // Bad TOML names the file and line.
    let err = scene_source("[scene\n", Path::new("dir/bad.toml")).unwrap_err();
    assert!(err.to_string().starts_with("dir/bad.toml:1"), "{err}");
    let err = scene_source("[scene]\nvox = 3\n", Path::new("dir/bad.toml")).unwrap_err();
    assert!(err.to_string().contains("scene.vox"), "{err}");
    let err = scene_source("[[scene.models]]\nmesh = 3\n", Path::new("dir/bad.toml")).unwrap_err();
    assert!(err.to_string().contains("scene.models[0].mesh"), "{err}");
}

#[test]
fn relocation_is_component_arithmetic() {
    let src = |p: &str| Table::from_iter([("vox".to_string(), Value::from(p))]);
    let vox = |t: &Table| t["vox"].as_str().unwrap().to_string();
    // Directories that do not exist: plain component arithmetic.
    let s = src("/nonexistent-root/data/models/m.vox");
    assert_eq!(
        vox(&relocate_scene_source(
            &s,
            Path::new("/nonexistent-root/out/x/y")
        )),
        "../../../data/models/m.vox"
    );
    assert_eq!(
        vox(&relocate_scene_source(
            &s,
            Path::new("/nonexistent-root/data")
        )),
        "models/m.vox"
    );
    // Only the root in common: absolute stays absolute.
    assert_eq!(
        vox(&relocate_scene_source(&s, Path::new("/elsewhere/out"))),
        "/nonexistent-root/data/models/m.vox"
    );
    // `..` below the common part of the destination: cannot tell, stays absolute.
    assert_eq!(
        vox(&relocate_scene_source(
            &s,
            Path::new("/nonexistent-root/out/../x")
        )),
        "/nonexistent-root/data/models/m.vox"
    );
    // Relative paths and other keys are left alone.
    let mut s = src("models/m.vox");
    s.insert("model".into(), Value::Integer(1));
    let r = relocate_scene_source(&s, Path::new("/nonexistent-root/out"));
    assert_eq!(r, s);
}

/// Exports `f` into `dest` with relocated paths, loads the export, and checks it is the
/// same experiment; returns the `vox`/`mesh` path written.
fn export_and_load(f: &Path, dest: &Path) -> String {
    let text = std::fs::read_to_string(f).unwrap();
    let e = parse(&text, f);
    let source = scene_source(&text, f).unwrap();
    let relocated = relocate_scene_source(&source, dest);
    std::fs::create_dir_all(dest).unwrap();
    let out = dest.join("exported.toml");
    std::fs::write(&out, write(&e, &relocated)).unwrap();
    let loaded = Experiment::load(&out).unwrap_or_else(|err| panic!("{err}"));
    assert_same(&loaded, &e, &out.display().to_string());
    // The scene's own file, else its first model's (`[[scene.models]]`).
    let table = match relocated.get("models") {
        Some(toml::Value::Array(models)) => models[0].as_table().unwrap(),
        _ => &relocated,
    };
    let key = if table.contains_key("vox") {
        "vox"
    } else {
        "mesh"
    };
    table[key].as_str().unwrap().to_string()
}

#[test]
fn relocated_exports_load_the_same_voxels() {
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("experiment_write");
    let _ = std::fs::remove_dir_all(&tmp);
    let deer = manifest().join("experiments/deer_area_light.toml");
    let bunny = manifest().join("experiments/bunny_glass.toml");
    let data = common::example_data("deer.vox").canonicalize().unwrap();
    let shares = |a: &Path, b: &Path| {
        a.components().nth(1).is_some() && a.components().nth(1) == b.components().nth(1)
    };
    // Beside the repository's data (the target directory usually shares a parent with
    // experiments/data): a relative path; where the target directory lies in another
    // tree, the absolute path. Either loads the same experiment.
    for (f, sub) in [(&deer, "a/deer"), (&bunny, "b/c/bunny")] {
        let dest = tmp.join(sub);
        let written = export_and_load(f, &dest);
        if shares(&dest.canonicalize().unwrap(), &data) {
            assert!(
                written.starts_with("..") && Path::new(&written).is_relative(),
                "{written}"
            );
        } else {
            assert!(Path::new(&written).is_absolute(), "{written}");
        }
    }
    // A directory that shares only the root with the data (the system's temp dir,
    // where that is so): the absolute path, which loads from anywhere.
    let sys = std::env::temp_dir().join(format!("voxlab-experiment-write-{}", std::process::id()));
    let written = export_and_load(&deer, &sys);
    if shares(&sys.canonicalize().unwrap(), &data) {
        assert!(Path::new(&written).is_relative(), "{written}");
    } else {
        assert_eq!(written, data.to_str().unwrap());
    }
    let _ = std::fs::remove_dir_all(&sys);
}

#[test]
fn the_cache_gives_what_from_str_gives_without_reloading() {
    let tmp = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("experiment_write_cache");
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    // A private copy of the deer, to delete once it is cached.
    let vox = tmp.join("deer.vox");
    std::fs::copy(common::example_data("deer.vox"), &vox).unwrap();
    let path = tmp.join("deer.toml");
    let text = std::fs::read_to_string(manifest().join("experiments/deer_area_light.toml"))
        .unwrap()
        .replace("data/deer.vox", "deer.vox");
    let plain = parse(&text, &path);
    let mut cache = SceneCache::default();
    assert!(cache.is_empty());
    let a = Experiment::from_str_cached(&text, &path, &mut cache).unwrap();
    assert_same(&a, &plain, "deer, first parse");
    assert_eq!((cache.len(), cache.hits(), cache.misses()), (1, 0, 1));
    // The same [scene] read from another directory is another scene (no deer there).
    let other = tmp.join("sub/deer.toml");
    let err = Experiment::from_str_cached(&text, &other, &mut cache).unwrap_err();
    assert!(err.to_string().contains("sub/deer.vox"), "{err}");
    assert_eq!((cache.len(), cache.hits(), cache.misses()), (1, 0, 1));

    // The viewer's way: the file's scene source (absolute paths), written and parsed:
    // another [scene] text than the file's, so loaded once more.
    let src = scene_source(&text, &path).unwrap();
    let written = write(&plain, &src);
    let w = Experiment::from_str_cached(&written, &path, &mut cache).unwrap();
    assert_same(&w, &plain, "deer, written");
    assert_eq!((cache.len(), cache.hits(), cache.misses()), (1, 0, 2));

    // An edit of a light: the same [scene], so no reload (the file is gone).
    std::fs::remove_file(&vox).unwrap();
    let mut edited = w.clone();
    if let Light::Area(l) = &mut edited.scene.lights[0] {
        l.intensity = 17.5;
    }
    let t = write(&edited, &src);
    assert!(
        Experiment::from_str(&t, &path).is_err(),
        "the .vox was not deleted"
    );
    let b = Experiment::from_str_cached(&t, &path, &mut cache).unwrap();
    assert_eq!((cache.hits(), cache.misses()), (1, 2));
    assert_same(&b, &edited, "deer, edited, from the cache");
    assert!(b.scene.lights != w.scene.lights);
    // Again: still the held scene.
    let c = Experiment::from_str_cached(&t, &path, &mut cache).unwrap();
    assert_same(&c, &b, "deer, edited, again");
    assert_eq!((cache.hits(), cache.misses()), (2, 2));

    // A failed load (the original text: its relative path is another source, and the
    // file is gone) keeps what was held.
    assert!(Experiment::from_str_cached(&text, &path, &mut cache).is_err());
    assert_eq!((cache.len(), cache.hits(), cache.misses()), (1, 2, 2));
    assert!(Experiment::from_str_cached(&t, &path, &mut cache).is_ok());
    assert_eq!(cache.hits(), 3);
    cache.clear();
    assert!(cache.is_empty());
    let _ = std::fs::remove_dir_all(&tmp);
}

#[test]
fn the_cache_applies_boxes_and_mesh_materials_to_a_copy() {
    for name in [
        "soft_coloured_shadows.toml",
        "bunny_glass.toml",
        "everything.toml",
    ] {
        let f = manifest().join("experiments").join(name);
        let text = std::fs::read_to_string(&f).unwrap();
        let plain = parse(&text, &f);
        let mut cache = SceneCache::default();
        for round in 0..3 {
            let e = Experiment::from_str_cached(&text, &f, &mut cache)
                .unwrap_or_else(|err| panic!("{err}"));
            assert_same(&e, &plain, &format!("{name}, cached parse {round}"));
            assert_eq!(cache.hits(), round, "{name}");
            assert_eq!(cache.misses(), 1, "{name}");
        }
        // Another material for the mesh or the boxes: applied (another [scene] text, so
        // the voxels are built again).
        let changed = text
            .replace("material = \"glass\"", "material = \"solid\"")
            .replace("material = \"amber\"", "material = \"floor\"");
        if changed != text {
            let e = Experiment::from_str_cached(&changed, &f, &mut cache).unwrap();
            assert_same(
                &e,
                &parse(&changed, &f),
                &format!("{name}, changed material"),
            );
            assert!(e.scene.grid != plain.scene.grid, "{name}: nothing changed");
        }
    }
}

/// An experiment named by its file's stem has a name the writer takes, whatever the
/// stem: Python's dicts and texts are "<dict>" and "<text>" in messages.
#[test]
fn a_name_taken_from_a_stem_is_one_the_writer_takes() {
    let long = "x".repeat(300);
    for (stem, want) in [
        ("<dict>", "_dict_".to_string()),
        ("my scene", "my_scene".to_string()),
        ("..dots", "_.dots".to_string()),
        ("ok-name_1.2", "ok-name_1.2".to_string()),
        ("\u{e9}t\u{e9}", "_t_".to_string()),
        (long.as_str(), "x".repeat(128)),
    ] {
        let e = Experiment::from_str("[render]\nwidth = 8\n", Path::new(&format!("{stem}.toml")))
            .unwrap_or_else(|err| panic!("{stem}: {err}"));
        assert_eq!(e.name, want, "{stem}");
        let text = to_toml(&e, &toml::Table::new())
            .unwrap_or_else(|err| panic!("{stem}: the writer refuses {:?}: {err}", e.name));
        let again = Experiment::from_str(&text, Path::new("elsewhere.toml")).unwrap();
        assert_eq!(again.name, want);
    }
}
