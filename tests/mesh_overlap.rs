//! The triangle/box separating-axis test (Akenine-Möller 2001) against independent
//! oracles, and the voxelizer's bounding-box iteration against brute force.
//!
//! Oracles:
//! - clipping: the triangle, clipped by the six half-spaces of the box (Sutherland-
//!   Hodgman), is non-empty exactly when they intersect. Exact in both directions up
//!   to rounding, so it is asked with the box shrunk (a "yes" there must be a yes) and
//!   grown (a "no" there must be a no) by 1e-9.
//! - sampling (one direction each): a point of the triangle inside the box proves
//!   overlap; all eight box corners strictly on one side of the triangle's plane, or
//!   the triangle beyond one box face, prove separation.

use glam::{DVec3, IVec3, UVec3};
use voxlab::scene::Grid;
use voxlab::scene::voxelize::{tri_box_overlap, voxelize_triangles};

/// SplitMix64: a tiny deterministic generator, so the tests need no RNG crate API.
struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    fn f(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f()
    }
    fn vec(&mut self, lo: f64, hi: f64) -> DVec3 {
        DVec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
}

/// Clips the polygon against `p[axis] >= bound` (sign +1) or `p[axis] <= bound` (-1).
fn clip(poly: &[DVec3], axis: usize, bound: f64, sign: f64) -> Vec<DVec3> {
    let inside = |p: DVec3| sign * (p[axis] - bound) >= 0.0;
    let mut out = Vec::new();
    for i in 0..poly.len() {
        let p = poly[i];
        let q = poly[(i + 1) % poly.len()];
        match (inside(p), inside(q)) {
            (true, true) => out.push(q),
            (true, false) | (false, true) => {
                let t = (bound - p[axis]) / (q[axis] - p[axis]);
                let mut x = p + (q - p) * t;
                x[axis] = bound;
                out.push(x);
                if inside(q) {
                    out.push(q);
                }
            }
            (false, false) => {}
        }
    }
    out
}

fn clip_oracle(lo: DVec3, hi: DVec3, tri: [DVec3; 3]) -> bool {
    let mut poly = tri.to_vec();
    for axis in 0..3 {
        poly = clip(&poly, axis, lo[axis], 1.0);
        poly = clip(&poly, axis, hi[axis], -1.0);
        if poly.is_empty() {
            return false;
        }
    }
    true
}

fn sample_proves_overlap(lo: DVec3, hi: DVec3, tri: [DVec3; 3], rng: &mut Rng) -> bool {
    (0..400).any(|_| {
        let (mut a, mut b) = (rng.f(), rng.f());
        if a + b > 1.0 {
            (a, b) = (1.0 - a, 1.0 - b);
        }
        let p = tri[0] + a * (tri[1] - tri[0]) + b * (tri[2] - tri[0]);
        p.cmpge(lo).all() && p.cmple(hi).all()
    })
}

fn corners_prove_separation(lo: DVec3, hi: DVec3, tri: [DVec3; 3]) -> bool {
    let tlo = tri[0].min(tri[1]).min(tri[2]);
    let thi = tri[0].max(tri[1]).max(tri[2]);
    if tlo.cmpgt(hi).any() || thi.cmplt(lo).any() {
        return true;
    }
    let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    if n.length() < 1e-12 {
        return false;
    }
    let s: Vec<f64> = (0..8)
        .map(|k| {
            let c = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            n.dot(c - tri[0])
        })
        .collect();
    s.iter().all(|&d| d > 1e-9) || s.iter().all(|&d| d < -1e-9)
}

fn sat(lo: DVec3, hi: DVec3, tri: [DVec3; 3]) -> bool {
    tri_box_overlap(0.5 * (lo + hi), 0.5 * (hi - lo), tri)
}

