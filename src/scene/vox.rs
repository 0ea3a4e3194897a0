//! MagicaVoxel `.vox` import and export, and the error type of every scene loader.
//!
//! # Axes
//!
//! MagicaVoxel is z-up, voxlab is y-up. Both are right-handed, so the mapping is a
//! proper rotation (-90 degrees about x), not a swap of two axes (which would mirror
//! the model): a point `(x, y, z)` of the MagicaVoxel world is `(x, z, -y)` in voxlab.
//! On voxel indices, with the loaded cells spanning `[min, max)` in MagicaVoxel world
//! cells, the cell `(x, y, z)` is voxlab voxel `(x - min.x, z - min.z, max.y - 1 - y)`,
//! so voxlab dimensions are `(size.x, size.z, size.y)`. The grid has voxel size 1 and
//! its corner at the origin (a `.vox` file has no unit or placement of its own).
//! A model's front (MagicaVoxel -y) thus faces voxlab +z.
//!
//! # Placement
//!
//! With no model chosen, every model is placed by the scene graph (nTRN translation
//! `_t` and rotation byte `_r`, composed down the tree; first animation frame; nodes
//! and layers marked hidden are left out). As in MagicaVoxel, a model's pivot is its
//! centre rounded down, `floor(size / 2)`: voxel `v` lands in the world cell
//! `floor(R (v + 0.5 - floor(size / 2)) + t)`. Where models overlap, the later one wins.
//! A file without a scene graph (the old format) holds the frames of an animation:
//! model 0 is loaded, as MagicaVoxel shows frame 0. A chosen model is loaded alone,
//! unmoved, in a grid of its own SIZE. A voxel of colour index 0 is empty, as in
//! MagicaVoxel (dot_vox reads it as colour 1, so the chunk walk marks such records).
//!
//! # Materials
//!
//! Each palette index used becomes one voxlab material, numbered 1, 2, ... in
//! increasing palette order (0 stays void), its albedo the palette colour / 255 (no
//! sRGB decoding: the palette is taken as the albedo, as the seed's colours are).
//! MagicaVoxel's MATL properties map as follows; MagicaVoxel's renderer is a path
//! tracer, so these are approximations chosen to look alike under Whitted shading:
//! - `_glass`: transmitting, with the seed glass's kd 0.2, ks 0.7, kr 0.3 (the seed
//!   report's Table 1); `kt` from `_trans`, else `_alpha`, else `_weight` (the key each
//!   MagicaVoxel version wrote), else 0.8. The index of refraction is `_ri` when
//!   present, else `1 + _ior`: MagicaVoxel 0.99 writes `_ior` as ior - 1 (its default
//!   material carries `_ior 0.3` beside `_ri 1.3`, see dot_vox's `axes.vox`), else 1.5.
//! - `_metal`: reflective, `kr` from `_metal`, else `_weight`, else 1; `ks = 1 - _rough`
//!   (a smooth metal has a strong highlight); `kd = 0.8 (1 - kr)`.
//! - `_emit`: diffuse plus `emission = albedo * _emit * (1 + _flux)` (`_emit` else
//!   `_weight`; `_flux` is MagicaVoxel's power step 0..4). MagicaVoxel defines no
//!   radiance unit, so this scale is a convention, not a conversion.
//! - everything else (`_diffuse`, `_blend`, `_media`, `_cloud`, no MATL): diffuse with
//!   `kd` [`VOX_KD`] 0.8, `ks` [`VOX_KS`] 0.1, no reflection or refraction: a matte
//!   surface with a faint highlight, like MagicaVoxel's default look.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use dot_vox::{Color, DotVoxData, SceneNode};
use glam::{DVec3, IVec3, UVec3};

use super::{Grid, MAX_SPARSE_SIDE, MAX_VOXELS, Material, SEED_SHININESS, Storage, VOID};
use crate::sparse::BrickSource;

/// Diffusivity of a diffuse material from a loaded file (`.vox` or mesh).
pub const VOX_KD: f64 = 0.8;
/// Specularity of a diffuse material from a loaded file.
pub const VOX_KS: f64 = 0.1;

/// Largest side of one MagicaVoxel model; larger grids are written as several models.
pub(crate) const VOX_MODEL_MAX: u32 = 256;

/// Any failure of a scene loader or writer: the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
#[error("{}: {kind}", path.display())]
pub struct LoadError {
    pub path: PathBuf,
    pub kind: LoadErrorKind,
}

