//! The viewer's window: a split view of two sides over one camera, the panels that edit
//! the scene and each side, and the bookkeeping that keeps the render workers busy with
//! the current state. The model lives in `state`; rendering in `worker`.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use eframe::egui;
use egui::{Color32, ColorImage, Rect, Sense, TextureHandle, TextureOptions, Vec2, pos2};
use glam::DVec3;

use super::display::{self, Display, ViewMode, Zoom};
use super::state::{
    AdaptiveScale, LightKind, MAX_VIEW_SPP, ShadowModel, Side, SideSettings, ViewerState,
    scaled_size,
};
use super::worker::{Job, Report, Update};
use crate::experiment::Experiment;
use crate::frame::Frame;
use crate::metrics::{Domain, compare};
use crate::scene::{AreaShape, Dielectric, Emission, Light};

/// One row of a declared setting (`crate::technique::Setting`): a drag value over its
/// declared range; true when it changed to a value the declaration's check accepts.
fn setting_row(ui: &mut egui::Ui, setting: &crate::settings::Setting, v: &mut f64) -> bool {
    let row = ui.label(setting.key).id;
    let changed = setting_edit(ui, row, setting, v);
    ui.end_row();
    changed
}

/// The drag value of [`setting_row`], named by `label`.
fn setting_edit(
    ui: &mut egui::Ui,
    label: egui::Id,
    setting: &crate::settings::Setting,
    v: &mut f64,
) -> bool {
    use crate::settings::Kind;
    let (lo, hi) = setting.widget_range();
    let decimals = matches!(setting.kind, Kind::Int { .. }).then_some(0);
    let mut edited = *v;
    let mut value = egui::DragValue::new(&mut edited)
        .range(lo..=hi)
        .speed((hi - lo).min(100.0) / 1000.0);
    if let Some(d) = decimals {
        value = value.max_decimals(d);
    }
    let changed = ui.add(value).labelled_by(label).changed();
    match setting.check(edited) {
        Ok(x) if changed => {
            *v = x;
            true
        }
        _ => false,
    }
}

/// A row for each of the declared `fields` (`crate::settings`) of `target` that `shown`
/// keeps; true when one changed.
fn field_rows<T>(
    ui: &mut egui::Ui,
    fields: &'static [crate::settings::Field<T>],
    target: &mut T,
    shown: impl Fn(&str) -> bool,
) -> bool {
    let mut changed = false;
    for f in fields.iter().filter(|f| shown(f.key())) {
        let mut v = (f.get)(target);
        if setting_row(ui, &f.setting, &mut v) {
            (f.set)(target, v);
            changed = true;
        }
    }
    changed
}

/// One row of a plug-in technique's declared setting, read from and written to `params`.
fn technique_setting_row(
    ui: &mut egui::Ui,
    technique: &str,
    setting: &crate::technique::Setting,
    params: &mut crate::technique::TechniqueParams,
) -> bool {
    let mut v = params.get(technique, setting);
    let changed = setting_row(ui, setting, &mut v);
    if changed {
        params.set(technique, setting.key, v);
    }
    changed
}

/// Where a report came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channel {
    Side(Side),
    Reference,
}

/// Offsets added to the seed of a reference, so it draws samples independent of the
/// sides it is compared with (as `voxlab ablate` does).
const REFERENCE_SEED_OFFSET: u32 = 0x9E37_79B9;

/// Converged references kept in memory.
const MAX_KEPT_REFERENCES: usize = 4;

/// Default frames of a converged reference.
pub(crate) const DEFAULT_REFERENCE_SPP: u32 = 256;

/// What the viewer does without a user: accumulate `frames` on both sides at full
/// resolution, save both sides and a window capture into `save_dir`, then close (the
/// end-to-end test, and scripted figures).
#[derive(Clone, Debug)]
pub struct Automation {
    pub frames: u32,
    pub save_dir: PathBuf,
    pub exit: bool,
}

/// How an automated run ended, for the command's exit status.
#[derive(Clone, Debug, Default)]
pub struct Outcome {
    pub saved: Vec<PathBuf>,
    pub error: Option<String>,
}

/// The error of one side against its converged reference.
#[derive(Clone, Debug)]
pub struct SideError {
    pub frames: u32,
    pub rmse: f64,
    pub psnr: f64,
    /// Mean FLIP (NVIDIA's perceptual error), computed on request.
    pub flip: Option<f64>,
}

/// A side as the window shows it.
#[derive(Default)]
struct SideView {
    texture: Option<TextureHandle>,
    /// The frame the texture shows (kept to redraw it under another display transform);
    /// when `latest` is `None` it is of an earlier state: stale, shown dimmed.
    shown: Option<Arc<Frame>>,
    /// Which of the side's controls apply (light samples, frames), for the generation
    /// they were worked out for: a plan each generation, not each window frame.
    controls: Option<(u64, bool, bool)>,
    /// The latest image of the current generation and size.
    latest: Option<Update>,
    /// What the worker was last asked for: generation and traced size.
    submitted: Option<(u64, u32, u32)>,
    error: Option<String>,
    metrics: Option<SideError>,
    /// The reference this side is compared with: its key (the reference experiment's
    /// TOML text).
    reference_key: Option<String>,
}

/// On-demand converged references, one per distinct reference experiment.
#[derive(Default)]
struct References {
    spp: u32,
    /// Finished references by key.
    done: Vec<(String, Arc<Frame>)>,
    /// Waiting: key and experiment.
    queue: Vec<(String, Arc<Experiment>)>,
    /// Rendering: key, generation, frames so far, total.
    running: Option<(String, u64, u32, u32)>,
    generation: u64,
}

impl References {
    fn get(&self, key: &str) -> Option<&Arc<Frame>> {
        self.done.iter().find(|(k, _)| k == key).map(|(_, f)| f)
    }
}

pub struct ViewerApp {
    pub state: ViewerState,
    /// Job queues of the left side, the right side and the reference worker.
    jobs: [Sender<Job>; 3],
    reports: Receiver<(Channel, Report)>,
    views: [SideView; 2],
    pub adaptive: AdaptiveScale,
    references: References,
    /// When each side last changed (restarting its accumulation).
    last_change: [Option<Instant>; 2],
    pub adapter: Option<String>,
    pub save_dir: String,
    /// The latest message for the status line (saves, errors).
    pub status: String,
    automation: Option<Automation>,
    outcome: Arc<Mutex<Outcome>>,
    /// Set by the screenshot callback once the window capture is written.
    capture_done: Arc<Mutex<Option<Result<PathBuf, String>>>>,
    automation_stage: u8,
    /// View mode, exposure, encoding, zoom.
    pub display: Display,
    /// The display the textures were made under.
    shown_display: Display,
    /// The comparison view's texture (difference or FLIP map), the state it was made
    /// from, and the FLIP mean of a FLIP map.
    compare: Option<(TextureHandle, CompareKey, Option<f64>)>,
    /// When the comparison image was last made: a FLIP map costs tens of milliseconds
    /// on the window's thread, so while the sides accumulate it is remade at most every
    /// `FLIP_INTERVAL`, and at once when both are done.
    compare_made: Option<Instant>,
    /// A pixel whose values stay shown (clicked); else the one under the pointer.
    pub probe_pinned: Option<(u32, u32)>,
    probe_hover: Option<(u32, u32)>,
    /// A drag that began on (or beside) the divider moves it and never orbits.
    dragging_divider: bool,
    /// Error readouts kept on: references are asked for again after every change.
    pub error_live: bool,
    /// Reloads the experiment when its file changes on disk.
    watch: Option<super::reload::Watch>,
}

/// What a comparison image was computed from: the view mode and display, and each
/// side's generation and frames.
#[derive(Clone, Debug, PartialEq)]
struct CompareKey {
    mode: ViewMode,
    display: Display,
    sides: [(u64, u32, u32, u32); 2],
}

/// Least time between two FLIP maps of one state while its sides accumulate.
const FLIP_INTERVAL: Duration = Duration::from_millis(500);

/// Pixels either side of the divider that grab it.
const DIVIDER_GRAB: f32 = 10.0;

