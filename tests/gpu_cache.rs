//! The GPU tracer keeps what it builds between renders (cone pyramids, walk data, a
//! shadow model's field, surfaces): a render whose inputs are unchanged reuses them,
//! any change of those inputs rebuilds them, and every render gives bit for bit the
//! image a fresh tracer gives (nothing stale), over changes of every input.

mod common;

use common::{
    DENSE_WALK, OCTANT_WALK, PROXIMITY_WALK, SPARSE_OCTANT_WALK, SPARSE_WALK, experiment, tracer,
};

use std::path::Path;

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

/// The CPU reference walks the walk data the GPU tracer keeps where it is the build
/// the reference would make (`render --check`): the same `Arc`, the image and counts
/// of a render that builds its own; and where the key differs (the voxels in another
/// shape, another budget, another walk) it builds its own.
#[test]
fn the_cpu_reference_walks_the_gpu_tracers_build_only_of_its_own_key() {
    use voxlab::cpu::Prepared;
    use voxlab::plan::Plan;
    use voxlab::technique::{HOST_WALK_BYTES, WalkKey, walk_budget};
    let first = load("baseline.toml", 24);
    for walk in voxlab::render::Traversal::walks() {
        let e = Experiment {
            settings: voxlab::RenderSettings {
                traversal: walk,
                ..first.settings.clone()
            },
            ..first.clone()
        };
        let mut gpu = tracer();
        render(&mut gpu, &e);
        let plan = Plan::new(&e.scene, &e.settings);
        let kept = |k: &WalkKey| gpu.kept_walk_data(k);
        let reusing = Prepared::reusing(&e.scene, &e.settings, &plan, &kept);
        let name = walk.name();
        let Some(data) = plan
            .traversal
            .data
            .map(|_| reusing.regions.clone().unwrap())
        else {
            assert!(reusing.regions.is_none(), "{name}");
            continue;
        };
        let budget = walk_budget(&e.settings, HOST_WALK_BYTES);
        let key = WalkKey::new(plan.traversal, &e.scene.grid, budget);
        let held = gpu
            .kept_walk_data(&key)
            .expect("the tracer keeps its build");
        assert!(std::sync::Arc::ptr_eq(&data, &held), "{name}: built again");
        let (w, h) = (e.settings.width, e.settings.height);
        let own = voxlab::cpu::render(&e.scene, &e.settings);
        let shared = voxlab::cpu::render_region_reusing(&e.scene, &e.settings, 0..w, 0..h, &kept);
        assert_eq!(shared.frame, own.frame, "{name}");
        assert_eq!(shared.stats.voxel_steps, own.stats.voxel_steps, "{name}");
        // Another key: none kept.
        let g = &e.scene.grid;
        let mut reshaped = voxlab::scene::Grid::new(
            glam::UVec3::new(8, 16, 32).min(g.dims() * 2),
            g.voxel_size(),
            g.origin(),
        )
        .unwrap();
        let n = reshaped.data().len().min(g.data().len());
        reshaped.data_mut()[..n].copy_from_slice(&g.data()[..n]);
        let others = [
            WalkKey::new(plan.traversal, &reshaped, budget),
            WalkKey::new(plan.traversal, g, budget / 2),
            WalkKey::new(voxlab::technique::default_traversal(), g, budget),
        ];
        for (k, other) in others.iter().enumerate() {
            assert!(gpu.kept_walk_data(other).is_none(), "{name}: other key {k}");
        }
    }
}