#[derive(Debug, thiserror::Error)]
pub enum LoadErrorKind {
    #[error("cannot read the file: {0}")]
    Read(std::io::Error),
    #[error("cannot read the file: {0}")]
    Input(crate::input::ReadError),
    #[error("cannot write the file: {0}")]
    Write(std::io::Error),
    #[error("not a valid MagicaVoxel .vox file: {0}")]
    InvalidVox(String),
    #[error("{}", model_range(*.index, *.count))]
    ModelOutOfRange { index: usize, count: usize },
    #[error("cannot read the mesh: {0}")]
    InvalidMesh(String),
    #[error("the mesh is empty: {0}")]
    EmptyMesh(String),
    #[error("invalid option: {0}")]
    InvalidOption(String),
    #[error("too large: {0}")]
    TooLarge(String),
}

fn model_range(index: usize, count: usize) -> String {
    if count == 0 {
        format!("model {index} was asked for, but the file holds no models")
    } else {
        format!(
            "model {index} does not exist: the file holds {count} model(s), valid indices 0..={}",
            count - 1
        )
    }
}

impl LoadError {
    pub fn new(path: &Path, kind: LoadErrorKind) -> Self {
        Self {
            path: path.to_path_buf(),
            kind,
        }
    }
}

/// A loaded `.vox` file.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxScene {
    pub grid: Grid,
    /// Index 0 is void; index k >= 1 is the k-th palette colour used.
    pub materials: Vec<Material>,
    /// The MagicaVoxel palette index (1..=255) of each voxlab material (0 for void).
    pub palette_index: Vec<u8>,
    /// How many models the file holds (whether or not all were loaded).
    pub model_count: usize,
}

/// A matte material of the given colour, as loaders make for plain colours.
pub fn diffuse_material(name: impl Into<String>, albedo: DVec3) -> Material {
    Material {
        name: name.into(),
        albedo,
        kd: VOX_KD,
        ks: VOX_KS,
        shininess: SEED_SHININESS,
        kr: 0.0,
        kt: 0.0,
        ior: 1.0,
        sigma: None,
        emission: DVec3::ZERO,
        dielectric: Default::default(),
    }
}

/// A signed permutation matrix (rows), MagicaVoxel's `_r` rotation/flip.
type Rot = [[i64; 3]; 3];
const IDENTITY: Rot = [[1, 0, 0], [0, 1, 0], [0, 0, 1]];

fn rot_mul(a: &Rot, b: &Rot) -> Rot {
    let mut m = [[0; 3]; 3];
    for (r, row) in m.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[r][k] * b[k][c]).sum();
        }
    }
    m
}

fn rot_apply(m: &Rot, p: [f64; 3]) -> [f64; 3] {
    let mut out = [0.0; 3];
    for (r, o) in out.iter_mut().enumerate() {
        *o = (0..3).map(|k| m[r][k] as f64 * p[k]).sum();
    }
    out
}

/// Decodes `_r`: bits 0-1 the column of row 0's non-zero entry, bits 2-3 that of row 1
/// (row 2 takes the remaining column), bits 4-6 the signs of rows 0-2. Validated here
/// because dot_vox's own decoder asserts (panics) on malformed bytes.
fn parse_rotation(s: &str) -> Result<Rot, String> {
    let b: u8 = s
        .trim()
        .parse()
        .map_err(|_| format!("rotation _r = {s:?} is not a byte"))?;
    let (c0, c1) = ((b & 3) as usize, ((b >> 2) & 3) as usize);
    if c0 == 3 || c1 == 3 || c0 == c1 || b >> 7 != 0 {
        return Err(format!(
            "rotation _r = {b} is not a valid rotation/flip byte"
        ));
    }
    let cols = [c0, c1, 3 - c0 - c1];
    let mut m = [[0; 3]; 3];
    for (r, &c) in cols.iter().enumerate() {
        m[r][c] = if b & (1 << (4 + r)) == 0 { 1 } else { -1 };
    }
    Ok(m)
}

#[derive(Clone, Debug)]
enum Place {
    /// Voxel `v` at cell `v` (old files, or a chosen model).
    Local,
    /// Voxel `v` at `floor(R (v + 0.5 - pivot) + t)`.
    Graph { rot: Rot, t: [i64; 3] },
}

const MAX_GRAPH_DEPTH: usize = 64;
const MAX_PLACEMENTS: usize = 1 << 16;

