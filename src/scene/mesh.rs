//! Mesh import (OBJ, glTF/GLB) and voxelization into a voxlab grid.
//!
//! The grid's corner is the mesh's bounding-box minimum and its voxel size is in the
//! mesh's units. Every voxel a triangle touches is solid (conservative, exact
//! separating-axis test, see [`super::voxelize`]); then every voxel the outside cannot
//! reach through void voxels is filled (cavities included), so a closed volume with
//! non-manifold edges, cracks or pinholes narrower than a voxel comes out solid. A mesh
//! is closed when, after welding vertices at identical positions, every edge is shared
//! by exactly two triangles; an open one is filled the same way and a warning says so.
//! Closedness is judged over the whole file, not per object.
//!
//! Conservative voxels cover the surface, so the solid's volume exceeds the mesh's by
//! roughly a shell of half a voxel times the surface area (about 7 % for a sphere 64
//! voxels across); it converges as 1 / resolution.
//!
//! Materials: each mesh material becomes one voxlab material, its albedo the OBJ/MTL
//! diffuse colour `Kd` or the glTF base colour factor (textures are not sampled), with
//! the matte parameters of [`super::vox::diffuse_material`]. Faces without a material
//! get a grey one. [`VoxelizeOptions::material`] replaces them all with one material.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, UVec3};

use super::vox::{LoadError, LoadErrorKind, diffuse_material};
use super::voxelize::{
    boundary_edge_count, fill_interior, grid_layout, voxelize_sparse, voxelize_triangles,
};
use super::{Grid, Material, Storage, seed_palette};

/// Largest voxel count along the longest axis that [`Resolution::Count`] accepts.
pub const MAX_RESOLUTION: u32 = 1 << 16;

/// Albedo of faces that name no material.
pub(crate) const DEFAULT_MESH_ALBEDO: f64 = 0.8;

/// How finely to voxelize.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Resolution {
    /// This many voxels along the mesh's longest bounding-box axis.
    Count(u32),
    /// Voxels of this width, in the mesh's units.
    VoxelSize(f64),
}

#[derive(Clone, Debug, PartialEq)]
pub struct VoxelizeOptions {
    pub resolution: Resolution,
    /// One material for the whole mesh instead of the file's own.
    pub material: Option<Material>,
    /// Whether the grid is dense or a sparse tree voxelized straight from the triangles
    /// (`Auto`: sparse past `DENSE_MAX_VOXELS`).
    pub storage: Storage,
}

impl VoxelizeOptions {
    pub fn count(n: u32) -> Self {
        Self {
            resolution: Resolution::Count(n),
            material: None,
            storage: Storage::Auto,
        }
    }
}

/// A voxelized mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Voxelized {
    pub grid: Grid,
    /// Index 0 is void.
    pub materials: Vec<Material>,
    /// Things the caller should tell the user (an open mesh, skipped primitives).
    pub warnings: Vec<String>,
    /// Whether the mesh was closed (every welded edge shared by exactly two triangles).
    /// The interior is filled either way: see `interior_voxels`.
    pub closed: bool,
    pub triangle_count: usize,
    /// Voxels touched by the surface, and voxels filled inside it.
    pub shell_voxels: usize,
    pub interior_voxels: usize,
    /// The triangles, in the mesh's coordinates (the grid's world), with the grid's
    /// material indices and face normals: what `render.surface = "mesh"` traces.
    pub surface: crate::surface::SurfaceMesh,
}

/// A triangle soup with one material per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    pub triangles: Vec<[DVec3; 3]>,
    /// Per triangle, the file's normals at its vertices (zero where it gives none);
    /// empty when the file gives no normals at all.
    pub normals: Vec<[DVec3; 3]>,
    /// Index into `materials` per triangle.
    pub material_of: Vec<usize>,
    pub materials: Vec<Material>,
    pub warnings: Vec<String>,
}

impl TriangleMesh {
    fn material_slot(
        &mut self,
        slots: &mut HashMap<Option<usize>, usize>,
        key: Option<usize>,
        make: impl FnOnce() -> Material,
    ) -> usize {
        *slots.entry(key).or_insert_with(|| {
            self.materials.push(make());
            self.materials.len() - 1
        })
    }
}

/// Loads an OBJ (`.obj`) or glTF (`.gltf`, `.glb`) file as triangles, with node
/// transforms applied (glTF: every mesh of the default scene, or of the first scene,
/// or every mesh untransformed if the file has no scene).
pub fn load_mesh(path: impl AsRef<Path>) -> Result<TriangleMesh, LoadError> {
    let path = path.as_ref();
    let fail = |kind| LoadError::new(path, kind);
    // Read errors first, so a missing file says so rather than a parser's guess; only a
    // regular file of at most MAX_MESH_BYTES is read.
    let bytes = crate::input::read_file(path, crate::input::MAX_MESH_BYTES, "mesh file")
        .map_err(|e| fail(LoadErrorKind::Input(e)))?;
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let mesh = match ext.as_str() {
        "obj" => load_obj(path, &bytes),
        "gltf" | "glb" => load_gltf(path, &bytes),
        _ => Err(LoadErrorKind::InvalidMesh(format!(
            "unknown mesh format {:?}: expected .obj, .gltf or .glb",
            ext
        ))),
    }
    .map_err(fail)?;
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| !t.iter().all(|p| p.is_finite()))
    {
        return Err(fail(LoadErrorKind::InvalidMesh(format!(
            "a vertex is not finite: triangle {:?}",
            t
        ))));
    }
    Ok(mesh)
}

