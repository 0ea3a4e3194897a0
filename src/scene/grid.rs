//! The voxel grid: dimensions, placement in the world, and one material index per voxel.

use std::sync::Arc;

use glam::{DVec3, IVec3, UVec3};

use super::SceneError;
use crate::sparse::SparseTree;

/// Material index 0 is void (empty space) everywhere in voxlab.
pub const VOID: u8 = 0;

/// Upper bound on voxels a grid may hold before any device limit is consulted
/// (2^31 bytes): a guard against allocating without bound on malformed input.
pub const MAX_VOXELS: u64 = 1 << 31;

/// Smallest and largest voxel size a grid may have, world units. A voxel of 1e308 made
/// the camera distance overflow and the CPU walk revisit one voxel forever; within this
/// range every distance the tracers compute (up to 1e6 voxels times 1e6) is far from
/// overflow, and squared falloff distances stay finite.
pub const MIN_VOXEL_SIZE: f64 = 1e-6;
pub const MAX_VOXEL_SIZE: f64 = 1e6;

/// Largest side of a grid held only as its sparse tree ([`Grid::from_tree`]): 4096 keeps
/// the tree of any scene voxlab generates or loads within host memory (the seed scene's
/// at 4096^3 is about 0.5 GiB) and its build within seconds.
pub const MAX_SPARSE_SIDE: u32 = 4096;

/// Grids of more voxels than this are held only as their sparse tree by the generators
/// and loaders that can build one directly (the seed scene, `.vox` scenes): 2^28 bytes
/// is 256 MiB of dense voxels, past the side (512) from which `render.traversal =
/// "auto"` walks the tree anyway, so a dense copy would only be built to be discarded.
pub const DENSE_MAX_VOXELS: u64 = 1 << 28;

/// How a generator or loader holds a grid's voxels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Storage {
    /// Densely up to [`DENSE_MAX_VOXELS`] voxels, as a sparse tree beyond.
    #[default]
    Auto,
    Dense,
    /// As a sparse tree built directly from the source, whatever its size.
    Sparse,
}

impl Storage {
    /// Whether a grid of `voxels` voxels is held as a sparse tree.
    pub(crate) fn is_sparse_for(self, voxels: u64) -> bool {
        match self {
            Storage::Auto => voxels > DENSE_MAX_VOXELS,
            Storage::Dense => false,
            Storage::Sparse => true,
        }
    }
}

/// A voxel grid. Voxel `(x, y, z)` covers the world box
/// `origin + voxel_size * [x, x+1] x [y, y+1] x [z, z+1]`.
///
/// Its voxels are held densely (x-fastest, then y, then z: the layout of a 3D texture
/// upload), or only as a sparse tree (the seed's O2) when the grid is too large to hold
/// densely: see [`Grid::from_tree`]. Everything that reads single voxels ([`Grid::get`])
/// works on both; what needs the dense array ([`Grid::dense`]: the cone pyramids, the
/// distance field, smooth surfaces, the dense walk) is refused for a sparse grid by the
/// plan and the loaders, with the reason.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    dims: UVec3,
    voxel_size: f64,
    origin: DVec3,
    voxels: Voxels,
    /// How many voxels hold each material, once asked for: every plan asks
    /// ([`Grid::materials_used`]), once a frame in the viewer, and counting took 80 ms
    /// at 512^3 (dense) and 0.45 s at 2048^3 (the tree's visit). Forgotten with the
    /// dense hash on every mutable borrow.
    counts: Taken<Box<[u64; 256]>>,
}

#[derive(Clone, Debug, PartialEq)]
enum Voxels {
    /// The voxels and their hash once asked for (every render asks, a 512^3 grid's
    /// 128 MiB take tens of milliseconds to hash); forgotten on every mutable borrow.
    Dense(Vec<u8>, Taken<blake3::Hash>),
    /// The tree and its hash, taken once: the device caches key every render by it, and
    /// the tree never changes (a 2048^3 scene's is 104 MiB).
    Sparse(Arc<SparseTree>, blake3::Hash),
}

/// What the voxels give (their hash, their material counts), taken when first asked
/// for. Two grids compare by their voxels, never by whether it was taken.
#[derive(Clone, Debug)]
struct Taken<T>(std::sync::OnceLock<T>);

