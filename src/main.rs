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
use voxlab::frame::Frame;
use voxlab::gpu::GpuTracer;
use voxlab::output::OutputFormat;
use voxlab::render::MAX_IMAGE_SIDE;

mod commands;
use commands::ablate::{AblateArgs, cmd_ablate};
use commands::bench::{BenchArgs, cmd_bench};
use commands::export::{ExportArgs, cmd_export};
use commands::mesh::{MeshArgs, VoxelizeArgs, cmd_mesh, cmd_voxelize};
use commands::stress::{StressArgs, cmd_stress};

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
    /// run (median ms per frame, wall ms per call of a warm tracer, counted rays and voxel
    /// steps per second, GPU/CPU ratio).
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
    #[arg(long, conflicts_with = "json")]
    markdown: bool,
    /// Print one JSON array of records (key, type, default, min, max, range, unit, doc).
    #[arg(long)]
    json: bool,
}

#[cfg(feature = "viewer")]
#[derive(Args, Debug)]
struct ViewArgs {
    /// The experiment file (TOML). Default: the seed scene.
    experiment: Option<PathBuf>,
    /// Features of the left side, comma-separated: a shadow model (hard, area, cone or a
    /// plug-in: `voxlab techniques`), min-kt, beer-lambert, a reconstruction (none,
    /// atrous), ao, indirect, samples=N (default: the experiment's own).
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
    if let Some(dir) = &args.save_dir {
        // Before the window opens and the frames accumulate, not at the save.
        voxlab::output::check_directory_output(
            "--save-dir",
            dir,
            "the viewer saves both sides' images and records and a window capture into a \
             directory",
        )
        .map_err(anyhow::Error::msg)?;
    }
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
    let ev = s
        .parse::<f64>()
        .map_err(|_| format!("`{s}`: exposure must be a number of stops"))?;
    voxlab::frame::DisplayTransform::check_exposure(ev)
}