impl ViewerApp {
    pub fn new(
        state: ViewerState,
        jobs: [Sender<Job>; 3],
        reports: Receiver<(Channel, Report)>,
        automation: Option<Automation>,
        outcome: Arc<Mutex<Outcome>>,
    ) -> Self {
        let mut state = state;
        if let Some(a) = &automation {
            // A scripted run stops exactly at its frame count.
            for s in &mut state.sides {
                s.max_spp = a.frames;
            }
            if let Err(e) = state.commit(&Side::BOTH) {
                outcome.lock().expect("outcome lock").error = Some(format!("{e:#}"));
            }
        }
        let save_dir = automation
            .as_ref()
            .map(|a| a.save_dir.display().to_string())
            .unwrap_or_else(|| "out/view".to_string());
        Self {
            state,
            jobs,
            reports,
            views: Default::default(),
            adaptive: AdaptiveScale::default(),
            references: References {
                spp: DEFAULT_REFERENCE_SPP,
                ..Default::default()
            },
            last_change: [None, None],
            adapter: None,
            save_dir,
            status: String::new(),
            automation,
            outcome,
            capture_done: Arc::new(Mutex::new(None)),
            automation_stage: 0,
            display: Display::default(),
            shown_display: Display::default(),
            compare: None,
            compare_made: None,
            probe_pinned: None,
            probe_hover: None,
            dragging_divider: false,
            error_live: false,
            watch: None,
        }
    }

    /// Reloads the experiment whenever its file or a file it reads changes on disk
    /// (`voxlab view` with a file does this), rebuilding the state as `opts` built it at
    /// the start.
    pub fn watch(&mut self, opts: super::ViewOptions) {
        self.watch = super::reload::Watch::new(opts);
    }

    /// Checks the watched files; on a change, the new state replaces the old one (the
    /// divider stays, and the camera where the user moved it unless the file's camera
    /// changed); a file that no longer loads leaves everything as it was and says why.
    fn poll_reload(&mut self) {
        let Some(w) = &mut self.watch else {
            return;
        };
        let path = w.path().display().to_string();
        let polled = w.poll();
        // Where a file the experiment reads changed, the status names it.
        let scene_file = w.changed().filter(|c| *c != w.path());
        let changed = scene_file
            .map(|c| format!(" ({} changed)", c.display()))
            .unwrap_or_default();
        let scene_file_changed = scene_file.is_some();
        match polled {
            None => {}
            Some(Err(e)) => {
                self.status = format!("reload failed, still showing the last good state: {e:#}")
            }
            Some(Ok(mut fresh)) => {
                fresh.divider = self.state.divider;
                if fresh.home_camera == self.state.home_camera {
                    let camera = self.state.base.scene.camera.clone();
                    fresh.base.scene.camera = camera;
                    if let Err(e) = fresh.commit(&Side::BOTH) {
                        self.status = format!("reload failed: {e:#}");
                        return;
                    }
                }
                // Generations continue, so reports of the old state are stale.
                for side in Side::BOTH {
                    fresh.generation[side.index()] += self.state.generation[side.index()];
                }
                self.state = fresh;
                if scene_file_changed {
                    // A reference is kept by its experiment's text, which names the
                    // scene's files but not what they hold: every one kept, waiting or
                    // rendering is of the old scene (a late report of the one rendering
                    // is dropped: none is running now).
                    self.references.done.clear();
                    self.references.queue.clear();
                    self.references.running = None;
                }
                self.changed(&Side::BOTH);
                self.status = format!("reloaded {path}{changed}");
            }
        }
    }

    /// Frames accumulated on `side` for the current state (0 before the first image).
    pub fn frames(&self, side: Side) -> u32 {
        self.views[side.index()]
            .latest
            .as_ref()
            .map_or(0, |u| u.frames)
    }

    /// The latest image of `side` for the current state.
    pub fn latest(&self, side: Side) -> Option<&Update> {
        self.views[side.index()].latest.as_ref()
    }

    /// Whether `side` shows an image of an earlier state (dimmed, labelled) while the
    /// current one renders.
    pub fn stale(&self, side: Side) -> bool {
        let v = &self.views[side.index()];
        v.latest.is_none() && v.texture.is_some()
    }

    /// The comparison view's image, when made: `Some(flip mean)` for a FLIP map,
    /// `Some(None)` for a difference.
    pub fn comparison(&self) -> Option<Option<f64>> {
        self.compare.as_ref().map(|(_, _, f)| *f)
    }

    pub fn side_error(&self, side: Side) -> Option<&SideError> {
        self.views[side.index()].metrics.as_ref()
    }

    /// Whether `side` changed within the settle time (it is being edited or moved).
    fn interacting(&self, side: Side) -> bool {
        self.last_change[side.index()]
            .is_some_and(|t| t.elapsed().as_secs_f64() < self.adaptive.settle_s)
    }

    fn any_interacting(&self) -> bool {
        Side::BOTH.iter().any(|&s| self.interacting(s))
    }

    /// Records that `sides` changed: their images restart, and their reference no
    /// longer applies (it was made from the old state).
    fn changed(&mut self, sides: &[Side]) {
        for s in sides {
            self.last_change[s.index()] = Some(Instant::now());
            let v = &mut self.views[s.index()];
            v.latest = None;
            v.metrics = None;
            v.error = None;
            v.reference_key = None;
        }
        self.compare = None;
    }

    /// Applies an edit of the shared state (`f`), then restarts both sides; an edit the
    /// file format rejects is undone and reported.
    fn edit_shared(&mut self, f: impl FnOnce(&mut ViewerState) -> anyhow::Result<()>) {
        let before = (self.state.base.clone(), self.state.sides.clone());
        match f(&mut self.state) {
            Ok(()) => self.changed(&Side::BOTH),
            Err(e) => {
                (self.state.base, self.state.sides) = before;
                self.status = format!("edit rejected: {e:#}");
            }
        }
    }

    /// The full-resolution image size, and the size `side` traces now: reduced only
    /// while that side is changing, so an edit of one side leaves the other side's
    /// accumulation alone.
    fn sizes(&self, side: Side) -> ((u32, u32), (u32, u32)) {
        let s = &self.state.base.settings;
        let full = (s.width, s.height);
        let pixels = s.width as u64 * s.height as u64;
        // The sides that are changing share the machine, so the budget covers them
        // together.
        let moving = Side::BOTH.iter().filter(|&&s| self.interacting(s)).count() as u64;
        let scale = self
            .adaptive
            .scale(moving.max(1) * pixels, self.interacting(side));
        (full, scaled_size(full.0, full.1, scale))
    }

    /// Sends each side's worker the job for the current state, when it changed.
    fn submit_jobs(&mut self) {
        for side in Side::BOTH {
            let (_, (w, h)) = self.sizes(side);
            let interacting = self.interacting(side);
            let generation = self.state.generation[side.index()];
            let want = (generation, w, h);
            let v = &mut self.views[side.index()];
            if v.submitted == Some(want) {
                continue;
            }
            v.submitted = Some(want);
            if v.latest.as_ref().is_some_and(|u| {
                u.generation != generation || (u.frame.width, u.frame.height) != (w, h)
            }) {
                v.latest = None;
                v.metrics = None;
            }
            let _ = self.jobs[side.index()].send(Job {
                generation,
                experiment: self.state.rendered(side).clone(),
                width: w,
                height: h,
                frames: self.state.sides[side.index()].max_spp,
                batch_budget: Duration::from_secs_f64(
                    if interacting {
                        self.adaptive.budget_ms
                    } else {
                        150.0
                    } * 1e-3,
                ),
            });
        }
    }

    /// Takes the workers' reports.
    fn receive(&mut self, ctx: &egui::Context) {
        while let Ok((channel, report)) = self.reports.try_recv() {
            match (channel, report) {
                (_, Report::Ready { adapter }) => self.adapter = Some(adapter),
                (Channel::Side(side), Report::Update(u)) => {
                    let v = &mut self.views[side.index()];
                    let Some((generation, w, h)) = v.submitted else {
                        continue;
                    };
                    if u.generation != generation || (u.frame.width, u.frame.height) != (w, h) {
                        continue;
                    }
                    let pixels = u.frame.width as u64 * u.frame.height as u64;
                    self.adaptive
                        .observe(pixels, u.frame_time.as_secs_f64() * 1e3);
                    let image = self.display.image(&u.frame);
                    set_texture(ctx, &mut v.texture, &format!("side-{}", side.name()), image);
                    v.shown = Some(u.frame.clone());
                    v.error = None;
                    let finished = u.frames == u.total;
                    v.latest = Some(u);
                    self.update_rmse(side);
                    // FLIP costs tens of ms: once when the accumulation ends (and on
                    // request), not with every frame.
                    if finished {
                        self.update_flip(side);
                    }
                }
                (
                    Channel::Side(side),
                    Report::Failed {
                        generation,
                        message,
                    },
                ) => {
                    if generation == self.state.generation[side.index()] || generation == 0 {
                        self.views[side.index()].error = Some(message);
                    }
                }
                (Channel::Reference, Report::Update(u)) => {
                    let Some((key, generation, _, _)) = self.references.running.clone() else {
                        continue;
                    };
                    if u.generation != generation {
                        continue;
                    }
                    if u.frames < u.total {
                        self.references.running = Some((key, generation, u.frames, u.total));
                        continue;
                    }
                    self.references.running = None;
                    // A few references are kept (switching back and forth between
                    // settings reuses them); the oldest goes first.
                    if self.references.done.len() >= MAX_KEPT_REFERENCES {
                        self.references.done.remove(0);
                    }
                    self.references.done.push((key, u.frame));
                    self.next_reference();
                    for side in Side::BOTH {
                        self.update_rmse(side);
                        self.update_flip(side);
                    }
                }
                (Channel::Reference, Report::Failed { message, .. }) => {
                    self.references.running = None;
                    self.references.queue.clear();
                    self.status = format!("reference failed: {message}");
                }
            }
        }
    }