fn walk_graph(
    data: &DotVoxData,
    node: u32,
    rot: Rot,
    t: [i64; 3],
    depth: usize,
    out: &mut Vec<(usize, Place)>,
) -> Result<(), String> {
    if depth > MAX_GRAPH_DEPTH {
        return Err(format!(
            "the scene graph is nested deeper than {MAX_GRAPH_DEPTH} levels (a cycle?)"
        ));
    }
    let Some(n) = data.scenes.get(node as usize) else {
        return Err(format!(
            "scene graph node {node} is referenced but the file has {} nodes",
            data.scenes.len()
        ));
    };
    match n {
        SceneNode::Transform {
            attributes,
            frames,
            child,
            layer_id,
        } => {
            let hidden_layer = data
                .layers
                .get(*layer_id as usize)
                .is_some_and(|l| l.hidden());
            if attributes.get("_hidden").is_some_and(|h| h == "1") || hidden_layer {
                return Ok(());
            }
            let (mut r, mut tt) = (IDENTITY, [0i64; 3]);
            if let Some(f) = frames.first() {
                if let Some(s) = f.attributes.get("_r") {
                    r = parse_rotation(s)?;
                }
                if let Some(s) = f.attributes.get("_t") {
                    let v: Vec<i64> = s
                        .split_whitespace()
                        .map(|x| x.parse::<i32>().map(i64::from))
                        .collect::<Result<_, _>>()
                        .map_err(|_| format!("translation _t = {s:?} is not three integers"))?;
                    if v.len() != 3 {
                        return Err(format!("translation _t = {s:?} is not three integers"));
                    }
                    tt = [v[0], v[1], v[2]];
                }
            }
            // Parent after child: world = R_p (R_c p + t_c) + t_p.
            let rt = rot_apply(&rot, tt.map(|x| x as f64));
            let t2 = [0, 1, 2].map(|k| t[k] + rt[k] as i64);
            walk_graph(data, *child, rot_mul(&rot, &r), t2, depth + 1, out)
        }
        SceneNode::Group { children, .. } => {
            for &c in children {
                walk_graph(data, c, rot, t, depth + 1, out)?;
            }
            Ok(())
        }
        SceneNode::Shape { models, .. } => {
            // Several models in one shape are animation frames: the first is shown.
            if let Some(m) = models.first() {
                let id = m.model_id as usize;
                if id >= data.models.len() {
                    return Err(format!(
                        "a shape node refers to model {id}, but the file holds {} model(s)",
                        data.models.len()
                    ));
                }
                if out.len() >= MAX_PLACEMENTS {
                    return Err(format!(
                        "the scene graph places more than {MAX_PLACEMENTS} model instances"
                    ));
                }
                out.push((id, Place::Graph { rot, t }));
            }
            Ok(())
        }
    }
}

fn prop(m: Option<&dot_vox::Material>, key: &str) -> Option<f64> {
    m?.properties
        .get(key)?
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|x| x.is_finite())
}

/// The voxlab material for MagicaVoxel colour index `file_index` (1..=255); see the
/// module documentation for the mapping.
fn vox_material(file_index: u32, c: Color, matl: Option<&dot_vox::Material>) -> Material {
    let albedo = DVec3::new(c.r as f64, c.g as f64, c.b as f64) / 255.0;
    let kind = matl.and_then(|m| m.properties.get("_type").map(String::as_str));
    let unit = |x: f64| x.clamp(0.0, 1.0);
    let mut m = diffuse_material(format!("vox {file_index}"), albedo);
    match kind {
        Some("_glass") => {
            m.name = format!("vox {file_index} glass");
            let kt = prop(matl, "_trans")
                .or_else(|| prop(matl, "_alpha"))
                .or_else(|| prop(matl, "_weight"))
                .unwrap_or(0.8);
            let ior = prop(matl, "_ri")
                .or_else(|| prop(matl, "_ior").map(|x| x + 1.0))
                .unwrap_or(1.5);
            (m.kd, m.ks, m.kr) = (0.2, 0.7, 0.3);
            m.kt = unit(kt);
            m.ior = ior.max(1.0);
        }
        Some("_metal") => {
            m.name = format!("vox {file_index} metal");
            m.kr = unit(
                prop(matl, "_metal")
                    .or_else(|| prop(matl, "_weight"))
                    .unwrap_or(1.0),
            );
            m.ks = unit(1.0 - prop(matl, "_rough").unwrap_or(0.1));
            m.kd = VOX_KD * (1.0 - m.kr);
        }
        Some("_emit") => {
            m.name = format!("vox {file_index} emit");
            let e = prop(matl, "_emit")
                .or_else(|| prop(matl, "_weight"))
                .unwrap_or(1.0)
                .max(0.0);
            let flux = prop(matl, "_flux").unwrap_or(0.0).max(0.0);
            m.emission = albedo * e * (1.0 + flux);
        }
        _ => {}
    }
    m
}

/// Loads a MagicaVoxel `.vox` file: every model placed by the scene graph when `model`
/// is `None`, model `k` alone otherwise. See the module documentation for axes,
/// placement and materials. Errors name the file; malformed input never panics.
pub fn load_vox(path: impl AsRef<Path>, model: Option<usize>) -> Result<VoxScene, LoadError> {
    load_vox_as(path, model, Storage::Auto)
}

