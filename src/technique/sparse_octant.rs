//! The sparse octant traversal: the sparse 64-tree ([`super::sparse`]) cut at cubes of
//! [`log_cell_side`] voxels, with the box field ([`super::boxes`]) over the cut. A cube
//! the tree holds as one material is a cell of the field: a ray in that material reads
//! its octant's box of such cells (the cell its corner, a reach per axis) and skips it
//! whole, however many tree nodes it crosses; a cube that holds a node is walked
//! through the tree below it, from that node. Boxes rather than the octant field's
//! cubes: a ray grazing a wall crosses cubes no larger than its height above the wall,
//! and a box long along the wall takes it there in a step or two (docs/sparse-traversal.md,
//! "Boxes over the cut"). The tree walk's cost grows with the grid's side (a ray leaving
//! a surface climbs level by level out of ever larger cubes, and descends again into its
//! hit); this walk climbs at most the levels of one cell.
//!
//! Below a node's cell, the tree's nodes carry boxes of their children: each node of
//! the cut's node level and below (the leaves among them, whose children are the voxels
//! next to surfaces) has, for each of its 64 children that is uniform, the box codes of
//! [`super::boxes::BoxField`] over its node's children: the child's box of children of
//! its material toward each octant. A ray that runs along a surface (a shadow ray to a
//! light beside a wall) then skips along it instead of stepping voxel by voxel through
//! the leaves, and one in a uniform child of a node skips that child's box of such
//! children. The boxes start from cubes, the recurrence of
//! [`super::octant::octant_radii`] swept over a level's nodes alone (`Level::radii`),
//! the levels from the top: a neighbour outside them lies in a uniform region the cut,
//! the tree or a level above holds, whose extent bounds its radius from below, so every
//! cube is uniform (a lower bound of the dense field's) and the walk leaves it where the
//! dense DDA does. The box field's extensions then stretch them along the runs of the
//! level's nodes next to each other (`Level::extend`) and on into the uniform region
//! past a run's end while the box fits in it, at most [`REACH_LIMIT`] children where a
//! box reaches past its cube. They cost four words a child (four planes, as the
//! box field's), a KiB a block of a node's children, each distinct block held once and
//! a node's block index a word (`SparseOctant::with_codes`: along a wall many nodes
//! share their block), and are kept only while they fit the walk's
//! budget (a binding's bytes, [`MAX_WALK_BYTES`] by default): after the cut where the
//! whole fits one binding, else the tree and the cut within one and the codes within
//! [`super::WALK_MORE_BINDINGS`] more ([`CodesAt`]).
//!
//! Layout of its words (`walk_data`, shaders/traversal_sparse_octant.wgsl): the tree's
//! words ([`crate::sparse`]: a header vec4 and five vec4s a node), or where the kernel
//! reads none of the tree (with codes and descents of at most two levels,
//! `SparseOctant::reads_tree`) a header of no nodes in its place; then, at vec4
//! `h = 1 + 5 * node count`, two vec4s (log2 of the cell side, the cut's dims; the
//! index of the first node with codes, the number of such nodes, the vec4 of its codes
//! counted from `h` where they follow the cut, the word of the first block in its
//! codes) and from
//! `h + 2` the cells (x fastest), a vec4 a cell. A uniform cell holds its eight boxes'
//! twelve-bit codes ([`super::boxes::REACHES`]), word `p` octants `2p` and `2p + 1`
//! (the second from bit 12), its material in the first word's top byte and
//! `UNIFORM_CELL` in the fourth's top bit; a cell the tree holds as a node holds the
//! node's block index (0 without codes), the node's index plus one and two 0s, or,
//! where the cells' nodes are nodes of 16 and have codes (`KERNEL_WITH_HEADS`), its
//! node's head (mask words and first child, as the tree holds them) and one more than
//! its block index. Then the codes: each node's block index in node order (to
//! a vec4 boundary), then the distinct blocks, 256 words each (four planes of a node's
//! children, x fastest, plane `p` each child's material and its boxes toward octants
//! `2p` and `2p + 1` from bits 8 and 20; 0 for a child that is a node): from a vec4
//! boundary after the cut, or as the walk's further words (`walk_more_word`, [`Regions::device_more_words`]). The tree
//! is not copied: its words, the cut's and the codes are uploaded as parts of one
//! buffer.

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;
use rustc_hash::FxHashMap;

use super::TraversalModel;
use super::boxes::{octant_boxes, plane_bits, reaches, stretch, sweep_lanes, word_reach};
use super::octant::{corner_box, octant, octant_signs};
use crate::sparse::{Cut, GPU_LOG_BRANCH, Region, Regions, SparseTree};

/// The most cells the cut has: 2 M, 32 MiB.
pub const MAX_CELLS: u64 = 1 << 21;

/// The most bytes a binding of the walk's data takes in [`SparseOctant::build`]: the
/// 128 MiB a storage buffer binding holds on lavapipe (and wgpu's default limit), the
/// CPU reference's budget. The GPU tracer builds within its device's binding instead
/// ([`SparseOctant::build_within`]). A tree whose codes do not fit is walked without
/// them.
pub const MAX_WALK_BYTES: usize = super::HOST_WALK_BYTES;

/// The flag of a uniform cell in its fourth word: a node's cell has a node's index or a
/// block index there, both far below it.
const UNIFORM_CELL: u32 = 1 << 31;

/// Children of a node of the 64-tree.
const CHILDREN: usize = 64;

/// Planes of a node's block of codes: plane `p` holds, for each child, its material
/// and the box codes of octants `2p` and `2p + 1` (the box field's word,
/// [`super::boxes::BoxField`]), so a step reads one word of its octant's plane.
const PLANES: usize = 4;

/// Words of a node's block of codes.
const BLOCK_WORDS: usize = PLANES * CHILDREN;

/// How far, in children, a child's box below the cut reaches along an axis where it
/// reaches past its cube. A box reaching to a run's end differs with the distance to
/// that end, and a wall's leaves would each have a block of their own: on the seed
/// scene at 1024^3 83,020 distinct blocks (82.4 MiB) with no limit, 23,794 (24.5 MiB)
/// with this one, and 3.08 and 3.25 steps a ray (128x128, CPU; 7.30 with cubes below
/// the cut). A limit of 16 past the cube instead: 52,299 blocks. With the stretch on
/// past a run's end (`Level::reach_past_run`) 87,328 and 22,435 blocks, 3.06 and
/// 3.25 steps.
pub const REACH_LIMIT: u8 = 16;

/// The kernel of a walk with codes (`WALK_VARIANT == 1` in
/// shaders/traversal_sparse_octant.wgsl; 0 without them): every node a cell's descent
/// can end at has its children's codes, so the step reads the child's word and never
/// the tree's materials, and without codes the reverse. Each kernel leaves out the
/// other's reads, which lavapipe would run for every lane (on the seed scene 12 % of
/// the frame at 256^3, 7 % at 1024^3: docs/sparse-traversal.md, "One kernel for codes,
/// one without").
const KERNEL_WITH_CODES: u32 = 1;

