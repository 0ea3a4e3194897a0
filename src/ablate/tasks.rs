//! The sweep as independent tasks, so that one process or many can do them: `voxlab
//! ablate` does them in order in its own process ([`super::run`]); `voxlab.ablate(...,
//! executor="ray")` hands them to Ray workers (python/voxlab/ray.py, docs/ray.md).
//!
//! A [`Schedule`] lists what a sweep renders: its points, and the converged references
//! they are measured against (the experiment's, and one per scene of a key sweep). A
//! [`Task`] is a band of rows of one half of a reference, or one point with all its
//! seeds, warm-ups and timed runs. A [`Worker`] (one tracer kept across tasks, so its
//! pipelines compile once) does a task and returns a [`TaskOutput`]: frames and times,
//! never errors against a reference, so points need not wait for the reference. The
//! [`Driver`] collects the outputs, assembles each reference from its bands in row
//! order (the CPU tracer's pixels do not depend on the band: `cpu::render_region`),
//! measures every point against its reference and writes what a local run writes.
//!
//! Every point's output is kept in the cache directory (`points/<key>.bin`, under a
//! blake3 hash of everything that changes its pixels and of the sweep's seeds and runs),
//! so a sweep that was stopped resumes (`--resume`) from the points already done.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result, anyhow, bail};
use serde::{Deserialize, Serialize};

use super::{
    AblateConfig, AblateOptions, AblateReport, BackendChoice, EXTERNAL_FILES, MODEL_VERSION, Meter,
    OUTPUT_FILES, Point, Reference, ReferenceMeta, Tracers, backend_label, external, point_row,
    reference_halves, reference_key, refuse_to_overwrite_inputs, summarize, write_external,
    write_outputs, write_text,
};
use crate::experiment::Experiment;
use crate::frame::Frame;
use crate::metrics::{Domain, compare};
use crate::output::{read_exr, write_frame};
use crate::render::RenderSettings;
use crate::scene::Scene;

/// A reference the sweep measures against: its scene and its two halves' settings.
#[derive(Clone, Debug)]
pub struct ReferenceScene {
    pub scene: Arc<Scene>,
    pub halves: [RenderSettings; 2],
}

/// What a sweep renders.
#[derive(Clone, Debug)]
pub struct Schedule {
    pub points: Vec<Point>,
    /// `[0]`: the experiment's scene; then one per distinct scene of a key sweep's points.
    pub references: Vec<ReferenceScene>,
    /// The reference each point is measured against.
    pub point_reference: Vec<usize>,
    /// Each point's content key (`point_key`): the name of its kept output.
    pub point_keys: Vec<String>,
    /// A hash of every point's key and every reference's scene and settings: a band
    /// rendered for another sweep (an experiment file changed between the driver and
    /// a worker) is refused by it.
    pub fingerprint: String,
}

impl Schedule {
    pub fn new(e: &Experiment, c: &AblateConfig) -> Self {
        // Without an area light every shadow model gives the hard image: only the
        // baseline and the key sweeps are measured.
        let points = if e.scene.lights.iter().any(|l| l.is_area()) {
            super::points(e, c)
        } else {
            super::baseline_points(e, c)
                .into_iter()
                .chain(super::key_sweep_points(e, c))
                .collect()
        };
        let mut references = vec![ReferenceScene {
            scene: Arc::new(e.scene.clone()),
            halves: reference_halves(e, c),
        }];
        let mut point_reference = Vec::with_capacity(points.len());
        for p in &points {
            let i = match &p.scene {
                None => 0,
                Some(scene) => {
                    let known = references[1..]
                        .iter()
                        .position(|r| *r.scene == **scene)
                        .map(|i| i + 1);
                    known.unwrap_or_else(|| {
                        let pe = Experiment {
                            scene: scene.as_ref().clone(),
                            ..e.clone()
                        };
                        references.push(ReferenceScene {
                            scene: scene.clone(),
                            halves: reference_halves(&pe, c),
                        });
                        references.len() - 1
                    })
                }
            };
            point_reference.push(i);
        }
        let point_keys: Vec<String> = points.iter().map(|p| point_key(e, c, p)).collect();
        let mut h = blake3::Hasher::new();
        for k in &point_keys {
            h.update(k.as_bytes());
        }
        for r in &references {
            h.update(reference_key(&r.scene, &r.halves, "").as_bytes());
        }
        Self {
            points,
            references,
            point_reference,
            point_keys,
            fingerprint: h.finalize().to_hex().to_string(),
        }
    }
}

