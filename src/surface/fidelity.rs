//! How close a surface of voxels lies to the shape the voxels were made from: shapes
//! with an exact distance (a sphere, a torus) voxelized by their voxel centres, the
//! two-sided Chamfer and Hausdorff distances of a mesh to them, and plain marching cubes
//! of the same voxels to compare the smooth surface with. `voxlab bench
//! --surface-fidelity` prints the table; `tests/surface.rs` holds the default
//! relaxation to beating marching cubes.

use glam::{DVec3, IVec3, UVec3};

use super::{Nets, SurfaceMesh, Volume, append_nets, edge_corners, edge_midpoint};
use crate::scene::Grid;

/// A shape with an exact distance to its surface, in world units.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    Sphere {
        centre: DVec3,
        radius: f64,
    },
    /// About the z axis through `centre`.
    Torus {
        centre: DVec3,
        major: f64,
        minor: f64,
    },
}

impl Shape {
    /// A sphere of radius 0.4 n in an n^3 grid of unit voxels, off the voxel lattice.
    pub fn sphere_in(n: u32) -> Self {
        Shape::Sphere {
            centre: DVec3::splat(n as f64 / 2.0) + DVec3::new(0.13, 0.29, 0.07),
            radius: 0.4 * n as f64,
        }
    }

    /// A torus of radii 0.3 n and 0.12 n in an n^3 grid of unit voxels.
    pub fn torus_in(n: u32) -> Self {
        Shape::Torus {
            centre: DVec3::splat(n as f64 / 2.0) + DVec3::new(0.21, 0.11, 0.17),
            major: 0.3 * n as f64,
            minor: 0.12 * n as f64,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Shape::Sphere { .. } => "sphere",
            Shape::Torus { .. } => "torus",
        }
    }

    /// Signed distance: negative inside.
    pub(crate) fn signed_distance(&self, p: DVec3) -> f64 {
        match *self {
            Shape::Sphere { centre, radius } => (p - centre).length() - radius,
            Shape::Torus {
                centre,
                major,
                minor,
            } => {
                let q = p - centre;
                let ring = (q.x * q.x + q.y * q.y).sqrt() - major;
                (ring * ring + q.z * q.z).sqrt() - minor
            }
        }
    }

    /// The n^3 grid of unit voxels (material 1 where the voxel's centre is inside).
    pub fn voxelize(&self, n: u32) -> Grid {
        let mut g = Grid::new(UVec3::splat(n), 1.0, DVec3::ZERO).expect("a small grid");
        for z in 0..n as i32 {
            for y in 0..n as i32 {
                for x in 0..n as i32 {
                    let c = DVec3::new(x as f64, y as f64, z as f64) + 0.5;
                    if self.signed_distance(c) <= 0.0 {
                        g.set(IVec3::new(x, y, z), 1);
                    }
                }
            }
        }
        g
    }

    /// Points on the surface, about `density` per unit of area, each with the area it
    /// stands for.
    fn samples(&self, density: f64) -> Vec<(DVec3, f64)> {
        match *self {
            Shape::Sphere { centre, radius } => {
                // A Fibonacci lattice: equal areas.
                let area = 4.0 * std::f64::consts::PI * radius * radius;
                let n = (area * density).ceil().max(64.0) as usize;
                let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
                (0..n)
                    .map(|i| {
                        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                        let r = (1.0 - z * z).sqrt();
                        let phi = golden * i as f64;
                        let d = DVec3::new(r * phi.cos(), r * phi.sin(), z);
                        (centre + radius * d, area / n as f64)
                    })
                    .collect()
            }
            Shape::Torus {
                centre,
                major,
                minor,
            } => {
                // A (u, v) lattice, each point weighted by its patch's area.
                let tau = std::f64::consts::TAU;
                let nu = ((tau * major * density.sqrt()).ceil() as usize).max(16);
                let nv = ((tau * minor * density.sqrt()).ceil() as usize).max(8);
                let mut out = Vec::with_capacity(nu * nv);
                for i in 0..nu {
                    let u = tau * (i as f64 + 0.5) / nu as f64;
                    for j in 0..nv {
                        let v = tau * (j as f64 + 0.5) / nv as f64;
                        let ring = major + minor * v.cos();
                        let p =
                            centre + DVec3::new(ring * u.cos(), ring * u.sin(), minor * v.sin());
                        let area = (tau / nu as f64) * ring * (tau / nv as f64) * minor;
                        out.push((p, area));
                    }
                }
                out
            }
        }
    }
}

/// Distances between a mesh and a shape, in voxels (the shapes' grids have unit voxels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fidelity {
    /// Area-weighted mean distance from the mesh's surface to the shape's.
    pub mesh_to_shape: f64,
    /// Area-weighted mean distance from the shape's surface to the mesh's.
    pub shape_to_mesh: f64,
    /// The two means' average: the symmetric Chamfer distance.
    pub chamfer: f64,
    /// The largest distance either way (Hausdorff), at the points sampled.
    pub hausdorff: f64,
    /// Enclosed volume against the shape's, as a fraction (+ is larger).
    pub volume_error: f64,
    pub triangles: usize,
}

