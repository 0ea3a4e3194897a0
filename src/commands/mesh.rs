//! `voxlab mesh` and `voxlab voxelize`: surfaces out of voxels, voxels out of a mesh.

// The binary's shared argument parsers and imports (main.rs).
use crate::*;

#[derive(Args, Debug)]
pub(crate) struct MeshArgs {
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

pub(crate) fn cmd_mesh(a: &MeshArgs) -> Result<()> {
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
    // The text as it was meshed, not as the file may hold it by now.
    let (text, inputs) = match (&a.experiment, &e.source_record) {
        (Some(p), Some(r)) => {
            let text = voxlab::experiment::apply_overrides(&r.text, &a.set)?;
            let inputs = voxlab::experiment::write::input_files(&text, p);
            (text, inputs)
        }
        (Some(p), None) => {
            let text =
                voxlab::experiment::apply_overrides(&voxlab::experiment::read_text(p)?, &a.set)?;
            let inputs = voxlab::experiment::write::input_files(&text, p);
            (text, inputs)
        }
        (None, _) => (String::new(), Vec::new()),
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

#[derive(Args, Debug)]
pub(crate) struct VoxelizeArgs {
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

pub(crate) fn cmd_voxelize(a: &VoxelizeArgs) -> Result<()> {
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