/// One function because tobj's material loader, its panic guard and the bookkeeping of
/// which face corners name a normal all follow the one file in order (each step's
/// comment below says what it guards against).
fn load_obj(path: &Path, bytes: &[u8]) -> Result<TriangleMesh, LoadErrorKind> {
    // tobj reads a line ending in `\` as it stands; the format continues it (below).
    let joined = join_continued_lines(bytes);
    let bytes: &[u8] = &joined;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    // tobj reads a `mtllib` itself unless given a loader: this one reads it (relative to
    // the OBJ's directory, as tobj would) as a regular file of bounded size.
    // A library that cannot be read (missing, not a regular file, too large) refuses the
    // mesh, naming it: tobj alone would drop it and every material with it.
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let unreadable = std::cell::RefCell::new(None);
    let mtl_loader = |name: &Path| -> tobj::MTLLoadResult {
        let mtl_path = dir.join(name);
        match crate::input::read_file(&mtl_path, crate::input::MAX_MESH_BYTES, "material library") {
            Ok(b) => tobj::load_mtl_buf(&mut std::io::Cursor::new(b)),
            Err(e) => {
                unreadable
                    .borrow_mut()
                    .get_or_insert_with(|| format!("{}: {e}", mtl_path.display()));
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    };
    // tobj panics on some malformed lines (a `Kd` with fewer than three values): its
    // panics become errors naming the file.
    let parse = |b: &[u8]| {
        crate::input::guarded(|| {
            tobj::load_obj_buf(&mut std::io::Cursor::new(b), &options, mtl_loader)
        })
    };
    let (models, mtl) = match parse(bytes) {
        Ok(Ok(parsed)) => parsed,
        failure => {
            // tobj names no line: the first line at which a prefix of the file fails is
            // the one. A failure at a `mtllib` line lies in the material library.
            let why = match failure {
                Ok(Err(e)) => e.to_string(),
                Err(p) => format!("the parser (tobj) failed: {p}"),
                Ok(Ok(_)) => unreachable!("matched above"),
            };
            let fails = |prefix: &[u8]| !matches!(parse(prefix), Ok(Ok(_)));
            let Some((n, line)) = first_failing_line(bytes, fails) else {
                return Err(LoadErrorKind::InvalidMesh(format!("OBJ: {why}")));
            };
            let text = String::from_utf8_lossy(line);
            let text = text.trim();
            if let Some(lib) = text.strip_prefix("mtllib") {
                let mtl_path = dir.join(lib.trim());
                if let Ok(mb) = crate::input::read_file(
                    &mtl_path,
                    crate::input::MAX_MESH_BYTES,
                    "material library",
                ) {
                    let mtl_fails = |prefix: &[u8]| {
                        !matches!(
                            crate::input::guarded(|| tobj::load_mtl_buf(
                                &mut std::io::Cursor::new(prefix)
                            )),
                            Ok(Ok(_))
                        )
                    };
                    if let Some((m, mline)) = first_failing_line(&mb, mtl_fails) {
                        return Err(LoadErrorKind::InvalidMesh(format!(
                            "its material library {}, line {m} ({:?}): {why}",
                            mtl_path.display(),
                            crate::input::excerpt(String::from_utf8_lossy(mline).trim(), 80)
                        )));
                    }
                }
            }
            return Err(LoadErrorKind::InvalidMesh(format!(
                "OBJ line {n} ({:?}): {why}",
                crate::input::excerpt(text, 80)
            )));
        }
    };
    if let Some(why) = unreadable.take() {
        return Err(LoadErrorKind::InvalidMesh(format!(
            "its material library (mtllib) cannot be read: {why}"
        )));
    }
    let mut mesh = TriangleMesh::default();
    let mtl = match mtl {
        Ok(m) => m,
        Err(e) => {
            // A missing or broken .mtl should not lose the geometry.
            if !models.iter().all(|m| m.mesh.material_id.is_none()) {
                mesh.warnings.push(format!(
                    "{}: the material library could not be read ({e}); default material used",
                    path.display()
                ));
            }
            Vec::new()
        }
    };
    // Which face corners name a normal, per triangle in the file's order: tobj's models
    // are runs of the file's faces in order, each triangulated as a fan.
    let emitted: usize = models.iter().map(|m| m.mesh.indices.len() / 3).sum();
    if emitted > MAX_MESH_TRIANGLES {
        return Err(LoadErrorKind::InvalidMesh(too_many_triangles(emitted)));
    }
    let corner_normals = obj_corner_normals(bytes).filter(|c| c.len() == emitted);
    if corner_normals.is_none() && models.iter().any(|m| !m.mesh.normals.is_empty()) {
        mesh.warnings.push(format!(
            "{}: the faces' normals could not be matched to their corners; face normals used",
            path.display()
        ));
    }
    let mut slots = HashMap::new();
    let mut first_triangle = 0;
    for model in &models {
        let m = &model.mesh;
        let n = m.positions.len() / 3;
        let key = m.material_id.filter(|&i| i < mtl.len());
        let slot = mesh.material_slot(&mut slots, key, || match key {
            Some(i) => {
                let mat = &mtl[i];
                let kd = mat.diffuse.unwrap_or([DEFAULT_MESH_ALBEDO as f32; 3]);
                diffuse_material(
                    mat.name.clone(),
                    DVec3::new(kd[0] as f64, kd[1] as f64, kd[2] as f64),
                )
            }
            None => diffuse_material("mesh default", DVec3::splat(DEFAULT_MESH_ALBEDO)),
        });
        let p = |i: u32| {
            let i = i as usize * 3;
            DVec3::new(
                m.positions[i] as f64,
                m.positions[i + 1] as f64,
                m.positions[i + 2] as f64,
            )
        };
        // The file's normals, at the face corners that name one: tobj makes one up for a
        // corner without (the previous corner's, or the file's first), which must not
        // shade it.
        let normal = |k: usize| -> DVec3 {
            let given = corner_normals
                .as_ref()
                .and_then(|c| c.get(first_triangle + k / 3))
                .is_some_and(|t| t[k % 3]);
            let (true, Some(&i)) = (given, m.normal_indices.get(k)) else {
                return DVec3::ZERO;
            };
            let i = i as usize * 3;
            match m.normals.get(i..i + 3) {
                Some(v) => DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64).normalize_or_zero(),
                None => DVec3::ZERO,
            }
        };
        let with_normals = corner_normals.is_some()
            && m.normal_indices.len() == m.indices.len()
            && !m.normals.is_empty();
        for (k, f) in m.indices.chunks(3).enumerate() {
            if f.len() < 3 {
                continue;
            }
            if let Some(&bad) = f.iter().find(|&&i| i as usize >= n) {
                return Err(LoadErrorKind::InvalidMesh(format!(
                    "OBJ object {:?}: face vertex {} out of range (the object has {n} vertices)",
                    model.name,
                    bad as usize + 1
                )));
            }
            mesh.triangles.push([p(f[0]), p(f[1]), p(f[2])]);
            mesh.material_of.push(slot);
            if with_normals {
                mesh.normals
                    .resize(mesh.triangles.len() - 1, [DVec3::ZERO; 3]);
                mesh.normals
                    .push([normal(3 * k), normal(3 * k + 1), normal(3 * k + 2)]);
            }
        }
        first_triangle += m.indices.len() / 3;
    }
    if !mesh.normals.is_empty() {
        mesh.normals.resize(mesh.triangles.len(), [DVec3::ZERO; 3]);
    }
    Ok(mesh)
}

/// Per triangle of an OBJ's faces, in the file's order and triangulated as tobj does (a
/// fan from the first corner), whether each corner names a normal (`v//vn`, `v/vt/vn`).
/// `None` where a face line does not read as one (tobj then refuses the file).
/// `bytes` with each line that ends in a backslash joined to the next: the OBJ format
/// continues such a line (Wavefront, "Object Files (.obj)", Appendix B1: "a backslash
/// (\\) at the end of a line continues it"; trimesh reads it so). The newlines removed
/// are put back after the joined line, so every later line keeps its number in errors.
fn join_continued_lines(bytes: &[u8]) -> std::borrow::Cow<'_, [u8]> {
    let continued = |i: usize| -> Option<usize> {
        // The index past a backslash's line end, if the backslash at `i` ends its line.
        let j = if bytes.get(i + 1) == Some(&b'\r') {
            i + 2
        } else {
            i + 1
        };
        (bytes.get(j) == Some(&b'\n')).then_some(j + 1)
    };
    if !(0..bytes.len()).any(|i| bytes[i] == b'\\' && continued(i).is_some()) {
        return std::borrow::Cow::Borrowed(bytes);
    }
    let mut out = Vec::with_capacity(bytes.len());
    let mut owed = 0;
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'\\'
            && let Some(next) = continued(i)
        {
            out.push(b' ');
            owed += 1;
            i = next;
            continue;
        }
        out.push(bytes[i]);
        if bytes[i] == b'\n' {
            out.extend(std::iter::repeat_n(b'\n', owed));
            owed = 0;
        }
        i += 1;
    }
    std::borrow::Cow::Owned(out)
}

