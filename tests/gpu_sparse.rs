//! The sparse walk on the GPU (`render.traversal = "sparse"`, shaders/traversal_sparse.wgsl),
//! and every other walk that skips regions (the proximity field): the golden baseline
//! images with each forced on; GPU against the f64 reference
//! and against the GPU's own dense walk over generated scenes that vary every parameter
//! that changes how the kernel runs (grid sizes from 1 to 100 a side, so tree depths 1 to
//! 4; image sizes; depth limits; both transmittances; sampled area lights over several
//! frames per dispatch); and the plan: the dense grid texture is not held while the tree
//! is walked.

mod common;

use common::{
    BOXES_WALK, DENSE_WALK, OCTANT_WALK, PROXIMITY_WALK, SPARSE_OCTANT_WALK, SPARSE_WALK,
};
use common::{assert_agree, assert_matches_golden, cpu_render_reusing, experiment, linear, tracer};
use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::render::{RenderSettings, Traversal};
use voxlab::scene::{
    AreaLight, AreaShape, Grid, Light, Scene, seed_ids, seed_scene, seed_scene_dims,
};

/// Every registered walk but the dense one: those that skip regions.
fn skipping_walks() -> Vec<Traversal> {
    Traversal::walks()
        .into_iter()
        .filter(|&t| t != DENSE_WALK)
        .collect()
}

#[test]
fn golden_baseline_images_with_the_tree_forced_on() {
    let mut gpu = tracer();
    for walk in skipping_walks() {
        for (name, w, h, refl, refr) in [
            ("baseline_160", 160, 160, 4, 4),
            ("baseline_200x120", 200, 120, 4, 4),
            ("baseline_depth0_128", 128, 128, 0, 0),
        ] {
            let mut e = experiment("baseline.toml");
            e.settings.width = w;
            e.settings.height = h;
            e.settings.max_reflection_depth = refl;
            e.settings.max_refraction_depth = refr;
            e.settings.traversal = walk;
            let frame = gpu.render(&e.scene, &e.settings).unwrap().frame;
            let plan = gpu.last_plan().unwrap();
            assert_eq!(Traversal::Walk(plan.traversal), walk, "{plan}");
            assert_matches_golden(
                &format!("{name} {}", walk.name()),
                &frame,
                &format!("{name}.png"),
            );
        }
    }
}

/// A scene over a random sparse grid of the seed's materials (glass, semi-solid, solid):
/// boxes of random size over a void or glass background, so that rays start, travel
/// and end in uniform regions of every material, with the seed's lights and camera.
fn random_scene(rng: &mut StdRng, dims: UVec3) -> Scene {
    let mut scene = seed_scene_dims(dims).unwrap();
    let mut g = Grid::new(dims, scene.grid.voxel_size(), scene.grid.origin()).unwrap();
    let mats = [
        seed_ids::VOID,
        seed_ids::GLASS,
        seed_ids::SEMI_SOLID,
        seed_ids::SOLID,
    ];
    g.data_mut().fill(if rng.random_bool(0.7) {
        seed_ids::VOID
    } else {
        seed_ids::GLASS
    });
    let d = dims.as_ivec3();
    for _ in 0..rng.random_range(1..8) {
        let size = (IVec3::new(
            rng.random_range(1..=d.x),
            rng.random_range(1..=d.y),
            rng.random_range(1..=d.z),
        ) / 2)
            .max(IVec3::ONE);
        let lo = IVec3::new(
            rng.random_range(0..=d.x - size.x),
            rng.random_range(0..=d.y - size.y),
            rng.random_range(0..=d.z - size.z),
        );
        let m = mats[rng.random_range(0..mats.len())];
        for z in lo.z..lo.z + size.z {
            for y in lo.y..lo.y + size.y {
                for x in lo.x..lo.x + size.x {
                    g.set(IVec3::new(x, y, z), m);
                }
            }
        }
    }
    scene.grid = g;
    scene
}

fn settings(w: u32, h: u32, depth: u32, traversal: Traversal) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        max_reflection_depth: depth,
        max_refraction_depth: depth,
        traversal,
        ..Default::default()
    }
}

