//! The baseline benchmark: the seed scene at several grid sizes, on the GPU and the CPU
//! reference in one run, so their ratio is measured under the same machine load.
//!
//! Times are medians over several frames after a warm-up frame, the walks of a scene
//! timed in turn, frame by frame, so that load on a shared machine falls on all of
//! them alike. Ray and voxel-step counts are counted by the tracers (a separate
//! counted frame on the GPU, so counting does not slow the timed frames), not
//! estimated.
//!
//! Unlike the other applications, which render through a [`crate::Session`], the
//! benchmarks drive the tracers themselves: they force a walk on a scene whose plan
//! would choose another (`GpuTracer::render_plan`), count rays in a frame of their
//! own, read the device's memory, and keep each walk's prepared data out of the CPU's
//! timed frames, which are the tracers' own controls and not the facade's.

pub mod cutoff;
pub mod lanes;
pub mod reconstruction;

use std::time::{Duration, Instant};

use anyhow::Result;

use crate::frame::RayStats;
use crate::gpu::GpuTracer;
use crate::render::{RenderSettings, Rules, Surface, Traversal};
use crate::scene::{Scene, seed_scene};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub sizes: Vec<u32>,
    pub settings: RenderSettings,
    /// Timed frames per backend and size (after one warm-up frame).
    pub gpu_runs: usize,
    pub cpu_runs: usize,
    /// Skip the CPU reference (e.g. on a fast GPU where only GPU figures are wanted).
    pub cpu: bool,
    /// The walks compared at each size (`render.traversal`).
    pub traversals: Vec<Traversal>,
    /// The ray-tree rules the seed scene is measured under at each size: voxlab's
    /// default model, and the seed's own (the like-for-like comparison with the seed's
    /// tracer).
    pub rules: Vec<Rules>,
    /// Experiments benchmarked after the seed scene, each with its own scene, camera,
    /// lights, materials and render settings (rules, depth limits, techniques), at the
    /// options' image size and one sample per pixel: a row's time is one frame's.
    pub experiments: Vec<crate::experiment::Experiment>,
    /// Generated scenes benchmarked after the experiments (a large mesh, say).
    pub scenes: Vec<(String, Scene)>,
    /// The surfaces compared on each scene (`render.surface`); a surface a scene cannot
    /// have (a mesh without one) is left out of its rows.
    pub surfaces: Vec<Surface>,
}

impl Default for BenchOptions {
    /// The benchmark: seed scene, 512x512, depth 4/4, grids 16, 64 and 256.
    fn default() -> Self {
        Self {
            sizes: vec![16, 64, 256],
            settings: RenderSettings::default(),
            gpu_runs: 5,
            cpu_runs: 3,
            cpu: true,
            traversals: Traversal::walks(),
            rules: vec![Rules::Consistent, Rules::Seed],
            experiments: Vec::new(),
            scenes: Vec::new(),
            surfaces: vec![Surface::default()],
        }
    }
}

/// One backend at one grid size.
#[derive(Clone, Debug)]
pub struct BenchRow {
    /// "seed N^3", or an experiment's name and grid.
    pub scene: String,
    pub grid: u32,
    pub backend: &'static str,
    /// The traversal's name (the plan's choice under "auto").
    pub traversal: &'static str,
    /// What rays hit: the surface's name.
    pub surface: &'static str,
    /// The median of `times`.
    pub median: Duration,
    /// The timed frames in the order of their rounds. The walks of one scene, surface
    /// and backend are timed a frame of each in turn, so round `r` of two such rows ran
    /// side by side, and their ratio round by round measures the difference under the
    /// same load ([`Ratio`]).
    pub times: Vec<Duration>,
    /// The median wall time of a whole call of a warm tracer, as a display loop makes
    /// it: on the GPU the plan, the checks of what the device holds, the submit and the
    /// image's readback around the device's time, over three calls back to back; on the
    /// CPU reference its prepared render, `median` itself. What the host adds per frame
    /// shows here and not in `median` (a plan that recounted a 1024^3 grid's materials
    /// made each call 310 ms for 5 ms of device time).
    pub wall: Duration,
    pub stats: RayStats,
    /// Bytes the geometry occupies per voxel of the grid's box: the R8Uint texture's 1,
    /// or the sparse tree's bytes over the voxels.
    pub bytes_per_voxel: f64,
    /// Time to build the walk's structure from the grid (the sparse tree; 0 for the
    /// dense grid, which is uploaded as it is).
    pub build: Duration,
    /// What measured `median`.
    pub timer: &'static str,
    /// GPU rows: the walks' voxel steps per loop iteration the timed frames ran with
    /// (`Plan::dda_unroll`: the software driver's retry after its loop limit raises it).
    pub dda_unroll: Option<u32>,
}

impl BenchRow {
    pub fn ms(&self) -> f64 {
        self.median.as_secs_f64() * 1e3
    }

    /// The fastest and slowest timed frames in ms, `lo to hi` (one frame: its time).
    pub fn range_text(&self) -> String {
        let ms = |d: Option<&Duration>| d.map_or(self.ms(), |d| d.as_secs_f64() * 1e3);
        match (self.times.iter().min(), self.times.iter().max()) {
            (lo, hi) if lo == hi => format!("{:.1}", ms(lo)),
            (lo, hi) => format!("{:.1} to {:.1}", ms(lo), ms(hi)),
        }
    }
    pub fn mrays_per_s(&self) -> f64 {
        self.stats.total_rays() as f64 / self.median.as_secs_f64() / 1e6
    }
    pub fn msteps_per_s(&self) -> f64 {
        self.stats.voxel_steps as f64 / self.median.as_secs_f64() / 1e6
    }

