//! Triangle surfaces found through the voxels they overlap: the seed's O6 (b), and (a)
//! through it (`render.surface`).
//!
//! Every voxel a triangle overlaps (the voxelizer's exact triangle/box test,
//! `crate::scene::voxelize::tri_box_overlap`, on the box grown by [`CELL_TOLERANCE`]) is
//! a *cell*: it keeps the list of its triangles, and the walks read it as the reserved
//! material [`SURFACE_TAG`] in a copy of the grid (so the sparse tree never merges a
//! cell into a uniform region, and the dense walk tells a cell by its one byte). The
//! DDA, dense or sparse, finds the cells along a ray; the ray is tested against their
//! triangles with the watertight test of Woop, Benthin and Wald ("Watertight
//! Ray/Triangle Intersection", JCGT 2(1), 2013), and a crossing counts only inside the
//! cell's ray interval (grown by the tolerance), so the first crossing found is the
//! first along the ray and a ray through a shared edge or vertex is neither lost nor
//! counted twice.
//!
//! The medium rule (trace contract, "Triangle surfaces"): every triangle separates void
//! from its material. A ray in void that crosses a triangle of material `m` passes into
//! `m`; a ray in any other medium passes into void, whatever the triangle's winding
//! (meshes from files are not reliably wound). Crossings closer than the tolerance are
//! one crossing (a duplicated face, or a ray through an edge). Nested materials (a solid
//! inside glass) are therefore not modelled: leaving the inner one leads to void. The
//! smooth surface is made to match: one surface between void and all other materials
//! ([`crate::surface::extract_solid`]), none where two materials meet. Outside the cells
//! the voxels rule as before: a ray entering a voxel whose material differs from its
//! medium hits its face (a mesh hole wider than the tolerance, a box added to a mesh
//! scene, or two materials meeting, show as voxels).

use std::time::{Duration, Instant};

use glam::{DVec3, IVec3};
use rayon::prelude::*;

use crate::dda::{Dda, Hit};
use crate::frame::RayStats;
use crate::scene::voxelize::tri_box_overlap;
use crate::scene::{Grid, Material, Scene, VOID};
use crate::sparse::Regions;
use crate::surface::SurfaceMesh;

/// The material index the walks read for a cell; no scene with triangle surfaces may
/// use it (at most 255 materials, void included).
pub const SURFACE_TAG: u8 = 255;

/// Voxel units. A cell's box is grown by this much when its triangles are listed, its
/// ray interval too when they are tested, and crossings closer than it are one. Far
/// above f32's error at the distances of a 4096-voxel grid (about 5e-4 voxels at worst
/// for a vertex, less for a crossing), far below a voxel.
pub const CELL_TOLERANCE: f64 = 1e-3;

/// Most triangles a surface may have.
pub const MAX_TRIANGLES: usize = 1 << 24;

/// Most (cell, triangle) references: 4 bytes each, plus 16 per cell, on both sides.
pub(crate) const MAX_REFERENCES: usize = 1 << 27;

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TriangleError {
    #[error("the surface has {0} triangles; at most {MAX_TRIANGLES} are traced")]
    TooManyTriangles(usize),
    #[error(
        "the scene defines {0} materials; triangle surfaces need index {SURFACE_TAG} free \
         (at most 255 materials, void included)"
    )]
    TagInUse(usize),
    #[error(
        "the surface's triangles' bounding boxes hold {0} voxels in all (counted once per \
         triangle); at most {MAX_REFERENCES} are listed: use a coarser grid or fewer \
         triangles"
    )]
    TooManyReferences(usize),
    #[error("the grid has {0} voxels; cells are keyed by 32-bit indices")]
    GridTooLarge(u64),
    #[error("{0}")]
    Extract(String),
}

/// How a shadow segment's media attenuate it: the walk passes each medium it enters to
/// this, in order, and asks for the result at the end. The transmittance slot's models
/// (`crate::technique::TransmittanceModel`) are given through it, so the walk knows no
/// technique.
pub trait Absorber {
    /// The segment passes into material `index` (`material`) at distance `t` (in the
    /// world, grid of `voxel_size`); true once nothing more can pass (the result is 0).
    fn pass(&mut self, t: f64, index: u8, material: &Material, voxel_size: f64) -> bool;
    /// The RGB transmittance of the segment ending at `t_end`.
    fn result(&self, t_end: f64) -> DVec3;
}

