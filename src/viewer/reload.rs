//! Hot reload: the viewer watches its experiment file and the files it reads (the
//! scene's `.vox` or mesh, its models', an OBJ's material libraries:
//! `experiment::write::input_files`), and rebuilds its state when one of them changes
//! on disk (saved from an editor, or from MagicaVoxel), as `voxlab view` built it at the
//! start (`--set` overrides and `--left/--right` lists included). Polled from the
//! window's frame loop, at most every `INTERVAL`: one `stat` a file per poll, no watcher
//! thread.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

use anyhow::Result;

use super::{ViewOptions, ViewerState, load_state};

/// How often the file's modification time is read.
pub const INTERVAL: Duration = Duration::from_millis(500);

pub struct Watch {
    opts: ViewOptions,
    path: PathBuf,
    /// The files watched, the experiment first, each with the modification time and
    /// length last loaded (or last failed to load; `None`: missing then). The list is
    /// taken again from the experiment at each load: an edit may name other files.
    seen: Vec<(PathBuf, Option<(SystemTime, u64)>)>,
    last_poll: Option<Instant>,
    /// The first watched file the last reload found changed.
    changed: Option<PathBuf>,
}

impl Watch {
    /// A watch of `opts.experiment`; `None` for the built-in seed scene (no file).
    pub fn new(opts: ViewOptions) -> Option<Self> {
        let path = opts.experiment.clone()?;
        let seen = stamps(&watched(&path, &opts));
        Some(Self {
            opts,
            path,
            seen,
            last_poll: None,
            changed: None,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The first watched file the last reload found changed (the experiment, or a
    /// file it reads).
    pub fn changed(&self) -> Option<&Path> {
        self.changed.as_deref()
    }

    /// The files watched: the experiment and the files it read at the last load.
    pub fn files(&self) -> impl Iterator<Item = &Path> {
        self.seen.iter().map(|(p, _)| p.as_path())
    }

    /// `Some` when a watched file changed since the last load: the new state, or why it
    /// does not load (each change is tried once; a file being written shows up again
    /// when the writer finishes, as a new change).
    pub fn poll(&mut self) -> Option<Result<ViewerState>> {
        if self.last_poll.is_some_and(|t| t.elapsed() < INTERVAL) {
            return None;
        }
        self.last_poll = Some(Instant::now());
        // A missing experiment is a file being replaced (or gone): nothing to load yet.
        stamp(&self.path)?;
        let changed = self
            .seen
            .iter()
            .find(|(p, seen)| stamp(p) != *seen)?
            .0
            .clone();
        self.changed = Some(changed);
        // Stamped before the load, so a change during it shows up at the next poll.
        self.seen = stamps(&watched(&self.path, &self.opts));
        Some(load_state(&self.opts))
    }
}

/// The experiment at `path` and every file it reads with `opts`' overrides applied
/// (`input_files`); the experiment alone where its text cannot be read or overridden
/// (the load says why).
fn watched(path: &Path, opts: &ViewOptions) -> Vec<PathBuf> {
    let text = crate::input::read_file(path, crate::input::MAX_EXPERIMENT_BYTES, "experiment")
        .ok()
        .and_then(|b| String::from_utf8(b).ok())
        .and_then(|t| crate::experiment::apply_overrides(&t, &opts.overrides).ok());
    match text {
        Some(t) => crate::experiment::write::input_files(&t, path),
        None => vec![path.to_path_buf()],
    }
}

fn stamps(files: &[PathBuf]) -> Vec<(PathBuf, Option<(SystemTime, u64)>)> {
    files.iter().map(|f| (f.clone(), stamp(f))).collect()
}

/// The file's modification time and length (either changes on a save).
fn stamp(path: &Path) -> Option<(SystemTime, u64)> {
    let m = std::fs::metadata(path).ok()?;
    Some((m.modified().ok()?, m.len()))
}
