//! Smooth surfaces of a voxel grid, per material: the seed's O6 (a), `voxlab mesh`.
//!
//! Each material's voxels are a binary volume; its surface is extracted by Naive Surface
//! Nets (one vertex per dual cell the surface crosses, quads between them; the
//! `fast-surface-nets` crate) on the volume padded by one voxel of outside, so the mesh
//! is closed. On a binary volume every vertex starts at the centre of its dual cell
//! (a staircase with chamfers); it is then relaxed as Gibson's constrained elastic
//! surface nets do ("Constrained Elastic Surface Nets", MERL TR 1998): each vertex moves
//! to the mean of its neighbours, clamped to its own cell, so the surface smooths out
//! while staying within the cells that the voxel boundary passes through (at most one
//! voxel from it, and the topology, hence closedness, unchanged).
//!
//! A boundary between two non-void materials gets a surface from each side (coincident,
//! opposite normals): each material's surface is closed on its own.

use std::io::Write as _;
use std::path::Path;

use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};
use glam::DVec3;

use crate::scene::{Grid, Material, VOID};

/// Most voxels a surface is extracted from: the padded field (4 bytes a voxel) and the
/// extractor's index (4 more) stay under 600 MiB.
pub const MAX_SURFACE_VOXELS: u64 = 1 << 26;
/// Relaxation passes by default (32 lambda|mu pairs): on a sphere voxelized at 64 they
/// halve the distance to the sphere and take the normals' error from 7.7 to 2.9 degrees.
pub const DEFAULT_RELAX: u32 = 64;
/// Most relaxation passes allowed.
pub const MAX_RELAX: u32 = 1000;
/// Taubin's pass factors: a smoothing step, then a larger inflating one (k_PB = 0.1).
const TAUBIN_LAMBDA: f64 = 0.5;
const TAUBIN_MU: f64 = -0.53;

#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    #[error(
        "the grid has {voxels} voxels; surfaces are extracted from at most {max} \
         (surface::MAX_SURFACE_VOXELS)"
    )]
    TooLarge { voxels: u64, max: u64 },
    /// The output's error already names the file and says why.
    #[error("{error}")]
    Write {
        path: String,
        error: crate::output::OutputError,
    },
    #[error("{path}: the output must end in .obj or .ply")]
    Format { path: String },
}

/// A triangle mesh in world coordinates, one material per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceMesh {
    pub positions: Vec<DVec3>,
    /// Unit vertex normals, pointing out of the material.
    pub normals: Vec<DVec3>,
    /// Counter-clockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    pub triangle_material: Vec<u8>,
}

impl SurfaceMesh {
    /// A triangle soup as a mesh: three vertices a triangle, each with the file's
    /// normal there (`normals`, per triangle, empty when the file has none) or else the
    /// face's unit normal (zero for a degenerate triangle; counter-clockwise winding
    /// gives the outward side, but tracing does not rely on it, see `crate::triangles`).
    pub fn from_soup(triangles: &[[DVec3; 3]], normals: &[[DVec3; 3]], materials: &[u8]) -> Self {
        let mut mesh = Self::default();
        for (i, (t, &m)) in triangles.iter().zip(materials).enumerate() {
            let face = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
            let at = mesh.positions.len() as u32;
            mesh.positions.extend_from_slice(t);
            let given = normals.get(i).copied().unwrap_or([DVec3::ZERO; 3]);
            mesh.normals
                .extend(given.map(|n| if n == DVec3::ZERO { face } else { n }));
            mesh.triangles.push([at, at + 1, at + 2]);
            mesh.triangle_material.push(m);
        }
        mesh
    }

    /// Feeds every vertex, normal, triangle and material into `h`: what the caches keyed
    /// by a scene's mesh (the ablation reference, the GPU's surfaces) compare.
    pub fn hash_into(&self, h: &mut blake3::Hasher) {
        for v in self.positions.iter().chain(&self.normals) {
            for c in v.to_array() {
                h.update(&c.to_le_bytes());
            }
        }
        for t in &self.triangles {
            for i in t {
                h.update(&i.to_le_bytes());
            }
        }
        h.update(&self.triangle_material);
    }

