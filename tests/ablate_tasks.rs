//! The sweep as tasks (`voxlab::ablate::tasks`), what a distributed run rests on: a
//! reference rendered in bands of rows equals the one-piece reference bit for bit, in
//! any order its bands arrive; a task's output survives its encoding exactly and a
//! damaged one is an error, never a panic; `--resume` renders only the points missing,
//! and a resumed sweep writes the same CSV.

use std::path::{Path, PathBuf};
use std::process::Command;

use voxlab::ablate::tasks::{Driver, Task, TaskOutput, Worker};
use voxlab::ablate::{self, AblateConfig, AblateOptions};
use voxlab::experiment::Experiment;

fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("ablate-tasks-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The seed scene at 8^3 under a rect light, 24x20 (bands that do not divide the
/// height evenly), a short CPU sweep.
const TINY: &str = r#"name = "tiny"
[scene]
size = 8
[[lights]]
type = "rect"
position = [7.0, 12.0, 11.0]
normal = [-3.0, -8.0, -7.0]
size = [4.0, 4.0]
intensity = 110.0
[render]
width = 24
height = 20
[ablate]
backend = "cpu"
reference_spp = 16
spp = [1, 4]
seeds = 2
runs = 1
warmup = 0
cone_step_factor = []
cone_aperture_deg = []
transmittance = []
"#;

fn load(dir: &Path) -> (Experiment, AblateConfig, PathBuf) {
    let path = dir.join("tiny.toml");
    std::fs::write(&path, TINY).unwrap();
    let (e, c, _) = ablate::load(&path).unwrap();
    (e, c, path)
}

fn options(dir: &Path, cache: &str) -> AblateOptions {
    AblateOptions {
        out_dir: dir.join(format!("out-{cache}")),
        out_option: "--out",
        cache_dir: Some(dir.join(cache)),
        progress: false,
        log: false,
        watch: None,
        resume: false,
    }
}

/// Does every task of `driver` in `bands` bands per reference half, in the order
/// `order` gives them, through their encoding (as a worker process would send them).
fn run_tasks(
    e: &Experiment,
    c: &AblateConfig,
    driver: &mut Driver,
    bands: u32,
    order: impl Fn(Vec<Task>) -> Vec<Task>,
) {
    let mut worker = Worker::new(c).unwrap();
    for t in order(driver.tasks(bands)) {
        let out = worker.run(e, c, &driver.schedule, &t).unwrap();
        driver
            .put(TaskOutput::decode(&out.encode()).unwrap())
            .unwrap();
    }
}

#[test]
fn a_reference_in_bands_equals_the_one_piece_reference_bit_for_bit() {
    let dir = scratch("bands");
    let (e, c, _) = load(&dir);
    let mut whole = Driver::new(&e, &c, None, &options(&dir, "whole"), "cpu f64").unwrap();
    let tasks = whole.tasks(1);
    assert_eq!(
        tasks
            .iter()
            .filter(|t| matches!(t, Task::ReferenceTile { .. }))
            .count(),
        2,
        "one band per half: {tasks:?}"
    );
    run_tasks(&e, &c, &mut whole, 1, |t| t);
    let one = whole.reference(0).unwrap().clone();
    let report = whole.finish("test").unwrap();
    assert_eq!(report.rows.len(), report.summaries.len() * 2);
    for bands in [2, 7, 20, 64] {
        let mut banded = Driver::new(
            &e,
            &c,
            None,
            &options(&dir, &format!("bands{bands}")),
            "cpu f64",
        )
        .unwrap();
        let tiles = banded
            .tasks(bands)
            .iter()
            .filter(|t| matches!(t, Task::ReferenceTile { .. }))
            .count();
        assert_eq!(tiles as u32, 2 * bands.min(20), "{bands} bands of 20 rows");
        // Bands arrive in any order: reversed here.
        run_tasks(&e, &c, &mut banded, bands, |mut t| {
            t.reverse();
            t
        });
        let r = banded.reference(0).unwrap();
        assert_eq!(r.key, one.key);
        assert!(
            r.frame
                .pixels
                .iter()
                .zip(&one.frame.pixels)
                .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)),
            "{bands} bands differ from the one-piece reference"
        );
        assert_eq!(r.noise_rmse.to_bits(), one.noise_rmse.to_bits());
        // The points measure the same whichever way the reference came, and each row
        // names what rendered it.
        let a = banded.finish("test").unwrap();
        assert_eq!(a.rows.len(), report.rows.len());
        for (x, y) in a.rows.iter().zip(&report.rows) {
            assert_eq!(
                (x.rmse.to_bits(), x.flip_mean.to_bits()),
                (y.rmse.to_bits(), y.flip_mean.to_bits())
            );
            assert!(x.adapter.starts_with("CPU reference (f64"), "{}", x.adapter);
        }
    }
}

