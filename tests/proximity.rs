//! The proximity traversal's field (src/technique/proximity.rs): every voxel's radius is
//! its exact Chebyshev distance to the nearest voxel with a neighbour of another
//! material (the separable passes against brute force), and the cube of that radius
//! holds the voxel's material only; the largest such cube, so the field skips as far as
//! the rule allows. The octant traversal's field (src/technique/octant.rs) likewise:
//! each octant's radius is the largest cube with the voxel as its corner, and the code
//! stored is the largest of its radii not above it. The box traversal's field
//! (src/technique/boxes.rs): each box holds its voxel's material only and holds the
//! octant walk's cube, it stretches where a surface leaves room, and the walk takes
//! fewer steps for it.

use glam::{IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::scene::Grid;
use voxlab::sparse::Regions;
use voxlab::technique::boxes::{BoxField, REACHES};
use voxlab::technique::octant::{OctantField, RADII, octant, octant_radii};
use voxlab::technique::proximity::{MAX_RADIUS, ProximityField, radii};

/// A grid of `dims` with a few boxes of `materials` materials over a background of one.
fn boxes(rng: &mut StdRng, dims: UVec3, materials: u8, count: usize) -> Grid {
    let mut g = Grid::new(dims, 1.0, glam::DVec3::ZERO).unwrap();
    let background = rng.random_range(0..materials);
    g.data_mut().fill(background);
    for _ in 0..count {
        let lo = IVec3::new(
            rng.random_range(0..dims.x as i32),
            rng.random_range(0..dims.y as i32),
            rng.random_range(0..dims.z as i32),
        );
        let size = IVec3::new(
            rng.random_range(1..=dims.x as i32),
            rng.random_range(1..=dims.y as i32),
            rng.random_range(1..=dims.z as i32),
        ) / rng.random_range(1..4);
        let m = rng.random_range(0..materials);
        let hi = (lo + size.max(IVec3::ONE)).min(dims.as_ivec3());
        for z in lo.z..hi.z {
            for y in lo.y..hi.y {
                for x in lo.x..hi.x {
                    g.set(IVec3::new(x, y, z), m);
                }
            }
        }
    }
    g
}

/// Dims of sides 1 to `below - 1`.
fn random_dims(rng: &mut StdRng, below: u32) -> UVec3 {
    UVec3::new(
        rng.random_range(1..below),
        rng.random_range(1..below),
        rng.random_range(1..below),
    )
}

fn all_voxels(dims: UVec3) -> impl Iterator<Item = IVec3> {
    let d = dims.as_ivec3();
    (0..d.z)
        .flat_map(move |z| (0..d.y).flat_map(move |y| (0..d.x).map(move |x| IVec3::new(x, y, z))))
}

/// Whether every voxel of the cube of radius `r` around `v`, clipped to the grid, has
/// `v`'s material.
fn uniform(g: &Grid, v: IVec3, r: i32) -> bool {
    let lo = (v - r).max(IVec3::ZERO);
    let hi = (v + r + 1).min(g.dims().as_ivec3());
    let m = g.get(v);
    (lo.z..hi.z)
        .all(|z| (lo.y..hi.y).all(|y| (lo.x..hi.x).all(|x| g.get(IVec3::new(x, y, z)) == m)))
}

/// `radii` of `g` against brute force: each voxel's Chebyshev distance to the nearest
/// seed (a voxel with a neighbour inside the grid of another material), capped.
fn check_radii(g: &Grid) {
    let dims = g.dims();
    let r = radii(g.data(), dims);
    let seeds: Vec<IVec3> = all_voxels(dims).filter(|&v| !uniform(g, v, 1)).collect();
    for (i, v) in all_voxels(dims).enumerate() {
        let want = seeds
            .iter()
            .map(|s| (*s - v).abs().max_element())
            .min()
            .map_or(MAX_RADIUS, |d| d.min(MAX_RADIUS as i32) as u8);
        assert_eq!(r[i], want, "grid {dims}, voxel {v}");
    }
}

#[test]
fn radii_are_the_exact_chebyshev_distances() {
    let mut rng = StdRng::seed_from_u64(7);
    for round in 0..40 {
        let dims = random_dims(&mut rng, 24);
        let count = rng.random_range(0..6);
        let g = boxes(&mut rng, dims, 1 + round as u8 % 4, count);
        check_radii(&g);
    }
}

#[test]
fn each_cube_is_the_largest_of_one_material() {
    let mut rng = StdRng::seed_from_u64(8);
    for round in 0..40 {
        let dims = random_dims(&mut rng, 20);
        let count = rng.random_range(1..5);
        let g = boxes(&mut rng, dims, 2 + round as u8 % 3, count);
        let field = ProximityField::build(&g);
        for v in all_voxels(dims) {
            let r = field.radius(v) as i32;
            assert!(uniform(&g, v, r), "grid {dims}, voxel {v}, radius {r}");
            // One more would take in another material, unless the cube already
            // covers the grid.
            let covers =
                (v - r).cmple(IVec3::ZERO).all() && (v + r + 1).cmpge(dims.as_ivec3()).all();
            if !covers && r < MAX_RADIUS as i32 {
                assert!(!uniform(&g, v, r + 1), "grid {dims}, voxel {v}, radius {r}");
            }
        }
    }
}

#[test]
fn a_uniform_grid_is_one_cube_and_radii_cap_at_one_byte() {
    // One material: no seeds, every radius the cap, every cube the whole grid.
    let g = Grid::new(UVec3::new(300, 2, 3), 1.0, glam::DVec3::ZERO).unwrap();
    let field = ProximityField::build(&g);
    assert_eq!(field.radius(IVec3::new(299, 1, 2)), MAX_RADIUS);
    // A voxel of another material at one end: the far end is 298 away, past the cap.
    let mut g = g;
    g.set(IVec3::ZERO, 3);
    let field = ProximityField::build(&g);
    assert_eq!(field.radius(IVec3::new(299, 0, 0)), MAX_RADIUS);
    assert_eq!(field.radius(IVec3::new(200, 0, 0)), 199);
    assert_eq!(field.radius(IVec3::new(1, 1, 1)), 0);
    assert_eq!(field.bytes_per_voxel(), 2.0);
}

#[test]
fn radii_past_the_cap_are_exact_along_every_axis() {
    // Lines longer than the one-byte cap, along each axis in turn, with a few voxels of
    // another material: the capped passes give the capped brute-force distance.
    let mut rng = StdRng::seed_from_u64(9);
    for axis in 0..3 {
        for _ in 0..3 {
            let mut d = [rng.random_range(1..5u32), rng.random_range(1..5u32), 0];
            d[2] = rng.random_range(260..700);
            d.rotate_right(2 - axis);
            let dims = UVec3::from_array(d);
            let mut g = Grid::new(dims, 1.0, glam::DVec3::ZERO).unwrap();
            for _ in 0..rng.random_range(0..4) {
                let v = IVec3::new(
                    rng.random_range(0..dims.x as i32),
                    rng.random_range(0..dims.y as i32),
                    rng.random_range(0..dims.z as i32),
                );
                g.set(v, 2);
            }
            check_radii(&g);
        }
    }
}

/// The side of the largest cube of `v`'s material with `v` as its corner toward octant
/// `o`, clipped to the grid, less one; [`MAX_RADIUS`] once the cube reaches the grid's
/// far side on every axis or passes the cap.
fn corner_radius(g: &Grid, v: IVec3, o: usize) -> u8 {
    let s = step_of(o);
    let dims = g.dims().as_ivec3();
    let m = g.get(v);
    for k in 1..=i32::from(MAX_RADIUS) {
        let far = v + s * k;
        let inside = far.cmpge(IVec3::ZERO) & far.cmplt(dims);
        if !inside.any() {
            return MAX_RADIUS;
        }
        // The cube of side k + 1 holds that of side k: only its new shell is read.
        let (lo, hi) = ((v).min(far).max(IVec3::ZERO), (v).max(far).min(dims - 1));
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    let u = IVec3::new(x, y, z);
                    if (u - v).abs().max_element() == k && g.get(u) != m {
                        return (k - 1) as u8;
                    }
                }
            }
        }
    }
    MAX_RADIUS
}