fn obj_corner_normals(bytes: &[u8]) -> Option<Vec<[bool; 3]>> {
    let mut out = Vec::new();
    for line in bytes.split(|&b| b == b'\n') {
        let line = std::str::from_utf8(line).ok()?;
        let mut words = line.split_whitespace();
        // tobj reads `l` lines as faces too, and keeps those of three or more corners.
        if !matches!(words.next(), Some("f" | "l")) {
            continue;
        }
        let corners: Vec<bool> = words
            .map(|w| w.split('/').nth(2).is_some_and(|vn| !vn.is_empty()))
            .collect();
        for i in 2..corners.len() {
            out.push([corners[0], corners[i - 1], corners[i]]);
        }
    }
    Some(out)
}

/// Most triangles a mesh file may give, after a glTF's nodes have placed its meshes
/// (each takes 76 to 148 bytes in memory).
pub const MAX_MESH_TRIANGLES: usize = 1 << 26;

fn too_many_triangles(n: usize) -> String {
    format!("it places {n} triangles; at most {MAX_MESH_TRIANGLES} are read")
}

/// glTF's extension for vertex attributes stored as integers, read by `gltf_vec3s`.
const QUANTIZATION: &str = "KHR_mesh_quantization";

fn load_gltf(path: &Path, bytes: &[u8]) -> Result<TriangleMesh, LoadErrorKind> {
    let invalid = |what: String| LoadErrorKind::InvalidMesh(format!("glTF: {what}"));
    // The gltf crate panics on some hostile documents (an index into a missing
    // accessor, index accessors of a float type): every call into it is guarded.
    let panicked = |p: String| invalid(format!("the glTF parser (gltf) failed on it: {p}"));
    // A required extension the reader lacks (Draco compression, say) is the reason to
    // give, before any validation error its missing data would cause.
    let raw = crate::input::guarded(|| gltf::Gltf::from_slice_without_validation(bytes))
        .map_err(panicked)?
        .map_err(|e| invalid(e.to_string()))?;
    let missing: Vec<&str> = raw
        .document
        .extensions_required()
        .filter(|e| !gltf::json::extensions::ENABLED_EXTENSIONS.contains(e) && *e != QUANTIZATION)
        .collect();
    if !missing.is_empty() {
        return Err(invalid(format!(
            "it requires the extension(s) {}, which voxlab's glTF reader does not support",
            missing.join(", ")
        )));
    }
    // The gltf crate validates everything but does not know the quantization extension,
    // which voxlab reads itself (`gltf_vec3s`): validated without it in the list.
    let gltf::Gltf { document, blob } = raw;
    let mut json = document.into_json();
    json.extensions_required.retain(|e| e != QUANTIZATION);
    let document = crate::input::guarded(|| gltf::Document::from_json(json))
        .map_err(panicked)?
        .map_err(|e| invalid(e.to_string()))?;
    let gltf = gltf::Gltf { document, blob };
    let buffers = gltf_buffers(&gltf, path).map_err(invalid)?;
    let mut mesh = crate::input::guarded(|| gltf_triangles(&gltf.document, &buffers))
        .map_err(panicked)?
        .map_err(invalid)?;
    // Integer attributes in a file that does not declare the extension break the
    // specification (its validator refuses them); read as the extension reads them, and
    // said so, since another reader may refuse or misread the file.
    if !gltf.document.extensions_used().any(|e| e == QUANTIZATION) {
        let integer = gltf
            .document
            .meshes()
            .flat_map(|m| m.primitives())
            .find_map(|p| {
                p.attributes().find(|(semantic, acc)| {
                    matches!(
                        semantic,
                        gltf::Semantic::Positions | gltf::Semantic::Normals
                    ) && acc.data_type() != gltf::accessor::DataType::F32
                })
            });
        if let Some((semantic, acc)) = integer {
            let semantic = match semantic {
                gltf::Semantic::Positions => "POSITION",
                _ => "NORMAL",
            };
            mesh.warnings.push(format!(
                "glTF: {semantic} accessor {} holds {} numbers, which only {QUANTIZATION} \
                 allows, and the file does not declare it; read as that extension reads them",
                acc.index(),
                component_name(acc.data_type())
            ));
        }
    }
    Ok(mesh)
}

