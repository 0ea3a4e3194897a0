//! `voxlab voxelize MESH --resolution N --out FILE.vox`, end to end through the binary.

use std::path::{Path, PathBuf};
use std::process::Command;

use voxlab::scene::{VoxelizeOptions, load_vox, voxelize_mesh};

fn bunny() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/data/bunny.obj");
    assert!(p.exists(), "example data {} is missing", p.display());
    p
}

fn voxlab(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(args)
        .output()
        .expect("run voxlab")
}

#[test]
fn voxelize_writes_a_vox_that_loads_back() {
    let dir = std::env::temp_dir().join(format!("voxlab-cli-vox-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("bunny.vox");
    let o = voxlab(&[
        "voxelize".as_ref(),
        bunny().as_os_str(),
        "--resolution".as_ref(),
        "40".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("3674 triangles") && stdout.contains("bunny.vox"),
        "{stdout}"
    );
    let v = voxelize_mesh(bunny(), &VoxelizeOptions::count(40)).unwrap();
    let back = load_vox(&out, None).unwrap();
    assert_eq!(back.grid.dims(), v.grid.dims());
    assert_eq!(back.grid.data(), v.grid.data());
}

#[test]
fn voxelize_reports_bad_input_without_writing() {
    let dir = std::env::temp_dir().join(format!("voxlab-cli-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("x.vox");
    let missing = dir.join("missing.obj");
    let o = voxlab(&[
        "voxelize".as_ref(),
        missing.as_os_str(),
        "--resolution".as_ref(),
        "8".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("missing.obj") && stderr.contains("cannot read"),
        "{stderr}"
    );
    assert!(!out.exists());

    let o = voxlab(&[
        "voxelize".as_ref(),
        bunny().as_os_str(),
        "--resolution".as_ref(),
        "0".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("--resolution") && stderr.contains("1..="),
        "{stderr}"
    );
    assert!(!out.exists());
}
