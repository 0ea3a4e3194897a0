//! The viewer's window logic, driven through its widgets with egui_kittest and no GPU:
//! the test holds the other ends of the app's channels, so it reads the jobs the app
//! sends to the left, right and reference workers and feeds it fake worker reports.
#![cfg(feature = "viewer")]

use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use eframe::egui::{self, Pos2, Rect, accesskit::Role, pos2, vec2};
use egui_kittest::kittest::Queryable;
use egui_kittest::{Harness, Node};
use voxlab::Frame;
use voxlab::experiment::Experiment;
use voxlab::scene::Light;
use voxlab::viewer::state::{ShadowModel, scaled_size};
use voxlab::viewer::worker::{Job, Report, Update};
use voxlab::viewer::{Channel, Outcome, Side, ViewOptions, ViewerApp, ViewerState};

/// The traced size the tests use: small, so fake frames and metrics are cheap.
const W: u32 = 96;
const H: u32 = 64;

fn area_lights() -> ViewerState {
    voxlab::viewer::load_state(&ViewOptions {
        experiment: Some(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/area_lights.toml"),
        ),
        ..Default::default()
    })
    .expect("experiments/area_lights.toml loads")
}

/// The area-lights experiment at `W` x `H`.
fn small_area_lights() -> ViewerState {
    let mut s = area_lights();
    s.base.settings.width = W;
    s.base.settings.height = H;
    s.commit_shared().expect("a smaller image is valid");
    s
}

/// The app in a window, with the workers' ends of its channels.
struct Rig {
    harness: Harness<'static, ViewerApp>,
    jobs: [Receiver<Job>; 3],
    reports: Sender<(Channel, Report)>,
    outcome: Arc<Mutex<Outcome>>,
}

impl Rig {
    /// `adaptive`: whether the resolution drops while the view changes. Off, every job
    /// is at full size, whatever the timing of the test.
    fn new(state: ViewerState, adaptive: bool) -> Self {
        let (left, left_rx) = channel();
        let (right, right_rx) = channel();
        let (reference, reference_rx) = channel();
        let (reports, reports_rx) = channel();
        let outcome = Arc::new(Mutex::new(Outcome::default()));
        let mut app = ViewerApp::new(
            state,
            [left, right, reference],
            reports_rx,
            None,
            outcome.clone(),
        );
        app.adaptive.enabled = adaptive;
        let harness = Harness::builder()
            .with_size([1400.0, 1200.0])
            .build_ui_state(|ui, app: &mut ViewerApp| app.show(ui), app);
        Self {
            harness,
            jobs: [left_rx, right_rx, reference_rx],
            reports,
            outcome,
        }
    }

    fn app(&self) -> &ViewerApp {
        self.harness.state()
    }

    fn state(&self) -> &ViewerState {
        &self.harness.state().state
    }

    /// The jobs sent to a queue since the last call: 0 left, 1 right, 2 reference.
    fn take_jobs(&self, queue: usize) -> Vec<Job> {
        self.jobs[queue].try_iter().collect()
    }

    fn take_side_jobs(&self, side: Side) -> Vec<Job> {
        self.take_jobs(side.index())
    }

    /// Drops every job sent so far.
    fn clear_jobs(&self) {
        for q in 0..3 {
            self.take_jobs(q);
        }
    }

    /// Feeds an image as a worker would, without a frame time (which would move the
    /// adaptive scale: see `send_timed`).
    fn send(&self, channel: Channel, generation: u64, frame: Frame, frames: u32, total: u32) {
        self.send_timed(channel, generation, frame, frames, total, Duration::ZERO);
    }

    fn send_timed(
        &self,
        channel: Channel,
        generation: u64,
        frame: Frame,
        frames: u32,
        total: u32,
        frame_time: Duration,
    ) {
        self.reports
            .send((
                channel,
                Report::Update(Update {
                    generation,
                    frame: Arc::new(frame),
                    frames,
                    total,
                    frame_time,
                    plan: "fake plan".to_string(),
                    warnings: Vec::new(),
                }),
            ))
            .expect("the app holds the receiver");
    }

    /// Feeds `side` an image of its current generation.
    fn send_current(&self, side: Side, frame: Frame, frames: u32) {
        let generation = self.state().generation[side.index()];
        let total = self.state().sides[side.index()].max_spp;
        self.send(Channel::Side(side), generation, frame, frames, total);
    }

    fn has_label(&self, text: &str) -> bool {
        self.harness.query_by_label(text).is_some()
    }

    fn has_label_containing(&self, text: &str) -> bool {
        self.harness
            .query_all_by_label_contains(text)
            .next()
            .is_some()
    }

    fn checkbox<'a>(&'a self, label: &'a str) -> Node<'a> {
        self.harness.get_by_role_and_label(Role::CheckBox, label)
    }

    /// The (first, leftmost) DragValue named by the grid label `row`.
    fn drag_value_in_row<'a>(&'a self, row: &'a str) -> Node<'a> {
        self.harness
            .query_all_by_role_and_label(Role::SpinButton, row)
            .min_by(|a, b| a.rect().min.x.total_cmp(&b.rect().min.x))
            .unwrap_or_else(|| panic!("no DragValue named {row:?}"))
    }

    /// The image (drawn where it takes its drags and scrolls) and the x of the
    /// divider, found by their accessible names.
    fn image_geometry(&self) -> ImageGeometry {
        let image = self
            .harness
            .get_by_role_and_label(Role::Image, "split view image")
            .rect();
        let handle = self
            .harness
            .get_by_role_and_label(Role::Splitter, "divider")
            .rect();
        assert!(
            (handle.width() - 20.0).abs() < 0.5,
            "the divider's handle is 20 wide: {handle:?}"
        );
        assert!(
            (handle.top() - image.top()).abs() < 0.5
                && (handle.bottom() - image.bottom()).abs() < 0.5,
            "the divider spans the image's height: {handle:?} against {image:?}"
        );
        ImageGeometry {
            drawn: image,
            response: image,
            split_x: handle.center().x,
        }
    }

    /// A drag with the primary button from `from` by `delta`, in `steps` moves.
    fn drag(&mut self, from: Pos2, delta: egui::Vec2, steps: usize) {
        self.harness.hover_at(from);
        self.harness.drag_at(from);
        for i in 1..=steps {
            self.harness
                .hover_at(from + delta * (i as f32 / steps as f32));
        }
        self.harness.drop_at(from + delta);
        self.harness.step();
    }
}

struct ImageGeometry {
    drawn: Rect,
    response: Rect,
    split_x: f32,
}

impl ImageGeometry {
    /// A point on the image, at fraction `fx` of its width, that also takes drags.
    fn point(&self, fx: f32) -> Pos2 {
        let top = self.drawn.top().max(self.response.top());
        let bottom = self.drawn.bottom().min(self.response.bottom());
        assert!(
            bottom - top > 40.0,
            "the image and its response barely overlap"
        );
        pos2(
            self.drawn.left() + fx * self.drawn.width(),
            (top + bottom) / 2.0,
        )
    }
}

fn constant(width: u32, height: u32, c: f32) -> Frame {
    Frame {
        width,
        height,
        pixels: vec![[c; 3]; (width * height) as usize],
    }
}

/// A frame whose pixels all differ in their display value, some out of [0, 1].
fn gradient(width: u32, height: u32) -> Frame {
    let mut f = Frame::new(width, height);
    for y in 0..height {
        for x in 0..width {
            f.pixels[(y * width + x) as usize] = [
                x as f32 / (width - 1) as f32,
                y as f32 / (height - 1) as f32,
                1.2 - (x + y) as f32 / (width + height) as f32,
            ];
        }
    }
    f
}

fn intensity(l: &Light) -> f64 {
    match l {
        Light::Point(p) => p.intensity,
        Light::Area(a) => a.intensity,
    }
}

/// A fresh directory under the target directory.
fn temp_dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("viewer_ui-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create a temp dir");
    dir
}