fn check_octant_radii(g: &Grid) {
    let dims = g.dims();
    let field = OctantField::build(g);
    for o in 0..8 {
        let r = octant_radii(g.data(), dims, o);
        for (i, v) in all_voxels(dims).enumerate() {
            let want = corner_radius(g, v, o);
            assert_eq!(r[i], want, "grid {dims}, voxel {v}, octant {o}");
            let stored = field.radius(v, o);
            let code = RADII.iter().rposition(|&q| q <= want).unwrap();
            assert_eq!(stored, RADII[code], "grid {dims}, voxel {v}, octant {o}");
        }
    }
}

#[test]
fn octant_radii_are_the_largest_corner_cubes() {
    let mut rng = StdRng::seed_from_u64(10);
    for round in 0..30 {
        let dims = random_dims(&mut rng, 18);
        let count = rng.random_range(0..6);
        let g = boxes(&mut rng, dims, 1 + round as u8 % 4, count);
        check_octant_radii(&g);
    }
    // Lines past the cap along each axis.
    for axis in 0..3 {
        let mut d = [2, 3, 2];
        d[axis] = 300;
        let mut g = Grid::new(UVec3::from_array(d), 1.0, glam::DVec3::ZERO).unwrap();
        let mut far = IVec3::ZERO;
        far[axis] = 280;
        g.set(far, 4);
        check_octant_radii(&g);
    }
}