/// [`Fidelity`] of `mesh` (all its triangles) to `shape`. The mesh is sampled at each
/// triangle's corners, edge midpoints and a 4x4 barycentric lattice inside; the shape at
/// about 16 points per unit of area, each against the nearest triangle (found through a
/// uniform grid of the triangles' boxes).
pub fn fidelity(mesh: &SurfaceMesh, shape: &Shape) -> Fidelity {
    let tris: Vec<[DVec3; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| mesh.positions[i as usize]))
        .collect();
    // Mesh to shape.
    let (mut sum, mut weight, mut far) = (0.0, 0.0, 0.0f64);
    for &[a, b, c] in &tris {
        let area = (b - a).cross(c - a).length() / 2.0;
        let mut points = vec![a, b, c, (a + b) / 2.0, (b + c) / 2.0, (a + c) / 2.0];
        let k = 4;
        for i in 0..k {
            for j in 0..k - i {
                let (u, v) = (
                    (i as f64 + 1.0 / 3.0) / k as f64,
                    (j as f64 + 1.0 / 3.0) / k as f64,
                );
                points.push(a + u * (b - a) + v * (c - a));
            }
        }
        let interior = &points[6..];
        let d_mean = interior
            .iter()
            .map(|p| shape.signed_distance(*p).abs())
            .sum::<f64>()
            / interior.len() as f64;
        sum += area * d_mean;
        weight += area;
        for p in &points {
            far = far.max(shape.signed_distance(*p).abs());
        }
    }
    let mesh_to_shape = sum / weight.max(f64::MIN_POSITIVE);
    // Shape to mesh, through a grid of unit cells holding the triangles whose boxes
    // meet them.
    let lo = tris
        .iter()
        .flatten()
        .fold(DVec3::splat(f64::INFINITY), |m, p| m.min(*p))
        .floor();
    let hi = tris
        .iter()
        .flatten()
        .fold(DVec3::splat(f64::NEG_INFINITY), |m, p| m.max(*p))
        .ceil();
    let dims = ((hi - lo).max(DVec3::ONE)).as_uvec3() + UVec3::ONE;
    let cell = |p: DVec3| ((p - lo).floor().as_ivec3()).clamp(IVec3::ZERO, dims.as_ivec3() - 1);
    let index = |c: IVec3| (c.x as u32 + dims.x * (c.y as u32 + dims.y * c.z as u32)) as usize;
    let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); (dims.x * dims.y * dims.z) as usize];
    for (i, t) in tris.iter().enumerate() {
        let (a, b) = (
            cell(t[0].min(t[1]).min(t[2])),
            cell(t[0].max(t[1]).max(t[2])),
        );
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    buckets[index(IVec3::new(x, y, z))].push(i as u32);
                }
            }
        }
    }
    let nearest = |p: DVec3| -> f64 {
        let c = cell(p);
        let mut best = f64::INFINITY;
        let mut r = 1;
        loop {
            for z in (c.z - r).max(0)..=(c.z + r).min(dims.z as i32 - 1) {
                for y in (c.y - r).max(0)..=(c.y + r).min(dims.y as i32 - 1) {
                    for x in (c.x - r).max(0)..=(c.x + r).min(dims.x as i32 - 1) {
                        for &t in &buckets[index(IVec3::new(x, y, z))] {
                            best = best.min(point_triangle_distance(p, &tris[t as usize]));
                        }
                    }
                }
            }
            // Every triangle within r cells was seen: a nearer one beyond lies further
            // than r - 1 away.
            if best <= (r - 1) as f64 || r as u32 > dims.max_element() {
                return best;
            }
            r += 1;
        }
    };
    let samples = shape.samples(16.0);
    let (mut sum2, mut weight2) = (0.0, 0.0);
    for &(p, area) in &samples {
        let d = nearest(p);
        sum2 += area * d;
        weight2 += area;
        far = far.max(d);
    }
    let shape_to_mesh = sum2 / weight2.max(f64::MIN_POSITIVE);
    let shape_volume = match *shape {
        Shape::Sphere { radius, .. } => 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3),
        Shape::Torus { major, minor, .. } => {
            2.0 * std::f64::consts::PI * std::f64::consts::PI * major * minor * minor
        }
    };
    let volume = super::enclosed_volume(&mesh.positions, &mesh.triangles);
    Fidelity {
        mesh_to_shape,
        shape_to_mesh,
        chamfer: (mesh_to_shape + shape_to_mesh) / 2.0,
        hausdorff: far,
        volume_error: volume / shape_volume - 1.0,
        triangles: tris.len(),
    }
}

/// Distance from `p` to the triangle (Ericson, "Real-Time Collision Detection", 5.1.5).
fn point_triangle_distance(p: DVec3, &[a, b, c]: &[DVec3; 3]) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + v * ab)).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + w * ac)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + w * (c - b))).length();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length()
}