    /// The row as one JSON object (`voxlab bench --json`): the measured figures and the
    /// counts they come from.
    pub fn json(&self) -> serde_json::Value {
        let s = &self.stats;
        let rays = s.total_rays().max(1) as f64;
        serde_json::json!({
            "scene": self.scene,
            "grid": self.grid,
            "backend": self.backend,
            "traversal": self.traversal,
            "surface": self.surface,
            "triangle_tests": s.triangle_tests,
            "build_ms": self.build.as_secs_f64() * 1e3,
            "ms_per_frame": self.ms(),
            "ms_per_frame_runs": self.times.iter().map(|t| t.as_secs_f64() * 1e3).collect::<Vec<_>>(),
            "wall_ms_per_call": self.wall.as_secs_f64() * 1e3,
            "mrays_per_s": self.mrays_per_s(),
            "msteps_per_s": self.msteps_per_s(),
            "rays": {
                "primary": s.primary,
                "secondary": s.secondary,
                "shadow": s.shadow,
                "untraced": s.untraced,
            },
            "voxel_steps": s.voxel_steps,
            "steps_per_ray": s.voxel_steps as f64 / rays,
            "bytes_per_voxel": self.bytes_per_voxel,
            "timer": self.timer,
            "dda_unroll": self.dda_unroll,
        })
    }
}

fn median(mut times: Vec<Duration>) -> Duration {
    times.sort();
    times[times.len() / 2]
}

/// The ratio of two rows' frame times (`num` over `den`) with the range the runs give
/// it: round by round where the two rows were timed in the same rounds (one scene,
/// surface and backend: their frames alternate), else the widest it could be, from the
/// slowest and the fastest frame of each. A ratio whose range holds 1 is no difference
/// the runs can tell from their noise, and says so.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ratio {
    /// The ratio of the medians.
    pub median: f64,
    pub lo: f64,
    pub hi: f64,
    /// Whether `lo` and `hi` are of the ratios round by round.
    pub paired: bool,
}

impl Ratio {
    /// The ratio of two rows' frame times, paired where they were timed in the same
    /// rounds (one backend, scene and surface).
    pub fn of(num: &BenchRow, den: &BenchRow) -> Self {
        let times = |r: &BenchRow| {
            if r.times.is_empty() {
                vec![r.median]
            } else {
                r.times.clone()
            }
        };
        let paired =
            num.backend == den.backend && num.scene == den.scene && num.surface == den.surface;
        Self::of_times(&times(num), &times(den), paired)
    }

    /// The ratio of the medians of `num` and `den` with its range: of the ratios round
    /// by round where `paired` (the two timed frame by frame in turn, as many of each),
    /// else from the slowest and fastest frames.
    pub fn of_times(num: &[Duration], den: &[Duration], paired: bool) -> Self {
        let secs = |v: &[Duration]| -> Vec<f64> { v.iter().map(Duration::as_secs_f64).collect() };
        let (a, b) = (secs(num), secs(den));
        let median = median(num.to_vec()).as_secs_f64() / median(den.to_vec()).as_secs_f64();
        let paired = paired && a.len() == b.len() && a.len() > 1;
        let (lo, hi) = if paired {
            a.iter()
                .zip(&b)
                .map(|(x, y)| x / y)
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
                    (lo.min(r), hi.max(r))
                })
        } else {
            let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
            let max = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            (min(&a) / max(&b), max(&a) / min(&b))
        };
        Self {
            median,
            lo,
            hi,
            paired,
        }
    }

    /// The record of `--json`: the ratio of the medians, its range, and how the range
    /// was taken.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "median": self.median,
            "lo": self.lo,
            "hi": self.hi,
            "paired": self.paired,
        })
    }

    /// For a table's cell: `1.23 (1.10 to 1.31)`, and `, noise` where the range holds 1.
    pub fn cell(&self) -> String {
        format!(
            "{:.2} ({:.2} to {:.2}{})",
            self.median,
            self.lo,
            self.hi,
            if self.within_noise() { ", noise" } else { "" }
        )
    }

    /// Whether the runs cannot tell the two rows apart: the range holds 1.
    pub fn within_noise(&self) -> bool {
        self.lo <= 1.0 && 1.0 <= self.hi
    }
}

impl std::fmt::Display for Ratio {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.2}x ({:.2} to {:.2} {}{})",
            self.median,
            self.lo,
            self.hi,
            if self.paired {
                "round by round"
            } else {
                "from the runs' slowest and fastest frames"
            },
            if self.within_noise() {
                ": within the runs' noise"
            } else {
                ""
            }
        )
    }
}

fn scene_label(name: &str, scene: &Scene) -> String {
    let d = scene.grid.dims();
    if d.x == d.y && d.y == d.z {
        format!("{name} {}^3", d.x)
    } else {
        format!("{name} {}x{}x{}", d.x, d.y, d.z)
    }
}

