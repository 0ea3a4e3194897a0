//! Conservative triangle voxelization and interior fill, independent of any file format.
//!
//! A voxel is marked when its closed box overlaps a triangle, decided exactly by the
//! separating-axis test of T. Akenine-Möller, "Fast 3D Triangle-Box Overlap Testing",
//! Journal of Graphics Tools 6(1), 2001. Closed meshes are then filled by flooding the
//! outside void from the grid border; what the flood cannot reach is inside.

use std::collections::{HashMap, VecDeque};

use glam::{DVec3, IVec3, UVec3};

use super::{Grid, MAX_VOXELS, VOID};

/// Whether the closed axis-aligned box `centre ± half` and the closed triangle `tri`
/// share at least one point (touching counts).
///
/// The 13 candidate separating axes of Akenine-Möller (2001): the 3 box face normals,
/// the triangle normal, and the 9 cross products of the box edge directions with the
/// triangle edges. If none separates the projections, the convex sets intersect (the
/// separating axis theorem for convex polyhedra). Degenerate triangles (segments,
/// points) are handled too: the zero normal never separates, and the remaining axes
/// are exactly the separating axes of a segment or a point against a box.
pub fn tri_box_overlap(centre: DVec3, half: DVec3, tri: [DVec3; 3]) -> bool {
    // Work relative to the box centre so the box is symmetric: its projection onto an
    // axis a is [-r, r] with r = half . |a|.
    let v = [tri[0] - centre, tri[1] - centre, tri[2] - centre];
    let separated = |axis: DVec3| {
        let p0 = axis.dot(v[0]);
        let p1 = axis.dot(v[1]);
        let p2 = axis.dot(v[2]);
        let r = half.dot(axis.abs());
        p0.min(p1).min(p2) > r || p0.max(p1).max(p2) < -r
    };

    // Box face normals: the two boxes' overlap, the cheapest of the 13 tests.
    let lo = v[0].min(v[1]).min(v[2]);
    let hi = v[0].max(v[1]).max(v[2]);
    if lo.cmpgt(half).any() || hi.cmplt(-half).any() {
        return false;
    }

    let e = [v[1] - v[0], v[2] - v[1], v[0] - v[2]];
    // Triangle plane: the box straddles it iff |n . (v0 - c)| <= half . |n|.
    if separated(e[0].cross(e[1])) {
        return false;
    }
    for edge in e {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            if separated(axis.cross(edge)) {
                return false;
            }
        }
    }
    true
}

/// Signed volume enclosed by a triangle soup by the divergence theorem:
/// `sum v0 . (v1 x v2) / 6`. Positive for a closed mesh with outward (counter-clockwise)
/// winding; meaningful only for closed meshes.
pub fn signed_volume(triangles: &[[DVec3; 3]]) -> f64 {
    triangles
        .iter()
        .map(|t| t[0].dot(t[1].cross(t[2])))
        .sum::<f64>()
        / 6.0
}

/// Number of edges not shared by exactly two triangles, after welding vertices at
/// identical positions (formats such as glTF split vertices along UV seams, so index
/// identity would call every textured mesh open). Degenerate triangles, whose welded
/// corners coincide, are ignored: they enclose nothing.
pub fn boundary_edge_count(triangles: &[[DVec3; 3]]) -> usize {
    let key = |p: DVec3| {
        // -0.0 and 0.0 are one position.
        let n = |x: f64| if x == 0.0 { 0u64 } else { x.to_bits() };
        (n(p.x), n(p.y), n(p.z))
    };
    let mut ids: HashMap<(u64, u64, u64), u32> = HashMap::new();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        let mut idx = [0u32; 3];
        for (k, p) in t.iter().enumerate() {
            let next = ids.len() as u32;
            idx[k] = *ids.entry(key(*p)).or_insert(next);
        }
        if idx[0] == idx[1] || idx[1] == idx[2] || idx[2] == idx[0] {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (idx[k], idx[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    edges.values().filter(|&&c| c != 2).count()
}

/// Grid dimensions and voxel size for a box of `extent`, or why not.
/// `count` voxels along the longest axis, or a given `voxel_size`.
pub(crate) fn grid_layout(extent: DVec3, voxel_size: f64) -> Result<UVec3, String> {
    // A small tolerance so that an extent of exactly n voxels is n, not n + 1, after
    // the rounding of extent / (extent / n).
    let dims_f = (extent / voxel_size - DVec3::splat(1e-9))
        .ceil()
        .max(DVec3::ONE);
    if !dims_f.is_finite() || dims_f.max_element() > u32::MAX as f64 {
        return Err(format!(
            "a voxel size of {voxel_size} gives a grid of {:.3e} x {:.3e} x {:.3e} voxels; \
             at most {MAX_VOXELS} voxels in all are allowed",
            dims_f.x, dims_f.y, dims_f.z
        ));
    }
    let total = dims_f.x * dims_f.y * dims_f.z;
    if total > MAX_VOXELS as f64 {
        return Err(format!(
            "a voxel size of {voxel_size} gives a grid of {} x {} x {} = {total:.0} voxels; \
             at most {MAX_VOXELS} are allowed (use a coarser resolution)",
            dims_f.x, dims_f.y, dims_f.z
        ));
    }
    Ok(dims_f.as_uvec3())
}

/// Marks every voxel of `grid` whose closed box overlaps a triangle with that triangle's
/// material (later triangles win where several touch one voxel). Returns how many
/// voxels were marked. Only the voxels of each triangle's bounding box are tested.
pub fn voxelize_triangles(grid: &mut Grid, triangles: &[[DVec3; 3]], materials: &[u8]) -> usize {
    assert_eq!(triangles.len(), materials.len());
    let dims = grid.dims().as_ivec3();
    let vs = grid.voxel_size();
    let origin = grid.origin();
    // Grow each box by a hair: rounding must never drop a voxel the triangle touches
    // (conservative means erring outwards), e.g. a face lying on a voxel boundary.
    let eps = 1e-9;
    let half = DVec3::splat(0.5 * vs * (1.0 + eps));
    let (nx, ny) = (dims.x as usize, dims.y as usize);
    let data = grid.data_mut();
    let mut marked = 0;
    for (tri, &m) in triangles.iter().zip(materials) {
        let lo = (tri[0].min(tri[1]).min(tri[2]) - origin) / vs;
        let hi = (tri[0].max(tri[1]).max(tri[2]) - origin) / vs;
        let lo = (lo - DVec3::splat(eps)).floor().as_ivec3().max(IVec3::ZERO);
        let hi = (hi + DVec3::splat(eps)).floor().as_ivec3().min(dims - 1);
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let centre = origin + (IVec3::new(x, y, z).as_dvec3() + 0.5) * vs;
                    if tri_box_overlap(centre, half, *tri) {
                        let i = x as usize + nx * (y as usize + ny * z as usize);
                        if data[i] == VOID {
                            marked += 1;
                        }
                        data[i] = m;
                    }
                }
            }
        }
    }
    marked
}