/// [`load_vox`] with the grid held as `storage` says: a scene larger than a dense grid
/// can hold is placed straight into a sparse tree.
pub fn load_vox_as(
    path: impl AsRef<Path>,
    model: Option<usize>,
    storage: Storage,
) -> Result<VoxScene, LoadError> {
    let path = path.as_ref();
    let fail = |kind| LoadError::new(path, kind);
    let bytes = crate::input::read_file(path, crate::input::MAX_VOX_BYTES, ".vox file")
        .map_err(|e| fail(LoadErrorKind::Input(e)))?;
    let empty = check_chunks(&bytes).map_err(fail)?;
    let data = crate::input::guarded(|| dot_vox::load_bytes(&bytes))
        .map_err(|p| {
            fail(LoadErrorKind::InvalidVox(format!(
                "the .vox parser (dot_vox) failed on it: {p}"
            )))
        })?
        .map_err(|e| {
            // dot_vox says what failed, not where: find the chunk whose content does not
            // have its kind's structure.
            let at = first_malformed_chunk(&bytes)
                .map(|w| format!("; {w}"))
                .unwrap_or_default();
            fail(LoadErrorKind::InvalidVox(format!("{e}{at}")))
        })?;
    vox_from_data(&data, model, &empty, storage).map_err(|k| match k {
        // dot_vox skips what it cannot read (a model whose XYZI count is wrong, say):
        // the chunk at fault explains what is missing.
        LoadErrorKind::InvalidVox(m) => {
            let at = first_malformed_chunk(&bytes)
                .map(|w| format!("; {w}"))
                .unwrap_or_default();
            fail(LoadErrorKind::InvalidVox(format!("{m}{at}")))
        }
        other => fail(other),
    })
}

/// Deepest chunk nesting a `.vox` file may have. MagicaVoxel writes MAIN with children
/// one level down; dot_vox parses children recursively, so a file nesting thousands of
/// chunks would overflow the stack in it.
pub const MAX_VOX_CHUNK_DEPTH: usize = 16;

/// Walks the RIFF-style chunk tree of a `.vox` file (id, content size, children size,
/// content, children) without recursion before any parser sees it: every chunk lies
/// inside its parent and the file, and nesting stays within [`MAX_VOX_CHUNK_DEPTH`].
/// `visit` sees each chunk's id, byte offset and content, depth first; its error, like
/// the walk's own, names the chunk and its offset.
fn walk_chunks(
    bytes: &[u8],
    mut visit: impl FnMut(&[u8], usize, &[u8]) -> Result<(), String>,
) -> Result<(), LoadErrorKind> {
    let invalid = |m: String| LoadErrorKind::InvalidVox(m);
    if bytes.len() < 8 || &bytes[..4] != b"VOX " {
        return Err(invalid(
            "it does not start with the magic \"VOX \" and a version (8 bytes)".into(),
        ));
    }
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    // Where the children of each chunk being walked end (the file's end at the top).
    let mut parents: Vec<usize> = vec![bytes.len()];
    let mut at = 8usize;
    while let Some(&end) = parents.last() {
        if at == end {
            parents.pop();
            continue;
        }
        let id = String::from_utf8_lossy(&bytes[at..(at + 4).min(bytes.len())]).to_string();
        if at + 12 > end {
            return Err(invalid(format!(
                "chunk {id:?} at byte {at}: its 12-byte header runs past its parent's end \
                 (byte {end})"
            )));
        }
        let content = word(at + 4) as usize;
        let children = word(at + 8) as usize;
        let body = at + 12;
        let child_start = body.checked_add(content);
        let chunk_end = child_start.and_then(|c| c.checked_add(children));
        let Some(chunk_end) = chunk_end.filter(|&e| e <= end) else {
            return Err(invalid(format!(
                "chunk {id:?} at byte {at}: {content} content bytes and {children} children \
                 bytes run past its parent's end (byte {end})"
            )));
        };
        let child_start = child_start.expect("checked above");
        visit(&bytes[at..at + 4], at, &bytes[body..child_start])
            .map_err(|what| invalid(format!("chunk {id:?} at byte {at}: {what}")))?;
        if children > 0 {
            if parents.len() >= MAX_VOX_CHUNK_DEPTH {
                return Err(invalid(format!(
                    "chunk {id:?} at byte {at}: chunks nest more than {MAX_VOX_CHUNK_DEPTH} \
                     deep (MagicaVoxel writes 2)"
                )));
            }
            // Its children follow its content; after them, its next sibling.
            parents.push(chunk_end);
            at = child_start;
        } else {
            at = chunk_end;
        }
    }
    Ok(())
}

