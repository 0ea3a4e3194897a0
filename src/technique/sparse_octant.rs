//! The sparse octant traversal: the sparse 64-tree ([`super::sparse`]) cut at cubes of
//! [`log_cell_side`] voxels, with the octant field ([`super::octant`]) over the cut. A cube
//! the tree holds as one material is a cell of the field: a ray in that material reads
//! its octant's cube of such cells and skips it whole, however many tree nodes it
//! crosses; a cube that holds a node is walked through the tree below it, from that
//! node. The tree walk's cost grows with the grid's side (a ray leaving a surface
//! climbs level by level out of ever larger cubes, and descends again into its hit); this
//! walk climbs at most the levels of one cell.
//!
//!
//! Below a node's cell, the tree's leaves (its 4^3 cubes that hold more than one
//! material, the voxels next to surfaces) carry the octant field at the voxel: each of
//! their voxels has the octant word of [`super::octant::OctantField`], its largest cube
//! of its material toward each octant, so a ray that runs along a surface (a shadow ray
//! to a light beside a wall) skips along it instead of stepping voxel by voxel through
//! the leaves. The codes are the recurrence of [`super::octant::octant_radii`] swept
//! over the leaves alone ([`leaf_words`]): a neighbour outside the leaves lies in a
//! uniform region the cut or the tree holds, whose cube bounds its radius from below, so
//! every cube is uniform (a lower bound of the dense field's), and the walk leaves it
//! where the dense DDA does. They cost a word a voxel of each leaf, 256 bytes a leaf,
//! and are built only while the walk's data stays within [`MAX_WALK_BYTES`].
//!
//! Layout of its words (`walk_data`, shaders/traversal_sparse_octant.wgsl): the tree's
//! words ([`crate::sparse`]: a header vec4 and five vec4s a node), then, at vec4 `h = 1 +
//! 5 * node count`, two vec4s (log2 of the cell side, the cut's dims; the first leaf's
//! node index, the number of leaves with codes, the vec4 of the first leaf's codes
//! counted from `h`, 0) and from `h + 2` two words a cell (x fastest): the octant
//! field's word (material and eight codes, [`super::octant::OctantField`]) and 0 for a
//! uniform cell, or 0 and the node's index plus one for a cell the tree holds as a node;
//! then, from a vec4 boundary, 64 words a leaf (its voxels, x fastest), in node order.
//! The tree is not copied: its words and the cut's are uploaded as two parts of one
//! buffer.

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::TraversalModel;
use super::octant::{corner_cube, octant, octant_radii, word};
use crate::sparse::{Cut, GPU_LOG_BRANCH, Region, Regions, SparseTree};

/// The most cells the cut has: 2 M, 16 MiB.
pub const MAX_CELLS: u64 = 1 << 21;

/// The most bytes of the walk's data (tree, cut and the leaves' codes) with which the
/// leaves get their codes: 120 MiB, within the 128 MiB a storage buffer binding holds on
/// lavapipe (and wgpu's default limit). A larger tree is walked without them.
pub const MAX_WALK_BYTES: usize = 120 << 20;

/// Voxels a leaf of the 64-tree holds, each with a word of codes.
const LEAF_VOXELS: usize = 64;