/// Fills the inside of a closed shell: floods the void reachable from outside the grid
/// (as if the grid had a 1-voxel void border, so every void border voxel is a seed)
/// through face neighbours; every void voxel the flood does not reach is inside. A
/// conservative surface voxelization of a closed surface has no 6-connected gaps, so
/// the flood cannot leak in. Inside voxels take the material of the nearest shell voxel
/// (breadth-first from the shell), so a multi-material mesh is filled by its own
/// materials. Returns the number of voxels filled.
/// Bytes [`fill_interior`] may allocate for a grid of `voxels` at most: a state byte per
/// voxel and two queues of u32 indices that can each hold every voxel.
pub fn fill_bytes(voxels: u64) -> u64 {
    voxels * (1 + 4 + 4)
}

/// Largest [`fill_bytes`] a voxelization may need; a larger one is refused before
/// anything is allocated.
pub const MAX_FILL_BYTES: u64 = 8 << 30;

pub fn fill_interior(grid: &mut Grid) -> usize {
    let d = grid.dims();
    let (nx, ny, nz) = (d.x as usize, d.y as usize, d.z as usize);
    let data = grid.data_mut();
    const UNSEEN: u8 = 0;
    const OUTSIDE: u8 = 1;
    const DONE: u8 = 2;
    let mut state = vec![UNSEEN; data.len()];
    let idx = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
    let neighbours = move |i: usize| {
        let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
        let mut out = [usize::MAX; 6];
        if x > 0 {
            out[0] = i - 1;
        }
        if x + 1 < nx {
            out[1] = i + 1;
        }
        if y > 0 {
            out[2] = i - nx;
        }
        if y + 1 < ny {
            out[3] = i + nx;
        }
        if z > 0 {
            out[4] = i - nx * ny;
        }
        if z + 1 < nz {
            out[5] = i + nx * ny;
        }
        out
    };

    // Outside flood, seeded from the void voxels of the six border faces.
    // u32 indices: a grid holds at most MAX_VOXELS (2^31) voxels.
    let mut queue: Vec<u32> = Vec::new();
    let seed = |i: usize, state: &mut [u8], queue: &mut Vec<u32>| {
        if data[i] == VOID && state[i] == UNSEEN {
            state[i] = OUTSIDE;
            queue.push(i as u32);
        }
    };
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                if x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz {
                    seed(idx(x, y, z), &mut state, &mut queue);
                }
            }
        }
    }
    while let Some(i) = queue.pop() {
        for j in neighbours(i as usize) {
            if j != usize::MAX && data[j] == VOID && state[j] == UNSEEN {
                state[j] = OUTSIDE;
                queue.push(j as u32);
            }
        }
    }

    // Inside: breadth-first from the shell so each inside voxel copies the material of
    // a nearest shell voxel.
    let mut bfs: VecDeque<u32> = (0..data.len())
        .filter(|&i| data[i] != VOID)
        .map(|i| i as u32)
        .collect();
    let mut filled = 0;
    while let Some(i) = bfs.pop_front() {
        let m = data[i as usize];
        for j in neighbours(i as usize) {
            if j != usize::MAX && data[j] == VOID && state[j] == UNSEEN {
                state[j] = DONE;
                data[j] = m;
                filled += 1;
                bfs.push_back(j as u32);
            }
        }
    }
    filled
}