#[test]
fn generated_scenes_agree_with_the_cpu_and_the_dense_walk() {
    let mut rng = StdRng::seed_from_u64(16);
    let mut gpu = tracer();
    // Sides 1..100: tree depths 1 to 4, non-cubic and non-power-of-two grids.
    let cases: [([u32; 3], u32, u32, u32); 7] = [
        ([1, 1, 1], 24, 24, 2),
        ([5, 3, 7], 40, 24, 4),
        ([16, 16, 16], 48, 48, 4),
        ([33, 17, 20], 56, 40, 3),
        ([64, 64, 64], 48, 48, 4),
        ([100, 30, 70], 40, 56, 1),
        ([48, 48, 48], 32, 32, 0),
    ];
    for (i, (dims, w, h, depth)) in cases.into_iter().enumerate() {
        let mut scene = random_scene(&mut rng, UVec3::from_array(dims));
        for walk in skipping_walks() {
            let mut s = settings(w, h, depth, walk);
            if i % 2 == 1 {
                // Beer-Lambert: a region's length counts at once.
                s.features.transmittance = voxlab::technique::beer_lambert::ID;
                for m in &mut scene.materials[1..] {
                    m.sigma = Some(DVec3::new(0.2, 0.05, 0.6));
                }
            }
            let name = format!(
                "{} walk, {dims:?} {w}x{h} depth {depth} {:?}",
                walk.name(),
                s.features.transmittance
            );
            let sparse = gpu.render(&scene, &s).unwrap();
            assert_eq!(
                Traversal::Walk(gpu.last_plan().unwrap().traversal),
                walk,
                "{name}"
            );
            let dense = gpu
                .render(
                    &scene,
                    &RenderSettings {
                        traversal: DENSE_WALK,
                        ..s.clone()
                    },
                )
                .unwrap();
            let cpu = voxlab::cpu::render(&scene, &s);
            assert_agree(
                &format!("{name} sparse GPU vs CPU"),
                &sparse.frame,
                &cpu.frame,
            );
            // The same voxels, hits and arithmetic of shading: the two GPU walks agree
            // closely (f32 may break an exact tie of planes differently at a region's exit
            // only where the ray grazes an edge).
            let d = linear(&sparse.frame, &dense.frame, 1e-4);
            assert!(
                d.fraction_over() < 0.005,
                "{name}: this and the dense GPU walk differ: {d}"
            );
            // The same rays, as `voxlab bench` requires of every walk.
            let rays = |s: &voxlab::frame::RayStats| (s.primary, s.secondary, s.shadow);
            assert_eq!(rays(&sparse.stats), rays(&dense.stats), "{name}");
        }
    }
}

#[test]
fn sampled_area_lights_over_many_frames_per_dispatch() {
    let mut scene = seed_scene(40).unwrap();
    let c = scene.grid.centre();
    scene.lights = vec![Light::Area(AreaLight {
        emission: Default::default(),
        shape: AreaShape::Rect {
            width: 12.0,
            height: 8.0,
        },
        position: c + DVec3::new(0.0, 30.0, 35.0),
        normal: DVec3::new(0.0, -0.6, -0.8),
        rotation: 0.3,
        color: DVec3::ONE,
        intensity: 2500.0,
    })];
    let mut gpu = tracer();
    for walk in skipping_walks() {
        let mut s = settings(32, 32, 2, walk);
        s.features.shadow_model = &voxlab::technique::area::MODEL;
        s.light_samples = 2;
        s.spp = 24;
        let g = gpu.render(&scene, &s).unwrap();
        let c = voxlab::cpu::render(&scene, &s);
        let name = format!("area light, 24 frames, {} walk", walk.name());
        assert_agree(&name, &g.frame, &c.frame);
    }
}

#[test]
fn the_sparse_plan_holds_the_tree_not_the_grid_texture() {
    let scene = seed_scene(64).unwrap();
    let mut gpu = tracer();
    gpu.render(&scene, &settings(16, 16, 1, SPARSE_WALK))
        .unwrap();
    let sparse = gpu.last_memory().unwrap();
    gpu.render(&scene, &settings(16, 16, 1, DENSE_WALK))
        .unwrap();
    let dense = gpu.last_memory().unwrap();
    assert_eq!(dense.grid, 64 * 64 * 64, "the voxel buffer");
    assert_eq!(dense.walk_data, 0);
    assert_eq!(sparse.grid, 0, "neither the voxel buffer nor the texture");
    assert!(
        sparse.walk_data > 0 && sparse.walk_data < dense.grid,
        "{sparse:?}"
    );
    // The sparse octant walk: in the tree's place a header of no nodes (with codes
    // whose descents take one level the kernel reads none of the tree), the cut's two
    // header vec4s, a vec4 for each of its cells (of 4 voxels a side at 64^3), a
    // block index for each leaf (the nodes below the cut there; to a vec4 boundary) and
    // four words (planes) for each voxel of each distinct block of the leaves' words.
    gpu.render(&scene, &settings(16, 16, 1, SPARSE_OCTANT_WALK))
        .unwrap();
    let cut = gpu.last_memory().unwrap();
    assert_eq!(cut.grid, 0, "{cut:?}");
    let coded = scene.grid.tree(2).nodes_up_to(2).1.len() as u64;
    assert!(coded > 0);
    let walk = voxlab::technique::sparse_octant::SparseOctant::build(scene.grid.tree(2));
    let blocks = walk.codes().len() as u64 - coded.next_multiple_of(4);
    assert_eq!(blocks % 256, 0);
    assert!(
        blocks > 0 && blocks / 256 < coded,
        "{} blocks",
        blocks / 256
    );
    assert_eq!(
        cut.walk_data,
        16 + 32 + 16 * 16 * 16 * 16 + 4 * coded.next_multiple_of(4) + 4 * blocks,
        "{cut:?}"
    );
    // The proximity walk: two bytes a voxel of its own, no voxel buffer.
    gpu.render(&scene, &settings(16, 16, 1, PROXIMITY_WALK))
        .unwrap();
    let proximity = gpu.last_memory().unwrap();
    assert_eq!(proximity.grid, 0, "{proximity:?}");
    assert_eq!(proximity.walk_data, 2 * 64 * 64 * 64, "{proximity:?}");
    // The octant walk: a word a voxel.
    gpu.render(&scene, &settings(16, 16, 1, OCTANT_WALK))
        .unwrap();
    let octant = gpu.last_memory().unwrap();
    assert_eq!(octant.grid, 0, "{octant:?}");
    assert_eq!(octant.walk_data, 4 * 64 * 64 * 64, "{octant:?}");
    // The box walk: four words a voxel.
    gpu.render(&scene, &settings(16, 16, 1, BOXES_WALK))
        .unwrap();
    let boxes = gpu.last_memory().unwrap();
    assert_eq!(boxes.grid, 0, "{boxes:?}");
    assert_eq!(boxes.walk_data, 16 * 64 * 64 * 64, "{boxes:?}");
    // Auto: dense below BOXES_FROM_SIDE, the box walk from it on, the sparse octant walk
    // from SPARSE_FROM_SIDE on; the plan says why.
    use voxlab::technique::{boxes::BOXES_FROM_SIDE, sparse::SPARSE_FROM_SIDE};
    for (n, want) in [
        (BOXES_FROM_SIDE - 1, DENSE_WALK),
        (BOXES_FROM_SIDE, BOXES_WALK),
        (SPARSE_FROM_SIDE - 1, BOXES_WALK),
        (SPARSE_FROM_SIDE, SPARSE_OCTANT_WALK),
    ] {
        let scene = seed_scene_dims(UVec3::new(n, 3, 2)).unwrap();
        let plan = voxlab::plan::Plan::new(&scene, &settings(8, 8, 1, Traversal::Auto));
        assert_eq!(Traversal::Walk(plan.traversal), want, "{plan}");
        assert!(plan.to_string().contains("traversal:"), "{plan}");
    }
}

