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
    // The record beside it: the mesh's hash, the build, the settings.
    let rec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("bunny.vox.json")).unwrap())
            .unwrap();
    assert_eq!(rec["made_by"], "voxlab voxelize");
    assert_eq!(rec["revision"], voxlab::revision::revision());
    assert_eq!(rec["resolution"], 40);
    let d = v.grid.dims();
    assert_eq!(rec["dims"], serde_json::json!([d.x, d.y, d.z]));
    let hash = blake3::hash(&std::fs::read(bunny()).unwrap())
        .to_hex()
        .to_string();
    assert_eq!(rec["inputs"][0]["blake3"], hash, "{rec}");
}

/// The record is part of the output: when it cannot be written (its name is taken by a
/// directory) the .vox is not left behind without it; and a record that would land on
/// the input mesh is refused before any work.
#[test]
fn voxelize_leaves_no_vox_without_its_record() {
    let dir = std::env::temp_dir().join(format!("voxlab-cli-record-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("b.vox");
    std::fs::create_dir_all(dir.join("b.vox.json")).unwrap();
    let o = voxlab(&[
        "voxelize".as_ref(),
        bunny().as_os_str(),
        "--resolution".as_ref(),
        "8".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{stderr}");
    assert!(stderr.contains("b.vox.json"), "{stderr}");
    assert!(!out.exists(), "a .vox without its record was left behind");

    // An input named like the record of the output.
    let input = dir.join("m.vox.json");
    std::fs::copy(bunny(), &input).unwrap();
    let before = std::fs::read(&input).unwrap();
    let o = voxlab(&[
        "voxelize".as_ref(),
        input.as_os_str(),
        "--resolution".as_ref(),
        "8".as_ref(),
        "--out".as_ref(),
        dir.join("m.vox").as_os_str(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("never overwrites its input"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&input).unwrap(), before);
    assert!(!dir.join("m.vox").exists());
    let _ = std::fs::remove_dir_all(&dir);
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

/// Under an address-space limit (`ulimit -v`), a voxelization that cannot fit is refused
/// at once, naming the limit, rather than aborting on a failed allocation minutes in;
/// one that fits still runs under the same limit.
#[test]
fn voxelize_refuses_what_the_memory_limit_cannot_hold() {
    let dir = std::env::temp_dir().join(format!("voxlab-cli-rlimit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let tetra = dir.join("tetra.obj");
    std::fs::write(
        &tetra,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let run = |resolution: u32| {
        let out = dir.join(format!("t{resolution}.vox"));
        let script = format!(
            "ulimit -v 3000000; exec \"$0\" voxelize \"$1\" --resolution {resolution} --out \"$2\""
        );
        let start = std::time::Instant::now();
        let o = Command::new("bash")
            .args(["-c", &script])
            .arg(env!("CARGO_BIN_EXE_voxlab"))
            .arg(&tetra)
            .arg(&out)
            .output()
            .unwrap();
        (o, out, start.elapsed())
    };
    let (o, out, took) = run(1290);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("RLIMIT_AS") && err.contains("coarser resolution"),
        "{err}"
    );
    assert!(took.as_secs() < 30, "refused only after {took:?}");
    assert!(!out.exists());
    let (o, out, _) = run(48);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.exists());
    std::fs::remove_dir_all(&dir).ok();
}
