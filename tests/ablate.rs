//! `voxlab ablate` on a tiny scene (8^3 seed grid, 32x32, a rect light): the files and
//! their columns, error falling with the sample count, reproducible error columns, and
//! the reference cache (reused when nothing changed, rebuilt when something did).
//!
//! The points that the GPU kernel supports must render on the GPU: a missing adapter
//! fails these tests (`docs/ablation.md`), it does not quietly measure the CPU.

use std::path::{Path, PathBuf};
use std::process::Command;

use voxlab::ablate::{self, AblateConfig, AblateOptions, AblateReport, CSV_COLUMNS};
use voxlab::experiment::Experiment;

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("ablate-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The seed scene at 8^3 under one rect light, Beer-Lambert on; `extra` is appended
/// (an `[ablate]` table, or overrides).
fn experiment_text(intensity: f64, ablate: &str) -> String {
    format!(
        r#"name = "tiny"
[scene]
size = 8
[[lights]]
type = "rect"
position = [7.0, 12.0, 11.0]
normal = [-3.0, -8.0, -7.0]
size = [4.0, 4.0]
intensity = {intensity:?}
[render]
width = 32
height = 32
[features]
transmittance = "beer-lambert"
{ablate}
"#
    )
}

const SWEEP: &str = "[ablate]\nreference_spp = 256\nspp = [1, 2, 4, 8, 16]\nseeds = 2\nruns = 2\nwarmup = 1\n\
                     cone_step_factor = [0.5, 2]\ncone_aperture_deg = [10, 40]\n";

fn load(dir: &Path, text: &str) -> (Experiment, AblateConfig) {
    let path = dir.join("tiny.toml");
    std::fs::write(&path, text).unwrap();
    let (e, c, _) = ablate::load(&path).unwrap();
    (e, c)
}

fn run(e: &Experiment, c: &AblateConfig, out: &Path, cache: &Path) -> AblateReport {
    ablate::run(
        e,
        c,
        Some("# test"),
        &AblateOptions {
            out_dir: out.to_path_buf(),
            out_option: "--out",
            cache_dir: Some(cache.to_path_buf()),
            progress: false,
            log: false,
            watch: None,
            resume: false,
        },
    )
    .unwrap()
}

/// The CSV as a header and rows of fields (the test's values hold no quoted commas but
/// the `fallback` column, which is last).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| {
            l.splitn(header.len(), ',')
                .map(str::to_string)
                .collect::<Vec<_>>()
        })
        .collect();
    (header, rows)
}

fn col<'a>(header: &[String], row: &'a [String], name: &str) -> &'a str {
    let i = header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    &row[i]
}

/// The columns that must not change between two runs of the same experiment.
fn error_columns(path: &Path) -> Vec<Vec<String>> {
    let (h, rows) = read_csv(path);
    rows.iter()
        .map(|r| {
            ["model", "value", "rmse", "psnr", "flip_mean"]
                .iter()
                .map(|c| col(&h, r, c).to_string())
                .collect()
        })
        .collect()
}