#[test]
fn a_walk_reads_its_own_octants_cube() {
    // Void with one solid voxel at (4, 4, 4) in a 9^3 grid: from the voxel at (2, 2, 2)
    // the cube toward +x+y+z stops short of it, the one toward -x-y-z reaches the corner.
    let mut g = Grid::new(UVec3::splat(9), 1.0, glam::DVec3::ZERO).unwrap();
    g.set(IVec3::splat(4), 1);
    let field = OctantField::build(&g);
    let v = IVec3::splat(2);
    let up = field.region(v, IVec3::ONE);
    assert_eq!((up.lo, up.hi), (v, v + 2), "{up:?}");
    let down = field.region(v, -IVec3::ONE);
    assert_eq!((down.lo, down.hi), (IVec3::ZERO, v + 1), "{down:?}");
    // Step 0 on an axis takes the positive side there: toward +x -y +z the solid voxel
    // is behind, and the cube reaches the grid's sides.
    assert_eq!(octant(IVec3::new(0, -1, 0)), 2);
    let flat = field.region(v, IVec3::new(0, -1, 0));
    assert_eq!(
        (flat.lo, flat.hi),
        (IVec3::new(2, 0, 2), IVec3::new(9, 3, 9)),
        "{flat:?}"
    );
}

/// The step of a walk that reads octant `o`.
fn step_of(o: usize) -> IVec3 {
    IVec3::new(
        1 - 2 * (o & 1) as i32,
        1 - 2 * (o >> 1 & 1) as i32,
        1 - 2 * (o >> 2 & 1) as i32,
    )
}

/// Every box, against brute force: it holds its voxel, only its voxel's material, and
/// the octant walk's cube toward the same octant; its reaches are entries of
/// [`REACHES`].
#[test]
fn boxes_hold_their_material_and_the_octant_cube() {
    let mut rng = StdRng::seed_from_u64(12);
    for round in 0..40 {
        let dims = random_dims(&mut rng, 20);
        let count = rng.random_range(0..8);
        let g = boxes(&mut rng, dims, 1 + round as u8 % 4, count);
        let (field, cubes) = (BoxField::build(&g), OctantField::build(&g));
        for v in all_voxels(dims) {
            for o in 0..8 {
                let step = step_of(o);
                let b = field.region(v, step);
                let reach = field.reach(v, o);
                assert!(
                    reach
                        .to_array()
                        .iter()
                        .all(|r| REACHES.contains(&(*r as u8))),
                    "grid {dims}, voxel {v}, octant {o}: {reach}"
                );
                assert!(b.lo.cmple(v).all() && v.cmplt(b.hi).all(), "{v} {b:?}");
                let m = g.get(v);
                for z in b.lo.z..b.hi.z {
                    for y in b.lo.y..b.hi.y {
                        for x in b.lo.x..b.hi.x {
                            let u = IVec3::new(x, y, z);
                            assert_eq!(g.get(u), m, "grid {dims}, voxel {v}, octant {o}: {u}");
                        }
                    }
                }
                let c = cubes.region(v, step);
                assert!(
                    b.lo.cmple(c.lo).all() && c.hi.cmple(b.hi).all(),
                    "grid {dims}, voxel {v}, octant {o}: box {b:?}, cube {c:?}"
                );
            }
        }
    }
}

