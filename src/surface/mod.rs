//! Smooth surfaces of a voxel grid, per material: the seed's O6 (a), `voxlab mesh`.
//!
//! Each material's voxels are a binary volume; its surface is extracted by surface nets
//! (one vertex per piece of surface in each dual cell, quads between them; Gibson,
//! "Constrained Elastic Surface Nets", MERL TR 1998) on the volume padded by one voxel
//! of outside. Where voxels of the material touch only along an edge or at a corner, the
//! cell's vertex is split by the pieces of surface in it (`cell_case`, as manifold
//! dual contouring does), so every surface is a closed 2-manifold: each edge shared by
//! exactly two triangles, each vertex's triangles one fan ([`SurfaceMesh::is_closed`]
//! checks it as trimesh and open3d do). On a binary volume every vertex starts at the
//! mean of its crossings' midpoints (a staircase with chamfers); it is then relaxed,
//! each vertex kept in its own cell, and the material's volume restored (see
//! `relax_nets`).
//!
//! A boundary between two non-void materials gets a surface from each side (coincident,
//! opposite normals): each material's surface is closed on its own.

pub mod fidelity;

use std::io::Write as _;
use std::path::Path;

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
/// How far inside its cell's box a relaxed vertex stays, in voxels.
const CELL_MARGIN: f64 = 1e-3;
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
    pub(crate) fn hash_into(&self, h: &mut blake3::Hasher) {
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

    /// How `material`'s triangles (all, with `None`) fall short of a closed 2-manifold,
    /// by the definitions the field's tools use, after welding vertices at equal
    /// positions (as trimesh does on load): trimesh's `is_watertight` (every edge shared
    /// by exactly two triangles) and `is_winding_consistent` (those two run it opposite
    /// ways), open3d's `is_edge_manifold` and `is_vertex_manifold` (a vertex's triangles
    /// form one fan), no triangle of zero area, and trimesh's `is_volume` (a positive
    /// enclosed volume).
    pub fn manifold_report(&self, material: Option<u8>) -> ManifoldReport {
        use std::collections::HashMap;
        let tris: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .zip(&self.triangle_material)
            .filter(|(_, m)| material.is_none_or(|k| k == **m))
            .map(|(t, _)| *t)
            .collect();
        // Weld by position.
        let mut welded: HashMap<[u64; 3], u32> = HashMap::new();
        let mut at = Vec::new();
        let id: Vec<u32> = self
            .positions
            .iter()
            .map(|p| {
                // +0.0 makes -0.0 and 0.0 one key.
                let key = p.to_array().map(|c| (c + 0.0).to_bits());
                *welded.entry(key).or_insert_with(|| {
                    at.push(*p);
                    at.len() as u32 - 1
                })
            })
            .collect();
        let tris: Vec<[u32; 3]> = tris.iter().map(|t| t.map(|i| id[i as usize])).collect();
        let mut report = ManifoldReport {
            triangles: tris.len(),
            ..Default::default()
        };
        let mut edges: HashMap<(u32, u32), (u32, i64)> = HashMap::new();
        let mut around: HashMap<u32, Vec<usize>> = HashMap::new();
        let mut volume = 0.0;
        for (f, t) in tris.iter().enumerate() {
            let [a, b, c] = t.map(|i| i as usize);
            if a == b || b == c || a == c {
                report.degenerate += 1;
                continue;
            }
            let [pa, pb, pc] = [a, b, c].map(|i| at[i]);
            if (pb - pa).cross(pc - pa).length_squared() == 0.0 {
                report.degenerate += 1;
            }
            // About a point of the mesh: far from the world's origin (1e6), the
            // products of absolute positions cancel to noise.
            let r = at[0];
            volume += (pa - r).dot((pb - r).cross(pc - r)) / 6.0;
            for k in 0..3 {
                let (x, y) = (t[k], t[(k + 1) % 3]);
                let e = edges.entry((x.min(y), x.max(y))).or_default();
                e.0 += 1;
                e.1 += if x < y { 1 } else { -1 };
                around.entry(t[k]).or_default().push(f);
            }
        }
        for &(n, signed) in edges.values() {
            if n != 2 {
                if n > 2 {
                    report.non_manifold_edges += 1;
                } else {
                    report.open_edges += 1;
                }
            } else if signed != 0 {
                report.inconsistent_edges += 1;
            }
        }
        // A vertex's triangles are one fan: connected through the edges at the vertex.
        for (&v, faces) in &around {
            let mut seen = vec![false; faces.len()];
            let mut stack = vec![0];
            seen[0] = true;
            while let Some(i) = stack.pop() {
                let ti = tris[faces[i]];
                for (j, &g) in faces.iter().enumerate() {
                    if seen[j] {
                        continue;
                    }
                    let tj = tris[g];
                    let shares = ti.iter().filter(|&&x| x != v && tj.contains(&x)).count() > 0;
                    if shares {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
            if seen.iter().any(|s| !s) {
                report.non_manifold_vertices += 1;
            }
        }
        report.volume = volume;
        report
    }

    /// Whether `material`'s surface is a closed, consistently wound 2-manifold
    /// enclosing a positive volume ([`SurfaceMesh::manifold_report`]).
    pub fn is_closed(&self, material: Option<u8>) -> bool {
        self.manifold_report(material).is_closed()
    }

    /// The materials that have triangles, ascending.
    pub fn materials(&self) -> Vec<u8> {
        let mut m = self.triangle_material.clone();
        m.sort_unstable();
        m.dedup();
        m
    }
}

/// What [`SurfaceMesh::manifold_report`] found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ManifoldReport {
    pub triangles: usize,
    /// Edges of one triangle (trimesh: not watertight).
    pub open_edges: usize,
    /// Edges of three or more triangles (open3d: not edge-manifold).
    pub non_manifold_edges: usize,
    /// Edges whose two triangles run them the same way (trimesh: winding inconsistent).
    pub inconsistent_edges: usize,
    /// Vertices whose triangles are more than one fan (open3d: not vertex-manifold).
    pub non_manifold_vertices: usize,
    /// Triangles of zero area.
    pub degenerate: usize,
    /// Enclosed volume (divergence theorem), world units cubed.
    pub volume: f64,
}

impl ManifoldReport {
    pub fn is_closed(&self) -> bool {
        self.triangles > 0
            && self.open_edges == 0
            && self.non_manifold_edges == 0
            && self.inconsistent_edges == 0
            && self.non_manifold_vertices == 0
            && self.degenerate == 0
            && self.volume > 0.0
    }
}

impl std::fmt::Display for ManifoldReport {
    /// "closed 2-manifold", or what it is not.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.is_closed() {
            return write!(f, "closed 2-manifold");
        }
        let mut faults = Vec::new();
        for (n, what) in [
            (self.open_edges, "open edges"),
            (self.non_manifold_edges, "non-manifold edges"),
            (self.inconsistent_edges, "inconsistently wound edges"),
            (self.non_manifold_vertices, "non-manifold vertices"),
            (self.degenerate, "degenerate triangles"),
        ] {
            if n > 0 {
                faults.push(format!("{n} {what}"));
            }
        }
        if self.volume <= 0.0 {
            faults.push(format!("enclosed volume {:.3e}", self.volume));
        }
        write!(f, "not a closed 2-manifold: {}", faults.join(", "))
    }
}