/// The scene `p` renders: its own or the experiment's, its area lights as points where
/// the curve asks.
pub(super) fn point_scene(e: &Experiment, p: &Point) -> Scene {
    let own = p.scene.as_deref().unwrap_or(&e.scene);
    if p.lights_as_points {
        super::lights_as_points(own)
    } else {
        own.clone()
    }
}

/// Everything that changes a point's images and times: its scene and settings, the
/// sweep's seeds, runs and warm-ups, and the backend asked for.
fn point_key(e: &Experiment, c: &AblateConfig, p: &Point) -> String {
    let scene = point_scene(e, p);
    let what = format!(
        "point backend {} seeds {} runs {} warmup {}",
        c.backend.name(),
        c.seeds,
        c.runs,
        c.warmup
    );
    super::content_key(&what, &scene, &format!("{:?}", p.settings), "")
}

/// One unit of work.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Task {
    /// Rows `rows[0]..rows[1]` of half `half` (0 or 1) of reference `reference`.
    ReferenceTile {
        reference: usize,
        half: usize,
        rows: [u32; 2],
    },
    /// Point `index` of the schedule: every seed, its warm-ups and timed runs.
    Point { index: usize },
}

/// A band of a reference half.
#[derive(Clone, Debug)]
pub struct Tile {
    /// The sweep's [`Schedule::fingerprint`].
    pub sweep: String,
    pub reference: usize,
    pub half: usize,
    pub rows: Range<u32>,
    pub frame: Frame,
    pub seconds: f64,
}

/// One seed of a point: its last render and the times of its timed runs.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SeedRender {
    pub seed: u32,
    /// `gpu` or `cpu`.
    pub backend: String,
    pub fallback: Option<String>,
    /// The registry name of the shadow model the plan used.
    pub shadow_model: String,
    /// The registry name of the reconstruction the plan used (older records: none).
    #[serde(default = "no_reconstruction")]
    pub reconstruction: String,
    /// The plan had cone pyramids (their build is the setup time).
    pub pyramid: bool,
    pub timestamps: bool,
    pub plan: String,
    pub times_ns: Vec<u64>,
    pub setups_ns: Vec<u64>,
    /// Under a camera path, FLIP of the image against the path's frame before it.
    #[serde(default)]
    pub path_flicker: Option<f64>,
    #[serde(skip, default = "empty_frame")]
    pub frame: Frame,
}

fn no_reconstruction() -> String {
    crate::technique::default_reconstruction().name.to_string()
}

fn empty_frame() -> Frame {
    Frame::new(0, 0)
}

/// A point's renders, one per seed, and the adapter that timed them.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PointRenders {
    pub index: usize,
    pub key: String,
    pub adapter: String,
    pub seeds: Vec<SeedRender>,
}

/// What a task gives back.
#[derive(Clone, Debug)]
pub enum TaskOutput {
    Tile(Tile),
    Point(PointRenders),
}

/// The header of an encoded output; the frames follow it.
#[derive(Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
enum Header {
    Tile {
        sweep: String,
        reference: usize,
        half: usize,
        rows: [u32; 2],
        seconds: f64,
        size: [u32; 2],
    },
    Point {
        renders: PointRenders,
        sizes: Vec<[u32; 2]>,
    },
}

const MAGIC: &[u8] = b"voxlab ablate task output 1\n";

/// The most pixels one encoded frame may hold (a 16k x 16k image): a decoder that
/// trusted a corrupt header would allocate without bound.
const MAX_FRAME_PIXELS: u64 = 1 << 28;

