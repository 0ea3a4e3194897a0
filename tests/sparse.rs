//! The sparse tree (the seed's O2), and every registered traversal with data of its own
//! (the tree, the proximity field), against the dense grid it is built from: every
//! voxel's region uniform and holding it, and along many thousands of random rays in
//! random sparse grids the same hit sequence (voxel, distance, face, material, bit for
//! bit) as the dense DDA, for octrees, 64-trees and 512-trees; the same shadow
//! transmittances; the same CPU images. Rays start on node boundaries, run along axes,
//! and start inside uniform regions of any material (a ray inside a glass block skips
//! the block too).

use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::RayStats;
use voxlab::cpu::{shadow_beer_lambert_over, shadow_min_kt_over};
use voxlab::dda::{Dda, cast_over};
use voxlab::render::{RenderSettings, Traversal};
use voxlab::scene::{Grid, Material, Scene, seed_scene};
use voxlab::sparse::{Region, Regions, SparseTree};

const DENSE_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::dense::TRAVERSAL);
const SPARSE_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::sparse::TRAVERSAL);
const SPARSE_OCTANT_WALK: voxlab::render::Traversal =
    voxlab::render::Traversal::Walk(&voxlab::technique::sparse_octant::TRAVERSAL);

/// Every registered traversal's data of `g` (those that skip regions), by name.
fn walk_data(g: &Grid) -> Vec<(&'static str, std::sync::Arc<dyn Regions>)> {
    voxlab::technique::TRAVERSALS
        .iter()
        .filter_map(|t| {
            t.data
                .map(|data| (t.name, data(g, voxlab::technique::HOST_WALK_BYTES)))
        })
        .collect()
}

/// A grid of `dims` that is mostly uniform: a few boxes of random materials (some
/// large, some one voxel), over a background that is void or, half the time, one
/// material, so regions of every material and size occur.
fn random_sparse_grid(rng: &mut StdRng, dims: UVec3, materials: u8) -> Grid {
    // Half the grids sit at the origin with voxels of 1 or 1/2, where node corners are
    // exact in world units and diagonal rays through them meet exact ties of the exit
    // planes (the tie rule: lowest axis first).
    let (origin, voxel_size) = if rng.random_bool(0.5) {
        (DVec3::ZERO, if rng.random_bool(0.5) { 1.0 } else { 0.5 })
    } else {
        (
            DVec3::new(
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
                rng.random_range(-5.0..5.0),
            ),
            rng.random_range(0.3..2.0),
        )
    };
    let mut g = Grid::new(dims, voxel_size, origin).unwrap();
    let background = if rng.random_bool(0.5) {
        0
    } else {
        rng.random_range(1..materials)
    };
    g.data_mut().fill(background);
    let d = dims.as_ivec3();
    for _ in 0..rng.random_range(1..12) {
        let size = IVec3::new(
            rng.random_range(1..=d.x),
            rng.random_range(1..=d.y),
            rng.random_range(1..=d.z),
        ) / if rng.random_bool(0.5) { 1 } else { 4 };
        let size = size.max(IVec3::ONE);
        let lo = IVec3::new(
            rng.random_range(0..=d.x - size.x),
            rng.random_range(0..=d.y - size.y),
            rng.random_range(0..=d.z - size.z),
        );
        let m = rng.random_range(0..materials);
        for z in lo.z..lo.z + size.z {
            for y in lo.y..lo.y + size.y {
                for x in lo.x..lo.x + size.x {
                    g.set(IVec3::new(x, y, z), m);
                }
            }
        }
    }
    // Scattered single voxels.
    for _ in 0..rng.random_range(0..40) {
        let v = IVec3::new(
            rng.random_range(0..d.x),
            rng.random_range(0..d.y),
            rng.random_range(0..d.z),
        );
        g.set(v, rng.random_range(0..materials));
    }
    g
}

/// Every change of material along the ray, from its start until it leaves the grid:
/// (voxel, entry distance, face, material). Over a tree, each region of the current
/// material is left whole.
fn transitions(
    g: &Grid,
    regions: Option<&dyn Regions>,
    o: DVec3,
    d: DVec3,
) -> (Vec<(IVec3, f64, DVec3, u8)>, u64) {
    let mut dda = Dda::over(g, regions, o, d, f64::INFINITY);
    let mut out = Vec::new();
    let mut medium = None;
    while let Some(v) = dda.next() {
        if medium != Some(v.material) {
            out.push((v.voxel, v.t_enter, v.normal, v.material));
            medium = Some(v.material);
        }
        dda.skip_region();
    }
    if let Some((voxel, normal)) = dda.exit {
        out.push((voxel, dda.t_end, normal, 0));
    }
    (out, dda.steps)
}

