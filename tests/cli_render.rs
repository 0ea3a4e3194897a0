//! The `voxlab` binary: renders with the CPU reference at small sizes (the CI machine has
//! two cores), prints what it did, and fails cleanly on bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use voxlab::output::{read_exr, read_png};

fn voxlab(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the voxlab binary runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("cli-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn baseline() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/baseline.toml").to_string()
}

fn text(o: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[track_caller]
fn assert_line(stdout: &str, prefix: &str, parts: &[&str]) {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(prefix))
        .unwrap_or_else(|| panic!("no line starting with {prefix:?} in:\n{stdout}"));
    for p in parts {
        assert!(line.contains(p), "line {line:?} lacks {p:?}");
    }
}

#[test]
fn render_baseline_on_the_cpu_writes_the_image_and_reports() {
    let dir = scratch("render");
    let o = voxlab(
        &dir,
        &[
            "render",
            &baseline(),
            "--backend",
            "cpu",
            "--width",
            "64",
            "--height",
            "48",
        ],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "stdout:\n{out}\nstderr:\n{err}");
    assert_line(&out, "experiment:", &["baseline", "baseline.toml"]);
    assert_line(&out, "backend:", &["CPU reference"]);
    assert_line(&out, "plan:", &["REFLECTION", "REFRACTION", "SHADOWS"]);
    assert_line(&out, "image:", &["64x48"]);
    assert_line(&out, "time:", &["ms per frame"]);
    assert_line(&out, "rays:", &["3072 primary"]);
    // The default output is out/<experiment name>.png, relative to the working directory.
    assert_line(&out, "output:", &["out/baseline.png"]);
    let frame = read_png(dir.join("out/baseline.png")).unwrap();
    assert_eq!((frame.width, frame.height), (64, 48));
    // Not a blank image: the seed's cube covers the centre.
    let centre = frame.get(32, 24);
    let corner = frame.get(0, 0);
    assert_ne!(centre, corner);
}

#[test]
fn no_subcommand_renders_the_seed_and_exr_keeps_radiance() {
    let dir = scratch("seed");
    std::fs::create_dir(dir.join("images")).unwrap();
    let o = voxlab(
        &dir,
        &[
            "--backend",
            "cpu",
            "--width",
            "32",
            "--height",
            "32",
            "--out",
            "images/seed.exr",
        ],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "stdout:\n{out}\nstderr:\n{err}");
    assert_line(&out, "experiment:", &["seed", "built-in"]);
    assert_line(&out, "image:", &["32x32"]);
    assert_line(&out, "output:", &["images/seed.exr"]);
    let f = read_exr(dir.join("images/seed.exr")).unwrap();
    assert_eq!((f.width, f.height), (32, 32));
    assert!(f.all_finite());
    // The corner misses the grid: exactly the seed's ambient (f32 of the f64 constant).
    let [r, g, b] = f.get(0, 0);
    assert_eq!([r, g, b], [0.05f32, 0.075, 0.1]);
}

