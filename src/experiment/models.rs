//! `[[scene.models]]`: `.vox` models and voxelized meshes placed into a grid of the
//! experiment's choosing, beside its generator's voxels, its boxes and the built-in
//! materials.
//!
//! Order of assembly (the one the file documents): the generator fills the grid; each
//! model's palette is appended to the built-in one (names prefixed by the model's name,
//! so two files' `vox 94` stay apart and `[[materials]]` can override either); the
//! `[[materials]]` entries apply; the models are written into the grid in file order,
//! each of its non-void voxels replacing what was there; the boxes apply last, so a box
//! can carve into a model.

use std::path::Path;

use glam::{IVec3, UVec3};
use serde::Deserialize;

use super::{Ctx, ExperimentError, MaterialRef, declared, int_in};
use crate::scene::{Grid, Material, Scene};
use crate::settings::{MODEL_RESOLUTION, MODEL_SCALE, VOX_MODEL};
use crate::sparse::{ModelOverlay, PlacedModel, SparseTree};

/// At most this many models in one scene: each is a file load, bounded on its own.
pub(crate) const MAX_MODELS: usize = 64;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawModel {
    /// A MagicaVoxel file (relative to the experiment file).
    vox: Option<String>,
    /// With `vox`: load only this model of the file (0-based).
    model: Option<i64>,
    /// A mesh (OBJ, glTF, GLB), voxelized on load.
    mesh: Option<String>,
    /// With `mesh`: voxels along its longest axis.
    resolution: Option<i64>,
    /// Every voxel of the model in this material (name or index of the final palette).
    material: Option<MaterialRef>,
    /// The grid voxel where the model's minimum corner goes.
    #[serde(default, deserialize_with = "super::exact::option")]
    offset: Option<[i64; 3]>,
    /// With `vox`: each voxel becomes a cube of scale^3 voxels.
    scale: Option<i64>,
    /// Prefix of its materials' names (default: the file's stem).
    name: Option<String>,
}

/// A model as loaded, before placement: what the scene cache keeps.
#[derive(Debug, Clone)]
pub(super) struct LoadedModel {
    grid: Grid,
    /// Index 0 is void.
    palette: Vec<Material>,
}

fn key(i: usize, k: &str) -> String {
    format!("scene.models[{i}].{k}")
}

/// Loads every model (the expensive part, cached with the grid).
pub(super) fn load_models(
    models: &[RawModel],
    ctx: &Ctx,
    grid: UVec3,
) -> Result<Vec<LoadedModel>, ExperimentError> {
    use crate::scene::mesh::MAX_RESOLUTION;
    use crate::scene::{Resolution, VoxelizeOptions, load_vox, voxelize_mesh};
    if models.len() > MAX_MODELS {
        return Err(ctx.invalid(
            "scene.models",
            format!("{} models; at most {MAX_MODELS} are allowed", models.len()),
        ));
    }
    let dir = Path::new(&ctx.file).parent().unwrap_or(Path::new(""));
    let mut out = Vec::with_capacity(models.len());
    for (i, m) in models.iter().enumerate() {
        let only = |present: bool, k: &str, with: &str| {
            if present {
                Err(ctx.invalid(&key(i, k), format!("only applies to a model with {with}")))
            } else {
                Ok(())
            }
        };
        only(m.model.is_some() && m.vox.is_none(), "model", "vox")?;
        only(
            m.scale.is_some() && m.vox.is_none(),
            "scale",
            "vox (a mesh's size is its resolution)",
        )?;
        only(
            m.resolution.is_some() && m.mesh.is_none(),
            "resolution",
            "mesh",
        )?;
        let loaded = match (&m.vox, &m.mesh) {
            (Some(p), None) => {
                let model = match m.model {
                    Some(v) => {
                        Some(declared(ctx, &key(i, "model"), &VOX_MODEL, v as f64)? as usize)
                    }
                    None => None,
                };
                let v = load_vox(dir.join(p), model).map_err(|e| ctx.invalid(&key(i, "vox"), e))?;
                LoadedModel {
                    grid: v.grid,
                    palette: v.materials,
                }
            }
            (None, Some(p)) => {
                let Some(n) = m.resolution else {
                    return Err(ctx.invalid(
                        &key(i, "mesh"),
                        "needs resolution (voxels along the mesh's longest axis)",
                    ));
                };
                // A model must fit the grid: a longer axis than the grid's longest side
                // is refused before the (bounded, but possibly large) voxelization.
                declared(ctx, &key(i, "resolution"), &MODEL_RESOLUTION, n as f64)?;
                let side = grid.max_element().min(MAX_RESOLUTION);
                let n = int_in(ctx, &key(i, "resolution"), n, 1..=i64::from(side))?;
                let options = VoxelizeOptions {
                    resolution: Resolution::Count(n),
                    material: None,
                    // Placed voxel by voxel into a dense grid.
                    storage: crate::scene::Storage::Dense,
                };
                let v = voxelize_mesh(dir.join(p), &options)
                    .map_err(|e| ctx.invalid(&key(i, "mesh"), e))?;
                for w in &v.warnings {
                    eprintln!("warning: {}: scene.models[{i}]: {w}", ctx.file);
                }
                LoadedModel {
                    grid: v.grid,
                    palette: v.materials,
                }
            }
            (Some(_), Some(_)) => {
                return Err(ctx.invalid(&key(i, "mesh"), "give either vox or mesh, not both"));
            }
            (None, None) => {
                return Err(ctx.invalid(
                    &format!("scene.models[{i}]"),
                    "needs vox = \"FILE.vox\" or mesh = \"FILE.obj|.gltf|.glb\"",
                ));
            }
        };
        out.push(loaded);
    }
    Ok(out)
}