/// A random ray for grid `g`: from inside or outside, on node boundaries (multiples of
/// 4 and 16 voxels) or anywhere, along an axis, a diagonal or any direction.
fn random_ray(rng: &mut StdRng, g: &Grid) -> (DVec3, DVec3) {
    let dims = g.dims().as_dvec3();
    let mut local = DVec3::new(
        rng.random_range(-0.3..1.3) * dims.x,
        rng.random_range(-0.3..1.3) * dims.y,
        rng.random_range(-0.3..1.3) * dims.z,
    );
    match rng.random_range(0..4) {
        // On a node boundary plane of one axis, or on a corner of nodes.
        0 => {
            let a = rng.random_range(0..3);
            let unit = if rng.random_bool(0.5) { 4.0 } else { 16.0 };
            local[a] = (local[a] / unit).round() * unit;
        }
        1 => local = (local / 4.0).round() * 4.0,
        _ => {}
    }
    let mut d = match rng.random_range(0..5) {
        0 => {
            let mut d = DVec3::ZERO;
            d[rng.random_range(0..3)] = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
            d
        }
        1 => DVec3::new(
            if rng.random_bool(0.5) { 1.0 } else { -1.0 },
            if rng.random_bool(0.5) { 1.0 } else { -1.0 },
            if rng.random_bool(0.5) { 1.0 } else { -1.0 },
        ),
        2 => {
            // In an axis plane.
            let mut d = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            d[rng.random_range(0..3)] = 0.0;
            d
        }
        _ => DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        ),
    };
    if d.length() < 1e-3 {
        d = DVec3::X;
    }
    // Rays from outside aim at the grid half the time.
    let inside = (0..3).all(|a| (0.0..dims[a]).contains(&local[a]));
    if !inside && rng.random_bool(0.5) {
        let target = DVec3::new(
            rng.random_range(0.0..dims.x),
            rng.random_range(0.0..dims.y),
            rng.random_range(0.0..dims.z),
        );
        d = target - local;
    }
    // Diagonals stay exact (unnormalised: distances are in units of |d|), so their
    // plane distances tie exactly.
    let d = if d.abs().x == d.abs().y && d.abs().y == d.abs().z {
        d
    } else {
        d.normalize()
    };
    (g.to_world(local), d)
}

const SIZES: [[u32; 3]; 6] = [
    [16, 16, 16],
    [13, 7, 21],
    [64, 64, 64],
    [5, 70, 3],
    [33, 17, 64],
    [1, 1, 1],
];

/// Every voxel of `g` lies in its region (found by `name`) for a walk of every step,
/// of its material and inside the grid; the region is uniform: every voxel of it on
/// small grids, its corners on the others.
fn assert_regions_hold_the_grid(g: &Grid, regions: &dyn Regions, name: &str) {
    let dims = g.dims().as_ivec3();
    let steps: Vec<IVec3> = (0..27)
        .map(|k| IVec3::new(k % 3 - 1, k / 3 % 3 - 1, k / 9 - 1))
        .collect();
    for z in 0..dims.z {
        for y in 0..dims.y {
            for x in 0..dims.x {
                let v = IVec3::new(x, y, z);
                for &step in &steps {
                    let r = regions.region(v, step);
                    assert_eq!(r.material, g.get(v), "{name}, {dims} at {v}, step {step}");
                    assert!(v.cmpge(r.lo).all() && v.cmplt(r.hi).all());
                    assert!(r.lo.cmpge(IVec3::ZERO).all());
                    assert!(r.hi.as_uvec3().cmple(g.dims()).all());
                    assert_region_uniform(g, r, &format!("{name}, {v}, step {step}"));
                }
            }
        }
    }
}

/// Every voxel of `r` holds its material on small grids, its two far corners on the
/// others.
fn assert_region_uniform(g: &Grid, r: Region, what: &str) {
    if g.voxel_count() <= 4096 {
        for zz in r.lo.z..r.hi.z {
            for yy in r.lo.y..r.hi.y {
                for xx in r.lo.x..r.hi.x {
                    let u = IVec3::new(xx, yy, zz);
                    assert_eq!(g.get(u), r.material, "{what}: {u}");
                }
            }
        }
    } else {
        for p in [r.lo, r.hi - IVec3::ONE] {
            assert_eq!(g.get(p), r.material, "{what}");
        }
    }
}