/// The glTF's buffers: the GLB's binary chunk, `data:` URIs (base64), or files
/// beside it read as regular files of bounded size; each at least its declared length.
fn gltf_buffers(gltf: &gltf::Gltf, path: &Path) -> Result<Vec<gltf::buffer::Data>, String> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out = Vec::new();
    for buffer in gltf.document.buffers() {
        let i = buffer.index();
        let mut data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| format!("buffer {i} names the binary chunk, which is missing"))?,
            gltf::buffer::Source::Uri(uri) => {
                if let Some(rest) = uri.strip_prefix("data:") {
                    let (_, payload) = rest.split_once(";base64,").ok_or_else(|| {
                        format!("buffer {i}: a data URI that is not base64 (\"data:...;base64,\")")
                    })?;
                    base64::decode(payload)
                        .map_err(|e| format!("buffer {i}: its base64 data URI: {e}"))?
                } else {
                    let name = percent_encoding::percent_decode_str(uri)
                        .decode_utf8()
                        .map_err(|_| {
                            format!(
                                "buffer {i}: its URI {:?} percent-decodes to invalid UTF-8",
                                crate::input::excerpt(uri, 80)
                            )
                        })?;
                    // A URI with a scheme is no relative path: file: URIs name a local
                    // file (RFC 8089; host empty or localhost), others are not fetched.
                    let scheme = name.split_once(':').map(|(s, _)| s).filter(|s| {
                        s.len() > 1
                            && s.chars()
                                .all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
                    });
                    let file = match scheme {
                        None => dir.join(name.as_ref()),
                        Some(s) if s.eq_ignore_ascii_case("file") => {
                            let rest = &name[s.len() + 1..];
                            let local = rest
                                .strip_prefix("//localhost/")
                                .map(|p| format!("/{p}"))
                                .or_else(|| rest.strip_prefix("//").map(str::to_string))
                                .unwrap_or_else(|| rest.to_string());
                            if !local.starts_with('/') {
                                return Err(format!(
                                    "buffer {i}: its URI {:?} names a file on another host",
                                    crate::input::excerpt(uri, 80)
                                ));
                            }
                            PathBuf::from(local)
                        }
                        Some(s) => {
                            return Err(format!(
                                "buffer {i}: its URI {:?} is a {s}: URI; only relative paths, \
                                 file: and data: URIs are read",
                                crate::input::excerpt(uri, 80)
                            ));
                        }
                    };
                    crate::input::read_file(&file, crate::input::MAX_MESH_BYTES, "glTF buffer")
                        .map_err(|e| format!("buffer {i} ({}): {e}", file.display()))?
                }
            }
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {i} holds {} bytes but declares {}",
                data.len(),
                buffer.length()
            ));
        }
        // As the gltf crate's importer: padded to a multiple of 4.
        while data.len() % 4 != 0 {
            data.push(0);
        }
        out.push(gltf::buffer::Data(data));
    }
    Ok(out)
}