impl<T> Default for Taken<T> {
    fn default() -> Self {
        Self(std::sync::OnceLock::new())
    }
}

impl<T> PartialEq for Taken<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Voxels {
    fn dense(voxels: Vec<u8>) -> Self {
        Voxels::Dense(voxels, Taken::default())
    }

    fn sparse(tree: SparseTree) -> Self {
        let mut h = blake3::Hasher::new();
        h.update(b"sparse");
        h.update(bytemuck::cast_slice(tree.words()));
        Voxels::Sparse(Arc::new(tree), h.finalize())
    }
}

impl Grid {
    /// An all-void grid. Any dimensions from 1x1x1 up are accepted (no power-of-two rule).
    pub fn new(dims: UVec3, voxel_size: f64, origin: DVec3) -> Result<Self, SceneError> {
        if dims.min_element() == 0 {
            return Err(SceneError::new(format!(
                "grid dimensions {}x{}x{}: every dimension must be at least 1",
                dims.x, dims.y, dims.z
            )));
        }
        let count = dims.x as u64 * dims.y as u64 * dims.z as u64;
        if count > MAX_VOXELS {
            return Err(SceneError::new(format!(
                "grid dimensions {}x{}x{} hold {count} voxels; at most {MAX_VOXELS} are allowed",
                dims.x, dims.y, dims.z
            )));
        }
        check_placement(voxel_size, origin)?;
        Ok(Self {
            dims,
            voxel_size,
            origin,
            // Fallibly: a failed allocation is an error, not an abort.
            voxels: Voxels::dense(
                crate::input::try_filled(count as usize, VOID, "the grid's voxels")
                    .map_err(SceneError::new)?,
            ),
            counts: Taken::default(),
        })
    }

    /// A grid held only as `tree` (its dims are the grid's), for grids too large to hold
    /// densely. Sides up to [`MAX_SPARSE_SIDE`].
    pub fn from_tree(tree: SparseTree, voxel_size: f64, origin: DVec3) -> Result<Self, SceneError> {
        let dims = tree.dims();
        if dims.max_element() > MAX_SPARSE_SIDE {
            return Err(SceneError::new(format!(
                "grid dimensions {}x{}x{}: a sparse grid's sides are at most {MAX_SPARSE_SIDE}",
                dims.x, dims.y, dims.z
            )));
        }
        check_placement(voxel_size, origin)?;
        Ok(Self {
            dims,
            voxel_size,
            origin,
            voxels: Voxels::sparse(tree),
            counts: Taken::default(),
        })
    }

    /// The same voxels at another voxel size and origin.
    pub fn placed(&self, voxel_size: f64, origin: DVec3) -> Result<Self, SceneError> {
        check_placement(voxel_size, origin)?;
        Ok(Self {
            voxel_size,
            origin,
            ..self.clone()
        })
    }