/// [`walk_chunks`] before dot_vox parses the file. Returns, per XYZI chunk in file order
/// (one per model), which voxel records have colour index 0: MagicaVoxel treats them as
/// empty, but dot_vox reads index 0 as colour 1.
fn check_chunks(bytes: &[u8]) -> Result<Vec<Vec<bool>>, LoadErrorKind> {
    let mut empty: Vec<Vec<bool>> = Vec::new();
    walk_chunks(bytes, |id, _, c| {
        if id == b"XYZI" {
            // count, then count records of x, y, z, colour index.
            let n = c.get(..4).map_or(0, |w| {
                u32::from_le_bytes(w.try_into().expect("4 bytes")) as usize
            });
            let records = n.min(c.len().saturating_sub(4) / 4);
            let flags: Vec<bool> = (0..records).map(|k| c[4 + 4 * k + 3] == 0).collect();
            empty.push(if flags.iter().any(|&f| f) {
                flags
            } else {
                Vec::new()
            });
        }
        Ok(())
    })?;
    Ok(empty)
}

/// Whether record `k` of model `id` is an empty voxel (colour index 0 in the file).
fn is_empty(empty: &[Vec<bool>], id: usize, k: usize) -> bool {
    empty
        .get(id)
        .and_then(|f| f.get(k))
        .copied()
        .unwrap_or(false)
}

/// The first chunk (id and byte offset) whose content does not have the structure of its
/// kind (fixed sizes; counts; the DICTs and strings of the scene-graph, material and
/// layer chunks), with what is wrong; `None` when every known chunk is well formed.
/// Only for messages, after dot_vox failed: the walk itself passed [`check_chunks`].
fn first_malformed_chunk(bytes: &[u8]) -> Option<String> {
    // A reader over one chunk's content.
    struct R<'a> {
        b: &'a [u8],
        at: usize,
    }
    impl R<'_> {
        fn i32(&mut self) -> Result<i64, String> {
            let w = self.b.get(self.at..self.at + 4).ok_or_else(|| {
                format!("its content ends at byte {} inside a number", self.b.len())
            })?;
            self.at += 4;
            Ok(i32::from_le_bytes(w.try_into().expect("4 bytes")) as i64)
        }
        fn count(&mut self, what: &str) -> Result<usize, String> {
            let n = self.i32()?;
            if n < 0 || n as usize > self.b.len() {
                return Err(format!(
                    "{what} count {n} cannot fit its {} bytes",
                    self.b.len()
                ));
            }
            Ok(n as usize)
        }
        fn string(&mut self) -> Result<(), String> {
            let n = self.count("string length")?;
            if self.at + n > self.b.len() {
                return Err(format!("a string of {n} bytes runs past its content"));
            }
            self.at += n;
            Ok(())
        }
        fn dict(&mut self) -> Result<(), String> {
            for _ in 0..self.count("DICT entry")? {
                self.string()?;
                self.string()?;
            }
            Ok(())
        }
    }
    let check = |id: &[u8], c: &[u8]| -> Result<(), String> {
        let mut r = R { b: c, at: 0 };
        match id {
            b"SIZE" if c.len() != 12 => Err(format!("{} content bytes; SIZE has 12", c.len())),
            b"XYZI" => {
                let n = r.count("voxel")?;
                if c.len() != 4 + 4 * n {
                    return Err(format!(
                        "{n} voxels need {} bytes; it has {}",
                        4 + 4 * n,
                        c.len()
                    ));
                }
                Ok(())
            }
            b"RGBA" if c.len() != 1024 => Err(format!("{} content bytes; RGBA has 1024", c.len())),
            b"nTRN" => {
                r.i32()?;
                r.dict()?;
                r.i32()?;
                r.i32()?;
                r.i32()?;
                for _ in 0..r.count("frame")? {
                    r.dict()?;
                }
                Ok(())
            }
            b"nGRP" => {
                r.i32()?;
                r.dict()?;
                for _ in 0..r.count("child")? {
                    r.i32()?;
                }
                Ok(())
            }
            b"nSHP" => {
                r.i32()?;
                r.dict()?;
                for _ in 0..r.count("model")? {
                    r.i32()?;
                    r.dict()?;
                }
                Ok(())
            }
            b"MATL" | b"rCAM" => {
                r.i32()?;
                r.dict()
            }
            b"LAYR" => {
                r.i32()?;
                r.dict()?;
                r.i32().map(|_| ())
            }
            b"rOBJ" => r.dict(),
            _ => Ok(()),
        }
    };
    match walk_chunks(bytes, |id, _, c| check(id, c)) {
        Err(LoadErrorKind::InvalidVox(m)) => Some(m),
        _ => None,
    }
}