/// Under `"auto"` a walk whose data the device cannot bind gives way to the last walk
/// that claims the grid and whose data it binds: past the box field's sixteen bytes a
/// voxel the octant field's four, past those the proximity field's two, past those the
/// dense grid's one (the tree claims only from its side), and past all of them the
/// tree.
#[test]
fn auto_takes_the_walk_the_device_binds() {
    use voxlab::technique::TraversalModel;
    let choose = |dims: UVec3, limit: u64| {
        let scene = seed_scene_dims(dims).unwrap();
        let fits = |t: &TraversalModel| t.binds_within(dims, limit);
        let (walk, why) =
            voxlab::plan::auto_traversal_within(&scene, &settings(8, 8, 1, Traversal::Auto), fits);
        (Traversal::Walk(walk), why)
    };
    let dims = UVec3::splat(64);
    let voxels = 64 * 64 * 64;
    for (limit, want) in [
        (16 * voxels, BOXES_WALK),
        (16 * voxels - 1, OCTANT_WALK),
        (4 * voxels, OCTANT_WALK),
        (4 * voxels - 1, PROXIMITY_WALK),
        (2 * voxels - 1, DENSE_WALK),
        (voxels - 1, SPARSE_OCTANT_WALK),
    ] {
        let (walk, why) = choose(dims, limit);
        assert_eq!(walk, want, "limit {limit}: {why}");
    }
    // The tracer itself, with its device's limit: a seed grid of sides below the
    // tree's whose octant field it cannot bind renders on the proximity walk and says
    // why. A device that binds more than such a grid's octant field keeps the octant
    // walk for the largest of them, or the box walk where it binds its field too.
    let mut gpu = tracer();
    let max = gpu.max_voxel_buffer_bytes();
    let side = SPARSE_FROM_SIDE_LESS_ONE;
    let depth = max / (4 * u64::from(side * side)) + 1;
    if depth < u64::from(side) {
        let scene = seed_scene_dims(UVec3::new(side, side, depth as u32)).unwrap();
        gpu.render(&scene, &settings(8, 8, 1, Traversal::Auto))
            .unwrap();
        let p = gpu.last_plan().unwrap();
        assert_eq!(Traversal::Walk(p.traversal), PROXIMITY_WALK, "{p}");
        assert!(
            p.traversal_reason.contains("more than this device binds"),
            "{p}"
        );
    } else {
        eprintln!("the device binds {max} bytes: every grid below the tree's side fits");
        let (walk, why) = choose(UVec3::splat(side), max);
        let boxes = 16 * u64::from(side).pow(3) <= max;
        let want = if boxes { BOXES_WALK } else { OCTANT_WALK };
        assert_eq!(walk, want, "{why}");
    }
    // From the tree's side on, the sparse octant walk whatever the device binds: never
    // the proximity field or the dense DDA that "auto" fell back to on lavapipe from
    // 320 to 511 when the tree claimed only from 512 (448^3: 1691 ms against 85); since
    // it claims from 256 every such side.
    for side in [side + 1, 320, 448, 511] {
        let (walk, why) = choose(UVec3::splat(side), max);
        assert_eq!(walk, SPARSE_OCTANT_WALK, "{side}: {why}");
    }
}

