//! The GPU tracer keeps its cone pyramids between renders: a render whose pyramid
//! inputs are unchanged reuses them, any change of those inputs rebuilds them, and a
//! rebuilt pyramid gives bit for bit the image a fresh tracer gives (nothing stale).

mod common;

use common::{
    DENSE_WALK, OCTANT_WALK, PROXIMITY_WALK, SPARSE_OCTANT_WALK, SPARSE_WALK, experiment, tracer,
};

use glam::DVec3;
use voxlab::Frame;
use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;
use voxlab::scene::Light;

/// The experiment at side x side pixels, on the dense walk: it has no data of its own,
/// so a render's setup time is its pyramids' alone (under `"auto"` a grid of side 16
/// or more takes the octant walk, whose field the setup time counts too).
fn load(name: &str, side: u32) -> Experiment {
    let mut e = experiment(name);
    e.settings.width = side;
    e.settings.height = side;
    e.settings.traversal = DENSE_WALK;
    e
}

fn render(gpu: &mut GpuTracer, e: &Experiment) -> Frame {
    gpu.render(&e.scene, &e.settings).unwrap().frame
}

/// The image a tracer without a cache history gives.
fn fresh(e: &Experiment) -> Frame {
    render(&mut tracer(), e)
}

fn move_first_light(e: &mut Experiment) {
    match &mut e.scene.lights[0] {
        Light::Point(p) => p.position += DVec3::new(1.5, -0.75, 0.5),
        Light::Area(a) => a.position += DVec3::new(1.5, -0.75, 0.5),
    }
}

#[test]
fn indirect_pyramids_are_reused_and_rebuilt_when_their_inputs_change() {
    let mut gpu = tracer();
    let mut e = load("indirect.toml", 32);
    let first = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 1);
    assert!(gpu.last_setup_time() > std::time::Duration::ZERO);
    assert_eq!(
        render(&mut gpu, &e),
        first,
        "a reused pyramid changed the image"
    );
    assert_eq!(gpu.pyramid_builds(), 1, "same scene, built again");

    // The camera is no input of the pyramids.
    e.scene.camera.yaw += 0.1;
    let moved = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 1, "camera moved, pyramid rebuilt");
    assert_eq!(moved, fresh(&e));

    // kt sets the solid's opacity and the injection's shadow rays.
    e.scene.materials[3].kt = 0.5;
    let kt = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 2, "kt changed, pyramid not rebuilt");
    assert_ne!(kt, moved);
    assert_eq!(kt, fresh(&e), "kt changed: stale pyramid");

    // A light is injected into the radiance pyramid.
    move_first_light(&mut e);
    let lit = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 3, "light moved, pyramid not rebuilt");
    assert_ne!(lit, kt);
    assert_eq!(lit, fresh(&e), "light moved: stale pyramid");

    // A setting the injection reads.
    e.settings.falloff = !e.settings.falloff;
    let falloff = render(&mut gpu, &e);
    assert_eq!(
        gpu.pyramid_builds(),
        4,
        "falloff changed, pyramid not rebuilt"
    );
    assert_eq!(falloff, fresh(&e), "falloff changed: stale pyramid");

    // Rendering without cones keeps the cache for the next cone render.
    let mut plain = e.clone();
    plain.settings.features.set_term("indirect", false);
    plain.settings.features.set_term("ambient_occlusion", false);
    render(&mut gpu, &plain);
    assert_eq!(gpu.last_setup_time(), std::time::Duration::ZERO);
    assert_eq!(render(&mut gpu, &e), falloff);
    assert_eq!(
        gpu.pyramid_builds(),
        4,
        "cache lost across a render without cones"
    );
}

#[test]
fn opacity_pyramid_ignores_lights_and_rebuilds_on_grid_and_layout() {
    let mut gpu = tracer();
    let mut e = load("ambient_occlusion.toml", 32);
    let first = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 1);

    // Without indirect light only the opacity is built, and lights are not its input.
    move_first_light(&mut e);
    let lit = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 1, "light moved, opacity rebuilt");
    assert_ne!(lit, first);
    assert_eq!(lit, fresh(&e));

    // Grid contents.
    let data = e.scene.grid.data_mut();
    let i = data.iter().position(|&m| m != 0).unwrap();
    data[i] = 0;
    let carved = render(&mut gpu, &e);
    assert_eq!(gpu.pyramid_builds(), 2, "grid changed, opacity not rebuilt");
    assert_eq!(carved, fresh(&e), "grid changed: stale pyramid");

    // Layout (0 chose it automatically).
    e.settings.cones.levels = 2;
    let levels = render(&mut gpu, &e);
    assert_eq!(
        gpu.pyramid_builds(),
        3,
        "levels changed, opacity not rebuilt"
    );
    assert_eq!(levels, fresh(&e), "levels changed: stale pyramid");
}

