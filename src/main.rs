//! The `voxlab` command line.
//!
//! `voxlab` alone renders the seed scene to `out/seed.png`; `voxlab render FILE.toml`
//! renders an experiment. Every failure is a message on stderr and a non-zero exit,
//! never a panic and never a partial output file.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use clap::{Args, Parser, Subcommand, ValueEnum};

use voxlab::Session;
use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;
use voxlab::output::OutputFormat;
use voxlab::render::{Frame, MAX_IMAGE_SIDE};

/// Whitted ray tracing over a voxel grid, on the GPU (wgpu) with an f64 CPU reference.
///
/// With no subcommand, renders the seed scene (16^3, 512x512, depth 4/4) to out/seed.png.
#[derive(Parser, Debug)]
#[command(name = "voxlab", version, args_conflicts_with_subcommands = true)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    /// Options for the default seed render.
    #[command(flatten)]
    render: RenderOpts,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render an experiment file to an image.
    Render(RenderArgs),
    /// Voxelize a mesh (OBJ, glTF, GLB) and write it as a MagicaVoxel .vox file.
    Voxelize(VoxelizeArgs),
    /// Benchmark the baseline: the seed scene at several grid sizes, GPU and CPU in one
    /// run (median ms per frame, counted rays and voxel steps per second, GPU/CPU ratio).
    Bench(BenchArgs),
    /// Stress suite (`docs/stress.md`): stiff and extreme cases on the GPU and the CPU
    /// reference; prints the table and writes it as stress.md and stress.csv.
    Stress(StressArgs),
    /// Error against run time: every shadow model and quality knob against a converged
    /// reference (the experiment's [ablate] table); writes images, a labelled grid, a CSV,
    /// a log-log plot and a markdown table.
    Ablate(AblateArgs),
    /// Interactive viewer: two feature sets of one scene side by side (split view),
    /// orbit camera, progressive accumulation, scene and side panels, error against a
    /// converged reference, PNG + TOML export that `voxlab render` reproduces exactly.
    #[cfg(feature = "viewer")]
    View(ViewArgs),
    /// List every technique (shadow models, transmittance, lighting terms): its slot,
    /// the `[features]` switch, its settings with type, default and range, and the paper
    /// it follows.
    Techniques(TechniquesArgs),
    /// Every number of an experiment file outside the techniques (camera, render,
    /// materials, lights): its type, range, default and unit, as the parser checks it.
    Settings(SettingsArgs),
    /// What a scene file holds: a .vox's or an experiment's grid and every palette entry
    /// with its voxel count and colour; a mesh's triangles, bounds and materials.
    Info(InfoArgs),
    /// The smooth surface of an experiment's voxels, per material (Naive Surface Nets,
    /// relaxed in its cells), written as OBJ (+ MTL) or binary PLY.
    Mesh(MeshArgs),
    /// The experiment's scene for an independent renderer: `--to mitsuba DIR` writes a
    /// Mitsuba 3 scene.xml and PLY meshes (docs/mitsuba.md lists what maps exactly).
    Export(ExportArgs),
    // Further subcommands go here, one variant each, with their own Args struct and
    // `cmd_*` function.
}

#[derive(Args, Debug)]
struct ExportArgs {
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
enum ExportTarget {
    /// Mitsuba 3 (scene format 3.0.0).
    Mitsuba,
}

#[derive(Args, Debug)]
struct MeshArgs {
    /// The experiment file (TOML) whose voxels are meshed; without one, the seed scene.
    experiment: Option<PathBuf>,
    /// Output: FILE.obj (with FILE.mtl beside it) or FILE.ply.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Relaxation passes: each vertex moves to its neighbours' mean, kept in its cell
    /// (0: the dual cells' centres, a chamfered staircase).
    #[arg(long, value_name = "N", default_value_t = voxlab::surface::DEFAULT_RELAX,
          value_parser = clap::value_parser!(u32).range(0..=voxlab::surface::MAX_RELAX as i64))]
    relax: u32,
    /// Override any key of the experiment file (repeatable; as `render --set`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
}

#[derive(Args, Debug)]
struct InfoArgs {
    /// A .vox, .toml (experiment), .obj, .gltf or .glb file.
    file: PathBuf,
}

#[derive(Args, Debug)]
struct TechniquesArgs {
    /// Print the markdown table docs/techniques.md holds.
    #[arg(long, conflicts_with = "json")]
    markdown: bool,
    /// Print the listing as JSON records (what the Python `voxlab.techniques()` gives).
    #[arg(long)]
    json: bool,
}

#[derive(Args, Debug)]
struct SettingsArgs {
    /// Print the markdown table docs/experiments.md holds (the default: plain text).
    #[arg(long)]
    markdown: bool,
}

#[cfg(feature = "viewer")]
#[derive(Args, Debug)]
struct ViewArgs {
    /// The experiment file (TOML). Default: the seed scene.
    experiment: Option<PathBuf>,
    /// Features of the left side, comma-separated: a shadow model (hard, area, cone or a
    /// plug-in: `voxlab techniques`), min-kt, beer-lambert, ao, indirect, samples=N
    /// (default: the experiment's own).
    #[arg(long, value_name = "LIST")]
    left: Option<String>,
    #[arg(long, value_name = "LIST", help = format!(
        "Features of the right side, as --left (default: {})",
        voxlab::viewer::state::DEFAULT_RIGHT_SIDE
    ))]
    right: Option<String>,
    /// Turn the camera by YAW,PITCH degrees before the first frame.
    #[arg(long, value_name = "YAW,PITCH", value_parser = parse_pair, allow_hyphen_values = true)]
    orbit: Option<(f64, f64)>,
    /// Window size in points, WIDTHxHEIGHT.
    #[arg(long, value_name = "WxH", default_value = "1280x800", value_parser = parse_window)]
    window: (f32, f32),
    /// Scripted run: accumulate this many frames on both sides at full resolution, save
    /// both sides (PNG + TOML) and a window capture into --save-dir, then close.
    #[arg(long, value_name = "N", requires = "save_dir",
          value_parser = clap::value_parser!(u32).range(1..=voxlab::viewer::state::MAX_VIEW_SPP as i64))]
    frames: Option<u32>,
    /// Directory for the scripted run's files.
    #[arg(long, value_name = "DIR", requires = "frames")]
    save_dir: Option<PathBuf>,
    /// Override any key of the experiment file (repeatable; as `render --set`).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
    /// What the image area shows at the start (B flips the sides in the window).
    #[arg(long, value_enum, default_value_t = ViewModeArg::Split)]
    view: ViewModeArg,
    /// Display exposure: radiance times 2^EV before the clamp.
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_hyphen_values = true,
          value_parser = parse_exposure)]
    exposure: f64,
    /// Show the sRGB-encoded display (default: the seed's linear framebuffer).
    #[arg(long)]
    srgb: bool,
}