/// The kernel of a walk with codes whose cells' nodes are nodes of 16 (descents of two
/// levels: 1024^3 and 2048^3), each node's cell holding the node's head (`WALK_VARIANT
/// == 2`): a step reads the cell's vec4 where the other kernel reads the cell and then
/// the node's head from the tree, and the tree is not uploaded. The seed scene's walk
/// data at 1024^3 takes 7.7 MiB instead of 31.6 and its frame 0.87x the time, at
/// 2048^3 39.5 MiB instead of 127.9 and 0.87x (docs/sparse-traversal.md, "The cells'
/// heads").
const KERNEL_WITH_HEADS: u32 = 2;

/// What stands for the tree where the kernel reads none of it ([`SparseOctant::reads_tree`]):
/// a tree header of no nodes, so the cut starts at vec4 1 (`region_cursor`).
const NO_TREE: [u32; 4] = [0; 4];

/// Log2 of the side of the cut's cells for a tree of these dims and branching: the
/// smallest side (4, 8, 16 ... voxels) whose cells number at most [`MAX_CELLS`]: the
/// smaller the cells, the nearer to a surface the boxes reach, and the fewer
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
              that number at most 2 M, with the box field over the cut and over the \
              children of each node below it (down to the voxels of the leaves): a \
              uniform cell's or child's box of its like toward the ray's octant, a reach \
              per axis, is skipped whole",
    label: "sparse 64-tree + boxes",
    plan: |_, _| Ok(()),
    // Where the plain tree walk claimed grids: on lavapipe (`voxlab bench --sizes
    // 256,512,1024,2048 --size 256 --no-cpu --gpu-runs 5 --rules seed --traversal
    // octant,sparse,sparse_octant`) 3.7x its speed at 256^3 and 512^3, 3.4x at 1024^3
    // and 1.6x at 2048^3 without the codes below the cut, which now take bindings of
    // their own there and make its frame 2.4x as fast again (docs/sparse-traversal.md,
    // "Codes below the cut", "Codes past one binding"). It claims from side 256
    // (`SPARSE_FROM_SIDE`), where it is faster than the dense octant field; below, that
    // field is faster and keeps its claim ("Where auto walks the tree").
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
    data: Some(|grid, budget| {
        Arc::new(SparseOctant::build_within(
            grid.tree(GPU_LOG_BRANCH),
            budget,
        ))
    }),
    device_bytes: None,
};

/// The tree and the box field over its cut and below it (see the module
/// documentation).
#[derive(Clone, Debug)]
pub struct SparseOctant {
    tree: Arc<SparseTree>,
    log_cell: u32,
    /// The shift of the children of a cell's node (`SparseTree::cut_node_log`).
    node_shift: u32,
    cut_dims: UVec3,
    /// The first node whose children have words, and how many do (0: none).
    coded_first: u32,
    coded_count: u32,
    /// The smallest children's shift whose words are in (during the build, the levels
    /// done so far; then 0).
    coded_shift: u32,
    /// The cut's two header vec4s and its cells (and, with the codes after it, up to
    /// two words to a vec4 boundary).
    cut: Vec<u32>,
    /// The codes as the kernel reads them: for each node with codes its block's index
    /// (`blocks_words` words, the nodes' count to a vec4 boundary), then the distinct
    /// blocks of its children's words, 256 words each ([`Self::with_codes`]).
    codes: Vec<u32>,
    blocks_words: usize,
    codes_at: CodesAt,
    /// The cut as [`KERNEL_WITH_HEADS`] reads it, its header and a vec4 a cell (a
    /// uniform cell's word and three 0s; a node's cell its node's head and one more than
    /// its block index); empty for the other kernels, which read `cut`.
    heads: Vec<u32>,
    /// The bytes a binding the data was built within, and the nodes below the cut whose
    /// codes did not fit them (0 where they did, or where there are none) with the bytes
    /// those would have taken (0 where the tree and the cut left no room to build them):
    /// said in the plan ([`Regions::summary`]), as the walk then takes more steps.
    budget: usize,
    uncoded: usize,
    uncoded_bytes: usize,
}

/// The same data, walked the same way: the budget it was built within and what it
/// says of codes it left out are not compared (a larger budget that builds the same
/// data is equal).
impl PartialEq for SparseOctant {
    fn eq(&self, other: &Self) -> bool {
        self.tree == other.tree
            && self.log_cell == other.log_cell
            && self.node_shift == other.node_shift
            && self.cut_dims == other.cut_dims
            && self.coded_first == other.coded_first
            && self.coded_count == other.coded_count
            && self.coded_shift == other.coded_shift
            && self.cut == other.cut
            && self.codes == other.codes
            && self.blocks_words == other.blocks_words
            && self.codes_at == other.codes_at
    }
}

/// Words before the cut's first cell.
const CUT_HEADER_WORDS: usize = 8;

/// Where the codes are held.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CodesAt {
    /// After the cut in `walk_data`, where the whole data fits one binding: the kernel
    /// reads a code from the binding that holds the tree.
    WalkData,
    /// In the walk's further bindings (`walk_more_word`), where the tree and the cut fit
    /// one binding and the codes [`super::WALK_MORE_BINDINGS`] more: a kernel that reads
    /// a code from another binding than the tree's is slower where both would fit one
    /// (lavapipe, the seed scene: 4 % at 256^3, 10 % at 1024^3; docs/sparse-traversal.md,
    /// "Codes past one binding").
    MoreBindings,
}

/// Where `codes` words of codes go beside the `first` words of the walk's data before
/// them ([`SparseOctant::words_before_codes`]) within `budget` bytes a binding, if
/// anywhere.
fn place_codes(first: usize, codes: usize, budget: usize) -> Option<CodesAt> {
    if 4 * (first.next_multiple_of(4) + codes) <= budget {
        Some(CodesAt::WalkData)
    } else if 4 * first <= budget
        && codes <= super::WALK_MORE_BINDINGS * super::walk_part_words(budget)
    {
        Some(CodesAt::MoreBindings)
    } else {
        None
    }
}

impl SparseOctant {
    /// Cells of [`log_cell_side`], with the codes below the cut where the walk's data
    /// fits [`MAX_WALK_BYTES`] a binding. Where that side lies between the tree's levels
    /// (8 for the 64-tree) and the codes fit with the next side's cells, the walk takes
    /// those: its cells are walked from the same nodes (a cell's node, the codes and the
    /// kernel's descent are the same), and below a node's cell the codes skip in
    /// children of 4 what the finer cut skipped in cells of 8, so the finer cut only
    /// adds bytes and steps (the seed scene at 1024^3, seed rules, 64x64 on the CPU:
    /// 9.77 steps a ray with cubes of 16 against 10.32 with cubes of 8, both with the
    /// codes; docs/sparse-traversal.md, "The walk's budget").
    pub fn build(tree: Arc<SparseTree>) -> Self {
        Self::build_within(tree, MAX_WALK_BYTES)
    }

