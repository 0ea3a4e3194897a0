//! `voxlab info FILE`: what a scene file holds, before it is used in an experiment: a
//! MagicaVoxel file's or an experiment's grid (dims, voxel size, origin, occupied
//! voxels) and every palette entry with its voxel count and colour; a mesh's triangles,
//! bounds and materials.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result, bail};
use glam::DVec3;

use crate::experiment::Experiment;
use crate::scene::{Grid, Material, load_mesh, load_vox};

/// The description of `path`, chosen by its extension: `.vox`, `.toml` (an experiment),
/// `.obj`, `.gltf`, `.glb`.
pub fn describe(path: &Path) -> Result<String> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let mut out = format!("{}\n", path.display());
    match ext.as_str() {
        "vox" => {
            let v = load_vox(path, None).with_context(|| format!("reading {}", path.display()))?;
            writeln!(
                out,
                "MagicaVoxel file, {} model(s) (all placed by the scene graph)",
                v.model_count
            )?;
            grid_lines(&mut out, &v.grid);
            palette_lines(&mut out, &v.grid, &v.materials, Some(&v.palette_index));
        }
        "toml" => {
            let e = Experiment::load(path)?;
            writeln!(
                out,
                "experiment `{}`: {} light(s), camera at distance {:.3}",
                e.name,
                e.scene.lights.len(),
                e.scene.camera.distance
            )?;
            grid_lines(&mut out, &e.scene.grid);
            palette_lines(&mut out, &e.scene.grid, &e.scene.materials, None);
        }
        "obj" | "gltf" | "glb" => {
            let m = load_mesh(path).with_context(|| format!("reading {}", path.display()))?;
            let (lo, hi) = m
                .triangles
                .iter()
                .flatten()
                .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &p| {
                    (lo.min(p), hi.max(p))
                });
            writeln!(out, "mesh: {} triangles", m.triangles.len())?;
            if !m.triangles.is_empty() {
                writeln!(
                    out,
                    "bounds: {} .. {} (size {})",
                    v3(lo),
                    v3(hi),
                    v3(hi - lo)
                )?;
            }
            writeln!(out, "materials ({}):", m.materials.len())?;
            for (i, mat) in m.materials.iter().enumerate() {
                let n = m.material_of.iter().filter(|&&k| k == i).count();
                writeln!(
                    out,
                    "  {i:>3}  {:<24} {n:>9} triangles  {}",
                    mat.name,
                    colour(mat)
                )?;
            }
            for w in &m.warnings {
                writeln!(out, "warning: {w}")?;
            }
        }
        _ => bail!(
            "{}: voxlab info reads .vox, .toml (experiments), .obj, .gltf and .glb files",
            path.display()
        ),
    }
    Ok(out)
}

fn v3(v: DVec3) -> String {
    format!("[{:.4}, {:.4}, {:.4}]", v.x, v.y, v.z)
}

/// `#rrggbb` of the albedo (clamped to [0, 1]) and the shading weights.
fn colour(m: &Material) -> String {
    let c = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    format!(
        "#{:02x}{:02x}{:02x}  kd {} ks {} kr {} kt {} ior {}{}",
        c(m.albedo.x),
        c(m.albedo.y),
        c(m.albedo.z),
        m.kd,
        m.ks,
        m.kr,
        m.kt,
        m.ior,
        if m.emission != DVec3::ZERO {
            format!(" emission {}", v3(m.emission))
        } else {
            String::new()
        }
    )
}

fn grid_lines(out: &mut String, g: &Grid) {
    let d = g.dims();
    let occupied: u64 = g.material_counts()[1..].iter().sum();
    let _ = writeln!(
        out,
        "grid: {}x{}x{} ({} voxels, {} occupied, {:.2} %), voxel size {}, origin {}",
        d.x,
        d.y,
        d.z,
        g.voxel_count(),
        occupied,
        100.0 * occupied as f64 / g.voxel_count().max(1) as f64,
        g.voxel_size(),
        v3(g.origin())
    );
    if let Some(t) = g.sparse_tree() {
        let _ = writeln!(
            out,
            "held as its sparse tree only ({} nodes, {:.1} MiB, {:.4} bytes per voxel): no dense \
             grid, walked sparse",
            t.node_count(),
            t.bytes() as f64 / (1u64 << 20) as f64,
            t.bytes_per_voxel()
        );
    }
}

/// Every palette entry: index, name, voxels of it, colour and weights; for a .vox, the
/// MagicaVoxel palette index each came from.
fn palette_lines(out: &mut String, g: &Grid, materials: &[Material], vox_index: Option<&[u8]>) {
    let counts = g.material_counts();
    let _ = writeln!(out, "palette ({} entries, 0 is void):", materials.len());
    for (i, m) in materials.iter().enumerate().skip(1) {
        let from = vox_index
            .and_then(|p| p.get(i))
            .map_or(String::new(), |k| format!(" (MagicaVoxel index {k})"));
        let _ = writeln!(
            out,
            "  {i:>3}  {:<24} {:>10} voxels  {}{from}",
            m.name,
            counts[i],
            colour(m)
        );
    }
}