#[cfg(feature = "viewer")]
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum ViewModeArg {
    Split,
    Left,
    Right,
    Difference,
    Flip,
}

#[cfg(feature = "viewer")]
fn parse_pair(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("`{s}`: expected YAW,PITCH in degrees"))?;
    let num = |t: &str| {
        t.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{t}` is not a finite number of degrees"))
    };
    Ok((num(a)?, num(b)?))
}

#[cfg(feature = "viewer")]
fn parse_window(s: &str) -> Result<(f32, f32), String> {
    let (a, b) = s
        .split_once('x')
        .ok_or_else(|| format!("`{s}`: expected WIDTHxHEIGHT"))?;
    let num = |t: &str| {
        t.parse::<u32>()
            .ok()
            .filter(|n| (200..=8192).contains(n))
            .map(|n| n as f32)
            .ok_or_else(|| format!("`{t}`: each side must be an integer in 200..=8192"))
    };
    Ok((num(a)?, num(b)?))
}

#[cfg(feature = "viewer")]
fn cmd_view(args: ViewArgs) -> Result<()> {
    use voxlab::viewer::{Automation, ViewOptions};
    let automation = match (args.frames, args.save_dir) {
        (Some(frames), Some(save_dir)) => Some(Automation {
            frames,
            save_dir,
            exit: true,
        }),
        _ => None,
    };
    let scripted = automation.is_some();
    use voxlab::viewer::display::{Display, ViewMode};
    let mode = match args.view {
        ViewModeArg::Split => ViewMode::Split,
        ViewModeArg::Left => ViewMode::Left,
        ViewModeArg::Right => ViewMode::Right,
        ViewModeArg::Difference => ViewMode::Difference,
        ViewModeArg::Flip => ViewMode::Flip,
    };
    let outcome = voxlab::viewer::run(ViewOptions {
        experiment: args.experiment,
        left: args.left,
        right: args.right,
        orbit: args.orbit,
        window: args.window,
        automation,
        overrides: args.set,
        display: Display {
            mode,
            exposure: args.exposure,
            srgb: args.srgb,
            ..Display::default()
        },
    })?;
    if scripted {
        for p in &outcome.saved {
            println!("saved {}", p.display());
        }
    }
    Ok(())
}

#[derive(Args, Debug)]
struct RenderArgs {
    /// The experiment files (TOML; see experiments/baseline.toml for every key),
    /// rendered in turn on one device, each to out/<name>.png.
    #[arg(required = true, num_args = 1..)]
    experiments: Vec<PathBuf>,
    #[command(flatten)]
    opts: RenderOpts,
}

#[derive(Args, Debug)]
struct VoxelizeArgs {
    /// The mesh: .obj (with its .mtl), .gltf or .glb.
    mesh: PathBuf,
    /// Voxels along the mesh's longest axis.
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32)
              .range(1..=voxlab::scene::mesh::MAX_RESOLUTION as i64))]
    resolution: u32,
    /// The .vox file to write (grids over 256 per side become several placed models).
    #[arg(long, value_name = "PATH")]
    out: PathBuf,
}

#[derive(Args, Debug)]
struct AblateArgs {
    /// The experiment file (TOML); its [ablate] table sets the sweep (every key optional).
    experiment: PathBuf,
    /// Output directory. Default: out/ablate/<experiment name>.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Where converged references and the points done are kept (by a hash of what
    /// they depend on). Default: <out>/cache.
    #[arg(long, value_name = "DIR")]
    cache: Option<PathBuf>,
    /// Take the points an earlier run of the same sweep left in the cache (one that
    /// was stopped): only the missing ones are rendered, the others keep their
    /// measured times.
    #[arg(long)]
    resume: bool,
    /// Override any key of the file, [ablate] included (e.g. `--set ablate.runs=1`,
    /// `--set render.width=64`); repeatable, checked exactly like the file.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
    /// Report progress as lines (each step, the share done, the time left) also when
    /// standard error is not a terminal, for logs; a terminal shows a bar anyway.
    #[arg(long)]
    progress: bool,
}

#[derive(Args, Debug)]
struct BenchArgs {
    /// Grid sizes of the seed scene (N^3).
    #[arg(long, value_delimiter = ',', default_values_t = [16u32, 64, 256],
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    sizes: Vec<u32>,
    /// Image width and height in pixels.
    #[arg(long, default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    size: u32,
    /// Timed GPU frames per grid size (after a warm-up frame).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=1000))]
    gpu_runs: u32,
    /// Timed CPU frames per grid size (after a warm-up frame).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    cpu_runs: u32,
    /// Leave the CPU reference out (no ratio).
    #[arg(long)]
    no_cpu: bool,
    /// The ray-tree rules the seed scene is measured under: voxlab's (consistent) and
    /// the seed's own, like for like with the seed's tracer. Default: both.
    #[arg(long, value_delimiter = ',', value_parser = parse_rules)]
    rules: Vec<voxlab::render::Rules>,
    /// Experiments to benchmark after the seed scene (each its own scene, camera and
    /// lights, at --size and depth 4/4).
    #[arg(long, num_args = 1.., value_name = "EXPERIMENT")]
    experiments: Vec<PathBuf>,
    /// Override a key of every --experiments file (e.g. `--set scene.resolution=2048`
    /// for a mesh scene), checked exactly like the file; repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
    /// Compare the sparse structures instead: the dense grid and trees of 2, 4 and 8
    /// children a side (octree, 64-tree, 512-tree) on the CPU walk over the seed scene
    /// at each of --sizes: nodes, bytes per voxel, build time, steps per ray.
    #[arg(long)]
    trees: bool,
    /// The walks to compare at each size: traversals by name (`voxlab techniques`), or
    /// auto (the plan's choice). Default: every traversal.
    #[arg(long, value_delimiter = ',', value_parser = parse_traversal)]
    traversal: Vec<voxlab::render::Traversal>,
    /// Benchmark mesh voxelization instead: this mesh and a 50,000-triangle torus, each
    /// at --voxelize-resolution.
    #[arg(long, value_name = "MESH", num_args = 0..=1,
          default_missing_value = "experiments/data/bunny.obj")]
    voxelize: Option<PathBuf>,
    #[arg(long, default_value_t = 256,
          value_parser = clap::value_parser!(u32).range(1..=voxlab::scene::mesh::MAX_RESOLUTION as i64))]
    voxelize_resolution: u32,
    /// Measure the smooth surfaces instead: an analytic sphere and torus voxelized at
    /// each of these sizes, marching cubes and surface nets at several relaxations,
    /// their Chamfer and Hausdorff distances to the shape (in voxels), volume error and
    /// time.
    #[arg(long, value_name = "SIZES", num_args = 0..=1, value_delimiter = ',',
          default_missing_value = "32,64,128",
          value_parser = clap::value_parser!(u32).range(4..=512),
          conflicts_with_all = ["voxelize", "plan", "trees"])]
    surface_fidelity: Option<Vec<u32>>,
    /// Measure the ray cutoff instead (`[render] ray_cutoff`): each experiment (--experiments,
    /// else every experiments/*.toml) at --size, one frame, exact tree against each of
    /// these cutoffs: rays, time, and the largest and mean difference in display levels;
    /// then the largest cutoff within one level (1/255) on every experiment.
    #[arg(long, value_name = "CUTOFFS", num_args = 0..=1, value_delimiter = ',',
          default_missing_value = "0.001,0.002,0.005,0.01,0.02,0.05",
          value_parser = parse_cutoff,
          conflicts_with_all = ["voxelize", "plan", "trees"])]
    cutoffs: Option<Vec<f64>>,
    /// Benchmark the render plan instead: the reduced kernel against the full one on
    /// scenes that do not need a feature (time and device memory, as ratios), on the
    /// seed geometry at the first of --sizes.
    #[arg(long, conflicts_with = "voxelize")]
    plan: bool,
    /// Benchmark the viewer's adaptive resolution instead: for each experiment, a
    /// full-size frame, the scale the viewer picks while both sides move, and a frame at
    /// that scale, against the frame budget.
    #[cfg(feature = "viewer")]
    #[arg(long, value_name = "EXPERIMENT", num_args = 0.., conflicts_with_all = ["voxelize", "plan"])]
    adaptive: Option<Vec<PathBuf>>,
    /// Print one JSON object per measured row (with the benchmark, revision, adapter
    /// and settings in each) instead of the table.
    #[arg(long)]
    json: bool,
    /// The surfaces to compare on each scene (`render.surface`, names as `voxlab
    /// techniques` lists them; a surface a scene cannot have is left out of its rows).
    /// Adds a table of the surfaces' sizes. Default: the voxels only.
    #[arg(long, value_delimiter = ',', value_parser = parse_surface)]
    surfaces: Vec<voxlab::render::Surface>,
    /// Add a generated closed torus of about this many triangles (solid, seed lights
    /// and camera), voxelized at --torus-resolution: a large mesh.
    #[arg(long, value_name = "TRIANGLES",
          value_parser = clap::value_parser!(u32).range(8..=4_000_000))]
    torus: Option<u32>,
    #[arg(long, default_value_t = 256,
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    torus_resolution: u32,
}