    /// [`Self::build`] within `budget` bytes a binding instead of [`MAX_WALK_BYTES`]: a
    /// device that binds more holds the codes of larger trees.
    pub fn build_within(tree: Arc<SparseTree>, budget: usize) -> Self {
        let b = tree.log_branch();
        let log_cell = log_cell_side(tree.dims(), b, tree.levels());
        let node_log = tree.cut_node_log(log_cell);
        if log_cell < node_log {
            let coarse = Self::with_cell_side_within(tree.clone(), node_log, budget);
            if coarse.has_codes() {
                return coarse;
            }
            if coarse.uncoded_bytes > 0 {
                // Built and placed nowhere: the finer cut has the same nodes below it, so
                // the same codes, beside more cells; not built a second time.
                return Self {
                    budget,
                    uncoded: coarse.uncoded,
                    uncoded_bytes: coarse.uncoded_bytes,
                    ..Self::without_codes(tree, log_cell)
                };
            }
        }
        Self::with_cell_side_within(tree, log_cell, budget)
    }

    /// With cells of `2^log_cell` voxels (1 up to the root's cube) whatever the grid: the
    /// tests walk every side the cut can have. The nodes below the cut have their
    /// children's codes within [`MAX_WALK_BYTES`].
    pub fn with_cell_side(tree: Arc<SparseTree>, log_cell: u32) -> Self {
        Self::with_cell_side_within(tree, log_cell, MAX_WALK_BYTES)
    }

    fn with_cell_side_within(tree: Arc<SparseTree>, log_cell: u32, budget: usize) -> Self {
        let cut = Self::without_codes(tree, log_cell);
        let (first_node, nodes) = cut.tree.nodes_up_to(cut.node_shift + cut.tree.log_branch());
        // The codes' layout is the 64-tree's (64 children a node, shaders/tree.wgsl).
        if nodes.is_empty() || cut.tree.log_branch() != GPU_LOG_BRANCH {
            return Self { budget, ..cut };
        }
        // Where what goes before the codes leaves no room in its binding, the codes fit
        // nowhere (place_codes), however few their distinct blocks: not built.
        let before = cut.words_before_codes();
        if 4 * before > budget {
            return Self {
                budget,
                uncoded: nodes.len(),
                ..cut
            };
        }
        let coded = cut.clone().with_codes(first_node, &nodes);
        match place_codes(before, coded.codes.len(), budget) {
            Some(at) => Self {
                budget,
                ..coded.placed(at)
            },
            None => Self {
                budget,
                uncoded: nodes.len(),
                uncoded_bytes: 4 * coded.codes.len(),
                ..cut
            },
        }
    }

    /// Only the cut: a node's cell is walked through the tree down to its uniform child.
    pub fn without_codes(tree: Arc<SparseTree>, log_cell: u32) -> Self {
        let (cut_dims, cut) = tree.cut(log_cell);
        // A node's cell matches no other: uniform cells' cubes stop at it.
        let cells: Vec<Option<u8>> = cut
            .iter()
            .map(|c| match c {
                Cut::Uniform(m) => Some(*m),
                Cut::Node(_) => None,
            })
            .collect();
        let boxes: Vec<Vec<u16>> = (0..8)
            .into_par_iter()
            .map(|o| octant_boxes(&cells, cut_dims, o))
            .collect();
        debug_assert_eq!(tree.words().len() % 4, 0, "the tree ends on a vec4");
        let mut words = Vec::with_capacity(CUT_HEADER_WORDS + 4 * cut.len());
        words.extend_from_slice(&[log_cell, cut_dims.x, cut_dims.y, cut_dims.z]);
        // The second header vec4 is the codes', filled in by with_codes.
        words.extend_from_slice(&[0; 4]);
        for (i, c) in cut.iter().enumerate() {
            match c {
                Cut::Uniform(m) => {
                    let plane = |p: usize| {
                        u32::from(boxes[2 * p][i]) | u32::from(boxes[2 * p + 1][i]) << 12
                    };
                    words.extend_from_slice(&[
                        plane(0) | u32::from(*m) << 24,
                        plane(1),
                        plane(2),
                        plane(3) | UNIFORM_CELL,
                    ]);
                }
                Cut::Node(n) => words.extend_from_slice(&[0, n + 1, 0, 0]),
            }
        }
        Self {
            node_shift: tree.cut_node_log(log_cell) - tree.log_branch(),
            tree,
            log_cell,
            cut_dims,
            coded_first: 0,
            coded_count: 0,
            coded_shift: 0,
            cut: words,
            codes: Vec::new(),
            blocks_words: 0,
            codes_at: CodesAt::WalkData,
            heads: Vec::new(),
            budget: MAX_WALK_BYTES,
            uncoded: 0,
            uncoded_bytes: 0,
        }
    }

    /// The cut with the codes of the children of `nodes` (the nodes from the cut's
    /// level down, [`SparseTree::nodes_up_to`]: the first's index, then each one's first
    /// voxel and log2 side), built a level at a time from the top, so that a level's
    /// sweep finds the regions of the levels above it, and held as the kernel reads them
    /// from the first level on: each node's block index, then each distinct block once,
    /// in the order they first occur (the breadth-first node order). Along a wall most
    /// leaves see the same neighbourhood and have the same words: on the seed scene
    /// 9,698 distinct blocks of 338,896 at 1024^3 and 9,302 of 1,363,216 at 2048^3
    /// (82.7 MiB of codes become 2.4 MiB of blocks and 1.3 MiB of indices, 332.8 MiB 2.3
    /// and 5.2 MiB), so a frame reads from far fewer bytes: 1024^3 1.16x as fast on
    /// lavapipe, 2048^3 1.31x (docs/sparse-traversal.md, "Distinct blocks"). With boxes
    /// (a KiB a block, their reaches differing along a wall) 22,435 blocks at 1024^3 and
    /// 24,507 at 2048^3 ([`REACH_LIMIT`]). Only a level's words are held whole while it
    /// is built. Not yet placed ([`Self::placed`]).
    fn with_codes(mut self, first: u32, nodes: &[(IVec3, u32)]) -> Self {
        self.blocks_words = nodes.len().next_multiple_of(4);
        self.codes = vec![0; self.blocks_words];
        self.coded_first = first;
        self.coded_count = nodes.len() as u32;
        let b = self.tree.log_branch();
        let mut sides: Vec<u32> = nodes.iter().map(|&(_, l)| l).collect();
        sides.sort_unstable();
        sides.dedup();
        self.coded_shift = u32::MAX;
        let mut distinct: FxHashMap<Box<[u32]>, u32> = FxHashMap::default();
        for &log_side in sides.iter().rev() {
            let (members, words) = level_words(&self, first, nodes, log_side);
            for (k, block) in members.into_iter().zip(words.chunks_exact(BLOCK_WORDS)) {
                self.codes[k] = match distinct.get(block) {
                    Some(&i) => i,
                    None => {
                        let i = distinct.len() as u32;
                        distinct.insert(block.into(), i);
                        self.codes.extend_from_slice(block);
                        i
                    }
                };
            }
            self.coded_shift = log_side - b;
        }
        self.coded_shift = 0;
        // A node's cell holds the node's block index in its first word (0 without
        // codes): where a descent takes one level it ends at that node, and the kernel
        // reads no index (traversal_sparse_octant.wgsl; the bunny at 512, whose curved
        // surface leaves nearly every block distinct, 4 % slower with the read).
        for cell in self.cut[CUT_HEADER_WORDS..].chunks_exact_mut(4) {
            if cell[3] & UNIFORM_CELL == 0 {
                cell[0] = self.codes[(cell[1] - 1 - first) as usize];
            }
        }
        self
    }