#[test]
fn task_outputs_survive_their_encoding_and_damage_is_an_error() {
    let dir = scratch("encoding");
    let (e, c, _) = load(&dir);
    let driver = Driver::new(&e, &c, None, &options(&dir, "cache"), "cpu f64").unwrap();
    let mut worker = Worker::new(&c).unwrap();
    let point = driver
        .tasks(3)
        .into_iter()
        .find(|t| matches!(t, Task::Point { .. }))
        .unwrap();
    let tile = driver.tasks(3)[1].clone();
    for task in [point, tile] {
        let bytes = worker
            .run(&e, &c, &driver.schedule, &task)
            .unwrap()
            .encode();
        let again = TaskOutput::decode(&bytes).unwrap().encode();
        assert_eq!(bytes, again, "{task:?}");
        // Every truncation, a flipped magic byte, a trailing byte, a header that claims
        // an enormous frame: errors.
        for cut in [0, 5, 40, bytes.len() / 2, bytes.len() - 1] {
            assert!(TaskOutput::decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        let mut bad = bytes.clone();
        bad[0] ^= 1;
        assert!(TaskOutput::decode(&bad).is_err());
        let mut long = bytes.clone();
        long.push(0);
        assert!(TaskOutput::decode(&long).is_err());
        let text = String::from_utf8_lossy(&bytes);
        if let Some(at) = text.find("\"size\":[24,") {
            let mut huge = bytes.clone();
            let from = at + "\"size\":[".len();
            huge[from..from + 2].copy_from_slice(b"99");
            assert!(TaskOutput::decode(&huge).is_err());
        }
    }
    // A task the schedule does not have is an error from the worker.
    assert!(
        worker
            .run(&e, &c, &driver.schedule, &Task::Point { index: 999 })
            .is_err()
    );
    let outside = Task::ReferenceTile {
        reference: 0,
        half: 0,
        rows: [10, 40],
    };
    assert!(worker.run(&e, &c, &driver.schedule, &outside).is_err());
}

#[test]
fn the_driver_refuses_outputs_of_another_sweep_and_bands_twice() {
    let dir = scratch("refuse");
    let (e, c, _) = load(&dir);
    let mut driver = Driver::new(&e, &c, None, &options(&dir, "cache"), "cpu f64").unwrap();
    let mut worker = Worker::new(&c).unwrap();
    let band = driver.tasks(4)[0].clone();
    let out = worker.run(&e, &c, &driver.schedule, &band).unwrap();
    driver.put(out.clone()).unwrap();
    let err = driver.put(out).unwrap_err().to_string();
    assert!(err.contains("twice"), "{err}");
    // A band and a point rendered for a sweep at another size.
    let other = dir.join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(
        other.join("tiny.toml"),
        TINY.replace("width = 24", "width = 16"),
    )
    .unwrap();
    let (e2, c2, _) = ablate::load(other.join("tiny.toml")).unwrap();
    let d2 = Driver::new(&e2, &c2, None, &options(&other, "cache"), "cpu f64").unwrap();
    let p = d2
        .tasks(1)
        .into_iter()
        .find(|t| matches!(t, Task::Point { .. }))
        .unwrap();
    let foreign = worker.run(&e2, &c2, &d2.schedule, &p).unwrap();
    let err = driver.put(foreign).unwrap_err().to_string();
    assert!(err.contains("another sweep"), "{err}");
    let band = d2.tasks(4)[1].clone();
    let foreign = Worker::cpu().run(&e2, &c2, &d2.schedule, &band).unwrap();
    let err = driver.put(foreign).unwrap_err().to_string();
    assert!(err.contains("another sweep"), "{err}");
    // Finishing with tasks missing names what is missing.
    let err = driver.finish("test").err().unwrap().to_string();
    assert!(
        err.contains("missing") || err.contains("not rendered"),
        "{err}"
    );
}

fn ablate_cli(path: &Path, out: &Path, cache: &Path, extra: &[&str]) -> (String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["ablate", path.to_str().unwrap(), "--progress", "--out"])
        .arg(out)
        .arg("--cache")
        .arg(cache)
        .args(extra)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(o.status.success(), "{stderr}");
    (
        stderr,
        std::fs::read_to_string(out.join("ablation.csv")).unwrap(),
    )
}

/// Lines of the `--progress` log that say a seed of a point was rendered.
fn rendered_seeds(stderr: &str) -> usize {
    stderr
        .lines()
        .filter(|l| l.starts_with('[') && l.contains(" seed ") && l.contains(" ms ("))
        .count()
}

#[test]
fn resume_renders_only_the_missing_points_and_writes_the_same_csv() {
    let dir = scratch("resume");
    let (_, c, path) = load(&dir);
    let cache = dir.join("cache");
    let (first, csv) = ablate_cli(&path, &dir.join("a"), &cache, &[]);
    let points = csv.lines().count() - 1;
    assert_eq!(rendered_seeds(&first), points, "{first}");
    assert_eq!(points % c.seeds as usize, 0);
    let kept: Vec<PathBuf> = std::fs::read_dir(cache.join("points"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(kept.len() * c.seeds as usize, points);

    // Everything done: nothing renders and the CSV is the same, times included.
    let (again, csv2) = ablate_cli(&path, &dir.join("b"), &cache, &["--resume"]);
    assert_eq!(rendered_seeds(&again), 0, "{again}");
    assert!(
        again.contains(&format!("{} of the points resumed", kept.len())),
        "{again}"
    );
    assert_eq!(csv, csv2);

    // One point lost, one damaged: those two render again, with a word for the damage.
    std::fs::remove_file(&kept[0]).unwrap();
    let bytes = std::fs::read(&kept[1]).unwrap();
    std::fs::write(&kept[1], &bytes[..bytes.len() / 2]).unwrap();
    let (third, csv3) = ablate_cli(&path, &dir.join("c"), &cache, &["--resume"]);
    assert_eq!(rendered_seeds(&third), 2 * c.seeds as usize, "{third}");
    assert!(third.contains("truncated"), "{third}");
    let lines = |s: &str| s.lines().count();
    assert_eq!(lines(&csv3), lines(&csv));
    // Without --resume every point renders again. The run's overrides (here one that
    // restates the file's value) are in every output's record and in run.txt.
    let d = dir.join("d");
    let (fresh, _) = ablate_cli(&path, &d, &cache, &["--set", "ablate.warmup=0"]);
    assert_eq!(rendered_seeds(&fresh), points, "{fresh}");
    for sidecar in ["table.md.json", "plot.png.json", "ablation.csv.json"] {
        let record: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join(sidecar)).unwrap()).unwrap();
        assert_eq!(
            record["overrides"],
            serde_json::json!(["ablate.warmup=0"]),
            "{sidecar}"
        );
    }
    let run_txt = std::fs::read_to_string(d.join("run.txt")).unwrap();
    assert!(
        run_txt.contains("overrides: ablate.warmup=0\n"),
        "{run_txt}"
    );
    let first_run = std::fs::read_to_string(dir.join("a").join("run.txt")).unwrap();
    assert!(first_run.contains("overrides: none\n"), "{first_run}");
}

#[test]
fn resume_takes_a_point_by_what_it_renders_not_by_its_place() {
    let dir = scratch("resume-by-key");
    // The hard min-kt point renders what the baseline does: one key, one file.
    let path = dir.join("tiny.toml");
    std::fs::write(
        &path,
        TINY.replace("transmittance = []", "transmittance = [\"min-kt\"]"),
    )
    .unwrap();
    let cache = dir.join("cache");
    let (first, csv) = ablate_cli(&path, &dir.join("a"), &cache, &[]);
    let points = (csv.lines().count() - 1) / 2;
    assert_eq!(rendered_seeds(&first), 2 * points, "{first}");
    let files = std::fs::read_dir(cache.join("points")).unwrap().count();
    assert_eq!(files, points - 1, "the baseline and min-kt share a key");
    let (again, _) = ablate_cli(&path, &dir.join("b"), &cache, &["--resume"]);
    assert_eq!(rendered_seeds(&again), 0, "{again}");
    assert!(
        again.contains(&format!("{points} of the points resumed")),
        "{again}"
    );
    // A shorter list moves the points after it: they are still done.
    std::fs::write(
        &path,
        TINY.replace("spp = [1, 4]", "spp = [4]")
            .replace("transmittance = []", "transmittance = [\"min-kt\"]"),
    )
    .unwrap();
    let (shorter, _) = ablate_cli(&path, &dir.join("c"), &cache, &["--resume"]);
    assert_eq!(rendered_seeds(&shorter), 0, "{shorter}");
    assert!(!shorter.contains("is not point"), "{shorter}");
}