/// The largest side `"auto"` leaves to walks other than the tree.
const SPARSE_FROM_SIDE_LESS_ONE: u32 = voxlab::technique::sparse::SPARSE_FROM_SIDE - 1;

/// A grid held only as its tree (#16) renders on the GPU exactly as its dense twin
/// walked through the same tree, and as the CPU reference; nothing dense is on the
/// device.
#[test]
fn a_grid_held_sparse_renders_as_its_dense_twin() {
    use voxlab::scene::Storage;
    use voxlab::scene::seed::seed_grid_as;
    let mut gpu = tracer();
    for (dims, w, h, depth) in [
        ([24, 24, 24], 32, 32, 4),
        ([33, 17, 20], 40, 24, 2),
        ([70, 9, 64], 24, 40, 0),
    ] {
        let dims = UVec3::from_array(dims);
        let mut scene = seed_scene_dims(dims).unwrap();
        let s = settings(w, h, depth, SPARSE_WALK);
        let dense = gpu.render(&scene, &s).unwrap();
        scene.grid = seed_grid_as(dims, 1.0, DVec3::ZERO, Storage::Sparse).unwrap();
        let held = gpu.render(&scene, &s).unwrap();
        let memory = gpu.last_memory().unwrap();
        assert_eq!(memory.grid, 0, "{dims}: {memory:?}");
        assert!(memory.walk_data > 0, "{dims}");
        assert!(
            held.frame.pixels == dense.frame.pixels,
            "{dims}: the grid held sparse renders differently"
        );
        let cpu = voxlab::cpu::render(&scene, &s);
        assert_agree(&format!("{dims} held sparse"), &held.frame, &cpu.frame);
    }
}

/// The seed scene at 2048^3 (8 GiB dense; lavapipe's 3D textures end at 4096 and the
/// host refuses 2^31 voxels) renders through its tree, GPU as CPU, with the codes below
/// the cut on any device that binds 128 MiB (over four bindings there): issue 37's 12
/// steps a ray or fewer, where the walk without them took 59.
#[test]
fn the_seed_scene_at_2048_renders_through_its_tree() {
    // The seed's rules, as the goal: depth 4/4, a tree at most 4 deep.
    let text = "[scene]\nsize = 2048\n\n[render]\nwidth = 32\nheight = 32\nrules = \"seed\"\n";
    let e = voxlab::experiment::Experiment::from_str(text, "x.toml").unwrap();
    assert!(e.scene.grid.is_sparse());
    let mut gpu = tracer();
    let g = gpu.render_counted(&e.scene, &e.settings).unwrap();
    let memory = gpu.last_memory().unwrap();
    println!("seed 2048^3 on the device: {memory:?}");
    assert_eq!(memory.grid, 0);
    // A small part of the 8 GiB dense grid: the cut, whose cells hold their nodes'
    // heads (32 MiB), and the codes, whose distinct blocks (26.2 MiB) and the nodes' block
    // indices (5.2 MiB) follow it in one of lavapipe's bindings; the tree (104 MiB) stays
    // on the host.
    assert!(
        memory.walk_data > 32 << 20 && memory.walk_data <= 72 << 20,
        "{} bytes",
        memory.walk_data
    );
    assert_eq!(gpu.walk_data_bindings(), 1);
    // The reference walks the tracer's build (30 s on two cores): the same data.
    let c = cpu_render_reusing(&gpu, &e.scene, &e.settings);
    assert_agree("seed 2048^3", &g.frame, &c.frame);
    let steps_a_ray = |s: &voxlab::frame::RayStats| s.voxel_steps as f64 / s.total_rays() as f64;
    let (gs, cs) = (steps_a_ray(&g.stats), steps_a_ray(&c.stats));
    println!("seed 2048^3: {gs:.2} steps a ray on the GPU, {cs:.2} on the CPU");
    assert!(
        gs <= 12.0 && (gs - cs).abs() <= 0.005 * cs,
        "GPU {gs}, CPU {cs}"
    );
    // Not a blank image: the frame, the panes and the cube are hit.
    assert!(c.stats.voxel_steps > 0);
    let lit = g.frame.pixels.iter().filter(|p| p[0] > 0.2).count();
    assert!(lit > 10, "{lit} lit pixels");
}

