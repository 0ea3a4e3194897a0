//! Grids held only as their sparse tree (#16): trees built straight from a source (the
//! seed's rules, a `.vox` scene's bricks, boxes written over a tree) are word for word
//! the trees of the dense grids of the same scenes, for every branching; a grid held
//! sparse answers every voxel, material count and image as its dense twin; and the
//! experiment loader holds large grids sparse, refuses what needs the dense grid with the
//! key that asks for it, and bounds a sparse grid's sides.

mod common;

use common::{DENSE_WALK, SPARSE_OCTANT_WALK, SPARSE_WALK};
use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::experiment::Experiment;
use voxlab::render::RenderSettings;
use voxlab::scene::seed::{SeedSource, seed_grid_as};
use voxlab::scene::{
    DENSE_MAX_VOXELS, Grid, MAX_SPARSE_SIDE, Storage, load_vox_as, seed_ids, seed_palette,
    write_vox,
};
use voxlab::sparse::{BoxOverlay, BrickSource, SparseTree, VoxelSource};

/// Dimensions that vary what the builder meets: one voxel, sides below, at and past a
/// node's, non-cubic, odd and power-of-two grids.
const DIMS: [[u32; 3]; 10] = [
    [1, 1, 1],
    [2, 3, 1],
    [4, 4, 4],
    [5, 9, 3],
    [16, 16, 16],
    [17, 16, 15],
    [33, 20, 47],
    [64, 64, 64],
    [65, 2, 70],
    [100, 37, 81],
];

#[track_caller]
fn assert_same_tree(a: &SparseTree, b: &SparseTree, what: &str) {
    assert_eq!(a.dims(), b.dims(), "{what}");
    assert_eq!(a.node_count(), b.node_count(), "{what}: node counts");
    assert!(a.words() == b.words(), "{what}: the trees' words differ");
}

#[test]
fn the_seed_rules_build_the_dense_seed_grids_tree() {
    for dims in DIMS.map(UVec3::from_array) {
        let dense = seed_grid_as(dims, 1.0, DVec3::ZERO, Storage::Dense).unwrap();
        let source = SeedSource::new(dims);
        for b in 1..=3 {
            assert_same_tree(
                &SparseTree::build(&source, b),
                &SparseTree::build(&dense, b),
                &format!("seed {dims} branching {b}"),
            );
        }
        // Held sparse: every voxel, and the counts, are the dense grid's.
        let sparse = seed_grid_as(dims, 0.5, DVec3::new(1.0, -2.0, 0.25), Storage::Sparse).unwrap();
        assert!(sparse.is_sparse() && !dense.is_sparse());
        assert_eq!(sparse.material_counts(), dense.material_counts(), "{dims}");
        assert_eq!(sparse.materials_used(), dense.materials_used(), "{dims}");
        assert_eq!(sparse.max_material(), dense.max_material(), "{dims}");
        assert_eq!(sparse.voxel_count(), dense.voxel_count());
        assert_eq!(sparse.to_dense().unwrap().data(), dense.data(), "{dims}");
        for z in -1..=dims.z as i32 {
            for y in -1..=dims.y as i32 {
                for x in -1..=dims.x as i32 {
                    let v = IVec3::new(x, y, z);
                    assert_eq!(sparse.get(v), dense.get(v), "{dims} {v}");
                }
            }
        }
    }
}

#[test]
fn auto_storage_holds_only_large_grids_sparse() {
    let small = seed_grid_as(UVec3::splat(64), 1.0, DVec3::ZERO, Storage::Auto).unwrap();
    assert!(!small.is_sparse());
    // Just past DENSE_MAX_VOXELS, with a thin axis so the test stays cheap.
    let side = 1u32 << 14;
    assert!(u64::from(side) * u64::from(side) * 2 > DENSE_MAX_VOXELS);
    let dims = UVec3::new(side.min(MAX_SPARSE_SIDE), side.min(MAX_SPARSE_SIDE), 17);
    let big = seed_grid_as(dims, 1.0, DVec3::ZERO, Storage::Auto).unwrap();
    assert!(big.is_sparse(), "{dims} = {} voxels", big.voxel_count());
    let too_wide = UVec3::new(MAX_SPARSE_SIDE + 1, 4, 4);
    let err = seed_grid_as(too_wide, 1.0, DVec3::ZERO, Storage::Sparse)
        .unwrap_err()
        .to_string();
    assert!(err.contains(&MAX_SPARSE_SIDE.to_string()), "{err}");
}