#[test]
fn the_tree_holds_every_voxel_of_the_grid() {
    let mut rng = StdRng::seed_from_u64(1);
    for dims in SIZES {
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 5);
        for b in 1..=3 {
            let t = SparseTree::build(&g, b);
            assert_regions_hold_the_grid(&g, &t, &format!("branch 2^{b}"));
        }
    }
}

#[test]
fn every_traversals_regions_are_uniform_and_hold_their_voxel() {
    let mut rng = StdRng::seed_from_u64(11);
    for dims in SIZES {
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 5);
        for (name, data) in walk_data(&g) {
            assert_regions_hold_the_grid(&g, data.as_ref(), name);
        }
    }
}

#[test]
fn random_rays_meet_the_same_transitions_as_the_dense_dda() {
    let mut rng = StdRng::seed_from_u64(2);
    let mut rays = 0;
    let (mut dense_steps, mut sparse_steps) = (0u64, 0u64);
    for round in 0..60 {
        let dims = SIZES[round % SIZES.len()];
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 4);
        let trees: Vec<SparseTree> = (1..=3).map(|b| SparseTree::build(&g, b)).collect();
        let data = walk_data(&g);
        for _ in 0..200 {
            let (o, d) = random_ray(&mut rng, &g);
            let (want, steps) = transitions(&g, None, o, d);
            dense_steps += steps;
            for (name, data) in &data {
                let (got, _) = transitions(&g, Some(data.as_ref()), o, d);
                assert_eq!(got, want, "grid {dims:?}, {name}, ray {o} + t {d}");
            }
            for t in &trees {
                let (got, steps) = transitions(&g, Some(t), o, d);
                assert_eq!(
                    got,
                    want,
                    "grid {dims:?}, branch 2^{}, ray {o} + t {d}",
                    t.log_branch()
                );
                if t.log_branch() == 2 {
                    sparse_steps += steps;
                }
            }
            rays += 1;
        }
    }
    assert_eq!(rays, 12000);
    // The sparse walk's moves (steps after skips) are fewer.
    assert!(
        sparse_steps < dense_steps,
        "{sparse_steps} vs {dense_steps}"
    );
}

#[test]
fn casts_in_every_medium_hit_what_the_dense_cast_hits() {
    let mut rng = StdRng::seed_from_u64(3);
    for round in 0..40 {
        let dims = SIZES[round % SIZES.len()];
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 4);
        let data = walk_data(&g);
        for _ in 0..200 {
            let (o, d) = random_ray(&mut rng, &g);
            for medium in 0..4 {
                for exit_hits in [true, false] {
                    let (want, _) = cast_over(&g, None, o, d, medium, exit_hits);
                    for (name, data) in &data {
                        let (got, _) = cast_over(&g, Some(data.as_ref()), o, d, medium, exit_hits);
                        assert_eq!(got, want, "{name}, medium {medium}, ray {o} + t {d}");
                    }
                }
            }
        }
    }
}

/// A scene over `g` with four materials of every kind a shadow ray meets: opaque,
/// partly transmitting, and absorbing by distance.
fn scene_over(g: Grid) -> Scene {
    let mut s = seed_scene(1).unwrap();
    let base = s.materials[1].clone();
    s.materials = vec![
        s.materials[0].clone(),
        Material {
            kt: 0.0,
            ..base.clone()
        },
        Material {
            kt: 0.7,
            ..base.clone()
        },
        Material {
            kt: 0.9,
            sigma: Some(DVec3::new(0.3, 0.05, 1.2)),
            ..base
        },
    ];
    s.grid = g;
    s
}

