//! Progress of a long render on standard error: on a terminal, one line rewritten in
//! place once a render has run for a second; elsewhere (a log, a pipe) only when asked
//! (`--progress`), as whole lines. Never on standard output, which carries the report
//! or the `--json` records.
//!
//! A [`Watch`] lets another thread follow a render and stop it: the Python bindings
//! drive a progress bar from it and stop the render on Ctrl-C.

use std::io::{IsTerminal, Write};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How often a line is written at most.
const INTERVAL: Duration = Duration::from_millis(250);
/// On a terminal, a render shorter than this prints nothing.
const QUIET_START: Duration = Duration::from_secs(1);

/// A render followed from another thread: the units done and to do, as the tracer
/// reports them, and a request to stop that the tracers honour between rows (CPU) or
/// dispatches (GPU).
#[derive(Debug, Default)]
pub struct Watch {
    done: AtomicU64,
    total: AtomicU64,
    stop: AtomicBool,
}

impl Watch {
    pub fn new() -> Arc<Self> {
        Arc::new(Self::default())
    }

    /// `(done, total)` units of the render so far (`(0, 0)` before the first report).
    pub fn done(&self) -> (u64, u64) {
        (
            self.done.load(Ordering::Relaxed),
            self.total.load(Ordering::Relaxed),
        )
    }

    /// Records that `done` of `total` units are finished.
    pub fn report(&self, done: u64, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        self.done.fetch_max(done, Ordering::Relaxed);
    }

    /// Asks the render to stop: it returns an error of kind `Interrupted`, no image.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Relaxed);
    }

    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::Relaxed)
    }
}

/// A reporter of `done / total` units of work (frames, rows), shared by the threads of a
/// render (`Sync`).
pub struct Progress {
    label: String,
    unit: &'static str,
    start: Instant,
    /// Forced (`--progress`): every interval, from the start, as whole lines.
    forced: bool,
    terminal: bool,
    /// Whether lines are printed at all (a watched render may print none).
    print: bool,
    watch: Option<Arc<Watch>>,
    state: Mutex<State>,
}

struct State {
    last: Option<Instant>,
    printed: bool,
    finished: bool,
}

impl Progress {
    /// A reporter for `label` (e.g. the experiment's name) counting in `unit`s; `forced`
    /// prints even when standard error is not a terminal. `None` when nothing would
    /// ever be printed.
    pub fn new(label: impl Into<String>, unit: &'static str, forced: bool) -> Option<Self> {
        let terminal = std::io::stderr().is_terminal();
        (forced || terminal).then(|| Self {
            label: label.into(),
            unit,
            start: Instant::now(),
            forced,
            terminal,
            print: true,
            watch: None,
            state: Mutex::new(State {
                last: None,
                printed: false,
                finished: false,
            }),
        })
    }

    /// A reporter that prints nothing and tells `watch`, which may stop the render.
    pub fn watched(watch: Arc<Watch>, unit: &'static str) -> Self {
        Self {
            label: String::new(),
            unit,
            start: Instant::now(),
            forced: false,
            terminal: false,
            print: false,
            watch: Some(watch),
            state: Mutex::new(State {
                last: None,
                printed: false,
                finished: false,
            }),
        }
    }

    /// Whether the render may be asked to stop (it has a [`Watch`]).
    pub(crate) fn can_stop(&self) -> bool {
        self.watch.is_some()
    }

    /// Whether the render was asked to stop (by its [`Watch`]).
    pub fn stopped(&self) -> bool {
        self.watch.as_ref().is_some_and(|w| w.stopped())
    }

    /// Reports that `done` of `total` units are finished.
    pub fn update(&self, done: u64, total: u64) {
        if let Some(w) = &self.watch {
            w.report(done, total);
        }
        if !self.print {
            return;
        }
        let now = Instant::now();
        let elapsed = now - self.start;
        let Ok(mut s) = self.state.lock() else {
            return;
        };
        if s.finished {
            return;
        }
        let last = done >= total;
        let due = s.last.is_none_or(|t| now - t >= INTERVAL);
        let started = self.forced || elapsed >= QUIET_START;
        if !(started && (due || last)) {
            return;
        }
        s.last = Some(now);
        s.printed = true;
        s.finished = last;
        let percent = if total == 0 {
            100.0
        } else {
            100.0 * done as f64 / total as f64
        };
        let eta = if done > 0 && !last {
            let left = elapsed.as_secs_f64() * (total - done) as f64 / done as f64;
            format!(", about {left:.0} s left")
        } else {
            String::new()
        };
        let line = format!(
            "progress:   {}: {percent:5.1} % ({done}/{total} {}, {:.1} s{eta})",
            self.label,
            self.unit,
            elapsed.as_secs_f64()
        );
        let mut err = std::io::stderr().lock();
        // A terminal shows one line, rewritten; its last state stays on screen.
        let _ = if self.terminal && !self.forced {
            write!(err, "\r\x1b[2K{line}{}", if last { "\n" } else { "" })
        } else {
            writeln!(err, "{line}")
        };
        let _ = err.flush();
    }

    /// Ends a terminal line left unfinished (a render that failed half-way).
    pub fn finish(&self) {
        if let Ok(mut s) = self.state.lock()
            && s.printed
            && !s.finished
        {
            s.finished = true;
            if self.terminal && !self.forced {
                let _ = writeln!(std::io::stderr());
            }
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.finish();
    }
}