    /// The codes held `at` (where [`place_codes`] puts them), in the cut's header.
    fn placed(mut self, at: CodesAt) -> Self {
        self.codes_at = at;
        let after_cut = match at {
            CodesAt::WalkData => {
                self.cut.resize(self.cut.len().next_multiple_of(4), 0);
                (self.cut.len() / 4) as u32
            }
            CodesAt::MoreBindings => 0,
        };
        self.cut[4..8].copy_from_slice(&[
            self.coded_first,
            self.coded_count,
            after_cut,
            self.blocks_words as u32,
        ]);
        if self.cells_hold_heads() {
            let cells = self.cut_dims.as_u64vec3().element_product() as usize;
            let mut heads = Vec::with_capacity(CUT_HEADER_WORDS + 4 * cells);
            heads.extend_from_slice(&self.cut[..CUT_HEADER_WORDS]);
            for cell in self.cut[CUT_HEADER_WORDS..][..4 * cells].chunks_exact(4) {
                if cell[3] & UNIFORM_CELL != 0 {
                    heads.extend_from_slice(cell);
                } else {
                    heads.extend_from_slice(self.tree.node_head(cell[1] - 1));
                    heads.push(cell[0] + 1);
                }
            }
            if at == CodesAt::WalkData {
                heads[6] = (heads.len() / 4) as u32;
            }
            self.heads = heads;
        }
        self
    }

    /// Whether, with codes, a step would read none of the tree: where a descent takes at
    /// most two levels, since a leaf's children are voxels and the descent's one read of
    /// a node of 16 is the head its cell holds ([`Self::heads_with_codes`]);
    /// shaders/tree.wgsl reads materials only without codes.
    fn tree_free_with_codes(&self) -> bool {
        self.node_shift <= self.tree.log_branch()
    }

    /// Whether, with codes, the cells would hold their nodes' heads
    /// ([`KERNEL_WITH_HEADS`]): where the cells' nodes are nodes of 16.
    fn heads_with_codes(&self) -> bool {
        self.node_shift == self.tree.log_branch()
    }

    /// Whether the kernel reads the tree: not with codes where a descent takes at most
    /// two levels. Then the tree stays on the host: [`NO_TREE`] stands for it.
    fn reads_tree(&self) -> bool {
        !(self.has_codes() && self.tree_free_with_codes())
    }

    /// Whether the cells hold their nodes' heads.
    fn cells_hold_heads(&self) -> bool {
        self.has_codes() && self.heads_with_codes()
    }

    /// The words of the walk's data before its codes, were the codes in: the tree (or
    /// [`NO_TREE`]) and the cut, at two words a cell or four with the heads. Where the
    /// codes go depends on it ([`place_codes`]).
    fn words_before_codes(&self) -> usize {
        let cells = self.cut_dims.as_u64vec3().element_product() as usize;
        let tree = if self.tree_free_with_codes() {
            NO_TREE.len()
        } else {
            self.tree.words().len()
        };
        tree + CUT_HEADER_WORDS + 4 * cells
    }

    /// The tree as uploaded: the tree, or [`NO_TREE`] where the kernel reads none of it.
    fn device_tree(&self) -> &[u32] {
        if self.reads_tree() {
            self.tree.words()
        } else {
            &NO_TREE
        }
    }

    /// The cut as uploaded: with its nodes' heads where the cells hold them.
    fn device_cut(&self) -> &[u32] {
        if self.heads.is_empty() {
            &self.cut
        } else {
            &self.heads
        }
    }

    /// Whether the nodes below the cut carry their children's codes.
    pub fn has_codes(&self) -> bool {
        self.coded_count > 0
    }

    /// Where the codes are held (with none, [`CodesAt::WalkData`]).
    pub fn codes_at(&self) -> CodesAt {
        self.codes_at
    }

    /// The codes as the kernel reads them: each coded node's block index, then the
    /// distinct blocks, 256 words each.
    pub fn codes(&self) -> &[u32] {
        &self.codes
    }

    /// The cells' log2 side.
    pub fn log_cell(&self) -> u32 {
        self.log_cell
    }
}

/// The children's box words of the nodes of side `2^log_side` among `nodes`: each such
/// node's ordinal among them, and [`BLOCK_WORDS`] a node in that order (four planes; a
/// child that is a node matches nothing and has the word 0), each child's cube by the
/// recurrence of [`super::octant::octant_radii`] over those children, for each octant
/// swept from its far corner ([`Level::radii`]), stretched to its box
/// ([`Level::boxes`]). The octants run as many at a time as rayon has threads, each
/// holding a few bytes a child, and fold their codes into the words as they end: not
/// all eight octants' at once (2048^3's leaves: 87 M children).
fn level_words(
    walk: &SparseOctant,
    first: u32,
    nodes: &[(IVec3, u32)],
    log_side: u32,
) -> (Vec<usize>, Vec<u32>) {
    let level = Level::new(walk, first, nodes, log_side);
    let mut words: Vec<u32> = level
        .children
        .par_chunks(CHILDREN)
        .flat_map_iter(|c| {
            let plane: Vec<u32> = c.iter().map(|m| m.map_or(0, u32::from)).collect();
            plane.repeat(PLANES)
        })
        .collect();
    let octants: Vec<usize> = (0..8).collect();
    for batch in octants.chunks(rayon::current_num_threads().clamp(1, 8)) {
        let boxes: Vec<(usize, Vec<u16>)> = batch
            .par_iter()
            .map(|&o| (o, level.boxes(walk, o, &level.radii(walk, o))))
            .collect();
        words
            .par_chunks_mut(BLOCK_WORDS)
            .zip(level.children.par_chunks(CHILDREN))
            .enumerate()
            .for_each(|(j, (block, children))| {
                for (i, child) in children.iter().enumerate() {
                    if child.is_some() {
                        for (o, b) in &boxes {
                            block[CHILDREN * (o >> 1) + i] |= plane_bits(b[j * CHILDREN + i], *o);
                        }
                    }
                }
            });
    }
    (level.members.iter().map(|&(k, _)| k).collect(), words)
}