    /// The reference experiment `side` is compared with: its scene and settings with the
    /// reference shadow model (`crate::technique::reference_shadow_model`, sampled area
    /// lights: the estimator that converges to the model), `references.spp` frames, an
    /// independent seed.
    fn reference_experiment(&self, side: Side) -> anyhow::Result<(String, Experiment)> {
        let mut e = self.state.rendered(side).as_ref().clone();
        e.settings.features.shadow_model = crate::technique::reference_shadow_model();
        e.settings.spp = self.references.spp;
        e.settings.seed = e.settings.seed.wrapping_add(REFERENCE_SEED_OFFSET);
        // The key is the experiment's file text: equal text, equal reference.
        let text = crate::experiment::write::to_toml(&e, &self.state.scene_source)?;
        Ok((text, e))
    }

    /// Asks for the references of both sides (rendered once per distinct experiment).
    pub(crate) fn request_error(&mut self) {
        // References of an earlier state that are still waiting or rendering are of
        // no use now: dropped, so the new ones start at once (a new job replaces the
        // reference worker's current one between batches).
        let wanted: Vec<String> = Side::BOTH
            .iter()
            .filter_map(|&s| self.reference_experiment(s).ok().map(|(k, _)| k))
            .collect();
        self.references.queue.retain(|(k, _)| wanted.contains(k));
        if self
            .references
            .running
            .as_ref()
            .is_some_and(|(k, ..)| !wanted.contains(k))
        {
            self.references.running = None;
        }
        for side in Side::BOTH {
            match self.reference_experiment(side) {
                Ok((key, e)) => {
                    let known = self.references.get(&key).is_some()
                        || self.references.queue.iter().any(|(k, _)| *k == key)
                        || self
                            .references
                            .running
                            .as_ref()
                            .is_some_and(|(k, ..)| *k == key);
                    if !known {
                        self.references.queue.push((key.clone(), Arc::new(e)));
                    }
                    self.views[side.index()].reference_key = Some(key);
                }
                Err(e) => self.status = format!("reference: {e:#}"),
            }
        }
        if self.references.running.is_none() {
            self.next_reference();
        }
        for side in Side::BOTH {
            self.update_rmse(side);
            self.update_flip(side);
        }
    }

    fn next_reference(&mut self) {
        if self.references.queue.is_empty() {
            return;
        }
        let (key, e) = self.references.queue.remove(0);
        self.references.generation += 1;
        let generation = self.references.generation;
        let (w, h) = (e.settings.width, e.settings.height);
        let total = self.references.spp;
        self.references.running = Some((key, generation, 0, total));
        let _ = self.jobs[2].send(Job {
            generation,
            experiment: e,
            width: w,
            height: h,
            frames: total,
            batch_budget: Duration::from_millis(500),
        });
    }

    /// The reference of `side` and its current full-size image, when both exist.
    fn pair(&self, side: Side) -> Option<(Arc<Frame>, Arc<Frame>, u32)> {
        let v = &self.views[side.index()];
        let key = v.reference_key.as_ref()?;
        let reference = self.references.get(key)?;
        let u = v.latest.as_ref()?;
        ((u.frame.width, u.frame.height) == (reference.width, reference.height))
            .then(|| (reference.clone(), u.frame.clone(), u.frames))
    }

    /// RMSE and PSNR against the reference, refreshed with every image (cheap).
    fn update_rmse(&mut self, side: Side) {
        let Some((reference, frame, frames)) = self.pair(side) else {
            return;
        };
        if let Some(d) = compare(&reference, &frame, Domain::Linear, 0.0) {
            let v = &mut self.views[side.index()];
            let flip = v
                .metrics
                .as_ref()
                .and_then(|m| (m.frames == frames).then_some(m.flip))
                .flatten();
            v.metrics = Some(SideError {
                frames,
                rmse: d.rmse,
                psnr: d.psnr,
                flip,
            });
        }
    }

    /// FLIP against the reference, on request (it costs tens of milliseconds).
    fn update_flip(&mut self, side: Side) {
        let Some((reference, frame, _)) = self.pair(side) else {
            return;
        };
        let (flip, _) = crate::ablate::flip(&reference, &frame);
        if let Some(m) = &mut self.views[side.index()].metrics {
            m.flip = Some(flip);
        }
    }

