//! The proximity traversal: the DDA over the dense grid with, beside each voxel's
//! material, the radius of the largest cube around the voxel that holds that material
//! only, so that a ray in that material leaves the whole cube in one step. These are
//! the proximity clouds of D. Cohen and Z. Sheffer, "Proximity clouds - an acceleration
//! technique for 3D grid traversal", The Visual Computer 11(1), 1994, with voxlab's hit
//! rule: a cube of any one material is skipped by a ray in that material, not only
//! empty space.
//!
//! Where the sparse tree descends its levels at every step (on a SIMD device every
//! level, whatever the lane needs), this walk reads one word a step, as the dense walk
//! does, and skips with the same exact exit (`dda_skip`, `crate::dda::Dda`), so its
//! hits, normals and images are the dense walk's. It costs two bytes a voxel (material
//! and radius) in place of the dense walk's one, and needs the dense grid.
//!
//! The radius of voxel `v` is its Chebyshev (L-infinity) distance to the nearest voxel
//! of the grid with a 26-neighbour of another material, capped at [`MAX_RADIUS`]. Such a
//! voxel `b` at distance `r` makes every voxel nearer than `r` of `v`'s material, so the
//! cube of radius `r` holds only that material: the nearest voxel of another material
//! lies at `r + 1`, and the voxel before it on the way has it as a neighbour. The
//! distances come from three 1D passes, one per axis, of Meijster, Roerdink and
//! Hesselink's linear-time transform (the Chebyshev distance is separable), each line
//! on a thread of its own (`tests/proximity.rs` checks them against brute force).

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;

use super::TraversalModel;
use crate::scene::Grid;
use crate::sparse::{Region, Regions};

/// The largest radius stored (one byte). A larger cube is skipped in several steps.
pub const MAX_RADIUS: u8 = 255;

/// The grid side from which `render.traversal = "auto"` walks the proximity field
/// where the octant field ([`super::octant`], registered after it, whose claim wins
/// where the device binds it) does not fit, up to the sparse walk's
/// [`super::sparse::SPARSE_FROM_SIDE`]. On lavapipe the seed scene renders at 0.75x the
/// dense walk's speed at 16^3, where a walk is a few steps and a skip costs more than
/// a step, at 1.48x at 64^3 and 3.23x at 256^3 (docs/sparse-traversal.md, "Speed
/// now"). On lavapipe every grid below that side binds the octant field, so "auto"
/// takes this walk only on a device that binds less; one whose field it cannot bind
/// either is left to the dense grid's buffer, then the tree (`crate::gpu`).
pub(crate) const PROXIMITY_FROM_SIDE: u32 = 64;

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "proximity",
    summary: "the DDA over the dense grid with each voxel's largest cube of its own \
              material, skipping each cube of the ray's medium whole (proximity clouds, \
              Cohen and Sheffer 1994)",
    label: "proximity clouds",
    plan: |scene, _| {
        super::dense_grid_only(scene, "the dense grid with a radius beside each voxel")
    },
    auto: Some(|scene| super::claim_dense_from_side(scene, PROXIMITY_FROM_SIDE)),
    wgsl: (
        "shaders/traversal_proximity.wgsl",
        include_str!("../../shaders/traversal_proximity.wgsl"),
    ),
    walks_tree: false,
    descent_levels: None,
    data: Some(|grid, _| Arc::new(ProximityField::build(grid))),
    // Two bytes a voxel.
    device_bytes: Some(|dims| super::per_voxel_bytes(dims, 2)),
};

/// Every voxel's material and radius, two bytes a voxel: voxel `i` (x fastest) in the
/// half `i % 2` of word `i / 2`, material in its low byte, radius in its high byte. The
/// kernel reads these words (`walk_data`, shaders/traversal_proximity.wgsl).
#[derive(Clone, Debug, PartialEq)]
pub struct ProximityField {
    dims: UVec3,
    words: Vec<u32>,
}

impl ProximityField {
    /// The field of `grid` (a grid held only as its tree is made dense first; the plan
    /// keeps this traversal from such grids).
    pub fn build(grid: &Grid) -> Self {
        let dense = grid
            .to_dense()
            .expect("the proximity traversal's plan rule keeps it to dense grids");
        let dims = grid.dims();
        let voxels = dense.data();
        let radii = radii(voxels, dims);
        let mut words = vec![0u32; voxels.len().div_ceil(2)];
        words.par_iter_mut().enumerate().for_each(|(w, word)| {
            for half in 0..2 {
                let i = 2 * w + half;
                if i < voxels.len() {
                    let voxel = voxels[i] as u32 | (radii[i] as u32) << 8;
                    *word |= voxel << (16 * half);
                }
            }
        });
        Self { dims, words }
    }

