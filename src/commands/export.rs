//! `voxlab export`: its arguments and the scene written for another renderer (`voxlab::export`).

// The binary's shared argument parsers and imports (main.rs).
use crate::*;

#[derive(Args, Debug)]
pub(crate) struct ExportArgs {
    /// The experiment file (TOML); without one, the seed scene.
    experiment: Option<PathBuf>,
    /// The renderer to write for.
    #[arg(long, value_enum)]
    to: ExportTarget,
    /// The directory to write scene.xml, meshes/ and scene.xml.json into (created when
    /// missing).
    dir: PathBuf,
    /// Refuse any part of the scene the renderer can hold only approximately (each is
    /// listed with its key).
    #[arg(long)]
    strict: bool,
    /// Override any key of the experiment file (repeatable; as `render --set`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub(crate) enum ExportTarget {
    /// Mitsuba 3 (scene format 3.0.0).
    Mitsuba,
}

pub(crate) fn cmd_export(a: &ExportArgs) -> Result<()> {
    let ExportTarget::Mitsuba = a.to;
    let (e, text) = match &a.experiment {
        Some(p) => {
            // The text the experiment was parsed from, not a second read of the file.
            let e = Experiment::load_with(p, &a.set)?;
            let read = match &e.source_record {
                Some(r) => r.text.to_string(),
                None => voxlab::experiment::read_text(p)?,
            };
            let text = voxlab::experiment::apply_overrides(&read, &a.set)?;
            (e, text)
        }
        None => (
            Experiment::from_str_with("", "seed", &a.set)?,
            String::new(),
        ),
    };
    let scene = voxlab::export::write_mitsuba(&e, &text, &a.dir, a.strict)?;
    println!(
        "{}: {} ({} triangles in {} mesh(es)), {} approximation(s)",
        e.name,
        a.dir.join("scene.xml").display(),
        scene.triangles,
        scene.files.len() - 1,
        scene.approximations.len()
    );
    for ap in &scene.approximations {
        println!("  approximation: {}: {}", ap.key, ap.mapping);
    }
    Ok(())
}
