//! `voxlab bench`: its arguments and the dispatch to the benchmarks in `voxlab::bench`
//! (and the viewer's), printed as tables or JSON rows.

// The binary's shared argument parsers and imports (main.rs).
use crate::*;

#[derive(Args, Debug)]
pub(crate) struct BenchArgs {
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
    /// Measure the reconstructions instead (`[features] reconstruction`): the first of
    /// --experiments (default experiments/mitsuba/rect_blocks.toml) at each of these
    /// square sizes, one frame, without a reconstruction and with each registered one:
    /// frame time and the filter's passes alone.
    #[arg(long, value_name = "SIZES", num_args = 0..=1, value_delimiter = ',',
          default_missing_value = "512,1024",
          value_parser = clap::value_parser!(u32).range(8..=4096),
          conflicts_with_all = ["voxelize", "plan", "trees", "cutoffs"])]
    reconstruction: Option<Vec<u32>>,
    /// Measure how evenly the kernel's SIMD lanes share the work instead: each
    /// experiment (--experiments, default experiments/baseline.toml and
    /// experiments/seed_rules.toml) at --size on the CPU reference, the rays each pixel
    /// traces and the voxel steps it walks, and what the software driver's vectors (4x2
    /// pixel blocks) run for them.
    #[arg(long, conflicts_with_all = ["voxelize", "plan", "trees", "cutoffs", "reconstruction"])]
    lanes: bool,
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

pub(crate) fn cmd_bench(a: &BenchArgs) -> Result<()> {
    #[cfg(feature = "viewer")]
    if let Some(files) = &a.adaptive {
        return bench_adaptive(a, files);
    }
    if let Some(cutoffs) = &a.cutoffs {
        return bench_cutoffs(a, cutoffs);
    }
    if let Some(sizes) = &a.reconstruction {
        return bench_reconstruction(a, sizes);
    }
    if a.lanes {
        return bench_lanes(a);
    }
    if a.plan {
        return bench_plan(a);
    }
    if a.trees {
        return bench_trees(a);
    }
    if let Some(sizes) = &a.surface_fidelity {
        return bench_surface_fidelity(a, sizes);
    }
    if let Some(mesh_path) = &a.voxelize {
        return bench_voxelize(a, mesh_path);
    }
    bench_seed(a)
}

/// `voxlab bench --adaptive`.
#[cfg(feature = "viewer")]
fn bench_adaptive(a: &BenchArgs, files: &[PathBuf]) -> Result<()> {
    let mut gpu = GpuTracer::new().context("the adaptive benchmark needs a GPU adapter")?;
    let default = [
        PathBuf::from("experiments/baseline.toml"),
        PathBuf::from("experiments/area_lights.toml"),
    ];
    let files = if files.is_empty() {
        &default[..]
    } else {
        files
    };
    let experiments = files
        .iter()
        .map(|f| Experiment::load_with(f, &a.set).map_err(anyhow::Error::from))
        .collect::<Result<Vec<_>>>()?;
    let rows = voxlab::viewer::bench::bench_adaptive(&mut gpu, &experiments, a.gpu_runs as usize)?;
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
    Ok(())
}

/// `voxlab bench --plan`.
fn bench_plan(a: &BenchArgs) -> Result<()> {
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
    Ok(())
}

/// `voxlab bench --trees`.
fn bench_trees(a: &BenchArgs) -> Result<()> {
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
    Ok(())
}

/// `voxlab bench --surface-fidelity`.
fn bench_surface_fidelity(a: &BenchArgs, sizes: &[u32]) -> Result<()> {
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
    Ok(())
}

/// `voxlab bench --voxelize`.
fn bench_voxelize(a: &BenchArgs, mesh_path: &Path) -> Result<()> {
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
    Ok(())
}

/// `voxlab bench`: the seed scene (and experiments, surfaces, a torus) on every walk,
/// both tracers.
fn bench_seed(a: &BenchArgs) -> Result<()> {
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
        experiments: load_experiments(a, Some(&[]))?,
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
    let experiments = load_experiments(a, None)?;
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

/// The --experiments files, each loaded with the --set overrides; without any, the files
/// of `default`, or every `experiments/*.toml` where there is no default.
fn load_experiments(a: &BenchArgs, default: Option<&[&str]>) -> Result<Vec<Experiment>> {
    let files = if !a.experiments.is_empty() {
        a.experiments.clone()
    } else if let Some(default) = default {
        default.iter().map(PathBuf::from).collect()
    } else {
        let mut files: Vec<PathBuf> = std::fs::read_dir("experiments")
            .context("reading experiments/ (run from the repository, or name --experiments)")?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        files
    };
    files
        .iter()
        .map(|f| Experiment::load_with(f, &a.set).map_err(anyhow::Error::from))
        .collect()
}

/// `voxlab bench --lanes`.
fn bench_lanes(a: &BenchArgs) -> Result<()> {
    let default = ["experiments/baseline.toml", "experiments/seed_rules.toml"];
    let experiments = load_experiments(a, Some(&default))?;
    let rows = voxlab::bench::lanes::bench_lanes(&experiments, a.size);
    if a.json {
        let head = bench_head("lanes", None, a);
        return print_json_rows(&head, rows.iter().map(|r| r.json()));
    }
    println!(
        "SIMD lanes: each experiment at {0}x{0}, frame 0, the rays and voxel steps of \
         each pixel (CPU reference) in the kernel's vectors of 4x2 pixels; lane \
         efficiency = what the lanes trace over 8 times each vector's largest count\n",
        a.size
    );
    println!("{}", voxlab::bench::lanes::lanes_table(&rows));
    Ok(())
}

/// `voxlab bench --reconstruction`.
fn bench_reconstruction(a: &BenchArgs, sizes: &[u32]) -> Result<()> {
    let mut gpu = GpuTracer::new().context("the reconstruction benchmark needs a GPU adapter")?;
    let file = a
        .experiments
        .first()
        .cloned()
        .unwrap_or_else(|| PathBuf::from("experiments/mitsuba/rect_blocks.toml"));
    let e = Experiment::load_with(&file, &a.set)?;
    eprintln!("GPU: {}", gpu.adapter_summary());
    let rows = voxlab::bench::reconstruction::bench_reconstructions(
        &mut gpu,
        &e,
        &voxlab::technique::RECONSTRUCTIONS[1..],
        sizes,
        a.gpu_runs as usize,
    )?;
    if a.json {
        let head = bench_head("reconstruction", Some(&gpu.adapter_summary()), a);
        return print_json_rows(&head, rows.iter().map(|r| r.json()));
    }
    println!(
        "reconstruction: {} ({}), one frame, shadow model {}; medians of {} interleaved \
         runs ({}; the filter's passes: wall around their synchronised submissions); GPU: {}\n",
        e.name,
        file.display(),
        e.settings.features.shadow_model.name,
        a.gpu_runs,
        gpu.timer_name(),
        gpu.adapter_summary()
    );
    println!("{}", voxlab::bench::reconstruction::filter_table(&rows));
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