type Change = (&'static str, fn(&mut Experiment));

/// Changes of every input of a scene whose first light is an area light and whose
/// materials 1 and 2 exist, one at a time (each applies to the state the ones before
/// it left).
fn input_changes() -> Vec<Change> {
    use voxlab::scene::{AreaShape, Emission};
    vec![
        ("light turned", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.normal = (a.normal + DVec3::new(0.7, 0.0, 0.0)).normalize();
            }
        }),
        ("light isotropic", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.emission = Emission::Isotropic;
            }
        }),
        ("light Lambertian again", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.emission = Emission::Lambertian;
            }
        }),
        ("light rotated about its normal", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.rotation += 0.6;
            }
        }),
        ("light resized", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.shape = AreaShape::Disk { radius: 2.5 };
            }
        }),
        ("light moved", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.position += DVec3::new(-1.0, 0.5, 2.0);
            }
        }),
        ("light colour", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.color = DVec3::new(1.0, 0.5, 0.25);
            }
        }),
        ("light intensity", |e| {
            if let Light::Area(a) = &mut e.scene.lights[0] {
                a.intensity *= 2.0;
            }
        }),
        ("a point light's intensity", |e| {
            if let Some(Light::Point(p)) = e.scene.lights.get_mut(1) {
                p.intensity *= 0.5;
            }
        }),
        ("albedo", |e| e.scene.materials[1].albedo *= 0.5),
        ("kd", |e| e.scene.materials[1].kd *= 0.5),
        ("ks", |e| e.scene.materials[1].ks = 0.9),
        ("shininess", |e| e.scene.materials[1].shininess *= 2.0),
        ("kr", |e| e.scene.materials[1].kr = 0.3),
        ("kt", |e| e.scene.materials[2].kt = 0.4),
        ("ior", |e| e.scene.materials[2].ior = 1.9),
        ("sigma", |e| {
            e.scene.materials[2].sigma = Some(DVec3::new(0.5, 0.2, 0.1))
        }),
        ("ambient", |e| e.scene.ambient = DVec3::splat(0.05)),
        ("falloff", |e| e.settings.falloff = !e.settings.falloff),
        ("falloff distance", |e| {
            e.settings.falloff_min_distance *= 3.0
        }),
        ("ray offset", |e| e.settings.ray_offset *= 4.0),
        ("levels", |e| e.settings.cones.levels = 2),
        ("aperture", |e| e.settings.cones.aperture_deg *= 0.5),
        ("AO range", |e| e.settings.cones.ao_range *= 0.5),
        ("indirect strength", |e| {
            e.settings.cones.indirect_strength *= 2.0
        }),
        ("a voxel", |e| {
            e.scene.grid.set(glam::IVec3::new(5, 3, 5), 1)
        }),
    ]
}

/// Applies `changes` in turn to `e`, rendering each on one tracer that keeps what it
/// built, and compares each image with a fresh tracer's.
fn assert_nothing_stale(what: &str, mut e: Experiment, changes: &[Change]) {
    let mut gpu = tracer();
    render(&mut gpu, &e);
    for (name, change) in changes {
        change(&mut e);
        let kept = render(&mut gpu, &e);
        assert_eq!(
            kept,
            fresh(&e),
            "{what}, {name}: what the tracer kept drew another image"
        );
    }
}

/// Every input of the scene and settings, changed one at a time on a tracer that keeps
/// its pyramids, against a fresh tracer's image: whatever the key leaves out must not
/// change the image. A Lambertian rect light over the indirect and ambient-occlusion
/// scene (the radiance pyramid reads the emitter's normal and emission: turning it drew
/// the old light's pyramid before they were in the key), each light and material field,
/// the settings the injection reads, a voxel.
#[test]
fn no_input_change_draws_a_stale_pyramid() {
    let mut e = load("indirect.toml", 16);
    e.settings.features.set_term("ambient_occlusion", true);
    lambertian_rect(&mut e);
    assert_nothing_stale("indirect light and AO", e, &input_changes());
}

/// The same changes under the distance-field shadow model (its field kept while its
/// inputs are the same), on the walks that keep data of their own, and on the smooth
/// surface (its triangles kept).
#[test]
fn no_input_change_draws_a_stale_field_or_walk() {
    let mut e = load("indirect.toml", 16);
    e.settings.features.set_term("indirect", false);
    lambertian_rect(&mut e);
    let mut sdf = e.clone();
    sdf.settings.features.shadow_model =
        voxlab::technique::shadow_model("sdf").expect("the sdf shadow model");
    let plan = voxlab::plan::Plan::new(&sdf.scene, &sdf.settings);
    assert_eq!(plan.shadow_model.name, "sdf", "{plan}");
    assert_nothing_stale("sdf shadows", sdf, &input_changes());
    for walk in [OCTANT_WALK, PROXIMITY_WALK, SPARSE_OCTANT_WALK] {
        let mut w = e.clone();
        w.settings.traversal = walk;
        assert_nothing_stale(walk.name(), w, &input_changes());
    }
    let mut smooth = e.clone();
    smooth.settings.surface = common::SMOOTH_SURFACE;
    let plan = voxlab::plan::Plan::new(&smooth.scene, &smooth.settings);
    assert_eq!(plan.surface.name(), "smooth", "{plan}");
    assert_nothing_stale("smooth surface", smooth, &input_changes());
}

