//! The box traversal: the octant walk ([`super::octant`]) with a reach per axis. Beside
//! each voxel's material, for each of the eight octants a ray can head into, a box of
//! the voxel's material with the voxel as its corner that reaches into that octant as
//! far along each axis as the build finds room. A cube toward the ray's octant is only
//! as large as the nearest surface on any axis, so a ray grazing a wall crosses it in
//! cubes no larger than its height above the wall; a box thin across the wall and long
//! along it takes such a ray to the wall, or past it, in a step or two.
//!
//! The boxes come from the corner cubes (`octant_radii`) by three extensions, one axis
//! after another. The box of reach `e` along axis `a` and the cube's `c` across it is
//! the union of the cubes of side `c + 1` at `v + j s e_a`, `j = 0 ..= e - c` (`s` the
//! octant's sign on `a`), so it holds `v`'s material when those voxels have it and
//! their cubes are at least `c`: the first `j` where one does not ends it (a "next
//! smaller element", one stack per line). The second axis extends the union of such
//! boxes, which holds where both keys (cube, first reach) stay at least `v`'s, and the
//! third where all three do: each extension is a linear pass over the lines of its
//! axis, and each box holds only `v`'s material and its corner cube (every reach starts
//! from the cube's). The order is z, x, y: on the seed scene and the bunny the other
//! orders, and the largest box of all three orders, take the CPU walk within 1 % of the
//! same steps, and a search of each voxel's largest boxes by summed-volume tables
//! (largest cube, then each axis stretched as far as it goes, the largest of three
//! orders) within 2 % (docs/sparse-traversal.md, "Boxes").
//!
//! Four bits a reach ([`REACHES`]), twelve an octant: the words are four planes of a
//! word a voxel, plane `p` holding octants `2p` and `2p + 1` beside the voxel's
//! material, so a step reads one word, and the rays of an octant read one plane of four
//! bytes a voxel as the octant walk does.

use std::sync::Arc;

use glam::{IVec3, UVec3};
use rayon::prelude::*;

use super::TraversalModel;
use super::octant::{corner_box, octant, octant_radii};
use crate::scene::Grid;
use crate::sparse::{Region, Regions};

/// The reaches a box's four-bit codes stand for along an axis: each box's reach is the
/// largest entry not above what the build found, so a box only shrinks. Entry `k` is
/// `k` below 2, else `(2 + k % 2) << (k / 2 - 1)` (shaders/traversal_boxes.wgsl).
pub const REACHES: [u8; 16] = [0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64, 96, 128, 192];

/// The grid side from which `render.traversal = "auto"` walks the box field (up to the
/// tree walks' [`super::sparse::SPARSE_FROM_SIDE`], whose claims, registered after it,
/// win from there). On lavapipe, 512x512, one round of `voxlab bench --sizes 8,12,16,64
/// --size 512 --gpu-runs 3 --no-cpu --traversal dense,octant,boxes` (both rule sets,
/// the second with `--rules seed`): at 8^3 the dense walk's time within the noise
/// (231.2 against 227.1 ms; the seed's rules 54.7 against 56.5), at 12^3 0.85x the
/// dense walk's (374.9 against 442.6; 66.8 against 76.4) and 0.78x the octant walk's,
/// at 16^3 0.77x and 0.84x the octant walk's, at 64^3 0.65x and 0.80x
/// (docs/sparse-traversal.md, "Boxes"). Where the device cannot bind its sixteen bytes
/// a voxel (lavapipe: 128 MiB, 8.4 M voxels, 203^3) `"auto"` takes the next walk that
/// claims the grid and fits, the octant field (`crate::plan::auto_traversal_within`).
pub const BOXES_FROM_SIDE: u32 = 12;

pub const TRAVERSAL: TraversalModel = TraversalModel {
    name: "boxes",
    summary: "the DDA over the dense grid with each voxel's box of its own material with \
              the voxel as its corner toward each of the 8 ray octants, a reach per axis, \
              skipping the ray's octant's box whole (the octant walk's cubes stretched \
              along the axes they leave room on)",
    label: "octant boxes",
    plan: |scene, _| super::dense_grid_only(scene, "the dense grid with 8 boxes beside each voxel"),
    auto: Some(|scene| super::claim_dense_from_side(scene, BOXES_FROM_SIDE)),
    wgsl: (
        "shaders/traversal_boxes.wgsl",
        include_str!("../../shaders/traversal_boxes.wgsl"),
    ),
    walks_tree: false,
    descent_levels: None,
    data: Some(|grid, _| Arc::new(BoxField::build(grid))),
    // Four planes of a word a voxel.
    device_bytes: Some(|dims| super::per_voxel_bytes(dims, 16)),
};