#[test]
fn first_frame_sends_each_side_its_full_size_job_and_nothing_to_the_reference_worker() {
    let state = area_lights();
    let (w, h) = (state.base.settings.width, state.base.settings.height);
    assert_eq!((w, h), (512, 512), "the experiment's size");
    let mut rig = Rig::new(state, true);
    rig.harness.run_steps(3);
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        assert_eq!(jobs.len(), 1, "{side:?}: one job, not one per frame");
        let job = &jobs[0];
        let state = rig.state();
        assert_eq!(job.generation, state.generation[side.index()]);
        assert!(Arc::ptr_eq(&job.experiment, state.rendered(side)));
        // Nothing moved yet, so no adaptive reduction: the full size.
        assert_eq!((job.width, job.height), (w, h));
        assert_eq!(job.frames, state.sides[side.index()].max_spp);
    }
    // The sides start different: the file's features against soft shadows.
    assert_ne!(
        rig.state().rendered(Side::Left).settings.features,
        rig.state().rendered(Side::Right).settings.features
    );
    assert!(
        rig.take_jobs(2).is_empty(),
        "no reference before it is asked for"
    );
    assert_eq!(rig.harness.query_all_by_label("rendering...").count(), 2);
}

#[test]
fn while_interacting_jobs_are_scaled_to_the_measured_cost_then_full_size_once_settled() {
    let mut rig = Rig::new(small_area_lights(), true);
    rig.harness.state_mut().adaptive.settle_s = 3600.0;
    rig.harness.step();
    rig.clear_jobs();
    let left_generation = rig.state().generation[0];
    rig.checkbox("ambient occlusion (right)").click();
    rig.harness.step();
    let generation = rig.state().generation[1];
    let sizes = |jobs: Vec<Job>| {
        jobs.iter()
            .map(|j| (j.generation, j.width, j.height))
            .collect::<Vec<_>>()
    };
    // Nothing measured yet: a quarter of each side.
    let quarter = scaled_size(W, H, 0.25);
    assert_eq!(
        sizes(rig.take_side_jobs(Side::Right)),
        vec![(generation, quarter.0, quarter.1)]
    );
    // A full-size image of this generation is not what the app waits for now.
    rig.send_current(Side::Right, constant(W, H, 0.5), 1);
    rig.harness.step();
    assert_eq!(rig.app().frames(Side::Right), 0);
    assert!(rig.take_side_jobs(Side::Right).is_empty());

    // A quarter-size frame that took 10 us per pixel: only the right side is
    // changing, so at scale s it costs 10 us * W * H * s^2 = 61 ms * s^2, and 0.75 is
    // the largest scale that fits the 50 ms budget (0.5 if both sides were moving).
    let pixels = quarter.0 * quarter.1;
    let total = rig.state().sides[1].max_spp;
    rig.send_timed(
        Channel::Side(Side::Right),
        generation,
        constant(quarter.0, quarter.1, 0.5),
        1,
        total,
        Duration::from_nanos(10_000 * pixels as u64),
    );
    rig.harness.step();
    let three_quarters = scaled_size(W, H, 0.75);
    assert_eq!(
        sizes(rig.take_side_jobs(Side::Right)),
        vec![(generation, three_quarters.0, three_quarters.1)]
    );
    // The left side, not changing, kept its full size throughout.
    assert!(rig.take_side_jobs(Side::Left).is_empty());

    // Settled: the same generation again, at full size.
    rig.harness.state_mut().adaptive.settle_s = 0.0;
    rig.harness.step();
    assert_eq!(
        sizes(rig.take_side_jobs(Side::Right)),
        vec![(generation, W, H)]
    );
    // The left side was not changed: no new job, its accumulation goes on.
    assert_eq!(rig.state().generation[0], left_generation);
    assert!(rig.take_side_jobs(Side::Left).is_empty());
}

#[test]
fn ambient_occlusion_checkbox_restarts_only_its_side() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    assert!(
        !rig.state()
            .rendered(Side::Right)
            .settings
            .features
            .term("ambient_occlusion")
    );
    rig.checkbox("ambient occlusion (right)").click();
    rig.harness.run_steps(2);
    let state = rig.state();
    assert_eq!(state.generation, [before[0], before[1] + 1]);
    let jobs = rig.take_side_jobs(Side::Right);
    assert_eq!(jobs.len(), 1);
    assert_eq!(jobs[0].generation, before[1] + 1);
    assert!(
        jobs[0]
            .experiment
            .settings
            .features
            .term("ambient_occlusion")
    );
    assert!(Arc::ptr_eq(
        &jobs[0].experiment,
        state.rendered(Side::Right)
    ));
    assert!(rig.take_side_jobs(Side::Left).is_empty());
    assert!(rig.take_jobs(2).is_empty());
    assert!(
        !state
            .rendered(Side::Left)
            .settings
            .features
            .term("ambient_occlusion")
    );
}

#[test]
fn shadow_combo_box_switches_the_left_side_to_cones_and_leaves_the_right_alone() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    let right_before = rig.state().rendered(Side::Right).clone();
    rig.harness
        .get_by_role_and_label(Role::ComboBox, "shadows (left)")
        .click();
    rig.harness.run_steps(2);
    rig.harness.get_by_label(ShadowModel("cone").name()).click();
    rig.harness.run_steps(2);
    let jobs = rig.take_side_jobs(Side::Left);
    assert_eq!(jobs.len(), 1);
    let f = &jobs[0].experiment.settings.features;
    assert_eq!(f.shadow_model.name, "cone", "{f:?}");
    assert_eq!(jobs[0].generation, before[0] + 1);
    assert_eq!(rig.state().generation, [before[0] + 1, before[1]]);
    assert!(rig.take_side_jobs(Side::Right).is_empty());
    assert!(Arc::ptr_eq(
        &right_before,
        rig.state().rendered(Side::Right)
    ));
    // The cone knobs appear for the side that now traces cones.
    assert!(rig.harness.query_by_label("cone knobs").is_some());
}

/// The reconstruction's combo box sets the side's filter (the plan keeps it under the
/// sampled area lights), and its knobs appear.
#[test]
fn reconstruction_combo_box_filters_the_left_side() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig.harness
        .get_by_role_and_label(Role::ComboBox, "reconstruction (left)")
        .click();
    rig.harness.run_steps(2);
    rig.harness.get_by_label("atrous").click();
    rig.harness.run_steps(2);
    let jobs = rig.take_side_jobs(Side::Left);
    assert_eq!(jobs.len(), 1);
    let f = &jobs[0].experiment.settings.features;
    assert_eq!(f.reconstruction.name, "atrous", "{f:?}");
    assert!(rig.take_side_jobs(Side::Right).is_empty());
    assert!(rig.harness.query_by_label("atrous knobs").is_some());
}

#[test]
fn light_intensity_edit_restarts_both_sides_with_the_new_value() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    assert_eq!(intensity(&rig.state().base.scene.lights[0]), 384.0);
    rig.drag_value_in_row("intensity")
        .set_value_accesskit(500.0);
    rig.harness.run_steps(2);
    assert_eq!(rig.state().generation, [before[0] + 1, before[1] + 1]);
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        assert_eq!(jobs.len(), 1, "{side:?}");
        assert_eq!(jobs[0].generation, before[side.index()] + 1);
        assert_eq!(intensity(&jobs[0].experiment.scene.lights[0]), 500.0);
        // The other lights are untouched.
        assert_eq!(intensity(&jobs[0].experiment.scene.lights[1]), 256.0);
    }
    assert!(rig.take_jobs(2).is_empty());
}

