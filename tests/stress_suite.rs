//! The whole stress suite (every `docs/stress.md` case but the large cube) passes, and
//! `voxlab stress` prints and writes the table.

mod common;

use common::tracer;
use std::process::Command;

use voxlab::stress::{SuiteOptions, Verdict, cases, csv, markdown, run};

#[test]
fn every_stress_case_is_finite_and_matches_the_oracle() {
    let mut gpu = tracer();
    let opts = SuiteOptions {
        max_grid_side: gpu.max_grid_side(),
        cube: None,
    };
    let all = cases(&opts).unwrap();
    let rows = run(Some(&mut gpu), &all, |_| {});
    let adapter = gpu.adapter_summary();
    let md = markdown(&rows, &adapter);
    println!("{md}");
    for r in &rows {
        assert!(r.cpu_finite, "{}: CPU image not finite", r.name);
        assert_eq!(r.verdict(), Verdict::Pass, "{}: {:?}", r.name, r.verdict());
        assert!(md.contains(&format!("| {} |", r.name)));
        assert!(r.flip_mean.is_some_and(|f| f.is_finite()));
    }
    assert_eq!(csv(&rows).lines().count(), rows.len() + 1);
    // Every file under experiments/stress/ is in the suite.
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/stress");
    let files = std::fs::read_dir(dir).unwrap().count();
    assert_eq!(files, voxlab::stress::STRESS_FILES.len());
}

#[test]
fn stress_command_writes_markdown_and_csv() {
    let out = std::env::temp_dir().join(format!("voxlab-stress-{}", std::process::id()));
    let run = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["stress", "--cube", "0", "--only", "grid-1x1x1", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("| grid-1x1x1 |"), "{stdout}");
    let md = std::fs::read_to_string(out.join("stress.md")).unwrap();
    let csv = std::fs::read_to_string(out.join("stress.csv")).unwrap();
    assert!(md.contains("| grid-1x1x1 |") && md.contains("pass"));
    assert_eq!(csv.lines().count(), 2);
    assert!(csv.starts_with("case,what,"));
    // Each table's record beside it: the build, the adapter, the cases.
    for name in ["stress.md.json", "stress.csv.json"] {
        let rec: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(name)).unwrap()).unwrap();
        assert_eq!(rec["made_by"], "voxlab stress", "{rec}");
        assert_eq!(rec["revision"], voxlab::revision::revision());
        assert_eq!(rec["cases"], serde_json::json!(["grid-1x1x1"]), "{rec}");
        assert!(rec["gpu"].as_str().is_some_and(|g| !g.is_empty()), "{rec}");
    }
    let bad = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(["stress", "--only", "no-such-case", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    let _ = std::fs::remove_dir_all(&out);
}