    /// The prefix of the next save into `dir`: `NAME-001`, `NAME-002`, ..., the first
    /// that no file in `dir` starts with, so a save never overwrites an earlier one.
    pub fn save_stem(&self, dir: &Path) -> String {
        let taken: Vec<String> = std::fs::read_dir(dir)
            .map(|d| {
                d.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        (1u32..)
            .map(|n| format!("{}-{n:03}", self.state.base.name))
            .find(|stem| !taken.iter().any(|f| f.starts_with(&format!("{stem}-"))))
            .expect("some number is free")
    }

    /// Saves `side`'s current image under a new prefix (`save_stem`): PNG (as `voxlab
    /// render` writes it), EXR (linear radiance), the experiment file that reproduces it,
    /// and its error map against its reference when there is one; returns the PNG's and
    /// the TOML's paths.
    pub fn save_side(&mut self, side: Side, dir: &Path) -> anyhow::Result<(PathBuf, PathBuf)> {
        let stem = self.save_stem(dir);
        let files = self.side_files(side, dir, &stem)?;
        crate::output::write_together(files.fills()?)?;
        Ok((files.png, files.toml))
    }

    /// What a save writes for `side`: `STEM-SIDE.png`, `.exr`, `.toml` and, with a
    /// reference, `-error.exr`, made before anything is written.
    fn side_files(&mut self, side: Side, dir: &Path, stem: &str) -> anyhow::Result<SideFiles> {
        let u = self.views[side.index()]
            .latest
            .clone()
            .ok_or_else(|| anyhow::anyhow!("the {} side has no image yet", side.name()))?;
        let (text, _) =
            self.state
                .export(side, u.frames, u.frame.width, u.frame.height, Some(dir))?;
        let base = dir.join(format!("{stem}-{}", side.name()));
        let with = |ext: &str| PathBuf::from(format!("{}.{ext}", base.display()));
        let (png, exr, toml) = (with("png"), with("exr"), with("toml"));
        // What made the image, with it (the PNG's iTXt chunk) and beside it (`.json`),
        // as `voxlab render` records it: the experiment that reproduces it, the files it
        // reads with their hashes, the build's revision.
        // The TOML is written after: a new stem, so it is not among them.
        let assets = crate::experiment::write::input_hashes(&text, &toml);
        let record = serde_json::json!({
            "voxlab": env!("CARGO_PKG_VERSION"),
            "revision": crate::revision::revision(),
            "saved_by": "voxlab view",
            "side": side.name(),
            "frames": u.frames,
            "width": u.frame.width,
            "height": u.frame.height,
            "experiment_file": toml.display().to_string(),
            "assets": assets,
            "resolved_experiment": text,
        });
        let record = serde_json::to_string_pretty(&record)?;
        let error = self.pair(side).and_then(|(reference, frame, _)| {
            display::difference(&frame, &reference)
                .map(|e| (PathBuf::from(format!("{}-error.exr", base.display())), e))
        });
        Ok(SideFiles {
            png,
            exr,
            toml,
            frame: u.frame,
            record,
            text,
            error,
        })
    }

    /// Saves both sides, their difference (`STEM-difference.exr`, |L - R| in linear
    /// radiance, when they have one size) and a capture of the window, under one new
    /// prefix: every file or, where one cannot be written, none (a side without an
    /// image yet fails the save before anything is written).
    ///
    /// Returns whether the files were written and the capture asked for; where not,
    /// `status` says why.
    pub(crate) fn save_all(&mut self, ctx: &egui::Context) -> bool {
        if let Some(side) = Side::BOTH
            .into_iter()
            .find(|s| self.views[s.index()].latest.is_none())
        {
            self.status = format!(
                "save failed: the {} side has no image yet; nothing written",
                side.name()
            );
            return false;
        }
        // Made by the write below, and removed again if it fails.
        let dir = PathBuf::from(self.save_dir.trim());
        let stem = self.save_stem(&dir);
        let sides = match Side::BOTH
            .into_iter()
            .map(|side| self.side_files(side, &dir, &stem))
            .collect::<anyhow::Result<Vec<_>>>()
        {
            Ok(sides) => sides,
            Err(e) => {
                self.status = format!("save failed: {e:#}; nothing written");
                return false;
            }
        };
        let difference = match (self.latest(Side::Left), self.latest(Side::Right)) {
            (Some(l), Some(r)) => display::difference(&l.frame, &r.frame)
                .map(|d| (dir.join(format!("{stem}-difference.exr")), d)),
            _ => None,
        };
        // Every file of both sides and their difference as one output: all are renamed
        // into place once all are whole (output::write_together), or none is.
        let written = (|| {
            let mut fills = Vec::new();
            for files in &sides {
                fills.extend(files.fills()?);
            }
            if let Some((path, d)) = &difference {
                fills.push((path.clone(), crate::output::frame_fill(d, path)?));
            }
            let paths: Vec<PathBuf> = fills.iter().map(|(p, _)| p.clone()).collect();
            crate::output::write_together(fills).map(|()| paths)
        })();
        let saved = match written {
            Ok(paths) => paths,
            Err(e) => {
                self.status = format!("save failed: {e}; nothing written");
                return false;
            }
        };
        let capture = dir.join(format!("{stem}-window.png"));
        // The capture's record: the build and the files saved with it, whose own
        // records say what each side rendered.
        let record = crate::output::record(
            "voxlab view (window capture)",
            &[],
            serde_json::json!({
                "saved_with": saved.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            }),
        );
        let done = self.capture_done.clone();
        *done.lock().expect("capture lock") = None;
        let repaint = ctx.clone();
        ctx.request_screenshot(move |image| {
            // The capture with its record or neither.
            let result = write_capture(&image, &capture)
                .and_then(|()| {
                    crate::output::write_sidecar(&capture, &record).map_err(|e| {
                        let _ = std::fs::remove_file(&capture);
                        e.into()
                    })
                })
                .map(|()| capture.clone())
                .map_err(|e| format!("{e:#}"));
            *done.lock().expect("capture lock") = Some(result);
            repaint.request_repaint();
        });
        self.status = format!(
            "saved {}",
            saved
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        );
        self.outcome
            .lock()
            .expect("outcome lock")
            .saved
            .extend(saved);
        true
    }

    /// Drives a scripted run: once both sides hold their frames at full size, save,
    /// wait for the window capture, close.
    fn automate(&mut self, ctx: &egui::Context) {
        let Some(a) = self.automation.clone() else {
            return;
        };
        for side in Side::BOTH {
            if let Some(e) = &self.views[side.index()].error {
                self.outcome.lock().expect("outcome lock").error =
                    Some(format!("{} side: {e}", side.name()));
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                return;
            }
        }
        match self.automation_stage {
            0 => {
                let ready = Side::BOTH.iter().all(|&s| {
                    let (full, now) = self.sizes(s);
                    full == now
                }) && Side::BOTH.iter().all(|&s| {
                    self.latest(s).is_some_and(|u| {
                        (u.frame.width, u.frame.height) == self.sizes(s).0
                            && u.frames >= a.frames.min(u.total)
                    })
                });
                if ready {
                    if self.save_all(ctx) {
                        self.automation_stage = 1;
                    } else {
                        // No capture will come: the run ends with the save's error
                        // instead of waiting for one.
                        self.outcome.lock().expect("outcome lock").error =
                            Some(self.status.clone());
                        self.automation_stage = 2;
                        if a.exit {
                            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                        }
                    }
                }
            }
            1 => {
                let done = self.capture_done.lock().expect("capture lock").clone();
                if let Some(result) = done {
                    let mut o = self.outcome.lock().expect("outcome lock");
                    match result {
                        Ok(p) => o.saved.push(p),
                        Err(e) => o.error = Some(format!("window capture: {e}")),
                    }
                    drop(o);
                    self.automation_stage = 2;
                    if a.exit {
                        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                } else {
                    ctx.request_repaint_after(Duration::from_millis(50));
                }
            }
            _ => {}
        }
    }

    /// One pass of the whole window.
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        self.poll_reload();
        self.receive(&ctx);
        let keys = !ctx.egui_wants_keyboard_input();
        if keys && ui.input(|i| i.key_pressed(egui::Key::R)) {
            self.edit_shared(|s| s.reset_camera());
        }
        if keys && ui.input(|i| i.key_pressed(egui::Key::B)) {
            self.display.mode = self.display.mode.flipped();
        }
        if keys && ui.input(|i| i.key_pressed(egui::Key::Escape)) {
            self.probe_pinned = None;
        }
        if self.error_live
            && !self.any_interacting()
            && self
                .views
                .iter()
                .any(|v| v.reference_key.is_none() && v.latest.is_some())
        {
            self.request_error();
        }
        egui::Panel::top("voxlab-top").show(ui, |ui| self.top_bar(ui));
        egui::Panel::top("voxlab-view").show(ui, |ui| self.view_bar(ui));
        self.refresh_textures(&ctx);
        egui::Panel::bottom("voxlab-status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::bottom("voxlab-probe").show(ui, |ui| self.probe_bar(ui));
        egui::Panel::left("voxlab-scene")
            .default_size(280.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| self.scene_panel(ui));
            });
        egui::Panel::right("voxlab-sides")
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    for side in Side::BOTH {
                        self.side_panel(ui, side);
                        ui.separator();
                    }
                    self.reference_panel(ui);
                });
            });
        egui::CentralPanel::default().show(ui, |ui| self.split_view(ui));
        self.submit_jobs();
        self.automate(&ctx);
        if self.any_interacting() {
            // Come back when the view settles, to go to full resolution.
            ctx.request_repaint_after(Duration::from_secs_f64(self.adaptive.settle_s));
        }
    }

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.strong(format!("voxlab view: {}", self.state.base.name));
            if ui.button("Reset camera (R)").clicked() {
                self.edit_shared(|s| s.reset_camera());
            }
            ui.separator();
            let row = ui.label("Save to").id;
            ui.add(egui::TextEdit::singleline(&mut self.save_dir).desired_width(160.0))
                .labelled_by(row);
            if ui
                .button("Save images + TOML")
                .on_hover_text(
                    "Each side's image as PNG, the experiment file that `voxlab render` \
                     reproduces it from, and a capture of the window",
                )
                .clicked()
            {
                let ctx = ui.ctx().clone();
                // A failure is in the status line.
                let _ = self.save_all(&ctx);
            }
        });
    }

    /// The view controls: mode, display transform, zoom.
    fn view_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let d = &mut self.display;
            egui::ComboBox::from_label("view (B flips sides)")
                .selected_text(d.mode.name())
                .show_ui(ui, |ui| {
                    for m in ViewMode::ALL {
                        ui.selectable_value(&mut d.mode, m, m.name());
                    }
                });
            let row = ui.label("exposure EV").id;
            ui.add(egui::DragValue::new(&mut d.exposure).speed(0.05).range(
                -crate::frame::DisplayTransform::MAX_EXPOSURE
                    ..=crate::frame::DisplayTransform::MAX_EXPOSURE,
            ))
            .labelled_by(row);
            ui.checkbox(&mut d.srgb, "sRGB display");
            egui::ComboBox::from_label("zoom")
                .selected_text(d.zoom.name())
                .show_ui(ui, |ui| {
                    for z in Zoom::ALL {
                        if ui.selectable_value(&mut d.zoom, z, z.name()).changed() {
                            d.centre = None;
                        }
                    }
                });
            if d.mode == ViewMode::Difference {
                let row = ui.label("difference gain").id;
                ui.add(
                    egui::DragValue::new(&mut d.difference_gain)
                        .speed(0.1)
                        .range(0.1..=1000.0),
                )
                .labelled_by(row);
            }
            if let Some((_, _, Some(f))) = &self.compare {
                ui.label(format!("FLIP mean (R vs L) {f:.4}"));
            }
            // What the comparison view's colours mean.
            if let Some(bar) = display::colour_bar(d) {
                let (rect, _) = ui.allocate_exact_size(Vec2::new(160.0, 12.0), Sense::hover());
                let n = bar.colours.len() as f32;
                for (k, c) in bar.colours.iter().enumerate() {
                    let x0 = rect.left() + rect.width() * k as f32 / n;
                    let x1 = rect.left() + rect.width() * (k + 1) as f32 / n;
                    ui.painter().rect_filled(
                        Rect::from_min_max(pos2(x0, rect.top()), pos2(x1, rect.bottom())),
                        0.0,
                        *c,
                    );
                }
                ui.label(format!("colour bar: {}", bar.caption()));
            }
        });
    }

    /// Redraws the side textures when the display transform changed, and makes the
    /// comparison view's image when its inputs changed.
    fn refresh_textures(&mut self, ctx: &egui::Context) {
        let redraw = self.display.transform() != self.shown_display.transform();
        if redraw {
            for side in Side::BOTH {
                let v = &mut self.views[side.index()];
                if let Some(f) = v.shown.clone() {
                    let image = self.display.image(&f);
                    set_texture(ctx, &mut v.texture, &format!("side-{}", side.name()), image);
                }
            }
            self.shown_display = self.display.clone();
        }
        if !self.display.mode.compares() {
            self.compare = None;
            return;
        }
        let key = |side: Side| {
            let v = &self.views[side.index()];
            v.latest.as_ref().map_or((0, 0, 0, 0), |u| {
                (u.generation, u.frames, u.frame.width, u.frame.height)
            })
        };
        let want = CompareKey {
            mode: self.display.mode,
            display: Display {
                zoom: Zoom::Fit,
                centre: None,
                ..self.display.clone()
            },
            sides: [key(Side::Left), key(Side::Right)],
        };
        if self.compare.as_ref().is_some_and(|(_, k, _)| *k == want) {
            return;
        }
        let settled = Side::BOTH
            .iter()
            .all(|&s| self.latest(s).is_some_and(|u| u.frames == u.total));
        let same_state = self.compare.as_ref().is_some_and(|(_, k, _)| {
            k.mode == want.mode
                && k.display == want.display
                && (0..2).all(|i| k.sides[i].0 == want.sides[i].0)
        });
        if self.display.mode == ViewMode::Flip
            && same_state
            && !settled
            && self
                .compare_made
                .is_some_and(|t| t.elapsed() < FLIP_INTERVAL)
        {
            ctx.request_repaint_after(FLIP_INTERVAL);
            return;
        }
        let (Some(l), Some(r)) = (self.latest(Side::Left), self.latest(Side::Right)) else {
            return;
        };
        let (l, r) = (l.frame.clone(), r.frame.clone());
        let made = match self.display.mode {
            ViewMode::Difference => {
                display::difference_image(&self.display, &l, &r).map(|i| (i, None))
            }
            _ => display::flip_image(&l, &r).map(|(mean, i)| (i, Some(mean))),
        };
        let Some((image, mean)) = made else {
            return;
        };
        let mut texture = self.compare.take().map(|(t, ..)| t);
        set_texture(ctx, &mut texture, "compare", image);
        self.compare = texture.map(|t| (t, want, mean));
        self.compare_made = Some(Instant::now());
    }

    /// The probed pixel's radiance on each side (the pinned one, else the one under the
    /// pointer).
    fn probe_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| match self.probe_text() {
            Some(t) => {
                ui.label(t);
                if self.probe_pinned.is_some() && ui.small_button("unpin (Esc)").clicked() {
                    self.probe_pinned = None;
                }
            }
            None => {
                ui.label("pixel probe: point at the image (click pins a pixel)");
            }
        });
    }

    /// The probe's readout: pixel, each side's linear radiance and frames, and their
    /// difference.
    pub fn probe_text(&self) -> Option<String> {
        let (x, y) = self.probe_pinned.or(self.probe_hover)?;
        let mut parts = vec![format!(
            "pixel ({x}, {y}){}",
            if self.probe_pinned.is_some() {
                " pinned"
            } else {
                ""
            }
        )];
        let mut values = Vec::new();
        for side in Side::BOTH {
            let Some(u) = self.latest(side) else {
                parts.push(format!("{}: rendering", side.name()));
                continue;
            };
            // The probe is in full-size pixels; a reduced image is sampled where it is.
            let (full, _) = self.sizes(side);
            let sx = (x as u64 * u.frame.width as u64 / full.0.max(1) as u64) as u32;
            let sy = (y as u64 * u.frame.height as u64 / full.1.max(1) as u64) as u32;
            let p = u.frame.pixels
                [(sy.min(u.frame.height - 1) * u.frame.width + sx.min(u.frame.width - 1)) as usize];
            values.push(p);
            parts.push(format!(
                "{}: {:.4} {:.4} {:.4} ({} frames)",
                side.name(),
                p[0],
                p[1],
                p[2],
                u.frames
            ));
        }
        if let [a, b] = values[..] {
            parts.push(format!(
                "|L - R|: {:.4} {:.4} {:.4}",
                (a[0] - b[0]).abs(),
                (a[1] - b[1]).abs(),
                (a[2] - b[2]).abs()
            ));
        }
        Some(parts.join("   "))
    }

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.label(
                self.adapter
                    .as_deref()
                    .unwrap_or("starting the GPU workers..."),
            );
            if !self.status.is_empty() {
                ui.separator();
                ui.label(&self.status);
            }
        });
    }

    /// One function because egui lays widgets out in the order they are called: the panel
    /// reads top to bottom as it appears on screen.
    fn scene_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("Scene");
        let mut camera = self.state.base.scene.camera.clone();
        let mut cam_changed = false;
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| {
                egui::Grid::new("camera").show(ui, |ui| {
                    cam_changed |= field_rows(ui, crate::settings::CAMERA, &mut camera, |_| true);
                    cam_changed |= vec3_row(ui, "target", &mut camera.target, 0.01, None);
                });
                ui.label("Drag the image to orbit, scroll to zoom, R to reset.");
            });
        if cam_changed {
            self.edit_shared(|s| {
                s.base.scene.camera = camera;
                s.commit_shared()
            });
        }

        let mut settings = self.state.base.settings.clone();
        let mut ambient = self.state.base.scene.ambient;
        let mut changed = false;
        egui::CollapsingHeader::new("Render")
            .default_open(true)
            .show(ui, |ui| {
                egui::Grid::new("render").show(ui, |ui| {
                    // Samples and frames are each side's, in its own panel; the filter's
                    // width only where a filter is chosen.
                    let filtered = settings.pixel_filter != crate::render::PixelFilter::None;
                    changed |= field_rows(ui, crate::settings::RENDER, &mut settings, |k| {
                        !matches!(k, "light_samples" | "spp") && (k != "filter_width" || filtered)
                    });
                    let row = ui.label("falloff").id;
                    changed |= ui
                        .checkbox(&mut settings.falloff, "inverse square")
                        .labelled_by(row)
                        .changed();
                    ui.end_row();
                    changed |= choice_row(
                        ui,
                        "pixel filter",
                        &mut settings.pixel_filter,
                        &crate::render::PixelFilter::ALL,
                        crate::render::PixelFilter::name,
                    );
                    changed |= vec3_row(ui, "ambient", &mut ambient, 0.005, Some(0.0));
                    changed |= choice_row(
                        ui,
                        "traversal",
                        &mut settings.traversal,
                        &crate::render::Traversal::all(),
                        crate::render::Traversal::name,
                    );
                    changed |= choice_row(
                        ui,
                        "surface",
                        &mut settings.surface,
                        &crate::render::Surface::all(),
                        crate::render::Surface::name,
                    );
                });
                ui.checkbox(
                    &mut self.adaptive.enabled,
                    "adaptive resolution while moving",
                );
                ui.horizontal(|ui| {
                    let row = ui.label("frame budget ms").id;
                    ui.add(egui::DragValue::new(&mut self.adaptive.budget_ms).range(5.0..=2000.0))
                        .labelled_by(row);
                });
            });
        if changed {
            self.edit_shared(|s| {
                s.base.settings = settings;
                s.base.scene.ambient = ambient;
                s.commit_shared()
            });
        }

        let mut lights = self.state.base.scene.lights.clone();
        let mut changed = false;
        let (mut remove, mut add) = (None, None);
        egui::CollapsingHeader::new(format!("Lights ({})", lights.len()))
            .default_open(true)
            .show(ui, |ui| {
                let (c, w) = (
                    self.state.base.scene.grid.centre(),
                    self.state.base.scene.grid.width(),
                );
                for (i, light) in lights.iter_mut().enumerate() {
                    match light_edit(ui, i, light, c, 0.25 * w) {
                        LightEdit::None => {}
                        LightEdit::Changed => changed = true,
                        LightEdit::Remove => remove = Some(i),
                    }
                }
                ui.horizontal(|ui| {
                    ui.label("add");
                    for kind in LightKind::ALL {
                        if ui.small_button(format!("+ {}", kind.name())).clicked() {
                            add = Some(kind);
                        }
                    }
                });
            });
        if changed {
            self.edit_shared(|s| {
                s.base.scene.lights = lights;
                s.commit_shared()
            });
        }
        if let Some(i) = remove {
            self.edit_shared(|s| s.remove_light(i));
        }
        if let Some(kind) = add {
            self.edit_shared(|s| s.add_light(kind));
        }

        let used = self.state.base.scene.grid.materials_used();
        let mut materials = self.state.base.scene.materials.clone();
        let mut changed = false;
        egui::CollapsingHeader::new("Materials")
            .default_open(false)
            .show(ui, |ui| {
                for (i, m) in materials.iter_mut().enumerate().skip(1) {
                    if !used.get(i).copied().unwrap_or(false) {
                        continue;
                    }
                    egui::CollapsingHeader::new(format!("{i}: {}", m.name))
                        .id_salt(("material", i))
                        .show(ui, |ui| {
                            egui::Grid::new(("material-grid", i)).show(ui, |ui| {
                                changed |= vec3_row(ui, "albedo", &mut m.albedo, 0.01, Some(0.0));
                                changed |= field_rows(ui, crate::settings::MATERIAL, m, |_| true);
                                changed |=
                                    vec3_row(ui, "emission", &mut m.emission, 0.01, Some(0.0));
                                let row = ui.label("sigma").id;
                                let mut explicit = m.sigma.is_some();
                                if ui
                                    .checkbox(&mut explicit, "explicit (else from kt)")
                                    .labelled_by(row)
                                    .changed()
                                {
                                    m.sigma = explicit.then(|| {
                                        m.absorption(self.state.base.scene.grid.voxel_size())
                                    });
                                    changed = true;
                                }
                                ui.end_row();
                                if let Some(s) = &mut m.sigma {
                                    changed |= vec3_row(ui, "", s, 0.01, Some(0.0));
                                }
                                ui.label("dielectric");
                                ui.horizontal(|ui| {
                                    for d in [Dielectric::Fixed, Dielectric::Fresnel] {
                                        changed |= ui
                                            .radio_value(&mut m.dielectric, d, d.name())
                                            .changed();
                                    }
                                });
                                ui.end_row();
                            });
                        });
                }
            });
        if changed {
            self.edit_shared(|s| {
                s.base.scene.materials = materials;
                s.commit_shared()
            });
        }
    }

    /// One function because egui lays widgets out in the order they are called: the panel
    /// reads top to bottom as it appears on screen.
    fn side_panel(&mut self, ui: &mut egui::Ui, side: Side) {
        let i = side.index();
        ui.heading(format!(
            "{} side",
            if side == Side::Left { "Left" } else { "Right" }
        ));
        let mut s: SideSettings = self.state.sides[i].clone();
        let mut changed = false;
        let mut model = ShadowModel::of(&s.features);
        egui::ComboBox::from_label(format!("shadows ({})", side.name()))
            .selected_text(model.name())
            .show_ui(ui, |ui| {
                for m in ShadowModel::all() {
                    changed |= ui.selectable_value(&mut model, m, m.name()).changed();
                }
            });
        model.apply(&mut s.features);
        let mut t = s.features.transmittance;
        egui::ComboBox::from_label(format!("transmittance ({})", side.name()))
            .selected_text(t.name())
            .show_ui(ui, |ui| {
                for name in crate::technique::transmittance_names() {
                    if let Some(m) = crate::technique::transmittance(name) {
                        changed |= ui.selectable_value(&mut t, m, name).changed();
                    }
                }
            });
        s.features.transmittance = t;
        let mut r = s.features.reconstruction;
        egui::ComboBox::from_label(format!("reconstruction ({})", side.name()))
            .selected_text(r.name)
            .show_ui(ui, |ui| {
                for &m in crate::technique::RECONSTRUCTIONS {
                    changed |= ui.selectable_value(&mut r, m, m.name).changed();
                }
            });
        s.features.reconstruction = r;
        // The lighting terms, each its own switch (crate::technique::LIGHTING_TERMS).
        for t in crate::technique::LIGHTING_TERMS {
            let mut on = s.features.term(t.name);
            if ui
                .checkbox(
                    &mut on,
                    format!("{} ({})", t.name.replace('_', " "), side.name()),
                )
                .changed()
            {
                s.features.set_term(t.name, on);
                changed = true;
            }
        }
        // Only controls that change this side's image: light samples where its plan
        // samples area lights (not for hard or cone shadows, or a scene of point
        // lights), frames where it accumulates anything.
        let generation = self.state.generation[i];
        let (samples_lights, accumulates) = match self.views[i].controls {
            Some((g, samples, frames)) if g == generation => (samples, frames),
            _ => {
                // As if it accumulated: whether more than one frame would differ at all.
                let e = self.state.rendered(side);
                let many = crate::RenderSettings {
                    spp: 2,
                    ..e.settings.clone()
                };
                let plan = crate::plan::Plan::new(&e.scene, &many);
                let samples = plan.shadow_model.stochastic;
                self.views[i].controls = Some((generation, samples, plan.accumulate));
                (samples, plan.accumulate)
            }
        };
        egui::Grid::new(("side-grid", i)).show(ui, |ui| {
            if samples_lights {
                let declared = &crate::settings::field(crate::settings::RENDER, "light_samples");
                let mut v = f64::from(s.light_samples);
                if setting_row(ui, &declared.setting, &mut v) {
                    s.light_samples = v as u32;
                    changed = true;
                }
            }
            if accumulates {
                changed |= drag_row(
                    ui,
                    "max frames",
                    egui::DragValue::new(&mut s.max_spp).range(1..=MAX_VIEW_SPP),
                );
            }
        });
        // The shared groups' panels, where the side's features read them.
        for g in crate::technique::SETTING_GROUPS
            .iter()
            .filter(|g| (g.used)(&s.features))
        {
            egui::CollapsingHeader::new(g.title)
                .id_salt((g.table, i))
                .show(ui, |ui| {
                    egui::Grid::new((g.table, "grid", i)).show(ui, |ui| {
                        for c in g.settings {
                            let mut v = (c.get)(&s.groups);
                            if setting_row(ui, &c.setting, &mut v) {
                                (c.set)(&mut s.groups, v);
                                changed = true;
                            }
                        }
                    });
                });
        }
        // The shadow model's own settings, from its declaration.
        if let Some(m) = Some(s.features.shadow_model).filter(|m| !m.settings.is_empty()) {
            egui::CollapsingHeader::new(format!("{} knobs", m.name))
                .id_salt((m.name, i))
                .show(ui, |ui| {
                    egui::Grid::new((m.name, "grid", i)).show(ui, |ui| {
                        for st in m.settings {
                            changed |=
                                technique_setting_row(ui, m.name, st, &mut s.technique_params);
                        }
                    });
                });
        }
        // The reconstruction's own settings, from its declaration.
        let r = s.features.reconstruction;
        if !r.settings.is_empty() {
            egui::CollapsingHeader::new(format!("{} knobs", r.name))
                .id_salt((r.name, i))
                .show(ui, |ui| {
                    egui::Grid::new((r.name, "grid", i)).show(ui, |ui| {
                        for st in r.settings {
                            changed |=
                                technique_setting_row(ui, r.name, st, &mut s.technique_params);
                        }
                    });
                });
        }
        if changed {
            let before = self.state.sides[i].clone();
            self.state.sides[i] = s;
            match self.state.commit(&[side]) {
                Ok(()) => self.changed(&[side]),
                Err(e) => {
                    self.state.sides[i] = before;
                    self.status = format!("edit rejected: {e:#}");
                }
            }
        }

        let v = &self.views[i];
        match &v.latest {
            Some(u) => {
                ui.label(format!(
                    "{} / {} frames at {}x{}",
                    u.frames, u.total, u.frame.width, u.frame.height
                ));
                if u.total > 1 {
                    let per_frame = self.state.rendered(side).settings.light_samples;
                    ui.label(format!(
                        "{} light samples per pixel and light",
                        u64::from(u.frames) * u64::from(per_frame)
                    ));
                }
                ui.label(format!(
                    "frame time {:.1} ms",
                    u.frame_time.as_secs_f64() * 1e3
                ));
                ui.label(egui::RichText::new(&u.plan).small());
                for w in &u.warnings {
                    ui.colored_label(Color32::YELLOW, format!("warning: {w}"));
                }
            }
            None => {
                ui.label("rendering...");
            }
        }
        if let Some(e) = &v.error {
            ui.colored_label(Color32::LIGHT_RED, e);
        }
        if let Some(m) = &v.metrics {
            ui.label(format!(
                "vs reference at {} frames: RMSE {:.5}, PSNR {:.2} dB, FLIP {}",
                m.frames,
                m.rmse,
                m.psnr,
                m.flip.map_or("-".to_string(), |f| format!("{f:.4}"))
            ));
        }
    }

    fn reference_panel(&mut self, ui: &mut egui::Ui) {
        ui.heading("Error");
        ui.horizontal(|ui| {
            let row = ui.label("reference frames").id;
            ui.add(egui::DragValue::new(&mut self.references.spp).range(1..=MAX_VIEW_SPP))
                .labelled_by(row);
        });
        ui.checkbox(&mut self.error_live, "keep error on")
            .on_hover_text(
                "After every change, once the view settles, render the new references and \
                 keep RMSE, PSNR and FLIP shown",
            );
        if ui
            .button("Error vs reference")
            .on_hover_text(format!(
                "Renders each side's converged reference (shadow model {}, an independent \
                 seed) and compares: RMSE and PSNR live, FLIP now",
                crate::technique::reference_shadow_model().title
            ))
            .clicked()
        {
            self.request_error();
        }
        if let Some((_, _, done, total)) = &self.references.running {
            ui.label(format!(
                "reference: {done} / {total} frames ({} more queued)",
                self.references.queue.len()
            ));
        }
    }

    /// The image area: the two images split by the divider, one side alone, or their
    /// comparison; fitted or zoomed; a stale image dimmed and labelled; the probe.
    ///
    /// One function because the divider, the two images, the stale labels and the probe
    /// share one painter and one response of the image area.
    fn split_view(&mut self, ui: &mut egui::Ui) {
        let (full, _) = self.sizes(Side::Left);
        let area = ui.max_rect();
        let rect = self
            .display
            .image_rect(area, full, ui.ctx().pixels_per_point());
        let visible = rect.intersect(area);
        let response = ui
            .allocate_rect(visible, Sense::click_and_drag())
            .on_hover_text("drag to orbit, shift-drag to pan a zoomed view, scroll to zoom the camera, click to pin the probe, R to reset, B to flip sides");
        response
            .widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "split view image"));
        let mode = self.display.mode;
        let split = mode == ViewMode::Split;
        let split_x = rect.left() + self.state.divider.clamp(0.0, 1.0) * rect.width();
        let painter = ui.painter().with_clip_rect(area);
        painter.rect_filled(visible, 0.0, Color32::BLACK);
        let uv = Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0));
        let font = egui::FontId::proportional(13.0);
        if mode.compares() {
            match &self.compare {
                Some((t, ..)) => {
                    painter.image(t.id(), rect, uv, Color32::WHITE);
                }
                None => {
                    painter.text(
                        visible.center(),
                        egui::Align2::CENTER_CENTER,
                        "waiting for both sides at one size",
                        font.clone(),
                        Color32::WHITE,
                    );
                }
            }
        } else {
            for side in Side::BOTH {
                let clip = match (mode, side) {
                    (ViewMode::Split, Side::Left) => {
                        Rect::from_min_max(rect.min, pos2(split_x, rect.max.y))
                    }
                    (ViewMode::Split, Side::Right) => {
                        Rect::from_min_max(pos2(split_x, rect.min.y), rect.max)
                    }
                    (ViewMode::Left, Side::Left) | (ViewMode::Right, Side::Right) => rect,
                    _ => continue,
                }
                .intersect(area);
                let v = &self.views[side.index()];
                let Some(t) = &v.texture else {
                    continue;
                };
                // An image of an earlier state (the camera was reset, a setting
                // changed) while the new one renders: dimmed and labelled, never shown
                // as current.
                let stale = v.latest.is_none();
                let tint = if stale {
                    display::STALE_TINT
                } else {
                    Color32::WHITE
                };
                painter.with_clip_rect(clip).image(t.id(), rect, uv, tint);
                if stale {
                    painter.with_clip_rect(clip).text(
                        clip.center(),
                        egui::Align2::CENTER_CENTER,
                        format!("{}: rendering the new state (stale image)", side.name()),
                        font.clone(),
                        Color32::YELLOW,
                    );
                }
            }
        }

        // The divider, in the split view: a line with a handle to drag. A drag that
        // starts beside the handle moves the divider too, and never orbits.
        let mut divider_dragged = false;
        if split {
            let handle = Rect::from_min_max(
                pos2(split_x - DIVIDER_GRAB, rect.top()),
                pos2(split_x + DIVIDER_GRAB, rect.bottom()),
            )
            .intersect(area);
            let divider = ui.interact(handle, egui::Id::unique("voxlab-divider"), Sense::drag());
            divider
                .widget_info(|| egui::WidgetInfo::labeled(egui::Role::Splitter, true, "divider"));
            if divider.hovered() || divider.dragged() {
                ui.ctx().set_cursor_icon(egui::CursorIcon::ResizeHorizontal);
            }
            if divider.dragged() && rect.width() > 0.0 {
                self.state.divider =
                    (self.state.divider + divider.drag_delta().x / rect.width()).clamp(0.0, 1.0);
                divider_dragged = true;
            }
            painter.line_segment(
                [pos2(split_x, rect.top()), pos2(split_x, rect.bottom())],
                egui::Stroke::new(2.0, Color32::WHITE),
            );
            let label = |x: f32, text: &str, align: egui::Align2| {
                painter.text(
                    pos2(x, visible.top() + 4.0),
                    align,
                    text,
                    font.clone(),
                    Color32::WHITE,
                );
            };
            label(split_x - 8.0, "left", egui::Align2::RIGHT_TOP);
            label(split_x + 8.0, "right", egui::Align2::LEFT_TOP);
        } else {
            painter.text(
                pos2(visible.left() + 6.0, visible.top() + 4.0),
                egui::Align2::LEFT_TOP,
                mode.name(),
                font.clone(),
                Color32::WHITE,
            );
        }

        if response.drag_started() {
            let origin = ui.input(|i| i.pointer.press_origin());
            self.dragging_divider =
                split && origin.is_some_and(|p| (p.x - split_x).abs() <= 2.0 * DIVIDER_GRAB);
        }
        if response.dragged() && !divider_dragged {
            let d = response.drag_delta();
            let shift = ui.input(|i| i.modifiers.shift);
            if self.dragging_divider {
                if rect.width() > 0.0 {
                    self.state.divider = (self.state.divider + d.x / rect.width()).clamp(0.0, 1.0);
                }
            } else if shift && matches!(self.display.zoom, Zoom::Pixels(_)) {
                // Pan the zoomed image: the centre pixel moves against the drag.
                let per_pixel = rect.width() / full.0.max(1) as f32;
                let (cx, cy) = self
                    .display
                    .centre
                    .unwrap_or((full.0 as f32 / 2.0, full.1 as f32 / 2.0));
                self.display.centre = Some((
                    (cx - d.x / per_pixel).clamp(0.0, full.0 as f32),
                    (cy - d.y / per_pixel).clamp(0.0, full.1 as f32),
                ));
            } else if d != Vec2::ZERO {
                self.edit_shared(|s| s.orbit_pixels(d.x, d.y));
            }
        }
        if response.drag_stopped() {
            self.dragging_divider = false;
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.edit_shared(|s| s.zoom(scroll / 50.0));
            }
        }

        // The probe: the pixel under the pointer, or the one clicked (pinned).
        self.probe_hover = response
            .hover_pos()
            .and_then(|p| display::pixel_at(rect, full, p));
        if response.clicked()
            && let Some(p) = response.interact_pointer_pos()
        {
            self.probe_pinned = display::pixel_at(rect, full, p);
        }
        if let Some(px) = self.probe_pinned {
            let c = display::pixel_centre(rect, full, px);
            let r = (rect.width() / full.0.max(1) as f32).max(6.0) / 2.0;
            painter.rect_stroke(
                Rect::from_center_size(c, Vec2::splat(2.0 * r)),
                0.0,
                egui::Stroke::new(1.5, Color32::YELLOW),
                egui::StrokeKind::Outside,
            );
        }
    }
}