    fn voxel(&self, v: IVec3) -> (u8, u8) {
        let d = self.dims.as_usizevec3();
        let i = v.x as usize + d.x * (v.y as usize + d.y * v.z as usize);
        let half = self.words[i / 2] >> (16 * (i % 2));
        (half as u8, (half >> 8) as u8)
    }

    /// The radius of voxel `v` (inside the grid): its cube `v +- radius` holds only
    /// its material.
    pub fn radius(&self, v: IVec3) -> u8 {
        self.voxel(v).1
    }

    /// Bytes per voxel of the grid's box.
    pub fn bytes_per_voxel(&self) -> f64 {
        (self.words.len() * 4) as f64 / self.dims.as_dvec3().element_product()
    }
}

impl Regions for ProximityField {
    fn region(&self, v: IVec3, _step: IVec3) -> Region {
        let (material, r) = self.voxel(v);
        let r = IVec3::splat(r as i32);
        Region {
            material,
            lo: (v - r).max(IVec3::ZERO),
            hi: (v + r + 1).min(self.dims.as_ivec3()),
        }
    }

    fn device_words(&self) -> Vec<&[u32]> {
        vec![&self.words]
    }
}

/// What the 1D pass keeps between lines: the lower envelope's indices and where each
/// starts, the line's input, and a column gathered from a plane.
#[derive(Default)]
struct LineScratch {
    input: Vec<u8>,
    at: Vec<i32>,
    from: Vec<i32>,
    column: Vec<u8>,
}

impl LineScratch {
    /// [`Self::pass`] down each of the `width` columns of `plane` (rows of `width`).
    fn pass_columns(&mut self, plane: &mut [u8], width: usize) {
        let mut column = std::mem::take(&mut self.column);
        for x in 0..width {
            column.clear();
            column.extend(plane[x..].iter().step_by(width));
            self.pass(&mut column);
            for (out, d) in plane[x..].iter_mut().step_by(width).zip(&column) {
                *out = *d;
            }
        }
        self.column = column;
    }

    /// `line[x] = min over i of max(|x - i|, line[i])`: the Chebyshev distance along one
    /// axis, given the distances over the other axes already taken, by the lower-envelope
    /// scan of A. Meijster, J. Roerdink and W. Hesselink, "A general algorithm for
    /// computing distance transforms in linear time" (Mathematical Morphology and its
    /// Applications to Image and Signal Processing, 2000), with its Sep for the
    /// chessboard metric: the last x at which i's function is at most u's (i < u).
    /// Values stay capped at [`MAX_RADIUS`], exactly: min(., cap) commutes with the pass.
    fn pass(&mut self, line: &mut [u8]) {
        let n = line.len() as i32;
        // A line without a seed within the cap stays as it is (most lines of empty space).
        if line.iter().all(|&d| d == MAX_RADIUS) {
            return;
        }
        self.input.clear();
        self.input.extend_from_slice(line);
        let h = |i: i32| i32::from(self.input[i as usize]);
        let f = |x: i32, i: i32| (x - i).abs().max(h(i));
        let sep = |i: i32, u: i32| {
            if h(i) <= h(u) {
                (i + h(u)).max((i + u) / 2)
            } else {
                (u - h(i)).min((i + u) / 2)
            }
        };
        let (at, from) = (&mut self.at, &mut self.from);
        at.clear();
        from.clear();
        at.push(0);
        from.push(0);
        for u in 1..n {
            while let (Some(&i), Some(&t)) = (at.last(), from.last()) {
                if f(t, i) > f(t, u) {
                    at.pop();
                    from.pop();
                } else {
                    break;
                }
            }
            match at.last() {
                None => {
                    at.push(u);
                    from.push(0);
                }
                Some(&i) => {
                    let w = 1 + sep(i, u);
                    if w < n {
                        at.push(u);
                        from.push(w);
                    }
                }
            }
        }
        let mut q = at.len() - 1;
        for x in (0..n).rev() {
            line[x as usize] = f(x, at[q]).min(i32::from(MAX_RADIUS)) as u8;
            if x == from[q] && q > 0 {
                q -= 1;
            }
        }
    }
}