#[derive(Args, Debug)]
struct StressArgs {
    /// Directory for stress.md and stress.csv.
    #[arg(long, value_name = "DIR", default_value = "out/stress")]
    out: PathBuf,
    /// Side of the large-cube case (the seed scene at N^3; 0 leaves it out).
    #[arg(long, value_name = "N", default_value_t = 512,
          value_parser = clap::value_parser!(u32).range(0..=1290))]
    cube: u32,
    /// Run only the cases whose name contains this text.
    #[arg(long, value_name = "TEXT")]
    only: Option<String>,
}

/// Overrides shared by every render.
#[derive(Args, Debug)]
struct RenderOpts {
    /// Output image: .png (8-bit, clamped to [0, 1]) or .exr (linear radiance).
    /// Default: out/<experiment name>.png.
    #[arg(long, value_name = "PATH")]
    out: Option<PathBuf>,
    /// Image width in pixels (overrides the experiment's; give --height too).
    #[arg(long, value_name = "W", requires = "height",
          value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    width: Option<u32>,
    /// Image height in pixels (overrides the experiment's; give --width too).
    #[arg(long, value_name = "H", requires = "width",
          value_parser = clap::value_parser!(u32).range(1..=MAX_IMAGE_SIDE as i64))]
    height: Option<u32>,
    /// Accumulate N frames (overrides the experiment's [render] spp). Each frame draws
    /// [render] light_samples new samples per area light; a scene with nothing to
    /// sample renders one frame, the same image.
    #[arg(long, value_name = "N",
          value_parser = clap::value_parser!(u32).range(1..=voxlab::render::MAX_SAMPLES as i64))]
    spp: Option<u32>,
    /// Which tracer renders: the wgpu compute kernel, or the f64 CPU reference.
    /// With `gpu` and no adapter, the CPU reference renders instead (and says so).
    #[arg(long, value_enum, default_value_t = Backend::Gpu)]
    backend: Backend,
    /// After a GPU render, re-render a SIDE x SIDE crop at the image's centre (the whole
    /// image when it is smaller) with the f64 CPU reference, the same samples, and print
    /// how the two differ; fails when they differ by more than the GPU tests allow
    /// (0.5 % of the crop's pixels over 2/255 or a mean difference of 1e-3, displayed
    /// values). A check of the GPU image on any driver.
    #[arg(long, value_name = "SIDE", num_args = 0..=1, default_missing_value = "32",
          value_parser = clap::value_parser!(u32).range(1..=4096))]
    check: Option<u32>,
    /// How a PNG stores radiance: `linear` (the seed's framebuffer, clamped, no gamma) or
    /// `srgb` (the sRGB transfer function, for viewing). An EXR is linear radiance always.
    #[arg(long, value_enum, default_value_t = DisplayArg::Linear)]
    display: DisplayArg,
    /// Multiply radiance by 2^EV before a PNG clamps it.
    #[arg(long, value_name = "EV", default_value_t = 0.0, allow_hyphen_values = true,
          value_parser = parse_exposure)]
    exposure: f64,
    /// Print, for each image, its provenance record (the JSON stored with it) as one
    /// line instead of the report.
    #[arg(long)]
    json: bool,
    /// Report progress (frames on the GPU, rows on the CPU) on standard error as lines,
    /// also when it is not a terminal (on a terminal a render of over a second shows
    /// one line, updated, without asking).
    #[arg(long)]
    progress: bool,
    /// Override any key of the experiment file, e.g. `--set render.light_samples=8`,
    /// `--set features.shadow_model=sdf`, `--set techniques.sdf.softness=0.5`,
    /// `--set lights[0].intensity=200` (repeatable; checked exactly like the file).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<voxlab::experiment::Override>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum DisplayArg {
    Linear,
    Srgb,
}

fn parse_exposure(s: &str) -> Result<f64, String> {
    s.parse::<f64>()
        .ok()
        .filter(|x| x.is_finite() && (-32.0..=32.0).contains(x))
        .ok_or_else(|| format!("`{s}`: exposure must be a number of stops in [-32, 32]"))
}