/// One triangle in world coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub vertices: [DVec3; 3],
    /// Unit shading normals at the vertices (zero where the mesh has none: the face's).
    pub normals: [DVec3; 3],
    pub material: u8,
}

impl Triangle {
    /// Unit normal of the plane, counter-clockwise; zero when degenerate.
    pub(crate) fn face_normal(&self) -> DVec3 {
        let [a, b, c] = self.vertices;
        (b - a).cross(c - a).normalize_or_zero()
    }
}

/// A ray set up once for the watertight test: the axis it moves most along becomes z,
/// and the shear that makes it the z axis (Woop et al. 2013, section 3).
#[derive(Clone, Copy, Debug)]
pub(crate) struct WatertightRay {
    origin: DVec3,
    k: [usize; 3],
    shear: DVec3,
}

/// Where a ray crosses a triangle: the distance along it and the barycentric weights of
/// the vertices (in vertex order).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Crossing {
    pub t: f64,
    pub weights: DVec3,
}

impl WatertightRay {
    pub fn new(origin: DVec3, dir: DVec3) -> Self {
        let a = dir.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        // Keep the winding: swapping x and y when the ray runs down z.
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            origin,
            k: [kx, ky, kz],
            shear: DVec3::new(dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz]),
        }
    }

    /// The crossing of the ray with the closed triangle `v`, either side, at any `t` (the
    /// caller bounds it). Edges shared by two triangles give the crossing to one of them
    /// or both, never to neither: the edge functions are computed the same way for both.
    pub fn intersect(&self, v: &[DVec3; 3]) -> Option<Crossing> {
        let [kx, ky, kz] = self.k;
        let s = self.shear;
        let rel = [v[0] - self.origin, v[1] - self.origin, v[2] - self.origin];
        let sheared = |p: DVec3| (p[kx] - s.x * p[kz], p[ky] - s.y * p[kz]);
        let (ax, ay) = sheared(rel[0]);
        let (bx, by) = sheared(rel[1]);
        let (cx, cy) = sheared(rel[2]);
        let u = cx * by - cy * bx;
        let w_v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || w_v < 0.0 || w < 0.0) && (u > 0.0 || w_v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + w_v + w;
        if det == 0.0 {
            return None;
        }
        let t = (u * s.z * rel[0][kz] + w_v * s.z * rel[1][kz] + w * s.z * rel[2][kz]) / det;
        if !t.is_finite() {
            return None;
        }
        Some(Crossing {
            t,
            weights: DVec3::new(u, w_v, w) / det,
        })
    }
}

/// The medium a crossing of a triangle of material `m` leads into from `medium`: every
/// triangle separates void from its material.
pub fn crossed(medium: u8, m: u8) -> u8 {
    if medium == VOID { m } else { VOID }
}

/// The next crossing along a ray inside a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transition {
    /// Where it is; crossings within the tolerance after it are the same crossing.
    pub t: f64,
    /// The medium past the group.
    pub medium: u8,
    /// The triangle whose crossing decided it, and where.
    pub triangle: u32,
    pub weights: DVec3,
}

/// The triangles of a scene's surfaces and the cells they overlap, ready for the walks.
#[derive(Clone, Debug)]
pub struct SurfaceTrace {
    /// The scene's grid with every cell set to [`SURFACE_TAG`]: what the walks read.
    pub tagged: Grid,
    pub triangles: Vec<Triangle>,
    /// Linear indices (x fastest) of the cells, ascending.
    pub cells: Vec<u32>,
    /// Cell `i`'s triangles are `refs[begin[i]..begin[i + 1]]`.
    pub begin: Vec<u32>,
    pub refs: Vec<u32>,
    /// Listing the cells (the tree, if any, is built after).
    pub build_time: Duration,
}