    /// The grid with its voxels held densely: itself when they are, else a dense copy of
    /// the tree's voxels (for the builds that read every voxel: smooth surfaces, the
    /// distance field, triangle cells), refused beyond [`MAX_VOXELS`].
    pub fn to_dense(&self) -> Result<std::borrow::Cow<'_, Grid>, SceneError> {
        use crate::sparse::VoxelSource;
        let Voxels::Sparse(tree, _) = &self.voxels else {
            return Ok(std::borrow::Cow::Borrowed(self));
        };
        let mut g = Grid::new(self.dims, self.voxel_size, self.origin)?;
        let d = self.dims;
        let row = d.x as usize;
        let mut block = vec![VOID; 64];
        let data = g.data_mut();
        // Four-voxel blocks, so a uniform region is read once per block.
        for z in (0..d.z).step_by(4) {
            for y in (0..d.y).step_by(4) {
                for x in (0..d.x).step_by(4) {
                    let lo = UVec3::new(x, y, z).as_ivec3();
                    tree.block(lo, 4, &mut block);
                    for (k, &m) in block.iter().enumerate() {
                        let v = lo.as_uvec3()
                            + UVec3::new(k as u32 % 4, k as u32 / 4 % 4, k as u32 / 16);
                        if v.cmplt(d).all() {
                            data[v.x as usize
                                + row * (v.y as usize + d.y as usize * v.z as usize)] = m;
                        }
                    }
                }
            }
        }
        Ok(std::borrow::Cow::Owned(g))
    }

    /// Replaces every voxel's material `m` by `map(m)` (`map(VOID)` must be void for a
    /// grid held sparse, whose tree is rebuilt once).
    pub fn map_materials(&mut self, map: impl Fn(u8) -> u8) {
        let table: [u8; 256] = std::array::from_fn(|m| map(m as u8));
        self.counts.0.take();
        match &mut self.voxels {
            Voxels::Dense(d, hash) => {
                hash.0.take();
                d.iter_mut().for_each(|m| *m = table[*m as usize]);
            }
            Voxels::Sparse(t, _) => {
                assert_eq!(
                    table[VOID as usize], VOID,
                    "a sparse grid's void stays void"
                );
                let source = crate::sparse::Mapped {
                    base: t.as_ref(),
                    table,
                };
                self.voxels = Voxels::sparse(SparseTree::build(&source, t.log_branch()));
            }
        }
    }

    /// Whether the voxels are held only as a sparse tree.
    pub fn is_sparse(&self) -> bool {
        matches!(self.voxels, Voxels::Sparse(..))
    }

    /// The tree a sparse grid is held as.
    pub fn sparse_tree(&self) -> Option<&Arc<SparseTree>> {
        match &self.voxels {
            Voxels::Sparse(t, _) => Some(t),
            Voxels::Dense(..) => None,
        }
    }

    /// The grid's tree with `2^log_branch` children a side: a sparse grid's own when its
    /// branching is that, else built.
    pub fn tree(&self, log_branch: u32) -> Arc<SparseTree> {
        match &self.voxels {
            Voxels::Sparse(t, _) if t.log_branch() == log_branch => t.clone(),
            Voxels::Sparse(t, _) => Arc::new(SparseTree::build(t.as_ref(), log_branch)),
            Voxels::Dense(..) => Arc::new(SparseTree::build(self, log_branch)),
        }
    }

    /// What a record names the voxels by, whatever made them (a file, a generator, an
    /// array): dims, voxel size, origin and the content's blake3 hash.
    pub fn record(&self) -> serde_json::Value {
        serde_json::json!({
            "dims": self.dims().to_array(),
            "voxel_size": self.voxel_size(),
            "origin": self.origin().to_array(),
            "blake3": self.content_hash().to_hex().to_string(),
        })
    }

    /// A hash of the voxels as bytes: not of the placement, nor of the dims (the same
    /// bytes in another shape hash alike), so the device caches keyed by it hold the
    /// dims beside it.
    pub fn content_hash(&self) -> blake3::Hash {
        match &self.voxels {
            Voxels::Dense(d, hash) => *hash.0.get_or_init(|| blake3::hash(d)),
            Voxels::Sparse(_, hash) => *hash,
        }
    }

    /// The bytes the host holds for the voxels.
    pub fn host_bytes(&self) -> usize {
        match &self.voxels {
            Voxels::Dense(d, _) => d.len(),
            Voxels::Sparse(t, _) => t.bytes(),
        }
    }

    pub fn dims(&self) -> UVec3 {
        self.dims
    }
    pub fn voxel_size(&self) -> f64 {
        self.voxel_size
    }
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    pub fn voxel_count(&self) -> usize {
        self.dims.as_u64vec3().element_product() as usize
    }
    /// Material indices, x-fastest, of a dense grid (`None` for a sparse one).
    pub fn dense(&self) -> Option<&[u8]> {
        match &self.voxels {
            Voxels::Dense(d, _) => Some(d),
            Voxels::Sparse(..) => None,
        }
    }
    /// Material indices, x-fastest. Dense grids only: the generators, loaders and tests
    /// that call it make dense grids; code that may meet a sparse grid calls
    /// [`Grid::dense`].
    pub fn data(&self) -> &[u8] {
        self.dense()
            .expect("Grid::data on a sparse grid (callers that may meet one use Grid::dense)")
    }
    /// The material indices, x-fastest, taken out of a dense grid without a copy (`None`
    /// for a sparse one): what a caller that hands the voxels on (Python's
    /// `Grid.to_numpy`, from a dense copy of a sparse grid) keeps from holding them twice.
    pub fn into_dense(self) -> Option<Vec<u8>> {
        match self.voxels {
            Voxels::Dense(d, _) => Some(d),
            Voxels::Sparse(..) => None,
        }
    }
    /// Dense grids only, as [`Grid::data`].
    pub fn data_mut(&mut self) -> &mut [u8] {
        self.counts.0.take();
        match &mut self.voxels {
            Voxels::Dense(d, hash) => {
                hash.0.take();
                d
            }
            Voxels::Sparse(..) => panic!("Grid::data_mut on a sparse grid"),
        }
    }

    pub fn contains(&self, v: IVec3) -> bool {
        v.x >= 0
            && v.y >= 0
            && v.z >= 0
            && (v.x as u32) < self.dims.x
            && (v.y as u32) < self.dims.y
            && (v.z as u32) < self.dims.z
    }

    fn index(&self, v: IVec3) -> usize {
        v.x as usize + self.dims.x as usize * (v.y as usize + self.dims.y as usize * v.z as usize)
    }

    /// Material at voxel `v`; void outside the grid.
    pub fn get(&self, v: IVec3) -> u8 {
        if !self.contains(v) {
            return VOID;
        }
        match &self.voxels {
            Voxels::Dense(d, _) => d[self.index(v)],
            Voxels::Sparse(t, _) => t.region(v).material,
        }
    }

    /// Sets voxel `v` of a dense grid; panics if `v` is outside the grid or the grid is
    /// sparse (programming errors, not input).
    pub fn set(&mut self, v: IVec3, material: u8) {
        assert!(self.contains(v), "voxel {v} outside grid {}", self.dims);
        let i = self.index(v);
        self.data_mut()[i] = material;
    }

    /// World-space size of the grid.
    pub fn extent(&self) -> DVec3 {
        self.dims.as_dvec3() * self.voxel_size
    }
    pub fn world_min(&self) -> DVec3 {
        self.origin
    }
    pub fn world_max(&self) -> DVec3 {
        self.origin + self.extent()
    }
    pub fn centre(&self) -> DVec3 {
        self.origin + 0.5 * self.extent()
    }
    /// The grid's width `W` of `src/trace_contract.md`: its largest world extent.
    pub fn width(&self) -> f64 {
        self.extent().max_element()
    }

    /// World point to grid-local coordinates (voxel units, grid corner at 0).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        (p - self.origin) / self.voxel_size
    }
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        self.origin + local * self.voxel_size
    }

    /// The voxel containing world point `p` (may lie outside the grid).
    pub fn voxel_at(&self, p: DVec3) -> IVec3 {
        self.to_local(p).floor().as_ivec3()
    }

    /// Material at world point `p` (void outside the grid).
    pub fn material_at(&self, p: DVec3) -> u8 {
        let l = self.to_local(p).floor();
        if l.x < 0.0 || l.y < 0.0 || l.z < 0.0 {
            return VOID;
        }
        self.get(l.as_ivec3())
    }

    /// Largest material index used (0 for an empty grid).
    pub fn max_material(&self) -> u8 {
        let used = self.materials_used();
        (0..=255u8)
            .rev()
            .find(|&m| used[m as usize])
            .unwrap_or(VOID)
    }

    /// Which material indices occur in the grid.
    pub fn materials_used(&self) -> [bool; 256] {
        self.material_counts().map(|n| n > 0)
    }

    /// How many voxels hold each material index (counted once, then kept).
    pub fn material_counts(&self) -> [u64; 256] {
        **self.counts.0.get_or_init(|| {
            Box::new(match &self.voxels {
                Voxels::Dense(d, _) => {
                    let mut counts = [0u64; 256];
                    for &m in d {
                        counts[m as usize] += 1;
                    }
                    counts
                }
                Voxels::Sparse(t, _) => t.material_counts(),
            })
        })
    }
}