#[test]
fn reset_camera_button_restores_the_experiment_camera_and_restarts_both_sides() {
    let mut state = small_area_lights();
    let home = state.home_camera.clone();
    state.orbit_degrees(30.0, -10.0).unwrap();
    assert_ne!(state.base.scene.camera, home);
    let mut rig = Rig::new(state, false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    rig.harness.get_by_label("Reset camera (R)").click();
    rig.harness.run_steps(2);
    assert_eq!(rig.state().base.scene.camera, home);
    assert_eq!(rig.state().generation, [before[0] + 1, before[1] + 1]);
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        assert_eq!(jobs.len(), 1, "{side:?}");
        assert_eq!(jobs[0].experiment.scene.camera, home);
    }
    // The R key does the same.
    rig.harness
        .state_mut()
        .state
        .orbit_degrees(-45.0, 5.0)
        .unwrap();
    rig.harness.run_steps(2);
    assert_ne!(rig.state().base.scene.camera, home);
    rig.clear_jobs();
    rig.harness.key_press(egui::Key::R);
    rig.harness.run_steps(2);
    assert_eq!(rig.state().base.scene.camera, home);
    for side in Side::BOTH {
        assert_eq!(rig.take_side_jobs(side).len(), 1, "{side:?}");
    }
}

#[test]
fn current_update_shows_its_frame_count_and_stale_updates_are_ignored() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let generation = rig.state().generation[0];
    let cap = rig.state().sides[0].max_spp;

    // Stale before anything arrived: an older generation, or the wrong size.
    rig.send(
        Channel::Side(Side::Left),
        generation - 1,
        constant(W, H, 0.5),
        2,
        cap,
    );
    rig.send(
        Channel::Side(Side::Left),
        generation,
        constant(W / 2, H / 2, 0.5),
        4,
        cap,
    );
    rig.harness.run_steps(2);
    assert!(rig.app().latest(Side::Left).is_none());
    assert_eq!(rig.harness.query_all_by_label("rendering...").count(), 2);

    rig.send(
        Channel::Side(Side::Left),
        generation,
        constant(W, H, 0.5),
        3,
        cap,
    );
    rig.harness.run_steps(2);
    assert_eq!(rig.app().frames(Side::Left), 3);
    assert!(rig.has_label(&format!("3 / {cap} frames at {W}x{H}")));
    assert!(rig.has_label("fake plan"));
    assert_eq!(rig.app().frames(Side::Right), 0);
    assert_eq!(rig.harness.query_all_by_label("rendering...").count(), 1);

    // Stale after: neither replaces the current image.
    rig.send(
        Channel::Side(Side::Left),
        generation - 1,
        constant(W, H, 0.5),
        5,
        cap,
    );
    rig.send(
        Channel::Side(Side::Left),
        generation,
        constant(W / 2, H / 2, 0.5),
        7,
        cap,
    );
    rig.harness.run_steps(2);
    assert_eq!(rig.app().frames(Side::Left), 3);
    assert!(rig.has_label(&format!("3 / {cap} frames at {W}x{H}")));
    assert!(!rig.has_label(&format!("5 / {cap} frames at {W}x{H}")));
    assert!(!rig.has_label(&format!("7 / {cap} frames at {}x{}", W / 2, H / 2)));

    // An image for the right side's channel goes to the right side only.
    let right_generation = rig.state().generation[1];
    rig.send(
        Channel::Side(Side::Right),
        right_generation,
        constant(W, H, 0.5),
        9,
        cap,
    );
    rig.harness.run_steps(2);
    assert_eq!(rig.app().frames(Side::Right), 9);
    assert_eq!(rig.app().frames(Side::Left), 3);

    // A change of the left side makes its image stale.
    rig.checkbox("indirect (left)").click();
    rig.harness.run_steps(2);
    assert!(rig.app().latest(Side::Left).is_none());
    assert!(!rig.has_label(&format!("3 / {cap} frames at {W}x{H}")));
    assert_eq!(rig.app().frames(Side::Right), 9);
}

/// A worker's update carries its plan's warnings (the GPU kernel's, `Plan::warnings`),
/// and the side's panel shows each under the plan; an update without any shows none.
#[test]
fn a_plans_warnings_are_shown_under_it() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let generation = rig.state().generation[0];
    let cap = rig.state().sides[0].max_spp;
    let warning = "render.ray_offset = 0 is below what the GPU kernel's f32 resolves";
    let update = |frames: u32, warnings: Vec<String>| {
        Report::Update(Update {
            generation,
            frame: Arc::new(constant(W, H, 0.5)),
            frames,
            total: cap,
            frame_time: Duration::ZERO,
            plan: "fake plan".to_string(),
            warnings,
        })
    };
    rig.reports
        .send((
            Channel::Side(Side::Left),
            update(1, vec![warning.to_string()]),
        ))
        .unwrap();
    rig.harness.run_steps(2);
    assert!(rig.has_label(&format!("warning: {warning}")));
    rig.reports
        .send((Channel::Side(Side::Left), update(2, Vec::new())))
        .unwrap();
    rig.harness.run_steps(2);
    assert_eq!(rig.app().frames(Side::Left), 2);
    assert!(!rig.has_label_containing("warning: "));
}

#[test]
fn dragging_the_divider_moves_it_without_restarting_anything() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    let camera = rig.state().base.scene.camera.clone();
    let g = rig.image_geometry();
    assert_eq!(rig.state().divider, 0.5);
    let from = pos2(g.split_x, g.point(0.5).y);
    rig.drag(from, vec2(0.25 * g.drawn.width(), 0.0), 5);
    let divider = rig.state().divider;
    assert!(
        (divider - 0.75).abs() < 0.02,
        "dragged a quarter of the width to the right: divider {divider}"
    );
    assert_eq!(rig.state().base.scene.camera, camera, "no orbit");
    assert_eq!(rig.state().generation, before);
    assert!(rig.take_side_jobs(Side::Left).is_empty());
    assert!(rig.take_side_jobs(Side::Right).is_empty());
    // The divider follows: its handle is where the line is drawn now.
    let moved = rig.image_geometry();
    assert!((moved.split_x - (g.drawn.left() + divider * g.drawn.width())).abs() < 0.5);
}

#[test]
fn dragging_the_image_orbits_the_camera_and_restarts_both_sides() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    let yaw = rig.state().base.scene.camera.yaw.to_degrees();
    let pitch = rig.state().base.scene.camera.pitch.to_degrees();
    let g = rig.image_geometry();
    // Left of the divider: the image, not the handle.
    rig.drag(g.point(0.2), vec2(40.0, 0.0), 4);
    let cam = &rig.state().base.scene.camera;
    let turned = yaw - cam.yaw.to_degrees();
    // 0.4 degrees per point; to the right turns the camera the other way.
    assert!(
        (turned - 16.0).abs() < 1e-3,
        "yaw {yaw} -> {}: turned {turned}",
        cam.yaw.to_degrees()
    );
    assert!((cam.pitch.to_degrees() - pitch).abs() < 1e-6);
    assert_eq!(rig.state().divider, 0.5, "the divider stays");
    let now = rig.state().generation;
    assert!(now[0] > before[0] && now[1] > before[1]);
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        let last = jobs.last().expect("a job for each side");
        assert_eq!(last.generation, now[side.index()]);
        assert_eq!(last.experiment.scene.camera, *cam);
    }
}

#[test]
fn scrolling_over_the_image_zooms_in_and_restarts_both_sides() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let before = rig.state().generation;
    let distance = rig.state().base.scene.camera.distance;
    let g = rig.image_geometry();
    rig.harness.hover_at(g.point(0.3));
    rig.harness.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Line,
        delta: vec2(0.0, 1.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Unknown,
        modifiers: egui::Modifiers::NONE,
    });
    // Smooth scrolling spreads the notch over a few frames.
    rig.harness.run_steps(10);
    let now = rig.state().base.scene.camera.distance;
    assert!(now < distance * 0.99, "distance {distance} -> {now}");
    assert!(
        now > distance * 0.5,
        "one notch, not a jump: {distance} -> {now}"
    );
    let generation = rig.state().generation;
    assert!(generation[0] > before[0] && generation[1] > before[1]);
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        let last = jobs.last().expect("a job for each side");
        assert_eq!(last.experiment.scene.camera.distance, now);
    }
    // Scrolling down zooms out.
    rig.harness.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Line,
        delta: vec2(0.0, -2.0),
        phase: egui::TouchPhase::Move,
        source: egui::MouseWheelSource::Unknown,
        modifiers: egui::Modifiers::NONE,
    });
    rig.harness.run_steps(10);
    assert!(rig.state().base.scene.camera.distance > now);
}