impl RenderOpts {
    fn display(&self) -> voxlab::frame::DisplayTransform {
        voxlab::frame::DisplayTransform {
            encoding: match self.display {
                DisplayArg::Linear => voxlab::frame::DisplayEncoding::Linear,
                DisplayArg::Srgb => voxlab::frame::DisplayEncoding::Srgb,
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
            if args.json {
                println!("{:#}", voxlab::settings::listing_json());
            } else if args.markdown {
                print!("{table}");
            } else {
                // The same rows without the markdown rules, in columns (the last, what a
                // key does, as long as it is).
                let rows: Vec<Vec<String>> = table
                    .lines()
                    .filter(|l| !l.starts_with("|---"))
                    .map(|l| {
                        l.trim()
                            .trim_matches('|')
                            .split(" | ")
                            .map(|c| c.trim().replace('`', ""))
                            .collect()
                    })
                    .collect();
                let columns = rows.iter().map(Vec::len).max().unwrap_or(0);
                let widths: Vec<usize> = (0..columns)
                    .map(|c| {
                        rows.iter()
                            .filter_map(|r| r.get(c))
                            .map(|v| v.chars().count())
                            .max()
                            .unwrap_or(0)
                    })
                    .collect();
                for row in &rows {
                    let mut line = String::new();
                    for (c, cell) in row.iter().enumerate() {
                        if c + 1 < row.len() {
                            line += &format!("{cell:<w$}  ", w = widths[c]);
                        } else {
                            line += cell;
                        }
                    }
                    println!("{}", line.trim_end());
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

/// An explicit output path's directory must exist: a mistyped directory is an error,
/// not a new tree. Only voxlab's own `out/` (the default outputs' directory, which the
/// README's commands name) is created, by the write (which removes it again if it
/// fails).
fn output_dir_exists(out: &Path) -> Result<()> {
    match out.parent() {
        Some(dir) if dir == Path::new("out") && dir.exists() && !dir.is_dir() => {
            bail!("--out {}: out is a file, not a directory", out.display())
        }
        Some(dir) if dir == Path::new("out") => Ok(()),
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
    match &opts.out {
        Some(out) => output_dir_exists(out)?,
        // Refused before any render, not at the first write.
        None if Path::new("out").exists() && !Path::new("out").is_dir() => bail!(
            "out is a file, and without --out each image goes to out/<name>.png: move it \
             or give --out"
        ),
        None => {}
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
    for w in &image.plan.warnings {
        eprintln!("warning: {w}");
    }
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
    if e.settings.path_frames > 1 {
        say!(
            opts,
            "path:       {} frames, the camera turning {} degrees per frame; the image, time and rays are the last frame's ({})",
            e.settings.path_frames,
            e.settings.orbit_deg,
            if e.settings.features.reconstruction.temporal {
                format!(
                    "the {} before it give its reconstruction's history",
                    e.settings.path_frames - 1
                )
            } else {
                "of the frames before it only the last is rendered, for the flicker: no temporal reconstruction".to_string()
            }
        );
    }
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
    let Some(gpu) = session.gpu() else {
        println!("check:      the image is the CPU reference's own; nothing to check");
        return Ok(());
    };
    let (w, h) = (frame.width, frame.height);
    let (cw, ch) = (side.min(w), side.min(h));
    let (x0, y0) = ((w - cw) / 2, (h - ch) / 2);
    let cut = |frame: &Frame| {
        let mut crop = Frame::new(cw, ch);
        for y in 0..ch {
            for x in 0..cw {
                crop.pixels[(y * cw + x) as usize] = frame.get(x0 + x, y0 + y);
            }
        }
        crop
    };
    let path_history = e.settings.path_frames > 1 && e.settings.features.reconstruction.temporal;
    let reference = if path_history {
        // A temporal reconstruction's image is its path's last frame, filtered with the
        // history of the frames before it, reprojected from anywhere in the image: the
        // reference renders that whole path whole (a CPU session, as a CPU render of the
        // experiment does), and the crop is cut from it. A crop alone, without the
        // history, drew 22 % of experiments/reconstruction.toml apart at 24x24.
        println!(
            "check:      the reference renders the whole path ({} frames of {}x{}): the \
             reconstruction's history reads the whole image",
            e.settings.path_frames, w, h
        );
        let image = Session::cpu().render(e)?;
        voxlab::frame::RenderOutput {
            frame: cut(&image.frame),
            stats: image.stats,
            trace_time: image.trace_time,
            setup_time: image.setup_time,
            walk_data: None,
        }
    } else {
        // The walk's data the GPU tracer built for the render, where the reference's is
        // the same build (the same budget), is walked rather than built again.
        voxlab::cpu::render_region_reusing(
            &e.scene,
            &e.settings,
            x0..x0 + cw,
            y0..y0 + ch,
            &|key| gpu.kept_walk_data(key),
        )
    };
    let crop = cut(frame);
    let d = voxlab::metrics::compare(
        &crop,
        &reference.frame,
        voxlab::metrics::Domain::Display,
        2.0 / 255.0,
    )
    .expect("same size");
    println!(
        "check:      pixels ({x0}, {y0})..({}, {}) against the CPU reference (f64, same \
         samples, {:.1} s{}): {d}",
        x0 + cw,
        y0 + ch,
        reference.trace_time.as_secs_f64(),
        if reference.setup_time.as_secs_f64() >= 0.05 {
            format!(" and {:.1} s of setup", reference.setup_time.as_secs_f64())
        } else {
            String::new()
        }
    );
    // Radiance past f32's range is an infinity in both images (the reference rounds its
    // f64 sums to f32 once): the same infinities agree, a NaN or an infinity of one
    // alone never does (the displayed values, clamped, would not tell).
    let apart: usize = crop
        .pixels
        .iter()
        .zip(&reference.frame.pixels)
        .filter(|(a, b)| (0..3).any(|c| !(a[c].is_finite() && b[c].is_finite() || a[c] == b[c])))
        .count();
    if d.fraction_over() < 0.005 && d.mean_abs < 1e-3 && apart == 0 {
        println!("check:      agrees within the GPU tests' tolerance");
        return Ok(());
    }
    // Where the rays of a pixel pass through voxel edges or corners, f32 and f64 may
    // pick either face and both are right: the stress suite's test of which pixels the
    // reference itself moves under a turn of the rays tells those apart (it traces
    // pixel centres one ray a frame, so not under a pixel filter or a filter of the
    // image).
    let conditioning = !plan.pixel_filter && plan.reconstruction.cpu.is_none() && !path_history;
    if conditioning && apart == 0 {
        // The stress suite's turn moves a ray by about 1e-4 voxels at its scenes'
        // distances (a few grid sides); a farther eye turns less, so that the band
        // around the edges stays as narrow and a real error there is not excused.
        let g = &e.scene.grid;
        let side = g.dims().max_element() as f64;
        let distance = (g.to_local(e.scene.camera.eye()) - 0.5 * g.dims().as_dvec3()).length();
        let turn = voxlab::stress::CONDITION_TURN * (2.0 * side / distance).min(1.0);
        let unstable = voxlab::stress::ill_conditioned_region(
            &e.scene,
            &e.settings,
            (x0..x0 + cw, y0..y0 + ch),
            &reference.frame,
            turn,
        );
        let ill = unstable.iter().filter(|&&u| u).count();
        let over = voxlab::stress::over_well_conditioned(&crop, &reference.frame, &unstable);
        let well = unstable.len() - ill;
        println!(
            "check:      {ill} of the {} pixels are ill-conditioned (the reference itself \
             moves past 2/255 when the primary rays turn by {turn:.1e} rad: rays through \
             voxel edges or corners); {over} of the other {well} are over 2/255",
            unstable.len(),
        );
        if (over as f64) < 0.005 * well as f64 {
            println!(
                "check:      agrees within the stress suite's tolerance (under 0.5 % of the \
                 well-conditioned pixels over 2/255)"
            );
            return Ok(());
        }
    }
    if apart > 0 {
        // The displayed values clamp an infinity to 1 and a NaN is no value: the figures
        // above cannot show it, so say what failed.
        bail!(
            "{apart} of the {} pixels checked are not finite in one image where the other \
             has a number or another non-finite value (a NaN, or radiance past what the \
             kernel's f32 holds, about 3.4e38, which the f64 reference sums before it \
             rounds once): {d}",
            crop.pixels.len()
        );
    }
    bail!(
        "the GPU image differs from the CPU reference by more than the GPU tests allow \
         (under 0.5 % of pixels over 2/255 and a mean below 1e-3): {d}"
    )
}