/// The name a model's materials are prefixed with.
fn model_name(m: &RawModel, i: usize, ctx: &Ctx) -> Result<String, ExperimentError> {
    if let Some(n) = &m.name {
        if n.is_empty() || n.len() > 64 {
            return Err(ctx.invalid(&key(i, "name"), "must be 1 to 64 characters"));
        }
        return Ok(n.clone());
    }
    let file = m.vox.as_deref().or(m.mesh.as_deref()).unwrap_or_default();
    Ok(Path::new(file).file_stem().map_or_else(
        || format!("model {i}"),
        |s| s.to_string_lossy().into_owned(),
    ))
}

/// Appends the palette of each model without a `material` to `palette` (prefixed
/// names; an entry equal to one already there, name included, is shared) and returns,
/// per model, the map from its palette index to the final one (`None` for models whose
/// material is resolved later, after `[[materials]]`).
pub(super) fn extend_palette(
    raw: &[RawModel],
    loaded: &[LoadedModel],
    palette: &mut Vec<Material>,
    ctx: &Ctx,
) -> Result<Vec<Option<Vec<u8>>>, ExperimentError> {
    let mut maps = Vec::with_capacity(raw.len());
    for (i, (m, l)) in raw.iter().zip(loaded).enumerate() {
        if m.material.is_some() {
            maps.push(None);
            continue;
        }
        let prefix = model_name(m, i, ctx)?;
        let mut map = vec![0u8; l.palette.len()];
        for (k, mat) in l.palette.iter().enumerate().skip(1) {
            let mut mat = mat.clone();
            mat.name = format!("{prefix}: {}", mat.name);
            let index = match palette.iter().position(|p| *p == mat) {
                Some(j) => j,
                None => {
                    if palette.len() >= 256 {
                        return Err(ctx.invalid(
                            &key(i, "vox"),
                            "the scene's palette would exceed 256 materials including void \
                             (u8 indices): give this model a material, or fewer models",
                        ));
                    }
                    palette.push(mat);
                    palette.len() - 1
                }
            };
            map[k] = index as u8;
        }
        maps.push(Some(map));
    }
    Ok(maps)
}