/// One function because a .vox file's models, placements, palette and materials are
/// checked against one another in one pass over its data, and the grid is filled by
/// the same pass, dense or into bricks.
fn vox_from_data(
    data: &DotVoxData,
    model: Option<usize>,
    empty: &[Vec<bool>],
    storage: Storage,
) -> Result<VoxScene, LoadErrorKind> {
    let invalid = LoadErrorKind::InvalidVox;
    let count = data.models.len();
    if count == 0 {
        return Err(match model {
            Some(index) => LoadErrorKind::ModelOutOfRange { index, count },
            None => invalid("it holds no models (no SIZE and XYZI chunks)".into()),
        });
    }
    let placements: Vec<(usize, Place)> = match model {
        Some(index) if index >= count => {
            return Err(LoadErrorKind::ModelOutOfRange { index, count });
        }
        Some(index) => vec![(index, Place::Local)],
        // Without a scene graph (files before MagicaVoxel 0.99) several models are the
        // frames of an animation: MagicaVoxel shows frame 0, and so does voxlab.
        None if data.scenes.is_empty() => vec![(0, Place::Local)],
        None => {
            let mut out = Vec::new();
            walk_graph(data, 0, IDENTITY, [0; 3], 0, &mut out).map_err(invalid)?;
            if out.is_empty() {
                // MagicaVoxel shows an empty scene; voxlab has no grid to make of it.
                return Err(invalid(format!(
                    "its scene graph shows none of its {count} model(s): every shape node \
                     is under a node or layer marked hidden, or there is none (one model \
                     can be loaded alone with `scene.model`)"
                )));
            }
            out
        }
    };

    // Check every voxel against its model's SIZE, and bound the placed cells.
    let cell_of = |place: &Place, size: dot_vox::Size, v: [f64; 3]| -> [i64; 3] {
        match place {
            Place::Local => v.map(|x| x as i64),
            Place::Graph { rot, t } => {
                let pivot = [size.x, size.y, size.z].map(|s| (s / 2) as f64);
                let p = [0, 1, 2].map(|k| v[k] - pivot[k]);
                let q = rot_apply(rot, p);
                [0, 1, 2].map(|k| (q[k] + t[k] as f64).floor() as i64)
            }
        }
    };
    let mut lo = [i64::MAX; 3];
    let mut hi = [i64::MIN; 3];
    for (id, place) in &placements {
        let m = &data.models[*id];
        let s = m.size;
        if let Some(v) = m
            .voxels
            .iter()
            .find(|v| v.x as u32 >= s.x || v.y as u32 >= s.y || v.z as u32 >= s.z)
        {
            return Err(invalid(format!(
                "model {id}: voxel ({}, {}, {}) lies outside its size {} x {} x {}",
                v.x, v.y, v.z, s.x, s.y, s.z
            )));
        }
        if s.x == 0 || s.y == 0 || s.z == 0 {
            continue;
        }
        // The model's box: its two extreme corners, through the placement. The cell of
        // a corner is found via the voxel centres next to it.
        for c in [
            [0.5, 0.5, 0.5],
            [s.x as f64 - 0.5, s.y as f64 - 0.5, s.z as f64 - 0.5],
        ] {
            let cell = cell_of(place, s, c);
            for k in 0..3 {
                lo[k] = lo[k].min(cell[k]);
                hi[k] = hi[k].max(cell[k] + 1);
            }
        }
    }
    if lo[0] > hi[0] {
        return Err(invalid("every model placed has an empty size".into()));
    }
    let ext = [0, 1, 2].map(|k| hi[k] - lo[k]);
    let total = ext.iter().map(|&e| e as f64).product::<f64>();
    let sparse = storage.is_sparse_for(total.min(u64::MAX as f64) as u64);
    if sparse && ext.iter().any(|&e| e > i64::from(MAX_SPARSE_SIDE)) {
        return Err(LoadErrorKind::TooLarge(format!(
            "the models span {} x {} x {} voxels; a sparse grid's sides are at most \
             {MAX_SPARSE_SIDE}",
            ext[0], ext[1], ext[2]
        )));
    }
    if !sparse && (total > MAX_VOXELS as f64 || ext.iter().any(|&e| e > u32::MAX as i64)) {
        return Err(LoadErrorKind::TooLarge(format!(
            "the models span {} x {} x {} voxels; at most {MAX_VOXELS} in all are allowed",
            ext[0], ext[1], ext[2]
        )));
    }

    // Palette: voxel index i (dot_vox subtracts 1 from the file's 1..=255) is
    // palette[i]; MATL ids are the file's colour indices, i + 1.
    let mut used = [false; 256];
    for (id, _) in &placements {
        for (k, v) in data.models[*id].voxels.iter().enumerate() {
            if !is_empty(empty, *id, k) {
                used[v.i as usize] = true;
            }
        }
    }
    let matl: HashMap<u32, &dot_vox::Material> = data.materials.iter().map(|m| (m.id, m)).collect();
    let mut remap = [VOID; 256];
    let mut materials = vec![diffuse_material("void", DVec3::ZERO)];
    materials[0].kd = 0.0;
    materials[0].ks = 0.0;
    materials[0].kt = 1.0;
    let mut palette_index = vec![0u8];
    for i in (0..256).filter(|&i| used[i]) {
        let Some(&c) = data.palette.get(i) else {
            return Err(invalid(format!(
                "a voxel uses colour index {} but the palette holds only {} colours",
                i + 1,
                data.palette.len()
            )));
        };
        if materials.len() > 255 {
            return Err(LoadErrorKind::TooLarge(
                "more than 255 distinct colours are used; voxlab materials are u8 with 0 void"
                    .into(),
            ));
        }
        remap[i] = materials.len() as u8;
        let file_index = i as u32 + 1;
        materials.push(vox_material(file_index, c, matl.get(&file_index).copied()));
        palette_index.push(file_index.min(255) as u8);
    }

    let dims = UVec3::new(ext[0] as u32, ext[2] as u32, ext[1] as u32);
    // Dense, or straight into bricks and a tree: the same voxels either way
    // (`tests/sparse_sources.rs`).
    let mut target = if sparse {
        VoxTarget::Sparse(BrickSource::new(dims))
    } else {
        VoxTarget::Dense(Grid::new(dims, 1.0, DVec3::ZERO).map_err(|e| invalid(e.0))?)
    };
    for (id, place) in &placements {
        let m = &data.models[*id];
        for (k, v) in m.voxels.iter().enumerate() {
            if is_empty(empty, *id, k) {
                continue;
            }
            let c = [v.x as f64 + 0.5, v.y as f64 + 0.5, v.z as f64 + 0.5];
            let cell = cell_of(place, m.size, c);
            let g = IVec3::new(
                (cell[0] - lo[0]) as i32,
                (cell[2] - lo[2]) as i32,
                (hi[1] - 1 - cell[1]) as i32,
            );
            match &mut target {
                VoxTarget::Dense(grid) => grid.set(g, remap[v.i as usize]),
                VoxTarget::Sparse(bricks) => {
                    bricks.set(g, remap[v.i as usize]);
                    if bricks.brick_count() > MAX_VOX_BRICKS {
                        return Err(LoadErrorKind::TooLarge(format!(
                            "the models place voxels in more than {MAX_VOX_BRICKS} blocks of \
                             4x4x4 (a sparse grid's bound on host memory)"
                        )));
                    }
                }
            }
        }
    }
    let grid = match target {
        VoxTarget::Dense(grid) => grid,
        VoxTarget::Sparse(bricks) => {
            let tree = bricks.into_tree(crate::sparse::GPU_LOG_BRANCH);
            Grid::from_tree(tree, 1.0, DVec3::ZERO).map_err(|e| invalid(e.0))?
        }
    };
    Ok(VoxScene {
        grid,
        materials,
        palette_index,
        model_count: count,
    })
}