/// Plain marching cubes of `material`'s voxels (every non-void one with `None`):
/// vertices at the midpoints of the edges between inside and outside voxel centres,
/// each piece of a cell a polygon through them, fanned into triangles (Lorensen and
/// Cline 1987, with the faces' pairings of the smooth surface's `cell_case`, so it is the same
/// closed 2-manifold topology as the smooth surface). The reference the smooth
/// surface is measured against.
pub fn marching_cubes(grid: &Grid, material: Option<u8>) -> SurfaceMesh {
    let volume = Volume::of(grid, material);
    let mut vertex_of = std::collections::HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    volume.for_each_surface_cell(|[x, y, z], k, case| {
        let base = DVec3::new(x as f64, y as f64, z as f64);
        for piece in &case.loops {
            // Outward: from the inside end of each crossed edge to the other.
            let mut outward = DVec3::ZERO;
            let ring: Vec<u32> = piece
                .iter()
                .map(|&e| {
                    let e = e as usize;
                    let (c0, _) = edge_corners(e);
                    let axis = e / 4;
                    outward[axis] += if k >> c0 & 1 == 1 { 1.0 } else { -1.0 };
                    // The edge's lower end, in padded voxel coordinates: its key.
                    let lower = [x + (c0 & 1), y + (c0 >> 1 & 1), z + (c0 >> 2 & 1)];
                    let key = (volume.at(lower[0], lower[1], lower[2]), axis);
                    *vertex_of.entry(key).or_insert_with(|| {
                        positions.push(base + edge_midpoint(e));
                        positions.len() as u32 - 1
                    })
                })
                .collect();
            // Newell's normal of the ring, against the outward direction.
            let mut normal = DVec3::ZERO;
            for i in 0..ring.len() {
                let (p, q) = (
                    positions[ring[i] as usize],
                    positions[ring[(i + 1) % ring.len()] as usize],
                );
                normal += p.cross(q);
            }
            let ccw = normal.dot(outward) > 0.0;
            for i in 1..ring.len() - 1 {
                let t = [ring[0], ring[i], ring[i + 1]];
                triangles.push(if ccw { t } else { [t[0], t[2], t[1]] });
            }
        }
    });
    let nets = Nets {
        cells: vec![DVec3::ZERO; positions.len()],
        positions,
        triangles,
    };
    let mut mesh = SurfaceMesh::default();
    append_nets(grid, material, nets, &mut mesh);
    mesh
}

/// One row of `voxlab bench --surface-fidelity`.
#[derive(Clone, Debug)]
pub struct FidelityRow {
    pub shape: &'static str,
    pub size: u32,
    /// "marching cubes" or "surface nets, relaxed N".
    pub method: String,
    pub fidelity: Fidelity,
    pub extract_ms: f64,
}

impl FidelityRow {
    pub fn json(&self) -> serde_json::Value {
        let f = &self.fidelity;
        serde_json::json!({
            "shape": self.shape,
            "size": self.size,
            "method": self.method,
            "triangles": f.triangles,
            "chamfer_voxels": f.chamfer,
            "hausdorff_voxels": f.hausdorff,
            "mesh_to_shape_voxels": f.mesh_to_shape,
            "shape_to_mesh_voxels": f.shape_to_mesh,
            "volume_error": f.volume_error,
            "extract_ms": self.extract_ms,
        })
    }
}

/// The sphere and the torus at each size, by marching cubes and by surface nets relaxed
/// 0, 16, [`super::DEFAULT_RELAX`] and 256 times.
pub fn fidelity_rows(sizes: &[u32], mut progress: impl FnMut(&FidelityRow)) -> Vec<FidelityRow> {
    let mut rows = Vec::new();
    for &n in sizes {
        for shape in [Shape::sphere_in(n), Shape::torus_in(n)] {
            let grid = shape.voxelize(n);
            let mut methods: Vec<(String, Option<u32>)> = vec![("marching cubes".into(), None)];
            for r in [0, 16, super::DEFAULT_RELAX, 256] {
                methods.push((format!("surface nets, relaxed {r}"), Some(r)));
            }
            for (method, relax) in methods {
                let start = std::time::Instant::now();
                let mesh = match relax {
                    None => marching_cubes(&grid, Some(1)),
                    Some(r) => super::extract(&grid, r).expect("a small grid"),
                };
                let extract_ms = start.elapsed().as_secs_f64() * 1e3;
                let row = FidelityRow {
                    shape: shape.name(),
                    size: n,
                    method,
                    fidelity: fidelity(&mesh, &shape),
                    extract_ms,
                };
                progress(&row);
                rows.push(row);
            }
        }
    }
    rows
}

/// The rows as a Markdown table.
pub fn fidelity_table(rows: &[FidelityRow]) -> String {
    let mut s = String::from(
        "| shape | grid | surface | triangles | Chamfer (voxels) | Hausdorff (voxels) | \
         volume error | extract ms |\n|---|---:|---|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let f = &r.fidelity;
        s += &format!(
            "| {} | {}^3 | {} | {} | {:.4} | {:.3} | {:+.3} % | {:.1} |\n",
            r.shape,
            r.size,
            r.method,
            f.triangles,
            f.chamfer,
            f.hausdorff,
            f.volume_error * 100.0,
            r.extract_ms
        );
    }
    s
}
