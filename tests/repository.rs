//! The repository stands alone: a plain clone with nothing beside it has every file the
//! code, the tests and the experiments read.

use std::path::{Path, PathBuf};

fn files_under(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            files_under(&p, out);
        } else {
            out.push(p);
        }
    }
}

#[test]
fn nothing_reads_a_folder_beside_the_repository() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // Spelled in two parts so that this file does not match itself.
    let sibling = format!("../{}", "shared");
    let mut files = Vec::new();
    for dir in ["src", "tests", "experiments", "shaders", ".ci"] {
        files_under(&root.join(dir), &mut files);
    }
    files.push(root.join("Cargo.toml"));
    let mut offenders = Vec::new();
    for f in &files {
        let Ok(text) = std::fs::read_to_string(f) else {
            continue; // binary data (models, golden images)
        };
        if text.contains(&sibling) {
            offenders.push(f.strip_prefix(root).unwrap().display().to_string());
        }
    }
    assert!(
        offenders.is_empty(),
        "files that read {sibling}: {offenders:?}"
    );
}

#[test]
fn the_example_data_carries_its_licences() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/data");
    let readme = std::fs::read_to_string(data.join("README.md")).unwrap();
    let mut files = Vec::new();
    files_under(&data, &mut files);
    for f in files {
        let name = f.file_name().unwrap().to_str().unwrap();
        if name == "README.md" || name.starts_with("LICENSE") {
            continue;
        }
        assert!(
            readme.contains(&format!("`{name}`")),
            "experiments/data/{name} has no row (source, licence) in its README"
        );
    }
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for licence in ["LICENSE-MIT", "LICENSE-APACHE"] {
        assert!(root.join(licence).is_file(), "{licence} is missing");
    }
}