    /// The mesh moved by `offset`.
    pub fn translated(mut self, offset: DVec3) -> Self {
        for p in &mut self.positions {
            *p += offset;
        }
        self
    }

    /// Edges of `material`'s surface that bound it: those whose two directions are not
    /// used by equally many of its (consistently wound) triangles. 0 for a closed
    /// surface. Where two voxels of a material touch along an edge only, four triangles
    /// share a mesh edge (a non-manifold but watertight place): two each way.
    pub fn open_edges(&self, material: u8) -> usize {
        self.edges(Some(material))
            .values()
            .filter(|(_, signed)| *signed != 0)
            .count()
    }

    /// Edges of `material`'s surface shared by more than two of its triangles (where
    /// voxels touch along an edge only).
    pub fn non_manifold_edges(&self, material: u8) -> usize {
        self.edges(Some(material))
            .values()
            .filter(|(n, _)| *n > 2)
            .count()
    }

    /// [`SurfaceMesh::open_edges`] of all the triangles together, whatever their
    /// materials (the surface of [`extract_solid`] is closed as a whole).
    pub fn open_edges_all(&self) -> usize {
        self.edges(None)
            .values()
            .filter(|(_, signed)| *signed != 0)
            .count()
    }

    /// Per undirected edge of `material`'s triangles (every triangle's with `None`): how
    /// many use it, and how many more use it from the lower vertex index to the higher
    /// than the other way.
    fn edges(&self, material: Option<u8>) -> std::collections::HashMap<(u32, u32), (u32, i64)> {
        let mut edges: std::collections::HashMap<(u32, u32), (u32, i64)> = Default::default();
        for (t, &m) in self.triangles.iter().zip(&self.triangle_material) {
            if material.is_some_and(|k| k != m) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let e = edges.entry((a.min(b), a.max(b))).or_default();
                e.0 += 1;
                e.1 += if a < b { 1 } else { -1 };
            }
        }
        edges
    }

    /// The materials that have triangles, ascending.
    pub fn materials(&self) -> Vec<u8> {
        let mut m = self.triangle_material.clone();
        m.sort_unstable();
        m.dedup();
        m
    }
}

/// The smooth surface of every non-void material of `grid`, relaxed `relax` times.
pub fn extract(grid: &Grid, relax: u32) -> Result<SurfaceMesh, SurfaceError> {
    let voxels = grid.voxel_count() as u64;
    if voxels > MAX_SURFACE_VOXELS {
        return Err(SurfaceError::TooLarge {
            voxels,
            max: MAX_SURFACE_VOXELS,
        });
    }
    let used = grid.materials_used();
    let dense = grid.to_dense().map_err(|_| SurfaceError::TooLarge {
        voxels,
        max: MAX_SURFACE_VOXELS,
    })?;
    let grid = dense.as_ref();
    let mut mesh = SurfaceMesh::default();
    for m in (0..=255u8).filter(|&m| m != VOID && used[m as usize]) {
        append_material(grid, Some(m), relax, &mut mesh);
    }
    Ok(mesh)
}

/// The smooth surface between void and everything else, relaxed `relax` times, each
/// triangle of the material of the voxel behind it: the surface `render.surface =
/// "smooth"` traces. Unlike [`extract`], where two touching materials each get a
/// surface, a place where two materials meet has none (the voxels show there): every
/// triangle separates void from one material, as `crate::triangles`' medium rule
/// reads it.
pub fn extract_solid(grid: &Grid, relax: u32) -> Result<SurfaceMesh, SurfaceError> {
    let voxels = grid.voxel_count() as u64;
    if voxels > MAX_SURFACE_VOXELS {
        return Err(SurfaceError::TooLarge {
            voxels,
            max: MAX_SURFACE_VOXELS,
        });
    }
    let dense = grid.to_dense().map_err(|_| SurfaceError::TooLarge {
        voxels,
        max: MAX_SURFACE_VOXELS,
    })?;
    let grid = dense.as_ref();
    let mut mesh = SurfaceMesh::default();
    append_material(grid, None, relax, &mut mesh);
    Ok(mesh)
}

