//! A [`Session`]: one tracer (the GPU kernel on one device, or the f64 CPU reference)
//! kept open across renders, so a sweep compiles each kernel variant and uploads each
//! scene once. [`Session::render`] gives an [`Image`]: the radiance, what it cost and
//! the plan it was traced with; [`Image::provenance`] the record `voxlab render --json`
//! prints and stores beside every image.

use std::ops::Range;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::accumulation::AccumulationKey;
use crate::error::{Error, ErrorKind, Result};
use crate::experiment::{Experiment, Override};
use crate::frame::{DisplayTransform, Frame, RayStats};
use crate::gpu::GpuTracer;
use crate::plan::Plan;
use crate::progress::{Progress, Watch};
use crate::render::RenderSettings;
use crate::scene::Scene;

/// Which tracer a session renders with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    /// The wgpu compute kernel on the first adapter wgpu finds.
    Gpu,
    /// The f64 reference on the CPU: the tests' oracle.
    Cpu,
}

enum Tracer {
    Gpu(Box<GpuTracer>),
    Cpu {
        label: String,
        /// The walks' data of the latest renders, kept as the GPU tracer keeps its
        /// own: a loop of renders of one grid builds it once.
        walks: crate::technique::WalkBuilds,
        /// The sums of the latest `render_frames` call of an accumulating plan, which
        /// the next may continue: what it was made from, and the sums.
        accumulation: Option<(AccumulationKey, crate::cpu::FrameSums)>,
        /// The triangle surface of the latest render that traced one, as the GPU
        /// tracer keeps its upload.
        surface: crate::cpu::KeptSurface,
    },
}

impl Tracer {
    fn cpu(label: String) -> Self {
        Self::Cpu {
            label,
            walks: crate::technique::WalkBuilds::new(crate::technique::WALK_BUILDS_KEPT),
            accumulation: None,
            surface: None,
        }
    }
}

/// One tracer kept open across renders.
///
/// ```
/// use voxlab::{Backend, Experiment, Session};
///
/// let mut e = Experiment::load(concat!(env!("CARGO_MANIFEST_DIR"), "/experiments/baseline.toml"))?;
/// (e.settings.width, e.settings.height) = (16, 12);
/// let mut session = Session::new(Backend::Cpu)?;
/// let image = session.render(&e)?;
/// assert_eq!((image.width(), image.height()), (16, 12));
/// assert!(image.radiance().iter().flatten().all(|c| c.is_finite()));
/// assert!(image.stats.primary == 16 * 12);
/// # Ok::<(), voxlab::Error>(())
/// ```
pub struct Session {
    tracer: Tracer,
    /// The CPU reference's temporal history (the GPU tracer keeps its own on the
    /// device): the latest frame of a camera path, for a temporal reconstruction.
    history: Option<crate::frame::History>,
}

impl Session {
    /// A session on `backend`; with [`Backend::Gpu`] an error of kind
    /// [`ErrorKind::Device`] when no adapter can be opened.
    pub fn new(backend: Backend) -> Result<Self> {
        match backend {
            Backend::Cpu => Ok(Self::cpu()),
            Backend::Gpu => Ok(Self {
                tracer: Tracer::Gpu(Box::new(GpuTracer::new().map_err(|e| {
                    Error::new(ErrorKind::Device, format!("no GPU device: {e:#}"))
                })?)),
                history: None,
            }),
        }
    }

    /// A session on the f64 CPU reference, which always opens.
    pub fn cpu() -> Self {
        Self {
            tracer: Tracer::cpu(crate::cpu::backend_summary()),
            history: None,
        }
    }

    /// A session on `backend`, or on the CPU reference when the GPU cannot be opened;
    /// `warn` is told why (the command line prints it).
    pub fn or_cpu(backend: Backend, warn: impl Fn(&str)) -> Self {
        match Self::new(backend) {
            Ok(s) => s,
            Err(e) => {
                warn(&format!("GPU backend unavailable: {e}"));
                warn("rendering with the CPU reference instead");
                Self {
                    tracer: Tracer::cpu(format!(
                        "{} -- fallback, no GPU adapter found",
                        crate::cpu::backend_summary()
                    )),
                    history: None,
                }
            }
        }
    }

