//! The sparse hierarchical grid (the seed's O2): a tree of uniform regions that the DDA
//! skips whole.
//!
//! Every node splits its cube into `B^3` children (`B = 2^log_branch`: 2 is an octree,
//! 4 the 64-tree of the GPU kernel). A child is either uniform (one material over its
//! whole cube, any material, not only void) or a node of its own. voxlab's hit rule is
//! "the first voxel whose material differs from the ray's medium", so a uniform region of
//! the ray's medium holds no hit, whatever that medium is: a ray inside a glass block
//! skips the block as a ray in air skips the air.
//!
//! The walk over it ([`crate::dda::Dda::skip`], `dda_skip` in shaders/traversal.wgsl)
//! leaves a region at exactly the voxel, distance and face where the dense DDA leaves it,
//! so the hits, normals and images are the dense grid's (`tests/sparse.rs`).
//!
//! Layout (`words`, also what the GPU reads): a header of [`HEADER_WORDS`] words
//! (`levels`, `log_branch`, node count, 0), then the nodes, root first, each
//! [`SparseTree::node_words`] words (a multiple of 4, so the GPU reads a 64-tree node's
//! mask and child index in one `vec4<u32>` load): a bit mask of the children that are
//! nodes (bit `i % 32` of mask word `i / 32`, child `i = x + B y + B^2 z`); the index of
//! its first child node; the children's materials, four bytes to a word, child `i` in
//! byte `i % 4` of word `i / 4`. The child nodes of one node are stored one after another,
//! in child order, so child `i`'s node is `first + (number of node bits below i)`.

use std::collections::VecDeque;

use rustc_hash::{FxHashMap, FxHashSet};
use std::time::{Duration, Instant};

use glam::{IVec3, UVec3};

use crate::scene::{Grid, VOID};

/// Words before the first node.
pub const HEADER_WORDS: usize = 4;

/// The branching of the GPU kernel's tree: 4x4x4 children (a 64-tree).
pub(crate) const GPU_LOG_BRANCH: u32 = 2;

/// Deepest tree the GPU kernel descends (shaders/traversal_sparse.wgsl unrolls its levels):
/// 4^8 = 65536 voxels a side, beyond any grid voxlab accepts.
pub(crate) const MAX_GPU_LEVELS: u32 = 8;

/// Levels of nodes a tree of a grid of `dims` has: its root's cube is
/// `2^(log_branch levels)` voxels a side, at least the grid's largest side.
pub fn levels_for(dims: UVec3, log_branch: u32) -> u32 {
    let side = dims.max_element().max(1) as u64;
    let mut levels = 1;
    while (1u64 << (log_branch * levels)) < side {
        levels += 1;
    }
    levels
}

/// A voxel source the tree can be built from without a dense copy of it.
pub trait VoxelSource: Sync {
    fn dims(&self) -> UVec3;
    /// The material at `v`, inside `dims`.
    fn material(&self, v: IVec3) -> u8;
    /// The cube `lo + [0, side)^3` into `out` (x-fastest, `side^3` entries), void where it
    /// leaves the grid. Sources with rows in memory override it.
    fn block(&self, lo: IVec3, side: i32, out: &mut [u8]) {
        let d = self.dims().as_ivec3();
        let mut i = 0;
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    let v = lo + IVec3::new(x, y, z);
                    out[i] = if v.cmplt(d).all() {
                        self.material(v)
                    } else {
                        VOID
                    };
                    i += 1;
                }
            }
        }
    }
    /// `Some(m)` when the source knows the whole cube `lo + [0, size)^3` (clipped to
    /// `dims`) is material `m`, so the builder need not read its voxels. `None`: not
    /// known, read them. (The builder counts the part of a cube outside the grid as
    /// void itself.)
    fn uniform(&self, _lo: IVec3, _size: i32) -> Option<u8> {
        None
    }
}

impl VoxelSource for Grid {
    fn dims(&self) -> UVec3 {
        Grid::dims(self)
    }
    fn material(&self, v: IVec3) -> u8 {
        self.get(v)
    }
    fn block(&self, lo: IVec3, side: i32, out: &mut [u8]) {
        let Some(data) = self.dense() else {
            let tree = self.sparse_tree().expect("a grid is dense or sparse");
            return tree.block(lo, side, out);
        };
        let d = Grid::dims(self).as_ivec3();
        out.fill(VOID);
        let w = (d.x - lo.x).clamp(0, side) as usize;
        for z in 0..side.min(d.z - lo.z) {
            for y in 0..side.min(d.y - lo.y) {
                let (gy, gz) = ((lo.y + y) as usize, (lo.z + z) as usize);
                let at = lo.x as usize + d.x as usize * (gy + d.y as usize * gz);
                let row = (z * side * side + y * side) as usize;
                out[row..row + w].copy_from_slice(&data[at..at + w]);
            }
        }
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        self.sparse_tree()?.uniform(lo, size)
    }
}