/// The experiment's first light as a Lambertian rect light facing the grid's centre.
fn lambertian_rect(e: &mut Experiment) {
    use voxlab::scene::{AreaLight, AreaShape, Emission};
    let (c, p) = (e.scene.grid.centre(), e.scene.lights[0].position());
    e.scene.lights[0] = Light::Area(AreaLight {
        shape: AreaShape::Rect {
            width: 3.0,
            height: 2.0,
        },
        emission: Emission::Lambertian,
        position: p,
        normal: (c - p).normalize(),
        rotation: 0.0,
        color: DVec3::ONE,
        intensity: 300.0,
    });
}

/// A render on a session that has rendered other things before gives bit for bit the
/// image of a fresh session: generated sequences over the shipped experiments with
/// image sizes of one pixel count in several shapes, every walk, surfaces, shadow
/// models, reconstructions, samples and camera paths (what each render leaves behind
/// on the device: pyramids, walk data, fields, surfaces, filter buffers, histories).
#[test]
fn a_render_does_not_depend_on_the_renders_before_it() {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(2026);
    let files = [
        "baseline.toml",
        "indirect.toml",
        "area_lights.toml",
        "deer_area_light.toml",
        "reconstruction.toml",
        "soft_coloured_shadows.toml",
        "deer_smooth.toml",
        "sdf.toml",
        "ratio.toml",
    ];
    let shapes = [(24, 16), (16, 24), (32, 12), (12, 32), (20, 20)];
    let walks = voxlab::render::Traversal::walks();
    let mut session = voxlab::Session::new(voxlab::Backend::Gpu).expect("a GPU adapter");
    let mut rendered = 0;
    for case in 0..24 {
        let file = files[rng.random_range(0..files.len())];
        let (w, h) = shapes[rng.random_range(0..shapes.len())];
        let mut sets = vec![
            format!("render.width={w}"),
            format!("render.height={h}"),
            format!("render.spp={}", rng.random_range(1..=3)),
            format!(
                "render.traversal=\"{}\"",
                walks[rng.random_range(0..walks.len())].name()
            ),
        ];
        if rng.random_bool(0.3) {
            sets.push(format!(
                "features.reconstruction=\"{}\"",
                ["atrous", "svgf"][rng.random_range(0..2)]
            ));
            sets.push(format!("render.path_frames={}", rng.random_range(1..=3)));
            sets.push(format!(
                "render.orbit_deg={}",
                [0.0, 2.0][rng.random_range(0..2)]
            ));
        }
        if rng.random_bool(0.3) {
            sets.push(format!("camera.yaw_deg={}", rng.random_range(-60..=60)));
        }
        let overrides: Vec<voxlab::experiment::Override> =
            sets.iter().map(|s| s.parse().unwrap()).collect();
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("experiments")
            .join(file);
        // A combination the file's scene cannot have (a reconstruction of a scene that
        // samples nothing, say) is refused by the parser: another case.
        let Ok(e) = Experiment::load_with(&path, &overrides) else {
            continue;
        };
        let name = format!("case {case}: {file} {sets:?}");
        let kept = session
            .render(&e)
            .unwrap_or_else(|err| panic!("{name}: {err}"));
        let fresh = voxlab::Session::new(voxlab::Backend::Gpu)
            .unwrap()
            .render(&e)
            .unwrap();
        assert!(
            kept.frame.pixels == fresh.frame.pixels,
            "{name}: the image depends on the renders before it"
        );
        rendered += 1;
    }
    eprintln!("{rendered} of 24 cases rendered");
    assert!(rendered >= 16, "only {rendered} cases rendered");
}