    /// The backend and, on the GPU, the adapter, as reports name it.
    pub fn label(&self) -> String {
        match &self.tracer {
            Tracer::Gpu(t) => format!("GPU {}", t.adapter_summary()),
            Tracer::Cpu { label, .. } => label.clone(),
        }
    }

    /// The GPU tracer, when the session has one (for its memory and timers).
    pub fn gpu(&self) -> Option<&GpuTracer> {
        match &self.tracer {
            Tracer::Gpu(t) => Some(t),
            Tracer::Cpu { .. } => None,
        }
    }

    /// Builds of a walk's data (the sparse tree, the octant field or codes) since the
    /// session opened, on either tracer: each keeps the latest
    /// [`WALK_BUILDS_KEPT`](crate::technique::WALK_BUILDS_KEPT), so a render of a grid
    /// and walk among them adds none.
    pub fn walk_data_builds(&self) -> u64 {
        match &self.tracer {
            Tracer::Gpu(t) => t.walk_data_builds(),
            Tracer::Cpu { walks, .. } => walks.built(),
        }
    }

    /// The GPU tracer, mutable: for what a measurement does beside renders (a cone
    /// pyramid built and read back on its own, to time it).
    pub(crate) fn gpu_mut(&mut self) -> Option<&mut GpuTracer> {
        match &mut self.tracer {
            Tracer::Gpu(t) => Some(t),
            Tracer::Cpu { .. } => None,
        }
    }

    /// Renders `e` (its `spp` frames where its plan samples anything, else one).
    pub fn render(&mut self, e: &Experiment) -> Result<Image> {
        self.render_with_progress(e, false)
    }

    /// Renders `scene` under `settings`, as [`render`](Self::render) renders an
    /// experiment: for a sweep that varies the settings of one scene, which it need not
    /// copy into an experiment per point.
    pub fn render_scene(&mut self, scene: &Scene, settings: &RenderSettings) -> Result<Image> {
        self.render_reporting(scene, settings, None, |_| None)
    }

    /// Renders frames `frames` (frame indices) of `settings`' accumulation of `scene`
    /// and gives the image averaged over frames `0..frames.end`, for a display that
    /// refines its image progressively: on the GPU, `frames.start > 0` continues the
    /// accumulation the session's previous call of this left (same scene, settings and
    /// plan, ended at `frames.start`; `GpuTracer::render_frames` says what else it
    /// checks), and `trace_time` covers this call's frames. The CPU reference keeps its
    /// sums in f64 and continues them by the same rule (the image is bit for bit a
    /// render of frames `0..frames.end`); on both, any other render ends the
    /// accumulation.
    pub fn render_frames(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        frames: Range<u32>,
    ) -> Result<Image> {
        self.render_reporting(scene, settings, Some(frames), |_| None)
    }

    /// As [`render`](Self::render), with a progress line on stderr (`forced`: even when
    /// stderr is not a terminal).
    pub fn render_with_progress(&mut self, e: &Experiment, forced: bool) -> Result<Image> {
        self.render_reporting(&e.scene, &e.settings, None, |unit| {
            Progress::new(&e.name, unit, forced)
        })
    }

    /// As [`render`](Self::render), followed by `watch` from another thread: its
    /// progress read there, and [`Watch::stop`] ends the render early with an error of
    /// kind [`ErrorKind::Interrupted`] (within a row of the CPU reference or a dispatch
    /// of the GPU kernel).
    pub fn render_watched(&mut self, e: &Experiment, watch: &Arc<Watch>) -> Result<Image> {
        self.render_reporting(&e.scene, &e.settings, None, |unit| {
            Some(Progress::watched(watch.clone(), unit))
        })
        .map_err(|err| {
            if watch.stopped() {
                Error::new(
                    ErrorKind::Interrupted,
                    format!("{}: render stopped on request", e.name),
                )
            } else {
                err
            }
        })
    }

