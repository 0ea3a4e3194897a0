//! Hot reload: the viewer watches its experiment file and rebuilds its state when the
//! file changes on disk (saved from an editor), as `voxlab view` built it at the start
//! (`--set` overrides and `--left/--right` lists included). Polled from the window's
//! frame loop, at most every `INTERVAL`: one `stat` per poll, no watcher thread.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime};

use anyhow::Result;

use super::{ViewOptions, ViewerState, load_state};

/// How often the file's modification time is read.
pub const INTERVAL: Duration = Duration::from_millis(500);

pub struct Watch {
    opts: ViewOptions,
    path: PathBuf,
    /// Modification time and length last loaded (or last failed to load).
    seen: Option<(SystemTime, u64)>,
    last_poll: Option<Instant>,
}

impl Watch {
    /// A watch of `opts.experiment`; `None` for the built-in seed scene (no file).
    pub fn new(opts: ViewOptions) -> Option<Self> {
        let path = opts.experiment.clone()?;
        let seen = stamp(&path);
        Some(Self {
            opts,
            path,
            seen,
            last_poll: None,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// `Some` when the file changed since the last load: the new state, or why it does
    /// not load (each change is tried once; a file being written shows up again when
    /// the writer finishes, as a new change).
    pub fn poll(&mut self) -> Option<Result<ViewerState>> {
        if self.last_poll.is_some_and(|t| t.elapsed() < INTERVAL) {
            return None;
        }
        self.last_poll = Some(Instant::now());
        let now = stamp(&self.path);
        if now.is_none() || now == self.seen {
            return None;
        }
        self.seen = now;
        Some(load_state(&self.opts))
    }
}

/// The file's modification time and length (either changes on a save).
fn stamp(path: &Path) -> Option<(SystemTime, u64)> {
    let m = std::fs::metadata(path).ok()?;
    Some((m.modified().ok()?, m.len()))
}