/// Every voxel's material and its eight boxes' codes: four planes of a word a voxel
/// (x fastest), plane `p` holding the voxel's material in bits 0..8, octant `2p`'s box
/// in bits 8..20 and octant `2p + 1`'s in bits 20..32; a box's code holds the four-bit
/// codes of its reaches along x, y and z, lowest first. Octant `o` has bit `a` set where
/// it heads down axis `a` ([`octant`]).
#[derive(Clone, Debug, PartialEq)]
pub struct BoxField {
    dims: UVec3,
    words: Vec<u32>,
}

/// The four-bit code of each reach 0..=255: the largest entry of [`REACHES`] not above
/// it.
static CODES: [u8; 256] = {
    let mut codes = [0u8; 256];
    let mut r = 0;
    while r < 256 {
        let mut k = 0;
        while k + 1 < REACHES.len() && REACHES[k + 1] as usize <= r {
            k += 1;
        }
        codes[r] = k as u8;
        r += 1;
    }
    codes
};

/// Where octant `o`'s box code sits in its plane's word (plane `o / 2`): from bit 8 for
/// an even octant, from bit 20 for an odd one, above the material's byte (WGSL
/// `box_codes::plane_shift`). The box field's voxels and the sparse octant walk's
/// children below its cut are such words.
fn plane_shift(o: usize) -> u32 {
    8 + 12 * (o as u32 & 1)
}

/// Octant `o`'s box code `code` placed in its plane's word ([`plane_shift`]).
pub(crate) fn plane_bits(code: u16, o: usize) -> u32 {
    u32::from(code) << plane_shift(o)
}

/// The reaches of octant `o`'s box in its plane's word ([`plane_shift`]).
pub(crate) fn word_reach(word: u32, o: usize) -> IVec3 {
    reaches(word >> plane_shift(o))
}

/// The twelve-bit code of a box of these reaches (each 0 to 255), each rounded down to
/// [`REACHES`].
pub(crate) fn box_code(reach: IVec3) -> u16 {
    (0..3).fold(0, |code, a| {
        code | u16::from(CODES[reach[a] as usize]) << (4 * a)
    })
}

/// The reaches a box's twelve-bit code stands for (the lowest twelve bits of `code`).
pub(crate) fn reaches(code: u32) -> IVec3 {
    IVec3::from_array([0, 4, 8].map(|s| i32::from(REACHES[(code >> s & 15) as usize])))
}

impl BoxField {
    /// The field of `grid` (a grid held only as its tree is made dense first; the plan
    /// keeps this traversal from such grids).
    pub fn build(grid: &Grid) -> Self {
        let dense = grid
            .to_dense()
            .expect("the box traversal's plan rule keeps it to dense grids");
        let dims = grid.dims();
        let voxels = dense.data();
        let codes: Vec<Vec<u16>> = (0..8)
            .into_par_iter()
            .map(|o| octant_boxes(voxels, dims, o))
            .collect();
        let n = voxels.len();
        let mut words = vec![0u32; 4 * n];
        words
            .par_chunks_mut(n.max(1))
            .enumerate()
            .for_each(|(p, plane)| {
                for (i, w) in plane.iter_mut().enumerate() {
                    *w = u32::from(voxels[i])
                        | plane_bits(codes[2 * p][i], 2 * p)
                        | plane_bits(codes[2 * p + 1][i], 2 * p + 1);
                }
            });
        Self { dims, words }
    }

    /// The reaches of voxel `v`'s box toward octant `o`, as the walk reads them.
    pub fn reach(&self, v: IVec3, o: usize) -> IVec3 {
        word_reach(self.word(v, o), o)
    }

    /// The word of voxel `v` in octant `o`'s plane: its material and the codes of
    /// octant `o`'s box and its plane's other octant's.
    fn word(&self, v: IVec3, o: usize) -> u32 {
        let d = self.dims.as_usizevec3();
        let i = v.x as usize + d.x * (v.y as usize + d.y * v.z as usize);
        self.words[(o >> 1) * d.element_product() + i]
    }
}

impl Regions for BoxField {
    fn region(&self, v: IVec3, step: IVec3) -> Region {
        let o = octant(step);
        let (lo, hi) = corner_box(v, self.reach(v, o), o);
        Region {
            material: self.word(v, o) as u8,
            lo: lo.max(IVec3::ZERO),
            hi: hi.min(self.dims.as_ivec3()),
        }
    }