/// The non-void voxel nearest to `p` (voxel-local coordinates) among the 27 around it.
fn solid_near(grid: &Grid, p: DVec3) -> u8 {
    let c = p.floor().as_ivec3();
    let mut best = (f64::INFINITY, VOID);
    for z in -1..=1 {
        for y in -1..=1 {
            for x in -1..=1 {
                let v = c + glam::IVec3::new(x, y, z);
                if !grid.contains(v) || grid.get(v) == VOID {
                    continue;
                }
                let d = (v.as_dvec3() + 0.5 - p).length_squared();
                if d < best.0 {
                    best = (d, grid.get(v));
                }
            }
        }
    }
    best.1
}

/// The surface of `material`'s voxels, or with `None` of every non-void voxel (each
/// triangle then of the material of the voxel behind it), appended to `mesh`.
fn append_material(grid: &Grid, material: Option<u8>, relax: u32, mesh: &mut SurfaceMesh) {
    let d = grid.dims();
    // One voxel of outside before the grid and two after: the extractor makes no face
    // for a cube edge whose cube starts on its last layer, so the outside layer that
    // closes the grid's far faces must not be the last.
    let padded = [d.x + 3, d.y + 3, d.z + 3];
    let shape = RuntimeShape::<u32, 3>::new(padded);
    // Negative inside the material; the one-voxel border is outside.
    let mut field = vec![0.5f32; shape.usize()];
    for (i, &m) in grid.data().iter().enumerate() {
        if material.map_or(m != VOID, |k| m == k) {
            let i = i as u32;
            let (x, y, z) = (i % d.x, (i / d.x) % d.y, i / (d.x * d.y));
            field[shape.linearize([x + 1, y + 1, z + 1]) as usize] = -0.5;
        }
    }
    let mut buf = SurfaceNetsBuffer::default();
    surface_nets(
        &field,
        &shape,
        [0; 3],
        [padded[0] - 1, padded[1] - 1, padded[2] - 1],
        &mut buf,
    );
    drop(field);
    let mut p: Vec<DVec3> = buf
        .positions
        .iter()
        .map(|q| DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64))
        .collect();
    let cells: Vec<DVec3> = buf
        .surface_points
        .iter()
        .map(|c| DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64))
        .collect();
    let triangles: Vec<[u32; 3]> = buf
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    // Neighbours along the mesh's edges, each once.
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); p.len()];
    for t in &triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            for (x, y) in [(a, b), (b, a)] {
                if !neighbours[x as usize].contains(&y) {
                    neighbours[x as usize].push(y);
                }
            }
        }
    }
    // Constrained relaxation (Gibson 1998), each vertex kept in its cell. The moves are
    // Taubin's lambda|mu pairs ("A signal processing approach to fair surface design",
    // SIGGRAPH 1995): a step towards the neighbours' mean, then a slightly larger one
    // away, which smooths without the shrinking of plain averaging (measured in
    // tests/surface.rs on a sphere).
    for pass in 0..relax {
        let k = if pass % 2 == 0 {
            TAUBIN_LAMBDA
        } else {
            TAUBIN_MU
        };
        let next: Vec<DVec3> = (0..p.len())
            .map(|v| {
                let n = &neighbours[v];
                if n.is_empty() {
                    return p[v];
                }
                let mean = n.iter().map(|&u| p[u as usize]).sum::<DVec3>() / n.len() as f64;
                (p[v] + k * (mean - p[v])).clamp(cells[v], cells[v] + DVec3::ONE)
            })
            .collect();
        p = next;
    }
    // The extractor winds every quad the same way round the material; which way is
    // told by the sign of the enclosed volume (divergence theorem), and the triangles
    // are turned counter-clockwise seen from outside.
    let volume: f64 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| p[i as usize]);
            a.dot(b.cross(c))
        })
        .sum();
    let flip = volume < 0.0;
    let base = mesh.positions.len() as u32;
    let vs = grid.voxel_size();
    // Padded index space to world: voxel i's centre is at padded index i + 1.
    let world = |q: DVec3| grid.origin() + (q - DVec3::splat(0.5)) * vs;
    let mut normals = vec![DVec3::ZERO; p.len()];
    for t in &triangles {
        let t = if flip { [t[0], t[2], t[1]] } else { *t };
        let [a, b, c] = t.map(|i| p[i as usize]);
        // Area-weighted: the cross product's length is twice the area.
        let face = (b - a).cross(c - a);
        for &i in &t {
            normals[i as usize] += face;
        }
        mesh.triangles.push(t.map(|i| i + base));
        // Behind the face, a quarter voxel in from its centroid (voxel-local: padded
        // index minus a half), is the voxel it bounds.
        let m = material.unwrap_or_else(|| {
            let inside = (a + b + c) / 3.0 - 0.25 * face.normalize_or_zero();
            solid_near(grid, inside - DVec3::splat(0.5))
        });
        mesh.triangle_material.push(m);
    }
    mesh.positions.extend(p.into_iter().map(world));
    mesh.normals
        .extend(normals.into_iter().map(|n| n.normalize_or_zero()));
}