/// The lines of a level's children along one axis: the level's nodes in runs of
/// neighbours along it (`order`, ordered across the axis and then along it; `runs` its
/// ranges), each swept as 16 lines of children side by side, their children laid
/// `[position][line]` (`children`: the child index of each of a node's 4 positions
/// along the axis times 16 lines).
struct Lines {
    order: Vec<u32>,
    runs: Vec<std::ops::Range<usize>>,
    /// Positions of the longest run's lines, one more for where they end.
    longest: usize,
    children: Vec<usize>,
}

impl Lines {
    fn new(level: &Level, axis: usize) -> Self {
        let b = level.log_branch;
        let branch = 1usize << b;
        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
        let node = |j: u32| level.members[j as usize].1 >> b;
        let mut order: Vec<u32> = (0..level.members.len() as u32).collect();
        order.par_sort_unstable_by_key(|&j| {
            let n = node(j);
            (n[u], n[w], n[axis])
        });
        let mut runs: Vec<std::ops::Range<usize>> = Vec::new();
        for (i, &j) in order.iter().enumerate() {
            let joins = i > 0 && {
                let (a, n) = (node(order[i - 1]), node(j));
                a[u] == n[u] && a[w] == n[w] && a[axis] + 1 == n[axis]
            };
            match runs.last_mut() {
                Some(run) if joins => run.end = i + 1,
                _ => runs.push(i..i + 1),
            }
        }
        let longest = runs.iter().map(|r| r.len()).max().unwrap_or(0) * branch + 1;
        let children = (0..branch * branch * branch)
            .map(|x| {
                let mut c = IVec3::ZERO;
                c[axis] = (x / (branch * branch)) as i32;
                c[u] = (x % branch) as i32;
                c[w] = (x / branch % branch) as i32;
                level.child(c)
            })
            .collect();
        Self {
            order,
            runs,
            longest,
            children,
        }
    }
}

/// What [`Level::extend`] gathers a run's lines into, kept by a thread between runs:
/// the children, keys and cubes laid `[position][line]`, the reaches swept, and the
/// sweep's stacks, each for the longest run.
struct RunScratch {
    stacks: super::boxes::Stacks,
    cells: Vec<Option<u8>>,
    key_cells: Vec<u8>,
    cube_cells: Vec<u8>,
    out: Vec<u8>,
}

impl RunScratch {
    fn new(keys: usize, lanes: usize, longest: usize) -> Self {
        Self {
            stacks: super::boxes::Stacks::new(keys, lanes, longest),
            cells: vec![None; lanes * longest],
            key_cells: vec![0; keys * lanes * longest],
            cube_cells: vec![0; lanes * longest],
            out: vec![0; lanes * longest],
        }
    }
}

/// A run's lines as [`Level::extend`] swept them: the children, the keys and the cubes
/// laid `[position][line]`, `n` positions of `lanes` lines.
struct Swept<'a> {
    cells: &'a [Option<u8>],
    keys: &'a [&'a [u8]],
    cube: &'a [u8],
    lanes: usize,
    n: usize,
}

/// The nodes of one level below the cut, as the sweep of their children reads them.
struct Level {
    /// Each node's ordinal among the coded nodes and its first child, in units.
    members: Vec<(usize, IVec3)>,
    /// Each node's children (x fastest), 64 a node in `members`' order: a uniform
    /// child's material, `None` for a node. One array, as the radii and boxes are: a
    /// sweep reads the children of a node's neighbours.
    children: Vec<Option<u8>>,
    /// A node's place in `members` by its position in nodes of its side.
    index: FxHashMap<IVec3, u32>,
    log_branch: i32,
    /// Log2 of a child's side (the unit the level's cubes count in).
    log_unit: i32,
    /// The grid in voxels and in units (a unit past it does not count).
    dims: IVec3,
    unit_dims: IVec3,
    /// The lines along x, y and z ([`Self::extend`]).
    lines: Vec<Lines>,
}

impl Level {
    fn new(walk: &SparseOctant, first: u32, nodes: &[(IVec3, u32)], log_side: u32) -> Self {
        let tree = &walk.tree;
        let log_branch = tree.log_branch() as i32;
        let log_unit = log_side as i32 - log_branch;
        let dims = tree.dims().as_ivec3();
        let members: Vec<(usize, IVec3)> = (0..nodes.len())
            .filter(|&k| nodes[k].1 == log_side)
            .map(|k| (k, nodes[k].0 >> log_unit))
            .collect();
        let children = members
            .par_iter()
            .flat_map_iter(|&(k, _)| tree.node_children(first + k as u32))
            .collect();
        let index = members
            .iter()
            .enumerate()
            .map(|(j, &(_, lo))| (lo >> log_branch, j as u32))
            .collect();
        let mut level = Self {
            members,
            children,
            index,
            log_branch,
            log_unit,
            dims,
            unit_dims: (dims + ((1 << log_unit) - 1)) >> log_unit,
            lines: Vec::new(),
        };
        level.lines = (0..3).map(|a| Lines::new(&level, a)).collect();
        level
    }

    fn child(&self, p: IVec3) -> usize {
        let b = self.log_branch;
        (p.x | (p.y << b) | (p.z << (2 * b))) as usize
    }