#[test]
fn sweep_writes_every_file_and_column_and_error_falls_with_spp() {
    let dir = scratch("sweep");
    let (e, c) = load(&dir, &experiment_text(110.0, SWEEP));
    assert_eq!(c.spp, vec![1, 2, 4, 8, 16]);
    assert_eq!(c.list("cone_step_factor"), [0.5, 2.0]);
    assert_eq!(c.list("cone_aperture_deg"), [10.0, 40.0]);
    let out = dir.join("out");
    let report = run(&e, &c, &out, &dir.join("cache"));

    for f in [
        "ablation.csv",
        "ablation.csv.json",
        "grid.png",
        "plot.png",
        "plot.svg",
        "table.md",
        "table.tex",
        "experiment.toml",
        "resolved.toml",
        "run.txt",
        "images/reference.png",
        "images/reference.exr",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
        assert!(report.files.iter().any(|g| g == f), "{f} not reported");
    }
    for f in &report.files {
        assert!(out.join(f).is_file(), "{f} reported but missing");
    }

    let (header, rows) = read_csv(&out.join("ablation.csv"));
    assert_eq!(header, CSV_COLUMNS);
    // The CSV describes itself in its sidecar: every column's meaning, the build's
    // revision, and the experiment's files with their content hashes.
    let sidecar: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("ablation.csv.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = sidecar["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, header);
    assert!(
        sidecar["columns"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| { c["meaning"].as_str().is_some_and(|m| m.len() >= 8) })
    );
    assert_eq!(sidecar["revision"], voxlab::revision::revision());
    assert_eq!(sidecar["seeds"], 2);
    // Every image carries what made it (a point's: its model, value and seed), and the
    // figures and tables have the run's record beside them.
    let first = report.summaries.iter().find(|r| r.knob == "spp").unwrap();
    let stored: serde_json::Value = serde_json::from_str(
        &voxlab::output::read_png_provenance(out.join(&first.image))
            .unwrap()
            .expect("a point's PNG holds its provenance"),
    )
    .unwrap();
    assert_eq!(stored["revision"], voxlab::revision::revision());
    assert_eq!(stored["image"]["seed"], first.seed);
    assert_eq!(stored["image"]["value"], first.value.as_str());
    for f in ["plot.png", "grid.png", "table.md", "images/reference.exr"] {
        let side: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(format!("{f}.json"))).unwrap())
                .unwrap();
        assert_eq!(side["revision"], voxlab::revision::revision(), "{f}");
        assert_eq!(side["seeds"], 2, "{f}");
    }
    // A FLIP map's record names the two images it compares.
    let flip_map = first.image.replace("images/", "flip/");
    let side: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join(format!("{flip_map}.json"))).unwrap(),
    )
    .unwrap();
    assert_eq!(side["revision"], voxlab::revision::revision());
    assert_eq!(side["image"]["flip_map_of"], first.image.as_str());
    assert_eq!(side["image"]["against"], "images/reference.png");
    let tiny = std::fs::read(dir.join("tiny.toml")).unwrap();
    assert_eq!(
        sidecar["assets"][0]["blake3"],
        blake3::hash(&tiny).to_hex().as_str()
    );
    for required in [
        "model",
        "knob",
        "value",
        "spp",
        "ms_median",
        "ms_runs",
        "trace_ms_median",
        "setup_ms_median",
        "shadow_model",
        "model_settings",
        "rmse",
        "psnr",
        "flip_mean",
    ] {
        assert!(header.iter().any(|h| h == required), "no column {required}");
    }
    // The baseline, then every curve each shadow model declares over its knob: hard
    // shadows with each transmittance model, five stochastic points, two cone step
    // factors and two cone apertures, the plug-ins over the spp list or their setting's
    // declared sweep.
    use voxlab::technique::Knob;
    let curves: usize = voxlab::technique::SHADOW_MODELS
        .iter()
        .flat_map(|m| m.ablate.iter().map(move |curve| (m, curve)))
        .map(|(m, curve)| match curve.knob {
            // The spp curve, and again under each reconstruction where the model
            // samples shadow rays for it to filter.
            Knob::Spp if m.stochastic && m.shadow_rays => {
                c.spp.len() * (1 + c.reconstruction.len())
            }
            Knob::Spp => c.spp.len(),
            Knob::Transmittance => c.transmittance.len(),
            Knob::Own(key) => m.setting(key).unwrap().sweep.len(),
            Knob::Shared { list, .. } => c.list(list).len(),
        })
        .sum();
    // A row per point and seed, the seeds of a point together.
    assert_eq!(c.seeds, 2);
    assert_eq!(rows.len(), 2 * (1 + curves));
    for pair in rows.chunks(2) {
        let point =
            |r: &Vec<String>| ["model", "knob", "value"].map(|k| col(&header, r, k).to_string());
        assert_eq!(point(&pair[0]), point(&pair[1]));
        let seed = |r: &Vec<String>| col(&header, r, "seed").parse::<u32>().unwrap();
        assert_eq!(seed(&pair[1]), seed(&pair[0]) + 1);
    }
    for m in voxlab::technique::SHADOW_MODELS {
        assert!(
            rows.iter()
                .any(|r| col(&header, r, "shadow_model") == m.name),
            "no point of {}",
            m.name
        );
    }
    let models: Vec<&str> = rows.iter().map(|r| col(&header, r, "model")).collect();
    assert_eq!(models[0], "baseline (all off)");
    assert!(models.contains(&"hard (min-kt)"));
    assert!(models.contains(&"hard (beer-lambert)"));
    // The sampled curves again under the a-trous filter, which the plan kept.
    assert!(
        models.contains(&"stochastic + atrous (beer-lambert)"),
        "{models:?}"
    );
    assert!(
        rows.iter()
            .any(|r| col(&header, r, "reconstruction") == "atrous"),
        "no filtered point"
    );
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
        let ms: f64 = col(&header, r, "ms_median").parse().unwrap();
        assert!(ms > 0.0);
        let runs: Vec<f64> = col(&header, r, "ms_runs")
            .split(';')
            .map(|t| t.parse().unwrap())
            .collect();
        assert_eq!(runs.len(), 2);
        // The plotted time is trace + setup; setup is only the cones' pyramid build.
        let trace: f64 = col(&header, r, "trace_ms_median").parse().unwrap();
        let setup: f64 = col(&header, r, "setup_ms_median").parse().unwrap();
        assert!(trace > 0.0 && trace.is_finite() && setup >= 0.0 && setup.is_finite());
        assert!(ms >= trace - 1e-3, "{r:?}");
        // Each point lists the settings its model reads, as key=value.
        let model = voxlab::technique::shadow_model(col(&header, r, "shadow_model")).unwrap();
        let settings: Vec<(&str, f64)> = col(&header, r, "model_settings")
            .split(';')
            .filter(|s| !s.is_empty())
            .map(|kv| {
                let (k, v) = kv.split_once('=').unwrap();
                (k, v.parse().unwrap())
            })
            .collect();
        let reconstruction =
            voxlab::technique::reconstruction(col(&header, r, "reconstruction")).unwrap();
        let declared =
            model.shared_settings.len() + model.settings.len() + reconstruction.settings.len();
        assert_eq!(settings.len(), declared, "{r:?}");
        for (k, v) in settings {
            assert!(v.is_finite(), "{k} of {r:?}");
        }
        if !model.pyramid {
            assert_eq!(setup, 0.0, "{r:?}");
        }
        let rmse: f64 = col(&header, r, "rmse").parse().unwrap();
        let psnr: f64 = col(&header, r, "psnr").parse().unwrap();
        let flip: f64 = col(&header, r, "flip_mean").parse().unwrap();
        assert!(rmse > 0.0 && rmse.is_finite());
        assert!((psnr - 10.0 * (1.0 / (rmse * rmse)).log10()).abs() < 1e-3);
        assert!((0.0..=1.0).contains(&flip));
        // The first seed's image is written; the others are measured only.
        let image = col(&header, r, "image");
        if col(&header, r, "seed_index") == "0" {
            assert!(out.join(image).is_file());
        } else {
            assert!(image.is_empty(), "{r:?}");
        }
        let corrected: f64 = col(&header, r, "rmse_corrected").parse().unwrap();
        let noise: f64 = col(&header, r, "reference_noise_rmse").parse().unwrap();
        assert!((corrected * corrected - (rmse * rmse - noise * noise).max(0.0)).abs() < 1e-9);
    }
    // The table's and the plot's rows: each point's mean over its seeds.
    let points = report.summaries.len();
    assert_eq!(points, 1 + curves);
    assert!(
        report
            .summaries
            .iter()
            .all(|r| r.interval.is_some_and(|i| i.seeds == 2))
    );
    // What the GPU kernel supports runs there; the rest is labelled where it ran.
    let baseline = &report.summaries[0];
    assert_eq!(
        baseline.backend, "gpu",
        "the baseline must render on the GPU"
    );
    for r in &report.summaries {
        assert_eq!(
            r.fallback.is_some(),
            r.backend == "cpu",
            "{} {}: {} ({:?})",
            r.model,
            r.value,
            r.backend,
            r.fallback
        );
    }

    // The cone curves: every point of each model, cone shadows on (hard shadows and
    // stochastic points keep them off), the knob in its column; on the GPU the pyramid
    // build is timed and counted.
    let setting = |r: &ablate::Row, key: &str| {
        r.model_settings
            .iter()
            .find(|(k, _)| k == key)
            .map(|&(_, v)| v)
    };
    let cones: Vec<&ablate::Row> = report
        .summaries
        .iter()
        .filter(|r| r.shadow_model == "cone")
        .collect();
    assert_eq!(cones.len(), 4);
    assert!(
        report
            .rows
            .iter()
            .filter(|r| r.model.starts_with("hard") || r.knob == "spp")
            .all(|r| r.shadow_model != "cone")
    );
    let steps: Vec<&ablate::Row> = cones
        .iter()
        .copied()
        .filter(|r| r.knob == "step_factor")
        .collect();
    assert_eq!(steps.len(), 2);
    assert_eq!(setting(steps[0], "cones.step_factor"), Some(0.5));
    assert_eq!(setting(steps[1], "cones.step_factor"), Some(2.0));
    assert!(steps.iter().all(|r| !r.lights_as_points));
    // The tiny rect light (4x4 at about 10 voxels) subtends some tens of degrees: the
    // cone model says so of the point.
    let note = steps[0].model_note.clone().unwrap();
    let subtended: f64 = note
        .split("subtends ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{note}"));
    assert!((5.0..90.0).contains(&subtended), "{subtended}");
    let apertures: Vec<&ablate::Row> = cones
        .iter()
        .copied()
        .filter(|r| r.knob == "aperture_deg")
        .collect();
    assert_eq!(apertures.len(), 2);
    assert_eq!(setting(apertures[0], "cones.aperture_deg"), Some(10.0));
    assert_eq!(setting(apertures[1], "cones.aperture_deg"), Some(40.0));
    assert!(apertures.iter().all(|r| r.lights_as_points));
    for r in &cones {
        assert!(r.rmse.is_finite() && r.rmse > 0.0 && r.flip_mean.is_finite());
        assert!(r.frame.all_finite());
        assert!((r.ms_median - r.trace_ms_median - r.setup_ms_median).abs() < 0.5 * r.ms_median);
        if r.backend == "gpu" {
            assert!(r.setup_ms_median > 0.0, "GPU pyramid build untimed: {r:?}");
        }
    }
    // Different knob values give different images.
    assert_ne!(steps[0].frame, steps[1].frame);
    assert_ne!(apertures[0].frame, apertures[1].frame);

    // Flicker: none for a first seed; zero for a deterministic model (every seed the
    // same image), above zero for a sampled one at one frame.
    for r in &report.rows {
        match (r.seed_index, r.flicker) {
            (0, f) => assert_eq!(f, None, "{} {}", r.model, r.value),
            (_, None) => panic!("{} {}: no flicker", r.model, r.value),
            (_, Some(f)) if r.shadow_model == "hard" || r.shadow_model == "cone" => {
                assert_eq!(f, 0.0, "{} {}", r.model, r.value)
            }
            (_, Some(f)) if r.shadow_model == "area" && r.spp == 1 => {
                assert!(f > 0.0, "{} {}", r.model, r.value)
            }
            _ => {}
        }
    }
    assert!(header.iter().any(|h| h == "flicker_flip"));

    // Error against the reference falls with every doubling of the samples, and 16x the
    // samples cut the RMSE by more than half (1/4 in theory, plus the reference's noise).
    let stochastic: Vec<&ablate::Row> = report
        .summaries
        .iter()
        .filter(|r| r.knob == "spp" && r.shadow_model == "area" && r.reconstruction == "none")
        .collect();
    assert_eq!(stochastic.len(), 5);
    for w in stochastic.windows(2) {
        assert!(w[1].spp > w[0].spp);
        assert!(
            w[1].rmse < w[0].rmse,
            "rmse rose from spp {} to {}",
            w[0].spp,
            w[1].spp
        );
    }
    assert!(stochastic[4].rmse < 0.5 * stochastic[0].rmse);
    assert!(stochastic[4].flip_mean < stochastic[0].flip_mean);
    // The reference's own noise is below every point's error.
    assert!(report.reference.noise_rmse < stochastic[4].rmse);

    let png = image::open(out.join("plot.png")).unwrap();
    assert!(png.width() >= 800 && png.height() >= 400);
    let svg = std::fs::read_to_string(out.join("plot.svg")).unwrap();
    assert!(
        svg.contains("stochastic (beer-lambert)"),
        "legend text in the SVG"
    );
    let grid = image::open(out.join("grid.png")).unwrap();
    // The reference and every point, each tile at least 128 wide with its label band.
    assert!(grid.width() >= 4 * 128 && grid.height() >= 4 * 128);
    let table = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert_eq!(
        table.lines().filter(|l| l.starts_with("| ")).count(),
        1 + points
    );
    assert!(table.contains("trace + setup"));
    assert!(table.contains(" ± "), "means with their intervals");
    // The Pareto column: the fastest point and the most accurate are on both fronts.
    let measured = &report.summaries;
    let fastest = (0..measured.len())
        .min_by(|&a, &b| measured[a].ms_median.total_cmp(&measured[b].ms_median))
        .unwrap();
    let front = ablate::pareto_front(measured, |r| r.rmse);
    assert!(front[fastest], "the fastest point is on the front");
    for (a, on) in measured.iter().zip(&front) {
        let beaten = measured.iter().any(|b| {
            b.ms_median <= a.ms_median
                && b.rmse <= a.rmse
                && (b.ms_median < a.ms_median || b.rmse < a.rmse)
        });
        assert_eq!(*on, !beaten, "{} {}", a.model, a.value);
    }
    assert!(
        table
            .lines()
            .any(|l| l.ends_with("| RMSE, FLIP |") || l.ends_with("| RMSE |"))
    );
    // The LaTeX table: booktabs, one line per point, LaTeX's specials escaped.
    let tex = std::fs::read_to_string(out.join("table.tex")).unwrap();
    assert!(
        tex.contains("\\toprule") && tex.contains("\\bottomrule"),
        "{tex}"
    );
    assert_eq!(
        tex.lines().filter(|l| l.ends_with("\\\\")).count(),
        1 + points,
        "{tex}"
    );
    assert!(
        tex.contains("step\\_factor") && !tex.contains(" step_factor "),
        "{tex}"
    );
    assert!(tex.contains("\\textbf{"), "{tex}");
    let run_txt = std::fs::read_to_string(out.join("run.txt")).unwrap();
    assert!(run_txt.contains("git revision: ") && run_txt.contains("adapter: "));
    assert!(run_txt.contains("plan: ["));
    let resolved: toml::Table =
        toml::from_str(&std::fs::read_to_string(out.join("resolved.toml")).unwrap()).unwrap();
    assert_eq!(resolved["points"].as_array().unwrap().len(), points);
    assert_eq!(
        resolved["ablate"]["cone_step_factor"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    assert!(
        svg.contains("cone at set aperture"),
        "cone legend text in the SVG"
    );
    assert_eq!(resolved["ablate"]["reference_spp"].as_integer(), Some(256));
}

#[test]
fn reference_cache_is_reused_when_nothing_changed_and_rebuilt_when_something_did() {
    let dir = scratch("cache");
    let cache = dir.join("cache");
    let small = "[ablate]\nreference_spp = 64\nspp = [1, 4]\nruns = 1\nwarmup = 0\n";
    let (e, c) = load(&dir, &experiment_text(110.0, small));

    let first = run(&e, &c, &dir.join("a"), &cache);
    assert!(!first.reference.reused);
    let mtime = std::fs::metadata(&first.reference.path)
        .unwrap()
        .modified()
        .unwrap();

    // Same experiment: the reference comes from the cache, untouched, and every error
    // column is the same (times may differ).
    let second = run(&e, &c, &dir.join("b"), &cache);
    assert!(second.reference.reused);
    assert_eq!(second.reference.key, first.reference.key);
    assert_eq!(
        std::fs::metadata(&second.reference.path)
            .unwrap()
            .modified()
            .unwrap(),
        mtime
    );
    assert_eq!(second.reference.frame, first.reference.frame);
    assert_eq!(
        error_columns(&dir.join("a/ablation.csv")),
        error_columns(&dir.join("b/ablation.csv"))
    );

    // A different sweep does not touch the reference.
    let (e2, c2) = load(
        &dir,
        &experiment_text(
            110.0,
            "[ablate]\nreference_spp = 64\nspp = [2]\nruns = 1\nwarmup = 0\n",
        ),
    );
    assert!(run(&e2, &c2, &dir.join("c"), &cache).reference.reused);

    // A brighter light, or more reference samples, is a new reference.
    let (e3, c3) = load(&dir, &experiment_text(150.0, small));
    let third = run(&e3, &c3, &dir.join("d"), &cache);
    assert!(!third.reference.reused);
    assert_ne!(third.reference.key, first.reference.key);
    let (e4, c4) = load(
        &dir,
        &experiment_text(
            110.0,
            "[ablate]\nreference_spp = 128\nspp = [1, 4]\nruns = 1\nwarmup = 0\n",
        ),
    );
    let fourth = run(&e4, &c4, &dir.join("e"), &cache);
    assert!(!fourth.reference.reused);
    assert_ne!(fourth.reference.key, first.reference.key);
    // And the first is still there to be reused.
    assert!(run(&e, &c, &dir.join("f"), &cache).reference.reused);
}

#[test]
fn ablate_table_errors_name_file_line_and_key() {
    let dir = scratch("errors");
    let path = dir.join("tiny.toml");
    let check = |ablate: &str, line: usize, key: &str, says: &str| {
        std::fs::write(&path, experiment_text(110.0, ablate)).unwrap();
        let err = ablate::load(&path).unwrap_err();
        let msg = err.to_string();
        assert_eq!(err.line(), Some(line), "{msg}");
        assert!(
            msg.starts_with(&format!("{}:{line}:", path.display())),
            "{msg}"
        );
        assert!(msg.contains(key) && msg.contains(says), "{msg}");
    };
    // The [ablate] header is line 15 of experiment_text.
    check("[ablate]\nspp = [4, 2]", 16, "ablate.spp", "ascending");
    check(
        "[ablate]\nreconstruction = [\"none\"]",
        16,
        "ablate.reconstruction",
        "always drawn",
    );
    check(
        "[ablate]\nreconstruction = [\"atrous\", \"atrous\"]",
        16,
        "ablate.reconstruction",
        "twice",
    );
    check("[ablate]\nspp = [0]", 16, "ablate.spp", "1..=65536");
    check("\n[ablate]\nruns = 0", 17, "ablate.runs = 0", "1..=1000");
    check(
        "[ablate]\nspp = [64]\nreference_spp = 32",
        17,
        "ablate.reference_spp = 32",
        "at least the largest swept spp (64)",
    );
    check(
        "[ablate]\ntransmittance = [\"fog\"]",
        16,
        "ablate.transmittance",
        "min-kt",
    );
    check("[ablate]\nbackend = \"tpu\"", 16, "ablate.backend", "auto");
    check(
        "[ablate]\ncone_step_factor = [0.5, 0.25]",
        16,
        "ablate.cone_step_factor",
        "ascending",
    );
    check(
        "[ablate]\nruns = 1\ncone_step_factor = [0, 1]",
        17,
        "ablate.cone_step_factor = [0, 1]",
        "(0, 4]",
    );
    check(
        "[ablate]\ncone_step_factor = [8]",
        16,
        "ablate.cone_step_factor",
        "(0, 4]",
    );
    check(
        "[ablate]\ncone_aperture_deg = [10, 180]",
        16,
        "ablate.cone_aperture_deg",
        "[0, 120]",
    );
    check(
        "[ablate]\ncone_aperture_deg = [nan]",
        16,
        "ablate.cone_aperture_deg",
        "[0, 120]",
    );
    check(
        "[ablate]\ncone_aperture_deg = \"wide\"",
        16,
        "ablate.cone_aperture_deg",
        "must be a list of numbers",
    );
    check("[ablate]\nspp = 4", 16, "ablate.spp", "invalid type");
    // A declared number of the wrong type says what it takes.
    check(
        "[ablate]\nseeds = 1.5",
        16,
        "ablate.seeds = 1.5",
        "expected an integer; must be an integer in 1..=64",
    );
    check(
        "[ablate]\nspp = [1, \"2\"]",
        16,
        "ablate.spp[1]",
        "expected an integer; every entry must be an integer in 1..=65536 (frames)",
    );
    check(
        "[ablate]\nsamples = 4",
        16,
        "ablate.samples",
        "reference_spp",
    );

    // The same file renders with `voxlab render` ([ablate] is allowed there), and the
    // command line reports a bad table before rendering anything.
    std::fs::write(&path, experiment_text(110.0, "[ablate]\nruns = 0")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["ablate", path.to_str().unwrap(), "--out"])
        .arg(dir.join("cli"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("ablate.runs = 0"), "{stderr}");
    assert!(!dir.join("cli").exists());
    assert!(Experiment::load(&path).is_ok());
}

/// `[ablate] sweep`: a curve over any key's values, each point the experiment with that
/// key set; it needs no area light (the reference is then the converged image of the
/// experiment itself), and a value the file would refuse, or a key that changes the
/// scene or the image size, is refused with the file, line and key.
#[test]
fn key_sweeps_measure_any_knob() {
    let dir = scratch("keys");
    let text = "name = \"keys\"\n[scene]\nsize = 8\n[render]\nwidth = 24\nheight = 24\n\
                [ablate]\nreference_spp = 2\nspp = [1]\nseeds = 1\nruns = 1\nwarmup = 0\n\
                sweep = { \"render.max_reflection_depth\" = [0, 1, 4] }\n";
    let (e, c) = load(&dir, text);
    assert_eq!(c.sweeps.len(), 1);
    assert_eq!(c.sweeps[0].points.len(), 3);
    let out = dir.join("out");
    run(&e, &c, &out, &dir.join("cache"));
    let (h, rows) = read_csv(&out.join("ablation.csv"));
    let swept: Vec<(String, f64)> = rows
        .iter()
        .filter(|r| col(&h, r, "model") == "sweep render.max_reflection_depth")
        .map(|r| {
            (
                col(&h, r, "value").to_string(),
                col(&h, r, "rmse").parse().unwrap(),
            )
        })
        .collect();
    assert_eq!(swept.len(), 3, "{rows:?}");
    // Seed lights are points: no shadow curve runs.
    assert!(
        rows.iter()
            .all(|r| !col(&h, r, "model").starts_with("stochastic"))
    );
    assert_eq!(swept[2].0, "4");
    assert!(
        swept[2].1 < 1e-6,
        "depth 4 is the reference's own setting: {swept:?}"
    );
    assert!(
        swept[0].1 > swept[1].1 && swept[1].1 > swept[2].1,
        "{swept:?}"
    );

    let bad = |sweep: &str| {
        let text = format!(
            "[scene]\nsize = 8\n[render]\nwidth = 8\nheight = 8\n[ablate]\nreference_spp = 2\n\
             spp = [1]\nsweep = {sweep}\n"
        );
        let path = dir.join("bad.toml");
        std::fs::write(&path, &text).unwrap();
        ablate::load(&path).expect_err("refused").to_string()
    };
    let e = bad("{ \"render.light_samples\" = [0] }");
    assert!(
        e.contains("bad.toml:9:")
            && e.contains("ablate.sweep")
            && e.contains("render.light_samples")
            && e.contains("1..=65536"),
        "{e}"
    );
    let e = bad("{ \"render.width\" = [16] }");
    assert!(e.contains("image size"), "{e}");
    let e = bad("{ \"render.spp\" = 3 }");
    assert!(e.contains("non-empty list"), "{e}");
    // Keys the rendered plan never reads, decided from the registry: a plug-in's
    // setting under another shadow model, a [cones] setting with no cone feature on.
    let e = bad("{ \"techniques.sdf.softness\" = [0.25, 1.0] }");
    assert!(
        e.contains("never reads techniques.sdf.softness")
            && e.contains("shadow model \"hard\"")
            && e.contains("\"sdf\" would read it"),
        "{e}"
    );
    let e = bad("{ \"cones.step_factor\" = [0.5, 1.0] }");
    assert!(
        e.contains("never reads cones.step_factor") && e.contains("shadow model \"cone\""),
        "{e}"
    );
    // Under the model that reads them, both load.
    for (features, sweep) in [
        (
            "shadow_model = \"sdf\"",
            "{ \"techniques.sdf.softness\" = [0.25, 1.0] }",
        ),
        (
            "ambient_occlusion = true",
            "{ \"cones.step_factor\" = [0.5, 1.0] }",
        ),
    ] {
        let text = format!(
            "[scene]\nsize = 8\n[render]\nwidth = 8\nheight = 8\n[features]\n{features}\n\
             [ablate]\nreference_spp = 2\nspp = [1]\nsweep = {sweep}\n"
        );
        let path = dir.join("good.toml");
        std::fs::write(&path, &text).unwrap();
        let (_, c, _) = ablate::load(&path).unwrap_or_else(|e| panic!("{features}: {e}"));
        assert_eq!(c.sweeps[0].points.len(), 2);
    }
}

/// `voxlab ablate --set`: overrides reach the experiment and the [ablate] table alike.
#[test]
fn overrides_reach_the_ablate_table() {
    let dir = scratch("set");
    let path = dir.join("tiny.toml");
    std::fs::write(&path, experiment_text(110.0, SWEEP)).unwrap();
    let set: Vec<voxlab::experiment::Override> =
        ["ablate.runs=4", "ablate.spp=[1, 2]", "render.width=16"]
            .iter()
            .map(|s| s.parse().unwrap())
            .collect();
    let (e, c, text) = ablate::load_with(&path, &set).unwrap();
    assert_eq!(
        (c.runs, c.spp.clone(), e.settings.width),
        (4, vec![1, 2], 16)
    );
    assert!(text.contains("runs = 4"));
    assert_eq!(
        c.overrides,
        ["ablate.runs=4", "ablate.spp=[1, 2]", "render.width=16"]
    );
    let bad: Vec<voxlab::experiment::Override> = vec!["ablate.runs=0".parse().unwrap()];
    let err = ablate::load_with(&path, &bad).unwrap_err().to_string();
    assert!(
        err.contains("ablate.runs") && err.contains("1..=1000"),
        "{err}"
    );
}

/// A sweep that lists a value twice would write two rows over one image file: refused,
/// naming the key and the value.
#[test]
fn a_sweep_value_listed_twice_is_refused() {
    let dir = scratch("sweep_twice");
    let path = dir.join("tiny.toml");
    std::fs::write(&path, experiment_text(110.0, SWEEP)).unwrap();
    for (sweep, value) in [
        (r#"ablate.sweep={"render.light_samples"=[2, 4, 2]}"#, "2"),
        (
            r#"ablate.sweep={"features.transmittance"=["min-kt", "min-kt"]}"#,
            "min-kt",
        ),
    ] {
        let set: Vec<voxlab::experiment::Override> = vec![sweep.parse().unwrap()];
        let err = ablate::load_with(&path, &set).unwrap_err().to_string();
        assert!(
            err.contains("sweep") && err.contains(&format!("{value} is listed twice")),
            "{sweep}: {err}"
        );
    }
}

/// FLIP is computed on the displayed sRGB image (LDR-FLIP's input), so an equal linear
/// step weighs more in the darks than in the brights, as it looks; fed the linear
/// values as if they were sRGB, both steps would look alike.
#[test]
fn flip_compares_the_srgb_display() {
    use voxlab::Frame;
    let flat = |v: f32| {
        let mut f = Frame::new(32, 32);
        f.pixels.iter_mut().for_each(|p| *p = [v; 3]);
        f
    };
    let (same, map) = voxlab::metrics::flip(&flat(0.3), &flat(0.3));
    assert_eq!(same, 0.0);
    assert_eq!(map.dimensions(), (32, 32));
    let dark = voxlab::metrics::flip_mean(&flat(0.02), &flat(0.04));
    let bright = voxlab::metrics::flip_mean(&flat(0.80), &flat(0.82));
    assert!(
        dark > 2.0 * bright && bright > 0.0,
        "dark {dark}, bright {bright}"
    );
}

/// A sweep over a key that changes the scene (here the camera) measures each point
/// against a converged reference of its own scene: with nothing sampled every point
/// equals its own reference, where against the experiment's it would be far off.
#[test]
fn a_camera_sweep_measures_each_point_against_its_own_reference() {
    let dir = scratch("camera-sweep");
    let text = "name = \"cams\"\n[scene]\nsize = 8\n[render]\nwidth = 24\nheight = 24\n\
                [ablate]\nreference_spp = 2\nspp = [1]\nseeds = 1\nruns = 1\nwarmup = 0\n\
                sweep = { \"camera.yaw_deg\" = [36, 10, -20] }\n";
    let (e, c) = load(&dir, text);
    let own: Vec<bool> = c.sweeps[0]
        .points
        .iter()
        .map(|p| p.scene.is_some())
        .collect();
    assert_eq!(
        own,
        [false, true, true],
        "36 degrees is the seed camera's yaw"
    );
    let out = dir.join("out");
    let report = run(&e, &c, &out, &dir.join("cache"));
    let (h, rows) = read_csv(&out.join("ablation.csv"));
    let swept: Vec<&Vec<String>> = rows
        .iter()
        .filter(|r| col(&h, r, "model") == "sweep camera.yaw_deg")
        .collect();
    assert_eq!(swept.len(), 3);
    for r in &swept {
        let rmse: f64 = col(&h, r, "rmse").parse().unwrap();
        // The reference is the f64 CPU's, the points the GPU's: equal to f32 precision.
        assert!(
            rmse < 1e-4,
            "{} against its own reference: {rmse}",
            col(&h, r, "value")
        );
    }
    assert_eq!(col(&h, swept[1], "own_reference"), "true");
    assert_eq!(col(&h, swept[0], "own_reference"), "false");
    // Against the experiment's reference the turned cameras would differ.
    let turned = report
        .rows
        .iter()
        .find(|r| r.model == "sweep camera.yaw_deg" && r.value == "10")
        .unwrap();
    let off = voxlab::metrics::compare(
        &report.reference.frame,
        &turned.frame,
        voxlab::metrics::Domain::Linear,
        0.0,
    )
    .unwrap();
    assert!(off.rmse > 1e-2, "{}", off.rmse);
    assert!(report.table.contains("reference of their own scene"));
}

/// The stochastic points only, at one spp, over `seeds` seeds (cone curves and key
/// sweeps left out).
fn seeded(seeds: u32, spp: u32) -> String {
    experiment_text(
        110.0,
        &format!(
            "[ablate]\nreference_spp = 64\nspp = [{spp}]\nseeds = {seeds}\nruns = 1\nwarmup = 0\n\
             cone_step_factor = []\ncone_aperture_deg = []\ntransmittance = [\"beer-lambert\"]\n"
        ),
    )
}

/// Seeds draw different samples (a sampled point's error changes with its seed, a
/// deterministic one's does not), and the interval of a point's mean narrows as seeds
/// are added (Student's t over 2 seeds is 12.7, over 6 2.57).
#[test]
fn seeds_draw_new_samples_and_the_interval_narrows_with_more() {
    let dir = scratch("seeds");
    let mut half = Vec::new();
    for seeds in [2, 6] {
        let (e, c) = load(&dir, &seeded(seeds, 1));
        let out = dir.join(format!("out-{seeds}"));
        let report = run(&e, &c, &out, &dir.join("cache"));
        let area: Vec<&ablate::Row> = report
            .rows
            .iter()
            .filter(|r| r.shadow_model == "area" && r.knob == "spp" && r.reconstruction == "none")
            .collect();
        assert_eq!(area.len(), seeds as usize);
        let seeds_used: Vec<u32> = area.iter().map(|r| r.seed).collect();
        assert_eq!(
            seeds_used,
            (0..seeds).map(|k| e.settings.seed + k).collect::<Vec<_>>()
        );
        assert!(
            area.windows(2).all(|w| w[0].rmse != w[1].rmse),
            "each seed draws its own samples"
        );
        let hard: Vec<f64> = report
            .rows
            .iter()
            .filter(|r| r.model == "baseline (all off)")
            .map(|r| r.rmse)
            .collect();
        assert_eq!(hard.len(), seeds as usize);
        assert!(hard.windows(2).all(|w| w[0] == w[1]), "nothing to sample");
        let summary = report
            .summaries
            .iter()
            .find(|r| r.shadow_model == "area" && r.knob == "spp")
            .unwrap();
        let i = summary
            .interval
            .expect("two seeds or more give an interval");
        assert_eq!(i.seeds, seeds);
        let mean = area.iter().map(|r| r.rmse).sum::<f64>() / f64::from(seeds);
        assert!((summary.rmse - mean).abs() < 1e-12);
        assert!(i.rmse > 0.0 && i.flip > 0.0);
        half.push(i.rmse);
    }
    assert!(half[1] < half[0] / 2.0, "interval half-widths {half:?}");
}

/// A point rendered at the reference's own spp (independent seeds) differs from it by
/// both images' noise, sqrt(2) times the reference's: the noise-corrected RMSE takes
/// the reference's share out and leaves the point's own, which equals the reference's
/// noise estimate from its two halves.
#[test]
fn the_reference_noise_is_taken_out_of_the_rmse() {
    let dir = scratch("floor");
    let (e, c) = load(&dir, &seeded(4, 64));
    let report = run(&e, &c, &dir.join("out"), &dir.join("cache"));
    let noise = report.reference.noise_rmse;
    assert!(noise > 0.0 && report.reference.flip_floor > 0.0);
    let point = report
        .summaries
        .iter()
        .find(|r| r.shadow_model == "area" && r.knob == "spp")
        .unwrap();
    assert!(
        (point.rmse / noise - 2f64.sqrt()).abs() < 0.35,
        "measured {} against noise {noise}",
        point.rmse
    );
    assert!(
        (point.rmse_corrected / noise - 1.0).abs() < 0.25,
        "corrected {} against noise {noise}",
        point.rmse_corrected
    );
    // The FLIP floor is each half against the whole: a point as noisy as the reference
    // measures more (its noise and the reference's add), never far less.
    assert!(point.flip_mean > 0.8 * report.reference.flip_floor);
}

/// Before anything long starts, ablate prints its plan with an estimate from
/// calibration renders; with `--progress` off a terminal (a log), a line per step with
/// the share done and an estimate of the time left that is never "0 s" while work
/// remains.
#[test]
fn ablate_prints_its_plan_and_progress_lines_with_a_moving_estimate() {
    let dir = scratch("progress");
    let path = dir.join("tiny.toml");
    std::fs::write(&path, seeded(2, 4)).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["ablate", path.to_str().unwrap(), "--progress", "--out"])
        .arg(dir.join("out"))
        .arg("--cache")
        .arg(dir.join("cache"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let plan = stderr
        .lines()
        .find(|l| l.starts_with("ablate tiny: "))
        .unwrap_or_else(|| panic!("no plan line: {stderr}"));
    assert!(
        plan.contains("x 2 seeds x 1 runs") && plan.contains("in all"),
        "{plan}"
    );
    let steps: Vec<&str> = stderr.lines().filter(|l| l.starts_with('[')).collect();
    assert!(steps.len() >= 4, "{stderr}");
    let percent = |l: &str| l[1..4].trim().parse::<u32>().unwrap();
    assert!(
        steps.windows(2).all(|w| percent(w[0]) <= percent(w[1])),
        "{stderr}"
    );
    assert!(steps.iter().all(|l| l.contains(" left")), "{stderr}");
    assert!(
        steps
            .iter()
            .any(|l| l.starts_with("[") && l.contains("reference half"))
    );
    assert_eq!(percent(steps.last().unwrap()), 100, "{stderr}");
}

/// `[ablate] reference` (another renderer's image): checked before anything renders
/// (an EXR of the experiment's size, finite and non-negative, with `reference_by`,
/// never an output), then every point of the experiment's scene is also measured
/// against it and voxlab's own reference gets its distance to it as a bias.
#[test]
fn an_external_reference_is_checked_and_measured_against() {
    let dir = scratch("external");
    let small = "[ablate]\nreference_spp = 64\nspp = [1, 4]\nseeds = 2\nruns = 1\nwarmup = 0\n\
                 cone_step_factor = []\ncone_aperture_deg = []\ntransmittance = []\n";
    // The "other renderer": voxlab's CPU at 256 spp, written as an EXR.
    let (e, _) = load(&dir, &experiment_text(300.0, small));
    let mut s = e.settings.clone();
    s.spp = 256;
    s.seed = 77;
    s.features.set_shadow_model("area");
    let frame = voxlab::cpu::render(&e.scene, &s).frame;
    voxlab::output::write_frame(&frame, dir.join("other.exr")).unwrap();
    let with = |extra: &str| format!("{small}{extra}");
    let config_error = |extra: &str| {
        let path = dir.join("tiny.toml");
        std::fs::write(&path, experiment_text(300.0, &with(extra))).unwrap();
        ablate::load(&path).unwrap_err().to_string()
    };
    let msg = config_error("reference = \"other.exr\"\n");
    assert!(
        msg.contains("ablate.reference") && msg.contains("reference_by"),
        "{msg}"
    );
    let msg = config_error("reference_by = \"Mitsuba\"\n");
    assert!(msg.contains("ablate.reference_by"), "{msg}");
    let msg = config_error("reference = \"other.png\"\nreference_by = \"x\"\n");
    assert!(
        msg.contains("OpenEXR") && msg.contains("tiny.toml"),
        "{msg}"
    );
    let msg = config_error("reference = \"other.exr\"\nreference_by = \"\"\n");
    assert!(msg.contains("ablate.reference_by"), "{msg}");

    // Checked at run time, before any render: missing, wrong size, NaN, negative.
    let run_error = |file: &str| {
        let (e, c) = load(
            &dir,
            &experiment_text(
                300.0,
                &with(&format!(
                    "reference = \"{file}\"\nreference_by = \"test\"\n"
                )),
            ),
        );
        let out = dir.join("out-bad");
        let err = ablate::run(
            &e,
            &c,
            None,
            &AblateOptions {
                out_dir: out.clone(),
                out_option: "--out",
                cache_dir: None,
                progress: false,
                log: false,
                watch: None,
                resume: false,
            },
        )
        .err()
        .map(|e| format!("{e:#}"))
        .unwrap_or_default();
        assert!(
            !out.join("cache").exists() || out.join("cache").read_dir().unwrap().count() == 0,
            "{file}: a reference was rendered before the check"
        );
        err
    };
    let msg = run_error("missing.exr");
    assert!(
        msg.contains("missing.exr") && msg.contains("ablate.reference"),
        "{msg}"
    );
    let mut wrong = voxlab::frame::Frame::new(16, 32);
    wrong.pixels.iter_mut().for_each(|p| *p = [0.5; 3]);
    voxlab::output::write_frame(&wrong, dir.join("wrong.exr")).unwrap();
    let msg = run_error("wrong.exr");
    assert!(msg.contains("16x32") && msg.contains("32x32"), "{msg}");
    for (name, bad) in [("nan.exr", f32::NAN), ("negative.exr", -1.0)] {
        let mut f = frame.clone();
        f.pixels[33] = [0.1, bad, 0.1];
        voxlab::output::write_frame(&f, dir.join(name)).unwrap();
        let msg = run_error(name);
        assert!(
            msg.contains("pixel (1, 1)") && msg.contains(name),
            "{name}: {msg}"
        );
    }

    // Measured: voxlab's reference and every point of the scene against it.
    let (e, c) = load(
        &dir,
        &experiment_text(
            300.0,
            &with("reference = \"other.exr\"\nreference_by = \"voxlab cpu, 256 spp\"\n"),
        ),
    );
    let out = dir.join("out");
    // The external reference among the outputs is refused.
    let clash = dir.join("clash");
    std::fs::create_dir_all(&clash).unwrap();
    std::fs::copy(dir.join("other.exr"), clash.join("plot-external.png")).unwrap();
    let mut c_clash = c.clone();
    c_clash.external.as_mut().unwrap().path = clash.join("plot-external.png");
    let err = ablate::run(
        &e,
        &c_clash,
        None,
        &AblateOptions {
            out_dir: clash.clone(),
            out_option: "--out",
            cache_dir: None,
            progress: false,
            log: false,
            watch: None,
            resume: false,
        },
    )
    .err()
    .map(|e| e.to_string())
    .unwrap_or_default();
    assert!(err.contains("external reference"), "{err}");

    let report = run(&e, &c, &out, &dir.join("cache"));
    let (x, rows) = report.external.as_ref().expect("an external report");
    // Both are converged images of the same model: the distance is the two noises
    // (the 256-spp image's is half the 64-spp reference's), no bias.
    let noise = report.reference.noise_rmse;
    assert!(
        x.bias_rmse > 0.5 * noise && x.bias_rmse < 2.0 * noise,
        "{} against noise {noise}",
        x.bias_rmse
    );
    let own_rows = report
        .rows
        .iter()
        .filter(|r| r.own_reference.is_none())
        .count();
    assert_eq!(rows.len(), own_rows);
    for (r, own) in rows
        .iter()
        .zip(report.rows.iter().filter(|r| r.own_reference.is_none()))
    {
        assert!(r.rmse.is_finite() && r.rmse > 0.0);
        assert_eq!(
            (&r.model, &r.value, r.seed),
            (&own.model, &own.value, own.seed)
        );
    }
    for f in ablate::EXTERNAL_FILES {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let text = std::fs::read_to_string(out.join("external.txt")).unwrap();
    assert!(
        text.contains("voxlab cpu, 256 spp") && text.contains("reference bias"),
        "{text}"
    );
    let (header, csv_rows) = read_csv(&out.join("ablation-external.csv"));
    assert_eq!(header, CSV_COLUMNS);
    assert_eq!(csv_rows.len(), own_rows);
    let sidecar: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("ablation.csv.json")).unwrap()).unwrap();
    assert_eq!(sidecar["external_reference"]["by"], "voxlab cpu, 256 spp");
    assert!(sidecar["external_reference"]["file"]["blake3"].is_string());

    // A reference of another model (hard shadows) shows as a bias far above the noise.
    let mut hard = e.settings.clone();
    hard.spp = 1;
    let frame = voxlab::cpu::render(&e.scene, &hard).frame;
    voxlab::output::write_frame(&frame, dir.join("hard.exr")).unwrap();
    let (e, c) = load(
        &dir,
        &experiment_text(
            300.0,
            &with("reference = \"hard.exr\"\nreference_by = \"hard\"\n"),
        ),
    );
    let report = run(&e, &c, &dir.join("out-hard"), &dir.join("cache"));
    let (x, _) = report.external.as_ref().unwrap();
    assert!(
        x.bias_rmse > 2.0 * report.reference.noise_rmse,
        "{}",
        x.bias_rmse
    );
}

/// An experiment that asks for a reconstruction: every curve but the filtered ones is
/// drawn without it (the plain sampled curves are what the filtered ones are compared
/// with), and each filtered curve carries it.
#[test]
fn only_the_filtered_curves_carry_the_reconstruction() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let (e, c, _) = ablate::load(root.join("experiments/reconstruction.toml")).unwrap();
    assert_eq!(e.settings.features.reconstruction.name, "svgf");
    let points = ablate::points(&e, &c);
    let mut filtered = 0;
    for p in &points {
        let r = p.settings.features.reconstruction.name;
        match c
            .reconstruction
            .iter()
            .find(|f| p.model.contains(&format!(" + {} (", f.name)))
        {
            Some(f) => {
                assert_eq!(r, f.name, "{}", p.model);
                filtered += 1;
            }
            None => assert_eq!(r, "none", "{}", p.model),
        }
    }
    // stochastic, ratio and solid-angle over the six spp values, under each filter.
    assert!(c.reconstruction.len() >= 2);
    assert_eq!(filtered, 3 * c.spp.len() * c.reconstruction.len());
}

/// Under a camera path the flicker is of each image against the path's frame before it:
/// every seed has one (the first too); a static path of a deterministic model has none
/// to show (the same image twice), an orbit shows the motion; the sampled model's
/// frames differ on a static camera too. The reference is one render of the
/// experiment's camera, so a path leaves its key unchanged.
#[test]
fn a_camera_path_measures_the_flicker_between_its_frames() {
    let dir = scratch("path-flicker");
    let run_with = |orbit: f64| {
        let text = experiment_text(
            110.0,
            "[ablate]\nreference_spp = 64\nspp = [1]\nseeds = 2\nruns = 1\nwarmup = 0\n\
             backend = \"cpu\"\nreference_backend = \"cpu\"\ncone_step_factor = []\n\
             cone_aperture_deg = []\nreconstruction = []\n",
        )
        .replace(
            "[render]\n",
            &format!("[render]\npath_frames = 3\norbit_deg = {orbit}\nwidth = 24\nheight = 24\n"),
        )
        .replace("width = 32\nheight = 32\n", "");
        let (e, c) = load(&dir, &text);
        let out = dir.join(format!("out-{orbit}"));
        run(&e, &c, &out, &dir.join("cache"))
    };
    let still = run_with(0.0);
    let orbit = run_with(3.0);
    assert_eq!(still.reference.key, orbit.reference.key);
    for (report, moving) in [(&still, false), (&orbit, true)] {
        for r in &report.rows {
            let f = r.flicker.unwrap_or_else(|| {
                panic!("{} seed {}: no flicker on a path", r.model, r.seed_index)
            });
            if r.shadow_model == "hard" {
                assert_eq!(f > 0.0, moving, "{} (orbit {moving}): {f}", r.model);
            }
            if r.shadow_model == "area" {
                assert!(f > 0.0, "{}: {f}", r.model);
            }
        }
    }
}