impl SurfaceTrace {
    /// Lists the cells of `mesh` (world coordinates) in `grid`.
    pub fn build(
        grid: &Grid,
        materials: usize,
        mesh: &SurfaceMesh,
    ) -> Result<SurfaceTrace, TriangleError> {
        let start = Instant::now();
        if materials > SURFACE_TAG as usize {
            return Err(TriangleError::TagInUse(materials));
        }
        if mesh.triangles.len() > MAX_TRIANGLES {
            return Err(TriangleError::TooManyTriangles(mesh.triangles.len()));
        }
        let voxels = grid.voxel_count() as u64;
        if voxels > u32::MAX as u64 {
            return Err(TriangleError::GridTooLarge(voxels));
        }
        let triangles: Vec<Triangle> = mesh
            .triangles
            .iter()
            .zip(&mesh.triangle_material)
            .map(|(t, &m)| Triangle {
                vertices: t.map(|i| mesh.positions[i as usize]),
                normals: t.map(|i| mesh.normals.get(i as usize).copied().unwrap_or_default()),
                material: m,
            })
            .collect();
        let dims = grid.dims().as_ivec3();
        let grow = DVec3::splat(0.5 + CELL_TOLERANCE);
        // The voxels of each triangle's (grown) bounding box that its plane and edges
        // reach; counted first so a huge surface is refused before it is listed.
        let boxes: Vec<(IVec3, IVec3)> = triangles
            .par_iter()
            .map(|t| {
                let l = t.vertices.map(|p| grid.to_local(p));
                let lo = l[0].min(l[1]).min(l[2]) - CELL_TOLERANCE;
                let hi = l[0].max(l[1]).max(l[2]) + CELL_TOLERANCE;
                let lo = lo.floor().as_ivec3().max(IVec3::ZERO);
                let hi = hi.floor().as_ivec3().min(dims - 1);
                (lo, hi)
            })
            .collect();
        let bound: usize = boxes
            .iter()
            .map(|(lo, hi)| {
                let e = (*hi - *lo + 1).max(IVec3::ZERO).as_u64vec3();
                (e.x * e.y * e.z) as usize
            })
            .fold(0usize, usize::saturating_add);
        if bound > MAX_REFERENCES {
            return Err(TriangleError::TooManyReferences(bound));
        }
        let mut pairs: Vec<(u32, u32)> = triangles
            .par_iter()
            .zip(&boxes)
            .enumerate()
            .flat_map_iter(|(i, (t, &(lo, hi)))| {
                let l = t.vertices.map(|p| grid.to_local(p));
                let mut out = Vec::new();
                for z in lo.z..=hi.z {
                    for y in lo.y..=hi.y {
                        for x in lo.x..=hi.x {
                            let v = IVec3::new(x, y, z);
                            if tri_box_overlap(v.as_dvec3() + 0.5, grow, l) {
                                out.push((linear(grid, v), i as u32));
                            }
                        }
                    }
                }
                out
            })
            .collect();
        pairs.par_sort_unstable();
        let mut tagged = grid
            .to_dense()
            .map_err(|_| TriangleError::GridTooLarge(voxels))?
            .into_owned();
        let mut cells = Vec::new();
        let mut begin = Vec::new();
        let refs: Vec<u32> = pairs.iter().map(|&(_, t)| t).collect();
        for (i, &(cell, _)) in pairs.iter().enumerate() {
            if cells.last() != Some(&cell) {
                cells.push(cell);
                begin.push(i as u32);
                tagged.data_mut()[cell as usize] = SURFACE_TAG;
            }
        }
        begin.push(refs.len() as u32);
        Ok(SurfaceTrace {
            tagged,
            triangles,
            cells,
            begin,
            refs,
            build_time: start.elapsed(),
        })
    }

    /// The triangles listed in the cell at `v`; empty when it is not a cell.
    pub fn cell_triangles(&self, v: IVec3) -> &[u32] {
        let key = linear(&self.tagged, v);
        match self.cells.binary_search(&key) {
            Ok(i) => &self.refs[self.begin[i] as usize..self.begin[i + 1] as usize],
            Err(_) => &[],
        }
    }

    /// Bytes of [`SurfaceTrace::gpu_words`], from its layout (without making it).
    pub fn gpu_bytes(&self) -> u64 {
        let refs = self.refs.len().div_ceil(4);
        16 * (1 + table_size(self.cells.len()) + refs + 6 * self.triangles.len()) as u64
    }