/// Writes `mesh` as OBJ (with `usemtl` per material and an MTL file beside it, the
/// materials' albedo as Kd) or binary PLY (a material index per face, the names in
/// comments), by the output's extension; atomically, as every output.
pub fn write_mesh(
    mesh: &SurfaceMesh,
    materials: &[Material],
    path: &Path,
) -> Result<(), SurfaceError> {
    let name = path.display().to_string();
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    let fail = |error| SurfaceError::Write {
        path: name.clone(),
        error,
    };
    match ext.as_deref() {
        Some("obj") => {
            let mtl = path.with_extension("mtl");
            let (obj, mtl_text) = obj_text(mesh, materials, &mtl);
            // Both or neither: an OBJ without its MTL, or an MTL left alone, is no output.
            crate::output::write_together(vec![
                (
                    path.to_path_buf(),
                    crate::output::bytes_fill(path, obj.as_bytes()),
                ),
                (
                    mtl.clone(),
                    crate::output::bytes_fill(&mtl, mtl_text.as_bytes()),
                ),
            ])
            .map_err(fail)
        }
        Some("ply") => crate::output::write_file(path, &ply_bytes(mesh, materials)).map_err(fail),
        _ => Err(SurfaceError::Format { path: name }),
    }
}

/// A material's name as OBJ/MTL can hold it (one token).
fn token(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_whitespace() { '_' } else { c })
        .collect()
}

fn obj_text(mesh: &SurfaceMesh, materials: &[Material], mtl: &Path) -> (String, String) {
    use std::fmt::Write as _;
    let mut s = String::new();
    let _ = writeln!(s, "# voxlab mesh: surface nets of each material's voxels");
    let _ = writeln!(
        s,
        "mtllib {}",
        mtl.file_name()
            .map_or(String::new(), |f| f.to_string_lossy().into_owned())
    );
    for p in &mesh.positions {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for n in &mesh.normals {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    let mut m_text = String::from("# voxlab mesh: the materials' albedo\n");
    for m in mesh.materials() {
        let mat = &materials[m as usize];
        let _ = writeln!(s, "usemtl {}", token(&mat.name));
        for (t, _) in mesh
            .triangles
            .iter()
            .zip(&mesh.triangle_material)
            .filter(|(_, k)| **k == m)
        {
            let [a, b, c] = t.map(|i| i + 1);
            let _ = writeln!(s, "f {a}//{a} {b}//{b} {c}//{c}");
        }
        let a = mat.albedo;
        let _ = writeln!(
            m_text,
            "newmtl {}\nKd {} {} {}",
            token(&mat.name),
            a.x,
            a.y,
            a.z
        );
    }
    (s, m_text)
}

fn ply_bytes(mesh: &SurfaceMesh, materials: &[Material]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut header = String::from("ply\nformat binary_little_endian 1.0\ncomment voxlab mesh\n");
    for m in mesh.materials() {
        header += &format!(
            "comment material {m} {}\n",
            token(&materials[m as usize].name)
        );
    }
    header += &format!(
        "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         element face {}\nproperty list uchar int vertex_indices\nproperty uchar material\n\
         end_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    out.extend_from_slice(header.as_bytes());
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            let _ = out.write_all(&(v as f32).to_le_bytes());
        }
    }
    for (t, m) in mesh.triangles.iter().zip(&mesh.triangle_material) {
        out.push(3);
        for i in t {
            let _ = out.write_all(&(*i as i32).to_le_bytes());
        }
        out.push(*m);
    }
    out
}