    fn device_words(&self) -> Vec<&[u32]> {
        vec![&self.words]
    }
}

/// Each voxel's box toward octant `o` as its twelve-bit code: the corner cube stretched
/// along z, then x, then y (see the module documentation), each reach rounded down to
/// [`REACHES`].
pub fn octant_boxes<T: Copy + PartialEq + Sync>(voxels: &[T], dims: UVec3, o: usize) -> Vec<u16> {
    let cube = octant_radii(voxels, dims, o);
    stretch(&cube, |axis, keys| {
        extend(voxels, dims, o, axis, keys, &cube)
    })
}

/// The boxes of the corner cubes `cube` as twelve-bit codes: each cube stretched along
/// z, then x, then y (the order the module documentation gives) by `extend(axis, keys)`,
/// the reaches along `axis` of the union of the boxes of the given keys (the cube, and
/// the reaches along the axes stretched before): the box field's [`extend`] over a
/// grid, or the sparse octant walk's over a level's nodes.
pub(crate) fn stretch(cube: &[u8], extend: impl Fn(usize, &[&[u8]]) -> Vec<u8>) -> Vec<u16> {
    let [x, y, z] = [0, 1, 2];
    let along_z = extend(z, &[cube]);
    let along_x = extend(x, &[cube, &along_z]);
    let along_y = extend(y, &[cube, &along_z, &along_x]);
    along_x
        .iter()
        .zip(&along_y)
        .zip(&along_z)
        .map(|((&x, &y), &z)| box_code(IVec3::new(x.into(), y.into(), z.into())))
        .collect()
}

/// Each voxel's reach along `axis` toward octant `o` of the union of the boxes, at
/// `v + j s e_axis`, that hold `v`'s box of the given `keys` (reaches along the other
/// axes, and the cube's `cube` across): the union holds `v`'s material while each voxel
/// on the way has `v`'s material and every key at least `v`'s, so the first `j >= 1`
/// where one does not ends it (a "next smaller element" per key, one stack per key and
/// line). A line that never ends reaches past the grid: 255, as far as a byte goes.
/// The lines of a slab (or, along z, of a row of x) are swept side by side, so that a
/// thread's stacks are allocated once and a step along y or z reads contiguous voxels.
fn extend<T: Copy + PartialEq + Sync>(
    voxels: &[T],
    dims: UVec3,
    o: usize,
    axis: usize,
    keys: &[&[u8]],
    cube: &[u8],
) -> Vec<u8> {
    let d = dims.as_usizevec3();
    let line = Line {
        voxels,
        keys,
        cube,
        n: d[axis],
        down: o >> axis & 1 == 1,
    };
    let mut reach = vec![0u8; voxels.len()];
    let slab = d.x * d.y;
    match axis {
        // A slab's rows side by side (a row's voxels contiguous, the rows' voxels of
        // one x a row apart), laid [x][y], then put in place.
        0 => reach.par_chunks_mut(slab).enumerate().for_each_init(
            || (Stacks::new(keys.len(), d.y, d.x), vec![0u8; slab]),
            |(stacks, swept), (z, out)| {
                line.sweep(z * slab, (d.y, d.x), 1, stacks, swept);
                for (x, column) in swept.chunks(d.y).enumerate() {
                    for (y, &r) in column.iter().enumerate() {
                        out[y * d.x + x] = r;
                    }
                }
            },
        ),
        // A slab's columns side by side: its reaches laid [y][x], as the grid's.
        1 => reach.par_chunks_mut(slab).enumerate().for_each_init(
            || Stacks::new(keys.len(), d.x, d.y),
            |stacks, (z, out)| line.sweep(z * slab, (d.x, 1), d.x, stacks, out),
        ),
        // A row of x's lines along z side by side, laid [z][x], then put in place.
        _ => {
            let sheets: Vec<Vec<u8>> = (0..d.y)
                .into_par_iter()
                .map_init(
                    || Stacks::new(keys.len(), d.x, d.z),
                    |stacks, y| {
                        let mut out = vec![0u8; d.x * d.z];
                        line.sweep(y * d.x, (d.x, 1), slab, stacks, &mut out);
                        out
                    },
                )
                .collect();
            for (y, sheet) in sheets.iter().enumerate() {
                for (z, row) in sheet.chunks(d.x).enumerate() {
                    reach[z * slab + y * d.x..][..d.x].copy_from_slice(row);
                }
            }
        }
    }
    reach
}