#[test]
fn error_vs_reference_renders_references_and_shows_rmse() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    // The left side traces cones: its reference samples the area lights instead.
    {
        let state = &mut rig.harness.state_mut().state;
        ShadowModel("cone").apply(&mut state.sides[0].features);
        state.commit(&[Side::Left]).unwrap();
    }
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    assert!(rig.take_side_jobs(Side::Left).is_empty());
    assert!(rig.take_side_jobs(Side::Right).is_empty());
    // The sides differ in transmittance too: two references, rendered one at a time.
    let mut jobs = rig.take_jobs(2);
    assert_eq!(jobs.len(), 1, "one reference at a time");
    let first = jobs.remove(0);
    let base_seed = rig.state().base.settings.seed;
    let left = rig.state().rendered(Side::Left).clone();
    let s = &first.experiment.settings;
    assert_eq!(s.features.shadow_model.name, "area");
    assert_eq!(
        s.features.transmittance,
        left.settings.features.transmittance
    );
    assert_ne!(s.seed, base_seed, "an independent seed");
    assert_eq!(s.seed, base_seed.wrapping_add(0x9E37_79B9));
    assert_eq!((first.width, first.height), (W, H));
    assert_eq!(first.frames, 256);
    assert!(rig.has_label("reference: 0 / 256 frames (1 more queued)"));

    // The left side's image arrives before its reference: no error yet.
    rig.send_current(Side::Left, constant(W, H, 0.25), 16);
    rig.send(
        Channel::Reference,
        first.generation,
        constant(W, H, 0.5),
        100,
        256,
    );
    rig.harness.run_steps(2);
    assert!(rig.app().side_error(Side::Left).is_none());
    assert!(rig.has_label("reference: 100 / 256 frames (1 more queued)"));
    assert!(rig.take_jobs(2).is_empty());

    // The finished reference: RMSE of 0.25 in every channel, and the next reference.
    rig.send(
        Channel::Reference,
        first.generation,
        constant(W, H, 0.5),
        256,
        256,
    );
    rig.harness.run_steps(2);
    let e = rig
        .app()
        .side_error(Side::Left)
        .expect("the left side's error");
    assert!((e.rmse - 0.25).abs() < 1e-9, "rmse {}", e.rmse);
    assert!(
        (e.psnr - 10.0 * 16f64.log10()).abs() < 1e-6,
        "psnr {}",
        e.psnr
    );
    assert_eq!(e.frames, 16);
    assert!(
        e.flip.is_some(),
        "FLIP is computed once the reference is there"
    );
    assert!(rig.has_label_containing("vs reference at 16 frames: RMSE 0.25000"));
    assert!(rig.app().side_error(Side::Right).is_none());
    let second = rig.take_jobs(2);
    assert_eq!(second.len(), 1);
    let s = &second[0].experiment.settings;
    assert_eq!(
        s.features.transmittance,
        rig.state()
            .rendered(Side::Right)
            .settings
            .features
            .transmittance
    );
    assert!(second[0].generation > first.generation);

    // A newer left image updates the error live.
    rig.send_current(Side::Left, constant(W, H, 0.4), 32);
    // A report of the finished first reference again is stale for the second.
    rig.send(
        Channel::Reference,
        first.generation,
        constant(W, H, 0.0),
        256,
        256,
    );
    rig.harness.run_steps(2);
    let e = rig.app().side_error(Side::Left).unwrap();
    assert!((e.rmse - 0.1).abs() < 1e-6, "rmse {}", e.rmse);
    assert_eq!(e.frames, 32);
    assert!(rig.app().side_error(Side::Right).is_none());

    rig.send(
        Channel::Reference,
        second[0].generation,
        constant(W, H, 1.0),
        256,
        256,
    );
    rig.send_current(Side::Right, constant(W, H, 0.5), 8);
    rig.harness.run_steps(2);
    let e = rig
        .app()
        .side_error(Side::Right)
        .expect("the right side's error");
    assert!((e.rmse - 0.5).abs() < 1e-6, "rmse {}", e.rmse);
    assert!(rig.take_jobs(2).is_empty(), "nothing more queued");
}

#[test]
fn sides_with_equal_reference_settings_share_one_reference_job() {
    let mut state = small_area_lights();
    // The same settings but the shadow model, which the reference replaces anyway.
    state.sides[1] = state.sides[0].clone();
    ShadowModel("hard").apply(&mut state.sides[0].features);
    ShadowModel("cone").apply(&mut state.sides[1].features);
    state.sides[1].max_spp = 64;
    state.commit(&Side::BOTH).unwrap();
    let mut rig = Rig::new(state, false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    let jobs = rig.take_jobs(2);
    assert_eq!(jobs.len(), 1);
    assert!(rig.has_label("reference: 0 / 256 frames (0 more queued)"));
    rig.send(
        Channel::Reference,
        jobs[0].generation,
        constant(W, H, 0.5),
        256,
        256,
    );
    rig.send_current(Side::Left, constant(W, H, 0.3), 4);
    rig.send_current(Side::Right, constant(W, H, 0.6), 4);
    rig.harness.run_steps(2);
    for (side, rmse) in [(Side::Left, 0.2), (Side::Right, 0.1)] {
        let e = rig.app().side_error(side).expect("both sides compared");
        assert!((e.rmse - rmse).abs() < 1e-6, "{side:?}: rmse {}", e.rmse);
    }
    // Asking again renders nothing new: the reference is known.
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    assert!(rig.take_jobs(2).is_empty());
}

/// `path` parsed, compared with what `side` renders with the traced size and frames.
fn assert_export_matches(rig: &Rig, side: Side, toml: &Path, frames: u32, size: (u32, u32)) {
    let mut loaded = Experiment::load(toml).expect("the exported file loads");
    assert_eq!(loaded.settings.spp, frames);
    assert_eq!((loaded.settings.width, loaded.settings.height), size);
    let mut expected = rig.state().rendered(side).as_ref().clone();
    expected.settings.spp = frames;
    expected.settings.width = size.0;
    expected.settings.height = size.1;
    assert_eq!(loaded.source_path.as_deref(), Some(toml));
    // What it was read from is the file's own record, not part of the experiment.
    assert!(loaded.source_record.is_some());
    loaded.source_path = expected.source_path.clone();
    loaded.source_record = expected.source_record.clone();
    assert_eq!(loaded.name, expected.name);
    assert_eq!(loaded.scene, expected.scene);
    assert_eq!(loaded.settings, expected.settings);
    assert_eq!(loaded, expected);
}

fn assert_png_is(path: &Path, frame: &Frame) {
    let png = image::open(path).expect("the PNG opens").to_rgb8();
    assert_eq!(png.dimensions(), (frame.width, frame.height));
    assert!(
        png.as_raw() == &frame.to_rgb8(),
        "{} differs",
        path.display()
    );
}

#[test]
fn save_button_writes_each_sides_image_and_the_experiment_that_reproduces_it() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let dir = temp_dir("save-button");
    rig.harness.state_mut().save_dir = dir.display().to_string();
    let (left, right) = (gradient(W, H), constant(W, H, 0.75));
    rig.send_current(Side::Left, left.clone(), 7);
    rig.send_current(Side::Right, right.clone(), 12);
    rig.harness.run_steps(2);
    rig.harness.get_by_label("Save images + TOML").click();
    rig.harness.run_steps(2);
    let name = rig.state().base.name.clone();
    assert_eq!(name, "area_lights");
    for (side, frame, frames) in [(Side::Left, &left, 7), (Side::Right, &right, 12)] {
        let png = dir.join(format!("{name}-001-{}.png", side.name()));
        let toml = dir.join(format!("{name}-001-{}.toml", side.name()));
        assert_png_is(&png, frame);
        assert_export_matches(&rig, side, &toml, frames, (W, H));
        // The image carries what made it: the experiment that reproduces it (the TOML
        // saved beside it), the build's revision, the frames.
        let stored: serde_json::Value = serde_json::from_str(
            &voxlab::output::read_png_provenance(&png)
                .unwrap()
                .expect("the PNG holds its provenance"),
        )
        .unwrap();
        assert_eq!(
            stored["resolved_experiment"].as_str().unwrap(),
            std::fs::read_to_string(&toml).unwrap()
        );
        assert_eq!(stored["revision"], voxlab::revision::revision());
        assert_eq!(stored["frames"], frames);
        let sidecar = std::fs::read_to_string(format!("{}.json", png.display())).unwrap();
        assert_eq!(
            serde_json::from_str::<serde_json::Value>(&sidecar).unwrap(),
            stored
        );
        // The EXR holds the radiance itself.
        let exr =
            voxlab::output::read_exr(dir.join(format!("{name}-001-{}.exr", side.name()))).unwrap();
        assert_eq!(exr.pixels, frame.pixels);
    }
    // The difference of the sides, in linear radiance.
    let diff = voxlab::output::read_exr(dir.join(format!("{name}-001-difference.exr"))).unwrap();
    for ((d, l), r) in diff.pixels.iter().zip(&left.pixels).zip(&right.pixels) {
        for c in 0..3 {
            assert!((d[c] - (l[c] - r[c]).abs()).abs() < 1e-6);
        }
    }
    let saved = rig.outcome.lock().unwrap().saved.clone();
    assert_eq!(
        saved.len(),
        11,
        "png, exr, toml and two provenance sidecars per side, and the difference: {saved:?}"
    );
    // A second save never overwrites the first: the next prefix.
    let first = std::fs::read(dir.join(format!("{name}-001-left.png"))).unwrap();
    rig.send_current(Side::Left, constant(W, H, 0.1), 8);
    rig.harness.run_steps(2);
    rig.harness.get_by_label("Save images + TOML").click();
    rig.harness.run_steps(2);
    assert_eq!(
        std::fs::read(dir.join(format!("{name}-001-left.png"))).unwrap(),
        first
    );
    assert_png_is(
        &dir.join(format!("{name}-002-left.png")),
        &constant(W, H, 0.1),
    );
    assert!(
        rig.app().status.starts_with("saved "),
        "{}",
        rig.app().status
    );
    assert!(rig.has_label_containing("saved "));
}