/// Log2 of the side of the cut's cells for a tree of these dims and branching: the
/// smallest side (4, 8, 16 ... voxels) whose cells number at most [`MAX_CELLS`]: the
/// smaller the cells, the nearer to a surface the octant cubes reach, and the fewer
/// steps a walk takes through the tree below a cell. A side between the tree's levels
/// (8 for the 64-tree) descends from the node of the level above.
pub fn log_cell_side(dims: UVec3, log_branch: u32, levels: u32) -> u32 {
    let mut log = log_branch;
    while log < log_branch * levels {
        let cells = (dims.as_u64vec3() + ((1u64 << log) - 1)) >> log;
        if cells.element_product() <= MAX_CELLS {
            break;
        }
        log += 1;
    }
    log
}

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "sparse_octant",
    summary: "the sparse 64-tree cut at its smallest cubes (4, 8 or 16 voxels a side) \
              that number at most 2 M, with the octant field over the cut: a uniform cube's octant \
              cube of uniform cubes is skipped whole, the others are walked through the \
              tree below them",
    label: "sparse 64-tree + octant cells",
    plan: |_, _| Ok(()),
    // Where the plain tree walk claimed grids: on lavapipe (`voxlab bench --sizes 16
    // --size 256 --no-cpu --gpu-runs 3 --experiments experiments/seed_rules.toml --set
    // scene.size=N --traversal sparse,sparse_octant`) 1.66x its speed at 256^3, 1.81x at
    // 512^3 and 1.25x at 1024^3 (cubes of 8), the bunny voxelized at 512 2.14x
    // (docs/sparse-traversal.md, "Octant cells over the tree").
    auto: Some(|scene| {
        if scene.grid.is_sparse() {
            return Ok("the grid is held only as its sparse tree".into());
        }
        super::claim_from_side(scene, super::sparse::SPARSE_FROM_SIDE)
    }),
    wgsl: (
        "shaders/traversal_sparse_octant.wgsl",
        include_str!("../../shaders/traversal_sparse_octant.wgsl"),
    ),
    walks_tree: true,
    // A descent starts at a cell's node: that node's levels of the tree.
    descent_levels: Some(|dims| {
        let levels = crate::sparse::levels_for(dims, GPU_LOG_BRANCH);
        log_cell_side(dims, GPU_LOG_BRANCH, levels).div_ceil(GPU_LOG_BRANCH)
    }),
    data: Some(|grid| Arc::new(SparseOctant::build(grid.tree(GPU_LOG_BRANCH)))),
    device_bytes: None,
};

/// The tree and the octant field over its cut and in its leaves (see the module
/// documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct SparseOctant {
    tree: Arc<SparseTree>,
    log_cell: u32,
    /// The shift of the children of a cell's node (`SparseTree::cut_node_log`).
    node_shift: u32,
    cut_dims: UVec3,
    /// The first leaf's node index and how many leaves have codes (0: none).
    leaf_first: u32,
    leaf_count: u32,
    /// Where the leaves' codes start in `cut`.
    codes_at: usize,
    /// The cut's two header vec4s, its cells, then the leaves' codes.
    cut: Vec<u32>,
}

/// Words before the cut's first cell.
const CUT_HEADER_WORDS: usize = 8;

impl SparseOctant {
    pub fn build(tree: Arc<SparseTree>) -> Self {
        let log_cell = log_cell_side(tree.dims(), tree.log_branch(), tree.levels());
        Self::with_cell_side(tree, log_cell)
    }

    /// With cells of `2^log_cell` voxels (1 up to the root's cube) whatever the grid: the
    /// tests walk every side the cut can have. The leaves have codes within
    /// [`MAX_WALK_BYTES`].
    pub fn with_cell_side(tree: Arc<SparseTree>, log_cell: u32) -> Self {
        let cut = Self::without_leaf_codes(tree, log_cell);
        let (leaf_first, leaves) = cut.tree.leaves();
        let bytes = 4 * (cut.tree.words().len() + cut.cut.len() + 3 + LEAF_VOXELS * leaves.len());
        if leaves.is_empty() || bytes > MAX_WALK_BYTES {
            return cut;
        }
        cut.with_leaf_codes(leaf_first, &leaves)
    }

    /// Only the cut: a node's cell is walked through the tree down to the voxel.
    pub fn without_leaf_codes(tree: Arc<SparseTree>, log_cell: u32) -> Self {
        let (cut_dims, cut) = tree.cut(log_cell);
        // A node's cell matches no other: uniform cells' cubes stop at it.
        let cells: Vec<Option<u8>> = cut
            .iter()
            .map(|c| match c {
                Cut::Uniform(m) => Some(*m),
                Cut::Node(_) => None,
            })
            .collect();
        let radii: Vec<Vec<u8>> = (0..8)
            .into_par_iter()
            .map(|o| octant_radii(&cells, cut_dims, o))
            .collect();
        debug_assert_eq!(tree.words().len() % 4, 0, "the tree ends on a vec4");
        let mut words = Vec::with_capacity(CUT_HEADER_WORDS + 2 * cut.len());
        words.extend_from_slice(&[log_cell, cut_dims.x, cut_dims.y, cut_dims.z]);
        for (i, c) in cut.iter().enumerate() {
            match c {
                Cut::Uniform(m) => words.extend_from_slice(&[word(*m, &radii, i), 0]),
                Cut::Node(n) => words.extend_from_slice(&[0, n + 1]),
            }
        }
        // The header's second vec4 is filled in by with_leaf_codes.
        words.splice(4..4, [0; 4]);
        Self {
            node_shift: tree.cut_node_log(log_cell) - tree.log_branch(),
            tree,
            log_cell,
            cut_dims,
            leaf_first: 0,
            leaf_count: 0,
            codes_at: 0,
            cut: words,
        }
    }