#[test]
fn random_triangles_agree_with_clipping_and_sampling() {
    let mut rng = Rng(0x5eed);
    let (mut yes, mut no) = (0, 0);
    for i in 0..20_000 {
        let centre = rng.vec(-0.5, 0.5);
        let half = DVec3::new(
            rng.range(0.1, 1.0),
            rng.range(0.1, 1.0),
            rng.range(0.1, 1.0),
        );
        let (lo, hi) = (centre - half, centre + half);
        // Mix of sizes: slivers and small triangles near the box, and large ones.
        let scale = [0.05, 0.3, 1.0, 3.0][i % 4];
        let anchor = centre + rng.vec(-1.6, 1.6) * half.max_element();
        let tri = [
            anchor + rng.vec(-1.0, 1.0) * scale,
            anchor + rng.vec(-1.0, 1.0) * scale,
            anchor + rng.vec(-1.0, 1.0) * scale,
        ];
        let got = sat(lo, hi, tri);
        let e = DVec3::splat(1e-9);
        if clip_oracle(lo + e, hi - e, tri) {
            assert!(
                got,
                "case {i}: clipping finds overlap, SAT does not: {tri:?} {lo} {hi}"
            );
        }
        if !clip_oracle(lo - e, hi + e, tri) {
            assert!(
                !got,
                "case {i}: clipping finds none, SAT reports overlap: {tri:?} {lo} {hi}"
            );
        }
        if sample_proves_overlap(lo, hi, tri, &mut rng) {
            assert!(
                got,
                "case {i}: a sampled point lies in the box: {tri:?} {lo} {hi}"
            );
        }
        if corners_prove_separation(lo, hi, tri) {
            assert!(!got, "case {i}: the box is on one side: {tri:?} {lo} {hi}");
        }
        if got {
            yes += 1;
        } else {
            no += 1;
        }
    }
    // The distribution must exercise both answers substantially.
    assert!(yes > 4000 && no > 4000, "overlaps {yes}, separations {no}");
}

#[test]
fn random_degenerate_triangles_agree_with_clipping() {
    // Segments and points: the triangle normal is zero and must not separate.
    let mut rng = Rng(7);
    for i in 0..5000 {
        let (lo, hi) = (DVec3::splat(-0.5), DVec3::splat(0.5));
        let a = rng.vec(-1.2, 1.2);
        let b = if i % 3 == 0 { a } else { rng.vec(-1.2, 1.2) };
        let tri = [a, b, a + (b - a) * rng.f()];
        let got = sat(lo, hi, tri);
        let e = DVec3::splat(1e-9);
        if clip_oracle(lo + e, hi - e, tri) {
            assert!(got, "case {i}: {tri:?}");
        }
        if !clip_oracle(lo - e, hi + e, tri) {
            assert!(!got, "case {i}: {tri:?}");
        }
    }
}

