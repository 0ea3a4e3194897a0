//! `[[scene.models]]`: .vox models and meshes placed into a grid of the experiment's
//! choosing, beside boxes and the built-in materials.

mod common;

use std::path::PathBuf;

use glam::IVec3;
use voxlab::experiment::{Experiment, ExperimentError};
use voxlab::scene::{Scene, load_vox};

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("experiments")
}

fn parse(text: &str) -> Result<Experiment, ExperimentError> {
    Experiment::from_str(text, dir().join("models_test.toml"))
}

fn deer_path() -> String {
    common::example_data("deer.vox").display().to_string()
}

fn composed(extra: &str) -> String {
    format!(
        "[scene]\ngenerator = \"empty\"\ndims = [40, 32, 20]\n\n[[scene.models]]\nvox = \"{}\"\n{extra}\n",
        deer_path()
    )
}

/// Every voxel of `scene` in the box [base, base + dims), against `model` (voxel for
/// voxel, through the materials' properties: the names are prefixed); everything else
/// must be `outside`.
fn assert_placed(scene: &Scene, model: &Scene, base: IVec3, scale: i32, outside: u8) {
    let g = &scene.grid;
    let d = g.dims().as_ivec3();
    let span = model.grid.dims().as_ivec3() * scale;
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let v = IVec3::new(x, y, z);
                let local = v - base;
                let inside = local.cmpge(IVec3::ZERO).all() && local.cmplt(span).all();
                let got = g.get(v);
                if !inside {
                    assert_eq!(got, outside, "outside the model at {v}");
                    continue;
                }
                let want = model.grid.get(local / scale);
                if want == 0 {
                    assert_eq!(got, outside, "a void voxel of the model at {v}");
                    continue;
                }
                let (a, b) = (
                    &scene.materials[got as usize],
                    &model.materials[want as usize],
                );
                assert_eq!(a.name, format!("deer: {}", b.name), "at {v}");
                let mut a = a.clone();
                a.name.clone_from(&b.name);
                assert_eq!(&a, b, "material at {v}");
            }
        }
    }
}

fn deer_alone() -> Scene {
    let v = load_vox(common::example_data("deer.vox"), None).unwrap();
    Scene {
        grid: v.grid,
        materials: v.materials,
        ..Experiment::seed_default().scene
    }
}

#[test]
fn a_placed_model_has_exactly_the_files_voxels_at_its_offset() {
    let model = deer_alone();
    for (offset, scale) in [
        ([0, 0, 0], 1),
        ([7, 3, 9], 1),
        ([14, 5, 11], 1),
        ([0, 0, 0], 2),
    ] {
        let dims = if scale == 2 {
            "[60, 60, 20]"
        } else {
            "[40, 32, 20]"
        };
        let text = composed(&format!("offset = {offset:?}\nscale = {scale}"))
            .replace("[40, 32, 20]", dims);
        let e = parse(&text).unwrap_or_else(|e| panic!("{e}"));
        let base = IVec3::from_array(offset);
        assert_placed(&e.scene, &model, base, scale, 0);
    }
}

#[test]
fn built_in_materials_stay_beside_the_models_palette() {
    let text = composed("offset = [2, 1, 2]")
        + "\n[[scene.boxes]]\nmin = [0, 0, 0]\nmax = [40, 1, 20]\nmaterial = \"solid\"\n";
    let e = parse(&text).unwrap_or_else(|e| panic!("{e}"));
    let seed = voxlab::scene::seed_palette();
    assert_eq!(
        &e.scene.materials[..seed.len()],
        &seed[..],
        "the built-in palette comes first"
    );
    let deer = deer_alone();
    assert_eq!(
        e.scene.materials.len(),
        seed.len() + deer.materials.len() - 1
    );
    let solid = e
        .scene
        .materials
        .iter()
        .position(|m| m.name == "solid")
        .unwrap() as u8;
    assert_eq!(
        e.scene.grid.get(IVec3::new(39, 0, 19)),
        solid,
        "the floor box"
    );
    assert_placed(
        &Scene {
            grid: {
                // The floor row is the box's: compare the model above it only.
                let mut g = e.scene.grid.clone();
                for z in 0..20 {
                    for x in 0..40 {
                        g.set(IVec3::new(x, 0, z), 0);
                    }
                }
                g
            },
            ..e.scene.clone()
        },
        &deer,
        IVec3::new(2, 1, 2),
        1,
        0,
    );
}