/// A save is both sides or nothing: pressed before the right side's first image, it
/// wrote the left side's files and then failed, leaving half a save behind.
#[test]
fn a_save_before_both_sides_have_an_image_writes_nothing() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let dir = temp_dir("save-half").join("new");
    rig.harness.state_mut().save_dir = dir.display().to_string();
    rig.send_current(Side::Left, gradient(W, H), 3);
    rig.harness.run_steps(2);
    rig.harness.get_by_label("Save images + TOML").click();
    rig.harness.run_steps(2);
    assert_eq!(
        rig.app().status,
        "save failed: the right side has no image yet; nothing written"
    );
    assert!(!dir.exists(), "a failed save made {}", dir.display());
    assert!(rig.outcome.lock().unwrap().saved.is_empty());
    // Once it has one, the save writes both.
    rig.send_current(Side::Right, constant(W, H, 0.5), 4);
    rig.harness.run_steps(2);
    rig.harness.get_by_label("Save images + TOML").click();
    rig.harness.run_steps(2);
    let name = rig.state().base.name.clone();
    for side in Side::BOTH {
        assert!(dir.join(format!("{name}-001-{}.png", side.name())).exists());
    }
}

#[test]
fn save_side_exports_the_traced_size_of_an_adaptive_image() {
    let mut rig = Rig::new(small_area_lights(), true);
    rig.harness.state_mut().adaptive.settle_s = 3600.0;
    rig.harness.step();
    // A change while interacting: the right side traces a quarter size.
    rig.checkbox("ambient occlusion (right)").click();
    rig.harness.run_steps(2);
    let job = rig.take_side_jobs(Side::Right).pop().expect("a job");
    let size = scaled_size(W, H, 0.25);
    assert_eq!((job.width, job.height), size);
    let frame = gradient(size.0, size.1);
    rig.send_current(Side::Right, frame.clone(), 5);
    rig.harness.run_steps(2);
    assert_eq!(rig.app().frames(Side::Right), 5);
    let dir = temp_dir("save-side");
    let (png, toml) = rig
        .harness
        .state_mut()
        .save_side(Side::Right, &dir)
        .expect("saved");
    assert_eq!(png, dir.join("area_lights-001-right.png"));
    assert_eq!(toml, dir.join("area_lights-001-right.toml"));
    assert_png_is(&png, &frame);
    assert_export_matches(&rig, Side::Right, &toml, 5, size);
    assert!(
        Experiment::load(&toml)
            .unwrap()
            .settings
            .features
            .term("ambient_occlusion")
    );
    // The left side has no image: nothing to save.
    let err = rig
        .harness
        .state_mut()
        .save_side(Side::Left, &dir)
        .unwrap_err();
    assert!(format!("{err}").contains("no image yet"), "{err}");
    assert!(!dir.join("area_lights-002-left.png").exists());
    assert!(!dir.join("area_lights-001-left.png").exists());
}

#[test]
fn a_value_beyond_the_declared_range_is_held_at_its_end_and_nothing_invalid_reaches_the_state() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    // The widgets span exactly the declared ranges (`voxlab::settings`): an infinite yaw
    // stops at the largest finite one, a pitch past the pole at the pole; the files the
    // state then exports parse.
    rig.drag_value_in_row("yaw_deg")
        .set_value_accesskit(f64::INFINITY);
    rig.harness.run_steps(2);
    rig.drag_value_in_row("pitch_deg").set_value_accesskit(95.0);
    rig.harness.run_steps(2);
    let status = rig.app().status.clone();
    assert!(!status.starts_with("edit rejected: "), "{status:?}");
    let camera = rig.state().base.scene.camera.clone();
    assert_eq!(camera.yaw, voxlab::settings::radians(f64::MAX));
    assert_eq!(camera.pitch, voxlab::settings::radians(90.0));
    let (_, parsed) = rig
        .harness
        .state_mut()
        .state
        .export(Side::Left, 1, W, H, None)
        .expect("the state exports a file that parses");
    assert_eq!(parsed.scene.camera, camera);
    assert!(!rig.take_side_jobs(Side::Left).is_empty());
}

#[test]
fn commit_of_a_value_the_file_format_rejects_changes_nothing() {
    // The light-samples field clamps to 1..=MAX_SAMPLES, so the window cannot produce
    // 0; the state's commit is what guards it.
    let mut state = small_area_lights();
    let generation = state.generation;
    let rendered = state.rendered(Side::Left).clone();
    state.sides[0].light_samples = 0;
    let err = state.commit(&[Side::Left]).unwrap_err();
    assert!(
        format!("{err:#}").contains("render.light_samples"),
        "{err:#}"
    );
    assert_eq!(state.generation, generation);
    assert!(Arc::ptr_eq(&rendered, state.rendered(Side::Left)));
}