/// A random sparse voxel set: a few blobs and scattered voxels of 1..=`materials`.
fn random_voxels(rng: &mut StdRng, dims: UVec3, materials: u8) -> Vec<(IVec3, u8)> {
    let d = dims.as_ivec3();
    let mut out = Vec::new();
    for _ in 0..rng.random_range(1..6) {
        let size = IVec3::new(
            rng.random_range(1..=d.x),
            rng.random_range(1..=d.y),
            rng.random_range(1..=d.z),
        ) / 3;
        let size = size.max(IVec3::ONE);
        let lo = IVec3::new(
            rng.random_range(0..=d.x - size.x),
            rng.random_range(0..=d.y - size.y),
            rng.random_range(0..=d.z - size.z),
        );
        let m = rng.random_range(1..=materials);
        for z in lo.z..lo.z + size.z {
            for y in lo.y..lo.y + size.y {
                for x in lo.x..lo.x + size.x {
                    out.push((IVec3::new(x, y, z), m));
                }
            }
        }
    }
    for _ in 0..rng.random_range(0..200) {
        let v = IVec3::new(
            rng.random_range(0..d.x),
            rng.random_range(0..d.y),
            rng.random_range(0..d.z),
        );
        out.push((v, rng.random_range(1..=materials)));
    }
    out
}

#[test]
fn bricks_build_the_dense_grids_tree() {
    let mut rng = StdRng::seed_from_u64(0x5eed);
    for (i, dims) in DIMS.map(UVec3::from_array).into_iter().enumerate() {
        for round in 0..3 {
            let voxels = random_voxels(&mut rng, dims, 1 + (i + round) as u8 % 5);
            let mut dense = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
            let mut bricks = BrickSource::new(dims);
            // Later writes win in both.
            for &(v, m) in &voxels {
                dense.set(v, m);
                bricks.set(v, m);
            }
            let reference: Vec<SparseTree> =
                (1..=3).map(|b| SparseTree::build(&dense, b)).collect();
            for b in 1..=3u32 {
                let mut copy = BrickSource::new(dims);
                for &(v, m) in &voxels {
                    copy.set(v, m);
                }
                assert_same_tree(
                    &copy.into_tree(b),
                    &reference[b as usize - 1],
                    &format!("bricks {dims} round {round} branching {b}"),
                );
            }
            // An empty set is one void region.
            let empty = BrickSource::new(dims).into_tree(2);
            assert_eq!(empty.node_count(), 1);
            assert_eq!(empty.materials_used()[1..], [false; 255]);
        }
    }
}

#[test]
fn boxes_over_a_tree_build_the_dense_grids_tree() {
    let mut rng = StdRng::seed_from_u64(0xb0c5);
    for dims in DIMS.map(UVec3::from_array) {
        for _ in 0..4 {
            let d = dims.as_ivec3();
            let boxes: Vec<(IVec3, IVec3, u8)> = (0..rng.random_range(0..6))
                .map(|_| {
                    let lo = IVec3::new(
                        rng.random_range(0..=d.x),
                        rng.random_range(0..=d.y),
                        rng.random_range(0..=d.z),
                    );
                    let hi = IVec3::new(
                        rng.random_range(lo.x..=d.x),
                        rng.random_range(lo.y..=d.y),
                        rng.random_range(lo.z..=d.z),
                    );
                    (lo, hi, rng.random_range(0..4u8))
                })
                .collect();
            let mut dense = seed_grid_as(dims, 1.0, DVec3::ZERO, Storage::Dense).unwrap();
            for &(lo, hi, m) in &boxes {
                for z in lo.z..hi.z {
                    for y in lo.y..hi.y {
                        for x in lo.x..hi.x {
                            dense.set(IVec3::new(x, y, z), m);
                        }
                    }
                }
            }
            let base = SparseTree::build(&SeedSource::new(dims), 2);
            let overlay = BoxOverlay {
                base: &base,
                boxes: &boxes,
            };
            assert_eq!(overlay.dims(), dims);
            for b in 1..=3 {
                assert_same_tree(
                    &SparseTree::build(&overlay, b),
                    &SparseTree::build(&dense, b),
                    &format!("{} boxes over seed {dims}, branching {b}", boxes.len()),
                );
            }
        }
    }
}