/// Times the walks on one scene and surface (`walks`: each walk's settings) with their
/// timed frames interleaved (a frame of each walk in turn, `runs` rounds), so that a
/// spell of load on a shared machine falls on every walk alike rather than on whichever
/// row it met: the seed scene at 256^3 measured its dense walk at 6.8 s in one run and
/// 9.0 s in another an hour later with the proximity walk at 2.0 s in both, when each
/// walk's frames ran back to back. Each walk starts from the device's own steps per iteration
/// (`device_unroll`). One result per walk, in their order: a walk the device cannot
/// render is its error, the others still measured.
fn bench_gpu(
    gpu: &mut GpuTracer,
    device_unroll: u32,
    name: &str,
    scene: &Scene,
    walks: &[RenderSettings],
    runs: usize,
) -> Vec<Result<BenchRow>> {
    let mut timing: Vec<Timing> = walks
        .iter()
        .map(|settings| Timing {
            settings,
            state: prepare_gpu_row(gpu, name, scene, settings, device_unroll),
            times: Vec::new(),
        })
        .collect();
    for _ in 0..runs.max(1) {
        for w in timing.iter_mut() {
            let Ok((_, unroll)) = &w.state else {
                continue;
            };
            // Each walk with the steps per iteration its own first frames settled on.
            let time = gpu.set_dda_unroll(*unroll).and_then(|()| {
                let out = gpu.render(scene, w.settings)?;
                Ok(gpu.last_gpu_time().unwrap_or(out.trace_time))
            });
            match time {
                Ok(t) => w.times.push(t),
                Err(e) => w.state = Err(e.context("a timed frame")),
            }
        }
    }
    timing
        .into_iter()
        .map(|w| {
            let (row, _) = w.state?;
            Ok(BenchRow {
                median: median(w.times.clone()),
                times: w.times,
                ..row
            })
        })
        .collect()
}

/// The back-to-back calls a GPU row's `wall` is the median of.
const WALL_CALLS: usize = 3;

/// One walk of [`bench_gpu`] while its frames are timed: its row and steps per
/// iteration once prepared (or why it could not be), and its frames' times.
struct Timing<'a> {
    settings: &'a RenderSettings,
    state: Result<(BenchRow, u32)>,
    times: Vec<Duration>,
}

/// A walk's row before its timing: the counted frame (which doubles as warm-up: it
/// uploads the grid and builds the counting pipeline) and one plain frame (which
/// builds the timed pipeline, and raises the steps per iteration if the driver's loop
/// limit cuts it); with the steps per iteration it settled on.
fn prepare_gpu_row(
    gpu: &mut GpuTracer,
    name: &str,
    scene: &Scene,
    s: &RenderSettings,
    device_unroll: u32,
) -> Result<(BenchRow, u32)> {
    gpu.set_dda_unroll(device_unroll)?;
    let counted = gpu.render_counted(scene, s)?;
    let memory = gpu.last_memory().unwrap_or_default();
    let plan = gpu.last_plan().expect("a render was made").traversal;
    // The counted frame built the tree (and uploaded it): the setup time of that render,
    // where nothing else is set up (no cone feature in the benchmark's settings).
    let build = gpu.last_setup_time();
    gpu.render(scene, s)?;
    // A display loop's calls: back to back on the same walk, warm (the timed frames
    // alternate walks, and a switch uploads the other walk's data again).
    let mut walls = Vec::new();
    for _ in 0..WALL_CALLS {
        let start = Instant::now();
        gpu.render(scene, s)?;
        walls.push(start.elapsed());
    }
    let row = BenchRow {
        scene: scene_label(name, scene),
        grid: scene.grid.dims().x,
        backend: "gpu",
        traversal: plan.name,
        surface: s.surface.name(),
        median: Duration::ZERO,
        times: Vec::new(),
        wall: median(walls),
        stats: counted.stats,
        bytes_per_voxel: (memory.grid + memory.walk_data) as f64 / scene.grid.voxel_count() as f64,
        build,
        timer: gpu.timer_name(),
        dda_unroll: gpu.last_plan().map(|p| p.dda_unroll),
    };
    Ok((row, gpu.dda_unroll()))
}

/// Times the walks (`walks`: each walk's settings) on the CPU reference as
/// [`bench_gpu`] does on the device: each walk's warm-up frame first, then one timed
/// frame of each walk in turn. What a render reads (the walk's data) is prepared once
/// per walk, as the GPU keeps it between frames; its time is the row's build time.
fn bench_cpu(name: &str, scene: &Scene, walks: &[RenderSettings], runs: usize) -> Vec<BenchRow> {
    let mut timing: Vec<_> = walks
        .iter()
        .map(|s| {
            let plan = crate::plan::Plan::new(scene, s);
            let start = Instant::now();
            let prepared = crate::cpu::Prepared::new(scene, s, &plan);
            let build = start.elapsed();
            // The walk's own data (the sparse tree, say); the dense grid's one byte a
            // voxel otherwise.
            let bytes_per_voxel = prepared.regions.as_ref().map_or(1.0, |r| {
                r.device_bytes() as f64 / scene.grid.voxel_count() as f64
            });
            let warm = crate::cpu::render_prepared(scene, s, &plan, &prepared);
            let row = BenchRow {
                scene: scene_label(name, scene),
                grid: scene.grid.dims().x,
                backend: "cpu",
                traversal: plan.traversal.name,
                surface: s.surface.name(),
                median: Duration::ZERO,
                times: Vec::new(),
                wall: Duration::ZERO,
                stats: warm.stats,
                bytes_per_voxel,
                build,
                timer: "wall (cpu::render)",
                dda_unroll: None,
            };
            (s, plan, prepared, row, Vec::with_capacity(runs))
        })
        .collect();
    for _ in 0..runs.max(1) {
        for (s, plan, prepared, _, times) in timing.iter_mut() {
            times.push(crate::cpu::render_prepared(scene, s, plan, prepared).trace_time);
        }
    }
    timing
        .into_iter()
        .map(|(_, _, _, row, times)| {
            let median = median(times.clone());
            BenchRow {
                median,
                times,
                wall: median,
                ..row
            }
        })
        .collect()
}

/// A scene of the run: its name, the scene, the settings it renders with, and for a
/// grid held only as its sparse tree the time that tree took to build from its source
/// (the rows' build time; rebuilding it from itself would say nothing).
type BenchScene = (String, Scene, RenderSettings, Option<Duration>);