/// Puts `image` into `texture` (made on first use): magnified nearest, so an image
/// pixel stays a sharp square at any zoom; minified linearly.
fn set_texture(
    ctx: &egui::Context,
    texture: &mut Option<TextureHandle>,
    name: &str,
    image: ColorImage,
) {
    let options = TextureOptions {
        magnification: egui::TextureFilter::Nearest,
        minification: egui::TextureFilter::Linear,
        ..TextureOptions::LINEAR
    };
    match texture {
        Some(t) => t.set(image, options),
        None => *texture = Some(ctx.load_texture(name, image, options)),
    }
}

/// A grid row: `label`, and a combo box of the named choices `all` for `value`. True
/// when the choice changed.
fn choice_row<T: Copy + PartialEq>(
    ui: &mut egui::Ui,
    label: &str,
    value: &mut T,
    all: &[T],
    name: fn(T) -> &'static str,
) -> bool {
    let mut changed = false;
    let row = ui.label(label).id;
    egui::ComboBox::from_id_salt(label)
        .selected_text(name(*value))
        .show_ui(ui, |ui| {
            for &c in all {
                changed |= ui.selectable_value(value, c, name(c)).changed();
            }
        })
        .response
        .labelled_by(row);
    ui.end_row();
    changed
}

/// A grid row: `label`, then `value` named by it (for screen readers and UI tests);
/// whether the value changed.
fn drag_row(ui: &mut egui::Ui, label: &str, value: egui::DragValue) -> bool {
    let row = ui.label(label).id;
    let changed = ui.add(value).labelled_by(row).changed();
    ui.end_row();
    changed
}