/// Cells between the tree's levels: a grid held only as its tree whose cut of 4-voxel
/// cubes would pass `MAX_CELLS` is cut at 8 voxels, each mixed cell walked from the node
/// of 16 above it. GPU = CPU there, and the CPU the plain tree walk's rays and image in
/// fewer steps.
#[test]
fn the_sparse_octant_walk_with_cells_of_eight() {
    use voxlab::technique::sparse_octant::log_cell_side;
    let dims = UVec3::new(1024, 1024, 512);
    let scene = seed_scene_dims(dims).unwrap();
    assert!(scene.grid.is_sparse());
    assert_eq!(
        log_cell_side(dims, 2, voxlab::sparse::levels_for(dims, 2)),
        3
    );
    let s = settings(20, 16, 2, SPARSE_OCTANT_WALK);
    let mut gpu = tracer();
    let g = gpu.render(&scene, &s).unwrap();
    let plan = gpu.last_plan().unwrap();
    assert_eq!(
        Traversal::Walk(plan.traversal),
        SPARSE_OCTANT_WALK,
        "{plan}"
    );
    assert_eq!(plan.tree_levels, 2, "{plan}");
    let c = cpu_render_reusing(&gpu, &scene, &s);
    assert_agree("seed 1024x1024x512, cells of 8", &g.frame, &c.frame);
    // Without the codes (not within 1 MiB a binding): the kernel without them, whose
    // descent also takes two levels here.
    let bare = RenderSettings {
        walk_budget_mib: 1,
        ..s.clone()
    };
    let g_bare = gpu.render_counted(&scene, &bare).unwrap();
    assert_eq!(gpu.walk_data_bindings(), 1);
    let c_bare = cpu_render_reusing(&gpu, &scene, &bare);
    assert_walked_alike(
        "seed 1024x1024x512, cells of 8, no codes",
        &g_bare,
        &c_bare,
        0.005,
    );
    let g_coded = gpu.render_counted(&scene, &s).unwrap();
    assert!(
        g_bare.stats.voxel_steps > g_coded.stats.voxel_steps,
        "without codes {} steps, with {}",
        g_bare.stats.voxel_steps,
        g_coded.stats.voxel_steps
    );
    let tree = voxlab::cpu::render(
        &scene,
        &RenderSettings {
            traversal: SPARSE_WALK,
            ..s.clone()
        },
    );
    let rays = |s: &voxlab::frame::RayStats| (s.primary, s.secondary, s.shadow);
    assert_eq!(rays(&c.stats), rays(&tree.stats));
    assert_eq!(c.frame.pixels, tree.frame.pixels);
    assert!(c.stats.voxel_steps < tree.stats.voxel_steps);
}

/// Every stress case (`docs/stress.md`: eyes on lattice points and grid faces,
/// axis-parallel and grazing rays, total internal reflection, far origins, extreme
/// depths, every shadow and transmittance model, the grid at the device's side limit)
/// rendered on the GPU with each walk that skips regions gives the dense walk's rays
/// exactly and its image to f32 rounding: the skips' exits are exact at the settings
/// the suite makes stiff.
#[test]
fn every_walk_renders_the_stress_cases_as_the_dense_walk() {
    let mut gpu = tracer();
    let opts = voxlab::stress::SuiteOptions {
        max_grid_side: gpu.max_grid_side(),
        cube: None,
    };
    let cases = voxlab::stress::cases(&opts).unwrap();
    let mut compared = 0;
    for case in &cases {
        // At most four frames: the many-frames cases' 64 and 100 test how a dispatch
        // splits its frames (the suite's own GPU = CPU comparison), not the walks, and
        // took 120 of this test's 137 s; four frames still cast each area light's
        // samples from every pixel.
        let case_settings = RenderSettings {
            spp: case.settings.spp.min(4),
            ..case.settings.clone()
        };
        let dense_settings = RenderSettings {
            traversal: DENSE_WALK,
            ..case_settings.clone()
        };
        let dense = gpu.render(&case.scene, &dense_settings).unwrap();
        for walk in skipping_walks() {
            let s = RenderSettings {
                traversal: walk,
                ..case_settings.clone()
            };
            let name = format!("{}, {} walk", case.name, walk.name());
            let out = gpu.render(&case.scene, &s).unwrap();
            // A walk the case cannot have (its plan rule) is replaced by the plan's
            // choice; such a render compares nothing.
            if Traversal::Walk(gpu.last_plan().unwrap().traversal) != walk {
                continue;
            }
            let rays = |s: &voxlab::frame::RayStats| (s.primary, s.secondary, s.shadow);
            assert_eq!(rays(&out.stats), rays(&dense.stats), "{name}");
            // The same hits; only Beer-Lambert's sums differ in f32 rounding (a region's
            // length counts at once where the dense walk adds each voxel's).
            let d = linear(&out.frame, &dense.frame, 1e-5);
            assert_eq!(d.fraction_over(), 0.0, "{name}: {d}");
            compared += 1;
        }
    }
    // Every case with every skipping walk: all of them walk dense grids.
    assert_eq!(compared, cases.len() * skipping_walks().len());
}

/// The GPU builds a walk's data within its device's largest binding, a binding; on
/// lavapipe that is the CPU reference's budget, so both walk the same cells and codes
/// (and count the same steps).
#[test]
fn the_walk_budget_is_the_devices_binding() {
    use voxlab::technique::HOST_WALK_BYTES;
    let gpu = tracer();
    let max = usize::try_from(gpu.max_voxel_buffer_bytes()).unwrap();
    assert_eq!(gpu.walk_budget(), max);
    let adapter = gpu.adapter_info();
    if adapter.name.contains("llvmpipe") {
        assert_eq!(max, 128 << 20, "{adapter:?}");
        assert_eq!(gpu.walk_budget(), HOST_WALK_BYTES);
    }
}