impl RenderOpts {
    fn display(&self) -> voxlab::render::DisplayTransform {
        voxlab::render::DisplayTransform {
            encoding: match self.display {
                DisplayArg::Linear => voxlab::render::DisplayEncoding::Linear,
                DisplayArg::Srgb => voxlab::render::DisplayEncoding::Srgb,
            },
            exposure: self.exposure,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
enum Backend {
    Gpu,
    Cpu,
}

/// Mesa's Vulkan drivers probe Wayland when the instance is made, and libwayland prints
/// "error: XDG_RUNTIME_DIR is invalid or not set in the environment." (twice per render,
/// in the same form as voxlab's own errors) when the variable is missing, as it is under
/// CI and in containers. voxlab draws no Wayland surface: a private directory stands in.
fn quiet_wayland_probe() {
    let valid = std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| Path::new(&d).is_dir());
    if valid {
        return;
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::{MetadataExt, PermissionsExt};
        let uid = std::fs::metadata("/proc/self")
            .map(|m| m.uid())
            .unwrap_or(0);
        let dir = std::env::temp_dir().join(format!("voxlab-runtime-{uid}"));
        if std::fs::create_dir_all(&dir).is_ok()
            && std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700)).is_ok()
        {
            // SAFETY: called first thing in main, before any other thread exists.
            unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
        }
    }
}

/// A value of an option that takes a name `voxlab techniques` lists: one of `all`.
fn parse_named<T: Copy>(s: &str, all: Vec<T>, name: fn(T) -> &'static str) -> Result<T, String> {
    all.iter().copied().find(|&t| name(t) == s).ok_or_else(|| {
        let names: Vec<_> = all.iter().map(|&t| name(t)).collect();
        format!("must be one of {}", names.join(", "))
    })
}

/// A `--traversal` value: `auto` or a registered traversal's name.
fn parse_traversal(s: &str) -> Result<voxlab::render::Traversal, String> {
    use voxlab::render::Traversal;
    parse_named(s, Traversal::all(), Traversal::name)
}

/// A `--rules` value.
fn parse_rules(s: &str) -> Result<voxlab::render::Rules, String> {
    use voxlab::render::Rules;
    parse_named(s, vec![Rules::Consistent, Rules::Seed], Rules::name)
}

/// A `--surfaces` value: a registered surface's name.
fn parse_surface(s: &str) -> Result<voxlab::render::Surface, String> {
    use voxlab::render::Surface;
    parse_named(s, Surface::all(), Surface::name)
}