/// The smooth surface of every non-void material of `grid`, relaxed `relax` times.
pub fn extract(grid: &Grid, relax: u32) -> Result<SurfaceMesh, SurfaceError> {
    let used = grid.materials_used();
    let dense = dense_within_bound(grid)?;
    let mut mesh = SurfaceMesh::default();
    for m in (0..=255u8).filter(|&m| m != VOID && used[m as usize]) {
        append_material(&dense, Some(m), relax, &mut mesh);
    }
    Ok(mesh)
}

/// `grid` held dense, refused past [`MAX_SURFACE_VOXELS`] before anything is allocated.
fn dense_within_bound(grid: &Grid) -> Result<std::borrow::Cow<'_, Grid>, SurfaceError> {
    let voxels = grid.voxel_count() as u64;
    let too_large = SurfaceError::TooLarge {
        voxels,
        max: MAX_SURFACE_VOXELS,
    };
    if voxels > MAX_SURFACE_VOXELS {
        return Err(too_large);
    }
    grid.to_dense().map_err(|_| too_large)
}

/// The smooth surface between void and everything else, relaxed `relax` times, each
/// triangle of the material of the voxel behind it: the surface `render.surface =
/// "smooth"` traces. Unlike [`extract`], where two touching materials each get a
/// surface, a place where two materials meet has none (the voxels show there): every
/// triangle separates void from one material, as `crate::triangles`' medium rule
/// reads it.
pub fn extract_solid(grid: &Grid, relax: u32) -> Result<SurfaceMesh, SurfaceError> {
    let dense = dense_within_bound(grid)?;
    let mut mesh = SurfaceMesh::default();
    append_material(&dense, None, relax, &mut mesh);
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
    let volume = Volume::of(grid, material);
    let mut nets = surface_nets(&volume);
    let voxels = volume.inside.iter().filter(|&&i| i).count();
    drop(volume);
    relax_nets(&mut nets, relax, voxels as f64);
    append_nets(grid, material, nets, mesh);
}