    /// The cut with the leaves' codes after it (`leaves`: the first leaf's node index and
    /// each leaf's first voxel, [`SparseTree::leaves`]).
    fn with_leaf_codes(mut self, leaf_first: u32, leaves: &[IVec3]) -> Self {
        let codes = leaf_words(&self, leaf_first, leaves);
        let at = self.cut.len().next_multiple_of(4);
        self.cut.resize(at, 0);
        self.cut.extend_from_slice(&codes);
        self.leaf_first = leaf_first;
        self.leaf_count = leaves.len() as u32;
        self.codes_at = at;
        self.cut[4..8].copy_from_slice(&[leaf_first, self.leaf_count, (at / 4) as u32, 0]);
        self
    }

    /// Whether the leaves carry their voxels' codes.
    pub fn has_leaf_codes(&self) -> bool {
        self.leaf_count > 0
    }
}

/// The octant words of every voxel of the leaves (64 a leaf, x fastest, in node order):
/// the recurrence of [`octant_radii`] swept over the leaves, for each octant, from its
/// far corner (leaves in the sweep's order, then each leaf's voxels). A neighbour in
/// another leaf has its radius already; one outside the leaves lies in the uniform
/// region `cut` finds for it (the cut's cube toward the octant, or the tree's child),
/// whose extent toward the octant bounds its radius from below; one outside the grid
/// does not count (as in the dense field: the walk ends there by its own test).
fn leaf_words(cut: &SparseOctant, leaf_first: u32, leaves: &[IVec3]) -> Vec<u32> {
    let tree = &cut.tree;
    let dims = tree.dims().as_ivec3();
    let materials: Vec<Vec<u8>> = (0..leaves.len())
        .into_par_iter()
        .map(|l| tree.node_materials(leaf_first + l as u32))
        .collect();
    let index: FxHashMap<IVec3, u32> = leaves
        .iter()
        .enumerate()
        .map(|(l, &lo)| (lo >> 2, l as u32))
        .collect();
    let local = |u: IVec3| (u.x + 4 * u.y + 16 * u.z) as usize;
    let radii: Vec<Vec<u8>> = (0..8)
        .into_par_iter()
        .map(|o| {
            let down = |a: usize| o >> a & 1 == 1;
            let s = IVec3::new(
                if down(0) { -1 } else { 1 },
                if down(1) { -1 } else { 1 },
                if down(2) { -1 } else { 1 },
            );
            // The sweep visits a voxel after its neighbours toward the octant: leaves by
            // their position against the octant, z first.
            let mut order: Vec<u32> = (0..leaves.len() as u32).collect();
            order.sort_unstable_by_key(|&l| {
                let k = -(leaves[l as usize] * s);
                (k.z, k.y, k.x)
            });
            let sweep =
                |a: usize| -> [i32; 4] { if down(a) { [0, 1, 2, 3] } else { [3, 2, 1, 0] } };
            let mut radii = vec![0u8; LEAF_VOXELS * leaves.len()];
            for &l in &order {
                let lo = leaves[l as usize];
                // The block of 4^3 toward the octant along the axes of `e`: a leaf, or the
                // uniform region holding it (None: past the grid).
                let block = |e: usize| -> Option<Result<u32, Region>> {
                    let b = lo
                        + 4 * s * IVec3::new((e & 1) as i32, (e >> 1 & 1) as i32, (e >> 2) as i32);
                    if b.cmplt(IVec3::ZERO).any() || b.cmpge(dims).any() {
                        return None;
                    }
                    Some(match index.get(&(b >> 2)) {
                        Some(&n) => Ok(n),
                        None => Err(cut.region(b, s)),
                    })
                };
                let blocks: [Option<Result<u32, Region>>; 8] =
                    std::array::from_fn(|e| if e == 0 { Some(Ok(l)) } else { block(e) });
                for z in sweep(2) {
                    for y in sweep(1) {
                        for x in sweep(0) {
                            let p = IVec3::new(x, y, z);
                            if (lo + p).cmpge(dims).any() {
                                continue;
                            }
                            let m = materials[l as usize][local(p)];
                            let mut r = u8::MAX;
                            for e in 1..8usize {
                                let q = p + s * IVec3::new(
                                    (e & 1) as i32,
                                    (e >> 1 & 1) as i32,
                                    (e >> 2) as i32,
                                );
                                let u = lo + q;
                                if u.cmplt(IVec3::ZERO).any() || u.cmpge(dims).any() {
                                    continue;
                                }
                                // Which block q falls in: the axes on which it left this leaf.
                                let out = (0..3)
                                    .fold(0, |k, a| k | usize::from(!(0..4).contains(&q[a])) << a);
                                let inner = q.rem_euclid(IVec3::splat(4));
                                let allowed = match blocks[out].as_ref() {
                                    None => continue,
                                    Some(Ok(n)) => {
                                        let i = *n as usize * LEAF_VOXELS + local(inner);
                                        if materials[*n as usize][local(inner)] == m {
                                            radii[i].saturating_add(1)
                                        } else {
                                            0
                                        }
                                    }
                                    Some(Err(region)) => {
                                        // Cells of 4 and more hold a block whole; smaller
                                        // ones (the tests' cuts) are asked per voxel.
                                        let region = if cut.log_cell >= 2 {
                                            *region
                                        } else {
                                            cut.region(u, s)
                                        };
                                        debug_assert!(
                                            u.cmpge(region.lo).all() && u.cmplt(region.hi).all()
                                        );
                                        if region.material == m {
                                            reach(u, &region, s, dims).saturating_add(1)
                                        } else {
                                            0
                                        }
                                    }
                                };
                                r = r.min(allowed);
                            }
                            radii[l as usize * LEAF_VOXELS + local(p)] = r;
                        }
                    }
                }
            }
            radii
        })
        .collect();
    (0..leaves.len() * LEAF_VOXELS)
        .into_par_iter()
        .map(|i| word(materials[i / LEAF_VOXELS][i % LEAF_VOXELS], &radii, i))
        .collect()
}