fn main() -> ExitCode {
    // Rust ignores SIGPIPE, so printing to a pipe whose reader has gone (`voxlab ... |
    // head`) panicked in println!; with the default action the process ends quietly, as
    // command-line tools do.
    #[cfg(unix)]
    // SAFETY: called first, before any thread exists; SIG_DFL is a valid handler.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    quiet_wayland_probe();
    let cli = Cli::parse();
    // Ctrl-C during a write removes the temporary file instead of leaving it behind.
    if let Err(e) = voxlab::output::remove_temporaries_on_interrupt() {
        eprintln!(
            "warning: no interrupt handler ({e}): an interrupted write may leave a temporary file"
        );
    }
    let result = match cli.command {
        None if cli.render.set.is_empty() => cmd_render(Experiment::seed_default(), &cli.render),
        None => Experiment::from_str_with("", "seed", &cli.render.set)
            .map_err(anyhow::Error::from)
            .and_then(|e| cmd_render(e, &cli.render)),
        Some(Command::Render(args)) => args
            .experiments
            .iter()
            .map(|p| Experiment::load_with(p, &args.opts.set))
            .collect::<Result<Vec<_>, _>>()
            .map_err(anyhow::Error::from)
            .and_then(|es| cmd_render_all(es, &args.opts)),
        Some(Command::Voxelize(args)) => cmd_voxelize(&args),
        Some(Command::Bench(args)) => cmd_bench(&args),
        Some(Command::Ablate(args)) => cmd_ablate(&args),
        Some(Command::Stress(args)) => cmd_stress(&args),
        #[cfg(feature = "viewer")]
        Some(Command::View(args)) => cmd_view(args),
        Some(Command::Info(args)) => voxlab::info::describe(&args.file).map(|t| print!("{t}")),
        Some(Command::Mesh(args)) => cmd_mesh(&args),
        Some(Command::Export(args)) => cmd_export(&args),
        Some(Command::Techniques(args)) => {
            print!(
                "{}",
                if args.json {
                    format!("{:#}\n", voxlab::technique::listing_json())
                } else if args.markdown {
                    voxlab::technique::listing_markdown()
                } else {
                    voxlab::technique::listing_text()
                }
            );
            Ok(())
        }
        Some(Command::Settings(args)) => {
            let table = voxlab::settings::markdown();
            if args.markdown {
                print!("{table}");
            } else {
                // The same rows without the markdown rules.
                for line in table.lines().filter(|l| !l.starts_with("|---")) {
                    let cells: Vec<&str> = line.trim_matches('|').split(" | ").collect();
                    println!("{}", cells.join("  ").replace('`', "").trim());
                }
            }
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// The session `--backend` asks for: on the GPU, or on the CPU reference (saying why)
/// when no adapter opens.
fn open_session(backend: Backend) -> Session {
    let backend = match backend {
        Backend::Cpu => voxlab::Backend::Cpu,
        Backend::Gpu => voxlab::Backend::Gpu,
    };
    let session = Session::or_cpu(backend, |w| eprintln!("warning: {w}"));
    if let Some(t) = session.gpu()
        && t.adapter_info().backend == wgpu::Backend::Gl
        && std::env::var_os("WGPU_BACKEND").is_none()
    {
        // A fresh machine without a Vulkan driver: the README's first command would
        // otherwise be slow without saying why.
        eprintln!(
            "note: no Vulkan driver found, so the GPU kernel runs through OpenGL, which is \
             slower; install Mesa's Vulkan driver (`apt-get install mesa-vulkan-drivers`, \
             which `bash tests/run.sh` does) or a GPU's own"
        );
    }
    session
}

fn cmd_ablate(a: &AblateArgs) -> Result<()> {
    use voxlab::ablate;
    let (e, config, text) = ablate::load_with(&a.experiment, &a.set)?;
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| Path::new("out").join("ablate").join(&e.name));
    let opts = ablate::AblateOptions {
        out_dir: out.clone(),
        cache_dir: a.cache.clone(),
        progress: true,
        log: a.progress,
        watch: None,
        resume: a.resume,
    };
    let report = ablate::run(&e, &config, Some(&text), &opts)?;
    println!("{}", report.table);
    let r = &report.reference;
    println!(
        "reference: {} ({}, key {})",
        r.path.display(),
        if r.reused {
            "reused from the cache"
        } else {
            "rendered"
        },
        &r.key[..16]
    );
    println!("wrote {} files under {}", report.files.len(), out.display());
    Ok(())
}

fn cmd_bench(a: &BenchArgs) -> Result<()> {
    #[cfg(feature = "viewer")]
    if let Some(files) = &a.adaptive {
        let mut gpu = GpuTracer::new().context("the adaptive benchmark needs a GPU adapter")?;
        let default = [
            PathBuf::from("experiments/baseline.toml"),
            PathBuf::from("experiments/area_lights.toml"),
        ];
        let files = if files.is_empty() {
            &default[..]
        } else {
            &files[..]
        };
        let experiments = files
            .iter()
            .map(|f| Experiment::load_with(f, &a.set).map_err(anyhow::Error::from))
            .collect::<Result<Vec<_>>>()?;
        let rows =
            voxlab::viewer::bench::bench_adaptive(&mut gpu, &experiments, a.gpu_runs as usize)?;
        if a.json {
            let head = bench_head("adaptive", Some(&gpu.adapter_summary()), a);
            return print_json_rows(&head, rows.iter().map(|r| r.json()));
        }
        println!(
            "viewer adaptive resolution: one frame per side at full size, and at the scale \
             the viewer settles on while both sides move (its controller fed each frame's \
             time for 8 frames); median of {} runs ({}); GPU: {}\n",
            a.gpu_runs,
            gpu.timer_name(),
            gpu.adapter_summary()
        );
        println!("{}", voxlab::viewer::bench::adaptive_table(&rows));
        return Ok(());
    }
    if let Some(cutoffs) = &a.cutoffs {
        return bench_cutoffs(a, cutoffs);
    }
    if a.plan {
        let mut gpu = GpuTracer::new().context("the plan benchmark needs a GPU adapter")?;
        let n = a.sizes.first().copied().unwrap_or(64);
        let settings = voxlab::RenderSettings {
            width: a.size,
            height: a.size,
            ..Default::default()
        };
        eprintln!("GPU: {}", gpu.adapter_summary());
        let scenes = voxlab::bench::plan_scenes(n)?;
        let rows = voxlab::bench::bench_plans(&mut gpu, &scenes, &settings, a.gpu_runs as usize)?;
        if a.json {
            let head = bench_head("plan", Some(&gpu.adapter_summary()), a);
            return print_json_rows(&head, rows.iter().map(|r| r.json()));
        }
        println!(
            "render plan: reduced kernel against the full one, {}x{}, depth {}/{}, median of {} runs; GPU: {}\n",
            a.size,
            a.size,
            settings.max_reflection_depth,
            settings.max_refraction_depth,
            a.gpu_runs,
            gpu.adapter_summary()
        );
        println!("{}", voxlab::bench::plan_table(&rows));
        return Ok(());
    }
    if a.trees {
        let mut rows = Vec::new();
        for &n in &a.sizes {
            let scene = voxlab::scene::seed_scene(n)?;
            let r = voxlab::bench::bench_trees(&format!("seed {n}^3"), &scene, a.size);
            for row in &r {
                eprintln!(
                    "  {} {}: {:.2} steps/ray, {:.4} bytes/voxel",
                    row.scene, row.structure, row.steps_per_ray, row.bytes_per_voxel
                );
            }
            rows.extend(r);
        }
        println!(
            "sparse structures on the CPU walk (f64, one thread): primary rays at {0}x{0} \
             and a min-kt shadow ray from each hit to each light\n",
            a.size
        );
        println!("{}", voxlab::bench::trees_table(&rows));
        return Ok(());
    }
    if let Some(sizes) = &a.surface_fidelity {
        use voxlab::surface::fidelity;
        let rows = fidelity::fidelity_rows(sizes, |r| {
            eprintln!(
                "  {} {}^3, {}: Chamfer {:.4}",
                r.shape, r.size, r.method, r.fidelity.chamfer
            )
        });
        if a.json {
            let head = bench_head("surface-fidelity", None, a);
            return print_json_rows(&head, rows.iter().map(|r| r.json()));
        }
        println!(
            "surface fidelity: distances to the analytic shape the voxels came from (voxel \
             centres inside), in voxels\n"
        );
        println!("{}", fidelity::fidelity_table(&rows));
        return Ok(());
    }
    if let Some(mesh_path) = &a.voxelize {
        let bunny = voxlab::scene::load_mesh(mesh_path)?;
        // 250 x 100 quads: exactly 50,000 triangles.
        let torus = voxlab::bench::torus_mesh(250, 100);
        let n = a.voxelize_resolution;
        let mut rows = Vec::new();
        for (name, mesh) in [
            (mesh_path.display().to_string(), &bunny),
            ("torus".to_string(), &torus),
        ] {
            let row = voxlab::bench::bench_voxelize(&name, mesh, n, 3)?;
            eprintln!("  {name} at {n}: {:.1} ms", row.median.as_secs_f64() * 1e3);
            rows.push(row);
        }
        if a.json {
            let head = bench_head("voxelize", None, a);
            return print_json_rows(&head, rows.iter().map(|r| r.json()));
        }
        println!("voxelization (conservative surface + interior fill), median of 3 runs\n");
        println!("{}", voxlab::bench::voxelize_table(&rows));
        return Ok(());
    }
    let mut opts = voxlab::bench::BenchOptions {
        sizes: a.sizes.clone(),
        gpu_runs: a.gpu_runs as usize,
        cpu_runs: a.cpu_runs as usize,
        cpu: !a.no_cpu,
        traversals: if a.traversal.is_empty() {
            voxlab::render::Traversal::walks()
        } else {
            a.traversal.clone()
        },
        rules: if a.rules.is_empty() {
            vec![
                voxlab::render::Rules::Consistent,
                voxlab::render::Rules::Seed,
            ]
        } else {
            a.rules.clone()
        },
        experiments: a
            .experiments
            .iter()
            .map(|f| Experiment::load_with(f, &a.set).map_err(anyhow::Error::from))
            .collect::<Result<Vec<_>>>()?,
        surfaces: if a.surfaces.is_empty() {
            vec![voxlab::render::Surface::default()]
        } else {
            a.surfaces.clone()
        },
        ..Default::default()
    };
    if let Some(n) = a.torus {
        // About 2.5 rings to a segment (the major circle is the longer), two triangles
        // a quad.
        let segments = ((n as f64 / 5.0).sqrt().round() as u32).max(2);
        let rings = (n / (2 * segments)).max(3);
        let mesh = voxlab::bench::torus_mesh(rings, segments);
        let name = format!("torus ({} triangles)", mesh.triangles.len());
        let solid = voxlab::scene::seed_palette()[voxlab::scene::seed_ids::SOLID as usize].clone();
        let scene = voxlab::scene::mesh::seed_lit_scene(&mesh, a.torus_resolution, solid)
            .map_err(|e| anyhow::anyhow!("the torus: {e}"))?;
        opts.scenes.push((name, scene));
    }
    opts.settings.width = a.size;
    opts.settings.height = a.size;
    let adapter = GpuTracer::new()
        .context("the benchmark compares GPU and CPU and needs a GPU adapter")?
        .adapter_summary();
    eprintln!(
        "GPU: {adapter}\nCPU: {}\nhost: {}",
        voxlab::cpu::backend_summary(),
        voxlab::cpu::host_summary()
    );
    let rows = voxlab::bench::run(&opts, |r| {
        eprintln!(
            "  {} {} {} {}: {:.1} ms/frame, {:.2} Mrays/s, {:.1} Msteps/s",
            r.scene,
            r.surface,
            r.backend,
            r.traversal,
            r.ms(),
            r.mrays_per_s(),
            r.msteps_per_s()
        )
    })?;
    let surfaces = voxlab::bench::surface_rows(&opts)?;
    if a.json {
        let mut head = bench_head("seed", Some(&adapter), a);
        head["cpu"] = voxlab::cpu::backend_summary().into();
        head["host"] = voxlab::cpu::host_summary().into();
        print_json_rows(&head, rows.iter().map(|r| r.json()))?;
        let head = bench_head("surfaces", None, a);
        print_json_rows(&head, surfaces.iter().map(|r| r.json()))?;
    } else {
        println!("{}", voxlab::bench::table(&rows, &adapter, &opts.settings));
        if !surfaces.is_empty() {
            println!("{}", voxlab::bench::surface_table(&surfaces));
        }
    }
    // Figures of a walk that renders another image than the default walk's compare
    // nothing: printed above, then refused.
    let wrong = voxlab::bench::walk_disagreements(&rows);
    if !wrong.is_empty() {
        bail!("{}", wrong.join("\n"));
    }
    Ok(())
}

/// `voxlab bench --cutoffs`.
fn bench_cutoffs(a: &BenchArgs, cutoffs: &[f64]) -> Result<()> {
    let mut gpu = GpuTracer::new().context("the cutoff benchmark needs a GPU adapter")?;
    let files = if a.experiments.is_empty() {
        let mut files: Vec<PathBuf> = std::fs::read_dir("experiments")
            .context("reading experiments/ (run from the repository, or name --experiments)")?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        files
    } else {
        a.experiments.clone()
    };
    let experiments = files
        .iter()
        .map(|f| Experiment::load_with(f, &a.set).map_err(anyhow::Error::from))
        .collect::<Result<Vec<_>>>()?;
    eprintln!("GPU: {}", gpu.adapter_summary());
    let rows = voxlab::bench::cutoff::bench_cutoffs(
        &mut gpu,
        &experiments,
        cutoffs,
        a.size,
        a.gpu_runs as usize,
        |r| {
            eprintln!(
                "  {} at {}: {:.1} % of the rays, max {} levels",
                r.experiment,
                r.cutoff,
                100.0 * r.rays as f64 / r.exact_rays.max(1) as f64,
                r.max_levels
            )
        },
    )?;
    if a.json {
        let head = bench_head("cutoffs", Some(&gpu.adapter_summary()), a);
        return print_json_rows(&head, rows.iter().map(|r| r.json()));
    }
    println!(
        "ray cutoff: each experiment at {0}x{0}, one frame, against its exact tree \
         (ray_cutoff = 0); times are medians of {1} interleaved runs ({2}); GPU: {3}\n",
        a.size,
        a.gpu_runs,
        gpu.timer_name(),
        gpu.adapter_summary()
    );
    println!("{}", voxlab::bench::cutoff::cutoff_table(&rows));
    match voxlab::bench::cutoff::largest_within(&rows, cutoffs, 1) {
        Some(c) => {
            println!("largest cutoff within 1/255 of the exact tree on every experiment: {c}")
        }
        None => println!("no cutoff measured stays within 1/255 on every experiment"),
    }
    Ok(())
}

fn parse_cutoff(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("{e}"))?;
    if (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!("{v} is outside [0, 1] (render.ray_cutoff's range)"))
    }
}

