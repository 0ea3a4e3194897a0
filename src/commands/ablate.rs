//! `voxlab ablate`: its arguments, and the sweep run and summarised (`voxlab::ablate`).

// The binary's shared argument parsers and imports (main.rs).
use crate::*;

#[derive(Args, Debug)]
pub(crate) struct AblateArgs {
    /// The experiment file (TOML); its [ablate] table sets the sweep (every key optional).
    experiment: PathBuf,
    /// Output directory. Default: out/ablate/<experiment name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Where converged references and the points done are kept (by a hash of what
    /// they depend on). Default: <out>/cache.
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Take the points an earlier run of the same sweep left in the cache (one that
    /// was stopped): only the missing ones are rendered, the others keep their
    /// measured times.
    #[arg(long)]
    resume: bool,
    /// Override any key of the file, [ablate] included (e.g. `--set ablate.runs=1`,
    /// `--set render.width=64`); repeatable, checked exactly like the file.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
    /// Report progress as lines (each step, the share done, the time left) also when
    /// standard error is not a terminal, for logs; a terminal shows a bar anyway.
    #[arg(long)]
    progress: bool,
}

pub(crate) fn cmd_ablate(a: &AblateArgs) -> Result<()> {
    use voxlab::ablate;
    let (e, config, text) = ablate::load_with(&a.experiment, &a.set)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join("ablate").join(&e.name));
    let opts = ablate::AblateOptions {
        out_dir: out.clone(),
        out_option: "--out",
        cache_dir: a.cache.clone(),
        progress: true,
        log: a.progress,
        watch: None,
        resume: a.resume,
    };
    let report = ablate::run(&e, &config, Some(&text), &opts)?;
    println!("{}", report.table);
    let r = &report.reference;
    println!(
        "reference: {} ({}, key {})",
        r.path.display(),
        if r.reused {
            "reused from the cache"
        } else {
            "rendered"
        },
        &r.key[..16]
    );
    println!("wrote {} files under {}", report.files.len(), out.display());
    Ok(())
}