impl Volume {
    /// `material`'s voxels of `grid` (every non-void one with `None`), with one voxel of
    /// outside on every side so that the surface closes inside the padded box.
    fn of(grid: &Grid, material: Option<u8>) -> Self {
        let d = grid.dims();
        let p = [d.x as usize + 2, d.y as usize + 2, d.z as usize + 2];
        let mut inside = vec![false; p[0] * p[1] * p[2]];
        for (i, &m) in grid.data().iter().enumerate() {
            if material.map_or(m != VOID, |k| m == k) {
                let i = i as u32;
                let (x, y, z) = (i % d.x, (i / d.x) % d.y, i / (d.x * d.y));
                let at = (x as usize + 1) + p[0] * ((y as usize + 1) + p[1] * (z as usize + 1));
                inside[at] = true;
            }
        }
        Self { inside, p }
    }
}

/// Enclosed volume of a closed, outward-wound triangle set (divergence theorem).
fn enclosed_volume(p: &[DVec3], triangles: &[[u32; 3]]) -> f64 {
    // About a point of the mesh, so that positions far from the origin do not cancel.
    let r = p.first().copied().unwrap_or(DVec3::ZERO);
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| p[i as usize] - r);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Constrained relaxation (Gibson 1998), each vertex kept in its cell, then the volume
/// restored. The moves are Taubin's lambda|mu pairs ("A signal processing approach to
/// fair surface design", SIGGRAPH 1995): a step towards the neighbours' mean, then a
/// slightly larger one away, which smooths without the shrinking of plain averaging.
/// What is left of the change of enclosed volume (measured: +0.3 % at 64 passes, up to
/// +2.6 % at 256 on real meshes) is then taken back: every vertex moves along its normal
/// by the same distance, (target - volume) / area, still within its cell, until the
/// volume is `target` (the voxels' own, an unbiased estimate of the shape's) to 1e-9 or
/// the cells stop it. `voxlab bench --surface-fidelity` measures the result against the
/// shape the voxels came from.
fn relax_nets(nets: &mut Nets, passes: u32, target: f64) {
    if passes == 0 {
        return;
    }
    let p = &mut nets.positions;
    let cells = &nets.cells;
    // Each vertex stays in its cell shrunk by a thousandth of a voxel: vertices of
    // different cells never meet (which would weld two of them into a pinch, or make a
    // triangle of zero area).
    let keep = |v: usize, q: DVec3| {
        q.clamp(
            cells[v] + DVec3::splat(CELL_MARGIN),
            cells[v] + DVec3::splat(1.0 - CELL_MARGIN),
        )
    };
    // Neighbours along the mesh's edges, each once.
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); p.len()];
    for t in &nets.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            for (x, y) in [(a, b), (b, a)] {
                if !neighbours[x as usize].contains(&y) {
                    neighbours[x as usize].push(y);
                }
            }
        }
    }
    for pass in 0..passes {
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
                keep(v, p[v] + k * (mean - p[v]))
            })
            .collect();
        *p = next;
    }
    for _ in 0..8 {
        let volume = enclosed_volume(p, &nets.triangles);
        let mut normals = vec![DVec3::ZERO; p.len()];
        let mut area = 0.0;
        for t in &nets.triangles {
            let [a, b, c] = t.map(|i| p[i as usize]);
            let face = (b - a).cross(c - a);
            area += face.length() / 2.0;
            for &i in t {
                normals[i as usize] += face;
            }
        }
        if area <= 0.0 || (target - volume).abs() <= 1e-9 * target.max(1.0) {
            break;
        }
        let step = (target - volume) / area;
        for (v, n) in normals.iter().enumerate() {
            p[v] = keep(v, p[v] + step * n.normalize_or_zero());
        }
    }
}

