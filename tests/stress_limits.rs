//! The longest grid side the device's 3D textures allow: rendered and checked against
//! the oracle; one voxel past it refused with an error that names the limit where the
//! grid must be a texture (the cone pyramids), and rendered by both walks, which read
//! buffers, matching the oracle.

mod common;

use common::tracer;
use glam::{DVec3, UVec3};
use voxlab::RenderSettings;
use voxlab::scene::{Grid, MAX_VOXELS, seed_scene_dims};
use voxlab::stress::{SuiteOptions, Verdict, generated_cases, run_case};

#[test]
fn longest_side_at_the_device_limit_renders_and_matches() {
    let mut gpu = tracer();
    let side = gpu.max_grid_side();
    let opts = SuiteOptions {
        max_grid_side: side,
        cube: None,
    };
    let name = format!("grid-{side}x8x8");
    let case = generated_cases(&opts)
        .unwrap()
        .into_iter()
        .find(|c| c.name == name)
        .unwrap();
    assert_eq!(case.scene.grid.dims(), UVec3::new(side, 8, 8));
    let row = run_case(Some(&mut gpu), &case);
    println!(
        "{name}: {} bytes, {} ill-conditioned px, {} over among the others",
        row.grid_bytes, row.ill_conditioned, row.over_well_conditioned
    );
    assert_eq!(row.verdict(), Verdict::Pass, "{:?}", row.verdict());
}

#[test]
fn one_past_the_texture_limit_renders_on_both_walks() {
    let mut gpu = tracer();
    let side = gpu.max_grid_side();
    let scene = seed_scene_dims(UVec3::new(side + 1, 2, 3)).unwrap();
    for traversal in voxlab::render::Traversal::walks() {
        let settings = RenderSettings {
            width: 24,
            height: 16,
            traversal,
            ..Default::default()
        };
        let g = gpu.render(&scene, &settings).unwrap();
        let plan = gpu.last_plan().unwrap();
        assert_eq!(
            voxlab::render::Traversal::Walk(plan.traversal),
            traversal,
            "{plan}"
        );
        let c = voxlab::cpu::render(&scene, &settings);
        common::assert_agree("one past the texture limit", &g.frame, &c.frame);
    }
}

#[test]
fn one_past_the_limit_is_a_clear_error() {
    let mut gpu = tracer();
    let side = gpu.max_grid_side();
    for dims in [
        UVec3::new(side + 1, 1, 1),
        UVec3::new(1, side + 1, 1),
        UVec3::new(1, 1, side + 1),
    ] {
        let scene = seed_scene_dims(dims).unwrap();
        let mut settings = RenderSettings {
            width: 8,
            height: 8,
            ..Default::default()
        };
        // The pyramids of cone shadows are 3D textures.
        settings.features.shadow_model = &voxlab::technique::cone::MODEL;
        let err = format!("{:#}", gpu.render(&scene, &settings).unwrap_err());
        assert!(
            err.contains("max_texture_dimension_3d") && err.contains(&side.to_string()),
            "{dims}: {err}"
        );
        assert!(
            err.contains(&format!("{}x{}x{}", dims.x, dims.y, dims.z)),
            "{err}"
        );
    }
    // The host's own cap comes before any device: 2^31 voxels.
    let too_many = UVec3::new(2048, 2048, 513);
    let err = Grid::new(too_many, 1.0, DVec3::ZERO)
        .unwrap_err()
        .to_string();
    assert!(err.contains(&MAX_VOXELS.to_string()), "{err}");
}

#[test]
fn long_walks_on_a_large_grid_keep_hits_on_their_faces() {
    // The seed scene at 256^3: primary and secondary rays walk hundreds of voxels. With
    // tMax accumulated by += tDelta in f32 the hit points drifted off their faces by more
    // than the ray offset and 4 % of the pixels differed from the oracle; tMax taken from
    // the boundary plane at every step (shaders/traversal.wgsl) leaves none.
    let mut gpu = tracer();
    let opts = SuiteOptions {
        max_grid_side: gpu.max_grid_side(),
        cube: Some(256),
    };
    let case = generated_cases(&opts)
        .unwrap()
        .into_iter()
        .find(|c| c.name == "grid-256^3")
        .unwrap();
    let row = run_case(Some(&mut gpu), &case);
    let d = row.diff.unwrap();
    println!(
        "{}: {d}; {} ill-conditioned",
        case.name, row.ill_conditioned
    );
    assert_eq!(row.verdict(), Verdict::Pass, "{:?}", row.verdict());
    assert_eq!(row.over_well_conditioned, 0);
}
