//! `voxlab stress`: its arguments and the run of the extreme cases (`voxlab::stress`).

// The binary's shared argument parsers and imports (main.rs).
use crate::*;

#[derive(Args, Debug)]
pub(crate) struct StressArgs {
    /// Directory for stress.md and stress.csv.
    #[arg(long, value_name = "DIR", default_value = "out/stress")]
    out: PathBuf,
    /// Side of the large-cube case (the seed scene at N^3; 0 leaves it out).
    #[arg(long, value_name = "N", default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(0..=1290))]
    cube: u32,
    /// Run only the cases whose name contains this text.
    #[arg(long, value_name = "TEXT")]
    only: Option<String>,
}

pub(crate) fn cmd_stress(a: &StressArgs) -> Result<()> {
    voxlab::output::check_directory_output(
        "--out",
        &a.out,
        "stress writes a directory (stress.md, stress.csv and their records)",
    )
    .map_err(anyhow::Error::msg)?;
    // A missing adapter is reported in every row (and fails them), not hidden.
    let mut gpu = match GpuTracer::new() {
        Ok(t) => Some(t),
        Err(e) => {
            eprintln!("warning: no GPU adapter ({e:#}); every case will fail its GPU half");
            None
        }
    };
    let adapter = gpu
        .as_ref()
        .map(|t| t.adapter_summary())
        .unwrap_or_else(|| "none".to_string());
    let opts = voxlab::stress::SuiteOptions {
        max_grid_side: gpu.as_ref().map_or(4096, |t| t.max_grid_side()),
        cube: (a.cube > 0).then_some(a.cube),
    };
    let mut cases = voxlab::stress::cases(&opts)?;
    if let Some(f) = &a.only {
        cases.retain(|c| c.name.contains(f.as_str()));
        anyhow::ensure!(!cases.is_empty(), "no stress case name contains {f:?}");
    }
    eprintln!("GPU: {adapter}\nCPU: {}", voxlab::cpu::backend_summary());
    let rows = voxlab::stress::run(gpu.as_mut(), &cases, |r| {
        eprintln!("  {}: {:?}", r.name, r.verdict())
    });
    let table = voxlab::stress::markdown(&rows, &adapter);
    println!("{table}");
    let record = voxlab::output::record(
        "voxlab stress",
        &[],
        serde_json::json!({
            "gpu": adapter,
            "cpu": voxlab::cpu::backend_summary(),
            "host": voxlab::cpu::host_summary(),
            "cube": a.cube,
            "only": a.only,
            "cases": rows.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
        }),
    );
    let (md, csv) = voxlab::stress::write_tables(&a.out, &rows, &adapter, &record)?;
    println!(
        "wrote {} and {} (records: .json beside each)",
        md.display(),
        csv.display()
    );
    let failed = rows
        .iter()
        .filter(|r| matches!(r.verdict(), voxlab::stress::Verdict::Fail(_)))
        .count();
    anyhow::ensure!(failed == 0, "{failed} stress case(s) failed");
    Ok(())
}