    /// Every child's radius toward octant `o` (the level's nodes' children, 64 a node in
    /// `members`' order), swept from the octant's far corner: nodes in an order that
    /// takes each after its neighbours toward the octant, then their children so, each
    /// after its seven neighbours toward the octant. A neighbour in another node of the
    /// level has its radius already; one outside them lies in the uniform region `walk`
    /// finds for it (the cut's cube toward the octant, the tree's child, or a level
    /// above's cube), whose extent toward the octant bounds its radius from below; one
    /// outside the grid does not count (as in the dense field: the walk ends there by
    /// its own test). A node's children are swept in a cube of 5 a side ([`Pad`]): its
    /// 64 and the layer of its neighbours toward the octant, gathered first, so the
    /// sweep of a child reads seven fixed offsets.
    fn radii(&self, walk: &SparseOctant, o: usize) -> Vec<u8> {
        let branch = 1i32 << self.log_branch;
        debug_assert_eq!(branch, PAD - 1, "the pad holds a node of 4 a side");
        let s = octant_signs(o);
        let offset =
            |e: usize| s * IVec3::new((e & 1) as i32, (e >> 1 & 1) as i32, (e >> 2) as i32);
        // Any order that takes a node after its neighbours toward the octant will do:
        // the Morton order of the nodes' positions counted from the octant's far
        // corner. The members are in the tree's breadth-first order, a Morton order
        // too, so the sweep reads the children and radii of nodes near in memory.
        let nodes = (self.unit_dims + (branch - 1)) >> self.log_branch;
        let mut order: Vec<u32> = (0..self.members.len() as u32).collect();
        order.sort_unstable_by_key(|&j| {
            let p = self.members[j as usize].1 >> self.log_branch;
            let k = IVec3::select(s.cmplt(IVec3::ZERO), p, nodes - 1 - p);
            morton(k.as_uvec3())
        });
        // The pad's cells in flipped coordinates `f` (the octant's way is +f on every
        // axis; 4 is the neighbours' layer): each one's unit from the node's first, the
        // neighbour node it lies in (bit a: f[a] = 4) and its child index there.
        let cells: Vec<(IVec3, usize, usize)> = (0..PAD * PAD * PAD)
            .map(|i| {
                let f = IVec3::new(i % PAD, i / PAD % PAD, i / (PAD * PAD));
                let p = IVec3::select(s.cmpgt(IVec3::ZERO), f, (branch - 1) - f);
                let e = (0..3).fold(0, |k, a| k | usize::from(f[a] == branch) << a);
                (p, e, self.child(p.rem_euclid(IVec3::splat(branch))))
            })
            .collect();
        let interior: Vec<usize> = (0..cells.len())
            .rev()
            .filter(|&i| cells[i].1 == 0)
            .collect();
        let mut radii = vec![0u8; CHILDREN * self.members.len()];
        let mut pad = Pad::default();
        for &j in &order {
            let lo = self.members[j as usize].1;
            // The node of the level toward the octant along the axes of `e`, or the
            // uniform region at its first unit (None: past the grid).
            let blocks: [Option<Result<u32, Region>>; 8] = std::array::from_fn(|e| {
                if e == 0 {
                    return Some(Ok(j));
                }
                let n = lo + branch * offset(e);
                if n.cmplt(IVec3::ZERO).any() || n.cmpge(self.unit_dims).any() {
                    return None;
                }
                Some(match self.index.get(&(n >> self.log_branch)) {
                    Some(&m) => Ok(m),
                    None => Err(walk.region(n << self.log_unit, s)),
                })
            });
            for (i, &(p, e, inner)) in cells.iter().enumerate() {
                (pad.material[i], pad.radius[i]) = match &blocks[e] {
                    None => (PAD_OUT, 0),
                    Some(Ok(n)) => {
                        let k = *n as usize * CHILDREN + inner;
                        (self.children[k].map_or(PAD_NODE, u16::from), radii[k])
                    }
                    Some(Err(region)) => {
                        let u = lo + p;
                        if u.cmplt(IVec3::ZERO).any() || u.cmpge(self.unit_dims).any() {
                            (PAD_OUT, 0)
                        } else {
                            self.held(walk, u, region, s)
                        }
                    }
                };
            }
            for &i in &interior {
                let m = pad.material[i];
                if m == PAD_NODE || (lo + cells[i].0).cmpge(self.unit_dims).any() {
                    pad.radius[i] = 0;
                    continue;
                }
                let mut r = u8::MAX;
                for d in PAD_NEIGHBOURS {
                    let (n, rn) = (pad.material[i + d], pad.radius[i + d]);
                    if n != PAD_OUT {
                        r = r.min(if n == m { rn.saturating_add(1) } else { 0 });
                    }
                }
                pad.radius[i] = r;
                radii[j as usize * CHILDREN + cells[i].2] = r;
            }
        }
        radii
    }

    /// Every child's box toward octant `o` as its twelve-bit code, from its cube
    /// (`cube`, [`Self::radii`]): stretched along z, then x, then y as the box field's
    /// are ([`super::boxes`]), along the lines of the level's nodes.
    fn boxes(&self, walk: &SparseOctant, o: usize, cube: &[u8]) -> Vec<u16> {
        stretch(cube, |axis, keys| self.extend(walk, o, axis, keys, cube))
    }

    /// Each child's reach along `axis` toward octant `o` of the union of the boxes of
    /// the given `keys` on its way ([`super::boxes`]' extension), over the lines of the
    /// level's nodes ([`Lines`]), at most [`REACH_LIMIT`] where that is past its cube.
    /// Past a run of nodes lies a region the level does not hold, where the lines end (a
    /// cell that matches nothing), or the grid's face. A stretch that ends at such a
    /// region goes on into it while the box fits there ([`Self::reach_past_run`]).
    fn extend(
        &self,
        walk: &SparseOctant,
        o: usize,
        axis: usize,
        keys: &[&[u8]],
        cube: &[u8],
    ) -> Vec<u8> {
        let lines = &self.lines[axis];
        let branch = 1usize << self.log_branch;
        let lanes = branch * branch;
        let down = o >> axis & 1 == 1;
        let swept: Vec<Vec<u8>> = lines
            .runs
            .par_iter()
            .map_init(
                || RunScratch::new(keys.len(), lanes, lines.longest),
                |scratch, run| {
                    let nodes = &lines.order[run.clone()];
                    let k = nodes.len();
                    let first = self.members[nodes[0] as usize].1[axis];
                    let last = self.members[nodes[k - 1] as usize].1[axis];
                    // The end of the lines toward the octant: a region past the run, or
                    // the grid's face (where a line reaches on, as in the box field).
                    let ends = if down {
                        first > 0
                    } else {
                        last + (branch as i32) < self.unit_dims[axis]
                    };
                    let n = branch * k + usize::from(ends);
                    let skip = usize::from(ends && down) * lanes;
                    let RunScratch {
                        stacks,
                        cells,
                        key_cells,
                        cube_cells,
                        out,
                    } = scratch;
                    let cells = &mut cells[..n * lanes];
                    let cube_cells = &mut cube_cells[..n * lanes];
                    // The sentinel that ends the lines, where they do (before or after
                    // the run's cells).
                    if ends {
                        let at = if down { 0 } else { (n - 1) * lanes };
                        cells[at..at + lanes].fill(None);
                        cube_cells[at..at + lanes].fill(0);
                        for e in 0..keys.len() {
                            key_cells[e * n * lanes + at..][..lanes].fill(0);
                        }
                    }
                    for (m, &j) in nodes.iter().enumerate() {
                        let at = skip + m * CHILDREN;
                        let from = j as usize * CHILDREN;
                        let (mine, cube) = (
                            &self.children[from..][..CHILDREN],
                            &cube[from..][..CHILDREN],
                        );
                        for (x, &c) in lines.children.iter().enumerate() {
                            cells[at + x] = mine[c];
                            cube_cells[at + x] = cube[c];
                        }
                        for (e, key) in keys.iter().enumerate() {
                            let key = &key[from..][..CHILDREN];
                            let into = &mut key_cells[e * n * lanes + at..][..CHILDREN];
                            for (x, &c) in lines.children.iter().enumerate() {
                                into[x] = key[c];
                            }
                        }
                    }
                    let key_refs: Vec<&[u8]> = key_cells[..keys.len() * n * lanes]
                        .chunks(n * lanes)
                        .collect();
                    let out = &mut out[..n * lanes];
                    sweep_lanes(cells, &key_refs, cube_cells, (lanes, n), down, stacks, out);
                    if ends {
                        let end = self.members[nodes[if down { 0 } else { k - 1 }] as usize].1;
                        let lines = Swept {
                            cells,
                            keys: &key_refs,
                            cube: cube_cells,
                            lanes,
                            n,
                        };
                        self.reach_past_run(walk, o, axis, end, &lines, out);
                    }
                    let mut reach = vec![0u8; k * CHILDREN];
                    for (m, reach) in reach.chunks_exact_mut(CHILDREN).enumerate() {
                        let at = skip + m * CHILDREN;
                        for (x, &c) in lines.children.iter().enumerate() {
                            let r = out[at + x];
                            reach[c] = r.min(cube_cells[at + x].max(REACH_LIMIT));
                        }
                    }
                    reach
                },
            )
            .collect();
        let mut reach = vec![0u8; CHILDREN * self.members.len()];
        for (run, swept) in lines.runs.iter().zip(&swept) {
            for (&j, block) in lines.order[run.clone()].iter().zip(swept.chunks(CHILDREN)) {
                reach[j as usize * CHILDREN..][..CHILDREN].copy_from_slice(block);
            }
        }
        reach
    }