impl TaskOutput {
    /// Bytes to send to the driver or keep on disk: a magic line, the header's length
    /// (u64 LE) and JSON, then each frame's pixels as f32 LE (exactly, so a frame that
    /// travels is the frame that was rendered).
    pub fn encode(&self) -> Vec<u8> {
        let (header, frames): (Header, Vec<&Frame>) = match self {
            Self::Tile(t) => (
                Header::Tile {
                    sweep: t.sweep.clone(),
                    reference: t.reference,
                    half: t.half,
                    rows: [t.rows.start, t.rows.end],
                    seconds: t.seconds,
                    size: [t.frame.width, t.frame.height],
                },
                vec![&t.frame],
            ),
            Self::Point(p) => (
                Header::Point {
                    renders: p.clone_without_frames(),
                    sizes: p
                        .seeds
                        .iter()
                        .map(|s| [s.frame.width, s.frame.height])
                        .collect(),
                },
                p.seeds.iter().map(|s| &s.frame).collect(),
            ),
        };
        let json = serde_json::to_vec(&header).expect("a header serialises");
        let mut out = Vec::with_capacity(
            MAGIC.len()
                + 8
                + json.len()
                + frames.iter().map(|f| f.pixels.len() * 12).sum::<usize>(),
        );
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&(json.len() as u64).to_le_bytes());
        out.extend_from_slice(&json);
        for f in frames {
            for p in &f.pixels {
                for v in p {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        out
    }

    /// The output `encode` wrote; an error (never a panic or an unbounded allocation)
    /// for anything else.
    pub fn decode(bytes: &[u8]) -> Result<Self> {
        let rest = bytes
            .strip_prefix(MAGIC)
            .ok_or_else(|| anyhow!("not a voxlab ablate task output (wrong magic line)"))?;
        if rest.len() < 8 {
            bail!("task output truncated in its header length");
        }
        let (len, rest) = rest.split_at(8);
        let len = u64::from_le_bytes(len.try_into().expect("8 bytes"));
        if len > rest.len() as u64 {
            bail!(
                "task output truncated: header of {len} bytes, {} left",
                rest.len()
            );
        }
        let (json, mut pixels) = rest.split_at(len as usize);
        let header: Header =
            serde_json::from_slice(json).context("task output header is not valid")?;
        let mut frame = |[w, h]: [u32; 2]| -> Result<Frame> {
            let n = u64::from(w) * u64::from(h);
            if n > MAX_FRAME_PIXELS || n * 12 > pixels.len() as u64 {
                bail!(
                    "task output truncated: a {w}x{h} frame, {} bytes left",
                    pixels.len()
                );
            }
            let (mine, more) = pixels.split_at(n as usize * 12);
            pixels = more;
            let mut f = Frame::new(w, h);
            for (p, c) in f.pixels.iter_mut().zip(mine.chunks_exact(12)) {
                for (k, v) in c.chunks_exact(4).enumerate() {
                    p[k] = f32::from_le_bytes(v.try_into().expect("4 bytes"));
                }
            }
            Ok(f)
        };
        let out = match header {
            Header::Tile {
                sweep,
                reference,
                half,
                rows,
                seconds,
                size,
            } => Self::Tile(Tile {
                sweep,
                reference,
                half,
                rows: rows[0]..rows[1],
                frame: frame(size)?,
                seconds,
            }),
            Header::Point { mut renders, sizes } => {
                if sizes.len() != renders.seeds.len() {
                    bail!(
                        "task output: {} frames for {} seeds",
                        sizes.len(),
                        renders.seeds.len()
                    );
                }
                for (s, size) in renders.seeds.iter_mut().zip(sizes) {
                    s.frame = frame(size)?;
                }
                Self::Point(renders)
            }
        };
        if !pixels.is_empty() {
            bail!("task output has {} bytes after its frames", pixels.len());
        }
        Ok(out)
    }
}

impl PointRenders {
    fn clone_without_frames(&self) -> Self {
        Self {
            index: self.index,
            key: self.key.clone(),
            adapter: self.adapter.clone(),
            seeds: self
                .seeds
                .iter()
                .map(|s| SeedRender {
                    frame: Frame::new(0, 0),
                    ..s.clone()
                })
                .collect(),
        }
    }
}

/// Does tasks with one tracer kept open: a local run's, or one Ray worker's.
pub struct Worker {
    tracers: Tracers,
}

impl Worker {
    /// The tracers `c` asks for (the GPU unless both backends are `cpu`).
    pub fn new(c: &AblateConfig) -> Result<Self> {
        Ok(Self {
            tracers: Tracers::new(c)?,
        })
    }

    /// A worker without a GPU, for the CPU reference's bands (a cluster's CPU tasks).
    pub fn cpu() -> Self {
        Self {
            tracers: Tracers::cpu_only("a CPU worker (reference bands)"),
        }
    }

    pub(super) fn tracers_mut(&mut self) -> &mut Tracers {
        &mut self.tracers
    }

    /// The adapter, as the rows record it.
    pub fn adapter(&self) -> String {
        self.tracers.adapter()
    }

    /// The reference's renderer as its cache key names it (`cpu f64`, or `gpu` and the
    /// adapter).
    pub fn reference_label(&self, c: &AblateConfig) -> String {
        backend_label(&self.tracers, c.reference_backend)
    }

    /// Does `task` of `schedule` (made from the same `e` and `c`).
    pub fn run(
        &mut self,
        e: &Experiment,
        c: &AblateConfig,
        schedule: &Schedule,
        task: &Task,
    ) -> Result<TaskOutput> {
        self.run_metered(e, c, schedule, task, &Meter::silent())
    }

    pub(super) fn run_metered(
        &mut self,
        e: &Experiment,
        c: &AblateConfig,
        schedule: &Schedule,
        task: &Task,
        progress: &Meter,
    ) -> Result<TaskOutput> {
        match *task {
            Task::ReferenceTile {
                reference,
                half,
                rows,
            } => {
                let r = schedule
                    .references
                    .get(reference)
                    .ok_or_else(|| anyhow!("no reference {reference} in this sweep"))?;
                let s = r
                    .halves
                    .get(half)
                    .ok_or_else(|| anyhow!("a reference has halves 0 and 1, not {half}"))?;
                let h = e.settings.height;
                if rows[0] >= rows[1] || rows[1] > h {
                    bail!("rows {}..{} outside the image's 0..{h}", rows[0], rows[1]);
                }
                let (frame, time) = if (rows[0], rows[1]) == (0, h) {
                    let out = self.tracers.render(c.reference_backend, &r.scene, s)?;
                    (out.frame, out.time)
                } else if c.reference_backend == BackendChoice::Cpu {
                    let out = crate::cpu::render_region(&r.scene, s, 0..s.width, rows[0]..rows[1]);
                    (out.frame, out.trace_time)
                } else {
                    bail!("only the CPU reference renders in bands of rows");
                };
                progress.advance(
                    progress.reference_cost(s.spp) * u64::from(rows[1] - rows[0]) / u64::from(h),
                );
                Ok(TaskOutput::Tile(Tile {
                    sweep: schedule.fingerprint.clone(),
                    reference,
                    half,
                    rows: rows[0]..rows[1],
                    frame,
                    seconds: time.as_secs_f64(),
                }))
            }
            Task::Point { index } => {
                let p = schedule
                    .points
                    .get(index)
                    .ok_or_else(|| anyhow!("no point {index} in this sweep"))?;
                let scene = point_scene(e, p);
                let seeds = self.measure(c, p, &scene, progress)?;
                // What rendered it: the GPU's adapter, or the CPU reference and the
                // processor it ran on (a worker's thread count shapes its times).
                let adapter = if seeds.iter().all(|s| s.backend == "gpu") {
                    self.adapter()
                } else {
                    format!(
                        "{} on {}",
                        crate::cpu::backend_summary(),
                        crate::cpu::host_summary()
                    )
                };
                Ok(TaskOutput::Point(PointRenders {
                    index,
                    key: schedule.point_keys[index].clone(),
                    adapter,
                    seeds,
                }))
            }
        }
    }

    /// `point` rendered with each of `c.seeds` seeds: warm-ups before the first seed
    /// only (later seeds reuse its pipelines), then `c.runs` timed renders per seed.
    fn measure(
        &mut self,
        c: &AblateConfig,
        point: &Point,
        scene: &Scene,
        progress: &Meter,
    ) -> Result<Vec<SeedRender>> {
        progress.working_on(&point.label());
        let mut choice = c.backend;
        let mut out = Vec::new();
        for k in 0..c.seeds {
            let s = RenderSettings {
                seed: point.settings.seed.wrapping_add(k),
                ..point.settings.clone()
            };
            let mut times = Vec::new();
            let mut setups = Vec::new();
            let mut last = None;
            let warmup = if k == 0 { c.warmup } else { 0 };
            for i in 0..(warmup + c.runs) {
                let r = self.tracers.render(choice, scene, &s)?;
                let setup = self.tracers.setup_time(&r, scene, &s)?;
                // The first render settles the backend, so later runs do not retry the GPU.
                if choice == BackendChoice::Auto {
                    choice = if r.backend == "gpu" {
                        BackendChoice::Gpu
                    } else {
                        BackendChoice::Cpu
                    };
                }
                if i >= warmup {
                    times.push(r.time);
                    setups.push(setup);
                }
                progress.advance(progress.point_cost(&point.model, s.spp));
                progress.check()?;
                last = Some(r);
            }
            let r = last.expect("runs >= 1");
            let ns = |d: &[Duration]| d.iter().map(|t| t.as_nanos() as u64).collect();
            out.push(SeedRender {
                seed: s.seed,
                backend: r.backend.to_string(),
                fallback: r.fallback,
                shadow_model: r.plan.shadow_model.name.to_string(),
                reconstruction: r.plan.reconstruction.name.to_string(),
                pyramid: r.plan.pyramid.is_some(),
                timestamps: r.timestamps,
                plan: r.plan.to_string(),
                times_ns: ns(&times),
                setups_ns: ns(&setups),
                path_flicker: r.path_flicker,
                frame: r.frame,
            });
        }
        Ok(out)
    }
}

/// A reference still being rendered: its bands so far.
#[derive(Default)]
struct PendingReference {
    key: String,
    label: String,
    exr: PathBuf,
    meta_path: PathBuf,
    bands: [Vec<(Range<u32>, Frame)>; 2],
    seconds: f64,
}

enum ReferenceSlot {
    Done(Reference),
    Pending(Box<PendingReference>),
}

/// Collects a sweep's task outputs and writes what a local run writes.
pub struct Driver {
    e: Experiment,
    c: AblateConfig,
    source: Option<String>,
    out: PathBuf,
    cache_dir: PathBuf,
    pub schedule: Schedule,
    references: Vec<ReferenceSlot>,
    renders: Vec<Option<PointRenders>>,
    /// Points whose output came from an earlier run (`resume`).
    pub resumed: usize,
    external: Option<external::External>,
}

impl Driver {
    /// Checks the sweep before anything renders or a tracer opens: an area light or a
    /// key sweep; no output over an input; the external reference. Returns that
    /// reference, loaded.
    pub fn check(
        e: &Experiment,
        c: &AblateConfig,
        source: Option<&str>,
        opts: &AblateOptions,
    ) -> Result<Option<external::External>> {
        crate::output::check_directory_output(
            opts.out_option,
            &opts.out_dir,
            "ablate writes a directory (ablation.csv, plot.png, table.md, images/ and \
             the rest)",
        )
        .map_err(anyhow::Error::msg)?;
        let has_area = e.scene.lights.iter().any(|l| l.is_area());
        if !has_area && c.sweeps.is_empty() {
            bail!(
                "{}: the shadow models' curves need an area light (type rect, disk or sphere): \
                 the reference is stochastic area lighting. Without one, give [ablate] sweep = \
                 {{ \"key\" = [values] }} to measure other knobs against the converged image",
                e.name
            );
        }
        let out = &opts.out_dir;
        refuse_to_overwrite_inputs(e, source, opts, &cache_dir(opts))?;
        let Some(spec) = &c.external else {
            return Ok(None);
        };
        let x = external::load(spec, e.settings.width, e.settings.height)?;
        let outputs: Vec<PathBuf> = OUTPUT_FILES
            .iter()
            .chain(EXTERNAL_FILES)
            .map(|f| out.join(f))
            .collect();
        if let Some((o, _)) =
            crate::experiment::write::overwrites(&outputs, std::slice::from_ref(&x.spec.path))
        {
            bail!(
                "{}: ablate would write {}, which is the external reference \
                 (ablate.reference); choose another output directory",
                crate::output::given(opts.out_option, out),
                o.display()
            );
        }
        Ok(Some(x))
    }

    /// [`Driver::check`]s the sweep, creates the output and cache directories, and
    /// finds the references already cached (under keys that name `reference_label`, the
    /// reference's renderer) and, with `opts.resume`, the points already done.
    pub fn new(
        e: &Experiment,
        c: &AblateConfig,
        source: Option<&str>,
        opts: &AblateOptions,
        reference_label: &str,
    ) -> Result<Self> {
        let external = Self::check(e, c, source, opts)?;
        Self::checked(e, c, source, opts, reference_label, external)
    }

    /// [`Driver::new`] for a sweep [`Driver::check`] passed, with the external reference
    /// it loaded (a local run checks before it opens a tracer).
    pub fn checked(
        e: &Experiment,
        c: &AblateConfig,
        source: Option<&str>,
        opts: &AblateOptions,
        reference_label: &str,
        external: Option<external::External>,
    ) -> Result<Self> {
        let out = opts.out_dir.clone();
        let cache_dir = cache_dir(opts);
        std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
        std::fs::create_dir_all(&cache_dir)
            .with_context(|| format!("creating {}", cache_dir.display()))?;

        let schedule = Schedule::new(e, c);
        let references = schedule
            .references
            .iter()
            .map(|r| cached_reference(e, c, r, reference_label, &cache_dir))
            .collect();
        let mut renders: Vec<Option<PointRenders>> = vec![None; schedule.points.len()];
        let mut resumed = 0;
        if opts.resume {
            for (i, key) in schedule.point_keys.iter().enumerate() {
                let path = point_path(&cache_dir, key);
                let Ok(bytes) = std::fs::read(&path) else {
                    continue;
                };
                // A damaged or foreign file is rendered again, and said so. The key
                // names what a point renders, not where the schedule puts it: points
                // of equal settings (the baseline and the hard min-kt point) share a
                // file, and a point whose place moved (a list shortened) is still done.
                match TaskOutput::decode(&bytes) {
                    Ok(TaskOutput::Point(p)) if p.key == *key => {
                        renders[i] = Some(PointRenders { index: i, ..p });
                        resumed += 1;
                    }
                    Ok(_) => eprintln!(
                        "ablate: {} is not point {i}'s output; rendering it again",
                        path.display()
                    ),
                    Err(err) => eprintln!(
                        "ablate: {}: {err:#}; rendering point {i} again",
                        path.display()
                    ),
                }
            }
        }
        Ok(Self {
            e: e.clone(),
            c: c.clone(),
            source: source.map(str::to_string),
            out,
            cache_dir,
            schedule,
            references,
            renders,
            resumed,
            external,
        })
    }

    /// The tasks still to do: each reference not cached, each half in `bands` bands of
    /// rows (one band on the GPU, which renders whole images), then every point not done.
    pub fn tasks(&self, bands: u32) -> Vec<Task> {
        let h = self.e.settings.height;
        let bands = if self.c.reference_backend == BackendChoice::Cpu {
            bands.clamp(1, h.max(1))
        } else {
            1
        };
        let mut out = Vec::new();
        for (reference, slot) in self.references.iter().enumerate() {
            if let ReferenceSlot::Pending(_) = slot {
                for half in 0..2 {
                    for b in 0..bands {
                        let rows = [b * h / bands, (b + 1) * h / bands];
                        if rows[0] < rows[1] {
                            out.push(Task::ReferenceTile {
                                reference,
                                half,
                                rows,
                            });
                        }
                    }
                }
            }
        }
        out.extend(
            (0..self.renders.len())
                .filter(|&i| self.renders[i].is_none())
                .map(|index| Task::Point { index }),
        );
        out
    }

    /// The reference `i`, once it is complete.
    pub fn reference(&self, i: usize) -> Option<&Reference> {
        match self.references.get(i)? {
            ReferenceSlot::Done(r) => Some(r),
            ReferenceSlot::Pending(_) => None,
        }
    }

    /// Takes a task's output: a band of a reference (the reference is assembled and
    /// cached when its last band arrives), or a point (kept in the cache for `resume`).
    pub fn put(&mut self, output: TaskOutput) -> Result<()> {
        match output {
            TaskOutput::Tile(t) => self.put_tile(t),
            TaskOutput::Point(p) => {
                let i = p.index;
                let Some(key) = self.schedule.point_keys.get(i) else {
                    bail!("no point {i} in this sweep");
                };
                if p.key != *key {
                    bail!(
                        "point {i}'s output was made for another sweep (key {}, expected {key})",
                        p.key
                    );
                }
                if p.seeds.len() != self.c.seeds as usize {
                    bail!(
                        "point {i}: {} seeds rendered, {} asked",
                        p.seeds.len(),
                        self.c.seeds
                    );
                }
                let (w, h) = (self.e.settings.width, self.e.settings.height);
                if p.seeds
                    .iter()
                    .any(|s| (s.frame.width, s.frame.height) != (w, h))
                {
                    bail!("point {i}: an image is not {w}x{h}");
                }
                let path = point_path(&self.cache_dir, key);
                crate::output::write_file(&path, &TaskOutput::Point(p.clone()).encode())
                    .with_context(|| format!("keeping point {i} in {}", path.display()))?;
                self.renders[i] = Some(p);
                Ok(())
            }
        }
    }

    fn put_tile(&mut self, t: Tile) -> Result<()> {
        let (w, h) = (self.e.settings.width, self.e.settings.height);
        if t.sweep != self.schedule.fingerprint {
            bail!(
                "a band of reference {} was made for another sweep (the experiment changed \
                 between the driver and a worker?)",
                t.reference
            );
        }
        let Some(ReferenceSlot::Pending(p)) = self.references.get_mut(t.reference) else {
            bail!("reference {} is not waiting for bands", t.reference);
        };
        if t.half > 1 || t.rows.start >= t.rows.end || t.rows.end > h {
            bail!(
                "band {:?} of half {} is outside the reference",
                t.rows,
                t.half
            );
        }
        if (t.frame.width, t.frame.height) != (w, t.rows.end - t.rows.start) {
            bail!(
                "band {:?} is {}x{}, not {w} wide and its rows high",
                t.rows,
                t.frame.width,
                t.frame.height
            );
        }
        let bands = &mut p.bands[t.half];
        if bands
            .iter()
            .any(|(r, _)| r.start < t.rows.end && t.rows.start < r.end)
        {
            bail!("band {:?} of half {} arrived twice", t.rows, t.half);
        }
        bands.push((t.rows, t.frame));
        p.seconds += t.seconds;
        let covered =
            |b: &Vec<(Range<u32>, Frame)>| b.iter().map(|(r, _)| r.end - r.start).sum::<u32>() == h;
        if p.bands.iter().all(covered) {
            let done = std::mem::take(&mut **p);
            let halves = &self.schedule.references[t.reference].halves;
            let r = finish_reference(done, halves, w, h, self.c.reference_spp)?;
            self.references[t.reference] = ReferenceSlot::Done(r);
        }
        Ok(())
    }

    /// Measures every point against its reference and writes the outputs; an error
    /// naming what is missing when a task's output has not arrived.
    pub fn finish(self, adapter: &str) -> Result<AblateReport> {
        let Self {
            e,
            c,
            source,
            out,
            schedule,
            references,
            renders,
            mut external,
            ..
        } = self;
        let references: Vec<Reference> = references
            .into_iter()
            .enumerate()
            .map(|(i, r)| match r {
                ReferenceSlot::Done(r) => Ok(r),
                ReferenceSlot::Pending(_) => Err(anyhow!("reference {i} has bands missing")),
            })
            .collect::<Result<_>>()?;
        if let Some(i) = renders.iter().position(Option::is_none) {
            bail!(
                "point {i} ({}) was not rendered",
                schedule.points[i].label()
            );
        }
        let reference = references[0].clone();
        if let Some(x) = &mut external {
            x.measure(&reference);
            // Printed whatever the progress mode: it is a finding, not progress.
            eprintln!("reference bias: {}", x.bias_line(&reference));
        }
        let mut rows = Vec::new();
        for (i, (p, renders)) in schedule.points.iter().zip(renders).enumerate() {
            let renders = renders.expect("checked above");
            let ri = schedule.point_reference[i];
            let against = &references[ri];
            let own = (ri > 0).then_some(against.noise_rmse);
            let scene = point_scene(&e, p);
            // The previous seed's image, for the flicker of the next.
            let mut previous: Option<Frame> = None;
            for (k, r) in renders.seeds.into_iter().enumerate() {
                let s = RenderSettings {
                    seed: r.seed,
                    ..p.settings.clone()
                };
                let r_path_flicker = r.path_flicker;
                let mut row = point_row(p, &scene, &s, r, &against.frame, against.noise_rmse)?;
                row.seed_index = k as u32;
                row.adapter = renders.adapter.clone();
                row.own_reference = own;
                if let (Some(x), None) = (&external, own) {
                    row.external = Some(external::errors(x, &row.frame));
                }
                let path_flicker = r_path_flicker;
                row.flicker = path_flicker.or_else(|| {
                    previous
                        .as_ref()
                        .map(|prev| crate::metrics::flip(prev, &row.frame).0)
                });
                previous = Some(row.frame.clone());
                // Only the first seed's image is kept and written: the others are measured.
                if row.seed_index > 0 {
                    row.image.clear();
                    row.frame = Frame::new(0, 0);
                }
                rows.push(row);
            }
        }

        let git_revision = crate::revision::revision().to_string();
        let mut files = Vec::new();
        let summaries = summarize(&rows);
        let external = external.map(|x| {
            let rows = external::rows(&rows);
            (x, rows)
        });
        write_outputs(
            &e,
            &c,
            source.as_deref(),
            &reference,
            &rows,
            &summaries,
            adapter,
            &git_revision,
            &out,
            &mut files,
        )?;
        if let Some((x, ext_rows)) = &external {
            write_external(&e, &reference, x, ext_rows, &out, &mut files)?;
        }
        let table = std::fs::read_to_string(out.join("table.md"))?;
        Ok(AblateReport {
            reference,
            rows,
            summaries,
            adapter: adapter.to_string(),
            git_revision,
            files,
            table,
            external,
        })
    }
}

/// Where references and points are kept: `--cache`, else `<out>/cache`.
fn cache_dir(opts: &AblateOptions) -> PathBuf {
    opts.cache_dir
        .clone()
        .unwrap_or_else(|| opts.out_dir.join("cache"))
}

fn point_path(cache_dir: &Path, key: &str) -> PathBuf {
    cache_dir
        .join("points")
        .join(format!("point-{}.bin", &key[..32]))
}

/// The reference `r` from the cache when it is there, else a slot waiting for its bands.
fn cached_reference(
    e: &Experiment,
    c: &AblateConfig,
    r: &ReferenceScene,
    label: &str,
    cache_dir: &Path,
) -> ReferenceSlot {
    let key = reference_key(&r.scene, &r.halves, label);
    let short = &key[..16];
    let exr = cache_dir.join(format!("reference-{short}.exr"));
    let meta_path = cache_dir.join(format!("reference-{short}.toml"));
    let (w, h) = (e.settings.width, e.settings.height);
    let cached = (|| -> Option<(Frame, ReferenceMeta)> {
        let meta: ReferenceMeta =
            toml::from_str(&std::fs::read_to_string(&meta_path).ok()?).ok()?;
        let frame = read_exr(&exr).ok()?;
        (meta.key == key && (frame.width, frame.height) == (w, h)).then_some((frame, meta))
    })();
    match cached {
        Some((frame, meta)) => ReferenceSlot::Done(Reference {
            frame,
            key,
            path: exr,
            reused: true,
            spp: c.reference_spp,
            backend: meta.backend,
            noise_rmse: meta.noise_rmse,
            flip_floor: meta.flip_floor,
            seconds: meta.seconds,
        }),
        None => ReferenceSlot::Pending(Box::new(PendingReference {
            key,
            label: label.to_string(),
            exr,
            meta_path,
            bands: [Vec::new(), Vec::new()],
            seconds: 0.0,
        })),
    }
}

/// The reference from its two halves' bands (placed in row order): their mean weighted
/// by each half's spp, half the RMSE between them as its noise; cached.
fn finish_reference(
    p: PendingReference,
    halves: &[RenderSettings; 2],
    w: u32,
    h: u32,
    spp: u32,
) -> Result<Reference> {
    let mut frames = Vec::new();
    for mut bands in p.bands {
        bands.sort_by_key(|(r, _)| r.start);
        let mut f = Frame::new(w, h);
        for (rows, band) in bands {
            let at = (rows.start * w) as usize;
            f.pixels[at..at + band.pixels.len()].copy_from_slice(&band.pixels);
        }
        frames.push(f);
    }
    let noise_rmse = compare(&frames[0], &frames[1], Domain::Linear, 0.0)
        .expect("halves have one size")
        .rmse
        / 2.0;
    // Weighted by each half's spp so an odd reference_spp is still the plain mean.
    let (na, nb) = (halves[0].spp as f32, halves[1].spp as f32);
    let mut frame = Frame::new(w, h);
    for ((o, a), b) in frame
        .pixels
        .iter_mut()
        .zip(&frames[0].pixels)
        .zip(&frames[1].pixels)
    {
        for k in 0..3 {
            o[k] = (a[k] * na + b[k] * nb) / (na + nb);
        }
    }
    let flip_floor = frames
        .iter()
        .map(|half| crate::metrics::flip_mean(&frame, half))
        .sum::<f64>()
        / 2.0;
    write_frame(&frame, &p.exr)?;
    let meta = ReferenceMeta {
        key: p.key.clone(),
        spp,
        backend: p.label.clone(),
        noise_rmse,
        flip_floor,
        seconds: p.seconds,
        model_version: MODEL_VERSION,
    };
    write_text(&p.meta_path, &toml::to_string(&meta)?)?;
    Ok(Reference {
        frame,
        key: p.key,
        path: p.exr,
        reused: false,
        spp,
        backend: p.label,
        noise_rmse,
        flip_floor,
        seconds: p.seconds,
    })
}