#[test]
fn shadow_transmittances_equal_the_dense_walks() {
    let mut rng = StdRng::seed_from_u64(4);
    for round in 0..30 {
        let dims = SIZES[round % SIZES.len()];
        let scene = scene_over(random_sparse_grid(&mut rng, UVec3::from_array(dims), 4));
        let data = walk_data(&scene.grid);
        for _ in 0..200 {
            let (q, d) = random_ray(&mut rng, &scene.grid);
            let len = rng.random_range(0.0..2.0) * scene.grid.width();
            let light = q + len * d;
            let mut stats = RayStats::default();
            for (name, data) in &data {
                let t = Some(data.as_ref());
                let want = shadow_min_kt_over(&scene, None, q, light, &mut stats);
                let got = shadow_min_kt_over(&scene, t, q, light, &mut stats);
                assert_eq!(got, want, "{name}, min-kt, {q} to {light}");
                let want = shadow_beer_lambert_over(&scene, None, q, light, &mut stats);
                let got = shadow_beer_lambert_over(&scene, t, q, light, &mut stats);
                // The per-voxel lengths telescope to the region's: equal up to rounding.
                assert!(
                    (got - want).abs().max_element() <= 1e-12 * want.max_element().max(1e-300),
                    "{name}, beer-lambert {got} vs {want}, {q} to {light}"
                );
            }
        }
    }
}

#[test]
fn cpu_images_over_the_tree_are_the_dense_images() {
    for size in [16, 40] {
        let scene = seed_scene(size).unwrap();
        let render = |traversal| {
            let settings = RenderSettings {
                width: 48,
                height: 40,
                traversal,
                ..Default::default()
            };
            voxlab::cpu::render(&scene, &settings)
        };
        let dense = render(DENSE_WALK);
        for walk in Traversal::walks().into_iter().filter(|&w| w != DENSE_WALK) {
            let other = render(walk);
            assert_eq!(
                dense.frame.pixels,
                other.frame.pixels,
                "{} walk, seed scene at {size}^3",
                walk.name()
            );
            assert!(
                other.stats.voxel_steps < dense.stats.voxel_steps,
                "{}: {} vs {}",
                walk.name(),
                other.stats.voxel_steps,
                dense.stats.voxel_steps
            );
        }
    }
}

#[test]
fn the_experiment_file_names_the_traversal() {
    use voxlab::experiment::Experiment;
    for t in Traversal::all() {
        let text = format!("[render]\ntraversal = \"{}\"\n", t.name());
        let e = Experiment::from_str(&text, "x.toml").unwrap();
        assert_eq!(e.settings.traversal, t);
        // The writer writes it back.
        let table = voxlab::experiment::write::render_table(&e.settings, e.scene.ambient);
        assert_eq!(table["traversal"].as_str(), Some(t.name()));
    }
    let err = Experiment::from_str("[render]\n\ntraversal = \"octree\"\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("x.toml:3:")
            && err.contains("render.traversal")
            && Traversal::all()
                .iter()
                .all(|t| err.contains(&format!("\"{}\"", t.name()))),
        "{err}"
    );
}

#[test]
fn building_from_a_vox_model_gives_the_tree_of_its_grid() {
    // The deer as the whole scene: the tree built from the loaded grid holds every voxel
    // the grid holds, and padding the grid with void changes no region's material.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/data/deer.vox");
    let vox = voxlab::scene::load_vox(&path, None).unwrap_or_else(|e| panic!("{e}"));
    let g = vox.grid;
    let t = SparseTree::build(&g, 2);
    let d = g.dims().as_ivec3();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let v = IVec3::new(x, y, z);
                assert_eq!(t.get(v), g.get(v), "{v}");
            }
        }
    }
    assert!(t.bytes_per_voxel() < 1.0, "{}", t.bytes_per_voxel());
}

/// Every registered traversal is listed, chosen by name, printed by its label, and
/// composes into the kernel; `auto` takes the default walk below every walk's claim.
#[test]
fn every_traversal_is_a_registered_slot() {
    use voxlab::plan::Plan;
    use voxlab::technique::{Slot, TRAVERSALS, listing};
    let rows = listing();
    let scene = seed_scene(16).unwrap();
    for t in TRAVERSALS {
        assert!(
            rows.iter()
                .any(|r| r.name == t.name && r.slot == Slot::Traversal),
            "{} is not listed",
            t.name
        );
        let settings = RenderSettings {
            traversal: Traversal::Walk(t),
            ..Default::default()
        };
        let plan = Plan::new(&scene, &settings);
        assert_eq!(plan.traversal, *t, "{plan}");
        assert!(plan.to_string().contains(t.label), "{plan}");
        assert_eq!(plan.tree_levels > 0, t.walks_tree, "{plan}");
    }
    // Below every walk's claim (the box walk's side is the smallest), auto takes the
    // default walk; tests/gpu_sparse.rs follows the claims up the sides.
    use voxlab::technique::{boxes::BOXES_FROM_SIDE, octant::OCTANT_FROM_SIDE};
    let side = 8;
    assert!(side < BOXES_FROM_SIDE && BOXES_FROM_SIDE <= OCTANT_FROM_SIDE);
    let auto = Plan::new(&seed_scene(side).unwrap(), &RenderSettings::default());
    assert_eq!(auto.traversal, voxlab::technique::default_traversal());
    assert!(auto.traversal_reason.starts_with("auto: "), "{auto}");
}