/// The scenes of `opts`, in order: the seed scene at each size, the experiments', the
/// generated ones; each made when it is reached.
fn scenes(opts: &BenchOptions) -> impl Iterator<Item = Result<BenchScene>> + '_ {
    let seeds = opts
        .sizes
        .iter()
        .flat_map(|&n| opts.rules.iter().map(move |&rules| (n, rules)));
    let seeds = seeds.map(|(n, rules)| -> Result<BenchScene> {
        let start = Instant::now();
        let scene = seed_scene(n)?;
        if scene.grid.is_sparse() {
            // Its tree was built straight from the seed's rules: that is its build time.
            eprintln!(
                "  seed {n}^3: held as its sparse tree ({:.1} MiB), built from the seed's rules \
                 in {:.1} ms, no dense grid",
                scene.grid.host_bytes() as f64 / (1u64 << 20) as f64,
                start.elapsed().as_secs_f64() * 1e3
            );
        }
        let held = scene.grid.is_sparse().then(|| start.elapsed());
        let name = match rules {
            Rules::Consistent => "seed".to_string(),
            Rules::Seed => "seed (seed rules)".to_string(),
        };
        let settings = RenderSettings {
            rules,
            ..opts.settings.clone()
        };
        Ok((name, scene, settings, held))
    });
    let experiments = opts.experiments.iter().map(|e| -> Result<BenchScene> {
        // The experiment's own rules and techniques are what its rows measure (a
        // `rules = "seed"` experiment is the like-for-like comparison with the seed's
        // tracer); only the image size is the run's, and one frame is timed.
        let settings = RenderSettings {
            width: opts.settings.width,
            height: opts.settings.height,
            spp: 1,
            ..e.settings.clone()
        };
        Ok((e.name.clone(), e.scene.clone(), settings, None))
    });
    let generated = opts
        .scenes
        .iter()
        .map(|(n, s)| Ok((n.clone(), s.clone(), opts.settings.clone(), None)));
    seeds.chain(experiments).chain(generated)
}

/// Runs the benchmark, printing each row as soon as it is measured (`progress`), and
/// returns all rows. A missing GPU is an error: the ratio is the point of the run.
pub fn run(opts: &BenchOptions, mut progress: impl FnMut(&BenchRow)) -> Result<Vec<BenchRow>> {
    let mut gpu = GpuTracer::new()?;
    // A render that runs into the software driver's loop limit is rendered again with
    // more steps per loop iteration, which the tracer keeps for that grid's dims and
    // walk (crate::gpu): every row starts from the device's own choice, so that no row
    // is measured with another's setting (the seed's rules at 16^3: 112 ms per frame
    // alone, 172 ms with the seed scene at 256^3's).
    let device_unroll = gpu.dda_unroll();
    let mut rows = Vec::new();
    for scene in scenes(opts) {
        let (name, scene, settings, held) = scene?;
        let held_build = |mut row: BenchRow| {
            if let Some(b) = held {
                row.build = b;
            }
            row
        };
        for &surface in &opts.surfaces {
            let probe = RenderSettings {
                surface,
                ..settings.clone()
            };
            if crate::plan::check_surface(&scene, &probe).is_err() {
                continue;
            }
            // Each walk's settings: the surface's with the walk.
            let walks: Vec<RenderSettings> = opts
                .traversals
                .iter()
                .map(|&traversal| RenderSettings {
                    traversal,
                    ..probe.clone()
                })
                .filter(|s| {
                    let t = s.traversal;
                    let planned = crate::plan::Plan::new(&scene, s).traversal;
                    // A grid held only as its tree has no dense walk: not measured twice.
                    let follows = t == Traversal::Auto || Traversal::Walk(planned) == t;
                    if !follows {
                        eprintln!(
                            "  {} {}: not measured: the grid is held only as its sparse tree",
                            scene_label(&name, &scene),
                            t.name()
                        );
                    }
                    follows
                })
                .collect();
            // A row the device cannot render (the software driver's loop limit, its
            // memory) is said and left out; the others are still measured.
            let measured = bench_gpu(
                &mut gpu,
                device_unroll,
                &name,
                &scene,
                &walks,
                opts.gpu_runs,
            );
            for (s, result) in walks.iter().zip(measured) {
                match result {
                    Ok(row) => {
                        let row = held_build(row);
                        progress(&row);
                        rows.push(row);
                    }
                    Err(e) => eprintln!(
                        "  {} {} gpu {}: not measured: {e:#}",
                        scene_label(&name, &scene),
                        surface.name(),
                        s.traversal.name()
                    ),
                }
            }
            if opts.cpu {
                for row in bench_cpu(&name, &scene, &walks, opts.cpu_runs) {
                    let row = held_build(row);
                    progress(&row);
                    rows.push(row);
                }
            }
        }
    }
    Ok(rows)
}

/// What a scene's triangle surface costs to hold: its triangles, the cells they
/// overlap and the references from cells to triangles.
#[derive(Clone, Debug)]
pub struct SurfaceRow {
    pub scene: String,
    pub surface: &'static str,
    pub triangles: usize,
    pub cells: usize,
    pub references: usize,
    /// Bytes of the GPU's buffer (triangles, cell table, references).
    pub gpu_bytes: u64,
    /// Extracting (smooth) and listing the cells, on the host.
    pub build: Duration,
}

impl SurfaceRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "scene": self.scene,
            "surface": self.surface,
            "triangles": self.triangles,
            "cells": self.cells,
            "references": self.references,
            "gpu_bytes": self.gpu_bytes,
            "bytes_per_reference": self.gpu_bytes as f64 / self.references.max(1) as f64,
            "build_ms": self.build.as_secs_f64() * 1e3,
        })
    }
}