/// One function because a primitive's checks (mode, indices, accessor bounds, normals,
/// material) read the same accessors in turn, each refusing the file with its own
/// message before any triangle is kept.
fn gltf_triangles(
    doc: &gltf::Document,
    buffers: &[gltf::buffer::Data],
) -> Result<TriangleMesh, String> {
    let mut mesh = TriangleMesh::default();
    let mut slots = HashMap::new();
    let mut add = |m: gltf::Mesh,
                   xf: DMat4,
                   weights: &[f32],
                   mesh: &mut TriangleMesh|
     -> Result<(), String> {
        for prim in m.primitives() {
            use gltf::mesh::Mode;
            let mode = prim.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                mesh.warnings.push(format!(
                    "mesh {}: a {mode:?} primitive has no surface and was skipped",
                    m.index()
                ));
                continue;
            }
            // glTF allows only unsigned integer indices; the gltf crate's reader treats
            // any other type as unreachable.
            if let Some(acc) = prim.indices() {
                use gltf::accessor::{DataType, Dimensions};
                if !matches!(
                    acc.data_type(),
                    DataType::U8 | DataType::U16 | DataType::U32
                ) || acc.dimensions() != Dimensions::Scalar
                {
                    return Err(format!(
                        "mesh {}: index accessor {} is {:?} {:?}; indices must be scalar \
                         UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT",
                        m.index(),
                        acc.index(),
                        acc.data_type(),
                        acc.dimensions()
                    ));
                }
            }
            let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
            let Some(pos) = prim.get(&gltf::Semantic::Positions) else {
                continue;
            };
            let at = |e: String| format!("mesh {}: {e}", m.index());
            let mut pos = gltf_vec3s(&pos, buffers, "POSITION").map_err(at)?;
            let mut normals = match prim.get(&gltf::Semantic::Normals) {
                Some(acc) => gltf_vec3s(&acc, buffers, "NORMAL").map_err(at)?,
                None => Vec::new(),
            };
            // Morph targets (glTF 2.0, 3.7.2.2): the shape shown is the base plus each
            // target's displacement times its weight (the node's, else the mesh's, else
            // 0); a file exported with shape keys set holds its shape this way.
            for (k, target) in prim.morph_targets().enumerate() {
                let w = weights.get(k).map_or(0.0, |&w| w as f64);
                if w == 0.0 {
                    continue;
                }
                for (acc, base, what) in [
                    (target.positions(), &mut pos, "POSITION"),
                    (target.normals(), &mut normals, "NORMAL"),
                ] {
                    let (Some(acc), false) = (acc, base.is_empty()) else {
                        continue;
                    };
                    let what = format!("morph target {k}'s {what}");
                    let d = gltf_vec3s(&acc, buffers, &what).map_err(at)?;
                    if d.len() != base.len() {
                        return Err(at(format!(
                            "{what} accessor {} holds {} elements for {} vertices",
                            acc.index(),
                            d.len(),
                            base.len()
                        )));
                    }
                    for (b, d) in base.iter_mut().zip(d) {
                        *b += w * d;
                    }
                }
            }
            let pos: Vec<DVec3> = pos.into_iter().map(|p| xf.transform_point3(p)).collect();
            // Normals go through the inverse transpose of the node's transform.
            let normal_xf = glam::DMat3::from_mat4(xf).inverse().transpose();
            let normals: Vec<DVec3> = normals
                .into_iter()
                .map(|v| (normal_xf * v).normalize_or_zero())
                .collect();
            let normals = if normals.len() == pos.len() {
                normals
            } else {
                Vec::new()
            };
            let idx: Vec<u32> = match reader.read_indices() {
                Some(i) => i.into_u32().collect(),
                None => (0..pos.len() as u32).collect(),
            };
            // The readers stop quietly at the end of a buffer view: a short read is
            // a file that claims more data than it holds.
            let want_pos = prim.get(&gltf::Semantic::Positions).map(|a| a.count());
            let want_idx = prim.indices().map(|a| a.count());
            if want_pos.is_some_and(|n| n != pos.len()) || want_idx.is_some_and(|n| n != idx.len())
            {
                return Err(format!(
                    "mesh {}: an accessor claims more elements than its buffer view holds",
                    m.index()
                ));
            }
            if let Some(&bad) = idx.iter().find(|&&i| i as usize >= pos.len()) {
                return Err(format!(
                    "mesh {}: index {bad} out of range ({} vertices)",
                    m.index(),
                    pos.len()
                ));
            }
            let material = prim.material();
            let slot = mesh.material_slot(&mut slots, material.index(), || {
                let c = material.pbr_metallic_roughness().base_color_factor();
                // Material names need the gltf crate's "names" feature, not enabled.
                let name = match material.index() {
                    Some(i) => format!("gltf material {i}"),
                    None => "gltf default".to_string(),
                };
                diffuse_material(name, DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
            });
            let tri = |a: u32, b: u32, c: u32| [pos[a as usize], pos[b as usize], pos[c as usize]];
            let before = mesh.triangles.len();
            let mut corners: Vec<[u32; 3]> = Vec::new();
            let n = idx.len();
            match mode {
                Mode::Triangles => {
                    for f in idx.chunks_exact(3) {
                        mesh.triangles.push(tri(f[0], f[1], f[2]));
                        corners.push([f[0], f[1], f[2]]);
                    }
                }
                Mode::TriangleStrip => {
                    for k in 0..n.saturating_sub(2) {
                        // Every other triangle of a strip is wound the other way.
                        let (a, b) = if k % 2 == 0 { (k, k + 1) } else { (k + 1, k) };
                        mesh.triangles.push(tri(idx[a], idx[b], idx[k + 2]));
                        corners.push([idx[a], idx[b], idx[k + 2]]);
                    }
                }
                _ => {
                    for k in 1..n.saturating_sub(1) {
                        mesh.triangles.push(tri(idx[0], idx[k], idx[k + 1]));
                        corners.push([idx[0], idx[k], idx[k + 1]]);
                    }
                }
            }
            mesh.material_of.resize(mesh.triangles.len(), slot);
            if !normals.is_empty() {
                mesh.normals.resize(before, [DVec3::ZERO; 3]);
                mesh.normals
                    .extend(corners.iter().map(|c| c.map(|i| normals[i as usize])));
            }
        }
        Ok(())
    };

    // Where each mesh is placed, with its morph weights, before any is read.
    let mut placed: Vec<(gltf::Mesh, DMat4, &[f32])> = Vec::new();
    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    match scene {
        Some(scene) => {
            // Explicit stack with depth: glTF forbids cycles, but the file may lie.
            let mut stack: Vec<(gltf::Node, DMat4, usize)> =
                scene.nodes().map(|n| (n, DMat4::IDENTITY, 0)).collect();
            let mut visited = 0usize;
            while let Some((node, parent, depth)) = stack.pop() {
                visited += 1;
                if depth > 256 || visited > 1 << 20 {
                    return Err("the node hierarchy is too deep or cyclic".into());
                }
                let m = node.transform().matrix();
                let local = DMat4::from_cols_array_2d(&m.map(|c| c.map(|x| x as f64)));
                let xf = parent * local;
                if let Some(m) = node.mesh() {
                    if node.skin().is_some() {
                        mesh.warnings.push(format!(
                            "glTF: node {}'s mesh {} is skinned; it is read without its \
                             skin, under the node's transform (which skinning ignores), so \
                             its pose and place may differ from a skinning viewer's",
                            node.index(),
                            m.index()
                        ));
                    }
                    let weights = node.weights().or(m.weights()).unwrap_or(&[]);
                    placed.push((m, xf, weights));
                }
                for c in node.children() {
                    stack.push((c, xf, depth + 1));
                }
            }
        }
        None => {
            for m in doc.meshes() {
                let weights = m.weights().unwrap_or(&[]);
                placed.push((m, DMat4::IDENTITY, weights));
            }
        }
    }
    // Nodes may place one mesh many times: a small file can ask for more triangles
    // than memory holds. Counted from the accessors' declared counts, before reading.
    let triangles = placed
        .iter()
        .flat_map(|(m, _, _)| m.primitives())
        .map(|p| {
            use gltf::mesh::Mode;
            let corners = p
                .indices()
                .or_else(|| p.get(&gltf::Semantic::Positions))
                .map_or(0, |a| a.count());
            match p.mode() {
                Mode::Triangles => corners / 3,
                Mode::TriangleStrip | Mode::TriangleFan => corners.saturating_sub(2),
                _ => 0,
            }
        })
        .fold(0usize, usize::saturating_add);
    if triangles > MAX_MESH_TRIANGLES {
        return Err(too_many_triangles(triangles));
    }
    for (m, xf, weights) in placed {
        add(m, xf, weights, &mut mesh)?;
    }
    Ok(mesh)
}