/// What every `bench --json` row carries: which benchmark, the revision, the adapter and
/// the options that shape the figures.
fn bench_head(bench: &str, adapter: Option<&str>, a: &BenchArgs) -> serde_json::Value {
    serde_json::json!({
        "bench": bench,
        "voxlab": env!("CARGO_PKG_VERSION"),
        "revision": voxlab::revision::revision(),
        "adapter": adapter,
        "image_side": a.size,
        "gpu_runs": a.gpu_runs,
        "cpu_runs": a.cpu_runs,
    })
}

/// Each row merged into `head`, one JSON object per line.
fn print_json_rows(
    head: &serde_json::Value,
    rows: impl Iterator<Item = serde_json::Value>,
) -> Result<()> {
    for row in rows {
        let mut line = head.clone();
        if let (Some(l), serde_json::Value::Object(r)) = (line.as_object_mut(), row) {
            l.extend(r);
        }
        println!("{line}");
    }
    Ok(())
}

fn cmd_stress(a: &StressArgs) -> Result<()> {
    // A missing adapter is reported in every row (and fails them), not hidden.
    let mut gpu = match GpuTracer::new() {
        Ok(t) => Some(t),
        Err(e) => {
            eprintln!("warning: no GPU adapter ({e:#}); every case will fail its GPU half");
            None
        }
    };
    let adapter = gpu
        .as_ref()
        .map(|t| t.adapter_summary())
        .unwrap_or_else(|| "none".to_string());
    let opts = voxlab::stress::SuiteOptions {
        max_grid_side: gpu.as_ref().map_or(4096, |t| t.max_grid_side()),
        cube: (a.cube > 0).then_some(a.cube),
    };
    let mut cases = voxlab::stress::cases(&opts)?;
    if let Some(f) = &a.only {
        cases.retain(|c| c.name.contains(f.as_str()));
        anyhow::ensure!(!cases.is_empty(), "no stress case name contains {f:?}");
    }
    eprintln!("GPU: {adapter}\nCPU: {}", voxlab::cpu::backend_summary());
    let rows = voxlab::stress::run(gpu.as_mut(), &cases, |r| {
        eprintln!("  {}: {:?}", r.name, r.verdict())
    });
    let table = voxlab::stress::markdown(&rows, &adapter);
    println!("{table}");
    let record = voxlab::output::record(
        "voxlab stress",
        &[],
        serde_json::json!({
            "gpu": adapter,
            "cpu": voxlab::cpu::backend_summary(),
            "host": voxlab::cpu::host_summary(),
            "cube": a.cube,
            "only": a.only,
            "cases": rows.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
        }),
    );
    let (md, csv) = voxlab::stress::write_tables(&a.out, &rows, &adapter, &record)?;
    println!(
        "wrote {} and {} (records: .json beside each)",
        md.display(),
        csv.display()
    );
    let failed = rows
        .iter()
        .filter(|r| matches!(r.verdict(), voxlab::stress::Verdict::Fail(_)))
        .count();
    anyhow::ensure!(failed == 0, "{failed} stress case(s) failed");
    Ok(())
}