/// A grid row of a vector: `label`, then its three drag values.
fn vec3_row(ui: &mut egui::Ui, label: &str, v: &mut DVec3, speed: f64, min: Option<f64>) -> bool {
    let row = ui.label(label).id;
    let changed = vec3_edit(ui, row, v, speed, min);
    ui.end_row();
    changed
}

/// Three drag values for a vector, named by the row's `label`; `min` bounds each
/// component.
fn vec3_edit(
    ui: &mut egui::Ui,
    label: egui::Id,
    v: &mut DVec3,
    speed: f64,
    min: Option<f64>,
) -> bool {
    let mut changed = false;
    ui.horizontal(|ui| {
        for c in [&mut v.x, &mut v.y, &mut v.z] {
            let mut d = egui::DragValue::new(c).speed(speed);
            if let Some(m) = min {
                d = d.range(m..=f64::MAX);
            }
            changed |= ui.add(d).labelled_by(label).changed();
        }
    });
    changed
}

/// What the light panel did to one light.
enum LightEdit {
    None,
    Changed,
    Remove,
}

fn light_edit(
    ui: &mut egui::Ui,
    i: usize,
    light: &mut Light,
    toward: DVec3,
    size: f64,
) -> LightEdit {
    let mut changed = false;
    let mut remove = false;
    let kind = LightKind::of(light);
    egui::CollapsingHeader::new(format!("light {i}: {}", kind.name()))
        .id_salt(("light", i))
        .default_open(i == 0)
        .show(ui, |ui| {
            ui.horizontal(|ui| {
                let mut k = kind;
                let row = ui.label(format!("type of light {i}")).id;
                egui::ComboBox::from_id_salt(("light-kind", i))
                    .selected_text(k.name())
                    .show_ui(ui, |ui| {
                        for option in LightKind::ALL {
                            ui.selectable_value(&mut k, option, option.name());
                        }
                    })
                    .response
                    .labelled_by(row);
                if k != kind {
                    *light = k.convert(light, toward, size);
                    changed = true;
                }
                remove = ui.small_button(format!("remove light {i}")).clicked();
            });
            egui::Grid::new(("light-grid", i)).show(ui, |ui| {
                let (position, color, intensity) = match light {
                    Light::Point(p) => (&mut p.position, &mut p.color, &mut p.intensity),
                    Light::Area(a) => (&mut a.position, &mut a.color, &mut a.intensity),
                };
                changed |= vec3_row(ui, "position", position, 0.01, None);
                changed |= vec3_row(ui, "color", color, 0.01, Some(0.0));
                changed |= setting_row(ui, &crate::settings::LIGHT_INTENSITY, intensity);
                if let Light::Area(a) = light {
                    match &mut a.shape {
                        AreaShape::Rect { width, height } => {
                            let side = &crate::settings::LIGHT_SIDE;
                            let row = ui.label(side.key).id;
                            ui.horizontal(|ui| {
                                for v in [width, height] {
                                    changed |= setting_edit(ui, row, side, v);
                                }
                            });
                            ui.end_row();
                        }
                        AreaShape::Disk { radius } | AreaShape::Sphere { radius } => {
                            changed |= setting_row(ui, &crate::settings::LIGHT_RADIUS, radius);
                        }
                    }
                    if !matches!(a.shape, AreaShape::Sphere { .. }) {
                        let row = ui.label("normal").id;
                        let mut n = a.normal;
                        if vec3_edit(ui, row, &mut n, 0.01, None) && n.length_squared() > 1e-12 {
                            a.normal = n;
                            changed = true;
                        }
                        ui.end_row();
                        ui.label("emission");
                        ui.horizontal(|ui| {
                            for e in [Emission::Isotropic, Emission::Lambertian] {
                                changed |= ui.radio_value(&mut a.emission, e, e.name()).changed();
                            }
                        });
                        ui.end_row();
                    }
                    // A disk looks the same turned about its normal: only a rect has a
                    // rotation that changes the image.
                    if matches!(a.shape, AreaShape::Rect { .. }) {
                        let mut deg = crate::settings::degrees(a.rotation);
                        if setting_row(ui, &crate::settings::LIGHT_ROTATION, &mut deg) {
                            a.rotation = crate::settings::radians(deg);
                            changed = true;
                        }
                    }
                }
            });
        });
    if remove {
        LightEdit::Remove
    } else if changed {
        LightEdit::Changed
    } else {
        LightEdit::None
    }
}