#[test]
fn an_edit_drops_the_comparison_with_the_old_reference() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    let jobs = rig.take_jobs(2);
    assert_eq!(jobs.len(), 1, "one reference at a time");
    rig.send(
        Channel::Reference,
        jobs[0].generation,
        constant(W, H, 0.5),
        256,
        256,
    );
    rig.send_current(Side::Left, constant(W, H, 0.25), 4);
    rig.harness.run_steps(2);
    assert!(rig.app().side_error(Side::Left).is_some());

    // A light changes: the old reference is of another scene, so a new image of the
    // left side is not compared with it until the error is asked for again.
    {
        let app = rig.harness.state_mut();
        let mut lights = app.state.base.scene.lights.clone();
        match &mut lights[0] {
            Light::Point(p) => p.intensity *= 2.0,
            Light::Area(a) => a.intensity *= 2.0,
        }
        app.state.base.scene.lights = lights;
        app.state.commit_shared().unwrap();
    }
    // The generation moved on in the state; the window learns of it when it restarts
    // the sides, which a UI edit does through the same path as this one.
    rig.harness.state_mut().state.reset_camera().unwrap();
    rig.harness.get_by_label("Reset camera (R)").click();
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig.send_current(Side::Left, constant(W, H, 0.25), 4);
    rig.harness.run_steps(2);
    assert!(
        rig.app().side_error(Side::Left).is_none(),
        "compared with the reference of the scene before the edit"
    );
    // (By accesskit: the button may be scrolled out of the side panel by now.)
    rig.harness
        .get_by_label("Error vs reference")
        .click_accesskit();
    rig.harness.run_steps(2);
    assert_eq!(
        rig.take_jobs(2).len(),
        1,
        "a new reference for the new scene"
    );
}

// ---------------------------------------------------------------------------------------
// Comparison views, probe, zoom, stale images, controls that apply, saves, reload.

use voxlab::viewer::display::{ViewMode, Zoom};

const SMOOTH_SURFACE: voxlab::render::Surface =
    voxlab::render::Surface(&voxlab::technique::smooth::SURFACE);

const SPARSE_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::sparse::TRAVERSAL);

#[test]
fn view_modes_compare_the_same_pixels_and_b_flips_the_sides() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let (left, right) = (gradient(W, H), constant(W, H, 0.5));
    rig.send_current(Side::Left, left.clone(), 3);
    rig.send_current(Side::Right, right.clone(), 3);
    rig.harness.run_steps(2);
    assert_eq!(
        rig.app().comparison(),
        None,
        "the split view compares nothing"
    );
    // The view combo box: difference.
    rig.harness
        .get_by_role_and_label(Role::ComboBox, "view (B flips sides)")
        .click();
    rig.harness.run_steps(2);
    rig.harness.get_by_label("difference |L - R|").click();
    rig.harness.run_steps(2);
    assert_eq!(rig.app().display.mode, ViewMode::Difference);
    assert_eq!(rig.app().comparison(), Some(None));
    assert!(rig.has_label("difference gain"));
    // A colour bar says what the view's colours mean: white is 1 / gain of radiance.
    assert!(
        rig.has_label_containing("colour bar: |L - R| radiance 0 .. 0.25"),
        "difference view without its colour bar"
    );
    // FLIP: the mean of the map, the one metrics::flip gives.
    rig.harness.state_mut().display.mode = ViewMode::Flip;
    rig.harness.run_steps(2);
    let want = voxlab::metrics::flip_mean(&left, &right);
    assert_eq!(rig.app().comparison(), Some(Some(want)));
    assert!(rig.has_label(&format!("FLIP mean (R vs L) {want:.4}")));
    assert!(rig.has_label_containing("colour bar: FLIP error 0 .. 1"));
    // A new frame of one side makes a new map: while the sides accumulate, once the
    // last map is half a second old (a FLIP map costs tens of ms on the window's thread).
    rig.send_current(Side::Right, constant(W, H, 0.4), 4);
    rig.harness.run_steps(2);
    let still = rig.app().comparison();
    assert_eq!(still, Some(Some(want)), "not remade within the interval");
    std::thread::sleep(Duration::from_millis(550));
    rig.harness.run_steps(2);
    let again = voxlab::metrics::flip_mean(&left, &constant(W, H, 0.4));
    assert_eq!(rig.app().comparison(), Some(Some(again)));
    // B: one side alone, then the other, over the same pixels.
    rig.harness.key_press(egui::Key::B);
    rig.harness.run_steps(1);
    assert_eq!(rig.app().display.mode, ViewMode::Left);
    assert_eq!(rig.app().comparison(), None);
    rig.harness.key_press(egui::Key::B);
    rig.harness.run_steps(1);
    assert_eq!(rig.app().display.mode, ViewMode::Right);
    // The divider exists only in the split view.
    assert!(
        rig.harness
            .query_by_role_and_label(Role::Splitter, "divider")
            .is_none()
    );
}

/// `voxlab view --exposure EV` takes what `render --exposure` takes, and the view bar's
/// control shows it as given: it once held any exposure past 16 stops at 16 without a
/// word, so the window showed another image than the one asked for.
#[test]
fn the_exposure_control_keeps_every_exposure_the_command_line_takes() {
    let most = voxlab::frame::DisplayTransform::MAX_EXPOSURE;
    let mut rig = Rig::new(small_area_lights(), false);
    for ev in [-most, -20.0, 20.0, most] {
        assert_eq!(voxlab::frame::DisplayTransform::check_exposure(ev), Ok(ev));
        rig.harness.state_mut().display.exposure = ev;
        rig.harness.run_steps(2);
        assert_eq!(rig.app().display.exposure, ev);
    }
    assert!(voxlab::frame::DisplayTransform::check_exposure(most + 0.5).is_err());
}

#[test]
fn the_probe_reads_each_sides_radiance_and_a_click_pins_it() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let left = gradient(W, H);
    rig.send_current(Side::Left, left.clone(), 5);
    rig.send_current(Side::Right, constant(W, H, 0.75), 9);
    rig.harness.run_steps(2);
    let g = rig.image_geometry();
    // The pixel at a quarter of the width, half the height.
    let at = pos2(
        g.drawn.left() + 0.25 * g.drawn.width(),
        g.drawn.top() + 0.5 * g.drawn.height(),
    );
    rig.harness.hover_at(at);
    rig.harness.run_steps(2);
    let (x, y) = (W / 4, H / 2);
    let p = left.pixels[(y * W + x) as usize];
    let text = rig.app().probe_text().expect("a probe under the pointer");
    assert!(text.starts_with(&format!("pixel ({x}, {y})")), "{text}");
    assert!(
        text.contains(&format!(
            "left: {:.4} {:.4} {:.4} (5 frames)",
            p[0], p[1], p[2]
        )),
        "{text}"
    );
    assert!(
        text.contains("right: 0.7500 0.7500 0.7500 (9 frames)"),
        "{text}"
    );
    assert!(rig.has_label(&text), "shown in the probe bar");
    // A click pins it; the pointer leaving keeps it; Escape lets go.
    rig.harness.drag_at(at);
    rig.harness.drop_at(at);
    rig.harness.run_steps(2);
    assert_eq!(rig.app().probe_pinned, Some((x, y)));
    rig.harness.hover_at(pos2(1.0, 1.0));
    rig.harness.run_steps(2);
    assert!(rig.app().probe_text().unwrap().contains("pinned"));
    rig.harness.key_press(egui::Key::Escape);
    rig.harness.run_steps(2);
    assert_eq!(rig.app().probe_pinned, None);
    assert_eq!(rig.app().probe_text(), None);
    // Clicking did not orbit.
    assert_eq!(
        rig.state().base.scene.camera,
        small_area_lights().base.scene.camera
    );
}

#[test]
fn one_to_one_zoom_shows_an_image_pixel_per_screen_pixel() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    let fit = rig.image_geometry().drawn;
    assert!(fit.width() > 4.0 * W as f32, "fitted to the panel: {fit:?}");
    rig.harness.state_mut().display.zoom = Zoom::Pixels(1);
    rig.harness.run_steps(2);
    let ppp = rig.harness.ctx.pixels_per_point();
    let one = rig.image_geometry().drawn;
    assert!(
        (one.width() * ppp - W as f32).abs() < 0.5,
        "{one:?} at {ppp}"
    );
    assert!((one.height() * ppp - H as f32).abs() < 0.5);
    rig.harness.state_mut().display.zoom = Zoom::Pixels(4);
    rig.harness.run_steps(2);
    let four = rig.image_geometry().drawn;
    assert!(
        (four.width() * ppp - 4.0 * W as f32).abs() < 0.5,
        "{four:?}"
    );
}