/// A tree is a source too: another branching is built from it region by region.
impl VoxelSource for SparseTree {
    fn dims(&self) -> UVec3 {
        self.dims
    }
    fn material(&self, v: IVec3) -> u8 {
        self.get(v)
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        let r = self.region(lo);
        let hi = (lo + IVec3::splat(size)).min(self.dims.as_ivec3());
        (r.lo.cmple(lo).all() && r.hi.cmpge(hi).all()).then_some(r.material)
    }
}

/// Side of a [`BrickSource`]'s bricks: the leaf blocks of the 64-tree, so the builder
/// reads a leaf with one look-up.
pub(crate) const BRICK: i32 = 4;

/// A sparse set of voxels: the material of every voxel set, void elsewhere, held in
/// 4x4x4 bricks, with the coarser cubes that hold any brick, so the tree builder skips
/// empty space without reading it. What loaders fill when the dense grid is too large to
/// allocate (`.vox` scenes).
pub struct BrickSource {
    dims: UVec3,
    bricks: FxHashMap<IVec3, [u8; 64]>,
    /// `occupied[k]`: the cubes of side `2^k` (k >= 2) that hold a brick, by `v >> k`.
    occupied: Vec<FxHashSet<IVec3>>,
}

impl BrickSource {
    pub fn new(dims: UVec3) -> Self {
        Self {
            dims,
            bricks: FxHashMap::default(),
            occupied: Vec::new(),
        }
    }

    /// Sets voxel `v` (inside `dims`); a later set replaces an earlier one.
    pub fn set(&mut self, v: IVec3, material: u8) {
        debug_assert!(v.cmpge(IVec3::ZERO).all() && v.as_uvec3().cmplt(self.dims).all());
        let b = v.div_euclid(IVec3::splat(BRICK));
        let o = v - b * BRICK;
        self.bricks.entry(b).or_insert([VOID; 64])[(o.x + 4 * o.y + 16 * o.z) as usize] = material;
        self.occupied.clear();
    }

    /// Bricks held (each 64 bytes).
    pub(crate) fn brick_count(&self) -> usize {
        self.bricks.len()
    }

    /// The tree of the voxels set.
    pub fn into_tree(mut self, log_branch: u32) -> SparseTree {
        self.index();
        SparseTree::build(&self, log_branch)
    }

    /// Indexes the coarser cubes; done once after the last `set`, before building.
    fn index(&mut self) {
        let top = 32 - self.dims.max_element().max(1).leading_zeros() + 1;
        self.occupied = (0..=top)
            .map(|k| {
                if k < 2 {
                    return FxHashSet::default();
                }
                self.bricks
                    .keys()
                    .map(|b| (*b * BRICK) >> k as i32)
                    .collect()
            })
            .collect();
    }
}

impl VoxelSource for BrickSource {
    fn dims(&self) -> UVec3 {
        self.dims
    }
    fn material(&self, v: IVec3) -> u8 {
        let b = v.div_euclid(IVec3::splat(BRICK));
        let o = v - b * BRICK;
        self.bricks
            .get(&b)
            .map_or(VOID, |k| k[(o.x + 4 * o.y + 16 * o.z) as usize])
    }
    fn block(&self, lo: IVec3, side: i32, out: &mut [u8]) {
        if side == BRICK && lo % BRICK == IVec3::ZERO {
            match self.bricks.get(&(lo / BRICK)) {
                Some(b) => out.copy_from_slice(b),
                None => out.fill(VOID),
            }
            return;
        }
        let mut i = 0;
        for z in 0..side {
            for y in 0..side {
                for x in 0..side {
                    out[i] = self.material(lo + IVec3::new(x, y, z));
                    i += 1;
                }
            }
        }
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        let k = size.trailing_zeros() as usize;
        let aligned = size.count_ones() == 1 && lo % size == IVec3::ZERO;
        // Not indexed yet, or not a cube the index holds: read the voxels.
        let set = self.occupied.get(k).filter(|_| k >= 2 && aligned)?;
        (!set.contains(&(lo >> k as i32))).then_some(VOID)
    }
}