/// Most 4x4x4 blocks a `.vox` scene held sparse may fill: 2^24 of 64 bytes, 1 GiB.
pub(crate) const MAX_VOX_BRICKS: usize = 1 << 24;

enum VoxTarget {
    Dense(Grid),
    Sparse(BrickSource),
}

/// Writes `grid` as a MagicaVoxel `.vox` file (SIZE, XYZI, RGBA, MATL chunks, version
/// 150), the inverse of [`load_vox`]'s axis mapping. Voxlab material `m` becomes
/// colour index `m` with its albedo as the colour; glass, metal and emissive materials
/// get a MATL chunk of that type (kt, ior, kr and emission are kept approximately;
/// kd, ks, shininess and sigma have no `.vox` equivalent). MagicaVoxel models hold at
/// most 256 voxels per side, so a larger grid is split into 256-voxel blocks, one model
/// each, placed by a scene graph (loading places them back exactly). Voxel size and
/// origin are not stored. The file is written beside its destination and renamed into
/// place, so an error never leaves a half-written file.
pub fn write_vox(
    path: impl AsRef<Path>,
    grid: &Grid,
    materials: &[Material],
) -> Result<(), LoadError> {
    let path = path.as_ref();
    let fail = |kind| LoadError::new(path, kind);
    let max = grid.max_material() as usize;
    if max >= materials.len() {
        return Err(fail(LoadErrorKind::InvalidOption(format!(
            "the grid uses material {max} but only {} materials are given",
            materials.len()
        ))));
    }
    let dense = grid
        .to_dense()
        .map_err(|e| fail(LoadErrorKind::TooLarge(e.0)))?;
    let data = vox_data(&dense, materials);
    let mut bytes = Vec::new();
    data.write_vox(&mut bytes)
        .map_err(|e| fail(LoadErrorKind::Write(e)))?;

    // Into an existing directory only (a mistyped path makes no new tree), and as every
    // output: complete or not at all, and any name the file system takes.
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty())
        && !dir.is_dir()
    {
        return Err(fail(LoadErrorKind::Write(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!("its directory {} does not exist", dir.display()),
        ))));
    }
    crate::output::write_file(path, &bytes)
        .map_err(|e| fail(LoadErrorKind::Write(std::io::Error::other(e.cause()))))
}