/// `nets` (padded index space, outward-wound) appended to `mesh` in world space, with
/// area-weighted vertex normals and each triangle's material.
fn append_nets(grid: &Grid, material: Option<u8>, nets: Nets, mesh: &mut SurfaceMesh) {
    let Nets {
        positions: p,
        triangles,
        ..
    } = nets;
    let base = mesh.positions.len() as u32;
    let vs = grid.voxel_size();
    // Padded index space to world: voxel i's centre is at padded index i + 1.
    let world = |q: DVec3| grid.origin() + (q - DVec3::splat(0.5)) * vs;
    let mut normals = vec![DVec3::ZERO; p.len()];
    for t in &triangles {
        let [a, b, c] = t.map(|i| p[i as usize]);
        // Area-weighted: the cross product's length is twice the area.
        let face = (b - a).cross(c - a);
        for &i in t {
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

/// The crossings of a binary volume's cell (a 2x2x2 block of voxel centres), grouped
/// into the surface's pieces within it. Corner k of a cell is at offset (k & 1, k >> 1 &
/// 1, k >> 2 & 1); edge `4a + ob + 2oc` runs along axis a from the corner whose offsets
/// are `ob` on axis (a + 1) % 3 and `oc` on axis (a + 2) % 3.
struct CellCase {
    /// Each piece of the surface in the cell: the crossed edges it passes, in order
    /// round the piece (a closed loop on the cell's faces).
    loops: Vec<Vec<u8>>,
    /// Per edge, the loop it belongs to (`u8::MAX`: not crossed).
    loop_of: [u8; 12],
}

fn edge_index(axis: usize, ob: usize, oc: usize) -> usize {
    4 * axis + ob + 2 * oc
}

/// The two corners of cell edge `e`, from offset 0 to offset 1 along its axis.
fn edge_corners(e: usize) -> (usize, usize) {
    let a = e / 4;
    let mut off = [0usize; 3];
    off[(a + 1) % 3] = e & 1;
    off[(a + 2) % 3] = (e >> 1) & 1;
    let c0 = off[0] + 2 * off[1] + 4 * off[2];
    (c0, c0 + (1 << a))
}

/// Face `f = 2n + s` of a cell (the corners whose offset on axis n is s): its corners in
/// order round it and its edges, edge i joining corners i and i + 1.
fn face_ring(f: usize) -> ([usize; 4], [usize; 4]) {
    let (n, s) = (f / 2, f % 2);
    let (u, v) = ((n + 1) % 3, (n + 2) % 3);
    let corner = |uo: usize, vo: usize| {
        let mut off = [0usize; 3];
        off[n] = s;
        off[u] = uo;
        off[v] = vo;
        off[0] + 2 * off[1] + 4 * off[2]
    };
    (
        [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)],
        [
            edge_index(u, 0, s),
            edge_index(v, s, 1),
            edge_index(u, 1, s),
            edge_index(v, s, 0),
        ],
    )
}

/// Whether face `f` of a cell of `config` has its inside corners on a diagonal (four
/// crossed edges: the one place where the pairing is a choice).
fn face_is_ambiguous(config: usize, f: usize) -> bool {
    let (corners, _) = face_ring(f);
    let inside = corners.map(|k| config >> k & 1 == 1);
    inside[0] == inside[2] && inside[1] == inside[3] && inside[0] != inside[1]
}

/// Whether the two inside corners of ambiguous face `f` are joined through the rest of
/// the cell (a path of inside corners along the cell's edges).
fn diagonal_joined(config: usize, f: usize) -> bool {
    let (corners, _) = face_ring(f);
    let inside = |k: usize| config >> k & 1 == 1;
    let (from, to) = if inside(corners[0]) {
        (corners[0], corners[2])
    } else {
        (corners[1], corners[3])
    };
    let mut seen = 1u8 << from;
    let mut stack = vec![from];
    while let Some(k) = stack.pop() {
        for a in 0..3 {
            let j = k ^ (1 << a);
            if inside(j) && seen >> j & 1 == 0 {
                seen |= 1 << j;
                stack.push(j);
            }
        }
    }
    seen >> to & 1 == 1
}

/// The pieces of a cell of `config` whose ambiguous faces are paired as `outside_faces`
/// says (bit f set: face f keeps its outside corners apart; clear: its inside corners).
/// Every crossed edge lies on two faces and so has two partners: the pieces are closed
/// loops. Both cells of a face pair its edges alike, so the pieces of neighbouring cells
/// fit. A loop crosses an ambiguous face twice where the face's diagonal pair that it
/// keeps apart is joined through the rest of the cell; [`surface_nets`] chooses each
/// face's pairing so that this never happens in both of its cells (where it would, four
/// triangles would share an edge).
fn cell_case(config: usize, outside_faces: u8) -> &'static CellCase {
    static CASES: std::sync::OnceLock<Vec<CellCase>> = std::sync::OnceLock::new();
    let cases = CASES.get_or_init(|| {
        (0..256 * 64usize)
            .map(|i| build_case(i % 256, (i / 256) as u8))
            .collect()
    });
    &cases[config + 256 * outside_faces as usize]
}

fn build_case(config: usize, outside_faces: u8) -> CellCase {
    let inside = |k: usize| config >> k & 1 == 1;
    let crossed = |e: usize| {
        let (a, b) = edge_corners(e);
        inside(a) != inside(b)
    };
    let mut partners: [Vec<usize>; 12] = Default::default();
    let mut link = |a: usize, b: usize| {
        partners[a].push(b);
        partners[b].push(a);
    };
    for f in 0..6 {
        let (corners, edges) = face_ring(f);
        let cut: Vec<usize> = edges.iter().copied().filter(|&e| crossed(e)).collect();
        match cut.len() {
            2 => link(cut[0], cut[1]),
            4 => {
                // Each segment cuts off one corner of the side kept apart.
                let apart = outside_faces >> f & 1 == 0;
                for i in 0..4 {
                    if inside(corners[i]) == apart {
                        link(edges[(i + 3) % 4], edges[i]);
                    }
                }
            }
            _ => {}
        }
    }
    let mut loop_of = [u8::MAX; 12];
    let mut loops = Vec::new();
    for start in (0..12).filter(|&e| crossed(e)) {
        if loop_of[start] != u8::MAX {
            continue;
        }
        let id = loops.len() as u8;
        let mut piece = vec![start as u8];
        loop_of[start] = id;
        let (mut prev, mut at) = (start, partners[start][0]);
        while at != start {
            loop_of[at] = id;
            piece.push(at as u8);
            let next = if partners[at][0] == prev {
                partners[at][1]
            } else {
                partners[at][0]
            };
            (prev, at) = (at, next);
        }
        loops.push(piece);
    }
    CellCase { loops, loop_of }
}

/// A surface of a binary volume in padded index space (voxel centres at integers).
struct Nets {
    positions: Vec<DVec3>,
    /// Each vertex's cell (its minimum corner), which relaxation keeps it in.
    cells: Vec<DVec3>,
    /// Counter-clockwise seen from outside.
    triangles: Vec<[u32; 3]>,
}

/// A binary volume in padded index space: `inside` (dims `p`, x fastest), whose
/// outermost layer is outside, and its cells (2x2x2 blocks of voxel centres, named by
/// their minimum corner).
struct Volume {
    inside: Vec<bool>,
    p: [usize; 3],
}

impl Volume {
    fn at(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.p[0] * (y + self.p[1] * z)
    }

    /// Cells along each axis.
    fn cells(&self) -> [usize; 3] {
        self.p.map(|n| n - 1)
    }

    fn cell_index(&self, m: [usize; 3]) -> usize {
        let c = self.cells();
        m[0] + c[0] * (m[1] + c[1] * m[2])
    }

    /// The cell's corners as bits: corner k at offset (k & 1, k >> 1 & 1, k >> 2 & 1).
    fn config(&self, m: [usize; 3]) -> usize {
        (0..8).fold(0usize, |acc, k| {
            let i = self.at(m[0] + (k & 1), m[1] + (k >> 1 & 1), m[2] + (k >> 2 & 1));
            acc | (usize::from(self.inside[i]) << k)
        })
    }

    /// The cell's pieces. An ambiguous face keeps its inside corners apart, unless the
    /// cells on both sides join them through their other corners: then a loop of each
    /// would cross the face twice, so the face keeps its outside corners apart instead
    /// (which neither cell then joins: an inside and an outside path round the face
    /// cannot both exist).
    fn case(&self, m: [usize; 3]) -> &'static CellCase {
        let k = self.config(m);
        let mut outside_faces = 0u8;
        for f in 0..6 {
            if !face_is_ambiguous(k, f) {
                continue;
            }
            // Never on the outermost layer (all outside): the neighbour exists.
            let (n, side) = (f / 2, f % 2);
            let mut other = m;
            if side == 1 {
                other[n] += 1;
            } else {
                other[n] -= 1;
            }
            if diagonal_joined(k, f) && diagonal_joined(self.config(other), f ^ 1) {
                outside_faces |= 1 << f;
            }
        }
        cell_case(k, outside_faces)
    }

    /// Every cell the surface passes (neither all inside nor all outside), in index
    /// order: its minimum corner, its corners' bits ([`Volume::config`]) and pieces.
    fn for_each_surface_cell(&self, mut f: impl FnMut([usize; 3], usize, &'static CellCase)) {
        let c = self.cells();
        for z in 0..c[2] {
            for y in 0..c[1] {
                for x in 0..c[0] {
                    let k = self.config([x, y, z]);
                    if k != 0 && k != 255 {
                        f([x, y, z], k, self.case([x, y, z]));
                    }
                }
            }
        }
    }

    /// Every crossed edge between two voxel centres: its lower end, its axis, and
    /// whether the lower end is the inside one.
    fn crossed_edges(&self, mut f: impl FnMut([usize; 3], usize, bool)) {
        let p = self.p;
        for z in 0..p[2] {
            for y in 0..p[1] {
                for x in 0..p[0] {
                    let here = [x, y, z];
                    let lower = self.inside[self.at(x, y, z)];
                    for a in 0..3 {
                        let mut there = here;
                        there[a] += 1;
                        if there[a] >= p[a] {
                            continue;
                        }
                        if lower != self.inside[self.at(there[0], there[1], there[2])] {
                            f(here, a, lower);
                        }
                    }
                }
            }
        }
    }
}

/// The midpoint of cell edge `e`, in the cell's own coordinates.
fn edge_midpoint(e: usize) -> DVec3 {
    let (c0, _) = edge_corners(e);
    let mut q = DVec3::new((c0 & 1) as f64, (c0 >> 1 & 1) as f64, (c0 >> 2 & 1) as f64);
    q[e / 4] += 0.5;
    q
}

/// Surface nets of the volume: a vertex per piece of the surface in each cell
/// ([`cell_case`]), at the mean of its crossings' midpoints, and a quad, as two
/// triangles, round every crossed edge between two voxel centres (Gibson 1998's surface
/// nets, with the cell's vertex split where the surface has more than one piece in it).
fn surface_nets(volume: &Volume) -> Nets {
    let c = volume.cells();
    let mut first = vec![u32::MAX; c[0] * c[1] * c[2]];
    let mut positions = Vec::new();
    let mut cells = Vec::new();
    volume.for_each_surface_cell(|m, _, case| {
        first[volume.cell_index(m)] = positions.len() as u32;
        let base = DVec3::new(m[0] as f64, m[1] as f64, m[2] as f64);
        for piece in &case.loops {
            let sum: DVec3 = piece.iter().map(|&e| edge_midpoint(e as usize)).sum();
            positions.push(base + sum / piece.len() as f64);
            cells.push(base);
        }
    });
    let mut triangles = Vec::new();
    volume.crossed_edges(|here, a, lower| {
        // The four cells round the edge, counter-clockwise about +a.
        let (b, cc) = ((a + 1) % 3, (a + 2) % 3);
        let quad = [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(sb, sc)| {
            let mut m = here;
            m[b] -= sb;
            m[cc] -= sc;
            let piece = volume.case(m).loop_of[edge_index(a, sb, sc)];
            first[volume.cell_index(m)] + u32::from(piece)
        });
        // Outward is +a where the lower voxel is the inside one.
        let [q0, q1, q2, q3] = if lower {
            quad
        } else {
            [quad[3], quad[2], quad[1], quad[0]]
        };
        let len = |i: u32, j: u32| (positions[i as usize] - positions[j as usize]).length_squared();
        if len(q0, q2) <= len(q1, q3) {
            triangles.push([q0, q1, q2]);
            triangles.push([q0, q2, q3]);
        } else {
            triangles.push([q0, q1, q3]);
            triangles.push([q1, q2, q3]);
        }
    });
    Nets {
        positions,
        cells,
        triangles,
    }
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