/// Boxes of one material each written over a source, later boxes over earlier ones: how
/// `[[scene.boxes]]` edit a grid held as a tree (the tree is rebuilt once from this).
pub struct BoxOverlay<'a> {
    pub base: &'a dyn VoxelSource,
    /// `(min, max, material)`: voxels `min <= v < max`.
    pub boxes: &'a [(IVec3, IVec3, u8)],
}

impl VoxelSource for BoxOverlay<'_> {
    fn dims(&self) -> UVec3 {
        self.base.dims()
    }
    fn material(&self, v: IVec3) -> u8 {
        self.boxes
            .iter()
            .rev()
            .find(|(lo, hi, _)| v.cmpge(*lo).all() && v.cmplt(*hi).all())
            .map_or_else(|| self.base.material(v), |b| b.2)
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        let hi = (lo + IVec3::splat(size)).min(self.dims().as_ivec3());
        // The topmost box that meets the cube decides: covering it, it is the box's.
        for &(bl, bh, m) in self.boxes.iter().rev() {
            let meets = bl.cmplt(hi).all() && lo.cmplt(bh).all() && bl.cmplt(bh).all();
            if !meets {
                continue;
            }
            let covers = bl.cmple(lo).all() && hi.cmple(bh).all();
            return covers.then_some(m);
        }
        self.base.uniform(lo, size)
    }
}

/// A model placed into a grid: its voxels, each a cube of `scale^3` at `base`, through
/// `map` (the model's material index to the grid's); its void voxels leave what is below.
pub struct PlacedModel<'a> {
    pub voxels: &'a Grid,
    pub base: IVec3,
    pub scale: i32,
    pub map: &'a [u8],
}

impl PlacedModel<'_> {
    /// The model voxel under grid voxel `v`, if `v` is inside its box.
    fn source(&self, v: IVec3) -> Option<IVec3> {
        let d = self.voxels.dims().as_ivec3() * self.scale;
        let local = v - self.base;
        (local.cmpge(IVec3::ZERO).all() && local.cmplt(d).all()).then(|| local / self.scale)
    }

    /// Whether the cube `lo + [0, size)^3` meets the model's box.
    fn meets(&self, lo: IVec3, size: i32) -> bool {
        let hi = self.base + self.voxels.dims().as_ivec3() * self.scale;
        lo.cmplt(hi).all() && self.base.cmplt(lo + size).all()
    }
}

/// Models written over a source in order, each non-void voxel replacing what was there:
/// how `[[scene.models]]` are placed into a grid held as a tree (rebuilt once from this).
pub struct ModelOverlay<'a> {
    pub base: &'a dyn VoxelSource,
    pub models: &'a [PlacedModel<'a>],
}

impl VoxelSource for ModelOverlay<'_> {
    fn dims(&self) -> UVec3 {
        self.base.dims()
    }
    fn material(&self, v: IVec3) -> u8 {
        for m in self.models.iter().rev() {
            if let Some(s) = m.source(v) {
                let k = m.voxels.get(s);
                if k != VOID {
                    return m.map[k as usize];
                }
            }
        }
        self.base.material(v)
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        // From the top: a model the cube meets decides if the cube lies inside one of
        // its scaled voxels (a solid one covers it, a void one lets the next show).
        for m in self.models.iter().rev() {
            if !m.meets(lo, size) {
                continue;
            }
            let (a, b) = (m.source(lo)?, m.source(lo + size - 1)?);
            if a != b {
                return None;
            }
            let k = m.voxels.get(a);
            if k != VOID {
                return Some(m.map[k as usize]);
            }
        }
        self.base.uniform(lo, size)
    }
}

/// A tree's voxels through a table of materials (rebuilt canonically: regions that
/// become alike merge).
pub(crate) struct Mapped<'a> {
    pub base: &'a SparseTree,
    pub table: [u8; 256],
}

impl VoxelSource for Mapped<'_> {
    fn dims(&self) -> UVec3 {
        self.base.dims
    }
    fn material(&self, v: IVec3) -> u8 {
        self.table[self.base.get(v) as usize]
    }
    fn uniform(&self, lo: IVec3, size: i32) -> Option<u8> {
        self.base.uniform(lo, size).map(|m| self.table[m as usize])
    }
}

/// The uniform region around a voxel: its material and its cube, clipped to the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    pub material: u8,
    /// First voxel of the region.
    pub lo: IVec3,
    /// One past the last voxel, per axis.
    pub hi: IVec3,
}

impl Region {
    /// Whether the region is the one voxel `lo`.
    pub(crate) fn is_voxel(&self) -> bool {
        self.hi - self.lo == IVec3::ONE
    }
}