#[test]
fn after_a_camera_reset_the_old_image_is_marked_stale_until_the_new_one_arrives() {
    let mut state = small_area_lights();
    state.orbit_degrees(30.0, 0.0).unwrap();
    let mut rig = Rig::new(state, false);
    rig.harness.run_steps(2);
    rig.send_current(Side::Left, constant(W, H, 0.3), 2);
    rig.send_current(Side::Right, constant(W, H, 0.6), 2);
    rig.harness.run_steps(2);
    assert!(!rig.app().stale(Side::Left) && !rig.app().stale(Side::Right));
    rig.harness.key_press(egui::Key::R);
    rig.harness.run_steps(2);
    // Both images are of the old camera now.
    assert!(rig.app().stale(Side::Left) && rig.app().stale(Side::Right));
    assert!(rig.app().latest(Side::Left).is_none());
    // An update of the old generation does not make it current.
    let old = rig.state().generation[0] - 1;
    rig.send(Channel::Side(Side::Left), old, constant(W, H, 0.9), 3, 256);
    rig.harness.run_steps(2);
    assert!(rig.app().stale(Side::Left));
    rig.send_current(Side::Left, constant(W, H, 0.3), 1);
    rig.harness.run_steps(2);
    assert!(!rig.app().stale(Side::Left));
    assert!(rig.app().stale(Side::Right), "the right side still renders");
}

#[test]
fn a_drag_that_starts_just_beside_the_divider_moves_it_and_never_orbits() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    let camera = rig.state().base.scene.camera.clone();
    let before = rig.state().generation;
    let g = rig.image_geometry();
    // 15 points right of the line: outside the 20-point handle, inside the grab zone.
    let from = pos2(g.split_x + 15.0, g.point(0.5).y);
    rig.drag(from, vec2(-0.1 * g.drawn.width(), 0.0), 4);
    let divider = rig.state().divider;
    assert!((divider - 0.4).abs() < 0.02, "divider {divider}");
    assert_eq!(rig.state().base.scene.camera, camera, "no orbit");
    assert_eq!(rig.state().generation, before, "no accumulation discarded");
    assert!(rig.take_side_jobs(Side::Left).is_empty());
}

#[test]
fn controls_that_do_not_apply_are_not_shown() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    // Both sides sample the area light: both have light samples and frames.
    let rows = |rig: &Rig, label: &str| rig.harness.query_all_by_label(label).count();
    assert_eq!(rows(&rig, "light_samples"), 2);
    assert_eq!(rows(&rig, "max frames"), 2);
    // Cones draw no samples: the left side's rows go.
    {
        let state = &mut rig.harness.state_mut().state;
        ShadowModel("cone").apply(&mut state.sides[0].features);
        state.commit(&[Side::Left]).unwrap();
    }
    rig.harness.run_steps(2);
    assert_eq!(rows(&rig, "light_samples"), 1);
    assert_eq!(rows(&rig, "max frames"), 1);
    // A rect light turns about its normal; a disk looks the same turned.
    assert_eq!(rows(&rig, "rotation_deg"), 1);
    {
        let state = &mut rig.harness.state_mut().state;
        if let Light::Area(a) = &mut state.base.scene.lights[0] {
            a.shape = voxlab::scene::AreaShape::Disk { radius: 2.0 };
        }
        state.commit_shared().unwrap();
    }
    rig.harness.run_steps(2);
    assert_eq!(rows(&rig, "rotation_deg"), 0);
    assert!(rig.has_label("radius"));
}

#[test]
fn the_pixel_filter_is_chosen_in_the_render_panel() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    assert!(!rig.has_label("filter_width"));
    rig.harness
        .get_by_role_and_label(Role::ComboBox, "pixel filter")
        .click();
    rig.harness.run_steps(2);
    rig.harness.get_by_label("gaussian").click();
    rig.harness.run_steps(2);
    assert_eq!(
        rig.state().base.settings.pixel_filter,
        voxlab::render::PixelFilter::Gaussian
    );
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        let job = jobs.last().expect("both sides restart");
        assert_eq!(
            job.experiment.settings.pixel_filter,
            voxlab::render::PixelFilter::Gaussian
        );
    }
    assert!(rig.has_label("filter_width"));
}

#[test]
fn the_walk_and_the_surface_are_chosen_in_the_render_panel() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig.harness
        .get_by_role_and_label(Role::ComboBox, "surface")
        .click();
    rig.harness.run_steps(2);
    rig.harness.get_by_label("smooth").click();
    rig.harness.run_steps(2);
    rig.harness
        .get_by_role_and_label(Role::ComboBox, "traversal")
        .click();
    rig.harness.run_steps(2);
    rig.harness.get_by_label("sparse").click();
    rig.harness.run_steps(2);
    let settings = &rig.state().base.settings;
    assert_eq!(settings.surface, SMOOTH_SURFACE);
    assert_eq!(settings.traversal, SPARSE_WALK);
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        let job = jobs.last().expect("both sides restart");
        assert_eq!(job.experiment.settings.surface, SMOOTH_SURFACE);
        assert_eq!(job.experiment.settings.traversal, SPARSE_WALK);
    }
}

#[test]
fn kept_on_error_readouts_ask_for_new_references_after_every_change() {
    let mut rig = Rig::new(small_area_lights(), false);
    rig.harness.state_mut().adaptive.settle_s = 0.0;
    rig.harness.run_steps(2);
    rig.checkbox("keep error on").click();
    rig.harness.run_steps(2);
    assert!(
        rig.take_jobs(2).is_empty(),
        "nothing to compare before an image"
    );
    rig.send_current(Side::Left, constant(W, H, 0.3), 1);
    rig.harness.run_steps(2);
    let first = rig.take_jobs(2);
    assert_eq!(first.len(), 1, "a reference, without the button");
    // A change: the references of the new state are asked for once it has an image.
    rig.checkbox("ambient occlusion (left)").click();
    rig.harness.run_steps(2);
    rig.send_current(Side::Left, constant(W, H, 0.3), 1);
    rig.harness.run_steps(2);
    // The old left reference is dropped; the right one (queued, still wanted) comes
    // first, then the new left one.
    let mut jobs = rig.take_jobs(2);
    assert_eq!(jobs.len(), 1, "one reference at a time");
    let right = jobs.remove(0);
    assert!(right.generation > first[0].generation);
    assert!(!right.experiment.settings.features.term("ambient_occlusion"));
    rig.send(
        Channel::Reference,
        right.generation,
        constant(W, H, 0.5),
        right.frames,
        right.frames,
    );
    rig.harness.run_steps(2);
    let left = rig.take_jobs(2);
    assert_eq!(left.len(), 1, "{}", left.len());
    assert!(
        left[0]
            .experiment
            .settings
            .features
            .term("ambient_occlusion")
    );
}

