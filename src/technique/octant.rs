//! The octant traversal: the proximity walk with one cube per ray octant. Beside each
//! voxel's material, for each of the eight octants a ray can head into, the largest
//! cube of the voxel's material that has the voxel as its corner and reaches into that
//! octant. A ray reads only its own octant's cube: what lies behind it does not shorten
//! its skip, so a ray leaving a surface skips at once what the centred cubes of
//! [`super::proximity`] let it leave only step by growing step.
//!
//! The cube of voxel `v` toward octant `s` (a sign per axis) of side `k + 1` is `v` and
//! the cubes of side `k` of its seven neighbours `v + s * e` (`e` in {0, 1}^3, not 0),
//! so the largest side is one more than the smallest of theirs where all seven hold
//! `v`'s material (the largest-square recurrence in 3D; neighbours outside the grid do
//! not count, as the walks end there by their own test).

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;

use super::TraversalModel;
use crate::scene::Grid;
use crate::sparse::{Region, Regions};

/// The radii a cube's three-bit code stands for: each the largest of the table not
/// above the true radius, so a cube is never larger than its voxels allow.
pub const RADII: [u8; 8] = [0, 1, 2, 4, 8, 16, 32, 64];

/// The grid side from which `render.traversal = "auto"` walks the octant field (up to
/// the tree walks' [`super::sparse::SPARSE_FROM_SIDE`]: the sparse octant walk,
/// registered after it, claims from there, and its claim wins). On lavapipe, 512x512, since the tracer's loops test their exit at the
/// bottom (shaders/counters.wgsl): the seed scene at 0.80x the dense walk's speed at
/// 8^3, 0.93x at 12^3, 1.05x at 16^3 and 1.22x at 24^3 (`voxlab bench --sizes
/// 8,12,16,24 --size 512 --gpu-runs 3 --no-cpu --traversal dense,octant`); the seed's
/// rules 0.87x at 8^3 and 0.94x at 12^3 (the same with `--sizes 8 --experiments
/// experiments/seed_rules.toml --set scene.size=8`, and 12), 1.04x at 16^3
/// (docs/sparse-traversal.md, "Speed now"). Where the device cannot bind its four
/// bytes a voxel (lavapipe: 128 MiB, 32 M voxels) `"auto"` takes the next walk that
/// claims the grid and fits (`crate::plan::auto_traversal_within`).
pub const OCTANT_FROM_SIDE: u32 = 16;

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "octant",
    summary: "the DDA over the dense grid with each voxel's largest cube of its own \
              material with the voxel as its corner toward each of the 8 ray octants, \
              skipping the ray's octant's cube whole (proximity clouds per octant)",
    label: "octant proximity",
    plan: |scene, _| super::dense_grid_only(scene, "the dense grid with 8 radii beside each voxel"),
    auto: Some(|scene| super::claim_dense_from_side(scene, OCTANT_FROM_SIDE)),
    wgsl: (
        "shaders/traversal_octant.wgsl",
        include_str!("../../shaders/traversal_octant.wgsl"),
    ),
    walks_tree: false,
    descent_levels: None,
    data: Some(|grid, _| Arc::new(OctantField::build(grid))),
    // One word a voxel.
    device_bytes: Some(|dims| super::per_voxel_bytes(dims, 4)),
};

/// Every voxel's material and its eight cubes' codes, one word a voxel (x fastest):
/// material in bits 0..8, octant `o`'s code in bits `8 + 3 o`. Octant `o` has bit `a`
/// set where it heads down axis `a`.
#[derive(Clone, Debug, PartialEq)]
pub struct OctantField {
    dims: UVec3,
    words: Vec<u32>,
}

/// The code of radius `r`: the largest entry of [`RADII`] not above it.
fn code(r: u8) -> u32 {
    RADII.iter().rposition(|&q| q <= r).unwrap_or(0) as u32
}

/// The octant a walk of `step` reads (an axis of step 0 takes the positive side).
pub fn octant(step: IVec3) -> usize {
    (0..3).map(|a| usize::from(step[a] < 0) << a).sum()
}

/// The signs of octant `o`'s axes: -1 where it heads down the axis, else 1 (the step
/// of a walk that reads it, [`octant`]'s inverse).
pub(crate) fn octant_signs(o: usize) -> IVec3 {
    IVec3::from(std::array::from_fn(
        |a| if o >> a & 1 == 1 { -1 } else { 1 },
    ))
}

impl OctantField {
    pub fn build(grid: &Grid) -> Self {
        let dense = grid
            .to_dense()
            .expect("the octant traversal's plan rule keeps it to dense grids");
        let dims = grid.dims();
        let voxels = dense.data();
        let radii: Vec<Vec<u8>> = (0..8)
            .into_par_iter()
            .map(|o| octant_radii(voxels, dims, o))
            .collect();
        let words = voxels
            .par_iter()
            .enumerate()
            .map(|(i, &m)| word(m, &radii, i))
            .collect();
        Self { dims, words }
    }

    fn index(&self, v: IVec3) -> usize {
        let d = self.dims.as_usizevec3();
        v.x as usize + d.x * (v.y as usize + d.y * v.z as usize)
    }