/// The sparse octant walk at a small image, depth 2/2, its data built within `mib` MiB
/// a binding.
fn within_budget(mib: u32) -> RenderSettings {
    RenderSettings {
        width: 24,
        height: 20,
        max_reflection_depth: 2,
        max_refraction_depth: 2,
        traversal: SPARSE_OCTANT_WALK,
        walk_budget_mib: mib,
        ..RenderSettings::default()
    }
}

/// The GPU's render as the CPU reference's: the image, and the steps of the same
/// regions on both tracers but where f32 and f64 take another voxel at an edge (within
/// `steps` of the CPU's, a fraction).
fn assert_walked_alike(
    name: &str,
    g: &voxlab::frame::RenderOutput,
    c: &voxlab::frame::RenderOutput,
    steps: f64,
) {
    assert_agree(name, &g.frame, &c.frame);
    let (gs, cs) = (g.stats.voxel_steps, c.stats.voxel_steps);
    assert!(
        gs.abs_diff(cs) as f64 <= steps * cs as f64,
        "{name}: GPU {gs} steps, CPU {cs}"
    );
}

/// `render.walk_budget_mib` bounds what a walk's data holds on both tracers alike: the
/// seed scene at 256^3 under the sparse octant walk holds its codes within the
/// tracers' own budgets (0) and not within 1 MiB, so the steps differ and the images do
/// not; at each budget the GPU counts the CPU reference's steps (a device that binds
/// more than lavapipe walks as the reference does once the budget is set). A budget is
/// a key of the device's walk cache, and one above the device's binding is refused
/// with the key and the range it allows.
#[test]
fn the_walk_budget_setting_changes_the_steps_alike_and_never_the_image() {
    let scene = seed_scene(256).unwrap();
    let mut gpu = tracer();
    let at = |gpu: &mut voxlab::gpu::GpuTracer, mib: u32| {
        let s = within_budget(mib);
        let g = gpu.render_counted(&scene, &s).unwrap();
        let c = voxlab::cpu::render(&scene, &s);
        assert_walked_alike(&format!("walk budget {mib} MiB"), &g, &c, 0.005);
        // Both tracers say what their data holds, alike.
        assert_eq!(g.walk_data, c.walk_data, "walk budget {mib} MiB");
        (g, c)
    };
    let (g_own, c_own) = at(&mut gpu, 0);
    let (g_one, c_one) = at(&mut gpu, 1);
    assert_eq!(
        g_own.frame.pixels, g_one.frame.pixels,
        "the GPU's image moved"
    );
    assert_eq!(
        c_own.frame.pixels, c_one.frame.pixels,
        "the CPU's image moved"
    );
    assert!(
        c_one.stats.voxel_steps > 2 * c_own.stats.voxel_steps,
        "without the codes the walk takes more steps: {} against {}",
        c_one.stats.voxel_steps,
        c_own.stats.voxel_steps
    );
    // The plan says so: a budget that leaves the codes out is never silent.
    let own_text = c_own.walk_data.clone().unwrap();
    assert!(
        own_text.contains("children's codes of")
            && own_text.contains("after the cut (")
            && own_text.contains("the tree stays on the host"),
        "{own_text}"
    );
    let one_text = c_one.walk_data.clone().unwrap();
    assert!(
        one_text.contains("no codes, so more steps")
            && one_text.contains("within 1.0 MiB a binding")
            && one_text.contains("render.walk_budget_mib"),
        "{one_text}"
    );
    assert!(
        gpu.last_plan()
            .unwrap()
            .to_string()
            .contains(&format!("walk data: {one_text}")),
        "{}",
        gpu.last_plan().unwrap()
    );
    // Each budget built once: its own data, kept for the next render at it.
    let builds = gpu.walk_data_builds();
    at(&mut gpu, 0);
    assert_eq!(gpu.walk_data_builds(), builds);

    let above = (gpu.walk_budget() >> 20) as u32 + 1;
    let s = RenderSettings {
        width: 8,
        height: 8,
        walk_budget_mib: above,
        ..RenderSettings::default()
    };
    let e = format!("{:#}", gpu.render(&scene, &s).unwrap_err());
    assert!(
        e.contains(&format!("render.walk_budget_mib = {above}"))
            && e.contains(&format!("allowed 0..={}", above - 1)),
        "{e}"
    );
}