/// The tree's cut (`SparseTree::cut`, what the sparse octant walk's cells are): a cube
/// is uniform only when its voxels inside the grid are one material, one of several is
/// a node, and a node's descent finds its voxels' regions.
#[test]
fn the_trees_cut_says_which_cubes_are_uniform() {
    use voxlab::sparse::Cut;
    let mut rng = StdRng::seed_from_u64(23);
    for dims in SIZES {
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 5);
        let tree = SparseTree::build(&g, 2);
        for log_side in 1..=2 * tree.levels() {
            let (cut_dims, cubes) = tree.cut(log_side);
            let side = 1i32 << log_side;
            assert_eq!(cut_dims, (g.dims() + (side as u32 - 1)) / side as u32);
            for (i, cube) in cubes.iter().enumerate() {
                let d = cut_dims.as_ivec3();
                let c = IVec3::new(i as i32 % d.x, i as i32 / d.x % d.y, i as i32 / d.x / d.y);
                let lo = c * side;
                let hi = (lo + side).min(g.dims().as_ivec3());
                let mut seen = std::collections::BTreeSet::new();
                for z in lo.z..hi.z {
                    for y in lo.y..hi.y {
                        for x in lo.x..hi.x {
                            seen.insert(g.get(IVec3::new(x, y, z)));
                        }
                    }
                }
                let what = format!("{dims:?}, cubes of {side}, {c}");
                match *cube {
                    Cut::Uniform(m) => {
                        assert_eq!(seen.into_iter().collect::<Vec<_>>(), [m], "{what}")
                    }
                    Cut::Node(n) => {
                        // One material inside the grid makes a node of a cube only where
                        // it reaches past the grid (there the tree holds void) or is the root.
                        let partial = hi != lo + side;
                        assert!(
                            seen.len() > 1 || partial || side == 1 << (2 * tree.levels()),
                            "{what}"
                        );
                        for v in [lo, hi - 1] {
                            let r = tree.region_below(v, n, tree.cut_node_log(log_side) - 2);
                            assert_eq!(r, tree.region(v), "{what}: {v}");
                        }
                    }
                }
            }
        }
    }
}

/// The nodes the sparse octant walk gives codes: `nodes_up_to` lists, after the index
/// of the first, every node of side at most its argument, in index order as the
/// breadth-first layout stores them (the tail of the nodes), each with its cube; and
/// `node_children` reads a node's children as the grid holds them (a uniform child's
/// material over its whole cube inside the grid, `None` for a node: mixed, or reaching
/// past the grid with a material other than void).
#[test]
fn the_nodes_below_a_side_are_the_trees_last() {
    let mut rng = StdRng::seed_from_u64(31);
    for dims in SIZES {
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 4);
        let tree = g.tree(2);
        let d = g.dims().as_ivec3();
        let (first, all) = tree.nodes_up_to(2 * tree.levels());
        assert_eq!(
            (first, all.len()),
            (0, tree.node_count()),
            "{dims:?}: every node"
        );
        for log_side in (2..=2 * tree.levels()).step_by(2) {
            let (first, nodes) = tree.nodes_up_to(log_side);
            assert_eq!(first as usize + nodes.len(), tree.node_count(), "{dims:?}");
            assert_eq!(
                nodes,
                all.iter()
                    .copied()
                    .filter(|&(_, side)| side <= log_side)
                    .collect::<Vec<_>>(),
                "{dims:?} up to 2^{log_side}"
            );
        }
        for (k, &(lo, log_side)) in all.iter().enumerate() {
            let shift = log_side as i32 - 2;
            for (i, child) in tree.node_children(k as u32).into_iter().enumerate() {
                let c = lo + (IVec3::new(i as i32 % 4, i as i32 / 4 % 4, i as i32 / 16) << shift);
                let hi = (c + IVec3::splat(1 << shift)).min(d);
                if c.cmpge(d).any() {
                    continue;
                }
                let cube: Vec<u8> = (c.z..hi.z)
                    .flat_map(|z| {
                        (c.y..hi.y).flat_map(move |y| (c.x..hi.x).map(move |x| IVec3::new(x, y, z)))
                    })
                    .map(|v| g.get(v))
                    .collect();
                match child {
                    Some(m) => assert!(cube.iter().all(|&v| v == m), "{dims:?} node {k} child {i}"),
                    // Mixed, or past the grid, where the tree counts void.
                    None => assert!(
                        shift > 0
                            && (cube.iter().any(|&v| v != cube[0])
                                || (c + IVec3::splat(1 << shift)).cmpgt(d).any()),
                        "{dims:?} node {k} child {i}: a node child holds one material"
                    ),
                }
            }
        }
    }
}