/// Writes every model into `scene.grid`, in file order.
pub(super) fn place_models(
    scene: &mut Scene,
    raw: &[RawModel],
    loaded: &[LoadedModel],
    maps: Vec<Option<Vec<u8>>>,
    ctx: &Ctx,
) -> Result<(), ExperimentError> {
    let dims = scene.grid.dims();
    // Into a grid held as its tree the models are written all at once, over the tree.
    let mut placed: Vec<(usize, IVec3, u32, Vec<u8>)> = Vec::new();
    for (i, ((m, l), map)) in raw.iter().zip(loaded).zip(maps).enumerate() {
        let map = match (map, &m.material) {
            (Some(map), _) => map,
            (None, Some(r)) => {
                let k = resolve_material(scene, r, &key(i, "material"), ctx)?;
                let mut map = vec![k; l.palette.len()];
                map[0] = 0;
                map
            }
            (None, None) => unreachable!("extend_palette maps every model without a material"),
        };
        let scale = match m.scale {
            Some(s) => declared(ctx, &key(i, "scale"), &MODEL_SCALE, s as f64)? as u32,
            None => 1,
        };
        let size = l.grid.dims() * scale;
        let offset = m.offset.unwrap_or([0; 3]);
        // Compared without adding to the file's number, which may be near i64::MAX.
        let fits =
            (0..3).all(|a| offset[a] >= 0 && offset[a] <= i64::from(dims[a]) - i64::from(size[a]));
        if !fits {
            let max = |a: usize| i64::from(dims[a]) - i64::from(size[a]);
            let range = if (0..3).all(|a| max(a) >= 0) {
                format!(
                    "offset must be in [0, {}] x [0, {}] x [0, {}]",
                    max(0),
                    max(1),
                    max(2)
                )
            } else {
                "no offset fits: make the grid larger".to_string()
            };
            return Err(ctx.invalid(
                &key(i, "offset"),
                format!(
                    "the model is {}x{}x{} voxels (scale {scale}) and must lie inside the grid \
                     ({}x{}x{}): {range}",
                    size.x, size.y, size.z, dims.x, dims.y, dims.z
                ),
            ));
        }
        let base = IVec3::new(offset[0] as i32, offset[1] as i32, offset[2] as i32);
        if !scene.grid.is_sparse() {
            write_scaled(&mut scene.grid, &l.grid, base, scale, &map);
            continue;
        }
        // The builder reads a scaled model's voxels where its cubes straddle them:
        // bounded like a dense grid.
        let footprint = size.as_u64vec3().element_product();
        if footprint > crate::scene::DENSE_MAX_VOXELS {
            return Err(ctx.invalid(
                &key(i, "scale"),
                format!(
                    "the model covers {}x{}x{} = {footprint} voxels (scale {scale}); placed \
                     into a grid held as its sparse tree a model covers at most {} \
                     (scene::DENSE_MAX_VOXELS)",
                    size.x,
                    size.y,
                    size.z,
                    crate::scene::DENSE_MAX_VOXELS
                ),
            ));
        }
        placed.push((i, base, scale, map));
    }
    if let Some(tree) = scene.grid.sparse_tree().filter(|_| !placed.is_empty()) {
        let models: Vec<PlacedModel> = placed
            .iter()
            .map(|(i, base, scale, map)| PlacedModel {
                voxels: &loaded[*i].grid,
                base: *base,
                scale: *scale as i32,
                map,
            })
            .collect();
        let overlay = ModelOverlay {
            base: tree.as_ref(),
            models: &models,
        };
        let tree = SparseTree::build(&overlay, crate::sparse::GPU_LOG_BRANCH);
        let g = &scene.grid;
        scene.grid = Grid::from_tree(tree, g.voxel_size(), g.origin())
            .map_err(|e| ctx.invalid("scene.models", e))?;
    }
    Ok(())
}

/// `src`'s non-void voxels, each as a cube of `scale`^3, through `map`, at `base`.
fn write_scaled(dst: &mut Grid, src: &Grid, base: IVec3, scale: u32, map: &[u8]) {
    let d = src.dims();
    let s = scale as i32;
    for z in 0..d.z as i32 {
        for y in 0..d.y as i32 {
            for x in 0..d.x as i32 {
                let m = src.get(IVec3::new(x, y, z));
                if m == 0 {
                    continue;
                }
                let v = map[usize::from(m)];
                let corner = base + IVec3::new(x, y, z) * s;
                for c in 0..UVec3::splat(scale).element_product() as i32 {
                    let o = IVec3::new(c % s, (c / s) % s, c / (s * s));
                    dst.set(corner + o, v);
                }
            }
        }
    }
}

/// A material reference (name or index) in the final palette, for a whole mesh or
/// model: void refused, an unknown name answered with the names defined.
pub(super) fn resolve_material(
    scene: &Scene,
    r: &MaterialRef,
    k: &str,
    ctx: &Ctx,
) -> Result<u8, ExperimentError> {
    let n = scene.materials.len();
    match r {
        MaterialRef::Index(i) => Ok(int_in(ctx, k, *i, 1..=(n as i64 - 1))? as u8),
        MaterialRef::Name(name) => match scene.materials.iter().position(|m| &m.name == name) {
            Some(0) => Err(ctx.invalid(k, "void cannot be a mesh's or model's material")),
            Some(i) => Ok(i as u8),
            None => {
                let names: Vec<&str> = scene.materials.iter().map(|m| m.name.as_str()).collect();
                Err(ctx.invalid(
                    k,
                    format!("no such material; defined: {}", names.join(", ")),
                ))
            }
        },
    }
}