/// A walk's data past one binding where its descents take two levels: the seed scene
/// at 1024^3 within 27 MiB a binding holds its cut, whose cells hold their nodes' heads
/// (4.0 MiB), in `walk_data` and its codes (24.5 MiB: the nodes' block indices and the
/// distinct blocks) in a further binding (`walk_more_word`, shaders/bindings.wgsl); all
/// of it (28.5 MiB) would not fit one. The GPU walks them to the image and the steps of
/// the same data in the device's own budget (on lavapipe all of it in one binding, the
/// codes after the cut), and to the CPU reference's image and steps at 27 MiB. Two and three further
/// bindings, which the seed scene's few distinct blocks never need, are walked by
/// `generated_scenes_walk_their_codes_wherever_held`.
#[test]
fn codes_in_a_further_binding_walk_as_codes_after_the_cut() {
    let scene = seed_scene(1024).unwrap();
    let mut gpu = tracer();
    let own = gpu.render_counted(&scene, &within_budget(0)).unwrap();
    assert_eq!(gpu.walk_data_bindings(), 1);
    let apart = gpu.render_counted(&scene, &within_budget(27)).unwrap();
    assert_eq!(gpu.walk_data_bindings(), 2);
    assert!(
        apart.frame.pixels == own.frame.pixels,
        "the codes in a further binding render another image"
    );
    assert_eq!(apart.stats.voxel_steps, own.stats.voxel_steps);
    let text = apart.walk_data.clone().unwrap();
    assert!(text.contains(") in 1 more of 27.0 MiB"), "{text}");
    assert!(text.contains("hold their nodes' heads"), "{text}");
    let cpu = voxlab::cpu::render(&scene, &within_budget(27));
    assert_walked_alike("codes in a further binding", &apart, &cpu, 0.005);
    assert_eq!(apart.walk_data, cpu.walk_data);
}

/// A generated case's own image and depth limits (0 to 4): each case its own ray trees.
#[derive(Clone, Copy)]
struct CaseImage {
    w: u32,
    h: u32,
    depth: u32,
}

impl CaseImage {
    fn random(
        rng: &mut StdRng,
        widths: std::ops::RangeInclusive<u32>,
        heights: std::ops::RangeInclusive<u32>,
    ) -> Self {
        Self {
            w: rng.random_range(widths),
            h: rng.random_range(heights),
            depth: rng.random_range(0..=4),
        }
    }

    /// Its settings for the sparse octant walk within `mib` MiB a binding.
    fn within(&self, mib: u32) -> RenderSettings {
        RenderSettings {
            width: self.w,
            height: self.h,
            max_reflection_depth: self.depth,
            max_refraction_depth: self.depth,
            ..within_budget(mib)
        }
    }
}

impl std::fmt::Display for CaseImage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{} depth {}", self.w, self.h, self.depth)
    }
}

/// A scene of `random_scene` with a box of voxel noise in it (each voxel one of the seed's
/// materials at random, solid ones at `density`): nearly every 4-voxel cube of the box is
/// a leaf of the tree with its own codes, so the box's side sets how many MiB of codes
/// the sparse octant walk has.
fn noisy_scene(rng: &mut StdRng, dims: UVec3, noise: u32, density: f64) -> Scene {
    let mut scene = random_scene(rng, dims);
    let n = IVec3::splat(noise as i32).min(dims.as_ivec3());
    let lo = (dims.as_ivec3() - n) / 2;
    let solid = [seed_ids::GLASS, seed_ids::SEMI_SOLID, seed_ids::SOLID];
    for z in lo.z..lo.z + n.z {
        for y in lo.y..lo.y + n.y {
            for x in lo.x..lo.x + n.x {
                let m = if rng.random_bool(density) {
                    solid[rng.random_range(0..solid.len())]
                } else {
                    seed_ids::VOID
                };
                scene.grid.set(IVec3::new(x, y, z), m);
            }
        }
    }
    scene
}