/// Lines past the byte cap (255) and the largest reach (192) along each axis: every
/// box stops short of the one other voxel, and a reach past 192 is rounded to it.
#[test]
fn boxes_past_the_cap_hold_their_material() {
    for axis in 0..3 {
        let mut d = [2, 3, 2];
        d[axis] = 300;
        let dims = UVec3::from_array(d);
        let mut g = Grid::new(dims, 1.0, glam::DVec3::ZERO).unwrap();
        let mut far = IVec3::ZERO;
        far[axis] = 280;
        g.set(far, 4);
        let field = BoxField::build(&g);
        for v in all_voxels(dims) {
            for o in 0..8 {
                let b = field.region(v, step_of(o));
                let inside = (b.lo.cmple(far) & far.cmplt(b.hi)).all();
                assert_eq!(
                    inside,
                    v == far,
                    "axis {axis}, voxel {v}, octant {o}: {b:?}"
                );
            }
        }
        // From the grid's first voxel toward the far voxel the box stops before it
        // (reach 279, rounded to 192); from the last voxel back toward it, 18 (16).
        let toward = field.reach(IVec3::ZERO, 0);
        assert_eq!(toward[axis], 192, "{toward}");
        let mut end = IVec3::ZERO;
        end[axis] = 299;
        let back = field.reach(end, 1 << axis);
        assert_eq!(back[axis], 16, "{back}");
    }
}

#[test]
fn a_box_stretches_along_a_floor() {
    // A floor (z = 0) under void in a 64^3 grid, and a pillar at x, y in 40..44. From
    // (10, 10, 5) toward +x +y -z the cube stops at the floor (reach 4); the box reaches
    // the floor across it and, along it, x to the pillar's face (x = 39: reach 29,
    // rounded to 24) and y past the grid (255, rounded to 192), or the other way round.
    let mut g = Grid::new(UVec3::splat(64), 1.0, glam::DVec3::ZERO).unwrap();
    for y in 0..64 {
        for x in 0..64 {
            g.set(IVec3::new(x, y, 0), 1);
        }
    }
    for z in 0..64 {
        for y in 40..44 {
            for x in 40..44 {
                g.set(IVec3::new(x, y, z), 1);
            }
        }
    }
    let field = BoxField::build(&g);
    let cubes = OctantField::build(&g);
    let v = IVec3::new(10, 10, 5);
    let o = octant(IVec3::new(1, 1, -1));
    assert_eq!(cubes.radius(v, o), 4);
    let reach = field.reach(v, o);
    assert_eq!(reach.z, 4, "{reach}");
    assert!(
        [IVec3::new(24, 192, 4), IVec3::new(192, 24, 4)].contains(&reach),
        "{reach}"
    );
    let b = field.region(v, IVec3::new(1, 1, -1));
    assert_eq!(b.lo, IVec3::new(10, 10, 1), "{b:?}");
    assert_eq!(b.hi.z, 6, "{b:?}");
}

/// What the boxes are for: on the seed scene (CPU, where steps are counted exactly) the
/// box walk takes at most half the octant walk's steps, with the same image (the
/// seed's rules, 32x32: about 0.4x at 64^3 and 0.35x at 128^3, docs/sparse-traversal.md,
/// "Boxes").
#[test]
fn the_boxes_take_fewer_steps_than_the_cubes() {
    use voxlab::render::{RenderSettings, Rules, Traversal};
    for size in [16, 64, 128] {
        let scene = voxlab::scene::seed_scene(size).unwrap();
        let settings = |traversal| RenderSettings {
            width: 32,
            height: 32,
            traversal,
            rules: Rules::Seed,
            ..Default::default()
        };
        let octant = Traversal::Walk(&voxlab::technique::octant::TRAVERSAL);
        let boxes = Traversal::Walk(&voxlab::technique::boxes::TRAVERSAL);
        let cubes = voxlab::cpu::render(&scene, &settings(octant));
        let stretched = voxlab::cpu::render(&scene, &settings(boxes));
        assert_eq!(cubes.frame.pixels, stretched.frame.pixels, "{size}^3");
        let ratio = stretched.stats.voxel_steps as f64 / cubes.stats.voxel_steps as f64;
        eprintln!("{size}^3: {ratio:.3}x the octant walk's steps");
        assert!(
            ratio <= 0.6,
            "{size}^3: {ratio:.3}x the octant walk's steps"
        );
    }
}