#[test]
fn the_experiment_file_is_reloaded_when_it_changes_on_disk() {
    let dir = temp_dir("reload");
    let file = dir.join("live.toml");
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/area_lights.toml"),
    )
    .unwrap()
    .replace("width = 512", &format!("width = {W}"))
    .replace("height = 512", &format!("height = {H}"));
    std::fs::write(&file, &text).unwrap();
    let mut rig = watching(&file);
    let before = rig.state().generation;
    assert_eq!(intensity(&rig.state().base.scene.lights[0]), 384.0);
    // The file is edited: a light's intensity.
    std::fs::write(
        &file,
        text.replacen("intensity = 384.0", "intensity = 99.0", 1),
    )
    .unwrap();
    std::thread::sleep(voxlab::viewer::reload::INTERVAL + Duration::from_millis(50));
    rig.harness.run_steps(2);
    assert_eq!(intensity(&rig.state().base.scene.lights[0]), 99.0);
    let now = rig.state().generation;
    assert!(
        now[0] > before[0] && now[1] > before[1],
        "{before:?} -> {now:?}"
    );
    for side in Side::BOTH {
        let jobs = rig.take_side_jobs(side);
        assert_eq!(
            intensity(&jobs.last().unwrap().experiment.scene.lights[0]),
            99.0
        );
    }
    assert!(
        rig.app().status.starts_with("reloaded "),
        "{}",
        rig.app().status
    );
    // A broken file keeps the last good state and says why.
    std::fs::write(&file, "[render]\nwidth = 0\n").unwrap();
    std::thread::sleep(voxlab::viewer::reload::INTERVAL + Duration::from_millis(50));
    rig.harness.run_steps(2);
    assert_eq!(intensity(&rig.state().base.scene.lights[0]), 99.0);
    let status = rig.app().status.clone();
    assert!(
        status.contains("reload failed") && status.contains("render.width"),
        "{status}"
    );
}

/// The files the experiment reads are watched too: a `.vox` saved again (from
/// MagicaVoxel, say) reloads the scene, and so does the experiment naming another one,
/// which is then the one watched.
/// A rig on the experiment `file`, watching it as `voxlab view` does, its first jobs
/// taken.
fn watching(file: &Path) -> Rig {
    let opts = ViewOptions {
        experiment: Some(file.to_path_buf()),
        ..Default::default()
    };
    let state = voxlab::viewer::load_state(&opts).unwrap();
    let mut rig = Rig::new(state, false);
    rig.harness.state_mut().watch(opts);
    rig.harness.run_steps(2);
    rig.clear_jobs();
    rig
}

/// `live.toml` in a fresh directory `name`, its scene `model.vox` (an 8x6x8 grid with
/// one voxel of material 2, returned with the palette it was written with) under
/// `light`, a `[[lights]]` table's lines.
fn vox_experiment(
    name: &str,
    light: &str,
) -> (PathBuf, voxlab::scene::Grid, Vec<voxlab::scene::Material>) {
    let dir = temp_dir(name);
    let materials = voxlab::scene::seed_scene(16).unwrap().materials;
    let mut grid =
        voxlab::scene::Grid::new(glam::UVec3::new(8, 6, 8), 1.0, glam::DVec3::ZERO).unwrap();
    grid.set(glam::IVec3::new(1, 0, 1), 2);
    voxlab::scene::write_vox(dir.join("model.vox"), &grid, &materials).unwrap();
    let file = dir.join("live.toml");
    std::fs::write(
        &file,
        format!(
            "[scene]\nvox = \"model.vox\"\n\n[render]\nwidth = {W}\nheight = {H}\n\n\
             [[lights]]\n{light}"
        ),
    )
    .unwrap();
    (file, grid, materials)
}

#[test]
fn a_scene_file_saved_again_reloads_the_scene() {
    let (file, mut grid, materials) = vox_experiment(
        "reload-vox",
        "type = \"point\"\nposition = [4.0, 12.0, 4.0]\nintensity = 50.0\n",
    );
    let dir = file.parent().unwrap().to_path_buf();
    let opts = ViewOptions {
        experiment: Some(file.clone()),
        ..Default::default()
    };
    let watch = voxlab::viewer::reload::Watch::new(opts).unwrap();
    let watched: Vec<_> = watch.files().map(Path::to_path_buf).collect();
    assert_eq!(watched.len(), 2, "{watched:?}");
    assert!(watched[1].ends_with("model.vox"), "{watched:?}");
    let mut rig = watching(&file);
    let solid = |rig: &Rig| {
        let g = &rig.state().base.scene.grid;
        (g.dims(), g.data().iter().filter(|&&m| m != 0).count())
    };
    assert_eq!(solid(&rig), (glam::UVec3::new(8, 6, 8), 1));
    let before = rig.state().generation;
    // MagicaVoxel saves the model again, with two more voxels.
    grid.set(glam::IVec3::new(2, 0, 1), 2);
    grid.set(glam::IVec3::new(3, 0, 1), 2);
    voxlab::scene::write_vox(dir.join("model.vox"), &grid, &materials).unwrap();
    std::thread::sleep(voxlab::viewer::reload::INTERVAL + Duration::from_millis(50));
    rig.harness.run_steps(2);
    assert_eq!(solid(&rig), (glam::UVec3::new(8, 6, 8), 3));
    let now = rig.state().generation;
    assert!(
        now[0] > before[0] && now[1] > before[1],
        "{before:?} -> {now:?}"
    );
    let status = &rig.app().status;
    assert!(
        status.starts_with("reloaded ") && status.ends_with("model.vox changed)"),
        "{status}"
    );
    // The experiment names another model: that one is watched from now on.
    let mut other =
        voxlab::scene::Grid::new(glam::UVec3::new(4, 4, 4), 1.0, glam::DVec3::ZERO).unwrap();
    other.set(glam::IVec3::new(0, 0, 0), 1);
    voxlab::scene::write_vox(dir.join("other.vox"), &other, &materials).unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replace("model.vox", "other.vox")).unwrap();
    std::thread::sleep(voxlab::viewer::reload::INTERVAL + Duration::from_millis(50));
    rig.harness.run_steps(2);
    assert_eq!(solid(&rig), (glam::UVec3::new(4, 4, 4), 1));
    other.set(glam::IVec3::new(1, 0, 0), 1);
    voxlab::scene::write_vox(dir.join("other.vox"), &other, &materials).unwrap();
    std::thread::sleep(voxlab::viewer::reload::INTERVAL + Duration::from_millis(50));
    rig.harness.run_steps(2);
    assert_eq!(solid(&rig), (glam::UVec3::new(4, 4, 4), 2));
}

/// A reference is kept by its experiment's text, which names the scene's files but not
/// what they hold: after a `.vox` is saved again and the scene reloads, asking for the
/// error renders new references instead of comparing with the old model's.
#[test]
fn a_scene_file_saved_again_drops_the_old_references() {
    let (file, mut grid, materials) = vox_experiment(
        "reload-vox-reference",
        "type = \"rect\"\nposition = [4.0, 12.0, 4.0]\nnormal = [0.0, -1.0, 0.0]\n\
         size = [2.0, 2.0]\nintensity = 50.0\n",
    );
    let dir = file.parent().unwrap().to_path_buf();
    let mut rig = watching(&file);
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    // The sides' references (one a side where their settings differ), one at a time.
    let mut rendered = 0;
    loop {
        let jobs = rig.take_jobs(2);
        let Some(job) = jobs.last() else { break };
        rig.send(
            Channel::Reference,
            job.generation,
            constant(W, H, 0.5),
            256,
            256,
        );
        rig.harness.run_steps(2);
        rendered += 1;
    }
    assert!((1..=2).contains(&rendered), "{rendered} references");
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    assert!(rig.take_jobs(2).is_empty(), "the reference is known");
    // The model is saved again: the experiment's text is the same, its scene is not.
    grid.set(glam::IVec3::new(2, 0, 1), 2);
    voxlab::scene::write_vox(dir.join("model.vox"), &grid, &materials).unwrap();
    std::thread::sleep(voxlab::viewer::reload::INTERVAL + Duration::from_millis(50));
    rig.harness.run_steps(2);
    assert!(
        rig.app().status.starts_with("reloaded "),
        "{}",
        rig.app().status
    );
    rig.clear_jobs();
    rig.harness.get_by_label("Error vs reference").click();
    rig.harness.run_steps(2);
    let jobs = rig.take_jobs(2);
    assert_eq!(jobs.len(), 1, "the old model's references were kept");
    let solid = jobs[0]
        .experiment
        .scene
        .grid
        .data()
        .iter()
        .filter(|&&m| m != 0)
        .count();
    assert_eq!(solid, 2, "the reference job renders the new model");
}