/// The sparse octant walk's codes wherever its budget puts them, on generated scenes
/// (grids of 112 to 176 a side, non-cubic, a box of noise whose leaves hold a few MiB of
/// codes; images of 12 to 36 by 10 to 30 pixels, depth limits 0 to 4): for each scene
/// the smallest whole-MiB budget that leaves them out (the kernel without codes) and
/// that puts them in one, two and three further bindings,
/// found by building the walk's data as the tracers do. At each, the GPU holds that many
/// bindings and renders the image of its own budget (lavapipe: every code after the
/// cut, one binding), with its steps where it has the codes, and the CPU reference's
/// image and steps at the same budget. Each place must occur among the scenes, or the
/// test says so.
#[test]
fn generated_scenes_walk_their_codes_wherever_held() {
    use voxlab::technique::sparse_octant::{CodesAt, SparseOctant};
    use voxlab::technique::{WALK_MORE_BINDINGS, walk_part_words};
    let mut rng = StdRng::seed_from_u64(37);
    let mut gpu = tracer();
    // Without codes, then over 1, 2, 3 further bindings.
    let mut seen = [0; 1 + WALK_MORE_BINDINGS];
    for case in 0..4 {
        let dims = UVec3::new(
            rng.random_range(112..=176),
            rng.random_range(112..=176),
            rng.random_range(112..=176),
        );
        let noise = rng.random_range(80..=116);
        let density = rng.random_range(0.1..0.6);
        let image = CaseImage::random(&mut rng, 12..=36, 10..=30);
        let budget = |mib: u32| image.within(mib);
        let scene = noisy_scene(&mut rng, dims, noise, density);
        let tree = scene.grid.tree(2);
        // The smallest budget for each place.
        let mut budgets = [None; 1 + WALK_MORE_BINDINGS];
        for mib in 1..=32u32 {
            let budget = (mib as usize) << 20;
            let walk = SparseOctant::build_within(tree.clone(), budget);
            match (walk.has_codes(), walk.codes_at()) {
                (true, CodesAt::MoreBindings) => {
                    let n = walk.codes().len().div_ceil(walk_part_words(budget));
                    budgets[n].get_or_insert(mib);
                }
                // All of it in one binding from here on.
                (true, CodesAt::WalkData) => break,
                (false, _) => {
                    budgets[0].get_or_insert(mib);
                }
            }
        }
        let name = format!("case {case}: {dims} noise {noise} density {density:.2}, {image}");
        eprintln!("{name}: budgets without codes, for 1, 2, 3 further bindings {budgets:?}");
        let own = gpu.render_counted(&scene, &budget(0)).unwrap();
        assert_eq!(gpu.walk_data_bindings(), 1, "{name}");
        for (n, mib) in budgets.iter().enumerate() {
            let Some(mib) = *mib else { continue };
            seen[n] += 1;
            let s = budget(mib);
            let g = gpu.render_counted(&scene, &s).unwrap();
            let at = format!("{name}, {mib} MiB a binding");
            assert_eq!(gpu.walk_data_bindings(), 1 + n, "{at}");
            assert!(
                g.frame.pixels == own.frame.pixels,
                "{at}: the walk {} renders another image",
                if n == 0 {
                    "without codes".to_string()
                } else {
                    format!("with its codes over {n} further bindings")
                }
            );
            if n > 0 {
                assert_eq!(g.stats.voxel_steps, own.stats.voxel_steps, "{at}");
            }
            // Noise has far more edges than the seed scene for a ray to graze, where f32
            // and f64 may take another voxel and a pixel another ray tree.
            let c = voxlab::cpu::render(&scene, &s);
            assert_walked_alike(&at, &g, &c, 0.02);
        }
    }
    assert!(
        seen.iter().all(|&n| n > 0),
        "scenes without codes, with codes over 1, 2, 3 further bindings: {seen:?}"
    );
}

/// The kernel whose cells hold their nodes' heads (cells of 16 below nodes of 16:
/// descents of two levels, the tree left on the host) on generated scenes: grids of
/// 960 to 1024 by 900 to 1024 by 160 to 200 voxels (past `MAX_CELLS` cells of 4),
/// random boxes and a box of voxel noise of 24 to 64 a side (leaves with codes of their
/// own, and nodes of 16 whose descents end at either level); images of 12 to 28 by 10
/// to 24 pixels, depth limits 0 to 4. The GPU with the codes after the cut and in a
/// further binding (the smallest whole-MiB budget that puts them there) renders the
/// same image and steps, and the CPU reference's, which walks the tree.
#[test]
fn generated_scenes_walk_the_cells_heads() {
    use voxlab::technique::sparse_octant::{CodesAt, SparseOctant, log_cell_side};
    let mut rng = StdRng::seed_from_u64(16);
    let mut gpu = tracer();
    for case in 0..3 {
        let dims = UVec3::new(
            rng.random_range(960..=1024),
            rng.random_range(900..=1024),
            rng.random_range(160..=200),
        );
        assert_eq!(
            log_cell_side(dims, 2, voxlab::sparse::levels_for(dims, 2)),
            3
        );
        let noise = rng.random_range(24..=64);
        let density = rng.random_range(0.1..0.6);
        let image = CaseImage::random(&mut rng, 12..=28, 10..=24);
        let budget = |mib: u32| image.within(mib);
        let scene = noisy_scene(&mut rng, dims, noise, density);
        let name = format!("case {case}: {dims} noise {noise} density {density:.2}, {image}");
        let tree = scene.grid.tree(2);
        let apart = (1..=16u32)
            .find(|&mib| {
                let walk = SparseOctant::build_within(tree.clone(), (mib as usize) << 20);
                walk.has_codes() && walk.codes_at() == CodesAt::MoreBindings
            })
            .unwrap_or_else(|| panic!("{name}: no budget puts the codes in further bindings"));
        let own = gpu.render_counted(&scene, &budget(0)).unwrap();
        let plan = gpu.last_plan().unwrap();
        assert_eq!(
            (plan.walk_variant, plan.tree_levels),
            (2, 2),
            "{name}: {plan}"
        );
        assert_eq!(gpu.walk_data_bindings(), 1, "{name}");
        let c = voxlab::cpu::render(&scene, &budget(0));
        assert_walked_alike(&name, &own, &c, 0.02);
        let g = gpu.render_counted(&scene, &budget(apart)).unwrap();
        let at = format!("{name}, {apart} MiB a binding");
        assert_eq!(gpu.last_plan().unwrap().walk_variant, 2, "{at}");
        assert!(gpu.walk_data_bindings() > 1, "{at}");
        assert!(g.frame.pixels == own.frame.pixels, "{at}: another image");
        assert_eq!(g.stats.voxel_steps, own.stats.voxel_steps, "{at}");
        let c = voxlab::cpu::render(&scene, &budget(apart));
        assert_walked_alike(&at, &g, &c, 0.02);
    }
}
