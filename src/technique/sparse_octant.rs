//! The sparse octant traversal: the sparse 64-tree ([`super::sparse`]) cut at cubes of
//! [`log_cell_side`] voxels, with the octant field ([`super::octant`]) over the cut. A cube
//! the tree holds as one material is a cell of the field: a ray in that material reads
//! its octant's cube of such cells and skips it whole, however many tree nodes it
//! crosses; a cube that holds a node is walked through the tree below it, from that
//! node. The tree walk's cost grows with the grid's side (a ray leaving a surface
//! climbs level by level out of ever larger cubes, and descends again into its hit); this
//! walk climbs at most the levels of one cell.
//!
//! Layout of its words (`walk_data`, shaders/traversal_sparse_octant.wgsl): the tree's
//! words ([`crate::sparse`]: a header vec4 and five vec4s a node), then, at vec4 `h = 1 +
//! 5 * node count`, one vec4 (log2 of the cell side, the cut's dims) and from `h + 1`
//! two words a cell (x fastest): the octant field's word (material and eight codes,
//! [`super::octant::OctantField`]) and 0 for a uniform cell, or 0 and the node's index
//! plus one for a cell the tree holds as a node. The tree is not copied: its words and
//! the cut's are uploaded as two parts of one buffer.

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;

use super::TraversalModel;
use super::octant::{corner_cube, octant, octant_radii, word};
use crate::sparse::{Cut, GPU_LOG_BRANCH, Region, Regions, SparseTree};

/// The most cells the cut has: 2 M, 16 MiB.
pub const MAX_CELLS: u64 = 1 << 21;

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

/// The tree and the octant field over its cut (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct SparseOctant {
    tree: Arc<SparseTree>,
    log_cell: u32,
    /// The shift of the children of a cell's node (`SparseTree::cut_node_log`).
    node_shift: u32,
    cut_dims: UVec3,
    /// The cut's header vec4, then its cells.
    cut: Vec<u32>,
}

/// Words before the cut's first cell.
const CUT_HEADER_WORDS: usize = 4;

impl SparseOctant {
    pub fn build(tree: Arc<SparseTree>) -> Self {
        let log_cell = log_cell_side(tree.dims(), tree.log_branch(), tree.levels());
        Self::with_cell_side(tree, log_cell)
    }

    /// With cells of `2^log_cell` voxels (1 up to the root's cube) whatever the grid: the
    /// tests walk every side the cut can have.
    pub fn with_cell_side(tree: Arc<SparseTree>, log_cell: u32) -> Self {
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
        Self {
            node_shift: tree.cut_node_log(log_cell) - tree.log_branch(),
            tree,
            log_cell,
            cut_dims,
            cut: words,
        }
    }
}

impl Regions for SparseOctant {
    fn region(&self, v: IVec3, step: IVec3) -> Region {
        let c = v >> self.log_cell as i32;
        let d = self.cut_dims;
        let i = CUT_HEADER_WORDS
            + 2 * (c.x as usize + d.x as usize * (c.y as usize + d.y as usize * c.z as usize));
        let node = self.cut[i + 1];
        if node != 0 {
            return self.tree.region_below(v, node - 1, self.node_shift);
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