#[test]
fn vox_scenes_load_into_the_same_tree_sparse_as_dense() {
    // deer.vox (a real file), and generated grids wider than a MagicaVoxel model, which
    // write_vox splits into 256-voxel models placed by a scene graph.
    let mut files = vec![common::example_data("deer.vox")];
    let dir = std::env::temp_dir().join(format!("voxlab-sparse-vox-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = StdRng::seed_from_u64(0x70c5);
    for (i, dims) in [[300u32, 40, 270], [20, 513, 9], [9, 9, 9]]
        .into_iter()
        .enumerate()
    {
        let dims = UVec3::from_array(dims);
        let mut g = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
        for (v, m) in random_voxels(&mut rng, dims, 3) {
            g.set(v, m);
        }
        let path = dir.join(format!("generated_{i}.vox"));
        write_vox(&path, &g, &seed_palette()).unwrap();
        files.push(path);
    }
    for path in &files {
        let dense = load_vox_as(path, None, Storage::Dense).unwrap();
        let sparse = load_vox_as(path, None, Storage::Sparse).unwrap();
        let what = path.display().to_string();
        assert!(!dense.grid.is_sparse() && sparse.grid.is_sparse(), "{what}");
        assert_eq!(sparse.materials, dense.materials, "{what}");
        let tree = sparse.grid.sparse_tree().unwrap();
        assert_same_tree(tree, &SparseTree::build(&dense.grid, 2), &what);
        assert_eq!(
            sparse.grid.to_dense().unwrap().data(),
            dense.grid.data(),
            "{what}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The experiment loader: `scene.size` past DENSE_MAX_VOXELS gives a grid held sparse
/// (built in well under a second at 2048^3), boxes written over it; what needs the
/// dense grid is refused with the key that asks for it.
#[test]
fn experiments_hold_large_grids_sparse_and_say_what_needs_them_dense() {
    let load = |text: &str| Experiment::from_str(text, "experiments/x.toml");
    let e = load("[scene]\nsize = 2048\n\n[[scene.boxes]]\nmin = [1000, 1000, 1000]\nmax = [1100, 1010, 1048]\nmaterial = 3\n").unwrap();
    assert!(e.scene.grid.is_sparse());
    assert_eq!(e.scene.grid.dims(), UVec3::splat(2048));
    assert_eq!(e.scene.grid.get(IVec3::new(1050, 1005, 1047)), 3);
    // Beside the box, the seed's semi-solid cube (radius 128 about the centre) and void.
    assert_eq!(
        e.scene.grid.get(IVec3::new(1050, 1010, 1047)),
        seed_ids::SEMI_SOLID
    );
    assert_eq!(e.scene.grid.get(IVec3::new(10, 1005, 1047)), seed_ids::VOID);
    // Holding 2048^3 voxels: less than a bit each.
    let tree = e.scene.grid.sparse_tree().unwrap();
    assert!(tree.bytes_per_voxel() < 0.02, "{}", tree.bytes_per_voxel());
    let plan = voxlab::plan::Plan::new(&e.scene, &e.settings);
    assert_eq!(plan.traversal.name, "sparse_octant");
    assert!(plan.traversal_reason.contains("sparse tree"), "{plan}");

    let msg = load("[scene]\nsize = 1024\n\n[render]\ntraversal = \"dense\"\n")
        .unwrap_err()
        .to_string();
    for part in ["x.toml:5:", "render.traversal", "sparse tree", "\"sparse\""] {
        assert!(msg.contains(part), "{part}: {msg}");
    }
    let msg = load("[scene]\ndims = [5000, 300, 300]\n")
        .unwrap_err()
        .to_string();
    for part in ["x.toml:2:", "scene.dims", &MAX_SPARSE_SIDE.to_string()] {
        assert!(msg.contains(part), "{part}: {msg}");
    }
    let msg = load("[scene]\nsize = 1024\n\n[render]\nsurface = \"smooth\"\n")
        .unwrap_err()
        .to_string();
    for part in ["render.surface", "sparse tree"] {
        assert!(msg.contains(part), "{part}: {msg}");
    }
    let msg = load("[scene]\nsize = 700\n\n[features]\nambient_occlusion = true\n")
        .unwrap_err()
        .to_string();
    for part in ["x.toml:", "features", "dense grid", "sparse tree"] {
        assert!(msg.contains(part), "{part}: {msg}");
    }
    // Past the loader (a scene made in code), the plan leaves the cone terms out of a
    // grid held sparse, and says why.
    let mut e = load("[scene]\nsize = 1024\n").unwrap();
    e.settings.features.shadow_model = &voxlab::technique::cone::MODEL;
    e.settings.features.set_term("ambient_occlusion", true);
    let plan = voxlab::plan::Plan::new(&e.scene, &e.settings);
    assert!(
        plan.shadow_model.name != "cone"
            && !plan.terms.iter().any(|t| t.name == "ambient_occlusion")
            && plan.pyramid.is_none()
    );
    assert!(
        plan.reasons
            .iter()
            .any(|r| r.contains("cone pyramids") && r.contains("sparse tree")),
        "{plan}"
    );
}

/// The CPU reference renders a grid held sparse exactly as its dense twin walked sparse.
#[test]
fn a_grid_held_sparse_renders_as_its_dense_twin_on_the_cpu() {
    for (dims, depth) in [([24, 24, 24], 4), ([33, 17, 20], 2), ([7, 40, 9], 0)] {
        let dims = UVec3::from_array(dims);
        let mut scene = voxlab::scene::seed_scene_dims(dims).unwrap();
        let settings = RenderSettings {
            width: 24,
            height: 20,
            max_reflection_depth: depth,
            max_refraction_depth: depth,
            traversal: SPARSE_WALK,
            ..Default::default()
        };
        let dense = voxlab::cpu::render(&scene, &settings);
        let octant_cells = RenderSettings {
            traversal: SPARSE_OCTANT_WALK,
            ..settings.clone()
        };
        let dense_cells = voxlab::cpu::render(&scene, &octant_cells);
        scene.grid = seed_grid_as(dims, 1.0, DVec3::ZERO, Storage::Sparse).unwrap();
        // "dense" cannot be followed for a grid held sparse: the plan walks the tree, the
        // faster tree walk (the last registered that can).
        let forced = RenderSettings {
            traversal: DENSE_WALK,
            ..settings.clone()
        };
        for (s, twin) in [(&settings, &dense), (&forced, &dense_cells)] {
            let sparse = voxlab::cpu::render(&scene, s);
            assert!(
                sparse.frame.pixels == dense.frame.pixels,
                "{dims} depth {depth} {:?}",
                s.traversal
            );
            assert_eq!(sparse.stats.voxel_steps, twin.stats.voxel_steps);
        }
    }
}

/// A mesh voxelized straight into a tree is the tree of the same mesh voxelized densely:
/// the shell (last triangle wins), the outside flood over whole empty bricks, the filled
/// interior and enclosed cavities, on a real mesh and on generated ones at resolutions
/// that are and are not multiples of a brick.
#[test]
fn meshes_voxelize_into_the_same_tree_sparse_as_dense() {
    use voxlab::scene::mesh::{TriangleMesh, voxelize};
    use voxlab::scene::{Resolution, VoxelizeOptions, load_mesh};
    let sphere = |c: DVec3, r: f64, k: u32, flip: bool| -> Vec<[DVec3; 3]> {
        common::icosphere(k)
            .into_iter()
            .map(|t| {
                let t = t.map(|p| c + r * p);
                if flip { [t[0], t[2], t[1]] } else { t }
            })
            .collect()
    };
    let soup = |triangles: Vec<[DVec3; 3]>| TriangleMesh {
        material_of: vec![0; triangles.len()],
        materials: vec![seed_palette()[3].clone()],
        normals: vec![],
        triangles,
        warnings: vec![],
    };
    // A hollow ball (a cavity the dense fill fills), an open one (its inside reached
    // through the hole), two touching balls, and the bunny.
    let mut hollow = sphere(DVec3::ZERO, 1.0, 2, false);
    hollow.extend(sphere(DVec3::ZERO, 0.6, 2, true));
    let mut open = sphere(DVec3::ZERO, 1.0, 2, false);
    open.retain(|t| t.iter().all(|p| p.z < 0.8));
    let mut pair = sphere(DVec3::ZERO, 1.0, 2, false);
    pair.extend(sphere(DVec3::new(1.9, 0.3, 0.0), 0.9, 1, false));
    let bunny = load_mesh(common::example_data("bunny.obj")).unwrap();
    let meshes = [
        ("hollow", soup(hollow)),
        ("open", soup(open)),
        ("pair", soup(pair)),
        ("bunny", bunny),
    ];
    for (name, mesh) in &meshes {
        for n in [5, 16, 37, 64, 101] {
            let options = |storage| VoxelizeOptions {
                resolution: Resolution::Count(n),
                material: Some(seed_palette()[2].clone()),
                storage,
            };
            let dense = voxelize(mesh, &options(Storage::Dense)).unwrap();
            let sparse = voxelize(mesh, &options(Storage::Sparse)).unwrap();
            let what = format!("{name} at {n}");
            assert!(sparse.grid.is_sparse() && !dense.grid.is_sparse(), "{what}");
            assert_same_tree(
                sparse.grid.sparse_tree().unwrap(),
                &SparseTree::build(&dense.grid, 2),
                &what,
            );
            assert_eq!(sparse.shell_voxels, dense.shell_voxels, "{what}");
            assert_eq!(sparse.interior_voxels, dense.interior_voxels, "{what}");
            assert_eq!(sparse.grid.voxel_size(), dense.grid.voxel_size());
            assert_eq!(sparse.grid.origin(), dense.grid.origin());
        }
    }
    // The hollow ball's cavity is filled, the open ball's inside is not.
    let count = |mesh: &TriangleMesh| {
        let o = VoxelizeOptions {
            resolution: Resolution::Count(40),
            material: None,
            storage: Storage::Sparse,
        };
        voxelize(mesh, &o).unwrap().interior_voxels
    };
    assert!(count(&meshes[0].1) > 1000);
    assert_eq!(count(&meshes[1].1), 0);

    // Several materials: the dense fill's nearest-surface rule is not followed sparse.
    let mut two = soup(sphere(DVec3::ZERO, 1.0, 1, false));
    two.materials.push(seed_palette()[1].clone());
    two.material_of[0] = 1;
    let o = VoxelizeOptions {
        resolution: Resolution::Count(16),
        material: None,
        storage: Storage::Sparse,
    };
    let err = voxelize(&two, &o).unwrap_err().to_string();
    assert!(err.contains("one material"), "{err}");
}

/// `scene.mesh` past DENSE_MAX_VOXELS voxelizes into a tree, and `scene.material`
/// recolours it (the tree rebuilt through the table).
#[test]
fn a_mesh_experiment_past_the_dense_bound_is_held_sparse() {
    let bunny = common::example_data("bunny.obj");
    let text = format!(
        "[scene]\nmesh = \"{}\"\nresolution = 1024\nmaterial = \"solid\"\n",
        bunny.display()
    );
    let e = Experiment::from_str(&text, "x.toml").unwrap();
    assert!(e.scene.grid.is_sparse());
    let used = e.scene.grid.materials_used();
    let solid = e
        .scene
        .materials
        .iter()
        .position(|m| m.name == "solid")
        .unwrap();
    let used: Vec<usize> = (0..256).filter(|&m| used[m]).collect();
    assert_eq!(used, vec![0, solid]);
    println!(
        "bunny at 1024: {} voxels, tree {} bytes ({:.4} bytes/voxel)",
        e.scene.grid.voxel_count(),
        e.scene.grid.host_bytes(),
        e.scene.grid.sparse_tree().unwrap().bytes_per_voxel()
    );
}

/// Models written over a tree (`ModelOverlay`, how `[[scene.models]]` go into a grid
/// held sparse) give the tree of the dense grid they are written into voxel by voxel:
/// overlapping models, scales 1-5, void voxels that leave what is below.
#[test]
fn models_over_a_tree_build_the_dense_grids_tree() {
    use voxlab::sparse::{ModelOverlay, PlacedModel};
    let mut rng = StdRng::seed_from_u64(0x30de1);
    for dims in [[40u32, 33, 47], [64, 64, 64], [17, 70, 9]].map(UVec3::from_array) {
        for _ in 0..4 {
            let count = rng.random_range(1..4);
            let mut sources = Vec::new();
            for _ in 0..count {
                let side = UVec3::new(
                    rng.random_range(1..9),
                    rng.random_range(1..9),
                    rng.random_range(1..9),
                );
                let mut g = Grid::new(side, 1.0, DVec3::ZERO).unwrap();
                for v in g.data_mut() {
                    // Half void, so the models below and the seed show through.
                    *v = if rng.random_bool(0.5) {
                        0
                    } else {
                        rng.random_range(1..4)
                    };
                }
                let scale = rng.random_range(1..=5i32);
                let room = (dims.as_ivec3() - side.as_ivec3() * scale).max(IVec3::ZERO);
                let base = IVec3::new(
                    rng.random_range(0..=room.x),
                    rng.random_range(0..=room.y),
                    rng.random_range(0..=room.z),
                );
                let map: Vec<u8> = vec![0, 3, 1, 2];
                sources.push((g, base, scale, map));
            }
            let mut dense = seed_grid_as(dims, 1.0, DVec3::ZERO, Storage::Dense).unwrap();
            for (g, base, scale, map) in &sources {
                let d = g.dims().as_ivec3();
                for z in 0..d.z * scale {
                    for y in 0..d.y * scale {
                        for x in 0..d.x * scale {
                            let v = IVec3::new(x, y, z);
                            let k = g.get(v / *scale);
                            if k != 0 && dense.contains(*base + v) {
                                dense.set(*base + v, map[k as usize]);
                            }
                        }
                    }
                }
            }
            let models: Vec<PlacedModel> = sources
                .iter()
                .map(|(g, base, scale, map)| PlacedModel {
                    voxels: g,
                    base: *base,
                    scale: *scale,
                    map,
                })
                .collect();
            let base = SparseTree::build(&SeedSource::new(dims), 2);
            let overlay = ModelOverlay {
                base: &base,
                models: &models,
            };
            for b in 1..=3 {
                assert_same_tree(
                    &SparseTree::build(&overlay, b),
                    &SparseTree::build(&dense, b),
                    &format!("{count} models over seed {dims}, branching {b}"),
                );
            }
        }
    }
}

/// `[[scene.models]]` into a grid held sparse: the deer placed into the seed scene at
/// 700^3, its voxels where they belong; a model too large to place is refused by key.
#[test]
fn models_go_into_a_grid_held_sparse() {
    let deer = common::example_data("deer.vox");
    let text = format!(
        "[scene]\nsize = 700\n\n[[scene.models]]\nvox = \"{}\"\noffset = [300, 10, 320]\n",
        deer.display()
    );
    let e = Experiment::from_str(&text, "x.toml").unwrap();
    assert!(e.scene.grid.is_sparse());
    let v = voxlab::scene::load_vox(&deer, None).unwrap();
    let offset = IVec3::new(300, 10, 320);
    let d = v.grid.dims().as_ivec3();
    let mut placed = 0;
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let p = IVec3::new(x, y, z);
                let k = v.grid.get(p);
                let got = e.scene.grid.get(offset + p);
                if k != 0 {
                    // The deer's colour, under the palette's "deer " names.
                    assert_ne!(got, 0, "{p}");
                    assert_eq!(
                        e.scene.materials[got as usize].albedo, v.materials[k as usize].albedo,
                        "{p}"
                    );
                    placed += 1;
                } else {
                    // Void model voxels leave the seed scene's voxel.
                    let seed = SeedSource::new(UVec3::splat(700));
                    assert_eq!(got, seed.material(offset + p), "{p}");
                }
            }
        }
    }
    assert!(placed > 0);
    assert_eq!(placed, v.grid.material_counts()[1..].iter().sum::<u64>());
    // A model of 256^3 (two voxels) at scale 3 covers 768^3 voxels, past the bound.
    let dir = std::env::temp_dir().join(format!("voxlab-models-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut g = Grid::new(UVec3::splat(256), 1.0, DVec3::ZERO).unwrap();
    g.set(IVec3::ZERO, 1);
    g.set(IVec3::splat(255), 2);
    let big = dir.join("big.vox");
    write_vox(&big, &g, &seed_palette()).unwrap();
    let text = format!(
        "[scene]\nsize = 800\n\n[[scene.models]]\nvox = \"{}\"\nscale = 3\n",
        big.display()
    );
    let msg = match Experiment::from_str(&text, "x.toml") {
        Ok(_) => panic!("a 768^3 model was placed"),
        Err(e) => e.to_string(),
    };
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        msg.contains("scene.models[0].scale") && msg.contains("sparse tree"),
        "{msg}"
    );
}