/// The uniform regions of a grid as a traversal finds them on the CPU (the f64 twin of
/// its WGSL `region_at`, `crate::technique::TraversalModel::cpu`): the walks
/// (`crate::dda::Dda`) leave a region of the ray's medium whole. Without one every
/// region is a voxel, read from the grid.
pub trait Regions: Send + Sync {
    /// A uniform region holding voxel `v` (inside the grid), for a walk whose step along
    /// each axis is `step` (-1, 0 or 1): a traversal may give one that reaches only the
    /// way the ray goes (it must hold `v` along an axis of step 0).
    fn region(&self, v: IVec3, step: IVec3) -> Region;
    /// The words the traversal's WGSL module reads (`walk_data`, shaders/bindings.wgsl),
    /// in parts laid one after another (so a walk that adds to the tree need not copy
    /// it).
    fn device_words(&self) -> Vec<&[u32]>;
    /// Words the WGSL module reads beyond `walk_data`, as one array
    /// (`walk_more_word`, shaders/bindings.wgsl) that the GPU tracer lays over up to
    /// [`crate::technique::WALK_MORE_BINDINGS`] bindings of
    /// [`crate::technique::walk_part_words`] words each: data that outgrows one
    /// binding (the sparse octant walk's codes at 2048^3). None by default.
    fn device_more_words(&self) -> &[u32] {
        &[]
    }
    /// Which kernel this data is walked by (`WALK_VARIANT`, a shader def of the
    /// traversal's WGSL module), where what the data holds decides the reads a step
    /// needs: Mesa's software driver runs a branch's storage reads for every lane
    /// whatever the lanes take, so a step that reads only what this data has is faster
    /// (the sparse octant walk with and without its codes). 0 by default.
    fn kernel_variant(&self) -> u32 {
        0
    }
    /// What this data holds where the walk chose it within its budget (the plan's
    /// `walk data:` line, in the render's record): a choice that changes the steps and
    /// not the image (the sparse octant walk's codes, left out where they do not fit)
    /// must not pass unsaid. None where the data is always the same.
    fn summary(&self) -> Option<String> {
        None
    }
    /// The bytes of all the words the kernel reads.
    fn device_bytes(&self) -> usize {
        let words: usize = self.device_words().iter().map(|w| w.len()).sum();
        4 * (words + self.device_more_words().len())
    }
}

impl Regions for SparseTree {
    fn region(&self, v: IVec3, _step: IVec3) -> Region {
        SparseTree::region(self, v)
    }

    fn device_words(&self) -> Vec<&[u32]> {
        vec![self.words()]
    }
}

/// A child of a node, as [`SparseTree::visit`] meets it: its cube is `lo + [0,
/// 2^log_side)^3`.
#[derive(Clone, Copy, Debug)]
enum Visited {
    Node {
        index: usize,
        lo: IVec3,
        log_side: u32,
    },
    Uniform {
        material: u8,
        lo: IVec3,
        log_side: u32,
    },
}

/// One cube of a [`SparseTree::cut`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// Every voxel of the cube inside the grid holds this material.
    Uniform(u8),
    /// The cube is the node of this index.
    Node(u32),
}

/// A sparse hierarchical grid: see the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct SparseTree {
    dims: UVec3,
    log_branch: u32,
    levels: u32,
    words: Vec<u32>,
}

/// A node while the tree is built, before it is laid out.
struct Pending {
    materials: Vec<u8>,
    /// The children that are nodes, in child order, with their child index (only
    /// these: a leaf's list is empty, which keeps the builder's peak memory near the
    /// tree's own on large grids).
    nodes: Vec<(usize, Box<Pending>)>,
}

enum Child {
    Uniform(u8),
    Node(Box<Pending>),
}

/// What building cost.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BuildStats {
    pub time: Duration,
}

impl SparseTree {
    /// The tree of `source` with `2^log_branch` children a side per node (1..=3).
    pub fn build(source: &dyn VoxelSource, log_branch: u32) -> Self {
        assert!((1..=3).contains(&log_branch), "log_branch {log_branch}");
        let dims = source.dims();
        let levels = levels_for(dims, log_branch);
        let root_shift = log_branch * levels;
        let builder = Builder {
            source,
            dims: dims.as_ivec3(),
            log_branch,
        };
        let root = match builder.child(IVec3::ZERO, root_shift) {
            Child::Node(n) => n,
            // A uniform grid still has a root node: every child uniform.
            Child::Uniform(m) => {
                let n = 1usize << (3 * log_branch);
                Box::new(Pending {
                    materials: vec![m; n],
                    nodes: Vec::new(),
                })
            }
        };
        let mut tree = Self {
            dims,
            log_branch,
            levels,
            words: vec![levels, log_branch, 0, 0],
        };
        tree.lay_out(root);
        tree
    }

