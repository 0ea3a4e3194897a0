//! `voxlab view`: an interactive window (egui on its wgpu integration) that compares two
//! feature sets of the same scene side by side, on the tracer `voxlab render` uses.
//!
//! - `state`: the model (shared scene, two sides, orbit camera, adaptive resolution),
//!   kept exact by a TOML round trip after every edit;
//! - `worker`: one render thread per side and one for references, each with its own
//!   `GpuTracer`, accumulating progressively;
//! - `app`: the window;
//! - `display`: how the images are shown (view modes, exposure, zoom, probe geometry);
//! - `reload`: the experiment file and the files it reads watched, reloaded on change.

pub mod app;
pub mod bench;
pub mod display;
pub mod reload;
pub mod state;
pub mod worker;

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use anyhow::{Context, Result, anyhow};
use eframe::egui;

use crate::experiment::Experiment;
pub use app::{Automation, Channel, Outcome, ViewerApp};
pub use state::{Side, ViewerState};

/// What `voxlab view` was asked for.
#[derive(Clone, Debug, Default)]
pub struct ViewOptions {
    /// The experiment (None: the seed scene).
    pub experiment: Option<PathBuf>,
    /// Feature lists for the sides (`SideSettings::parse_list`).
    pub left: Option<String>,
    pub right: Option<String>,
    /// Camera turn applied before the first frame, degrees (yaw, pitch).
    pub orbit: Option<(f64, f64)>,
    /// Window inner size in points.
    pub window: (f32, f32),
    pub automation: Option<Automation>,
    /// `--set KEY=VALUE` overrides of the experiment (`crate::experiment::Override`).
    pub overrides: Vec<crate::experiment::Override>,
    /// The image area's first view mode, exposure and encoding.
    pub display: display::Display,
}

/// Loads the experiment and builds the viewer's state (no window: testable).
pub fn load_state(opts: &ViewOptions) -> Result<ViewerState> {
    let mut state = match &opts.experiment {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read experiment file {}", p.display()))?;
            let e = Experiment::load_with(p, &opts.overrides).map_err(|e| anyhow!("{e}"))?;
            // The text the experiment was parsed from, so the scene source (and every
            // export) holds the overrides too.
            let text = crate::experiment::apply_overrides(&text, &opts.overrides)?;
            ViewerState::new(e, Some(&text), Some(p.clone()))?
        }
        None if opts.overrides.is_empty() => {
            ViewerState::new(Experiment::seed_default(), None, None)?
        }
        None => {
            let e = Experiment::from_str_with("", "seed", &opts.overrides)
                .map_err(|e| anyhow!("{e}"))?;
            ViewerState::new(e, None, None)?
        }
    };
    for (side, list) in [(Side::Left, &opts.left), (Side::Right, &opts.right)] {
        if let Some(l) = list {
            state.sides[side.index()]
                .parse_list(l)
                .with_context(|| format!("--{}", side.name()))?;
        }
    }
    state.commit(&Side::BOTH)?;
    if let Some((yaw, pitch)) = opts.orbit {
        state.orbit_degrees(yaw, pitch)?;
    }
    Ok(state)
}

/// Opens the window and runs until it is closed. With automation, an error during the
/// run (a worker that failed, a save that failed) is returned as this call's error.
pub fn run(opts: ViewOptions) -> Result<Outcome> {
    let state = load_state(&opts)?;
    let outcome = Arc::new(Mutex::new(Outcome::default()));
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(format!("voxlab view: {}", state.base.name))
            .with_inner_size([opts.window.0, opts.window.1]),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let automation = opts.automation.clone();
    let app_outcome = outcome.clone();
    let watch_opts = opts.clone();
    eframe::run_native(
        "voxlab view",
        native,
        Box::new(move |cc| {
            let (report_tx, reports) = std::sync::mpsc::channel();
            let mut workers = Vec::new();
            let mut jobs = Vec::new();
            for (i, channel) in [
                Channel::Side(Side::Left),
                Channel::Side(Side::Right),
                Channel::Reference,
            ]
            .into_iter()
            .enumerate()
            {
                let (tx, rx) = std::sync::mpsc::channel();
                let ctx = cc.egui_ctx.clone();
                let reports = report_tx.clone();
                let name = ["left", "right", "reference"][i];
                workers.push(worker::Worker::spawn(
                    name,
                    rx,
                    move |r| {
                        let _ = reports.send((channel, r));
                    },
                    move || ctx.request_repaint(),
                )?);
                jobs.push(tx);
            }
            let jobs: [_; 3] = jobs.try_into().expect("three job queues");
            let mut app = ViewerApp::new(state, jobs, reports, automation, app_outcome);
            app.display = watch_opts.display.clone();
            app.watch(watch_opts);
            Ok(Box::new(WindowApp {
                app,
                _workers: workers,
            }))
        }),
    )
    .map_err(|e| anyhow!("the viewer window failed: {e}"))?;
    let o = outcome.lock().expect("outcome lock").clone();
    if let Some(e) = &o.error {
        return Err(anyhow!("{e}"));
    }
    Ok(o)
}

/// The app with the workers it owns (they stop when the window closes).
struct WindowApp {
    app: ViewerApp,
    _workers: Vec<worker::Worker>,
}

impl eframe::App for WindowApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.app.show(ui);
    }
}
