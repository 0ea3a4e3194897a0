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
//! does, and skips with the same exact exit (`dda_skip`, `crate::cpu::Dda`), so its
//! hits, normals and images are the dense walk's. It costs two bytes a voxel (material
//! and radius) in place of the dense walk's one, and needs the dense grid.
//!
//! The radius of voxel `v` is its Chebyshev (L-infinity) distance to the nearest voxel
//! of the grid with a 26-neighbour of another material, capped at [`MAX_RADIUS`]. Such a
//! voxel `b` at distance `r` makes every voxel nearer than `r` of `v`'s material, so the
//! cube of radius `r` holds only that material: the nearest voxel of another material
//! lies at `r + 1`, and the voxel before it on the way has it as a neighbour. The
//! distances come from the two raster passes of a chamfer transform with unit weights
//! over the 26-neighbourhood, exact for the Chebyshev metric (G. Borgefors, "Distance
//! transformations in digital images", CVGIP 34, 1986; `tests/proximity.rs` checks it
//! against brute force).

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;

use super::TraversalModel;
use crate::scene::Grid;
use crate::sparse::{Region, Regions};

/// The largest radius stored (one byte). A larger cube is skipped in several steps.
pub const MAX_RADIUS: u8 = 255;

/// The grid side from which `render.traversal = "auto"` walks the proximity field
/// (up to the sparse walk's [`super::sparse::SPARSE_FROM_SIDE`], registered after it,
/// whose claim wins). On lavapipe the seed scene renders at 0.80x the dense walk's
/// speed at 16^3, where a walk is a few steps and a skip costs more than a step, at
/// 1.47x at 64^3 and 3.39x at 256^3 (README "Sparse traversal", "Speed now"). A field
/// larger than the device binds as one buffer (lavapipe: 128 MiB, 64 M voxels) is
/// left to the tree under "auto" (`crate::gpu`).
pub const PROXIMITY_FROM_SIDE: u32 = 64;

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "proximity",
    summary: "the DDA over the dense grid with each voxel's largest cube of its own \
              material, skipping each cube of the ray's medium whole (proximity clouds, \
              Cohen and Sheffer 1994)",
    label: "proximity clouds",
    plan: |scene, _| {
        super::dense_grid_only(scene, "the dense grid with a radius beside each voxel")
    },
    auto: Some(|scene| {
        super::dense_grid_only(scene, "the dense grid")?;
        super::claim_from_side(scene, PROXIMITY_FROM_SIDE)
    }),
    wgsl: (
        "shaders/traversal_proximity.wgsl",
        include_str!("../../shaders/traversal_proximity.wgsl"),
    ),
    walks_tree: false,
    data: Some(|grid| Arc::new(ProximityField::build(grid))),
    // Two bytes a voxel, in whole vec4<u32>s.
    device_bytes: Some(|dims| (2 * dims.as_u64vec3().element_product()).next_multiple_of(16)),
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
    fn region(&self, v: IVec3) -> Region {
        let (material, r) = self.voxel(v);
        let r = IVec3::splat(r as i32);
        Region {
            material,
            lo: (v - r).max(IVec3::ZERO),
            hi: (v + r + 1).min(self.dims.as_ivec3()),
        }
    }

    fn device_words(&self) -> &[u32] {
        &self.words
    }
}

/// Each voxel's Chebyshev distance to the nearest voxel with a 26-neighbour of another
/// material, capped at [`MAX_RADIUS`] (see the module documentation).
pub fn radii(voxels: &[u8], dims: UVec3) -> Vec<u8> {
    let (nx, ny, nz) = (dims.x as usize, dims.y as usize, dims.z as usize);
    let slice = nx * ny;
    let mut r = vec![MAX_RADIUS; voxels.len()];
    // Seeds: the voxels with a neighbour of another material (outside the grid is no
    // neighbour: the walks end there by their own test).
    r.par_chunks_mut(slice.max(1))
        .enumerate()
        .for_each(|(z, out)| {
            for y in 0..ny {
                for x in 0..nx {
                    let m = voxels[x + nx * (y + ny * z)];
                    let mut seed = false;
                    'n: for zz in z.saturating_sub(1)..(z + 2).min(nz) {
                        for yy in y.saturating_sub(1)..(y + 2).min(ny) {
                            let row = nx * (yy + ny * zz);
                            for xx in x.saturating_sub(1)..(x + 2).min(nx) {
                                if voxels[row + xx] != m {
                                    seed = true;
                                    break 'n;
                                }
                            }
                        }
                    }
                    if seed {
                        out[x + nx * y] = 0;
                    }
                }
            }
        });
    // The forward pass takes the 13 neighbours before a voxel in raster order, the
    // backward pass the 13 after it. Voxels off the grid's faces read them by index
    // offset; those on a face check each neighbour.
    let before: Vec<IVec3> = (-1..=1)
        .flat_map(|z| (-1..=1).flat_map(move |y| (-1..=1).map(move |x| IVec3::new(x, y, z))))
        .filter(|o| (o.z, o.y, o.x) < (0, 0, 0))
        .collect();
    let size = IVec3::new(nx as i32, ny as i32, nz as i32);
    for sign in [1, -1] {
        let offsets: Vec<IVec3> = before.iter().map(|o| *o * sign).collect();
        let steps: Vec<isize> = offsets
            .iter()
            .map(|o| o.x as isize + nx as isize * (o.y as isize + ny as isize * o.z as isize))
            .collect();
        let order = |n: usize| -> Box<dyn Iterator<Item = usize>> {
            if sign > 0 {
                Box::new(0..n)
            } else {
                Box::new((0..n).rev())
            }
        };
        for z in order(nz) {
            for y in order(ny) {
                let inner_row = z > 0 && z + 1 < nz && y > 0 && y + 1 < ny;
                for x in order(nx) {
                    let i = x + nx * (y + ny * z);
                    if r[i] == 0 {
                        continue;
                    }
                    let mut best = r[i];
                    if inner_row && x > 0 && x + 1 < nx {
                        for &step in &steps {
                            best = best.min(r[(i as isize + step) as usize].saturating_add(1));
                        }
                    } else {
                        let v = IVec3::new(x as i32, y as i32, z as i32);
                        for (o, &step) in offsets.iter().zip(&steps) {
                            let u = v + *o;
                            if u.cmpge(IVec3::ZERO).all() && u.cmplt(size).all() {
                                best = best.min(r[(i as isize + step) as usize].saturating_add(1));
                            }
                        }
                    }
                    r[i] = best;
                }
            }
        }
    }
    r
}