fn check_placement(voxel_size: f64, origin: DVec3) -> Result<(), SceneError> {
    if !(MIN_VOXEL_SIZE..=MAX_VOXEL_SIZE).contains(&voxel_size) {
        return Err(SceneError::new(format!(
            "voxel size {}: must be in [{MIN_VOXEL_SIZE:e}, {MAX_VOXEL_SIZE:e}] \
             (world units; beyond them camera distances and light falloff leave f64's \
             range)",
            crate::input::short_number(voxel_size)
        )));
    }
    if !origin.is_finite() {
        return Err(SceneError::new(format!(
            "grid origin {}: must be finite",
            crate::input::short_vector(origin)
        )));
    }
    Ok(())
}

/// The six face normals of a voxel, in the order the cone pyramids' builders and the
/// interior fill visit them.
pub const FACES: [IVec3; 6] = [
    IVec3::new(-1, 0, 0),
    IVec3::new(1, 0, 0),
    IVec3::new(0, -1, 0),
    IVec3::new(0, 1, 0),
    IVec3::new(0, 0, -1),
    IVec3::new(0, 0, 1),
];

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> Grid {
        Grid::new(UVec3::new(5, 3, 4), 1.0, DVec3::ZERO).unwrap()
    }

    #[test]
    fn the_cached_hash_follows_every_change_and_never_decides_equality() {
        let mut g = grid();
        let empty = g.content_hash();
        g.set(IVec3::new(1, 2, 3), 7);
        let one = g.content_hash();
        assert_ne!(one, empty, "set after a hash was taken");
        assert_eq!(one, blake3::hash(g.data()));
        g.data_mut()[0] = 2;
        assert_ne!(g.content_hash(), one, "data_mut after a hash was taken");
        let before = g.content_hash();
        g.map_materials(|m| if m == 7 { 9 } else { m });
        assert_ne!(
            g.content_hash(),
            before,
            "map_materials after a hash was taken"
        );
        assert_eq!(g.content_hash(), blake3::hash(g.data()));
        // Equal voxels are equal grids, whether or not either hash was taken.
        let mut fresh = grid();
        fresh.data_mut().copy_from_slice(g.data());
        assert_eq!(fresh, g);
        assert_eq!(fresh.content_hash(), g.content_hash());
        let cloned = g.clone();
        assert_eq!(cloned.content_hash(), g.content_hash());
    }

    #[test]
    fn the_kept_material_counts_follow_every_change() {
        let count = |g: &Grid, m: u8| g.data().iter().filter(|&&v| v == m).count() as u64;
        let mut g = grid();
        assert_eq!(g.material_counts()[0], 60);
        g.set(IVec3::new(1, 2, 3), 7);
        assert_eq!(g.material_counts()[7], 1, "set after the counts were taken");
        assert!(g.materials_used()[7]);
        g.data_mut()[0] = 2;
        assert_eq!(
            g.material_counts()[2],
            1,
            "data_mut after the counts were taken"
        );
        g.map_materials(|m| if m == 7 { 9 } else { m });
        let counts = g.material_counts();
        assert_eq!((counts[7], counts[9]), (0, 1), "map_materials after");
        assert_eq!(g.max_material(), 9);
        for m in 0..=255u8 {
            assert_eq!(counts[m as usize], count(&g, m), "material {m}");
        }
        // A grid held as its tree counts alike, and its remapped tree is counted anew.
        let mut sparse = Grid::from_tree(SparseTree::build(&g, 2), 1.0, DVec3::ZERO).unwrap();
        assert_eq!(sparse.material_counts(), counts);
        sparse.map_materials(|m| if m == 9 { 4 } else { m });
        assert_eq!(sparse.material_counts()[4], 1);
        assert_eq!(sparse.material_counts()[9], 0);
        // Equal voxels are equal grids, whether or not either was counted.
        let mut fresh = grid();
        fresh.data_mut().copy_from_slice(g.data());
        assert_eq!(fresh, g);
    }

    #[test]
    fn into_dense_gives_the_voxels_of_a_dense_grid_and_of_a_trees_dense_copy() {
        let mut g = grid();
        g.set(IVec3::new(1, 2, 3), 7);
        g.set(IVec3::new(0, 0, 0), 2);
        let sparse = Grid::from_tree(SparseTree::build(&g, 2), 1.0, DVec3::ZERO).unwrap();
        let copy = sparse.to_dense().unwrap().into_owned();
        assert_eq!(copy.into_dense().as_deref(), Some(g.data()));
        assert_eq!(sparse.into_dense(), None);
        assert_eq!(g.clone().into_dense().as_deref(), Some(g.data()));
    }
}