#[test]
fn exact_cases() {
    let (c, h) = (DVec3::ZERO, DVec3::ONE);
    let t = |a: [f64; 3], b: [f64; 3], d: [f64; 3]| [a.into(), b.into(), d.into()];
    let cases: &[(&str, [DVec3; 3], bool)] = &[
        (
            "fully inside",
            t([-0.5, -0.5, 0.0], [0.5, -0.5, 0.1], [0.0, 0.5, -0.2]),
            true,
        ),
        (
            "far away",
            t([5.0, 5.0, 5.0], [6.0, 5.0, 5.0], [5.0, 6.0, 5.0]),
            false,
        ),
        (
            "box inside a large triangle",
            t([-10.0, -10.0, 0.3], [10.0, -10.0, 0.3], [0.0, 10.0, 0.3]),
            true,
        ),
        (
            "lying on the face x = 1",
            t([1.0, -0.5, -0.5], [1.0, 0.5, -0.5], [1.0, 0.0, 0.5]),
            true,
        ),
        (
            "parallel to x = 1, just outside",
            t([1.001, -0.5, -0.5], [1.001, 0.5, -0.5], [1.001, 0.0, 0.5]),
            false,
        ),
        (
            "one vertex on a box corner",
            t([1.0, 1.0, 1.0], [2.0, 1.0, 1.0], [1.0, 2.0, 1.0]),
            true,
        ),
        (
            "edge touching a box edge",
            t([1.0, 1.0, -3.0], [1.0, 1.0, 3.0], [3.0, 3.0, 0.0]),
            true,
        ),
        // Only an edge-cross-product axis, (1, 1, 0), separates these: their plane
        // z = 0 cuts the box and their bounding boxes overlap it.
        (
            "edge passing outside a box edge",
            t([1.5, 0.9, 0.0], [0.9, 1.5, 0.0], [2.0, 2.0, 0.0]),
            false,
        ),
        (
            "edge crossing a box edge",
            t([1.2, 0.7, 0.0], [0.7, 1.2, 0.0], [2.0, 2.0, 0.0]),
            true,
        ),
        // Only the triangle normal separates: a tilted triangle past the corner.
        (
            "plane past the corner",
            t([3.2, 0.0, 0.0], [0.0, 3.2, 0.0], [0.0, 0.0, 3.2]),
            false,
        ),
        (
            "plane through the corner region",
            t([2.8, 0.0, 0.0], [0.0, 2.8, 0.0], [0.0, 0.0, 2.8]),
            true,
        ),
        (
            "a point inside",
            t([0.2, 0.2, 0.2], [0.2, 0.2, 0.2], [0.2, 0.2, 0.2]),
            true,
        ),
        (
            "a segment through the box",
            t([-3.0, 0.1, 0.1], [3.0, 0.1, 0.1], [3.0, 0.1, 0.1]),
            true,
        ),
        (
            "a segment past a box edge",
            t([2.5, 0.0, 0.0], [0.0, 2.5, 0.0], [0.0, 2.5, 0.0]),
            false,
        ),
    ];
    for (name, tri, want) in cases {
        assert_eq!(tri_box_overlap(c, h, *tri), *want, "{name}");
        // The oracle agrees on the unambiguous ones (not on exact touching).
        if !name.contains("on ") && !name.contains("touching") {
            assert_eq!(clip_oracle(c - h, c + h, *tri), *want, "oracle: {name}");
        }
    }
}

#[test]
fn voxelizer_marks_exactly_the_overlapping_voxels() {
    let mut rng = Rng(99);
    let dims = UVec3::new(9, 7, 8);
    let vs = 0.25;
    let origin = DVec3::new(-1.0, 0.5, 2.0);
    let tris: Vec<[DVec3; 3]> = (0..40)
        .map(|_| {
            let a = origin + rng.vec(-0.3, 2.5);
            [a, a + rng.vec(-0.6, 0.6), a + rng.vec(-0.6, 0.6)]
        })
        .collect();
    let mut grid = Grid::new(dims, vs, origin).unwrap();
    voxelize_triangles(&mut grid, &tris, &vec![1; tris.len()]);
    for z in 0..dims.z as i32 {
        for y in 0..dims.y as i32 {
            for x in 0..dims.x as i32 {
                let v = IVec3::new(x, y, z);
                let c = origin + (v.as_dvec3() + 0.5) * vs;
                let exact = tris
                    .iter()
                    .any(|t| tri_box_overlap(c, DVec3::splat(vs / 2.0), *t));
                let grown = tris
                    .iter()
                    .any(|t| tri_box_overlap(c, DVec3::splat(vs / 2.0 * (1.0 + 1e-6)), *t));
                let marked = grid.get(v) != 0;
                assert!(
                    !exact || marked,
                    "voxel {v} overlaps a triangle but is not marked"
                );
                assert!(
                    marked <= grown,
                    "voxel {v} is marked but touches no triangle"
                );
            }
        }
    }
    assert!(grid.data().iter().filter(|&&m| m != 0).count() > 50);
}