/// The triangle surfaces of `opts`' scenes, one row per scene and surface other than
/// voxels that the scene can have.
pub fn surface_rows(opts: &BenchOptions) -> Result<Vec<SurfaceRow>> {
    let mut rows = Vec::new();
    // Voxels only: no table, and no scene made a second time (the seed scene at 2048^3
    // takes half a second).
    if opts.surfaces.iter().all(|s| !s.traces_triangles()) {
        return Ok(rows);
    }
    for scene in scenes(opts) {
        let (name, scene, settings, _) = scene?;
        for &surface in opts.surfaces.iter().filter(|s| s.traces_triangles()) {
            let probe = RenderSettings {
                surface,
                ..settings.clone()
            };
            if crate::plan::check_surface(&scene, &probe).is_err() {
                continue;
            }
            let start = std::time::Instant::now();
            let Some(t) = surface.trace(&scene)? else {
                continue;
            };
            rows.push(SurfaceRow {
                scene: scene_label(&name, &scene),
                surface: surface.name(),
                build: start.elapsed(),
                triangles: t.triangles.len(),
                cells: t.cells.len(),
                references: t.refs.len(),
                gpu_bytes: t.gpu_bytes(),
            });
        }
    }
    Ok(rows)
}

/// The surfaces' table: sizes and bytes per triangle reference.
pub fn surface_table(rows: &[SurfaceRow]) -> String {
    let mut out = String::from(
        "| scene | surface | triangles | cells | references | references/cell | GPU MiB | bytes/reference | listing ms |\n\
         |---|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.1} | {:.1} |\n",
            r.scene,
            r.surface,
            r.triangles,
            r.cells,
            r.references,
            r.references as f64 / r.cells.max(1) as f64,
            r.gpu_bytes as f64 / 1048576.0,
            r.gpu_bytes as f64 / r.references.max(1) as f64,
            r.build.as_secs_f64() * 1e3,
        );
    }
    out
}

/// The table docs/sparse-traversal.md quotes: one line per grid size and backend, then the ratio.
pub fn table(rows: &[BenchRow], adapter: &str, settings: &RenderSettings) -> String {
    let mut out = format!(
        "{}x{}, depth {}/{} (experiments: their own render settings, one frame); GPU: {adapter}; CPU: {}; host: {}\n\n\
         | scene | surface | backend | walk | median ms/frame | runs' range ms | timer | wall ms/call | steps/iteration | Mrays/s | Msteps/s | rays/frame (primary + secondary + shadow) | voxel steps/frame | steps/ray | triangle tests/ray | bytes/voxel | build ms |\n\
         |---:|---|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        settings.width,
        settings.height,
        settings.max_reflection_depth,
        settings.max_refraction_depth,
        crate::cpu::backend_summary(),
        crate::cpu::host_summary(),
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {} | {} | {:.1} | {} | {} | {:.1} | {} | {:.2} | {:.1} | {} ({} + {} + {}) | {} | {:.2} | {} | {:.4} | {:.1} |\n",
            r.scene,
            r.surface,
            r.backend,
            r.traversal,
            r.ms(),
            r.range_text(),
            r.timer,
            r.wall.as_secs_f64() * 1e3,
            r.dda_unroll.map_or("-".to_string(), |n| n.to_string()),
            r.mrays_per_s(),
            r.msteps_per_s(),
            r.stats.total_rays(),
            r.stats.primary,
            r.stats.secondary,
            r.stats.shadow,
            r.stats.voxel_steps,
            r.stats.voxel_steps as f64 / r.stats.total_rays().max(1) as f64,
            // Counted by the CPU reference only.
            if r.backend == "cpu" && r.surface != crate::technique::default_surface().name {
                format!(
                    "{:.2}",
                    r.stats.triangle_tests as f64 / r.stats.total_rays().max(1) as f64
                )
            } else {
                "-".to_string()
            },
            r.bytes_per_voxel,
            r.build.as_secs_f64() * 1e3,
        );
    }
    // Each row against the row of the same scene that differs in one thing only.
    let partner = |r, backend, traversal, surface| partner(rows, r, backend, traversal, surface);
    let mut ratios = String::new();
    for g in rows.iter().filter(|r| r.backend == "gpu") {
        if let Some(c) = partner(g, "cpu", g.traversal, g.surface) {
            ratios += &format!(
                "{} {} {}: GPU is {} the CPU's speed (time ratio CPU/GPU)\n",
                g.scene,
                g.surface,
                g.traversal,
                Ratio::of(c, g)
            );
        }
    }
    // Each traversal against the default one on each backend and scene: time and steps.
    let default = crate::technique::default_traversal().name;
    for s in rows.iter().filter(|r| r.traversal != default) {
        if let Some(d) = partner(s, s.backend, default, s.surface) {
            ratios += &format!(
                "{} {} {}: {} is {} {default}'s speed, with {:.2}x fewer steps per ray\n",
                s.scene,
                s.surface,
                s.backend,
                s.traversal,
                Ratio::of(d, s),
                d.stats.voxel_steps as f64 / s.stats.voxel_steps.max(1) as f64
            );
        }
    }
    // Triangles against the voxel image of the same scene, backend and walk.
    let voxels = crate::technique::default_surface().name;
    for t in rows.iter().filter(|r| r.surface != voxels) {
        if let Some(v) = partner(t, t.backend, t.traversal, voxels) {
            ratios += &format!(
                "{} {} {} {}: {} the voxel image's time per frame\n",
                t.scene,
                t.surface,
                t.backend,
                t.traversal,
                Ratio::of(t, v)
            );
        }
    }
    if !ratios.is_empty() {
        out += "\n";
        out += &ratios;
    }
    out
}

