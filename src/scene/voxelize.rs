//! Conservative triangle voxelization and interior fill, independent of any file format.
//!
//! A voxel is marked when its closed box overlaps a triangle, decided exactly by the
//! separating-axis test of T. Akenine-Möller, "Fast 3D Triangle-Box Overlap Testing",
//! Journal of Graphics Tools 6(1), 2001. Closed meshes are then filled by flooding the
//! outside void from the grid border; what the flood cannot reach is inside.

use std::collections::{HashMap, VecDeque};

use glam::{DVec3, IVec3, UVec3};

use super::{Grid, MAX_VOXELS, VOID};
use crate::sparse::{BRICK, SparseTree, VoxelSource};
use rustc_hash::FxHashMap;

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
pub(crate) fn boundary_edge_count(triangles: &[[DVec3; 3]]) -> usize {
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
pub(crate) fn grid_layout(
    extent: DVec3,
    voxel_size: f64,
    storage: super::Storage,
) -> Result<UVec3, String> {
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
    // Past DENSE_MAX_VOXELS (Storage::Auto) the voxels go straight into a sparse tree,
    // bounded by its side instead.
    let sparse_ok =
        storage != super::Storage::Dense && dims_f.max_element() <= f64::from(MAX_SPARSE_MESH_SIDE);
    if total > MAX_VOXELS as f64 && !sparse_ok {
        return Err(format!(
            "a voxel size of {voxel_size} gives a grid of {} x {} x {} = {total:.0} voxels; \
             at most {MAX_VOXELS} are allowed densely, or sides up to \
             {MAX_SPARSE_MESH_SIDE} held as a sparse tree (use a coarser resolution)",
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
    let (vs, origin) = (grid.voxel_size(), grid.origin());
    let (nx, ny) = (dims.x as usize, dims.y as usize);
    let data = grid.data_mut();
    let mut marked = 0;
    for (tri, &m) in triangles.iter().zip(materials) {
        overlapped_voxels(tri, origin, vs, dims, 0..dims.z, |v| {
            let i = v.x as usize + nx * (v.y as usize + ny * v.z as usize);
            if data[i] == VOID {
                marked += 1;
            }
            data[i] = m;
        });
    }
    marked
}

/// Calls `mark` for every voxel of a grid of `dims` (`origin`, `voxel_size`) with its z
/// in `z` whose closed box overlaps `tri`, in x-fastest order: the conservative surface
/// test both voxelizers share. Only the voxels of the triangle's bounding box are tested.
fn overlapped_voxels(
    tri: &[DVec3; 3],
    origin: DVec3,
    voxel_size: f64,
    dims: IVec3,
    z: std::ops::Range<i32>,
    mut mark: impl FnMut(IVec3),
) {
    // Grow each box by a hair: rounding must never drop a voxel the triangle touches
    // (conservative means erring outwards), e.g. a face lying on a voxel boundary.
    let eps = 1e-9;
    let half = DVec3::splat(0.5 * voxel_size * (1.0 + eps));
    let lo = (tri[0].min(tri[1]).min(tri[2]) - origin) / voxel_size;
    let hi = (tri[0].max(tri[1]).max(tri[2]) - origin) / voxel_size;
    let lo = (lo - DVec3::splat(eps)).floor().as_ivec3().max(IVec3::ZERO);
    let hi = (hi + DVec3::splat(eps)).floor().as_ivec3().min(dims - 1);
    for vz in lo.z.max(z.start)..=hi.z.min(z.end - 1) {
        for y in lo.y..=hi.y {
            for x in lo.x..=hi.x {
                let v = IVec3::new(x, y, vz);
                let centre = origin + (v.as_dvec3() + 0.5) * voxel_size;
                if tri_box_overlap(centre, half, *tri) {
                    mark(v);
                }
            }
        }
    }
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
pub(crate) const MAX_FILL_BYTES: u64 = 8 << 30;

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

/// Largest side of a mesh voxelized straight into a sparse tree: the fill keeps one
/// byte per 4x4x4 brick of the grid's box (128 MiB at 2048), and a pyramid over them.
pub(crate) const MAX_SPARSE_MESH_SIDE: u32 = 2048;

/// Most shell bricks (4x4x4 blocks the surface touches) a mesh voxelized sparse may
/// have: 2^24, each 64 bytes and a reach mask.
pub(crate) const MAX_SHELL_BRICKS: usize = 1 << 24;

/// A mesh voxelized into a sparse tree: [`voxelize_triangles`] and [`fill_interior`]
/// done without the dense grid.
pub(crate) struct SparseVoxels {
    pub tree: SparseTree,
    pub shell_voxels: usize,
    pub interior_voxels: u64,
}

// A brick's state in the fill: touched by the surface, reached from outside, enclosed.
const SHELL: u8 = 1;
const OUT: u8 = 2;
const IN: u8 = 4;
/// An empty brick the flood has reached but not yet spread from (on its stack).
const PENDING: u8 = 8;

/// Calls `visit` for the 16 voxels of the neighbour of brick `b` across face `f` that
/// touch `b` (some may lie outside the grid: the caller skips those).
fn shell_face(b: IVec3, f: IVec3, visit: &mut impl FnMut(IVec3)) {
    let lo = b * BRICK;
    let axis = f.abs().to_array().iter().position(|&c| c != 0).unwrap();
    let layer = if f[axis] > 0 {
        lo[axis] + BRICK
    } else {
        lo[axis] - 1
    };
    for u in 0..BRICK {
        for w in 0..BRICK {
            let mut v = lo;
            v[axis] = layer;
            v[(axis + 1) % 3] += u;
            v[(axis + 2) % 3] += w;
            visit(v);
        }
    }
}

/// The shell in bricks, the outside flood over whole empty bricks, and the enclosed
/// bricks filled implicitly: the voxel source the tree is built from.
struct FilledShell {
    dims: UVec3,
    bricks: FxHashMap<IVec3, [u8; 64]>,
    /// Per level `j`, per cube of `2^j` bricks a side: the OR of its bricks' states.
    levels: Vec<(IVec3, Vec<u8>)>,
    fill: u8,
}

impl FilledShell {
    fn state(&self, j: usize, c: IVec3) -> u8 {
        let (n, s) = &self.levels[j];
        if c.cmplt(IVec3::ZERO).any() || c.cmpge(*n).any() {
            return OUT;
        }
        s[(c.x + n.x * (c.y + n.y * c.z)) as usize]
    }
}

impl VoxelSource for FilledShell {
    fn dims(&self) -> UVec3 {
        self.dims
    }
    fn material(&self, v: IVec3) -> u8 {
        let b = v.div_euclid(IVec3::splat(BRICK));
        if let Some(k) = self.bricks.get(&b) {
            let o = v - b * BRICK;
            return k[(o.x + 4 * o.y + 16 * o.z) as usize];
        }
        if self.state(0, b) == IN {
            self.fill
        } else {
            VOID
        }
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        if size < BRICK || size.count_ones() != 1 || lo % size != IVec3::ZERO {
            return None;
        }
        let j = (size / BRICK).trailing_zeros() as usize;
        if j >= self.levels.len() {
            return None;
        }
        match self.state(j, lo / size) {
            OUT => Some(VOID),
            IN => Some(self.fill),
            _ => None,
        }
    }
}

/// The outside flood of [`fill_interior`] over bricks: whole empty bricks (a scanline
/// fill along runs of them in x) and the void voxels of shell bricks one by one,
/// 6-connected, from every voxel of the grid's boundary layer. Afterwards `state` says
/// which empty bricks it reached (`OUT`; unreached ones stay 0) and `reached` which void
/// voxels of each shell brick.
struct OutsideFlood<'a> {
    /// The grid's voxels and bricks a side.
    dims: IVec3,
    nb: IVec3,
    bricks: &'a FxHashMap<IVec3, [u8; 64]>,
    /// Per brick: 0 (empty, unreached), `SHELL`, `PENDING` or `OUT`.
    state: Vec<u8>,
    /// Per shell brick, the voxels reached (bit `o.x + 4 o.y + 16 o.z`).
    reached: FxHashMap<IVec3, u64>,
    brick_stack: Vec<IVec3>,
    voxel_stack: Vec<IVec3>,
}

impl<'a> OutsideFlood<'a> {
    fn new(dims: IVec3, bricks: &'a FxHashMap<IVec3, [u8; 64]>) -> Self {
        let nb = (dims + BRICK - 1) / BRICK;
        let mut flood = Self {
            dims,
            nb,
            bricks,
            state: vec![0u8; nb.as_uvec3().as_u64vec3().element_product() as usize],
            reached: bricks.keys().map(|b| (*b, 0)).collect(),
            brick_stack: Vec::new(),
            voxel_stack: Vec::new(),
        };
        for b in bricks.keys() {
            let i = flood.index(*b);
            flood.state[i] = SHELL;
        }
        flood
    }

    fn index(&self, b: IVec3) -> usize {
        (b.x + self.nb.x * (b.y + self.nb.y * b.z)) as usize
    }

    /// Marks voxel `v` reached, if it is in the grid, void and unreached: as a whole
    /// empty brick (pending until the flood spreads from it), or one shell-brick voxel.
    fn visit(&mut self, v: IVec3) {
        if v.cmplt(IVec3::ZERO).any() || v.cmpge(self.dims).any() {
            return;
        }
        let b = v.div_euclid(IVec3::splat(BRICK));
        let i = self.index(b);
        match self.state[i] {
            0 => {
                self.state[i] = PENDING;
                self.brick_stack.push(b);
            }
            SHELL => {
                let o = v - b * BRICK;
                let k = o.x + 4 * o.y + 16 * o.z;
                if self.bricks[&b][k as usize] != VOID {
                    return;
                }
                let r = self
                    .reached
                    .get_mut(&b)
                    .expect("every shell brick has a mask");
                if *r & (1 << k) == 0 {
                    *r |= 1 << k;
                    self.voxel_stack.push(v);
                }
            }
            _ => {}
        }
    }

    fn spread(&mut self) {
        let d = self.dims;
        // Seeds: every voxel of the grid's boundary layer.
        for z in 0..d.z {
            for y in 0..d.y {
                if z == 0 || y == 0 || z == d.z - 1 || y == d.y - 1 {
                    (0..d.x).for_each(|x| self.visit(IVec3::new(x, y, z)));
                } else {
                    self.visit(IVec3::new(0, y, z));
                    self.visit(IVec3::new(d.x - 1, y, z));
                }
            }
        }
        loop {
            if let Some(b) = self.brick_stack.pop() {
                if self.state[self.index(b)] == PENDING {
                    self.spread_run(b);
                }
                // Otherwise reached along a run since it was pushed.
            } else if let Some(v) = self.voxel_stack.pop() {
                for f in crate::scene::FACES {
                    self.visit(v + f);
                }
            } else {
                break;
            }
        }
    }

    /// Reaches the run of unreached empty bricks along x through `b` at once (a scanline
    /// fill: rows are contiguous in memory, and seeds few), and what borders it.
    fn spread_run(&mut self, b: IVec3) {
        let row = |x: i32| IVec3::new(x, b.y, b.z);
        let open = |s: u8| s == 0 || s == PENDING;
        let (mut x0, mut x1) = (b.x, b.x);
        let i = self.index(b);
        self.state[i] = OUT;
        while x0 > 0 && open(self.state[self.index(row(x0 - 1))]) {
            x0 -= 1;
            let i = self.index(row(x0));
            self.state[i] = OUT;
        }
        while x1 + 1 < self.nb.x && open(self.state[self.index(row(x1 + 1))]) {
            x1 += 1;
            let i = self.index(row(x1));
            self.state[i] = OUT;
        }
        // Past the run's ends: shell bricks only (anything else stopped it).
        for (x, f) in [(x0, IVec3::NEG_X), (x1, IVec3::X)] {
            let n = row(x) + f;
            if n.x >= 0 && n.x < self.nb.x && self.state[self.index(n)] == SHELL {
                shell_face(row(x), f, &mut |v| self.visit(v));
            }
        }
        // The four rows beside it: one seed per run of unreached bricks, and the faces of
        // shell bricks.
        for f in [IVec3::NEG_Y, IVec3::Y, IVec3::NEG_Z, IVec3::Z] {
            let side = row(x0) + f;
            if side.cmplt(IVec3::ZERO).any() || side.cmpge(self.nb).any() {
                continue;
            }
            let mut in_run = false;
            for x in x0..=x1 {
                let n = IVec3::new(x, side.y, side.z);
                let k = self.index(n);
                match self.state[k] {
                    0 if !in_run => {
                        self.state[k] = PENDING;
                        self.brick_stack.push(n);
                        in_run = true;
                    }
                    0 | PENDING => in_run = true,
                    SHELL => {
                        in_run = false;
                        shell_face(row(x), f, &mut |v| self.visit(v));
                    }
                    _ => in_run = false,
                }
            }
        }
    }
}

/// The triangles voxelized into a sparse tree of `dims` (see [`voxelize_triangles`] and
/// [`fill_interior`], whose rules it follows voxel for voxel: a voxel a triangle's box
/// test touches takes the last such triangle's material; void the outside cannot reach
/// is filled). The fill's material is the surface's one material; a surface of several
/// materials (whose hidden voxels take the nearest surface voxel's) is refused.
pub(crate) fn voxelize_sparse(
    dims: UVec3,
    voxel_size: f64,
    origin: DVec3,
    triangles: &[[DVec3; 3]],
    materials: &[u8],
) -> Result<SparseVoxels, String> {
    assert_eq!(triangles.len(), materials.len());
    if dims.max_element() > MAX_SPARSE_MESH_SIDE {
        return Err(format!(
            "{}x{}x{} voxels: a mesh is voxelized sparse up to {MAX_SPARSE_MESH_SIDE} a side",
            dims.x, dims.y, dims.z
        ));
    }
    let fill = materials.first().copied().unwrap_or(VOID);
    if materials.iter().any(|&m| m != fill) {
        return Err(format!(
            "{}x{}x{} voxels are held as a sparse tree, whose interior fill takes one \
             material, and the mesh has several: give it one material (scene.material) or \
             a coarser resolution",
            dims.x, dims.y, dims.z
        ));
    }
    let d = dims.as_ivec3();
    // The shell, as voxelize_triangles marks it: in slabs of z on every core, each
    // slab taking the triangles in order, so the last triangle still wins a voxel.
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let total_bricks = AtomicUsize::new(0);
    let slab = (d.z / BRICK / (4 * rayon::current_num_threads() as i32)).max(1) * BRICK;
    let slabs: Vec<i32> = (0..d.z).step_by(slab as usize).collect();
    type Shell = (FxHashMap<IVec3, [u8; 64]>, usize);
    let shells: Vec<Result<Shell, String>> = slabs
        .par_iter()
        .map(|&z0| {
            let z1 = (z0 + slab).min(d.z);
            let mut bricks: FxHashMap<IVec3, [u8; 64]> = FxHashMap::default();
            let mut marked = 0;
            for (tri, &m) in triangles.iter().zip(materials) {
                overlapped_voxels(tri, origin, voxel_size, d, z0..z1, |v| {
                    let b = v.div_euclid(IVec3::splat(BRICK));
                    let o = v - b * BRICK;
                    let brick = bricks.entry(b).or_insert_with(|| {
                        total_bricks.fetch_add(1, Ordering::Relaxed);
                        [VOID; 64]
                    });
                    let cell = &mut brick[(o.x + 4 * o.y + 16 * o.z) as usize];
                    if *cell == VOID {
                        marked += 1;
                    }
                    *cell = m;
                });
                if total_bricks.load(Ordering::Relaxed) > MAX_SHELL_BRICKS {
                    return Err(format!(
                        "the surface touches more than {MAX_SHELL_BRICKS} blocks of 4x4x4 \
                         voxels (a sparse grid's bound on host memory); choose a coarser \
                         resolution"
                    ));
                }
            }
            Ok((bricks, marked))
        })
        .collect();
    let mut bricks: FxHashMap<IVec3, [u8; 64]> = FxHashMap::default();
    let mut shell_voxels = 0;
    for shell in shells {
        let (b, marked) = shell?;
        bricks.extend(b);
        shell_voxels += marked;
    }
    // The outside flood of fill_interior, over whole empty bricks and the void voxels of
    // shell bricks (6-connected, from the grid's boundary).
    let nb = (d + BRICK - 1) / BRICK;
    let mut flood = OutsideFlood::new(d, &bricks);
    flood.spread();
    let OutsideFlood {
        mut state, reached, ..
    } = flood;
    let in_grid = |v: IVec3| v.cmpge(IVec3::ZERO).all() && v.cmplt(d).all();
    // What the flood did not reach is inside: enclosed empty bricks whole (never at the
    // grid's edge, whose voxels seeded the flood), and the unreached void of shell bricks.
    let mut interior_voxels = 0u64;
    for s in state.iter_mut().filter(|s| **s == 0) {
        *s = IN;
        interior_voxels += 64;
    }
    for (b, brick) in bricks.iter_mut() {
        let r = reached[b];
        for (k, cell) in brick.iter_mut().enumerate() {
            let v = *b * BRICK + IVec3::new(k as i32 % 4, k as i32 / 4 % 4, k as i32 / 16);
            if *cell == VOID && in_grid(v) && r & (1 << k) == 0 {
                *cell = fill;
                interior_voxels += 1;
            }
        }
    }
    // The pyramid of brick states the tree builder asks.
    let mut levels = vec![(nb, state)];
    while levels.last().unwrap().0.max_element() > 1 {
        let (n, s) = levels.last().unwrap();
        let m = (*n + 1) / 2;
        let mut next = vec![0u8; m.as_uvec3().as_u64vec3().element_product() as usize];
        for z in 0..n.z {
            for y in 0..n.y {
                for x in 0..n.x {
                    let c = IVec3::new(x, y, z) / 2;
                    next[(c.x + m.x * (c.y + m.y * c.z)) as usize] |=
                        s[(x + n.x * (y + n.y * z)) as usize];
                }
            }
        }
        // A cube reaching past the brick grid holds void there.
        if (*n % 2).cmpne(IVec3::ZERO).any() {
            for z in 0..m.z {
                for y in 0..m.y {
                    for x in 0..m.x {
                        let c = IVec3::new(x, y, z);
                        if (c * 2 + 1).cmpge(*n).any() {
                            next[(c.x + m.x * (c.y + m.y * c.z)) as usize] |= OUT;
                        }
                    }
                }
            }
        }
        levels.push((m, next));
    }
    let source = FilledShell {
        dims,
        bricks,
        levels,
        fill,
    };
    let tree = SparseTree::build(&source, crate::sparse::GPU_LOG_BRANCH);
    drop(source);
    Ok(SparseVoxels {
        tree,
        shell_voxels,
        interior_voxels,
    })
}