#[test]
fn bad_experiment_fails_with_the_message_and_no_file() {
    let dir = scratch("bad");
    std::fs::write(dir.join("x.toml"), "[render]\nwidth = 0\n").unwrap();
    let o = voxlab(&dir, &["render", "x.toml", "--backend", "cpu"]);
    let (out, err) = text(&o);
    assert!(!o.status.success());
    assert!(
        err.contains("x.toml:2: render.width = 0: must be an integer in 1..=16384"),
        "stderr:\n{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.is_empty(), "{out}");
    assert!(!dir.join("out").exists());

    std::fs::write(dir.join("y.toml"), "[render\n").unwrap();
    let o = voxlab(&dir, &["render", "y.toml", "--backend", "cpu"]);
    let (_, err) = text(&o);
    assert!(!o.status.success());
    assert!(err.contains("y.toml:1: malformed TOML"), "{err}");

    let o = voxlab(&dir, &["render", "missing.toml", "--backend", "cpu"]);
    let (_, err) = text(&o);
    assert!(!o.status.success());
    assert!(err.contains("missing.toml"), "{err}");
}

#[test]
fn bad_output_paths_fail_before_rendering_or_leave_nothing() {
    let dir = scratch("badout");
    let o = voxlab(
        &dir,
        &[
            "--backend",
            "cpu",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
            "a.jpg",
        ],
    );
    let (out, err) = text(&o);
    assert!(!o.status.success());
    assert!(err.contains("a.jpg") && err.contains(".png"), "{err}");
    assert!(out.is_empty(), "rendered before failing:\n{out}");
    assert!(!dir.join("a.jpg").exists());

    std::fs::write(dir.join("file"), b"x").unwrap();
    let o = voxlab(
        &dir,
        &[
            "--backend",
            "cpu",
            "--width",
            "8",
            "--height",
            "8",
            "--out",
            "file/a.png",
        ],
    );
    let (_, err) = text(&o);
    assert!(!o.status.success());
    assert!(err.contains("file/a.png"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_arguments_are_usage_errors() {
    let dir = scratch("args");
    for args in [
        &["--width", "0", "--height", "8"][..],
        &["--width", "8"][..],
        &["--backend", "tpu"][..],
        &["render"][..],
    ] {
        let o = voxlab(&dir, args);
        let (_, err) = text(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains("error"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(std::fs::read_dir(&dir).unwrap().next().is_none());
}

/// With `--backend gpu` and no adapter, the CPU reference renders and says so. The
/// adapter is hidden by pointing the Vulkan and EGL loaders at no driver; where that
/// cannot hide it (another backend answers), the GPU render is checked instead.
#[test]
fn gpu_backend_without_adapter_falls_back_to_the_cpu_labelled() {
    let dir = scratch("fallback");
    let o = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["--width", "16", "--height", "16", "--out", "f.png"])
        .current_dir(&dir)
        .env("VK_ICD_FILENAMES", "/nonexistent/icd.json")
        .env("VK_DRIVER_FILES", "/nonexistent/icd.json")
        .env("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/egl.json")
        .output()
        .unwrap();
    let (out, err) = text(&o);
    assert!(o.status.success(), "stdout:\n{out}\nstderr:\n{err}");
    let backend = out.lines().find(|l| l.starts_with("backend:")).unwrap();
    if !backend.contains("GPU ") {
        assert!(
            backend.contains("CPU reference") && backend.contains("fallback, no GPU adapter"),
            "{backend}"
        );
        assert!(
            err.contains("rendering with the CPU reference instead"),
            "{err}"
        );
    }
    assert!(dir.join("f.png").exists());
}

/// A reader that goes away (`voxlab ... | head`) ends the process quietly: no panic
/// from printing to a closed pipe.
#[test]
fn a_closed_stdout_is_no_panic() {
    use std::process::Stdio;
    for args in [
        vec!["techniques"],
        vec![
            "render",
            "experiments/baseline.toml",
            "--width",
            "8",
            "--height",
            "8",
            "--backend",
            "cpu",
            "--out",
        ],
    ] {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_voxlab"));
        cmd.args(&args);
        if args.len() > 1 {
            cmd.arg(std::env::temp_dir().join(format!("voxlab-pipe-{}.png", std::process::id())));
        }
        let mut child = cmd
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take());
        let out = child.wait_with_output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
}

#[test]
fn an_output_into_a_missing_directory_is_an_error_and_the_default_out_is_created() {
    let dir = scratch("missing-dir");
    let args = ["--backend", "cpu", "--width", "8", "--height", "8"];
    let o = voxlab(&dir, &[&args[..], &["--out", "typo/seed.png"]].concat());
    let (out, err) = text(&o);
    assert!(!o.status.success(), "stdout:\n{out}");
    assert!(
        err.contains("--out typo/seed.png") && err.contains("typo does not exist"),
        "{err}"
    );
    assert!(!dir.join("typo").exists(), "no directory made");
    let o = voxlab(&dir, &args);
    assert!(o.status.success(), "{}", text(&o).1);
    assert!(
        dir.join("out/seed.png").is_file(),
        "the default out/ is created"
    );
}

#[test]
fn progress_goes_to_stderr_as_lines_when_asked() {
    let dir = scratch("progress");
    for backend in ["cpu", "gpu"] {
        let o = voxlab(
            &dir,
            &[
                "render",
                &format!(
                    "{}/experiments/area_lights.toml",
                    env!("CARGO_MANIFEST_DIR")
                ),
                "--backend",
                backend,
                "--width",
                "16",
                "--height",
                "16",
                "--spp",
                "4",
                "--progress",
                "--json",
            ],
        );
        let (out, err) = text(&o);
        assert!(o.status.success(), "{err}");
        // The CPU counts rows, the GPU frames.
        let done = if backend == "cpu" {
            "(16/16 rows"
        } else {
            "(4/4 frames"
        };
        let last = err
            .lines()
            .rfind(|l| l.starts_with("progress:"))
            .unwrap_or_else(|| panic!("{err}"));
        assert!(
            last.contains("area_lights: 100.0 % ") && last.contains(done),
            "{last}"
        );
        assert!(
            !out.contains("progress"),
            "stdout holds the record alone: {out}"
        );
        assert_eq!(out.lines().count(), 1, "{out}");
    }
}

/// `voxlab bench --plan`: each scene's reduced kernel against the full one
/// (`Plan::with_all_code`), which must render the same image.
#[test]
fn bench_plan_compares_the_reduced_kernel_with_the_full_one() {
    let dir = scratch("bench-plan");
    let o = voxlab(
        &dir,
        &[
            "bench",
            "--plan",
            "--sizes",
            "8",
            "--size",
            "16",
            "--gpu-runs",
            "1",
            "--json",
        ],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let rows: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    assert_eq!(rows.len(), 3, "{out}");
    for r in &rows {
        assert_eq!(r["max_diff"].as_f64(), Some(0.0), "{r}");
        assert!(r["full_ms"].as_f64().unwrap() > 0.0, "{r}");
    }
}

#[test]
fn bench_json_prints_one_object_per_row() {
    let dir = scratch("bench-json");
    let o = voxlab(
        &dir,
        &[
            "bench",
            "--sizes",
            "4,8",
            "--size",
            "16",
            "--gpu-runs",
            "1",
            "--cpu-runs",
            "1",
            "--json",
        ],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let rows: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
        .collect();
    // Every registered walk, by default.
    let walks: Vec<&str> = voxlab::technique::TRAVERSALS
        .iter()
        .map(|t| t.name)
        .collect();
    let n = walks.len();
    assert_eq!(
        rows.len(),
        8 * n,
        "two sizes, both rule sets, two backends, every walk: {out}"
    );
    for walk in &walks {
        assert_eq!(
            rows.iter().filter(|r| r["traversal"] == *walk).count(),
            8,
            "{out}"
        );
    }
    // voxlab's rules, then the seed's, at each size; the seed's trace fewer rays.
    for (size, pair) in rows.chunks(4 * n).enumerate() {
        let (own, seed) = pair.split_at(2 * n);
        assert!(
            own.iter()
                .all(|r| !r["scene"].as_str().unwrap().contains("seed rules"))
        );
        assert!(
            seed.iter()
                .all(|r| r["scene"].as_str().unwrap().contains("seed rules"))
        );
        let rays = |r: &serde_json::Value| {
            ["primary", "secondary", "shadow"]
                .iter()
                .map(|k| r["rays"][k].as_u64().unwrap())
                .sum::<u64>()
        };
        assert!(rays(&seed[0]) < rays(&own[0]), "size {size}: {pair:?}");
    }
    for r in &rows {
        assert_eq!(r["bench"], "seed");
        assert_eq!(r["image_side"], 16);
        assert!(r["ms_per_frame"].as_f64().unwrap() > 0.0, "{r}");
        // The timed frames behind the median: one run of each here.
        assert_eq!(
            r["ms_per_frame_runs"],
            serde_json::json!([r["ms_per_frame"]]),
            "{r}"
        );
        // A whole call of a warm tracer: the device's time and what the host adds.
        assert!(r["wall_ms_per_call"].as_f64().unwrap() > 0.0, "{r}");
        if r["backend"] == "cpu" {
            assert_eq!(r["wall_ms_per_call"], r["ms_per_frame"], "{r}");
        }
        assert!(r["adapter"].as_str().is_some_and(|a| !a.is_empty()), "{r}");
        // The processor the figures come from (a software adapter runs on it too).
        assert!(
            r["host"]
                .as_str()
                .is_some_and(|h| h.contains("hardware threads")),
            "{r}"
        );
        assert!(r["steps_per_ray"].as_f64().unwrap() > 0.0, "{r}");
    }
    // Per size: the GPU's walks, then the CPU's; both tracers and every walk count the
    // same rays (steps may differ by the few rays f32 and f64 walk differently).
    for size in rows.chunks(2 * n) {
        let backends: Vec<_> = size
            .iter()
            .map(|r| r["backend"].as_str().unwrap())
            .collect();
        assert_eq!(backends[..n], vec!["gpu"; n], "{size:?}");
        assert_eq!(backends[n..], vec!["cpu"; n], "{size:?}");
        for r in &size[1..] {
            assert_eq!(r["rays"], size[0]["rays"], "{size:?}");
        }
        for g in 0..n {
            assert_eq!(size[g]["traversal"], size[n + g]["traversal"]);
        }
    }
}

/// A ray offset below what the kernel's f32 resolves on the scene is accepted (it is in
/// the key's range) and warned of on a GPU render: the image then parts from the
/// reference's at faces. At the default no warning.
#[test]
fn a_ray_offset_below_the_kernels_resolution_is_warned_of() {
    let dir = scratch("ray-offset");
    for (offset, warned) in [("0", true), ("1e-7", true), ("0.001", false)] {
        let o = voxlab(
            &dir,
            &[
                "render",
                &baseline(),
                "--width",
                "8",
                "--height",
                "8",
                "--set",
                &format!("render.ray_offset={offset}"),
                "--out",
                "x.png",
            ],
        );
        let (_, stderr) = text(&o);
        assert!(o.status.success(), "{stderr}");
        let warning = stderr
            .lines()
            .find(|l| l.starts_with("warning: render.ray_offset"));
        assert_eq!(warning.is_some(), warned, "{offset}: {stderr}");
        if let Some(w) = warning {
            assert!(
                w.contains("16x16x16 grid") && w.contains("two f32 ulps are"),
                "{w}"
            );
        }
    }
}

/// `render --check` compares the GPU image with the f64 reference's on a crop: it
/// agrees on a plain render and on a temporal reconstruction's path end (whose
/// reference renders the whole path: a crop without the history drew 22 % of
/// reconstruction.toml's pixels apart at 24x24, and the check failed on the shipped
/// experiment); where rays pass through voxel edges and corners (an eye on a lattice
/// point, 1.4 % apart) it agrees by the stress suite's test of the pixels the
/// reference itself moves under a turn of the rays, and says so; and it fails, saying
/// so, where the two do part (a ray offset of 1e-9, below what the f32 kernel
/// resolves, 39 % apart with none of them ill-conditioned).
#[test]
fn check_compares_like_with_like() {
    let dir = scratch("check");
    let experiments = concat!(env!("CARGO_MANIFEST_DIR"), "/experiments");
    let cases: [(&str, &[&str], bool); 6] = [
        ("baseline.toml", &[], true),
        ("stress/eye_on_lattice.toml", &[], true),
        ("stress/camera_in_glass.toml", &[], true),
        ("reconstruction.toml", &[], true),
        (
            "reconstruction.toml",
            &[
                "render.path_frames=3",
                "render.orbit_deg=-2",
                "techniques.svgf.alpha=0.5",
            ],
            true,
        ),
        ("area_lights.toml", &["render.ray_offset=1e-9"], false),
    ];
    for (file, sets, agrees) in cases {
        let mut args: Vec<String> = ["render", &format!("{experiments}/{file}")]
            .iter()
            .map(|s| s.to_string())
            .collect();
        for s in sets {
            args.extend(["--set".to_string(), s.to_string()]);
        }
        args.extend(
            [
                "--width", "24", "--height", "24", "--check", "--out", "x.png",
            ]
            .map(String::from),
        );
        let args: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        let o = voxlab(&dir, &args);
        let (stdout, stderr) = text(&o);
        assert_eq!(
            o.status.success(),
            agrees,
            "{file} {sets:?}: {stdout}\n{stderr}"
        );
        if file.starts_with("stress/") {
            // Apart beyond the GPU tests' tolerance, only at ill-conditioned pixels.
            assert!(
                stdout.contains("are ill-conditioned")
                    && stdout.contains("agrees within the stress suite's tolerance"),
                "{stdout}"
            );
        } else if agrees {
            assert!(
                stdout.contains("agrees within the GPU tests' tolerance"),
                "{stdout}"
            );
        } else {
            assert!(
                stderr.contains("differs from the CPU reference"),
                "{stderr}"
            );
        }
        let whole_path = stdout.contains("renders the whole path");
        assert_eq!(
            whole_path,
            file == "reconstruction.toml",
            "{file}: {stdout}"
        );
    }
}

/// A file whose name is no experiment name (a space, a letter outside ASCII, a leading
/// '.') and that gives none renders under its stem made valid, to the default path: it
/// once rendered and then failed to write the image's record.
#[test]
fn a_file_name_that_is_no_experiment_name_still_renders_and_writes() {
    let dir = scratch("stem-names");
    let text = std::fs::read_to_string(baseline()).unwrap();
    for (file, name) in [
        ("my scene.toml", "my_scene"),
        ("\u{fc}ber.toml", "_ber"),
        (".hidden.toml", "_hidden"),
    ] {
        std::fs::write(dir.join(file), &text).unwrap();
        let o = voxlab(
            &dir,
            &[
                "render",
                file,
                "--backend",
                "cpu",
                "--width",
                "8",
                "--height",
                "8",
            ],
        );
        let (stdout, stderr) = self::text(&o);
        assert!(o.status.success(), "{file}: {stderr}");
        let png = dir.join("out").join(format!("{name}.png"));
        assert!(png.is_file(), "{file}: no {}\n{stdout}", png.display());
        let record =
            std::fs::read_to_string(dir.join("out").join(format!("{name}.png.json"))).unwrap();
        let record: serde_json::Value = serde_json::from_str(&record).unwrap();
        assert_eq!(record["experiment"], name, "{file}");
    }
}

/// `voxlab settings` lists every declared number of a file once, in columns: each line
/// starts with its key and what it does starts at the same place on every line.
#[test]
fn settings_lists_every_declared_number_in_columns() {
    let o = voxlab(Path::new("."), &["settings"]);
    let (stdout, stderr) = text(&o);
    assert!(o.status.success(), "{stderr}");
    let lines: Vec<&str> = stdout.lines().collect();
    let want: Vec<String> = voxlab::settings::file_settings()
        .into_iter()
        .flat_map(|(table, s)| s.into_iter().map(move |s| format!("{table}.{}", s.key)))
        .collect();
    assert_eq!(lines.len(), want.len() + 1, "{stdout}");
    for (line, key) in lines[1..].iter().zip(&want) {
        assert_eq!(line.split_whitespace().next(), Some(key.as_str()), "{line}");
    }
    let doc_at = lines[0].find("what it does").unwrap();
    let settings = voxlab::settings::file_settings();
    let docs = settings.iter().flat_map(|(_, s)| s.iter().map(|s| s.doc));
    for (line, doc) in lines[1..].iter().zip(docs) {
        assert_eq!(line.get(doc_at..), Some(doc), "{line}");
    }
}

/// A ratio the bench prints between two walks carries the range of its rounds, and the
/// table each row's range: a comparison with no spread would call noise a finding.
#[test]
fn bench_ratios_carry_the_range_of_their_rounds() {
    let dir = scratch("bench-ratios");
    let o = voxlab(
        &dir,
        &[
            "bench",
            "--sizes",
            "8",
            "--size",
            "16",
            "--gpu-runs",
            "4",
            "--no-cpu",
            "--traversal",
            "dense,octant",
        ],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("| median ms/frame | runs' range ms |"),
        "{out}"
    );
    let line = out
        .lines()
        .find(|l| l.contains("octant is ") && l.contains("dense's speed"))
        .unwrap_or_else(|| panic!("no ratio of octant to dense:\n{out}"));
    assert!(line.contains(" round by round)"), "{line}");
}

/// Radiance past f32's range is an infinity in the GPU image and in the reference alike
/// (which rounds its f64 sums to f32 once): `--check` takes the same infinities as
/// agreeing. It failed such a render, printing figures that passed (the displayed values
/// clamp an infinity to 1), with "differs by more than the GPU tests allow".
#[test]
fn check_agrees_where_both_images_hold_the_same_infinities() {
    let dir = scratch("check-infinite");
    let exp = dir.join("bright.toml");
    std::fs::write(
        &exp,
        "[[materials]]\nname = \"glass\"\nemission = [1e38, 1e38, 1e38]\n\
         [render]\nwidth = 8\nheight = 8\n",
    )
    .unwrap();
    let o = voxlab(
        &dir,
        &["render", "bright.toml", "--check", "--out", "bright.exr"],
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{out}\n{err}");
    assert!(out.contains("check:      agrees"), "{out}");
    let image = read_exr(dir.join("bright.exr")).unwrap();
    assert!(
        image.pixels.iter().flatten().any(|c| c.is_infinite()),
        "the scene no longer overflows f32; the test needs a brighter one"
    );
}