fn cmd_export(a: &ExportArgs) -> Result<()> {
    let ExportTarget::Mitsuba = a.to;
    let (e, text) = match &a.experiment {
        Some(p) => {
            let text =
                voxlab::experiment::apply_overrides(&voxlab::experiment::read_text(p)?, &a.set)?;
            (Experiment::load_with(p, &a.set)?, text)
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

fn cmd_mesh(a: &MeshArgs) -> Result<()> {
    // Refused before any work: the format and the directory.
    let ext = a
        .out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if !matches!(ext.as_deref(), Some("obj" | "ply")) {
        bail!(
            "--out {}: the output of mesh must end in .obj or .ply",
            a.out.display()
        );
    }
    output_dir_exists(&a.out)?;
    // Never over what the experiment reads (its own mesh and MTL, the file itself).
    if let Some(p) = &a.experiment {
        let text = voxlab::experiment::apply_overrides(&voxlab::experiment::read_text(p)?, &a.set)?;
        let inputs = voxlab::experiment::write::input_files(&text, p);
        let mut outputs = vec![a.out.clone(), voxlab::output::sidecar_path(&a.out)];
        if ext.as_deref() == Some("obj") {
            outputs.push(a.out.with_extension("mtl"));
        }
        if let Some((o, i)) = voxlab::experiment::write::overwrites(&outputs, &inputs) {
            bail!(
                "--out {}: mesh would write {}, which is the experiment's input {}; \
                 mesh never overwrites its input",
                a.out.display(),
                o.display(),
                i.display()
            );
        }
    }
    let e = match &a.experiment {
        Some(p) => Experiment::load_with(p, &a.set)?,
        None => Experiment::from_str_with("", "seed", &a.set)?,
    };
    let start = Instant::now();
    let mesh = voxlab::surface::extract(&e.scene.grid, a.relax)?;
    let took = start.elapsed();
    voxlab::surface::write_mesh(&mesh, &e.scene.materials, &a.out)?;
    let d = e.scene.grid.dims();
    // What made the mesh, beside it: the experiment (its text with the overrides, every
    // file it reads, hashed), the build, the relaxation.
    let (text, inputs) = match &a.experiment {
        Some(p) => {
            let text =
                voxlab::experiment::apply_overrides(&voxlab::experiment::read_text(p)?, &a.set)?;
            let inputs = voxlab::experiment::write::input_files(&text, p);
            (text, inputs)
        }
        None => (String::new(), Vec::new()),
    };
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let write_record = voxlab::output::write_sidecar(
        &a.out,
        &voxlab::output::record(
            "voxlab mesh",
            &inputs,
            serde_json::json!({
                "experiment": e.name,
                "experiment_text": text,
                "overrides": a.set.iter().map(|o| o.to_string()).collect::<Vec<_>>(),
                "relax": a.relax,
                "dims": [d.x, d.y, d.z],
                "vertices": mesh.positions.len(),
                "triangles": mesh.triangles.len(),
            }),
        ),
    );
    if let Err(err) = write_record {
        // The mesh went with its record: its MTL too.
        if ext.as_deref() == Some("obj") {
            let _ = std::fs::remove_file(a.out.with_extension("mtl"));
        }
        return Err(err.into());
    }
    println!(
        "{}: {}x{}x{} voxels -> {} vertices, {} triangles in {} material(s), relaxed {} times, \
         {:.1} ms",
        e.name,
        d.x,
        d.y,
        d.z,
        mesh.positions.len(),
        mesh.triangles.len(),
        mesh.materials().len(),
        a.relax,
        took.as_secs_f64() * 1e3
    );
    for m in mesh.materials() {
        let count = mesh.triangle_material.iter().filter(|&&k| k == m).count();
        // "closed" as trimesh and open3d mean it: watertight, consistently wound, edge-
        // and vertex-manifold, a positive volume.
        println!(
            "  {m:>3} {:<28} {count:>9} triangles, {}",
            e.scene.materials[m as usize].name,
            mesh.manifold_report(Some(m))
        );
    }
    println!(
        "wrote {} (record: {})",
        a.out.display(),
        voxlab::output::sidecar_path(&a.out).display()
    );
    Ok(())
}

fn cmd_voxelize(a: &VoxelizeArgs) -> Result<()> {
    use voxlab::scene::{VoxelizeOptions, voxelize_mesh, write_vox};
    // The output is a .vox and never the input: checked before the work is done.
    let is_vox = a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("vox"));
    if !is_vox {
        bail!(
            "--out {}: the output of voxelize is a MagicaVoxel file, so its name must end in .vox",
            a.out.display()
        );
    }
    let same = |x: &Path, y: &Path| match (x.canonicalize(), y.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    };
    if same(&a.out, &a.mesh) {
        bail!(
            "--out {} is the input mesh {}: voxelize never overwrites its input",
            a.out.display(),
            a.mesh.display()
        );
    }
    let sidecar = voxlab::output::sidecar_path(&a.out);
    if same(&sidecar, &a.mesh) {
        bail!(
            "--out {}: its record {} would be the input mesh {}: voxelize never overwrites its input",
            a.out.display(),
            sidecar.display(),
            a.mesh.display()
        );
    }
    output_dir_exists(&a.out)?;
    let start = Instant::now();
    let options = VoxelizeOptions::count(a.resolution);
    // Memory for the whole command, before the work: writing a .vox holds the grid
    // dense (a byte a voxel), its voxels as MagicaVoxel records (4 bytes each, every
    // voxel solid at worst) and the file's bytes (as many again).
    let mesh = voxlab::scene::load_mesh(&a.mesh)?;
    let (dims, ..) = voxlab::scene::mesh::voxelize_layout(&mesh, &options)
        .map_err(|k| voxlab::scene::LoadError::new(&a.mesh, k))?;
    drop(mesh);
    let voxels = dims.x as u64 * dims.y as u64 * dims.z as u64;
    voxlab::input::check_memory(
        voxels * 9,
        &format!(
            "writing a .vox of {}x{}x{} voxels (resolution {})",
            dims.x, dims.y, dims.z, a.resolution
        ),
    )
    .map_err(|e| anyhow::anyhow!("{}: {e}; choose a coarser resolution", a.mesh.display()))?;
    let v = voxelize_mesh(&a.mesh, &options)?;
    for w in &v.warnings {
        eprintln!("warning: {w}");
    }
    write_vox(&a.out, &v.grid, &v.materials)?;
    let d = v.grid.dims();
    // What made the file, beside it: the mesh's hash, the build, the settings.
    voxlab::output::write_sidecar(
        &a.out,
        &voxlab::output::record(
            "voxlab voxelize",
            &[&a.mesh],
            serde_json::json!({
                "resolution": a.resolution,
                "dims": [d.x, d.y, d.z],
                "voxel_size": v.grid.voxel_size(),
                "triangles": v.triangle_count,
                "surface_voxels": v.shell_voxels,
                "filled_voxels": v.interior_voxels,
                "closed": v.closed,
            }),
        ),
    )?;
    println!(
        "{}: {} triangles -> {}x{}x{} voxels of size {} ({} on the surface, {} filled{}), \
         {} materials, {:.2} s; wrote {}",
        a.mesh.display(),
        v.triangle_count,
        d.x,
        d.y,
        d.z,
        v.grid.voxel_size(),
        v.shell_voxels,
        v.interior_voxels,
        if v.closed { "" } else { ": open mesh" },
        v.materials.len() - 1,
        start.elapsed().as_secs_f64(),
        a.out.display()
    );
    println!("record:     {}", sidecar.display());
    Ok(())
}

/// An explicit output path's directory must exist: a mistyped directory is an error,
/// not a new tree. Only voxlab's own `out/` (the default outputs' directory, which the
/// README's commands name) is created.
fn output_dir_exists(out: &Path) -> Result<()> {
    match out.parent() {
        Some(dir) if dir == Path::new("out") => {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))
        }
        Some(dir) if !dir.as_os_str().is_empty() && !dir.is_dir() => bail!(
            "--out {}: the directory {} does not exist (voxlab creates only its default \
             out/; create it first)",
            out.display(),
            dir.display()
        ),
        _ => Ok(()),
    }
}

