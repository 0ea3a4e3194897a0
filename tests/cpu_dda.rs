//! The f64 DDA against brute-force ray/voxel intersection: thousands of random rays,
//! axis-parallel rays, and rays that start on voxel faces, edges and corners.

use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::dda::{Dda, cast};
use voxlab::scene::Grid;

/// A non-cubic, non-power-of-two grid away from the origin, with non-unit voxels and a
/// random fill of 4 materials (about half void).
fn random_grid(rng: &mut StdRng) -> Grid {
    let mut g = Grid::new(UVec3::new(7, 5, 9), 0.7, DVec3::new(-3.0, 2.0, 1.5)).unwrap();
    for m in g.data_mut() {
        *m = if rng.random_bool(0.5) {
            0
        } else {
            rng.random_range(1..4)
        };
    }
    g
}

/// The closed parameter interval in which the ray lies inside voxel `v`'s box grown by
/// `grow` on every side (negative: shrunk), if any.
fn voxel_interval_grown(g: &Grid, v: IVec3, o: DVec3, d: DVec3, grow: f64) -> Option<(f64, f64)> {
    let lo = g.origin() + v.as_dvec3() * g.voxel_size() - DVec3::splat(grow);
    let hi = lo + DVec3::splat(g.voxel_size() + 2.0 * grow);
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return None;
            }
        } else {
            let (p, q) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
            t0 = t0.max(p.min(q));
            t1 = t1.min(p.max(q));
        }
    }
    (t0 <= t1).then_some((t0, t1))
}

fn all_voxels(g: &Grid) -> impl Iterator<Item = IVec3> + '_ {
    let d = g.dims().as_ivec3();
    (0..d.z)
        .flat_map(move |z| (0..d.y).flat_map(move |y| (0..d.x).map(move |x| IVec3::new(x, y, z))))
}

const TOL: f64 = 1e-9;

/// Checks the visit sequence of one ray against brute force. A ray that runs exactly
/// along a face or an edge touches two or four voxels equally; the DDA visits one of
/// them, so "crossed" means crossing a voxel shrunk by TOL, and the sequence must leave
/// no gap along the ray.
fn check_ray(g: &Grid, o: DVec3, d: DVec3) {
    let visits: Vec<_> = Dda::new(g, o, d, f64::INFINITY).collect();
    // Every voxel the ray crosses for a positive length is visited ...
    for v in all_voxels(g) {
        if let Some((t0, t1)) = voxel_interval_grown(g, v, o, d, -TOL)
            && t1 - t0 > TOL
        {
            assert!(
                visits.iter().any(|x| x.voxel == v),
                "ray {o} {d}: voxel {v} crossed on [{t0}, {t1}] but not visited; visits {visits:?}"
            );
        }
    }
    for (k, x) in visits.iter().enumerate() {
        // ... every visited voxel touches the ray where the DDA says it enters ...
        let (t0, t1) = voxel_interval_grown(g, x.voxel, o, d, TOL)
            .unwrap_or_else(|| panic!("ray {o} {d}: visited {x:?} that the ray misses"));
        assert!(
            x.t_enter >= t0 - TOL && x.t_enter <= t1 + TOL,
            "ray {o} {d}: {x:?} entered outside [{t0}, {t1}]"
        );
        if k > 0 {
            let prev = visits[k - 1];
            // ... in order, without repeats, each a face neighbour of the last ...
            assert!(x.t_enter >= prev.t_enter - TOL, "ray {o} {d}: out of order");
            // The exact box, unless rounding puts the ray a hair outside it.
            let (_, prev_exit) = voxel_interval_grown(g, prev.voxel, o, d, 0.0)
                .or_else(|| voxel_interval_grown(g, prev.voxel, o, d, TOL))
                .unwrap();
            // A tolerance in space is one in t divided by the ray's slope.
            let slope = (0..3)
                .map(|a| d[a].abs())
                .filter(|&c| c > 0.0)
                .fold(1.0, f64::min);
            assert!(
                (prev_exit - x.t_enter).abs() < 1e-7 / slope,
                "ray {o} {d}: gap after {prev:?}"
            );
            let diff = (x.voxel - prev.voxel).abs();
            assert_eq!(
                diff.element_sum(),
                1,
                "ray {o} {d}: {prev:?} -> {x:?} not face-adjacent"
            );
            // ... entering through the face the normal names.
            let face_point = o + x.t_enter * d;
            let a = (0..3).find(|&a| x.normal[a] != 0.0).unwrap();
            let lo = g.origin()[a] + x.voxel[a] as f64 * g.voxel_size();
            let plane = if x.normal[a] < 0.0 {
                lo
            } else {
                lo + g.voxel_size()
            };
            assert!(
                (face_point[a] - plane).abs() < 1e-7,
                "ray {o} {d}: {x:?} normal does not name its face"
            );
        }
    }
    let mut seen = std::collections::HashSet::new();
    assert!(
        visits.iter().all(|x| seen.insert(x.voxel)),
        "ray {o} {d}: a voxel visited twice"
    );

    // cast() returns the first visited voxel after the start voxel whose material differs
    // from the medium: check it against brute force ordering by entry distance.
    let inside = g.contains(g.voxel_at(o)) && g.to_local(o).min_element() >= 0.0;
    let medium = if inside { g.material_at(o) } else { 0 };
    let (hit, _) = cast(g, o, d, medium);
    let start = inside.then(|| visits[0].voxel);
    let expected = visits
        .iter()
        .filter(|x| Some(x.voxel) != start || x.normal != DVec3::ZERO)
        .find(|x| g.get(x.voxel) != medium);
    match (hit, expected) {
        (None, None) => {}
        (Some(h), Some(e)) => {
            assert_eq!(h.voxel, e.voxel);
            assert_eq!(h.t, e.t_enter);
            assert_eq!(h.material, g.get(e.voxel));
        }
        // Outside the grid is void: a ray in a non-void medium that meets no other
        // material hits void where it leaves the grid's box.
        (Some(h), None) if medium != 0 => {
            let (lo, hi) = (g.world_min(), g.world_max());
            let t_exit = (0..3)
                .filter(|&a| d[a] != 0.0)
                .map(|a| ((lo[a] - o[a]) / d[a]).max((hi[a] - o[a]) / d[a]))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(h.material, 0, "ray {o} {d}: exit hit {h:?}");
            assert!(!g.contains(h.voxel), "ray {o} {d}: exit hit inside {h:?}");
            assert!(
                (h.t - t_exit).abs() < 1e-9 * (1.0 + t_exit),
                "ray {o} {d}: exit hit at {} but the box ends at {t_exit}",
                h.t
            );
            assert_eq!(h.normal.dot(d).signum(), -1.0, "ray {o} {d}: {h:?}");
        }
        (h, e) => panic!("ray {o} {d}: cast {h:?}, expected {e:?}"),
    }
}