/// A vertex attribute's VEC3 elements as f64. Besides floats, the integer types of
/// `KHR_mesh_quantization` (what gltfpack writes): signed and unsigned bytes and shorts,
/// normalized or not, dequantized by the glTF 2.0 specification's rules (section 3.11:
/// `max(c / 127, -1)`, `c / 255`, `max(c / 32767, -1)`, `c / 65535`); the offset and scale
/// that map them back to the model's units are in the node's transform. An accessor whose
/// buffer view holds fewer elements than it claims gives fewer; the caller compares.
fn gltf_vec3s(
    acc: &gltf::Accessor,
    buffers: &[gltf::buffer::Data],
    semantic: &str,
) -> Result<Vec<DVec3>, String> {
    use gltf::accessor::{DataType, Dimensions, Iter};
    if acc.dimensions() != Dimensions::Vec3 {
        return Err(format!(
            "{semantic} accessor {} is {}; it must be VEC3",
            acc.index(),
            format!("{:?}", acc.dimensions()).to_uppercase()
        ));
    }
    fn read<T: gltf::accessor::Item + Copy>(
        acc: &gltf::Accessor,
        buffers: &[gltf::buffer::Data],
        to_f64: impl Fn(T) -> f64,
    ) -> Vec<DVec3> {
        let data = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);
        Iter::<[T; 3]>::new(acc.clone(), data).map_or_else(Vec::new, |it| {
            it.map(|v| DVec3::new(to_f64(v[0]), to_f64(v[1]), to_f64(v[2])))
                .collect()
        })
    }
    let normalized = acc.normalized();
    Ok(match acc.data_type() {
        DataType::F32 => read(acc, buffers, |c: f32| c as f64),
        DataType::I8 if normalized => read(acc, buffers, |c: i8| (c as f64 / 127.0).max(-1.0)),
        DataType::U8 if normalized => read(acc, buffers, |c: u8| c as f64 / 255.0),
        DataType::I16 if normalized => read(acc, buffers, |c: i16| (c as f64 / 32767.0).max(-1.0)),
        DataType::U16 if normalized => read(acc, buffers, |c: u16| c as f64 / 65535.0),
        DataType::I8 => read(acc, buffers, |c: i8| c as f64),
        DataType::U8 => read(acc, buffers, |c: u8| c as f64),
        DataType::I16 => read(acc, buffers, |c: i16| c as f64),
        DataType::U16 => read(acc, buffers, |c: u16| c as f64),
        DataType::U32 => {
            return Err(format!(
                "{semantic} accessor {} is UNSIGNED_INT; a vertex attribute is FLOAT, or \
                 under {QUANTIZATION} a byte or short",
                acc.index()
            ));
        }
    })
}