/// How far voxel `u`'s cube toward the octant of `s` reaches inside `region`, which holds
/// `u`: its radius, at most 255; a side of the region on the grid's face does not bound
/// it (past the grid nothing counts).
fn reach(u: IVec3, region: &Region, s: IVec3, dims: IVec3) -> u8 {
    let mut r = i32::from(u8::MAX);
    for a in 0..3 {
        let room = if s[a] > 0 {
            (region.hi[a] < dims[a]).then(|| region.hi[a] - 1 - u[a])
        } else {
            (region.lo[a] > 0).then(|| u[a] - region.lo[a])
        };
        if let Some(room) = room {
            r = r.min(room);
        }
    }
    r as u8
}

impl Regions for SparseOctant {
    fn region(&self, v: IVec3, step: IVec3) -> Region {
        let c = v >> self.log_cell as i32;
        let d = self.cut_dims;
        let i = CUT_HEADER_WORDS
            + 2 * (c.x as usize + d.x as usize * (c.y as usize + d.y as usize * c.z as usize));
        let node = self.cut[i + 1];
        if node != 0 {
            let (region, found, shift) = self.tree.descend(v, node - 1, self.node_shift);
            let leaf = found.wrapping_sub(self.leaf_first);
            if shift > 0 || leaf >= self.leaf_count {
                return region;
            }
            let p = v & 3;
            let at =
                self.codes_at + LEAF_VOXELS * leaf as usize + (p.x + 4 * p.y + 16 * p.z) as usize;
            let word = self.cut[at];
            let (lo, hi) = corner_cube(v, word, octant(step));
            return Region {
                material: word as u8,
                lo: lo.max(IVec3::ZERO),
                hi: hi.min(self.tree.dims().as_ivec3()),
            };
        }
        let word = self.cut[i];
        let (lo, hi) = corner_cube(c, word, octant(step));
        let shift = self.log_cell as i32;
        Region {
            material: word as u8,
            lo: (lo << shift).max(IVec3::ZERO),
            hi: (hi << shift).min(self.tree.dims().as_ivec3()),
        }
    }

    fn device_words(&self) -> Vec<&[u32]> {
        vec![self.tree.words(), &self.cut]
    }
}