    /// [`Self::build`] timed.
    pub(crate) fn build_timed(source: &dyn VoxelSource, log_branch: u32) -> (Self, BuildStats) {
        let start = Instant::now();
        let tree = Self::build(source, log_branch);
        (
            tree,
            BuildStats {
                time: start.elapsed(),
            },
        )
    }

    fn children(&self) -> usize {
        1 << (3 * self.log_branch)
    }

    /// Words of one node: mask, first child, materials, a multiple of 4.
    pub fn node_words(&self) -> usize {
        let (_, _, materials_at) = self.offsets();
        (materials_at + self.children().div_ceil(4)).next_multiple_of(4)
    }

    /// Where a node's mask, first-child index and materials start within it: the
    /// materials on a 4-word boundary unless the whole node fits in 4 words (an octree's).
    fn offsets(&self) -> (usize, usize, usize) {
        let n = self.children();
        let mask_words = n.div_ceil(32);
        let head = mask_words + 1;
        if head + n.div_ceil(4) <= 4 {
            (0, mask_words, head)
        } else {
            (0, mask_words, head.next_multiple_of(4))
        }
    }

    /// Breadth first, so the child nodes of each node lie one after another.
    fn lay_out(&mut self, root: Box<Pending>) {
        let (mask_at, first_at, materials_at) = self.offsets();
        let mut queue = VecDeque::from([root]);
        let mut next_index = 1u32; // the root is node 0
        let mut count = 0u32;
        while let Some(node) = queue.pop_front() {
            count += 1;
            let mut words = vec![0u32; self.node_words()];
            for (i, &m) in node.materials.iter().enumerate() {
                words[materials_at + i / 4] |= u32::from(m) << (8 * (i % 4));
            }
            words[first_at] = next_index;
            for (i, c) in node.nodes {
                words[mask_at + i / 32] |= 1 << (i % 32);
                queue.push_back(c);
                next_index += 1;
            }
            self.words.extend_from_slice(&words);
        }
        self.words[2] = count;
    }

    pub fn dims(&self) -> UVec3 {
        self.dims
    }
    pub fn levels(&self) -> u32 {
        self.levels
    }
    pub fn log_branch(&self) -> u32 {
        self.log_branch
    }
    pub fn node_count(&self) -> usize {
        self.words[2] as usize
    }
    /// The tree as the GPU reads it.
    pub fn words(&self) -> &[u32] {
        &self.words
    }
    /// Bytes of the tree.
    pub fn bytes(&self) -> usize {
        self.words.len() * 4
    }
    /// Bytes per voxel of the grid's box (the dense grid's is 1).
    pub fn bytes_per_voxel(&self) -> f64 {
        let d = self.dims.as_dvec3();
        self.bytes() as f64 / (d.x * d.y * d.z)
    }

    /// The uniform region holding voxel `v` (inside the grid).
    pub fn region(&self, v: IVec3) -> Region {
        self.region_below(v, 0, self.log_branch * (self.levels - 1))
    }

    /// The uniform region holding voxel `v` (inside the grid), found by descending from
    /// `node`, whose cube holds `v` and whose children are `2^shift` voxels a side.
    pub fn region_below(&self, v: IVec3, node: u32, shift: u32) -> Region {
        self.descend(v, node, shift).0
    }

    /// [`Self::region_below`], with the node the descent ended in and its children's
    /// shift (0: a leaf, [`Self::nodes_up_to`]), as shaders/tree.wgsl's `Found`.
    pub fn descend(&self, v: IVec3, node: u32, shift: u32) -> (Region, u32, u32) {
        debug_assert!(v.cmpge(IVec3::ZERO).all() && v.as_uvec3().cmplt(self.dims).all());
        let (mask_at, first_at, materials_at) = self.offsets();
        let b = self.log_branch;
        let mask = (1 << b) - 1;
        let mut node = node as usize;
        let mut shift = shift;
        loop {
            let c = (v >> shift as i32) & mask;
            let i = (c.x | (c.y << b) | (c.z << (2 * b))) as usize;
            let base = HEADER_WORDS + node * self.node_words();
            let bits = &self.words[base + mask_at..base + first_at];
            if bits[i / 32] & (1 << (i % 32)) != 0 {
                let below: u32 = bits[..i / 32].iter().map(|w| w.count_ones()).sum::<u32>()
                    + (bits[i / 32] & ((1u32 << (i % 32)) - 1)).count_ones();
                node = (self.words[base + first_at] + below) as usize;
                shift -= b;
                continue;
            }
            let material = (self.words[base + materials_at + i / 4] >> (8 * (i % 4))) as u8;
            let lo = (v >> shift as i32) << shift as i32;
            let hi = (lo + IVec3::splat(1 << shift)).min(self.dims.as_ivec3());
            return (Region { material, lo, hi }, node as u32, shift);
        }
    }