    /// The radius of voxel `v`'s cube toward octant `o`.
    pub fn radius(&self, v: IVec3, o: usize) -> u8 {
        radius(self.words[self.index(v)], o)
    }
}

/// The radius toward octant `o` a voxel's word holds.
fn radius(word: u32, o: usize) -> u8 {
    RADII[(word >> (8 + 3 * o) & 7) as usize]
}

/// The word of a cell of material `m`: its material and the codes of its eight radii
/// (`radii[o][i]`, octant `o`, cell `i`), as [`OctantField`] keeps it.
pub(crate) fn word(m: u8, radii: &[Vec<u8>], i: usize) -> u32 {
    (0..8).fold(u32::from(m), |w, o| w | code_bits(radii[o][i], o))
}

/// Radius `r` toward octant `o` as its code's bits in a word.
pub(crate) fn code_bits(r: u8, o: usize) -> u32 {
    code(r) << (8 + 3 * o)
}

/// The cube of cell `c` whose word is `word` toward octant `o`, in cells (unclipped):
/// its first cell and one past its last.
pub(crate) fn corner_cube(c: IVec3, word: u32, o: usize) -> (IVec3, IVec3) {
    corner_box(c, IVec3::splat(i32::from(radius(word, o))), o)
}

/// The box of reaches `reach` (per axis) with cell `c` as its corner toward octant `o`
/// (unclipped): its first cell and one past its last.
pub(crate) fn corner_box(c: IVec3, reach: IVec3, o: usize) -> (IVec3, IVec3) {
    let down = IVec3::new((o & 1) as i32, (o >> 1 & 1) as i32, (o >> 2 & 1) as i32);
    (
        c - reach * down,
        c + IVec3::ONE + reach * (IVec3::ONE - down),
    )
}

impl Regions for OctantField {
    fn region(&self, v: IVec3, step: IVec3) -> Region {
        let word = self.words[self.index(v)];
        let (lo, hi) = corner_cube(v, word, octant(step));
        Region {
            material: word as u8,
            lo: lo.max(IVec3::ZERO),
            hi: hi.min(self.dims.as_ivec3()),
        }
    }

    fn device_words(&self) -> Vec<&[u32]> {
        vec![&self.words]
    }
}

/// Each voxel's radius toward octant `o` (any cell type compared by equality: the
/// sparse octant walk's cells), capped at 255 (see the module documentation),
/// by the recurrence swept from the octant's far corner a row at a time: first the six
/// neighbours in the three rows done before (one pass over whole rows, which the
/// compiler vectorizes), then the one before it in its own row.
pub fn octant_radii<T: Copy + PartialEq>(voxels: &[T], dims: UVec3, o: usize) -> Vec<u8> {
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let down = |a: usize| o >> a & 1 == 1;
    // The voxels in the order the sweep takes them along an axis, and whether the
    // neighbour toward the octant of the one at `c` is inside the grid.
    let order = |n: usize, a: usize| -> Box<dyn Iterator<Item = usize>> {
        if down(a) {
            Box::new(0..n)
        } else {
            Box::new((0..n).rev())
        }
    };
    let ahead = |c: usize, n: usize, a: usize| {
        if down(a) {
            c.checked_sub(1)
        } else {
            (c + 1 < n).then_some(c + 1)
        }
    };
    let mut out = vec![0u8; voxels.len()];
    let mut cross = vec![0u8; nx];
    for z in order(nz, 2) {
        for y in order(ny, 1) {
            let row = nx * (y + ny * z);
            let mine = &voxels[row..row + nx];
            cross.fill(u8::MAX);
            let rows = [
                ahead(y, ny, 1).map(|y1| (y1, z)),
                ahead(z, nz, 2).map(|z1| (y, z1)),
                ahead(y, ny, 1).zip(ahead(z, nz, 2)),
            ];
            for (y1, z1) in rows.into_iter().flatten() {
                let other = nx * (y1 + ny * z1);
                let (theirs, radii) = (&voxels[other..other + nx], &out[other..other + nx]);
                fold(&mut cross, mine, theirs, radii);
                if nx > 1 {
                    let n = nx - 1;
                    if down(0) {
                        fold(&mut cross[1..], &mine[1..], &theirs[..n], &radii[..n]);
                    } else {
                        fold(&mut cross[..n], &mine[..n], &theirs[1..], &radii[1..]);
                    }
                }
            }
            for x in order(nx, 0) {
                let i = row + x;
                out[i] = match ahead(x, nx, 0) {
                    Some(x1) if voxels[row + x1] != voxels[i] => 0,
                    Some(x1) => cross[x].min(out[row + x1].saturating_add(1)),
                    None => cross[x],
                };
            }
        }
    }
    out
}

/// `cross[x]` lowered to what neighbour `x` of another row allows: one more than its
/// radius where it holds `mine[x]`'s material, else 0.
fn fold<T: Copy + PartialEq>(cross: &mut [u8], mine: &[T], theirs: &[T], radii: &[u8]) {
    for (((c, &m), &t), &r) in cross.iter_mut().zip(mine).zip(theirs).zip(radii) {
        let allowed = if t == m { r.saturating_add(1) } else { 0 };
        *c = (*c).min(allowed);
    }
}