#[test]
fn materials_override_a_models_entry_and_a_model_can_take_one_material() {
    let text = composed("offset = [1, 1, 1]")
        + "\n[[materials]]\nname = \"deer: vox 94\"\nalbedo = [1.0, 0.0, 0.0]\n";
    let e = parse(&text).unwrap_or_else(|e| panic!("{e}"));
    let m = e
        .scene
        .materials
        .iter()
        .find(|m| m.name == "deer: vox 94")
        .unwrap();
    assert_eq!(m.albedo, glam::DVec3::new(1.0, 0.0, 0.0));

    let e = parse(&composed("offset = [1, 1, 1]\nmaterial = \"glass\"")).unwrap();
    assert_eq!(
        e.scene.materials,
        voxlab::scene::seed_palette(),
        "no palette appended"
    );
    let glass = e
        .scene
        .materials
        .iter()
        .position(|m| m.name == "glass")
        .unwrap() as u8;
    let used = e.scene.grid.materials_used();
    assert!(used[glass as usize]);
    assert_eq!(
        used.iter().filter(|&&u| u).count(),
        2,
        "void and glass only"
    );
    let count = e.scene.grid.data().iter().filter(|&&m| m != 0).count();
    let deer = deer_alone();
    assert_eq!(count, deer.grid.data().iter().filter(|&&m| m != 0).count());
}

#[test]
fn two_models_of_one_file_share_their_palette_and_a_later_one_wins() {
    let text = format!(
        "{}\n[[scene.models]]\nvox = \"{}\"\noffset = [10, 0, 5]\n",
        composed("offset = [0, 0, 0]"),
        deer_path()
    );
    let e = parse(&text).unwrap_or_else(|e| panic!("{e}"));
    let deer = deer_alone();
    assert_eq!(
        e.scene.materials.len(),
        voxlab::scene::seed_palette().len() + deer.materials.len() - 1,
        "equal entries are shared"
    );
    // Where both cover a voxel, the second's voxel (if not void) is there.
    let v = IVec3::new(12, 5, 7);
    let second = deer.grid.get(v - IVec3::new(10, 0, 5));
    if second != 0 {
        assert_eq!(
            e.scene.materials[e.scene.grid.get(v) as usize].name,
            format!("deer: {}", deer.materials[second as usize].name)
        );
    }
}

#[test]
fn a_mesh_model_has_the_voxels_of_the_same_mesh_as_a_whole_scene() {
    let bunny = common::example_data("bunny.obj").display().to_string();
    let whole = parse(&format!(
        "[scene]\nmesh = \"{bunny}\"\nresolution = 20\nmaterial = \"glass\"\n"
    ))
    .unwrap();
    let placed = parse(&format!(
        "[scene]\ngenerator = \"empty\"\ndims = [30, 30, 30]\n[[scene.models]]\nmesh = \"{bunny}\"\nresolution = 20\nmaterial = \"glass\"\noffset = [3, 4, 5]\n"
    ))
    .unwrap();
    let d = whole.scene.grid.dims().as_ivec3();
    let base = IVec3::new(3, 4, 5);
    let mut occupied = 0;
    for z in 0..30 {
        for y in 0..30 {
            for x in 0..30 {
                let v = IVec3::new(x, y, z);
                let l = v - base;
                let want = if l.cmpge(IVec3::ZERO).all() && l.cmplt(d).all() {
                    whole.scene.grid.get(l)
                } else {
                    0
                };
                assert_eq!(placed.scene.grid.get(v), want, "at {v}");
                occupied += usize::from(want != 0);
            }
        }
    }
    assert!(occupied > 100, "{occupied}");
}