    /// Where the lines of a run end at a region past it (the level holds no node
    /// there, so the region is uniform), the reaches of the children whose stretch ended
    /// there (`out`, from [`sweep_lanes`]) go on into the region while the box moved
    /// along the axis stays inside it: the region holds the child's material and has
    /// room for the box's reaches across the axis (the keys of the axes stretched
    /// before, the cube on the others), and the box's far side along the axis, its cube
    /// past the translation, stays inside. `end` is the first unit of the run's node at
    /// its end toward the octant.
    fn reach_past_run(
        &self,
        walk: &SparseOctant,
        o: usize,
        axis: usize,
        end: IVec3,
        lines: &Swept,
        out: &mut [u8],
    ) {
        let s = octant_signs(o);
        let branch = 1i32 << self.log_branch;
        let down = s[axis] < 0;
        let sentinel = if down { 0 } else { lines.n - 1 };
        // Whether the stretch of the child at position t, index i, ended at the run's
        // end; where none did, the region is not asked for.
        let ended = |out: &[u8], t: usize, i: usize| {
            t != sentinel
                && lines.cells[i].is_some()
                && out[i] != u8::MAX
                && i32::from(out[i]) == i32::from(lines.cube[i]) + t.abs_diff(sentinel) as i32 - 1
        };
        if !(0..lines.n * lines.lanes).any(|i| ended(out, i / lines.lanes, i)) {
            return;
        }
        // The first unit past the run on each line, and the region there (the one at
        // the first line's holds the others' where the region is at least a node's
        // side, as past a run it is).
        let mut past = end;
        past[axis] += if down { -1 } else { branch };
        let mut region = None;
        // The key across the axis on each other axis: z stretched first, then x, then
        // y ([`stretch`]'s order).
        let across = |b: usize, i: usize| -> u8 {
            match (b, axis) {
                (2, 0) | (2, 1) => lines.keys[1][i],
                (0, 1) => lines.keys[2][i],
                _ => lines.cube[i],
            }
        };
        for lane in 0..lines.lanes {
            let c = self.lines[axis].children[lane];
            let b = self.log_branch;
            let p = IVec3::new(c as i32, (c >> b) as i32, (c >> (2 * b)) as i32) & (branch - 1);
            let mut u = end + p;
            u[axis] = past[axis];
            if u.cmpge(self.unit_dims).any() {
                continue;
            }
            let (lo, hi) = (
                u << self.log_unit,
                ((u + 1) << self.log_unit).min(self.dims),
            );
            let held = |r: &Region| lo.cmpge(r.lo).all() && hi.cmple(r.hi).all();
            let r = match region {
                Some(r) if held(&r) => r,
                _ => {
                    let r = walk.region(lo, s);
                    region = Some(r);
                    r
                }
            };
            let room = rooms(u, &r, s, self.log_unit, self.dims);
            let along = room[axis] + 1;
            for t in 0..lines.n {
                let i = t * lines.lanes + lane;
                if !ended(out, t, i) || lines.cells[i] != Some(r.material) {
                    continue;
                }
                let cube = i32::from(lines.cube[i]);
                let to_end = t.abs_diff(sentinel) as i32 - 1;
                if (0..3).all(|b| b == axis || room[b] >= i32::from(across(b, i))) {
                    out[i] = (cube + to_end + (along - cube).max(0)).min(255) as u8;
                }
            }
        }
    }

    /// The material of unit `u`, a neighbour outside the level's nodes, and how far
    /// its uniform region reaches from it toward the octant of `s` (a cube of material
    /// `m` next to it allows one more where `m` is that material). `region` is the one
    /// at its node's first unit, which holds the whole node where the cut's cells are as
    /// large; else the region is asked at the unit.
    fn held(&self, walk: &SparseOctant, u: IVec3, region: &Region, s: IVec3) -> (u16, u8) {
        let (lo, hi) = (u << self.log_unit, (u + 1) << self.log_unit);
        let region = if lo.cmpge(region.lo).all() && hi.min(self.dims).cmple(region.hi).all() {
            *region
        } else {
            walk.region(lo, s)
        };
        (
            u16::from(region.material),
            reach(u, &region, s, self.log_unit, self.dims),
        )
    }
}

/// The side of [`Level::radii`]'s cube of a node's children and the layer of its
/// neighbours toward the octant.
const PAD: i32 = 5;

/// A pad cell's material where it lies past the grid (it does not count) or is a node
/// (it matches no material).
const PAD_OUT: u16 = u16::MAX;
const PAD_NODE: u16 = 256;

/// The seven neighbours toward the octant of a pad cell (x fastest, flipped so the
/// octant's way is + on every axis).
const PAD_NEIGHBOURS: [usize; 7] = [1, 5, 6, 25, 26, 30, 31];