    /// The words of `surface` in shaders/triangles.wgsl: a header `vec4` (the cell
    /// table's log2 size, and where the table, the references and the triangles start,
    /// in `vec4`s); the cells in an open-addressing hash table at most half full
    /// (Fibonacci hashing of the voxel index, linear probing), a `vec4` per slot (voxel
    /// index or [`EMPTY_SLOT`], first reference, count, 0); the references four to a
    /// `vec4`; six `vec4`s per triangle: its vertices in voxel units (the first's `w` its
    /// material) and its vertex normals, as f32 bits.
    pub fn gpu_words(&self) -> Vec<u32> {
        let size = table_size(self.cells.len());
        let log_size = size.trailing_zeros();
        let table_at = 1;
        let refs_at = table_at + size;
        let tris_at = refs_at + self.refs.len().div_ceil(4);
        let mut w = Vec::with_capacity(4 * (tris_at + 6 * self.triangles.len()));
        w.extend([log_size, table_at as u32, refs_at as u32, tris_at as u32]);
        let mut table = vec![[EMPTY_SLOT, 0, 0, 0]; size];
        for (i, &c) in self.cells.iter().enumerate() {
            let mut slot = cell_slot(c, log_size);
            while table[slot][0] != EMPTY_SLOT {
                slot = (slot + 1) & (size - 1);
            }
            table[slot] = [c, self.begin[i], self.begin[i + 1] - self.begin[i], 0];
        }
        w.extend(table.iter().flatten());
        w.extend(&self.refs);
        w.resize(4 * tris_at, 0);
        let g = &self.tagged;
        for t in &self.triangles {
            for (k, p) in t.vertices.iter().enumerate() {
                let l = g.to_local(*p).as_vec3();
                let extra = if k == 0 { t.material as u32 } else { 0 };
                w.extend([l.x.to_bits(), l.y.to_bits(), l.z.to_bits(), extra]);
            }
            for n in &t.normals {
                let n = n.as_vec3();
                w.extend([n.x.to_bits(), n.y.to_bits(), n.z.to_bits(), 0]);
            }
        }
        w
    }

    /// The next crossing of the ray (`ray` from `origin` along unit `dir`) in the cell
    /// at `v`: the first at `t > after` within `window` grown by the tolerance. Crossings
    /// within the tolerance after it are the same crossing (a duplicated face, or the
    /// faces of an edge the ray passes through): a caller that goes on moves `after` to
    /// `t` plus the tolerance.
    pub(crate) fn next_transition(
        &self,
        v: IVec3,
        ray: &WatertightRay,
        window: (f64, f64),
        after: f64,
        medium: u8,
        tests: &mut u64,
    ) -> Option<Transition> {
        let tol = CELL_TOLERANCE * self.tagged.voxel_size();
        let (lo, hi) = (window.0 - tol, window.1 + tol);
        let list = self.cell_triangles(v);
        let mut first: Option<(f64, u32, DVec3)> = None;
        for &i in list {
            *tests += 1;
            let Some(c) = ray.intersect(&self.triangles[i as usize].vertices) else {
                continue;
            };
            if c.t > after && c.t >= lo && c.t <= hi && first.is_none_or(|f| c.t < f.0) {
                first = Some((c.t, i, c.weights));
            }
        }
        let (t, i, weights) = first?;
        Some(Transition {
            t,
            medium: crossed(medium, self.triangles[i as usize].material),
            triangle: i,
            weights,
        })
    }

    /// The hit of a ray along `dir` at a transition: the shading normal interpolated
    /// from the vertices (the face's where they have none) and the face normal, both
    /// turned to face the ray.
    pub fn hit(&self, v: IVec3, dir: DVec3, tr: &Transition) -> Hit {
        let tri = &self.triangles[tr.triangle as usize];
        let mut geometric = tri.face_normal();
        if geometric.dot(dir) > 0.0 {
            geometric = -geometric;
        }
        let [na, nb, nc] = tri.normals;
        let w = tr.weights;
        let mut normal = (w.x * na + w.y * nb + w.z * nc).normalize_or_zero();
        if normal == DVec3::ZERO {
            normal = geometric;
        } else if normal.dot(geometric) < 0.0 {
            normal = -normal;
        }
        Hit {
            voxel: v,
            t: tr.t,
            normal,
            geometric,
            material: tr.medium,
        }
    }

