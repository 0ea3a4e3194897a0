//! Records the git revision the binary is built from (and whether its sources differ
//! from it) as `VOXLAB_REVISION`, so every output names the code that made it even
//! after the checkout moves on (`src/revision.rs`).

use std::path::Path;
use std::process::Command;

/// What decides the binary: a change to any of these makes it "-dirty".
const SOURCES: &[&str] = &["src", "shaders", "build.rs", "Cargo.toml", "Cargo.lock"];

fn git(dir: &Path, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .ok()?;
    out.status
        .success()
        .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

fn main() {
    let dir = std::env::var("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let dir = Path::new(&dir);
    let revision = match git(dir, &["rev-parse", "HEAD"]) {
        Some(rev) if !rev.is_empty() => {
            let mut status = vec!["status", "--porcelain", "--untracked-files=no", "--"];
            status.extend_from_slice(SOURCES);
            let dirty = git(dir, &status).is_some_and(|s| !s.is_empty());
            if dirty { format!("{rev}-dirty") } else { rev }
        }
        // A tarball, or no git on the machine.
        _ => "unknown".to_string(),
    };
    println!("cargo:rustc-env=VOXLAB_REVISION={revision}");
    // Again when HEAD moves or the index changes (a commit, a checkout, an add), and when
    // a source changes (its dirty state).
    if let Some(git_dir) = git(dir, &["rev-parse", "--absolute-git-dir"]) {
        for f in ["HEAD", "index", "packed-refs", "refs"] {
            let p = Path::new(&git_dir).join(f);
            if p.exists() {
                println!("cargo:rerun-if-changed={}", p.display());
            }
        }
    }
    for s in SOURCES {
        println!("cargo:rerun-if-changed={s}");
    }
}