    /// Empties the temporal history (`crate::frame::History`): the next render starts
    /// a camera path. [`render`](Self::render) does so itself where its path starts; a
    /// display that renders its own path (`render_frames` across camera moves) calls it
    /// when the path should forget what came before.
    pub fn reset_history(&mut self) {
        self.history = None;
        if let Tracer::Gpu(t) = &mut self.tracer {
            t.reset_history();
        }
    }

    /// A whole render: under `[render] path_frames = K > 1` the camera path's K frames
    /// (`RenderSettings::path_pose`; without a temporal reconstruction only the last
    /// two), the history emptied before the first, and the last frame's image, timings
    /// and counts (the frames before it are warm-up, outside them), with the one before
    /// it kept in [`Image::previous`]; otherwise one frame. A render starts with the
    /// history empty; only a range of the accumulation (a display's refinement) is a
    /// frame of the display's own path, accumulated onto the history the session keeps.
    fn render_reporting(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        range: Option<Range<u32>>,
        progress: impl Fn(&'static str) -> Option<Progress>,
    ) -> Result<Image> {
        let path = settings.path_frames.max(1);
        if range.is_some() {
            return self.render_frame(scene, settings, range, progress);
        }
        // A render is its own: no history from another render reaches it (an ablation's
        // points would otherwise depend on their order).
        self.reset_history();
        if path == 1 {
            return self.render_frame(scene, settings, range, progress);
        }
        let wall = Instant::now();
        let mut posed = scene.clone();
        let mut previous = None;
        // Without a temporal reconstruction the frames before the last change nothing
        // but `previous`: only that one is rendered.
        let first = if settings.features.reconstruction.temporal {
            0
        } else {
            path - 2
        };
        for k in first..path - 1 {
            let (camera, s) = settings.path_pose(&scene.camera, k);
            posed.camera = camera;
            previous = Some(self.render_frame(&posed, &s, None, |_| None)?.frame);
        }
        let mut image = self.render_frame(scene, settings, None, progress)?;
        image.previous = previous;
        image.wall_time = wall.elapsed();
        Ok(image)
    }

    /// One frame of a render (`render_reporting`).
    fn render_frame(
        &mut self,
        scene: &Scene,
        settings: &RenderSettings,
        range: Option<Range<u32>>,
        progress: impl Fn(&'static str) -> Option<Progress>,
    ) -> Result<Image> {
        let wall = Instant::now();
        let accumulated = range.as_ref().map_or(settings.spp, |r| r.end);
        let (out, plan, timer, device_timed) = match &mut self.tracer {
            Tracer::Gpu(t) => {
                let progress = progress("frames");
                t.set_progress(progress.map(Arc::new));
                let out = match range {
                    Some(r) => t.render_frames(scene, settings, r),
                    None => t.render(scene, settings),
                };
                t.set_progress(None);
                let mut out = out.map_err(|err| {
                    Error::new(ErrorKind::Device, format!("GPU render failed: {err:#}"))
                })?;

                // Device time from timestamp queries, where the adapter has them and the
                // render's passes fit a query set.
                let (timer, device_timed) = match t.last_gpu_time() {
                    Some(device) => {
                        out.trace_time = device;
                        (t.timer_name(), true)
                    }
                    None => ("wall time around a synchronised submit", false),
                };
                let plan = t
                    .last_plan()
                    .cloned()
                    .unwrap_or_else(|| Plan::new(scene, settings));
                (out, plan, timer, device_timed)
            }
            Tracer::Cpu {
                walks,
                accumulation,
                surface,
                ..
            } => {
                // The CPU's plan is derived the same way, for the record: it needs no
                // shader variant, but the scene's needs are the same.
                let mut plan = Plan::new(scene, settings);
                // A range of the accumulation is, on the CPU, the render of its first
                // frames, summed on from the sums of the frames before it where the call
                // continues an accumulation, both checked by the GPU tracer's rules.
                let ranged;
                let (settings, key) = match &range {
                    Some(r) => {
                        plan.check_frames(settings, r)
                            .map_err(|m| Error::new(ErrorKind::Invalid, m))?;
                        ranged = RenderSettings {
                            spp: r.end,
                            ..settings.clone()
                        };
                        let key = plan
                            .accumulate
                            .then(|| cpu_accumulation_key(scene, settings, &plan));
                        if r.start > 0 {
                            let key = key.as_ref().expect("a range past 0 accumulates");
                            let holds = accumulation
                                .as_ref()
                                .map(|(k, sums)| (k, sums.frames(), Vec::new()));
                            crate::accumulation::check_continuation(holds, key, r)
                                .map_err(|m| Error::new(ErrorKind::Invalid, m))?;
                        }
                        (&ranged, key)
                    }
                    None => (settings, None),
                };
                // Past the checks the render ends the accumulation held, whether it
                // continues it or not, and whether it succeeds or fails.
                let held = accumulation.take();
                let prior = held
                    .as_ref()
                    .filter(|_| range.as_ref().is_some_and(|r| r.start > 0))
                    .map(|(_, sums)| sums);
                let progress = progress("rows");
                let (out, sums) = crate::cpu::render_keeping(
                    scene,
                    settings,
                    progress.as_ref(),
                    &mut self.history,
                    (walks, surface),
                    prior,
                );
                if progress.is_some_and(|p| p.stopped()) {
                    return Err(Error::new(ErrorKind::Interrupted, "render stopped"));
                }
                *accumulation = key.map(|key| (key, sums));
                plan.walk_data = out.walk_data.clone();
                (out, plan, "wall", false)
            }
        };
        // Only a plan that samples something accumulates frames; otherwise one is traced.
        let frames = if plan.accumulate {
            accumulated.max(1)
        } else {
            1
        };
        Ok(Image {
            frame: out.frame,
            stats: out.stats,
            trace_time: out.trace_time,
            setup_time: out.setup_time,
            wall_time: wall.elapsed(),
            timer,
            device_timed,
            frames,
            plan,
            backend: self.label(),
            previous: None,
        })
    }
}

/// What a CPU accumulation was made from: the GPU tracer's key, with the voxels' hash
/// where the GPU tracer has its upload's generation, and the triangle surface's inputs
/// where it has its upload's key.
fn cpu_accumulation_key(scene: &Scene, settings: &RenderSettings, plan: &Plan) -> AccumulationKey {
    let surface = plan
        .surface
        .traces_triangles()
        .then(|| plan.surface.trace_key(scene, scene.grid.content_hash()));
    AccumulationKey::new(scene, settings, plan, surface).with("voxels", scene.grid.content_hash())
}

/// A rendered image and what made it.
#[derive(Clone, Debug)]
pub struct Image {
    /// Linear radiance, row-major from the top-left pixel.
    pub frame: Frame,
    /// Rays and voxel steps, counted by the tracer.
    pub stats: RayStats,
    /// The trace alone: device time from timestamp queries where the GPU has them, else
    /// wall time (`timer` says which).
    pub trace_time: Duration,
    /// Preparation before the trace (walk data, triangle surfaces, cone pyramids).
    pub setup_time: Duration,
    /// The whole call.
    pub wall_time: Duration,
    /// What measured `trace_time`.
    pub timer: &'static str,
    /// Whether `trace_time` is device time from timestamp queries.
    pub device_timed: bool,
    /// Frames accumulated.
    pub frames: u32,
    /// What the tracer ran and what it left out.
    pub plan: Plan,
    /// The session's [`Session::label`].
    pub backend: String,
    /// Under a camera path (`[render] path_frames > 1`), the image of the frame before
    /// this one: what a frame-to-frame measure (flicker on an orbit) compares.
    pub previous: Option<Frame>,
}

impl Image {
    pub fn width(&self) -> u32 {
        self.frame.width
    }

    pub fn height(&self) -> u32 {
        self.frame.height
    }

    /// Linear RGB per pixel, row-major from the top-left.
    pub fn radiance(&self) -> &[[f32; 3]] {
        &self.frame.pixels
    }

    /// What made the image, as JSON: the resolved experiment (overrides applied), the
    /// overrides, every file it read with its content's blake3 hash, the revision
    /// voxlab was built from, the backend and adapter, size, frames, samples, seed,
    /// plan, timings and rays. `voxlab render` stores it with the
    /// image and prints it with `--json`.
    pub fn provenance(
        &self,
        e: &Experiment,
        overrides: &[Override],
        display: DisplayTransform,
        output: Option<&Path>,
    ) -> Result<serde_json::Value> {
        let labels: Vec<String> = overrides.iter().map(|o| o.to_string()).collect();
        // The [scene] table as the file (with the overrides) gives it, so the resolved
        // experiment renders again from its own text.
        let recorded = e.source_record.as_ref().filter(|r| r.overrides == labels);
        let (scene_source, assets) = match (&e.source_path, recorded) {
            // As the files (or the text) were when it was read.
            (_, Some(r)) => (r.scene.clone(), r.inputs.clone()),
            (Some(p), None) => {
                let text = crate::experiment::read_text(p)?;
                let text = crate::experiment::apply_overrides(&text, overrides)?;
                let assets = crate::experiment::write::input_hashes(&text, p);
                (crate::experiment::write::scene_source(&text, p)?, assets)
            }
            (None, _) => (toml::Table::new(), Vec::new()),
        };
        let mut resolved = crate::experiment::to_toml(e, &scene_source)?;
        // No [scene] table: the file renders the seed's scene at its size, which is not
        // what was rendered where the voxels were set in memory.
        let seed_size = glam::UVec3::splat(crate::scene::seed::SEED_SIZE);
        if scene_source.is_empty()
            && crate::scene::seed::seed_grid(seed_size, 1.0, glam::DVec3::ZERO)
                .is_ok_and(|g| g != e.scene.grid)
        {
            resolved = resolved.replacen(
                crate::experiment::write::HEADER,
                crate::experiment::write::IN_MEMORY_HEADER,
                1,
            );
        }
        let s = &self.stats;
        Ok(serde_json::json!({
            "voxlab": env!("CARGO_PKG_VERSION"),
            "revision": crate::revision::revision(),
            "experiment": e.name,
            "source": e.source_path.as_ref().map(|p| p.display().to_string()),
            "assets": assets,
            "overrides": labels,
            "backend": self.backend,
            "width": e.settings.width,
            "height": e.settings.height,
            "spp": e.settings.spp,
            "frames": self.frames,
            "light_samples": e.settings.light_samples,
            "seed": e.settings.seed,
            "pixel_filter": e.settings.pixel_filter.name(),
            "display": display.encoding.name(),
            "exposure": display.exposure,
            "plan": self.plan.to_string(),
            "warnings": self.plan.warnings,
            "trace_ms": self.trace_time.as_secs_f64() * 1e3,
            "wall_ms": self.wall_time.as_secs_f64() * 1e3,
            "rays": {
                "primary": s.primary,
                "secondary": s.secondary,
                "shadow": s.shadow,
                "voxel_steps": s.voxel_steps,
                "untraced": s.untraced,
                "counted": s.total_rays() > 0,
            },
            // The voxels rendered, whatever made them (a file, a generator, an array).
            "grid": e.scene.grid.record(),
            "finite": self.frame.all_finite(),
            "output": output.map(|p| p.display().to_string()),
            "resolved_experiment": resolved,
        }))
    }

    /// Writes the image (`.png`: 8 bits, clamped, `display` applied; `.exr`: linear)
    /// with `provenance` stored in it and beside it (`<path>.json`), all or nothing.
    pub fn save(
        &self,
        path: impl AsRef<Path>,
        provenance: &serde_json::Value,
        display: DisplayTransform,
    ) -> Result<()> {
        DisplayTransform::check_exposure(display.exposure)
            .map_err(|e| Error::new(ErrorKind::Invalid, e))?;
        let text = serde_json::to_string_pretty(provenance)
            .map_err(|e| Error::new(ErrorKind::Other, e.to_string()))?;
        crate::output::write_frame_with_provenance(&self.frame, path, &text, display)?;
        Ok(())
    }
}