    /// The nodes of side at most `2^log_side`: the tree's lowest levels, which the
    /// breadth-first layout stores last. The index of the first and each one's first
    /// voxel and log2 side, in index order. `nodes_up_to(log_branch)` are the leaves,
    /// the nodes whose children are voxels.
    pub fn nodes_up_to(&self, log_side: u32) -> (u32, Vec<(IVec3, u32)>) {
        let count = self.node_count();
        let root_side = self.log_branch * self.levels;
        let mut found = Vec::new();
        if root_side <= log_side && count > 0 {
            found.push((0, (IVec3::ZERO, root_side)));
        }
        self.visit(|child| match child {
            Visited::Node {
                index,
                lo,
                log_side: side,
            } => {
                if side <= log_side {
                    found.push((index, (lo, side)));
                }
                // A leaf's children are voxels: nothing below it to visit.
                side > self.log_branch
            }
            Visited::Uniform { .. } => true,
        });
        found.sort_unstable_by_key(|&(i, _)| i);
        let first = count - found.len();
        debug_assert!(found.iter().enumerate().all(|(k, &(i, _))| i == first + k));
        (first as u32, found.into_iter().map(|(_, n)| n).collect())
    }

    /// The head of node `node`: its mask words and its first child's index, what a
    /// descent reads of a node whose children's materials it does not need.
    pub fn node_head(&self, node: u32) -> &[u32] {
        let (mask_at, first_at, _) = self.offsets();
        let base = HEADER_WORDS + node as usize * self.node_words();
        &self.words[base + mask_at..=base + first_at]
    }

    /// The children of node `node` (x fastest): the material of a uniform one, `None`
    /// for a node.
    pub fn node_children(&self, node: u32) -> Vec<Option<u8>> {
        let (mask_at, _, materials_at) = self.offsets();
        let base = HEADER_WORDS + node as usize * self.node_words();
        (0..self.children())
            .map(|i| {
                let is_node = self.words[base + mask_at + i / 32] & (1 << (i % 32)) != 0;
                let m = (self.words[base + materials_at + i / 4] >> (8 * (i % 4))) as u8;
                (!is_node).then_some(m)
            })
            .collect()
    }

    /// The tree cut at the cubes of `2^log_side` voxels a side (at most the root's
    /// cube): the cut's dims (the grid's, rounded up) and, for each cube (x fastest), its
    /// material where it is uniform, else the node that holds it: the node of side
    /// `2^node_log`, [`Self::cut_node_log`], whose descent finds the cube's regions. A
    /// cube reaching past the grid is uniform only where the tree holds it so (its part
    /// outside the grid counts as void, `Builder::child`).
    pub fn cut(&self, log_side: u32) -> (UVec3, Vec<Cut>) {
        let b = self.log_branch;
        assert!(
            (1..=b * self.levels).contains(&log_side),
            "cut at 2^{log_side}"
        );
        let node_log = self.cut_node_log(log_side);
        let side = 1u32 << log_side;
        let cut_dims = (self.dims + UVec3::splat(side - 1)) / side;
        let mut cubes = vec![Cut::Uniform(VOID); cut_dims.as_usizevec3().element_product()];
        let index_of = |c: IVec3| {
            c.x as usize + cut_dims.x as usize * (c.y as usize + cut_dims.y as usize * c.z as usize)
        };
        let dims = self.dims.as_ivec3();
        if node_log == b * self.levels {
            self.cut_node(0, IVec3::ZERO, node_log, log_side, &mut |c, cube| {
                cubes[index_of(c)] = cube
            });
            return (cut_dims, cubes);
        }
        self.visit(|child| match child {
            // Past the grid: no cube.
            Visited::Node { lo, .. } | Visited::Uniform { lo, .. } if lo.cmpge(dims).any() => false,
            Visited::Node {
                index,
                lo,
                log_side: l,
            } if l == node_log => {
                self.cut_node(index, lo, node_log, log_side, &mut |c, cube| {
                    cubes[index_of(c)] = cube
                });
                false
            }
            Visited::Node { .. } => true,
            // A uniform child of side 2^l >= 2^node_log: whole cubes.
            Visited::Uniform {
                material,
                lo,
                log_side: l,
            } => {
                let hi = (lo + IVec3::splat(1 << l)).min(dims);
                let (c_lo, c_hi) = (
                    lo >> log_side as i32,
                    (hi + IVec3::splat(side as i32 - 1)) >> log_side as i32,
                );
                for z in c_lo.z..c_hi.z {
                    for y in c_lo.y..c_hi.y {
                        for x in c_lo.x..c_hi.x {
                            cubes[index_of(IVec3::new(x, y, z))] = Cut::Uniform(material);
                        }
                    }
                }
                false
            }
        });
        (cut_dims, cubes)
    }