/// The row of `rows` of `r`'s scene on this backend, walk and surface.
fn partner<'a>(
    rows: &'a [BenchRow],
    r: &BenchRow,
    backend: &str,
    traversal: &str,
    surface: &str,
) -> Option<&'a BenchRow> {
    rows.iter().find(|p| {
        p.scene == r.scene
            && p.backend == backend
            && p.traversal == traversal
            && p.surface == surface
    })
}

/// The rows whose walk counted other rays than the default walk on the same scene,
/// surface and backend, one line each. Every walk gives the dense walk's visits, so
/// the same rays and image (`tests/sparse.rs`, `tests/gpu_sparse.rs`): a difference is a
/// walk that renders wrong, and its figures are not comparable. (The GPU and the CPU
/// may differ by a few rays through voxel edges: f32 against f64.)
pub fn walk_disagreements(rows: &[BenchRow]) -> Vec<String> {
    let default = crate::technique::default_traversal().name;
    rows.iter()
        .filter(|r| r.traversal != default)
        .filter_map(|r| {
            let d = partner(rows, r, r.backend, default, r.surface)?;
            let rays = |s: &RayStats| (s.primary, s.secondary, s.shadow);
            let count = |s: &RayStats| {
                format!(
                    "{} rays ({} + {} + {})",
                    s.total_rays(),
                    s.primary,
                    s.secondary,
                    s.shadow
                )
            };
            (rays(&d.stats) != rays(&r.stats)).then(|| {
                format!(
                    "{} {} {}: the {} walk counted {}, the {default} walk {}: the walks \
                     must trace the same rays",
                    r.scene,
                    r.surface,
                    r.backend,
                    r.traversal,
                    count(&r.stats),
                    count(&d.stats),
                )
            })
        })
        .collect()
}

/// One mesh voxelized at one resolution: the median of several runs.
#[derive(Clone, Debug)]
pub struct VoxelizeRow {
    pub mesh: String,
    pub triangles: usize,
    pub resolution: u32,
    pub dims: glam::UVec3,
    pub solid_voxels: usize,
    pub median: Duration,
}

impl VoxelizeRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "mesh": self.mesh,
            "triangles": self.triangles,
            "resolution": self.resolution,
            "dims": self.dims.to_array(),
            "solid_voxels": self.solid_voxels,
            "ms": self.median.as_secs_f64() * 1e3,
        })
    }
}

/// A closed torus of `rings x segments x 2` triangles (major radius 1, minor 0.35): a
/// synthetic mesh of a chosen size for the voxelization benchmark.
pub fn torus_mesh(rings: u32, segments: u32) -> crate::scene::mesh::TriangleMesh {
    use glam::DVec3;
    use std::f64::consts::TAU;
    let point = |i: u32, j: u32| {
        let (su, cu) = (TAU * (i % rings) as f64 / rings as f64).sin_cos();
        let (sv, cv) = (TAU * (j % segments) as f64 / segments as f64).sin_cos();
        let r = 1.0 + 0.35 * cv;
        DVec3::new(r * cu, 0.35 * sv, r * su)
    };
    let mut triangles = Vec::with_capacity((2 * rings * segments) as usize);
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (
                point(i, j),
                point(i + 1, j),
                point(i + 1, j + 1),
                point(i, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    crate::scene::mesh::TriangleMesh {
        material_of: vec![0; triangles.len()],
        materials: vec![crate::scene::seed_palette()[3].clone()],
        triangles,
        normals: Vec::new(),
        warnings: Vec::new(),
    }
}

/// Times the voxelization (surface + interior fill) of `mesh` at `resolution`.
pub fn bench_voxelize(
    name: &str,
    mesh: &crate::scene::mesh::TriangleMesh,
    resolution: u32,
    runs: usize,
) -> Result<VoxelizeRow> {
    let opts = crate::scene::VoxelizeOptions::count(resolution);
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..runs.max(1) {
        let start = std::time::Instant::now();
        let v = crate::scene::mesh::voxelize(mesh, &opts)
            .map_err(|k| anyhow::anyhow!("{name}: {k}"))?;
        times.push(start.elapsed());
        last = Some(v);
    }
    let v = last.expect("at least one run");
    Ok(VoxelizeRow {
        mesh: name.to_string(),
        triangles: v.triangle_count,
        resolution,
        dims: v.grid.dims(),
        solid_voxels: v.shell_voxels + v.interior_voxels,
        median: median(times),
    })
}

pub fn voxelize_table(rows: &[VoxelizeRow]) -> String {
    let mut out = String::from(
        "| mesh | triangles | resolution | grid | solid voxels | median ms | grid Mvoxels/s |\n\
         |---|---:|---:|---|---:|---:|---:|\n",
    );
    for r in rows {
        let s = r.median.as_secs_f64();
        out += &format!(
            "| {} | {} | {} | {}x{}x{} | {} | {:.1} | {:.2} |\n",
            r.mesh,
            r.triangles,
            r.resolution,
            r.dims.x,
            r.dims.y,
            r.dims.z,
            r.solid_voxels,
            s * 1e3,
            r.dims.as_dvec3().element_product() / s / 1e6
        );
    }
    out
}

/// A scene that does not need some feature, rendered by the planned (reduced) kernel
/// and by the full one: every flag whose code leaves this scene's image unchanged
/// forced on, the settings' whole ray stack, and the resources a plan-less tracer would
/// hold (accumulation buffer, opacity pyramid). `docs/plan.md`.
#[derive(Clone, Debug)]
pub struct PlanRow {
    pub scene: String,
    pub reduced: crate::plan::Plan,
    pub reduced_ms: f64,
    pub full_ms: f64,
    /// The full kernel's time over the reduced one's, round by round (the two are timed
    /// a frame of each in turn).
    pub time_ratio: Ratio,
    pub reduced_bytes: u64,
    pub full_bytes: u64,
    /// Largest per-channel difference between the two images: 0 shows the comparison
    /// is fair (the reduced kernel renders the same image).
    pub max_diff: f32,
}

impl PlanRow {
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "scene": self.scene,
            "plan": self.reduced.to_string(),
            "reduced_ms": self.reduced_ms,
            "full_ms": self.full_ms,
            "time_full_over_reduced": self.time_ratio.json(),
            "reduced_bytes": self.reduced_bytes,
            "full_bytes": self.full_bytes,
            "max_diff": self.max_diff,
        })
    }
}