/// The sparse octant walk's regions with cells of every side the cut can have (on these
/// grids `"auto"` takes only cubes of 4), with and without the leaves' codes: uniform,
/// holding their voxel, for every step.
#[test]
fn sparse_octant_regions_hold_the_grid_at_every_cell_side() {
    use voxlab::technique::sparse_octant::SparseOctant;
    let mut rng = StdRng::seed_from_u64(29);
    for dims in SIZES {
        let g = random_sparse_grid(&mut rng, UVec3::from_array(dims), 5);
        // Every voxel, 27 steps, each side: the large grids once are enough
        // (every_traversals_regions_are_uniform_and_hold_their_voxel).
        if g.voxel_count() > 1 << 15 {
            continue;
        }
        let tree = g.tree(2);
        for log_cell in 1..=2 * tree.levels() {
            let walk = SparseOctant::with_cell_side(tree.clone(), log_cell);
            assert!(walk.has_codes() || tree.nodes_up_to(2 * tree.levels()).1.is_empty());
            assert_regions_hold_the_grid(&g, &walk, &format!("cells of 2^{log_cell}"));
            let walk = SparseOctant::without_codes(tree.clone(), log_cell);
            let name = format!("cells of 2^{log_cell}, no codes below the cut");
            assert_regions_hold_the_grid(&g, &walk, &name);
        }
    }
}

/// At 1024^3 the walk takes cubes of 16 with the codes below them, walked from the same
/// nodes as the cubes of 8 its cells would otherwise be: the codes are built, the data
/// fits one of lavapipe's bindings, and the kernel's descent (compiled from the grid's dims
/// alone) is the one the cells need. Within any larger budget it takes the same.
#[test]
fn cubes_of_sixteen_make_room_for_the_codes_at_1024() {
    use voxlab::technique::sparse_octant::{CodesAt, MAX_WALK_BYTES, SparseOctant, TRAVERSAL};
    let scene = seed_scene(1024).unwrap();
    let walk = SparseOctant::build(scene.grid.tree(2));
    assert_eq!(walk.log_cell(), 4);
    assert!(walk.has_codes());
    // The cells of nodes of 16 hold their heads, a vec4 a cell, and the tree stays on
    // the host: the kernel with heads reads nothing else of it.
    assert_eq!(walk.kernel_variant(), 2);
    assert_eq!(walk.device_words()[0], [0; 4]);
    let cells = (1024usize / 16).pow(3);
    assert_eq!(walk.device_words()[1].len(), 8 + 4 * cells);
    // All of it in one of lavapipe's bindings: the codes follow the cut.
    assert_eq!(walk.codes_at(), CodesAt::WalkData);
    assert!(
        walk.device_bytes() <= MAX_WALK_BYTES,
        "{}",
        walk.device_bytes()
    );
    let descent = (TRAVERSAL.descent_levels.unwrap())(scene.grid.dims());
    assert_eq!(descent, walk.log_cell().div_ceil(2));
    // Each node's block index, then each distinct block of 256 words (four planes of
    // 64) once: along the walls many nodes share one (338,896 nodes, 23,794 blocks).
    let nodes = scene.grid.tree(2).nodes_up_to(4).1.len();
    let codes = walk.codes();
    let head = nodes.next_multiple_of(4);
    let distinct = (codes.len() - head) / 256;
    assert_eq!((codes.len() - head) % 256, 0);
    assert!(
        distinct > 0 && distinct * 10 < nodes,
        "{distinct} of {nodes}"
    );
    assert!(codes[..nodes].iter().all(|&b| (b as usize) < distinct));
    let blocks: std::collections::HashSet<&[u32]> = codes[head..].chunks(256).collect();
    assert_eq!(blocks.len(), distinct, "a block held twice");
    assert!(4 * codes.len() < 32 << 20, "{} bytes", 4 * codes.len());
    // A budget that would hold cubes of 8 with the codes takes the same cubes of 16:
    // below a node's cell the codes skip what the finer cut would, so a device that
    // binds more walks this grid as lavapipe and the CPU reference do.
    assert!(SparseOctant::build_within(scene.grid.tree(2), usize::MAX) == walk);
}