/// A component type as the glTF specification spells it.
fn component_name(t: gltf::accessor::DataType) -> &'static str {
    use gltf::accessor::DataType;
    match t {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

/// The first line (1-based, with its text) at which the prefix of `bytes` ending there
/// `fails`, by bisection over line ends: a line-by-line parser that stops at its first
/// bad line fails on every longer prefix too. `None` if even the whole does not fail.
fn first_failing_line(bytes: &[u8], fails: impl Fn(&[u8]) -> bool) -> Option<(usize, &[u8])> {
    let mut ends: Vec<usize> = bytes
        .iter()
        .enumerate()
        .filter(|(_, b)| **b == b'\n')
        .map(|(i, _)| i + 1)
        .collect();
    if ends.last() != Some(&bytes.len()) {
        ends.push(bytes.len());
    }
    if !fails(bytes) {
        return None;
    }
    // The smallest k whose prefix of k + 1 lines fails.
    let (mut lo, mut hi) = (0usize, ends.len() - 1);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if fails(&bytes[..ends[mid]]) {
            hi = mid;
        } else {
            lo = mid + 1;
        }
    }
    let start = if lo == 0 { 0 } else { ends[lo - 1] };
    Some((lo + 1, &bytes[start..ends[lo]]))
}

/// `mesh` voxelized at `resolution` voxels along its longest axis, all in `material`
/// (its interior filled), keeping its triangles, lit and framed as the seed scene is:
/// a mesh scene without an experiment file (`voxlab bench --torus`, the tests).
pub fn seed_lit_scene(
    mesh: &TriangleMesh,
    resolution: u32,
    material: Material,
) -> Result<super::Scene, LoadErrorKind> {
    let v = voxelize(
        mesh,
        &VoxelizeOptions {
            resolution: Resolution::Count(resolution),
            material: Some(material),
            storage: Storage::Auto,
        },
    )?;
    let (c, w) = (v.grid.centre(), v.grid.width());
    Ok(super::Scene {
        lights: super::seed::seed_lights(c, w),
        camera: super::seed::seed_camera(c, w),
        ambient: super::seed::SEED_AMBIENT,
        materials: v.materials,
        mesh: Some(std::sync::Arc::new(v.surface)),
        grid: v.grid,
    })
}

/// Loads a mesh file and voxelizes it; see the module documentation.
pub fn voxelize_mesh(
    path: impl AsRef<Path>,
    options: &VoxelizeOptions,
) -> Result<Voxelized, LoadError> {
    let path = path.as_ref();
    let mut mesh = load_mesh(path)?;
    let mut v = voxelize(&mesh, options).map_err(|k| LoadError::new(path, k))?;
    for w in v.warnings.iter_mut() {
        *w = format!("{}: {w}", path.display());
    }
    let mut warnings = std::mem::take(&mut mesh.warnings);
    warnings.append(&mut v.warnings);
    v.warnings = warnings;
    Ok(v)
}