/// Walks of one grid in turn build their data once each while two are kept (what
/// `voxlab bench` does frame by frame), give a fresh tracer's images, and a third walk
/// or another grid builds again: what is kept stays bounded.
#[test]
fn walks_in_turn_build_their_data_once() {
    let mut e = load("baseline.toml", 24);
    let at = |e: &Experiment, walk| Experiment {
        settings: voxlab::RenderSettings {
            traversal: walk,
            ..e.settings.clone()
        },
        ..e.clone()
    };
    let mut gpu = tracer();
    let mut builds = Vec::new();
    for walk in [
        SPARSE_WALK,
        SPARSE_OCTANT_WALK,
        SPARSE_WALK,
        SPARSE_OCTANT_WALK,
    ] {
        let frame = render(&mut gpu, &at(&e, walk));
        assert_eq!(frame, fresh(&at(&e, walk)), "{}", walk.name());
        builds.push(gpu.walk_data_builds());
    }
    assert_eq!(builds, [1, 2, 2, 2]);
    // A walk without data of its own (the dense walk) keeps them too.
    render(&mut gpu, &at(&e, DENSE_WALK));
    render(&mut gpu, &at(&e, SPARSE_WALK));
    assert_eq!(gpu.walk_data_builds(), 2);
    // Two more walks with data: the oldest two give way.
    for walk in [OCTANT_WALK, PROXIMITY_WALK] {
        render(&mut gpu, &at(&e, walk));
    }
    assert_eq!(gpu.walk_data_builds(), 4);
    render(&mut gpu, &at(&e, SPARSE_OCTANT_WALK));
    assert_eq!(gpu.walk_data_builds(), 5, "the oldest build gave way");
    // Another grid: its own data.
    e.scene.grid.set(glam::IVec3::new(3, 1, 3), 1);
    let frame = render(&mut gpu, &at(&e, SPARSE_OCTANT_WALK));
    assert_eq!(gpu.walk_data_builds(), 6, "another grid builds again");
    assert_eq!(frame, fresh(&at(&e, SPARSE_OCTANT_WALK)));
}

/// A walk's data is kept by the hash of the voxels it walks, which is of the bytes
/// alone: a grid of the same bytes in another shape (a volume reshaped) has other data,
/// and renders as a fresh tracer renders it after the first shape's render, on every
/// walk (before the dims were in the key, the walks with data of their own drew the
/// second shape through the first's data).
#[test]
fn the_same_voxels_in_another_shape_build_their_own_walk_data() {
    let first = load("baseline.toml", 24);
    let shapes = [
        glam::UVec3::new(8, 16, 32),
        glam::UVec3::new(32, 16, 8),
        glam::UVec3::new(16, 32, 8),
    ];
    for walk in voxlab::render::Traversal::walks() {
        let at = |e: &Experiment| Experiment {
            settings: voxlab::RenderSettings {
                traversal: walk,
                ..e.settings.clone()
            },
            ..e.clone()
        };
        let mut gpu = tracer();
        render(&mut gpu, &at(&first));
        for dims in shapes {
            let mut e = first.clone();
            let g = &first.scene.grid;
            let mut grid = voxlab::scene::Grid::new(dims, g.voxel_size(), g.origin()).unwrap();
            grid.data_mut().copy_from_slice(g.data());
            assert_eq!(grid.content_hash(), g.content_hash());
            e.scene.grid = grid;
            let builds = gpu.walk_data_builds();
            let frame = render(&mut gpu, &at(&e));
            let name = format!("{} walk, {dims} after {}", walk.name(), g.dims());
            assert_eq!(frame, fresh(&at(&e)), "{name}: the first shape's data");
            if at(&e).settings.traversal != DENSE_WALK {
                assert_eq!(gpu.walk_data_builds(), builds + 1, "{name}");
            }
        }
    }
}