/// A node's children and its neighbours toward the octant in [`Level::radii`]'s
/// sweep: materials (or [`PAD_OUT`], [`PAD_NODE`]) and radii.
struct Pad {
    material: [u16; 125],
    radius: [u8; 125],
}

impl Default for Pad {
    fn default() -> Self {
        Self {
            material: [PAD_OUT; 125],
            radius: [0; 125],
        }
    }
}

/// The Morton code of `p` (its coordinates' bits interleaved, x lowest; 21 bits each):
/// a point's code is below that of any point at least as large on every axis.
fn morton(p: UVec3) -> u64 {
    let spread = |v: u32| {
        let mut x = u64::from(v) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        (x | x << 2) & 0x1249_2492_4924_9249
    };
    spread(p.x) | spread(p.y) << 1 | spread(p.z) << 2
}

/// How far unit `u`'s cube (units of `2^log_unit` voxels) toward the octant of `s`
/// reaches inside `region`, which holds it: its radius in units, at most 255; a side of
/// the region on the grid's face does not bound it (past the grid nothing counts).
fn reach(u: IVec3, region: &Region, s: IVec3, log_unit: i32, dims: IVec3) -> u8 {
    rooms(u, region, s, log_unit, dims).min_element().max(0) as u8
}

/// How many units past unit `u` toward the octant of `s` `region` (which holds `u`)
/// goes on along each axis, 255 where its side is the grid's face or it goes further.
fn rooms(u: IVec3, region: &Region, s: IVec3, log_unit: i32, dims: IVec3) -> IVec3 {
    let unit = 1i32 << log_unit;
    IVec3::from(std::array::from_fn(|a| {
        let room = if s[a] > 0 {
            (region.hi[a] < dims[a]).then(|| (region.hi[a] >> log_unit) - 1 - u[a])
        } else {
            (region.lo[a] > 0).then(|| u[a] - ((region.lo[a] + unit - 1) >> log_unit))
        };
        room.map_or(i32::from(u8::MAX), |r| r.min(i32::from(u8::MAX)))
    }))
}

impl Regions for SparseOctant {
    fn region(&self, v: IVec3, step: IVec3) -> Region {
        let c = v >> self.log_cell as i32;
        let d = self.cut_dims;
        let i = CUT_HEADER_WORDS
            + 4 * (c.x as usize + d.x as usize * (c.y as usize + d.y as usize * c.z as usize));
        let cell = &self.cut[i..i + 4];
        if cell[3] & UNIFORM_CELL == 0 {
            let node = cell[1];
            let (region, found, shift) = self.tree.descend(v, node - 1, self.node_shift);
            let k = found.wrapping_sub(self.coded_first);
            if k >= self.coded_count || shift < self.coded_shift {
                return region;
            }
            // The uniform child's own cube, in children of its node.
            let b = self.tree.log_branch() as i32;
            let p = (v >> shift as i32) & ((1 << b) - 1);
            let block = self.codes[k as usize] as usize;
            let child = (p.x + (p.y << b) + (p.z << (2 * b))) as usize;
            let o = octant(step);
            let word =
                self.codes[self.blocks_words + BLOCK_WORDS * block + CHILDREN * (o >> 1) + child];
            let (lo, hi) = corner_box(v >> shift as i32, word_reach(word, o), o);
            return Region {
                material: word as u8,
                lo: (lo << shift as i32).max(IVec3::ZERO),
                hi: (hi << shift as i32).min(self.tree.dims().as_ivec3()),
            };
        }
        let o = octant(step);
        let (lo, hi) = corner_box(c, reaches(cell[o >> 1] >> (12 * (o & 1))), o);
        let shift = self.log_cell as i32;
        Region {
            material: (cell[0] >> 24) as u8,
            lo: (lo << shift).max(IVec3::ZERO),
            hi: (hi << shift).min(self.tree.dims().as_ivec3()),
        }
    }

    fn device_words(&self) -> Vec<&[u32]> {
        match self.codes_at {
            CodesAt::WalkData => vec![self.device_tree(), self.device_cut(), &self.codes],
            CodesAt::MoreBindings => vec![self.device_tree(), self.device_cut()],
        }
    }

    fn device_more_words(&self) -> &[u32] {
        match self.codes_at {
            CodesAt::WalkData => &[],
            CodesAt::MoreBindings => &self.codes,
        }
    }

    fn kernel_variant(&self) -> u32 {
        if self.cells_hold_heads() {
            KERNEL_WITH_HEADS
        } else if self.has_codes() {
            KERNEL_WITH_CODES
        } else {
            0
        }
    }

    fn summary(&self) -> Option<String> {
        let size = |words: usize| crate::output::bytes_text(4 * words as u64);
        let budget = crate::output::bytes_text(self.budget as u64);
        let cells = format!("cells of {} voxels a side", 1u64 << self.log_cell);
        let tree = size(self.tree.words().len() + self.cut.len());
        // What the codes follow, or would have followed.
        let before = {
            let cut = if self.heads_with_codes() {
                "the cut, whose cells hold their nodes' heads"
            } else {
                "the cut"
            };
            let host = if self.has_codes() {
                "; the tree stays on the host"
            } else {
                ""
            };
            if self.tree_free_with_codes() {
                format!("{cut} ({}{host})", size(self.words_before_codes()))
            } else {
                format!("the tree and the cut ({tree})")
            }
        };
        Some(if self.has_codes() {
            let codes = format!(
                "the children's codes of {} nodes in {} distinct blocks ({})",
                self.coded_count,
                (self.codes.len() - self.blocks_words) / BLOCK_WORDS,
                size(self.codes.len())
            );
            match self.codes_at {
                CodesAt::WalkData => {
                    format!("{cells}; {codes} after {before}, within {budget} a binding")
                }
                CodesAt::MoreBindings => format!(
                    "{cells}; {before} in one binding, {codes} in {} more of {budget}",
                    self.codes
                        .len()
                        .div_ceil(super::walk_part_words(self.budget))
                ),
            }
        } else if self.tree.log_branch() != GPU_LOG_BRANCH {
            format!("{cells}; no codes (theirs are the 64-tree's children)")
        } else if self.uncoded_bytes > 0 {
            format!(
                "{cells}; no codes, so more steps a ray: the children's codes of its {} nodes \
                 ({}) do not fit beside {before} within {budget} a binding and {} more \
                 (render.walk_budget_mib)",
                self.uncoded,
                crate::output::bytes_text(self.uncoded_bytes as u64),
                super::WALK_MORE_BINDINGS
            )
        } else if self.uncoded > 0 {
            format!(
                "{cells}; no codes, so more steps a ray: {before} leaves no room within \
                 {budget} a binding for the children's codes of its {} nodes \
                 (render.walk_budget_mib)",
                self.uncoded
            )
        } else {
            format!("{cells}, no node below them ({tree})")
        })
    }
}
