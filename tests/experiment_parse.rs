//! Experiment files: the baseline equals the built-in seed experiment, every key works,
//! and every class of bad input gives a message naming the file, the line, the key and
//! what is allowed.

use glam::DVec3;
use voxlab::experiment::{Experiment, ExperimentError};
use voxlab::render::MAX_DEPTH_LIMIT;
use voxlab::scene::{Light, MAX_SPARSE_SIDE};

const FILE: &str = "experiments/x.toml";

fn err(text: &str) -> String {
    match Experiment::from_str(text, FILE) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn ok(text: &str) -> Experiment {
    Experiment::from_str(text, FILE).unwrap_or_else(|e| panic!("{e}"))
}

#[track_caller]
fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message {msg:?} lacks {p:?}");
    }
}

#[test]
fn baseline_file_is_the_seed_default() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/baseline.toml");
    let e = Experiment::load(path).unwrap_or_else(|e| panic!("{e}"));
    let d = Experiment::seed_default();
    assert_eq!(e.scene, d.scene);
    assert_eq!(e.settings, d.settings);
    assert_eq!(e.settings.features, d.settings.features);
    assert_eq!(e.name, "baseline");
    assert_eq!(e.source_path.as_deref(), Some(std::path::Path::new(path)));
    assert_eq!(d.settings.width, 512);
    assert_eq!(d.settings.max_reflection_depth, 4);
    assert_eq!(d.settings.max_refraction_depth, 4);
    assert_eq!(d.scene.grid.dims(), glam::UVec3::splat(16));
}

#[test]
fn an_empty_file_is_the_seed_default() {
    let e = ok("");
    let d = Experiment::seed_default();
    assert_eq!((e.scene, e.settings), (d.scene, d.settings));
    assert_eq!(e.name, "x");
}

