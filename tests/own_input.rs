//! Commands that write never overwrite what they read: `voxlab mesh` over the
//! experiment's own mesh or MTL, `voxlab ablate` over its own experiment file. Each
//! is refused before any work, with the input named, and leaves the input unchanged.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn voxlab(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(args)
        .output()
        .expect("run voxlab")
}

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn manifest() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Runs voxlab, expects a refusal naming `input`, and checks every file in `unchanged`
/// still holds what it held.
fn refused(args: &[&std::ffi::OsStr], input: &str, unchanged: &[&Path]) {
    let before: Vec<Vec<u8>> = unchanged
        .iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    let o = voxlab(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} succeeded:\n{err}");
    assert!(
        err.contains(input) && err.contains("input"),
        "{args:?}: {err}"
    );
    for (p, b) in unchanged.iter().zip(before) {
        assert_eq!(std::fs::read(p).unwrap(), b, "{} changed", p.display());
    }
}

#[test]
fn mesh_never_writes_over_the_experiments_own_mesh_or_mtl() {
    let d = dir("own_input_mesh");
    let obj = d.join("tet.obj");
    let mtl = d.join("tet.mtl");
    std::fs::write(
        &obj,
        "mtllib tet.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
         f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    std::fs::write(&mtl, "newmtl red\nKd 0.8 0.1 0.1\n").unwrap();
    let exp = d.join("tet.toml");
    std::fs::write(&exp, "[scene]\nmesh = \"tet.obj\"\nresolution = 8\n").unwrap();
    let all = [obj.as_path(), mtl.as_path(), exp.as_path()];
    // The mesh itself; its MTL (beside an output of the same stem); the experiment file
    // read through another name.
    refused(
        &[
            "mesh".as_ref(),
            exp.as_os_str(),
            "--out".as_ref(),
            obj.as_os_str(),
        ],
        "tet.obj",
        &all,
    );
    let other = d.join("other");
    std::fs::create_dir(&other).unwrap();
    std::os::unix::fs::symlink(&mtl, other.join("x.mtl")).unwrap();
    refused(
        &[
            "mesh".as_ref(),
            exp.as_os_str(),
            "--out".as_ref(),
            other.join("x.obj").as_os_str(),
        ],
        "tet.mtl",
        &all,
    );
    std::os::unix::fs::symlink(&exp, other.join("y.ply")).unwrap();
    refused(
        &[
            "mesh".as_ref(),
            exp.as_os_str(),
            "--out".as_ref(),
            other.join("y.ply").as_os_str(),
        ],
        "tet.toml",
        &all,
    );
    // An --set that names another mesh: that one is the input.
    let o = voxlab(&[
        "mesh".as_ref(),
        exp.as_os_str(),
        "--out".as_ref(),
        d.join("out.obj").as_os_str(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    refused(
        &[
            "mesh".as_ref(),
            exp.as_os_str(),
            "--set".as_ref(),
            "scene.mesh=out.obj".as_ref(),
            "--out".as_ref(),
            d.join("out.obj").as_os_str(),
        ],
        "out.obj",
        &[d.join("out.obj").as_path(), d.join("out.mtl").as_path()],
    );
}

#[test]
fn ablate_never_writes_over_its_own_experiment() {
    let d = dir("own_input_ablate");
    let text = std::fs::read_to_string(manifest().join("experiments/ablate_area.toml")).unwrap();
    for name in ["resolved.toml", "experiment.toml", "run.txt", "table.md"] {
        let exp = d.join(name);
        std::fs::write(&exp, &text).unwrap();
        refused(
            &[
                "ablate".as_ref(),
                exp.as_os_str(),
                "--out".as_ref(),
                d.as_os_str(),
            ],
            name,
            &[exp.as_path()],
        );
        std::fs::remove_file(&exp).unwrap();
    }
    // An input kept under images/ (where the points' images go).
    std::fs::create_dir_all(d.join("images")).unwrap();
    let exp = d.join("images/a.toml");
    std::fs::write(&exp, &text).unwrap();
    refused(
        &[
            "ablate".as_ref(),
            exp.as_os_str(),
            "--out".as_ref(),
            d.as_os_str(),
        ],
        "a.toml",
        &[exp.as_path()],
    );
}

/// A directory output given as an existing file is refused before any work, naming the
/// option, the path and what the command writes there; the file is left as it was.
/// `ablate` and `stress` said "creating FILE: File exists" (`stress` only after its
/// whole run, minutes in), the scripted viewer only after its frames and a window.
#[test]
fn a_directory_output_that_is_a_file_is_refused_at_once() {
    let d = dir("directory_output_file");
    let file = d.join("not_a_directory");
    std::fs::write(&file, b"keep me").unwrap();
    let ablate = manifest().join("experiments/ablate_area.toml");
    let baseline = manifest().join("experiments/baseline.toml");
    for (args, option) in [
        (
            vec![
                "ablate".as_ref(),
                ablate.as_os_str(),
                "--out".as_ref(),
                file.as_os_str(),
            ],
            "--out",
        ),
        (
            vec!["stress".as_ref(), "--out".as_ref(), file.as_os_str()],
            "--out",
        ),
        (
            vec![
                "export".as_ref(),
                baseline.as_os_str(),
                "--to".as_ref(),
                "mitsuba".as_ref(),
                file.as_os_str(),
            ],
            "",
        ),
        (
            vec![
                "view".as_ref(),
                baseline.as_os_str(),
                "--frames".as_ref(),
                "1".as_ref(),
                "--save-dir".as_ref(),
                file.as_os_str(),
            ],
            "--save-dir",
        ),
    ] {
        let started = std::time::Instant::now();
        let o = voxlab(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded:\n{err}");
        assert!(
            err.contains(&voxlab::output::given(option, &file))
                && err.contains("directory")
                && err.contains("this is a file"),
            "{args:?}: {err}"
        );
        // Refused before any case or point renders (a stress run takes minutes).
        assert!(started.elapsed().as_secs() < 30, "{args:?}: refused late");
        assert_eq!(std::fs::read(&file).unwrap(), b"keep me");
        assert_eq!(
            std::fs::read_dir(&d).unwrap().count(),
            1,
            "{args:?} left files"
        );
    }
}

/// `render`'s default outputs' directory, `out/`, that is a file: refused before the
/// render, with and without `--out out/NAME`, and the file kept.
#[test]
fn renders_default_out_that_is_a_file_is_refused_at_once() {
    let d = dir("default_out_file");
    std::fs::write(d.join("out"), b"keep me").unwrap();
    let baseline = manifest().join("experiments/baseline.toml");
    for extra in [&[][..], &["--out", "out/x.png"][..]] {
        let o = Command::new(env!("CARGO_BIN_EXE_voxlab"))
            .current_dir(&d)
            .arg("render")
            .arg(&baseline)
            .args(["--backend", "cpu", "--width", "4", "--height", "4"])
            .args(extra)
            .output()
            .expect("run voxlab");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{extra:?} succeeded:\n{err}");
        assert!(
            err.contains("out is a file") && !err.contains("rendered"),
            "{extra:?}: {err}"
        );
        assert_eq!(std::fs::read(d.join("out")).unwrap(), b"keep me");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 1, "{extra:?}");
    }
}