    /// The log2 side of the nodes a cut at `2^log_side` finds its cubes' regions below:
    /// `log_side` rounded up to the tree's levels.
    pub fn cut_node_log(&self, log_side: u32) -> u32 {
        log_side.next_multiple_of(self.log_branch)
    }

    /// The cubes of side `2^log_side` (inside the grid) of node `node` (side
    /// `2^node_log`, at `lo`), to `put`: a cube whose children inside the grid are
    /// uniform of one material is that material, any other the node.
    fn cut_node(
        &self,
        node: usize,
        lo: IVec3,
        node_log: u32,
        log_side: u32,
        put: &mut dyn FnMut(IVec3, Cut),
    ) {
        let dims = self.dims.as_ivec3();
        let b = self.log_branch;
        if log_side == node_log {
            put(lo >> log_side as i32, Cut::Node(node as u32));
            return;
        }
        let (mask_at, _, materials_at) = self.offsets();
        let base = HEADER_WORDS + node * self.node_words();
        let branch = 1i32 << b;
        let child_log = node_log - b;
        let per_cube = 1i32 << (log_side - child_log);
        let cubes = branch / per_cube;
        for cz in 0..cubes {
            for cy in 0..cubes {
                for cx in 0..cubes {
                    let cube = IVec3::new(cx, cy, cz);
                    let cube_lo = lo + (cube << log_side as i32);
                    if cube_lo.cmpge(dims).any() {
                        continue;
                    }
                    let mut material = None;
                    let mut uniform = true;
                    for k in 0..per_cube * per_cube * per_cube {
                        let c = cube * per_cube
                            + IVec3::new(
                                k % per_cube,
                                k / per_cube % per_cube,
                                k / per_cube / per_cube,
                            );
                        if (lo + (c << child_log as i32)).cmpge(dims).any() {
                            continue;
                        }
                        let i = (c.x | (c.y << b) | (c.z << (2 * b))) as usize;
                        if self.words[base + mask_at + i / 32] & (1 << (i % 32)) != 0 {
                            uniform = false;
                            break;
                        }
                        let m = (self.words[base + materials_at + i / 4] >> (8 * (i % 4))) as u8;
                        if *material.get_or_insert(m) != m {
                            uniform = false;
                            break;
                        }
                    }
                    let at = cube_lo >> log_side as i32;
                    match (uniform, material) {
                        (true, Some(m)) => put(at, Cut::Uniform(m)),
                        _ => put(at, Cut::Node(node as u32)),
                    }
                }
            }
        }
    }

    /// How many of the grid's voxels hold each material (the parts of the root's cube
    /// outside the grid are not counted).
    pub fn material_counts(&self) -> [u64; 256] {
        let mut counts = [0u64; 256];
        let dims = self.dims.as_ivec3();
        self.visit(|child| {
            if let Visited::Uniform {
                material,
                lo,
                log_side,
            } = child
            {
                let hi = (lo + IVec3::splat(1 << log_side)).min(dims);
                let volume = (hi - lo).max(IVec3::ZERO).as_u64vec3().element_product();
                counts[material as usize] += volume;
            }
            true
        });
        counts
    }