/// A warm frame of `plan` (its image and the device's bytes), so that the timed rounds
/// that follow find its pipeline built.
fn warm_plan(
    gpu: &mut GpuTracer,
    scene: &Scene,
    settings: &RenderSettings,
    plan: &crate::plan::Plan,
) -> Result<(crate::frame::Frame, u64)> {
    let warm = gpu.render_plan(scene, settings, plan.clone())?;
    let bytes = gpu.last_memory().map_or(0, |m| m.total());
    Ok((warm.frame, bytes))
}

/// Scenes that leave something out: opaque materials only (no refraction), no lights
/// (no shadow rays), and the seed scene itself (no cones, nothing to sample).
pub fn plan_scenes(n: u32) -> Result<Vec<(String, Scene)>> {
    let seed = seed_scene(n)?;
    let mut opaque = seed.clone();
    for m in opaque.materials.iter_mut().skip(1) {
        m.kt = 0.0;
    }
    let mut unlit = seed.clone();
    unlit.lights.clear();
    Ok(vec![
        (format!("seed {n}^3, opaque materials only"), opaque),
        (format!("seed {n}^3, no lights"), unlit),
        (format!("seed {n}^3 (no cones, no area lights)"), seed),
    ])
}

pub fn bench_plans(
    gpu: &mut GpuTracer,
    scenes: &[(String, Scene)],
    settings: &RenderSettings,
    runs: usize,
) -> Result<Vec<PlanRow>> {
    let mut rows = Vec::new();
    for (name, scene) in scenes {
        let reduced = crate::plan::Plan::new(scene, settings);
        let full = reduced.with_all_code(scene, settings);
        let (a, reduced_bytes) = warm_plan(gpu, scene, settings, &reduced)?;
        let (b, full_bytes) = warm_plan(gpu, scene, settings, &full)?;
        // A frame of each in turn, so that load on a shared machine falls on both alike.
        let (mut reduced_times, mut full_times) = (Vec::new(), Vec::new());
        for _ in 0..runs.max(1) {
            for (plan, times) in [(&reduced, &mut reduced_times), (&full, &mut full_times)] {
                let out = gpu.render_plan(scene, settings, plan.clone())?;
                times.push(gpu.last_gpu_time().unwrap_or(out.trace_time));
            }
        }
        let ms = |t: &[Duration]| median(t.to_vec()).as_secs_f64() * 1e3;
        let (reduced_ms, full_ms) = (ms(&reduced_times), ms(&full_times));
        let time_ratio = Ratio::of_times(&full_times, &reduced_times, true);
        let max_diff = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
            .fold(0.0f32, f32::max);
        rows.push(PlanRow {
            scene: name.clone(),
            reduced,
            reduced_ms,
            full_ms,
            time_ratio,
            reduced_bytes,
            full_bytes,
            max_diff,
        });
    }
    Ok(rows)
}