/// The codes are held where the walk's data fits the budget it is built within, in
/// bytes a binding (the device's binding on the GPU): after the cut where all of it fits
/// one binding; one byte short of that, with the cut in one and the codes in
/// `WALK_MORE_BINDINGS` more (the same codes; on the seed scene the cut decides there:
/// the codes take under 3.2 times its bytes); one
/// byte short of that, the walk holds the cut alone and walks to the same regions.
/// `build` is the CPU reference's budget.
#[test]
fn the_codes_are_held_within_the_budget_they_are_built_for() {
    use voxlab::technique::sparse_octant::{CodesAt, MAX_WALK_BYTES, SparseOctant};
    use voxlab::technique::{WALK_MORE_BINDINGS, walk_part_words};
    let scene = seed_scene(64).unwrap();
    let tree = scene.grid.tree(2);
    let first = |w: &SparseOctant| -> usize { w.device_words().iter().map(|p| 4 * p.len()).sum() };
    let coded = SparseOctant::build_within(tree.clone(), usize::MAX);
    assert!(coded.has_codes());
    assert_eq!(coded.codes_at(), CodesAt::WalkData);
    assert!(coded.device_more_words().is_empty());
    let all = first(&coded);
    assert_eq!(all, coded.device_bytes());
    assert!(SparseOctant::build_within(tree.clone(), all) == coded);
    let split = SparseOctant::build_within(tree.clone(), all - 1);
    assert_eq!(split.codes_at(), CodesAt::MoreBindings);
    assert_eq!(split.codes(), coded.codes());
    assert_eq!(split.device_more_words(), coded.codes());
    let codes = coded.codes().len();
    let need = first(&split).max(4 * codes.div_ceil(WALK_MORE_BINDINGS));
    assert!(WALK_MORE_BINDINGS * walk_part_words(need) >= codes);
    assert!(SparseOctant::build_within(tree.clone(), need) == split);
    let without = SparseOctant::build_within(tree.clone(), need - 1);
    assert!(!without.has_codes());
    assert!(without.device_more_words().is_empty());
    // The same cells (a node's holds its block index only with codes). With codes the
    // kernel reads no tree at 64^3 (its descents take one level): a header of no nodes
    // stands for it. Without them it walks the tree.
    assert_eq!(split.device_words()[0], [0; 4]);
    assert!(split.device_words()[1].len() == without.device_words()[1].len());
    assert!(without.device_words()[0] == tree.words());
    assert!(SparseOctant::build(tree.clone()) == SparseOctant::build_within(tree, MAX_WALK_BYTES));
    assert_eq!(MAX_WALK_BYTES, voxlab::technique::HOST_WALK_BYTES);
    // Without codes, the same regions for every voxel and octant.
    let dims = scene.grid.dims().as_ivec3();
    let mut rng = StdRng::seed_from_u64(37);
    for _ in 0..2000 {
        let v = IVec3::new(
            rng.random_range(0..dims.x),
            rng.random_range(0..dims.y),
            rng.random_range(0..dims.z),
        );
        let step = IVec3::new(
            rng.random_range(-1..=1),
            rng.random_range(-1..=1),
            rng.random_range(-1..=1),
        );
        let (a, b) = (coded.region(v, step), without.region(v, step));
        assert_eq!(a.material, b.material, "{v} {step}");
        assert_eq!(a, split.region(v, step), "{v} {step}");
        for r in [a, b] {
            assert!(
                r.lo.cmple(v).all() && r.hi.cmpgt(v).all(),
                "{v} {step}: {r:?}"
            );
        }
    }
}