/// Writes the window capture as PNG (atomically, as every output).
fn write_capture(image: &ColorImage, path: &Path) -> anyhow::Result<()> {
    let [w, h] = image.size;
    let bytes: Vec<u8> = image
        .pixels
        .iter()
        .flat_map(|c| [c.r(), c.g(), c.b()])
        .collect();
    let img = image::RgbImage::from_raw(w as u32, h as u32, bytes)
        .ok_or_else(|| anyhow::anyhow!("window capture of {w}x{h} has the wrong length"))?;
    let mut png = std::io::Cursor::new(Vec::new());
    img.write_to(&mut png, image::ImageFormat::Png)?;
    crate::output::write_file(path, png.get_ref())?;
    Ok(())
}

/// One side's files of a save ([`ViewerApp::side_files`]).
struct SideFiles {
    png: PathBuf,
    exr: PathBuf,
    toml: PathBuf,
    frame: std::sync::Arc<crate::Frame>,
    record: String,
    text: String,
    /// The side's error map against its reference, where it has one.
    error: Option<(PathBuf, crate::Frame)>,
}

impl SideFiles {
    /// The PNG and the EXR, each with its record, the experiment file and the error map,
    /// for [`crate::output::write_together`]: the images linear, as `voxlab render`
    /// writes them.
    fn fills(&self) -> Result<Vec<(PathBuf, crate::output::Fill<'_>)>, crate::output::OutputError> {
        use crate::output::{bytes_fill, frame_fill, frame_with_provenance_fills};
        let linear = crate::frame::DisplayTransform {
            encoding: crate::frame::DisplayEncoding::Linear,
            exposure: 0.0,
        };
        let mut fills = frame_with_provenance_fills(&self.frame, &self.png, &self.record, linear)?;
        fills.extend(frame_with_provenance_fills(
            &self.frame,
            &self.exr,
            &self.record,
            linear,
        )?);
        fills.push((
            self.toml.clone(),
            bytes_fill(&self.toml, self.text.as_bytes()),
        ));
        if let Some((path, e)) = &self.error {
            fills.push((path.clone(), frame_fill(e, path)?));
        }
        Ok(fills)
    }
}