    /// Transmittance (RGB) of the shadow segment from `q` (in `medium`) to `light` as
    /// `absorber` attenuates it (a fresh one), the medium followed through every crossing: min-kt is the smallest kt
    /// of the media passed, Beer-Lambert `exp(-sum sigma len)` over them; a voxel
    /// outside the cells sets the medium to its material, as for voxels.
    #[allow(clippy::too_many_arguments)]
    pub fn transmittance(
        &self,
        scene: &Scene,
        regions: Option<&dyn Regions>,
        absorber: &mut dyn Absorber,
        q: DVec3,
        light: DVec3,
        medium: u8,
        stats: &mut RayStats,
    ) -> DVec3 {
        let to_light = light - q;
        let len = to_light.length();
        if len == 0.0 {
            return DVec3::ONE;
        }
        let dir = to_light / len;
        let vs = self.tagged.voxel_size();
        let mut walk = MediumWalk {
            materials: &scene.materials,
            voxel_size: vs,
            absorber,
            medium: VOID,
            t: 0.0,
        };
        // The medium at q counts, as the start voxel does for voxels.
        if walk.pass(0.0, medium) {
            return DVec3::ZERO;
        }
        let mut dda = Dda::over(&self.tagged, regions, q, dir, len);
        let ray = WatertightRay::new(q, dir);
        let mut tests = 0;
        let mut after = 0.0;
        let mut opaque = false;
        while let Some(v) = dda.next() {
            if v.material == SURFACE_TAG {
                let window = (v.t_enter, dda.t_exit().min(len));
                while let Some(tr) =
                    self.next_transition(v.voxel, &ray, window, after, walk.medium, &mut tests)
                {
                    if tr.t >= len {
                        break;
                    }
                    opaque |= walk.pass(tr.t, tr.medium);
                    after = tr.t + CELL_TOLERANCE * vs;
                    if opaque {
                        break;
                    }
                }
            } else {
                opaque |= walk.pass(v.t_enter.max(walk.t), v.material);
                dda.skip_region();
            }
            if opaque {
                break;
            }
        }
        stats.voxel_steps += dda.steps;
        stats.triangle_tests += tests;
        if opaque {
            return DVec3::ZERO;
        }
        // Beyond the grid is void: nothing more absorbs.
        walk.pass(dda.t_end.min(len).max(walk.t), VOID);
        walk.absorber.result(walk.t)
    }
}

/// A shadow segment's media, piece by piece, passed to its absorber.
struct MediumWalk<'a> {
    materials: &'a [Material],
    voxel_size: f64,
    absorber: &'a mut dyn Absorber,
    medium: u8,
    /// Where the current medium began.
    t: f64,
}

impl MediumWalk<'_> {
    /// The segment passes into `next` at `t`; true once nothing more passes.
    fn pass(&mut self, t: f64, next: u8) -> bool {
        self.medium = next;
        self.t = t;
        let m = &self.materials[next as usize];
        self.absorber.pass(t, next, m, self.voxel_size)
    }
}

/// Slots of the GPU's cell table for `cells` cells: a power of two, at most half full.
fn table_size(cells: usize) -> usize {
    (2 * cells).next_power_of_two().max(2)
}

/// A free slot of the GPU's cell table (no voxel index: grids have fewer than 2^32 - 1).
pub const EMPTY_SLOT: u32 = u32::MAX;

/// The home slot of cell `key` in a table of `2^log_size` slots: Fibonacci hashing
/// (Knuth, TAOCP vol. 3, 6.4), the top bits of `key` times 2^32 / phi.
fn cell_slot(key: u32, log_size: u32) -> usize {
    (key.wrapping_mul(2_654_435_769) >> (32 - log_size)) as usize
}

/// The index of `v` in the grid's data (x fastest).
fn linear(grid: &Grid, v: IVec3) -> u32 {
    let d = grid.dims();
    (v.x as u32) + d.x * (v.y as u32 + d.y * v.z as u32)
}