fn cmd_render(e: Experiment, opts: &RenderOpts) -> Result<()> {
    cmd_render_all(vec![e], opts)
}

/// Renders each experiment in turn on one tracer (one device, its pipelines and uploads
/// reused), each to `out/<name>.png` unless `--out` names the one output.
fn cmd_render_all(mut experiments: Vec<Experiment>, opts: &RenderOpts) -> Result<()> {
    if experiments.len() > 1 && opts.out.is_some() {
        bail!("--out names one output; with several experiments each goes to out/<name>.png");
    }
    if let Some(out) = &opts.out {
        output_dir_exists(out)?;
    }
    let mut outs = Vec::new();
    for e in &mut experiments {
        if let (Some(w), Some(h)) = (opts.width, opts.height) {
            e.settings.width = w;
            e.settings.height = h;
        }
        if let Some(n) = opts.spp {
            e.settings.spp = n;
        }
        let out = opts
            .out
            .clone()
            .unwrap_or_else(|| Path::new("out").join(format!("{}.png", e.name)));
        // Fail on a bad or repeated output name before spending any render on it.
        OutputFormat::from_path(&out)?;
        if outs.contains(&out) {
            bail!(
                "two experiments are named {:?}: both would write {} (give one a `name`)",
                e.name,
                out.display()
            );
        }
        outs.push(out);
    }
    let mut session = open_session(opts.backend);
    for (i, (e, out)) in experiments.iter().zip(&outs).enumerate() {
        if i > 0 && !opts.json {
            println!();
        }
        render_one(&mut session, e, out, opts)?;
    }
    Ok(())
}

/// Prints a line of the human-readable report, unless `--json` asked for the record alone.
macro_rules! say {
    ($opts:expr, $($arg:tt)*) => {
        if !$opts.json {
            println!($($arg)*);
        }
    };
}

fn render_one(session: &mut Session, e: &Experiment, out: &Path, opts: &RenderOpts) -> Result<()> {
    let source = match &e.source_path {
        Some(p) => p.display().to_string(),
        None => "built-in".to_string(),
    };
    say!(opts, "experiment: {} ({source})", e.name);
    say!(opts, "backend:    {}", session.label());
    let image = session.render_with_progress(e, opts.progress)?;
    // Plan's Display starts with "plan:" and lists what was left out on further lines.
    say!(opts, "{}", image.plan);
    say!(
        opts,
        "image:      {}x{}",
        e.settings.width,
        e.settings.height
    );
    let frames = image.frames;
    let trace_ms = image.trace_time.as_secs_f64() * 1e3;
    say!(
        opts,
        "time:       {:.3} ms per frame (trace, {}), {} frame{} in {:.3} ms, {:.3} ms wall",
        trace_ms / frames as f64,
        image.timer,
        frames,
        if frames == 1 { "" } else { "s" },
        trace_ms,
        image.wall_time.as_secs_f64() * 1e3
    );
    // What the trace reads is prepared before it, so the trace time leaves it out.
    if !image.setup_time.is_zero() {
        say!(
            opts,
            "setup:      {:.3} ms (walk data, triangle surfaces, cone pyramids: not in the trace time)",
            image.setup_time.as_secs_f64() * 1e3
        );
    }
    if let Some(m) = session.gpu().and_then(|t| t.last_memory()) {
        say!(opts, "memory:     {m} on the device");
    }
    let s = image.stats;
    if s.total_rays() > 0 {
        say!(
            opts,
            "rays:       {} ({} primary, {} secondary, {} shadow), {} voxel steps",
            s.total_rays(),
            s.primary,
            s.secondary,
            s.shadow,
            s.voxel_steps
        );
    }
    if !image.frame.all_finite() {
        eprintln!("warning: the image holds non-finite values (NaN or inf)");
    }
    let record = image.provenance(e, &opts.set, opts.display(), Some(out))?;
    image.save(out, &record, opts.display())?;
    say!(
        opts,
        "output:     {} (provenance: its iTXt chunk `voxlab` and {}.json)",
        out.display(),
        out.display()
    );
    if opts.json {
        println!("{record}");
    }
    if let Some(side) = opts.check {
        check_against_cpu(e, &image.frame, side, session)?;
    }
    Ok(())
}

/// `render --check`: the centre crop of `frame` against the CPU reference's.
fn check_against_cpu(e: &Experiment, frame: &Frame, side: u32, session: &Session) -> Result<()> {
    let plan = voxlab::plan::Plan::new(&e.scene, &e.settings);
    if plan.ray_cutoff {
        let bounds = voxlab::ray_cutoff::Bounds::new(&e.scene, &e.settings, &plan);
        println!("check:      {bounds}");
    }
    if session.gpu().is_none() {
        println!("check:      the image is the CPU reference's own; nothing to check");
        return Ok(());
    }
    let (w, h) = (frame.width, frame.height);
    let (cw, ch) = (side.min(w), side.min(h));
    let (x0, y0) = ((w - cw) / 2, (h - ch) / 2);
    let reference = voxlab::cpu::render_region(&e.scene, &e.settings, x0..x0 + cw, y0..y0 + ch);
    let mut crop = Frame::new(cw, ch);
    for y in 0..ch {
        for x in 0..cw {
            crop.pixels[(y * cw + x) as usize] = frame.get(x0 + x, y0 + y);
        }
    }
    let d = voxlab::metrics::compare(
        &crop,
        &reference.frame,
        voxlab::metrics::Domain::Display,
        2.0 / 255.0,
    )
    .expect("same size");
    println!(
        "check:      pixels ({x0}, {y0})..({}, {}) against the CPU reference (f64, same \
         samples, {:.1} s): {d}",
        x0 + cw,
        y0 + ch,
        reference.trace_time.as_secs_f64()
    );
    if d.fraction_over() < 0.005 && d.mean_abs < 1e-3 && crop.all_finite() {
        println!("check:      agrees within the GPU tests' tolerance");
        Ok(())
    } else {
        bail!(
            "the GPU image differs from the CPU reference by more than the GPU tests allow \
             (under 0.5 % of pixels over 2/255 and a mean below 1e-3): {d}"
        )
    }
}