/// The reaches of [`extend`] along `lanes` lines of `n` cells laid side by side
/// (`cells[t * lanes + lane]`, `t` the position along the lines, increasing along the
/// axis; the keys and the corner cubes alike) into `out`, laid so: for the lines of a
/// sparse walk's level, whose nodes are not one grid (`crate::technique::sparse_octant`).
/// A line that never ends reaches 255: the caller ends a line where its cells do by a
/// cell that matches none of them.
#[allow(clippy::too_many_arguments)]
pub(crate) fn sweep_lanes<T: Copy + PartialEq>(
    cells: &[T],
    keys: &[&[u8]],
    cube: &[u8],
    (lanes, n): (usize, usize),
    down: bool,
    stacks: &mut Stacks,
    out: &mut [u8],
) {
    let line = Line {
        voxels: cells,
        keys,
        cube,
        n,
        down,
    };
    line.sweep(0, (lanes, 1), lanes, stacks, out);
}

/// What [`extend`] sweeps: the grid, the keys, the corner cubes, the lines' length and
/// whether the octant heads down the axis.
struct Line<'a, T> {
    voxels: &'a [T],
    keys: &'a [&'a [u8]],
    cube: &'a [u8],
    n: usize,
    down: bool,
}

/// The stacks of `lanes` lines of `n` voxels for each key (positions and keys, the
/// lines' entries of one depth side by side: `[key][depth][line]`), kept between
/// sweeps so that a thread allocates them once; they serve any shorter lines too.
pub(crate) struct Stacks {
    at: Vec<u32>,
    kept: Vec<u8>,
    depth: Vec<usize>,
    differs_at: Vec<u32>,
    ends: Vec<u32>,
}

impl Stacks {
    pub(crate) fn new(keys: usize, lanes: usize, n: usize) -> Self {
        Self {
            at: vec![0; keys * lanes * n],
            kept: vec![0; keys * lanes * n],
            depth: vec![0; keys * lanes],
            differs_at: vec![0; lanes],
            ends: vec![0; lanes],
        }
    }
}

impl<T: Copy + PartialEq> Line<'_, T> {
    /// The reaches of `lanes` lines side by side from voxel `base` (a line's voxels
    /// `stride` apart, the lines' first voxels `lane_stride` apart) into `out`, laid
    /// `[position][line]`.
    fn sweep(
        &self,
        base: usize,
        (lanes, lane_stride): (usize, usize),
        stride: usize,
        s: &mut Stacks,
        out: &mut [u8],
    ) {
        let n = self.n;
        s.depth.fill(0);
        // Per line: the nearest position toward the octant of another material than
        // the voxel's, and how far the union goes before its first end.
        s.differs_at.fill(u32::MAX);
        // From the octant's far end, so what lies toward the octant is done first.
        let position = |k: usize| if self.down { k } else { n - 1 - k };
        let at_lane = |t: usize, lane: usize| base + t * stride + lane * lane_stride;
        for k in 0..n {
            let t = position(k);
            if k > 0 {
                let before = position(k - 1);
                for (lane, at) in s.differs_at.iter_mut().enumerate() {
                    if self.voxels[at_lane(t, lane)] != self.voxels[at_lane(before, lane)] {
                        *at = before as u32;
                    }
                }
            }
            for (e, &at) in s.ends.iter_mut().zip(&s.differs_at) {
                *e = if at == u32::MAX {
                    u32::MAX
                } else {
                    at.abs_diff(t as u32)
                };
            }
            for (key_index, key) in self.keys.iter().enumerate() {
                let at = &mut s.at[key_index * n * lanes..][..n * lanes];
                let kept = &mut s.kept[key_index * n * lanes..][..n * lanes];
                let depth = &mut s.depth[key_index * lanes..][..lanes];
                for lane in 0..lanes {
                    let mine = key[at_lane(t, lane)];
                    let mut h = depth[lane];
                    while h > 0 && kept[(h - 1) * lanes + lane] >= mine {
                        h -= 1;
                    }
                    if h > 0 {
                        let j = at[(h - 1) * lanes + lane].abs_diff(t as u32);
                        s.ends[lane] = s.ends[lane].min(j);
                    }
                    at[h * lanes + lane] = t as u32;
                    kept[h * lanes + lane] = mine;
                    depth[lane] = h + 1;
                }
            }
            for (lane, (o, &e)) in out[t * lanes..][..lanes]
                .iter_mut()
                .zip(&s.ends)
                .enumerate()
            {
                let c = self.cube[at_lane(t, lane)];
                *o = if e == u32::MAX {
                    255
                } else {
                    (u32::from(c) + e - 1).min(255) as u8
                };
            }
        }
    }
}
