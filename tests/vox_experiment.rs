//! Experiment keys `[scene] vox = "path"` (+ `model`) and `mesh = "path"`
//! (+ `resolution` or `voxel_size`, optional `material`).

mod common;

use std::path::{Path, PathBuf};

use glam::UVec3;
use voxlab::experiment::Experiment;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxlab-exp-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn load(dir: &Path, text: &str) -> Result<Experiment, String> {
    let p = dir.join("e.toml");
    std::fs::write(&p, text).unwrap();
    Experiment::load(&p).map_err(|e| e.to_string())
}

#[test]
fn vox_scene_with_model_and_material_override() {
    let dir = temp_dir("vox");
    let deer = common::example_data("deer.vox");
    let e = load(
        &dir,
        &format!("[scene]\nvox = {:?}\n", deer.to_str().unwrap()),
    )
    .unwrap();
    assert_eq!(e.scene.grid.dims(), UVec3::new(26, 27, 9));
    assert_eq!(e.scene.materials.len(), 31);
    assert_eq!(e.scene.grid.data().iter().filter(|&&m| m != 0).count(), 355);
    e.scene.validate().unwrap();

    // [[materials]] override the file's by name; voxel_size rescales.
    let text = format!(
        "[scene]\nvox = {:?}\nmodel = 0\nvoxel_size = 0.5\n\n[[materials]]\nname = \"vox 94\"\nkt = 0.5\n",
        deer.to_str().unwrap()
    );
    let e = load(&dir, &text).unwrap();
    assert_eq!(e.scene.grid.voxel_size(), 0.5);
    let m = e
        .scene
        .materials
        .iter()
        .find(|m| m.name == "vox 94")
        .unwrap();
    assert_eq!(m.kt, 0.5);

    let bad = format!("[scene]\nvox = {:?}\nmodel = 3\n", deer.to_str().unwrap());
    let err = load(&dir, &bad).unwrap_err();
    assert!(
        err.contains("e.toml:2") && err.contains("deer.vox") && err.contains("0..=0"),
        "{err}"
    );
    let err = load(&dir, "[scene]\nvox = \"nope.vox\"\n").unwrap_err();
    assert!(
        err.contains("nope.vox") && err.contains("cannot read"),
        "{err}"
    );
    let err = load(
        &dir,
        &format!("[scene]\nvox = {:?}\nsize = 8\n", deer.to_str().unwrap()),
    )
    .unwrap_err();
    assert!(
        err.contains("scene.size") && err.contains("not used with scene.vox"),
        "{err}"
    );
    let err = load(&dir, "[scene]\nmodel = 1\n").unwrap_err();
    assert!(
        err.contains("scene.model") && err.contains("only applies with scene.vox"),
        "{err}"
    );
}

#[test]
fn mesh_scene_relative_path_resolution_and_material() {
    let dir = temp_dir("mesh");
    std::fs::write(
        dir.join("tet.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    // A path relative to the experiment file; the file's default material.
    let e = load(&dir, "[scene]\nmesh = \"tet.obj\"\nresolution = 12\n").unwrap();
    assert_eq!(e.scene.grid.dims(), UVec3::splat(12));
    assert_eq!(e.scene.materials.len(), 2);
    assert_eq!(e.scene.grid.max_material(), 1);

    // The bunny in the seed's glass: the palette is the seed's, voxels use "glass".
    let text = format!(
        "[scene]\nmesh = {:?}\nresolution = 24\nmaterial = \"glass\"\n",
        common::example_data("bunny.obj").to_str().unwrap()
    );
    let e = load(&dir, &text).unwrap();
    let glass = e
        .scene
        .materials
        .iter()
        .position(|m| m.name == "glass")
        .unwrap() as u8;
    assert!(e.scene.grid.data().iter().all(|&m| m == 0 || m == glass));
    assert_eq!(e.scene.grid.dims().max_element(), 24);
    e.scene.validate().unwrap();

    // By voxel size instead.
    let e = load(&dir, "[scene]\nmesh = \"tet.obj\"\nvoxel_size = 0.25\n").unwrap();
    assert_eq!(e.scene.grid.dims(), UVec3::splat(4));

    for (text, want) in [
        ("[scene]\nmesh = \"tet.obj\"\n", "needs scene.resolution"),
        (
            "[scene]\nmesh = \"tet.obj\"\nresolution = 0\n",
            "scene.resolution = 0",
        ),
        (
            "[scene]\nmesh = \"tet.obj\"\nvoxel_size = nan\n",
            "scene.voxel_size = nan",
        ),
        (
            "[scene]\nmesh = \"tet.obj\"\nresolution = 4\nmaterial = \"unobtainium\"\n",
            "no such material",
        ),
        (
            "[scene]\nmesh = \"tet.obj\"\nresolution = 4\nmaterial = 0\n",
            "scene.material",
        ),
        ("[scene]\nmesh = \"tet.obj\"\nvox = \"x.vox\"\n", "not both"),
        ("[scene]\nresolution = 4\n", "only applies with scene.mesh"),
        (
            "[scene]\nmesh = \"missing.obj\"\nresolution = 4\n",
            "missing.obj",
        ),
    ] {
        let err = load(&dir, text).unwrap_err();
        assert!(
            err.contains(want) && err.contains("e.toml"),
            "{text}: {err}"
        );
    }
}