fn error_of(text: &str) -> String {
    match parse(text) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_models_get_an_error_naming_the_key_and_the_range() {
    // The deer is 26 x 27 x 9: in a 40 x 32 x 20 grid, offsets up to 14, 5, 11.
    let e = error_of(&composed("offset = [15, 0, 0]"));
    assert!(
        e.contains("scene.models[0].offset") && e.contains("[0, 14] x [0, 5] x [0, 11]"),
        "{e}"
    );
    assert!(
        e.contains("models_test.toml:"),
        "names the file and line: {e}"
    );
    let e = error_of(&composed("offset = [-1, 0, 0]"));
    assert!(e.contains("scene.models[0].offset"), "{e}");
    // Offsets whose sum with the model's size would wrap: refused, never a panic.
    for extreme in [
        "[9223372036854775807, 0, 0]",
        "[0, 9223372036854775807, 0]",
        "[0, 0, 9223372036854775800]",
        "[-9223372036854775808, 0, 0]",
    ] {
        let e = error_of(&composed(&format!("offset = {extreme}")));
        assert!(e.contains("scene.models[0].offset"), "{extreme}: {e}");
    }
    let e = error_of(&composed("scale = 2"));
    assert!(e.contains("no offset fits"), "{e}");
    let e = error_of(&composed("scale = 0"));
    assert!(
        e.contains("scene.models[0].scale") && e.contains("1..=16"),
        "{e}"
    );
    let e = error_of(&composed("resolution = 4"));
    assert!(
        e.contains("scene.models[0].resolution") && e.contains("only applies"),
        "{e}"
    );
    let e = error_of(&composed("material = \"gold\""));
    assert!(
        e.contains("scene.models[0].material") && e.contains("glass"),
        "{e}"
    );
    let e = error_of(&composed("material = \"void\""));
    assert!(e.contains("void cannot"), "{e}");
    let e = error_of(&composed("colour = 1"));
    assert!(e.contains("colour"), "{e}");
    let e = error_of("[scene]\ngenerator = \"empty\"\n[[scene.models]]\noffset = [0, 0, 0]\n");
    assert!(
        e.contains("scene.models[0]") && e.contains("needs vox"),
        "{e}"
    );
    let e = error_of(&format!(
        "[scene]\nvox = \"{}\"\n[[scene.models]]\nvox = \"{}\"\n",
        deer_path(),
        deer_path()
    ));
    assert!(
        e.contains("scene.models") && e.contains("whole grid"),
        "{e}"
    );
    let e = error_of(&composed("").replace(&deer_path(), "no/such/file.vox"));
    assert!(
        e.contains("scene.models[0].vox") && e.contains("no/such/file.vox"),
        "{e}"
    );
    let e = error_of(&format!(
        "[scene]\ngenerator = \"empty\"\n[[scene.models]]\nmesh = \"{}\"\n",
        common::example_data("bunny.obj").display()
    ));
    assert!(
        e.contains("scene.models[0].mesh") && e.contains("resolution"),
        "{e}"
    );
    // Hostile: too many models (each a file load) are refused before any is loaded; a
    // device or a directory as the model is refused by the loader, the key named.
    let many = format!(
        "[scene]\ngenerator = \"empty\"\ndims = [40, 32, 20]\n{}",
        format!("[[scene.models]]\nvox = \"{}\"\n", deer_path()).repeat(65)
    );
    let e = error_of(&many);
    assert!(
        e.contains("scene.models") && e.contains("at most 64"),
        "{e}"
    );
    for path in ["/dev/zero", "/tmp"] {
        let e = error_of(&composed("").replace(&deer_path(), path));
        assert!(e.contains("scene.models[0].vox") && e.contains(path), "{e}");
    }
    // A mesh model longer than the grid is refused before it is voxelized.
    let e = error_of(&format!(
        "[scene]\ngenerator = \"empty\"\ndims = [30, 20, 10]\n[[scene.models]]\nmesh = \"{}\"\nresolution = 60000\n",
        common::example_data("bunny.obj").display()
    ));
    assert!(
        e.contains("scene.models[0].resolution") && e.contains("1..=30"),
        "{e}"
    );
}

#[test]
fn the_deer_experiment_stands_on_a_floor() {
    let e = common::experiment("deer_area_light.toml");
    let g = &e.scene.grid;
    let d = g.dims();
    let floor = (0..d.x as i32)
        .flat_map(|x| (0..d.z as i32).map(move |z| IVec3::new(x, 0, z)))
        .all(|v| e.scene.materials[g.get(v) as usize].name == "solid");
    assert!(
        floor,
        "a solid floor under the whole grid, for its shadows to fall on"
    );
    assert!(
        e.scene
            .materials
            .iter()
            .any(|m| m.name.starts_with("deer: vox"))
    );
}

/// Composed scenes are scenes like any other: on generated compositions (random grid,
/// offsets, scales, a material override, a floor box, with and without an area light),
/// the GPU renders what the f64 CPU reference renders.
#[test]
fn gpu_equals_cpu_on_generated_compositions() {
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};
    let mut rng = StdRng::seed_from_u64(18);
    let mut gpu = common::tracer();
    for case in 0..5 {
        let scale = rng.random_range(1..=2u32);
        let dims = [
            26 * scale + rng.random_range(0..10u32),
            27 * scale + rng.random_range(1..6u32),
            9 * scale + rng.random_range(0..20u32),
        ];
        let offset = [
            rng.random_range(0..=dims[0] - 26 * scale),
            rng.random_range(1..=dims[1] - 27 * scale),
            rng.random_range(0..=dims[2] - 9 * scale),
        ];
        let material = if rng.random_bool(0.3) {
            "material = \"glass\"\n"
        } else {
            ""
        };
        let light = if rng.random_bool(0.5) {
            "[[lights]]\ntype = \"rect\"\nposition = [10.0, 60.0, 30.0]\nnormal = [0.0, -1.0, -0.3]\nsize = [8.0, 8.0]\nintensity = 3000.0\n[features]\nshadow_model = \"area\"\n[render]\nlight_samples = 2\nspp = 3\n"
        } else {
            ""
        };
        let text = format!(
            "[scene]\ngenerator = \"empty\"\ndims = {dims:?}\n[[scene.models]]\nvox = \"{}\"\noffset = {offset:?}\nscale = {scale}\n{material}[[scene.boxes]]\nmin = [0, 0, 0]\nmax = [{}, 1, {}]\nmaterial = \"solid\"\n{light}",
            deer_path(),
            dims[0],
            dims[2]
        );
        let mut e = parse(&text).unwrap_or_else(|e| panic!("case {case}: {e}\n{text}"));
        e.settings.width = 40;
        e.settings.height = 40;
        let g = gpu.render(&e.scene, &e.settings).unwrap().frame;
        let c = voxlab::cpu::render(&e.scene, &e.settings).frame;
        common::assert_agree(&format!("composition {case}: {text}"), &g, &c);
    }
}