fn vox_data(grid: &Grid, materials: &[Material]) -> DotVoxData {
    use dot_vox::{Dict, Frame, Layer, Model, ShapeModel, Size, Voxel};
    let d = grid.dims();
    // MagicaVoxel-space dimensions: (x, y, z) = (X, nz - 1 - Z, Y).
    let vd = [d.x, d.z, d.y];
    let blocks = vd.map(|n| n.div_ceil(VOX_MODEL_MAX));
    let block_index = |b: [u32; 3]| (b[0] + blocks[0] * (b[1] + blocks[1] * b[2])) as usize;
    let mut models: Vec<Model> = Vec::new();
    let mut offsets = Vec::new();
    for bz in 0..blocks[2] {
        for by in 0..blocks[1] {
            for bx in 0..blocks[0] {
                let o = [bx, by, bz].map(|b| b * VOX_MODEL_MAX);
                let s = [0, 1, 2].map(|k| (vd[k] - o[k]).min(VOX_MODEL_MAX));
                models.push(Model {
                    size: Size {
                        x: s[0],
                        y: s[1],
                        z: s[2],
                    },
                    voxels: Vec::new(),
                });
                offsets.push((o, s));
            }
        }
    }
    let data = grid.data();
    let (nx, ny) = (d.x as usize, d.y as usize);
    for (i, &m) in data.iter().enumerate() {
        if m == VOID {
            continue;
        }
        let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
        let v = [x as u32, d.z - 1 - z as u32, y as u32];
        let b = v.map(|c| c / VOX_MODEL_MAX);
        let r = v.map(|c| (c % VOX_MODEL_MAX) as u8);
        models[block_index(b)].voxels.push(Voxel {
            x: r[0],
            y: r[1],
            z: r[2],
            i: m - 1,
        });
    }

    let mut palette = dot_vox::DEFAULT_PALETTE.clone();
    palette.resize(
        256,
        Color {
            r: 0,
            g: 0,
            b: 0,
            a: 255,
        },
    );
    let mut matl = Vec::new();
    for (k, m) in materials.iter().enumerate().skip(1).take(255) {
        let b = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
        palette[k - 1] = Color {
            r: b(m.albedo.x),
            g: b(m.albedo.y),
            b: b(m.albedo.z),
            a: 255,
        };
        let mut props = Dict::new();
        let mut set = |key: &str, v: String| {
            props.insert(key.to_string(), v);
        };
        if m.kt > 0.0 {
            set("_type", "_glass".into());
            set("_trans", format!("{}", m.kt));
            set("_ior", format!("{}", m.ior - 1.0));
        } else if m.kr > 0.0 {
            set("_type", "_metal".into());
            set("_metal", format!("{}", m.kr));
            set("_rough", format!("{}", (1.0 - m.ks).clamp(0.0, 1.0)));
        } else if m.emission.max_element() > 0.0 {
            let a = m.albedo.max_element().max(1e-6);
            set("_type", "_emit".into());
            set("_emit", format!("{}", m.emission.max_element() / a));
        } else {
            continue;
        }
        matl.push(dot_vox::Material {
            id: k as u32,
            properties: props,
        });
    }

    // One model needs no scene graph (the original format, read by every version);
    // several are placed by translations chosen so that, with MagicaVoxel's pivot
    // floor(size / 2), block b's voxel v lands at b's offset + v.
    let mut scenes = Vec::new();
    let mut layers = Vec::new();
    if models.len() > 1 {
        let n = models.len() as u32;
        scenes.push(SceneNode::Transform {
            attributes: Dict::new(),
            frames: vec![Frame::new(Dict::new())],
            child: 1,
            layer_id: u32::MAX,
        });
        scenes.push(SceneNode::Group {
            attributes: Dict::new(),
            children: (0..n).map(|j| 2 + 2 * j).collect(),
        });
        for (j, (o, s)) in offsets.iter().enumerate() {
            let t = [0, 1, 2].map(|k| o[k] + s[k] / 2);
            let mut f = Dict::new();
            f.insert("_t".into(), format!("{} {} {}", t[0], t[1], t[2]));
            scenes.push(SceneNode::Transform {
                attributes: Dict::new(),
                frames: vec![Frame::new(f)],
                child: 3 + 2 * j as u32,
                layer_id: 0,
            });
            scenes.push(SceneNode::Shape {
                attributes: Dict::new(),
                models: vec![ShapeModel {
                    model_id: j as u32,
                    attributes: Dict::new(),
                }],
            });
        }
        layers.push(Layer {
            attributes: Dict::new(),
        });
    }
    DotVoxData {
        version: 150,
        index_map: Vec::new(),
        models,
        palette,
        materials: matl,
        scenes,
        layers,
    }
}