/// Each voxel's Chebyshev distance to the nearest voxel with a 26-neighbour of another
/// material, capped at [`MAX_RADIUS`] (see the module documentation).
pub fn radii(voxels: &[u8], dims: UVec3) -> Vec<u8> {
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let slice = nx * ny;
    // Seeds: the voxels with a neighbour of another material (outside the grid is no
    // neighbour: the walks end there by their own test). Whether a voxel's 3x3x3 block
    // holds its material only is separable too: its row of three along x does, then
    // the three such rows along y, then the three such planes along z (each pass with
    // the neighbours' materials, which must be the voxel's). `r` holds the rows' flags,
    // `block` the planes', and then `r` the seeds.
    let mut r = vec![0u8; voxels.len()];
    let mut block = vec![0u8; voxels.len()];
    r.par_chunks_mut(nx.max(1))
        .zip(voxels.par_chunks(nx.max(1)))
        .for_each(|(out, row)| {
            for x in 0..nx {
                let m = row[x];
                let uniform = (x == 0 || row[x - 1] == m) && (x + 1 == nx || row[x + 1] == m);
                out[x] = u8::from(uniform);
            }
        });
    block
        .par_chunks_mut(slice.max(1))
        .zip(r.par_chunks(slice.max(1)))
        .zip(voxels.par_chunks(slice.max(1)))
        .for_each(|((out, rows), plane)| {
            for y in 0..ny {
                for x in 0..nx {
                    let i = x + nx * y;
                    let m = plane[i];
                    let near = |j: usize| rows[j] == 1 && plane[j] == m;
                    out[i] = u8::from(
                        near(i) && (y == 0 || near(i - nx)) && (y + 1 == ny || near(i + nx)),
                    );
                }
            }
        });
    r.par_chunks_mut(slice.max(1))
        .enumerate()
        .for_each(|(z, out)| {
            for (k, o) in out.iter_mut().enumerate() {
                let i = k + slice * z;
                let m = voxels[i];
                let near = |j: usize| block[j] == 1 && voxels[j] == m;
                let uniform =
                    near(i) && (z == 0 || near(i - slice)) && (z + 1 == nz || near(i + slice));
                *o = if uniform { MAX_RADIUS } else { 0 };
            }
        });
    // The distance to the nearest seed is separable (Chebyshev: the largest of the
    // three axis distances), so three passes of a 1D transform, one axis after the
    // other, each line independent of the others and the lines spread over the threads.
    // With the seeds found by the separable test above, the seed scene's 256^3 field
    // builds in 307 to 340 ms instead of 676 on two cores (`voxlab bench --sizes 256
    // --size 64 --no-cpu --traversal proximity`, build ms), where the chamfer
    // transform's two raster passes and a 27-voxel test per voxel ran before.
    // Along x every distance is 0 or the cap, so each is the distance to the nearest
    // seed of its row: one sweep each way (what the general pass gives, faster).
    r.par_chunks_mut(nx.max(1)).for_each(|row| {
        let mut d = MAX_RADIUS;
        for v in row.iter_mut() {
            d = if *v == 0 { 0 } else { d.saturating_add(1) };
            *v = d;
        }
        let mut d = MAX_RADIUS;
        for v in row.iter_mut().rev() {
            d = if *v == 0 {
                0
            } else {
                d.saturating_add(1).min(*v)
            };
            *v = d;
        }
    });
    r.par_chunks_mut(slice.max(1))
        .for_each_init(LineScratch::default, |scratch, plane| {
            scratch.pass_columns(plane, nx)
        });
    // Along z through a copy of the grid in (x, z, y) order: a y's rows are read whole
    // and its lines along z passed in a block of their own, then written back row by row.
    let mut lines = block;
    lines
        .par_chunks_mut((nx * nz).max(1))
        .enumerate()
        .for_each_init(LineScratch::default, |scratch, (y, plane)| {
            for z in 0..nz {
                let row = nx * (y + ny * z);
                plane[nx * z..nx * (z + 1)].copy_from_slice(&r[row..row + nx]);
            }
            scratch.pass_columns(plane, nx);
        });
    r.par_chunks_mut(slice.max(1))
        .enumerate()
        .for_each(|(z, plane)| {
            for y in 0..ny {
                let from = nx * (z + nz * y);
                plane[nx * y..nx * (y + 1)].copy_from_slice(&lines[from..from + nx]);
            }
        });
    r
}