#[test]
fn keys_set_what_they_name() {
    let e = ok(r#"
name = "glassy"
[scene]
generator = "empty"
dims = [4, 3, 5]
voxel_size = 0.5
origin = [1.0, 2.0, 3.0]
[[scene.boxes]]
min = [0, 0, 0]
max = [2, 1, 1]
material = "mirror"
[[scene.boxes]]
min = [3, 2, 4]
max = [4, 3, 5]
material = 1
[camera]
distance = 10
yaw_deg = 90
pitch_deg = -30
vfov_deg = 60
[[lights]]
type = "point"
position = [0, 10, 0]
intensity = 2.5
[[materials]]
name = "glass"
ior = 2.0
[[materials]]
name = "mirror"
kr = 1.0
[render]
width = 32
height = 16
max_reflection_depth = 0
max_refraction_depth = 16
falloff = false
falloff_min_distance = 0.5
ray_offset = 0.0
ambient = [0, 0, 0]
"#);
    assert_eq!(e.name, "glassy");
    let g = &e.scene.grid;
    assert_eq!(g.dims(), glam::UVec3::new(4, 3, 5));
    assert_eq!(g.voxel_size(), 0.5);
    assert_eq!(g.origin(), DVec3::new(1.0, 2.0, 3.0));
    // Glass overridden in place (other keys kept), mirror appended as index 4.
    assert_eq!(e.scene.materials.len(), 5);
    assert_eq!(e.scene.materials[1].ior, 2.0);
    assert_eq!(e.scene.materials[1].kt, 0.8);
    assert_eq!(e.scene.materials[4].name, "mirror");
    assert_eq!(e.scene.materials[4].kr, 1.0);
    assert_eq!(e.scene.materials[4].kd, 0.0);
    assert_eq!(g.get(glam::IVec3::new(1, 0, 0)), 4);
    assert_eq!(g.get(glam::IVec3::new(3, 2, 4)), 1);
    assert_eq!(g.get(glam::IVec3::new(2, 0, 0)), 0);
    assert_eq!(g.data().iter().filter(|&&m| m != 0).count(), 3);
    // The camera targets the grid centre unless told otherwise.
    assert_eq!(e.scene.camera.target, g.centre());
    assert_eq!(e.scene.camera.distance, 10.0);
    assert_eq!(e.scene.camera.yaw, std::f64::consts::FRAC_PI_2);
    assert!((e.scene.camera.pitch + std::f64::consts::PI / 6.0).abs() < 1e-15);
    assert!((e.scene.camera.vfov - std::f64::consts::PI / 3.0).abs() < 1e-15);
    assert_eq!(e.scene.lights.len(), 1);
    let Light::Point(l) = &e.scene.lights[0] else {
        panic!("a point light")
    };
    assert_eq!(l.color, DVec3::ONE);
    assert_eq!(l.intensity, 2.5);
    let s = &e.settings;
    assert_eq!((s.width, s.height), (32, 16));
    assert_eq!((s.max_reflection_depth, s.max_refraction_depth), (0, 16));
    assert!(!s.falloff);
    assert_eq!(s.falloff_min_distance, 0.5);
    assert_eq!(s.ray_offset, 0.0);
    assert_eq!(e.scene.ambient, DVec3::ZERO);
}

#[test]
fn lights_absent_means_seed_lights_and_empty_list_means_none() {
    assert_eq!(ok("").scene.lights.len(), 3);
    assert!(ok("lights = []").scene.lights.is_empty());
    // The seed's lights follow the grid.
    let e = ok("[scene]\nsize = 32");
    let c = e.scene.grid.centre();
    assert_eq!(
        e.scene.lights[0].position(),
        c + 32.0 * DVec3::new(0.9, 0.8, 1.0)
    );
    // 2.5 W and the seed's VIEW_OFFSET of 3.
    assert_eq!(e.scene.camera.distance, 83.0);
}

#[test]
fn out_of_range_value_names_file_line_key_and_range() {
    let msg = err("[render]\nheight = 8\nwidth = 0\n");
    assert_eq!(
        msg,
        "experiments/x.toml:3: render.width = 0: must be an integer in 1..=16384 (pixels)"
    );
}

#[test]
fn zero_and_negative_image_sizes() {
    assert_has(
        &err("[render]\nheight = 0"),
        &["experiments/x.toml:2:", "render.height = 0", "1..=16384"],
    );
    assert_has(
        &err("[render]\nwidth = -5"),
        &["x.toml:2:", "render.width = -5", "1..=16384"],
    );
    assert_has(
        &err("[render]\nwidth = 16385"),
        &["x.toml:2:", "render.width = 16385", "1..=16384"],
    );
}

#[test]
fn depth_limits_above_the_maximum() {
    let msg = err("[render]\n\nmax_refraction_depth = 17\n");
    assert_has(
        &msg,
        &[
            "experiments/x.toml:3:",
            "render.max_refraction_depth = 17",
            &format!("0..={MAX_DEPTH_LIMIT}"),
        ],
    );
    // The limit itself is accepted.
    ok(&format!(
        "[render]\nmax_reflection_depth = {MAX_DEPTH_LIMIT}"
    ));
}

#[test]
fn nan_inf_and_negative_floats() {
    assert_has(
        &err("[camera]\ndistance = nan"),
        &[
            "experiments/x.toml:2:",
            "camera.distance = nan",
            "finite number > 0",
        ],
    );
    assert_has(
        &err("[render]\nfalloff_min_distance = inf"),
        &["x.toml:2:", "render.falloff_min_distance = inf", "> 0"],
    );
    assert_has(
        &err("[render]\nambient = [0.1, -0.1, 0.1]"),
        &["x.toml:2:", "render.ambient = [0.1, -0.1, 0.1]", ">= 0"],
    );
    assert_has(
        &err("[scene]\nvoxel_size = 0.0"),
        &[
            "x.toml:2:",
            "scene.voxel_size = 0.0",
            "[0.000001, 1000000] (world units)",
        ],
    );
    // 1e308 overflowed the camera distance and hung the CPU walk.
    assert_has(
        &err("[scene]\nvoxel_size = 1e308"),
        &["x.toml:2:", "scene.voxel_size", "[0.000001, 1000000]"],
    );
    assert_has(
        &err("[camera]\npitch_deg = 91"),
        &["x.toml:2:", "camera.pitch_deg = 91", "[-90, 90]"],
    );
    assert_has(
        &err("[camera]\nvfov_deg = 180"),
        &[
            "x.toml:2:",
            "camera.vfov_deg = 180",
            "[0.000001, 180) (degrees)",
        ],
    );
}

#[test]
fn errors_inside_arrays_of_tables_name_the_entry() {
    let text = r#"
[[lights]]
type = "point"
position = [0, 0, 0]
intensity = 1

[[lights]]
type = "point"
position = [0, 0, 0]
intensity = -1
"#;
    assert_has(
        &err(text),
        &["experiments/x.toml:10:", "lights[1].intensity = -1", ">= 0"],
    );
    let text = "[[materials]]\nname = \"glass\"\nkt = 1.5\n";
    assert_has(
        &err(text),
        &["x.toml:3:", "materials[0].kt = 1.5", "in [0, 1]"],
    );
    let text = "[[materials]]\nname = \"g2\"\nsigma = [1, nan, 1]\n";
    assert_has(&err(text), &["x.toml:3:", "materials[0].sigma", ">= 0"]);
    let text = "[[materials]]\nname = \"void\"\nior = 1.3\n";
    assert_has(&err(text), &["x.toml:2:", "materials[0].name", "void"]);
}

#[test]
fn grid_larger_than_a_sparse_grid_allows() {
    // Past DENSE_MAX_VOXELS a generated grid is held as its sparse tree, whose sides are
    // bounded (tests/sparse_sources.rs loads 2048^3).
    let msg = err("[scene]\ndims = [8192, 2048, 32]\n");
    assert_has(
        &msg,
        &[
            "experiments/x.toml:2:",
            "scene.dims = [8192, 2048, 32]",
            "536870912 voxels",
            &format!("at most {MAX_SPARSE_SIDE}"),
        ],
    );
    assert_has(
        &err("[scene]\nsize = 5000"),
        &["x.toml:2:", "scene.size = 5000", "1..=4096 (voxels)"],
    );
    assert_has(
        &err("[scene]\ndims = [4, 0, 4]"),
        &[
            "x.toml:2:",
            "scene.dims = [4, 0, 4]",
            "every side must be an integer in 1..=268435456",
        ],
    );
    assert_has(
        &err("[scene]\nsize = 4\ndims = [4, 4, 4]"),
        &["x.toml:3:", "scene.dims", "not both"],
    );
}

/// A number 64 bits cannot hold is refused by toml as malformed, without its key: the
/// message names the key, what 64 bits hold and the key's own range.
#[test]
fn a_number_past_64_bits_names_its_key_and_range() {
    for (text, line_key, range) in [
        (
            "[camera]\ndistance = 1e400",
            "x.toml:2: camera.distance = 1e400",
            Some("finite number > 0"),
        ),
        (
            "[render]\nwidth = 99999999999999999999",
            "x.toml:2: render.width = 99999999999999999999",
            Some("1..=16384"),
        ),
        (
            "[render]\nheight = 8\nwidth = -9223372036854775809",
            "x.toml:3: render.width = -9223372036854775809",
            Some("1..=16384"),
        ),
        (
            "[scene]\ndims = [4, 99999999999999999999, 4]",
            "x.toml:2: scene.dims[1] = 99999999999999999999",
            Some("1..=268435456"),
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [1, -2e999, 3]\nintensity = 1",
            "x.toml:3: lights[0].position[1] = -2e999",
            None,
        ),
        (
            // serde stops at the type error first; the number is still what is wrong.
            "[render]\nwidth = [1, 1e400]",
            "x.toml:2: render.width[1] = 1e400",
            None,
        ),
        (
            "[render]\nwidth = 9223372036854775808",
            "x.toml:2: render.width = 9223372036854775808",
            Some("1..=16384"),
        ),
        (
            "[ablate]\nseeds = 1e999",
            "x.toml:2: ablate.seeds = 1e999",
            Some("1..=64"),
        ),
    ] {
        let e = err(text);
        assert_has(&e, &[line_key, "past what 64 bits hold"]);
        if let Some(r) = range {
            assert_has(&e, &[r]);
        }
    }
    // Any other syntax error stays one.
    assert_has(
        &err("[render]\nwidth = 1e"),
        &["x.toml:2:", "malformed TOML"],
    );
}

#[test]
fn material_index_out_of_range() {
    let text = r#"
[scene]
generator = "empty"
size = 4

[[scene.boxes]]
min = [0, 0, 0]
max = [1, 1, 1]
material = 9
"#;
    assert_eq!(
        err(text),
        "experiments/x.toml:9: scene.boxes[0].material = 9: must be an integer in 0..=3"
    );
    let text = text.replace("material = 9", "material = \"gold\"");
    assert_has(
        &err(&text),
        &[
            "x.toml:9:",
            "scene.boxes[0].material = \"gold\"",
            "no such material",
            "glass",
        ],
    );
    let text = text.replace("max = [1, 1, 1]", "max = [1, 5, 1]");
    let text = text.replace("\"gold\"", "1");
    assert_has(&err(&text), &["x.toml:8:", "scene.boxes[0].max", "<= dims"]);
}

#[test]
fn unknown_keys_list_the_allowed_ones() {
    let msg = err("[render]\nwidth = 8\nwidht = 8\n");
    assert_has(
        &msg,
        &[
            "experiments/x.toml:3:",
            "render.widht",
            "width, height, max_reflection_depth",
        ],
    );
    assert_has(
        &err("[scene]\ngenerator = \"seed\"\nvox_file = \"a.vox\""),
        &["x.toml:3:", "scene.vox_file", "generator, size, dims"],
    );
    assert_has(
        &err("\n[cam]\ndistance = 3"),
        &["x.toml:2:", "`cam`", "scene, camera, lights"],
    );
    assert_has(
        &err("[[lights]]\ntype = \"point\"\nposition = [0, 0, 0]\nintensity = 1\nradius = 2\n"),
        &[
            "x.toml:5:",
            "lights[0].radius",
            "position, color, intensity",
        ],
    );
    assert_has(
        &err("[[lights]]\ntype = \"area\"\nposition = [0, 0, 0]\nintensity = 1\n"),
        &["x.toml:2:", "lights[0].type", "point"],
    );
}

#[test]
fn unknown_features_are_errors() {
    let msg = err("[features]\nbeer_lambert = true\n");
    assert_has(
        &msg,
        &[
            "experiments/x.toml:2:",
            "features.beer_lambert",
            "allowed keys",
        ],
    );
}

#[test]
fn wrong_types_and_missing_keys() {
    assert_has(
        &err("[render]\n\nwidth = \"big\""),
        &["x.toml:3:", "render.width", "invalid type"],
    );
    assert_has(
        &err("[render]\nfalloff = 1"),
        &["x.toml:2:", "render.falloff", "bool"],
    );
    assert_has(
        &err("[[lights]]\ntype = \"point\"\nintensity = 1\n"),
        &["x.toml:1:", "lights[0]", "position"],
    );
    assert_has(
        &err("[scene]\ngenerator = \"menger\""),
        &["x.toml:2:", "scene.generator", "seed", "empty"],
    );
}

#[test]
fn malformed_toml_names_file_and_line() {
    let e = Experiment::from_str("[render]\nwidth = 8\nheight = \n", FILE).unwrap_err();
    assert!(matches!(e, ExperimentError::Syntax { .. }), "{e:?}");
    assert_has(&e.to_string(), &["experiments/x.toml:3:", "malformed TOML"]);
    assert_eq!(e.line(), Some(3));
    assert_has(
        &err("[render\nwidth = 8"),
        &["experiments/x.toml:1:", "malformed TOML"],
    );
    assert_has(
        &err("[render]\nwidth = 8\nwidth = 9\n"),
        &["experiments/x.toml:3:", "malformed TOML", "duplicate"],
    );
}

#[test]
fn missing_file_names_the_path() {
    let e = Experiment::load("experiments/does-not-exist.toml").unwrap_err();
    assert!(matches!(e, ExperimentError::Io { .. }));
    assert_has(&e.to_string(), &["experiments/does-not-exist.toml"]);
}

#[test]
fn bad_names_are_rejected() {
    assert_has(
        &err("name = \"../escape\""),
        &["x.toml:1:", "name = \"../escape\"", "output file"],
    );
}

/// Every fixed-length array of the file, given one element too many or too few: refused
/// with the key, the line and the length it must have (serde alone read the first N of a
/// longer array and dropped the rest).
#[test]
fn fixed_length_arrays_of_any_other_length_are_refused() {
    let cases = [
        ("[scene]\ndims = {}\n", "scene.dims", 3, "8"),
        ("[scene]\norigin = {}\n", "scene.origin", 3, "0.5"),
        (
            "[scene]\ngenerator = \"empty\"\n[[scene.boxes]]\nmin = {}\nmax = [2, 2, 2]\nmaterial = 1\n",
            "scene.boxes[0].min",
            3,
            "0",
        ),
        ("[camera]\ntarget = {}\n", "camera.target", 3, "1"),
        (
            "[[lights]]\ntype = \"point\"\nposition = {}\nintensity = 1\n",
            "lights[0].position",
            3,
            "1",
        ),
        (
            "[[lights]]\ntype = \"rect\"\nposition = [0, 9, 0]\nnormal = [0, -1, 0]\nsize = {}\nintensity = 1\n",
            "lights[0].size",
            2,
            "1",
        ),
        (
            "[[materials]]\nname = \"glass\"\nalbedo = {}\n",
            "materials[0].albedo",
            3,
            "0.5",
        ),
        ("[render]\nambient = {}\n", "render.ambient", 3, "0.1"),
    ];
    for (template, key, n, element) in cases {
        let array = |len: usize| format!("[{}]", vec![element; len].join(", "));
        // The right length reads; one more (of the element's type or another) or one
        // fewer is an error.
        ok(&template.replace("{}", &array(n)));
        for bad in [
            array(n + 1),
            format!("[{}, \"x\"]", vec![element; n].join(", ")),
            array(n - 1),
        ] {
            let text = template.replace("{}", &bad);
            let e = err(&text);
            assert!(e.contains(key), "{bad}: {e}");
            assert!(e.contains(FILE), "{bad}: names the file: {e}");
            if !bad.contains('"') {
                assert!(e.contains(&format!("length {n}")), "{bad}: {e}");
            }
        }
    }
}