/// The grid [`voxelize`] would make of `mesh` (its dims, voxel size and minimum
/// corner), and whether it would be held sparse: what a caller checks memory against
/// before the work starts.
pub fn voxelize_layout(
    mesh: &TriangleMesh,
    options: &VoxelizeOptions,
) -> Result<(UVec3, f64, DVec3, bool), LoadErrorKind> {
    let tris = &mesh.triangles;
    if tris.is_empty() {
        return Err(LoadErrorKind::EmptyMesh(
            "it has no triangles (no faces)".into(),
        ));
    }
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for t in tris {
        for p in t {
            if !p.is_finite() {
                return Err(LoadErrorKind::InvalidMesh(format!(
                    "vertex {p} is not finite"
                )));
            }
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
    }
    let extent = hi - lo;
    let longest = extent.max_element();
    if longest <= 0.0 {
        return Err(LoadErrorKind::EmptyMesh(format!(
            "all {} triangles collapse to the single point {lo}",
            tris.len()
        )));
    }
    let voxel_size = match options.resolution {
        Resolution::Count(n) => {
            if !(1..=MAX_RESOLUTION).contains(&n) {
                return Err(LoadErrorKind::InvalidOption(format!(
                    "resolution {n}: the voxel count along the longest axis must be in \
                     1..={MAX_RESOLUTION}"
                )));
            }
            longest / n as f64
        }
        Resolution::VoxelSize(s) => {
            if !(s.is_finite() && s > 0.0) {
                return Err(LoadErrorKind::InvalidOption(format!(
                    "voxel size {}: must be a finite number > 0 (in the mesh's units; \
                     the mesh is {} x {} x {})",
                    crate::input::short_number(s),
                    crate::input::short_number(extent.x),
                    crate::input::short_number(extent.y),
                    crate::input::short_number(extent.z)
                )));
            }
            s
        }
    };
    // A mesh of the wrong scale (1e-30 across, or light years) is not "too large": say
    // what its voxels would be, against the range a grid takes.
    use crate::scene::grid::{MAX_VOXEL_SIZE, MIN_VOXEL_SIZE};
    if !(MIN_VOXEL_SIZE..=MAX_VOXEL_SIZE).contains(&voxel_size) {
        return Err(LoadErrorKind::InvalidOption(format!(
            "the mesh is {:e} x {:e} x {:e} units, so its voxels would be {voxel_size:e} \
             units across, and a grid's voxel size must be in [{MIN_VOXEL_SIZE:e}, \
             {MAX_VOXEL_SIZE:e}]: scale the mesh{}",
            extent.x,
            extent.y,
            extent.z,
            match options.resolution {
                Resolution::Count(_) => "",
                Resolution::VoxelSize(_) => " or choose another voxel size",
            }
        )));
    }
    let dims = grid_layout(extent, voxel_size, options.storage).map_err(LoadErrorKind::TooLarge)?;
    let voxels = dims.x as u64 * dims.y as u64 * dims.z as u64;
    Ok((dims, voxel_size, lo, options.storage.is_sparse_for(voxels)))
}

/// Voxelizes a triangle soup (the in-memory half of [`voxelize_mesh`]).
pub fn voxelize(
    mesh: &TriangleMesh,
    options: &VoxelizeOptions,
) -> Result<Voxelized, LoadErrorKind> {
    let tris = &mesh.triangles;
    let (dims, voxel_size, lo, sparse) = voxelize_layout(mesh, options)?;
    let voxels = dims.x as u64 * dims.y as u64 * dims.z as u64;
    let fill = super::voxelize::fill_bytes(voxels);
    if !sparse && fill > super::voxelize::MAX_FILL_BYTES {
        return Err(LoadErrorKind::TooLarge(format!(
            "a grid of {}x{}x{} voxels: filling its interior may need {fill} bytes, more than \
             the {} allowed (9 bytes per voxel); choose a coarser resolution",
            dims.x,
            dims.y,
            dims.z,
            super::voxelize::MAX_FILL_BYTES
        )));
    }
    if !sparse {
        // The grid and the fill's state and queues, against the limits this process
        // runs under: refused now, not aborted half-way.
        crate::input::check_memory(
            voxels + fill,
            &format!("a dense grid of {}x{}x{} voxels", dims.x, dims.y, dims.z),
        )
        .map_err(|e| LoadErrorKind::TooLarge(format!("{e}; choose a coarser resolution")))?;
    }
    let mut materials = vec![seed_palette()[0].clone()];
    let ids: Vec<u8> = match &options.material {
        Some(m) => {
            materials.push(m.clone());
            vec![1; tris.len()]
        }
        None => {
            if mesh.materials.len() > 255 {
                return Err(LoadErrorKind::TooLarge(format!(
                    "the mesh has {} materials; at most 255 fit voxlab's u8 indices \
                     (give one material to override them)",
                    mesh.materials.len()
                )));
            }
            materials.extend(mesh.materials.iter().cloned());
            mesh.material_of.iter().map(|&i| (i + 1) as u8).collect()
        }
    };
    if ids.len() != tris.len() {
        return Err(LoadErrorKind::InvalidMesh(
            "the triangle and material counts differ".into(),
        ));
    }

    // Whatever the outside flood does not reach is inside, whatever the topology says:
    // a closed volume with a non-manifold edge, a tiny crack or a pinhole (sealed by the
    // conservative shell) comes out solid. Enclosed cavities are filled too.
    let (grid, shell_voxels, interior_voxels) = if sparse {
        let v =
            voxelize_sparse(dims, voxel_size, lo, tris, &ids).map_err(LoadErrorKind::TooLarge)?;
        let grid =
            Grid::from_tree(v.tree, voxel_size, lo).map_err(|e| LoadErrorKind::TooLarge(e.0))?;
        (grid, v.shell_voxels, v.interior_voxels as usize)
    } else {
        let mut grid = Grid::new(dims, voxel_size, lo).map_err(|e| LoadErrorKind::TooLarge(e.0))?;
        let shell = voxelize_triangles(&mut grid, tris, &ids);
        let interior = fill_interior(&mut grid);
        (grid, shell, interior)
    };
    let open_edges = boundary_edge_count(tris);
    let mut warnings = Vec::new();
    if open_edges > 0 {
        warnings.push(format!(
            "the mesh is not closed ({open_edges} edges are not shared by exactly two \
             triangles): {interior_voxels} voxels the outside could not reach were filled; \
             a hole wider than a voxel leaves the inside empty"
        ));
    }
    Ok(Voxelized {
        grid,
        materials,
        warnings,
        closed: open_edges == 0,
        triangle_count: tris.len(),
        shell_voxels,
        interior_voxels,
        surface: crate::surface::SurfaceMesh::from_soup(tris, &mesh.normals, &ids),
    })
}