    /// Visits the children of the root and, depth first, of every child node `visit`
    /// returns true for.
    fn visit(&self, mut visit: impl FnMut(Visited) -> bool) {
        let (mask_at, first_at, materials_at) = self.offsets();
        let b = self.log_branch;
        let branch = 1i32 << b;
        let mut stack = vec![(0usize, IVec3::ZERO, b * (self.levels - 1))];
        while let Some((node, lo, shift)) = stack.pop() {
            let base = HEADER_WORDS + node * self.node_words();
            let first = self.words[base + first_at] as usize;
            let mut below = 0;
            for i in 0..self.children() {
                let c = IVec3::new(
                    i as i32 % branch,
                    i as i32 / branch % branch,
                    i as i32 / branch / branch,
                );
                let child_lo = lo + (c << shift as i32);
                if self.words[base + mask_at + i / 32] & (1 << (i % 32)) != 0 {
                    let index = first + below;
                    below += 1;
                    let child = Visited::Node {
                        index,
                        lo: child_lo,
                        log_side: shift,
                    };
                    if visit(child) && shift >= b {
                        stack.push((index, child_lo, shift - b));
                    }
                    continue;
                }
                let material = (self.words[base + materials_at + i / 4] >> (8 * (i % 4))) as u8;
                visit(Visited::Uniform {
                    material,
                    lo: child_lo,
                    log_side: shift,
                });
            }
        }
    }

    /// Which materials the grid's voxels hold.
    pub fn materials_used(&self) -> [bool; 256] {
        self.material_counts().map(|n| n > 0)
    }

    /// The material at `v` (void outside the grid).
    pub fn get(&self, v: IVec3) -> u8 {
        if v.cmplt(IVec3::ZERO).any() || v.as_uvec3().cmpge(self.dims).any() {
            return VOID;
        }
        self.region(v).material
    }
}

struct Builder<'a> {
    source: &'a dyn VoxelSource,
    dims: IVec3,
    log_branch: u32,
}

impl Builder<'_> {
    /// The child covering the cube `lo + [0, 2^shift)^3`; voxels outside the grid are
    /// void, so a region reaching past the grid's side merges with the void inside it.
    fn child(&self, lo: IVec3, shift: u32) -> Child {
        if lo.cmpge(self.dims).any() {
            return Child::Uniform(VOID);
        }
        if shift == 0 {
            return Child::Uniform(self.source.material(lo));
        }
        let size = 1i32 << shift;
        // A cube reaching past the grid holds void there: uniform only if void (so the
        // tree of a source is the dense grid's, word for word, whatever the source says
        // of the part of a cube outside the grid).
        let inside = (lo + IVec3::splat(size)).cmple(self.dims).all();
        if let Some(m) = self
            .source
            .uniform(lo, size)
            .filter(|&m| inside || m == VOID)
        {
            return Child::Uniform(m);
        }
        let b = self.log_branch;
        let side = 1i32 << b;
        let sub = shift - b;
        let n = 1usize << (3 * b);
        if sub == 0 {
            // The children are voxels: read them as one block.
            let mut materials = vec![VOID; n];
            self.source.block(lo, side, &mut materials);
            if materials.iter().all(|&m| m == materials[0]) {
                return Child::Uniform(materials[0]);
            }
            return Child::Node(Box::new(Pending {
                materials,
                nodes: Vec::new(),
            }));
        }
        let build = |i: usize| {
            let (x, y, z) = (
                i as i32 % side,
                i as i32 / side % side,
                i as i32 / side / side,
            );
            self.child(lo + (IVec3::new(x, y, z) << sub as i32), sub)
        };
        // Children of 64 voxels a side and more are built on every core.
        let children: Vec<Child> = if sub >= 6 {
            use rayon::prelude::*;
            (0..n).into_par_iter().map(build).collect()
        } else {
            (0..n).map(build).collect()
        };
        let mut materials = Vec::with_capacity(n);
        let mut nodes = Vec::new();
        for (i, c) in children.into_iter().enumerate() {
            match c {
                Child::Uniform(m) => materials.push(m),
                Child::Node(node) => {
                    materials.push(VOID);
                    nodes.push((i, node));
                }
            }
        }
        if nodes.is_empty() && materials.iter().all(|&m| m == materials[0]) {
            return Child::Uniform(materials[0]);
        }
        Child::Node(Box::new(Pending { materials, nodes }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn regions_cover_the_grid_exactly() {
        let mut g = Grid::new(UVec3::new(13, 7, 21), 1.0, DVec3::ZERO).unwrap();
        for (i, v) in g.data_mut().iter_mut().enumerate() {
            *v = if i % 97 < 3 { (i % 5) as u8 } else { 0 };
        }
        for b in 1..=3 {
            let t = SparseTree::build(&g, b);
            for z in 0..21 {
                for y in 0..7 {
                    for x in 0..13 {
                        let v = IVec3::new(x, y, z);
                        let r = t.region(v);
                        assert_eq!(r.material, g.get(v), "{v} b {b}");
                        assert!(v.cmpge(r.lo).all() && v.cmplt(r.hi).all());
                    }
                }
            }
        }
    }
}