/// What the boxes of the cells and of the children below them are for: on the seed
/// scene (CPU, where steps are counted exactly), from 64^3 the sparse octant walk takes
/// at most 0.6 times the steps of the dense octant field, whose cubes cannot skip along
/// the walls (the seed's rules, 32x32: 0.48x at 64^3, 0.46x at 200^3; with boxes over
/// the cut and cubes below it 0.82x and 0.77x; with cubes over both 4.60 against 4.17
/// steps a ray at 64^3 and 6.71 against 6.04 at 256^3, 64x64, and 12.29 and 18.57
/// before the leaves had codes).
#[test]
fn the_cells_boxes_and_the_leaves_codes_walk_fewer_steps_than_the_dense_octant_field() {
    let octant = Traversal::Walk(&voxlab::technique::octant::TRAVERSAL);
    for size in [64, 200] {
        let scene = seed_scene(size).unwrap();
        let settings = |traversal| RenderSettings {
            width: 32,
            height: 32,
            traversal,
            rules: voxlab::render::Rules::Seed,
            ..Default::default()
        };
        let dense = voxlab::cpu::render(&scene, &settings(octant));
        let leaves = voxlab::cpu::render(&scene, &settings(SPARSE_OCTANT_WALK));
        assert_eq!(dense.frame.pixels, leaves.frame.pixels, "{size}^3");
        let ratio = leaves.stats.voxel_steps as f64 / dense.stats.voxel_steps as f64;
        assert!(
            ratio <= 0.6,
            "{size}^3: {ratio:.3}x the dense octant walk's steps"
        );
    }
}

/// What the cut's box cells are for: on the seed scene (CPU, where steps are counted
/// exactly), the sparse octant walk takes fewer steps than the plain tree walk at every
/// size, with the same image.
#[test]
fn box_cells_take_fewer_steps_than_the_tree() {
    for size in [16, 64, 200] {
        let scene = seed_scene(size).unwrap();
        let render = |traversal| {
            let settings = RenderSettings {
                width: 24,
                height: 20,
                traversal,
                ..Default::default()
            };
            voxlab::cpu::render(&scene, &settings)
        };
        let tree = render(SPARSE_WALK);
        let cells = render(SPARSE_OCTANT_WALK);
        assert_eq!(tree.frame.pixels, cells.frame.pixels, "{size}^3");
        assert!(
            cells.stats.voxel_steps < tree.stats.voxel_steps,
            "{size}^3: {} vs {}",
            cells.stats.voxel_steps,
            tree.stats.voxel_steps
        );
    }
}

/// Where the cut's own cells are finer than its nodes' (cells of 8, nodes of 16) the
/// build first takes the nodes' cells with the codes; codes that fit nowhere there fit
/// nowhere with the finer cut either (the same nodes below it, so the same codes, beside
/// more cells), so that walk holds the finer cut without codes, built once, and says
/// what did not fit. A grid of 2048 x 2048 x 36 (more than 2 M cells of 4) with a box of
/// voxel noise (512 x 1024 x 36), whose blocks of codes are all distinct, within the bytes of its tree and
/// coarser cut a binding: the codes take more than three such bindings.
#[test]
fn codes_that_fit_nowhere_leave_the_finer_cut_without_them() {
    use voxlab::technique::sparse_octant::SparseOctant;
    let dims = UVec3::new(2048, 2048, 36);
    let mut grid = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
    let mut rng = StdRng::seed_from_u64(11);
    for z in 0..36 {
        for y in 0..1024 {
            for x in 0..512 {
                grid.set(IVec3::new(x, y, z), rng.random_range(0..4u8));
            }
        }
    }
    let tree = grid.tree(2);
    let fine = SparseOctant::without_codes(tree.clone(), 3);
    let budget = SparseOctant::without_codes(tree.clone(), 4).device_bytes();
    let walk = SparseOctant::build_within(tree.clone(), budget);
    assert!(!walk.has_codes());
    assert_eq!(walk.log_cell(), 3);
    assert!(walk == fine);
    let said = walk.summary().unwrap();
    assert!(
        said.contains("cells of 8") && said.contains("do not fit beside the cut"),
        "{said}"
    );
    // Within room enough, the nodes' cells of 16 with the codes.
    let roomy = SparseOctant::build_within(tree, usize::MAX);
    assert!(roomy.has_codes() && roomy.log_cell() == 4);
    assert!(
        roomy.codes().len() * 4 > 3 * budget,
        "{} bytes",
        4 * roomy.codes().len()
    );
}
