//! The layers of `src/` (docs/layout.md): each module imports only its own layer and the
//! ones below, so a technique never reaches into a tracer and a tracer never into an
//! application. Read from the source text: every `crate::<module>` path outside
//! comments counts.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, lowest first, and the top-level modules of each.
const LAYERS: &[(&str, &[&str])] = &[
    (
        "model",
        &[
            "scene", "frame", "geometry", "sampling", "sparse", "surface", "input", "output",
            "metrics", "progress", "revision",
        ],
    ),
    ("walks", &["dda", "triangles", "device"]),
    (
        "techniques",
        &["settings", "render", "technique", "plan", "ray_cutoff"],
    ),
    ("experiments", &["experiment", "error"]),
    ("tracers", &["accumulation", "cpu", "gpu"]),
    (
        "applications",
        &[
            "session", "ablate", "bench", "stress", "info", "viewer", "export", "commands",
        ],
    ),
];

fn rank(module: &str) -> Option<usize> {
    LAYERS.iter().position(|(_, mods)| mods.contains(&module))
}

/// The top-level module a file of `src/` belongs to (`None`: the binary's main.rs, which
/// is an application of the facade, and lib.rs, which lists the modules).
fn module_of(src: &Path, file: &Path) -> Option<String> {
    let rel = file.strip_prefix(src).unwrap();
    let first = rel.components().next()?.as_os_str().to_str()?.to_string();
    let name = first.trim_end_matches(".rs").to_string();
    (!matches!(name.as_str(), "main" | "lib")).then_some(name)
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The text without `//` comments (doc comments cite other modules freely).
fn code(text: &str) -> String {
    text.lines()
        .map(|l| match l.find("//") {
            // A `//` inside a string literal ("http://") is rare in src/ and only hides
            // the rest of that line.
            Some(i) => &l[..i],
            None => l,
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// The modules a path after `crate::` names: one (`cpu::render`), or each at the top
/// level of a group (`{cpu::{self, Dda}, gpu}`).
fn first_segments(rest: &str) -> Vec<String> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let Some(group) = rest.strip_prefix('{') else {
        return vec![ident(rest)]
            .into_iter()
            .filter(|s| !s.is_empty())
            .collect();
    };
    let (mut depth, mut names, mut start) = (0, Vec::new(), 0);
    for (i, c) in group.char_indices() {
        match c {
            '{' => depth += 1,
            '}' if depth == 0 => {
                names.push(ident(group[start..].trim_start()));
                break;
            }
            '}' => depth -= 1,
            ',' if depth == 0 => {
                names.push(ident(group[start..].trim_start()));
                start = i + 1;
            }
            _ => {}
        }
    }
    names.into_iter().filter(|s| !s.is_empty()).collect()
}

/// Every (module, module it imports, file) of `src/`.
fn imports() -> Vec<(String, String, PathBuf)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut out = Vec::new();
    for file in files {
        let Some(from) = module_of(&src, &file) else {
            continue;
        };
        let text = code(&std::fs::read_to_string(&file).unwrap());
        for (i, _) in text.match_indices("crate::") {
            for to in first_segments(&text[i + 7..]) {
                if to != from {
                    out.push((from.clone(), to, file.clone()));
                }
            }
        }
    }
    out
}

#[test]
fn every_module_has_a_layer() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let unplaced: BTreeSet<String> = files
        .iter()
        .filter_map(|f| module_of(&src, f))
        .filter(|m| rank(m).is_none())
        .collect();
    assert!(
        unplaced.is_empty(),
        "modules in no layer of tests/layers.rs: {unplaced:?}"
    );
}

#[test]
fn no_module_imports_a_higher_layer() {
    let mut violations = BTreeMap::new();
    for (from, to, file) in imports() {
        let (Some(a), Some(b)) = (rank(&from), rank(&to)) else {
            continue;
        };
        if b <= a {
            continue;
        }
        violations
            .entry(format!(
                "{from} ({}) imports {to} ({})",
                LAYERS[a].0, LAYERS[b].0
            ))
            .or_insert_with(BTreeSet::new)
            .insert(file.display().to_string());
    }
    assert!(violations.is_empty(), "{violations:#?}");
}

#[test]
fn techniques_never_import_a_tracer_and_tracers_never_each_other() {
    for (from, to, file) in imports() {
        let tracer = matches!(to.as_str(), "cpu" | "gpu");
        assert!(
            !(tracer && matches!(from.as_str(), "technique" | "plan" | "cpu" | "gpu")),
            "{} ({from}) imports the {to} tracer",
            file.display()
        );
    }
}

/// Most lines a function of `src/` has without saying why it is not split.
const LONG_FUNCTION: usize = 150;

/// Each function of `src/` over [`LONG_FUNCTION`] lines, with its file and length, and
/// whether the comments right above it say why it stays one function (the words "one
/// function"). A function ends at the first line that closes its indentation.
fn long_functions() -> Vec<(PathBuf, String, usize, bool)> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut out = Vec::new();
    for file in files {
        let text = std::fs::read_to_string(&file).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        for (i, line) in lines.iter().enumerate() {
            let body = line.trim_start();
            let indent = &line[..line.len() - body.len()];
            let signature = [
                "fn ",
                "pub fn ",
                "pub(crate) fn ",
                "pub(super) fn ",
                "const fn ",
            ]
            .iter()
            .any(|p| body.starts_with(p));
            // WGSL in a Rust string has `fn` lines too; they end in `{{`.
            if !signature || line.ends_with(';') || line.ends_with("{{") {
                continue;
            }
            let close = format!("{indent}}}");
            let Some(end) = (i + 1..lines.len()).find(|&j| lines[j] == close) else {
                continue;
            };
            let length = end - i + 1;
            if length <= LONG_FUNCTION {
                continue;
            }
            let name = body[body.find("fn ").unwrap_or(0)..]
                .split('(')
                .next()
                .unwrap_or(body)
                .to_string();
            let comments = lines[..i]
                .iter()
                .rev()
                .take_while(|l| {
                    let t = l.trim_start();
                    t.starts_with("//") || t.starts_with("#[")
                })
                .map(|l| l.to_lowercase())
                .collect::<Vec<_>>()
                .join(" ");
            out.push((
                file.clone(),
                name,
                length,
                comments.contains("one function"),
            ));
        }
    }
    out
}

#[test]
fn a_long_function_says_why_it_is_one() {
    let unexplained: Vec<String> = long_functions()
        .into_iter()
        .filter(|(_, _, _, why)| !why)
        .map(|(file, name, length, _)| format!("{} {name}: {length} lines", file.display()))
        .collect();
    assert!(
        unexplained.is_empty(),
        "functions over {LONG_FUNCTION} lines whose comment does not say why they are one \
         function (split them, or say why): {unexplained:#?}"
    );
}