fn random_unit(rng: &mut StdRng) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.length_squared() > 1e-6 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

#[test]
fn random_rays_match_brute_force() {
    let mut rng = StdRng::seed_from_u64(1);
    let g = random_grid(&mut rng);
    let (lo, hi) = (g.world_min(), g.world_max());
    for _ in 0..4000 {
        // Origins inside, around and far from the grid.
        let o = DVec3::new(
            rng.random_range(lo.x - 4.0..hi.x + 4.0),
            rng.random_range(lo.y - 4.0..hi.y + 4.0),
            rng.random_range(lo.z - 4.0..hi.z + 4.0),
        );
        let d = random_unit(&mut rng);
        check_ray(&g, o, d);
        // Aimed at a random point of the grid, so most of these rays hit.
        let target = lo + (hi - lo) * DVec3::new(rng.random(), rng.random(), rng.random());
        if (target - o).length() > 1e-6 {
            check_ray(&g, o, (target - o).normalize());
        }
    }
}

#[test]
fn axis_parallel_and_planar_rays() {
    let mut rng = StdRng::seed_from_u64(2);
    let g = random_grid(&mut rng);
    let (lo, hi) = (g.world_min(), g.world_max());
    for _ in 0..2000 {
        let o = DVec3::new(
            rng.random_range(lo.x - 2.0..hi.x + 2.0),
            rng.random_range(lo.y - 2.0..hi.y + 2.0),
            rng.random_range(lo.z - 2.0..hi.z + 2.0),
        );
        let mut d = random_unit(&mut rng);
        // Zero one or two components: rays in an axis plane and along an axis.
        let zeroed = rng.random_range(1..3);
        for _ in 0..zeroed {
            d[rng.random_range(0..3)] = 0.0;
        }
        if d.length_squared() == 0.0 {
            d[rng.random_range(0..3)] = 1.0;
        }
        check_ray(&g, o, d.normalize());
    }
}

#[test]
fn rays_starting_on_faces_edges_and_corners() {
    let mut rng = StdRng::seed_from_u64(3);
    let g = random_grid(&mut rng);
    let dims = g.dims().as_ivec3();
    for _ in 0..3000 {
        // A lattice point of the grid (corner), then free one or two coordinates to get
        // points on edges and faces, inside the grid and on its boundary.
        let mut l = IVec3::new(
            rng.random_range(0..=dims.x),
            rng.random_range(0..=dims.y),
            rng.random_range(0..=dims.z),
        )
        .as_dvec3();
        let free = rng.random_range(0..3);
        for _ in 0..free {
            let a = rng.random_range(0..3);
            l[a] = rng.random_range(0.0..dims[a] as f64);
        }
        let o = g.to_world(l);
        let mut d = random_unit(&mut rng);
        if rng.random_bool(0.3) {
            d[rng.random_range(0..3)] = 0.0;
            if d.length_squared() == 0.0 {
                d.x = 1.0;
            }
        }
        check_ray(&g, o, d.normalize());
    }
}

#[test]
fn shadow_segments_stop_at_their_length() {
    // A ray along +x through a row of voxels: a limit inside voxel 3 visits 0..=3.
    let g = Grid::new(UVec3::new(8, 1, 1), 1.0, DVec3::ZERO).unwrap();
    let o = DVec3::new(0.5, 0.5, 0.5);
    let visited: Vec<i32> = Dda::new(&g, o, DVec3::X, 3.2).map(|v| v.voxel.x).collect();
    assert_eq!(visited, vec![0, 1, 2, 3]);
    // A limit exactly on a boundary does not enter the next voxel.
    let visited: Vec<i32> = Dda::new(&g, o, DVec3::X, 2.5).map(|v| v.voxel.x).collect();
    assert_eq!(visited, vec![0, 1, 2]);
}