pub fn plan_table(rows: &[PlanRow]) -> String {
    let mut out = String::from(
        "| scene | reduced plan | reduced ms | full ms | time full/reduced (round by round) | reduced MiB | full MiB | memory full/reduced | max image diff |\n\
         |---|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mib = |b: u64| b as f64 / 1048576.0;
    for r in rows {
        let flags = r.reduced.flags_on();
        out += &format!(
            "| {} | {} (stack {}) | {:.1} | {:.1} | {} | {:.2} | {:.2} | {:.2} | {:.1e} |\n",
            r.scene,
            if flags.is_empty() {
                "primary only".to_string()
            } else {
                flags.join(" ")
            },
            r.reduced.ray_stack_size,
            r.reduced_ms,
            r.full_ms,
            r.time_ratio.cell(),
            mib(r.reduced_bytes),
            mib(r.full_bytes),
            r.full_bytes as f64 / r.reduced_bytes as f64,
            r.max_diff
        );
    }
    out
}

/// One tree shape over one scene in the structure comparison (`voxlab bench --trees`).
#[derive(Clone, Debug)]
pub struct TreeRow {
    pub scene: String,
    /// "dense", or the tree's children per node side ("octree", "64-tree", "512-tree").
    pub structure: &'static str,
    pub nodes: usize,
    pub bytes_per_voxel: f64,
    pub build: Duration,
    /// Rays walked: the primary rays and a shadow ray from each primary hit to each
    /// light.
    pub rays: u64,
    /// Moves of the walk per ray (voxel steps; a region left whole is one).
    pub steps_per_ray: f64,
    /// Time of the walks, one thread.
    pub ms: f64,
}

/// Compares the dense grid with trees of 2, 4 and 8 children a side on the CPU walk
/// (f64, one thread, so the times compare the work): the primary rays of the scene's
/// camera at `size`^2 and a min-kt shadow ray from each hit to each light.
pub fn bench_trees(name: &str, scene: &Scene, size: u32) -> Vec<TreeRow> {
    use crate::cpu::shadow_min_kt_over;
    use crate::dda::cast_over;
    use crate::sparse::SparseTree;
    let cam = scene.camera.frame();
    let mut rows = Vec::new();
    for b in [0, 1, 2, 3] {
        let (tree, build) = if b == 0 {
            (None, Duration::ZERO)
        } else {
            let (t, s) = SparseTree::build_timed(&scene.grid, b);
            (Some(t), s.time)
        };
        let regions = tree.as_ref().map(|t| t as &dyn crate::sparse::Regions);
        let start = std::time::Instant::now();
        let mut stats = RayStats::default();
        let mut rays = 0u64;
        for j in 0..size {
            for i in 0..size {
                let d = cam.primary_dir(i, j, size, size);
                let medium = scene.medium_at(cam.eye);
                let (hit, steps) = cast_over(&scene.grid, regions, cam.eye, d, medium, true);
                stats.voxel_steps += steps;
                rays += 1;
                if let Some(h) = hit {
                    let q = cam.eye + h.t * d + 1e-3 * scene.grid.voxel_size() * h.normal;
                    for l in &scene.lights {
                        shadow_min_kt_over(scene, regions, q, l.position(), &mut stats);
                        rays += 1;
                    }
                }
            }
        }
        let ms = start.elapsed().as_secs_f64() * 1e3;
        rows.push(TreeRow {
            scene: name.to_string(),
            structure: ["dense", "octree", "64-tree", "512-tree"][b as usize],
            nodes: tree.as_ref().map_or(0, |t| t.node_count()),
            bytes_per_voxel: tree.as_ref().map_or(1.0, |t| t.bytes_per_voxel()),
            build,
            rays,
            steps_per_ray: stats.voxel_steps as f64 / rays.max(1) as f64,
            ms,
        });
    }
    rows
}

/// The structure comparison as a markdown table.
pub fn trees_table(rows: &[TreeRow]) -> String {
    let mut out = String::from(
        "| scene | structure | nodes | bytes/voxel | build ms | rays | steps/ray | CPU walk ms |\n\
         |---|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {} | {:.4} | {:.1} | {} | {:.2} | {:.1} |\n",
            r.scene,
            r.structure,
            r.nodes,
            r.bytes_per_voxel,
            r.build.as_secs_f64() * 1e3,
            r.rays,
            r.steps_per_ray,
            r.ms
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(backend: &'static str, traversal: &'static str, shadow: u64) -> BenchRow {
        BenchRow {
            scene: "seed 16^3".into(),
            grid: 16,
            backend,
            traversal,
            surface: "voxels",
            median: Duration::from_millis(1),
            times: vec![Duration::from_millis(1)],
            wall: Duration::from_millis(1),
            stats: RayStats {
                primary: 4,
                secondary: 2,
                shadow,
                ..RayStats::default()
            },
            bytes_per_voxel: 1.0,
            build: Duration::ZERO,
            timer: "wall",
            dda_unroll: None,
        }
    }

    fn timed(backend: &'static str, traversal: &'static str, ms: &[u64]) -> BenchRow {
        let times: Vec<Duration> = ms.iter().map(|&m| Duration::from_millis(m)).collect();
        BenchRow {
            median: median(times.clone()),
            times,
            ..row(backend, traversal, 5)
        }
    }

    /// Two walks timed in the same rounds are compared round by round; a range that holds
    /// 1 is said to be noise, whatever the medians' ratio.
    #[test]
    fn a_ratio_carries_the_range_of_its_rounds() {
        let (a, b) = (
            timed("gpu", "octant", &[10, 12, 11]),
            timed("gpu", "boxes", &[10, 11, 12]),
        );
        let r = Ratio::of(&a, &b);
        assert!(r.paired);
        assert_eq!(r.median, 1.0);
        assert!(
            (r.lo - 11.0 / 12.0).abs() < 1e-12 && (r.hi - 12.0 / 11.0).abs() < 1e-12,
            "{r:?}"
        );
        assert!(r.within_noise());
        assert!(r.to_string().contains("within the runs' noise"), "{r}");
        // Faster in every round: a finding, its range clear of 1.
        let c = timed("gpu", "boxes", &[8, 9, 9]);
        let r = Ratio::of(&a, &c);
        assert!(!r.within_noise() && r.lo > 1.0, "{r:?}");
        assert!(!r.to_string().contains("noise"), "{r}");
        // Rows of two backends were not timed in the same rounds: the widest range.
        let cpu = timed("cpu", "octant", &[40, 44, 42]);
        let r = Ratio::of(&cpu, &a);
        assert!(!r.paired);
        assert!(
            (r.lo - 40.0 / 12.0).abs() < 1e-12 && (r.hi - 4.4).abs() < 1e-12,
            "{r:?}"
        );
        assert!(r.to_string().contains("slowest and fastest"), "{r}");
    }

    #[test]
    fn a_walk_with_other_rays_than_the_default_walks_is_named() {
        let rows = [
            row("gpu", "dense", 5),
            row("gpu", "octant", 5),
            row("gpu", "proximity", 6),
            // The CPU's rows compare with the CPU's default walk only.
            row("cpu", "dense", 7),
            row("cpu", "octant", 7),
        ];
        let wrong = walk_disagreements(&rows);
        assert_eq!(wrong.len(), 1, "{wrong:?}");
        assert!(
            wrong[0].contains("gpu: the proximity walk counted 12 rays"),
            "{wrong:?}"
        );
    }
}
