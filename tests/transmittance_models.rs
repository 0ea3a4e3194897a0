//! What every transmittance model (`voxlab::technique::TRANSMITTANCES`) gets without a
//! test of its own: it is listed, parsed and written back, offered by `voxlab ablate`
//! and the stress suite; the default is the baseline's `min-kt`; through materials that
//! are fully clear or opaque every model gives exactly 1 or 0 (where all models agree);
//! the walk over the tree equals the dense walk; and GPU = CPU over image sizes, depth
//! limits, frames of sampled area lights, both walks and triangle surfaces.
//!
//! Tolerances: those of tests/gpu_agreement.rs (`assert_agree`).

mod common;

use common::{BOXES_WALK, DENSE_WALK, OCTANT_WALK, PROXIMITY_WALK, SMOOTH_SURFACE, SPARSE_WALK};
use common::{assert_agree, tracer};
use glam::{DVec3, IVec3, UVec3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::RayStats;
use voxlab::experiment::{Experiment, write};
use voxlab::render::{RenderSettings, Transmittance};
use voxlab::scene::{AreaLight, AreaShape, Grid, Light, seed_ids, seed_scene, seed_scene_dims};
use voxlab::sparse::SparseTree;
use voxlab::technique::shading::shadow_transmittance_over;
use voxlab::technique::{self, Slot, TRANSMITTANCES};

fn every_model() -> impl Iterator<Item = Transmittance> {
    TRANSMITTANCES.iter().map(|&m| Transmittance(m))
}

#[test]
fn every_model_is_declared_listed_parsed_and_offered() {
    assert_eq!(Transmittance::default().model().index(), 0);
    assert_eq!(Transmittance::default().name(), "min-kt", "the baseline's");
    let listing = technique::listing();
    let ablate = voxlab::ablate::AblateConfig::default();
    for t in every_model() {
        let m = t.model();
        assert!(!m.summary.is_empty() && !m.wgsl.1.is_empty(), "{}", m.name);
        assert!(
            m.wgsl
                .1
                .contains("#define_import_path voxlab::transmittance"),
            "{}: the WGSL module's import path",
            m.name
        );
        assert!(
            listing
                .iter()
                .any(|r| r.name == m.name && r.slot == Slot::Transmittance),
            "{} not listed",
            m.name
        );
        assert_eq!(technique::transmittance(m.name), Some(t));
        let text = format!("[features]\ntransmittance = \"{}\"\n", m.name);
        let e = Experiment::from_str(&text, "x.toml").unwrap();
        assert_eq!(e.settings.features.transmittance, t);
        let written = write::to_toml(&e, &toml::Table::new()).unwrap();
        let back = Experiment::from_str(&written, "x.toml").unwrap();
        assert_eq!(back.settings.features.transmittance, t, "{}", m.name);
        assert!(
            ablate.transmittance.contains(&t),
            "{} not in ablate",
            m.name
        );
    }
    let err = Experiment::from_str("[features]\ntransmittance = \"fog\"\n", "x.toml")
        .unwrap_err()
        .to_string();
    for t in every_model() {
        assert!(err.contains(t.name()), "{err}");
    }
}

/// A grid of clear (kt 1, no absorption) and opaque (kt 0) voxels: every model gives
/// exactly 1 or 0, the same as every other that lets the clear material through (its
/// `voxel_transmittance` is 1), on the dense walk and on the tree's; one that stops it
/// (`opaque`) gives 0 wherever those do, and on the segments that cross only void.
#[test]
fn clear_and_opaque_materials_give_exactly_one_or_zero_in_every_model() {
    let mut rng = StdRng::seed_from_u64(0x7a);
    let mut scene = seed_scene(16).unwrap();
    // Material 1 clear, 2 opaque.
    scene.materials[1].kt = 1.0;
    scene.materials[1].sigma = Some(DVec3::ZERO);
    scene.materials[2].kt = 0.0;
    let dims = UVec3::new(20, 13, 17);
    let mut g = Grid::new(dims, 0.7, DVec3::new(-1.0, 0.5, 2.0)).unwrap();
    for (i, v) in g.data_mut().iter_mut().enumerate() {
        *v = match i % 53 {
            0 => 2,
            k if k < 20 => 1,
            _ => 0,
        };
    }
    scene.grid = g;
    let tree = SparseTree::build(&scene.grid, 2);
    let lo = scene.grid.world_min() - 2.0;
    let hi = scene.grid.world_max() + 2.0;
    let point = |rng: &mut StdRng| {
        DVec3::new(
            rng.random_range(lo.x..hi.x),
            rng.random_range(lo.y..hi.y),
            rng.random_range(lo.z..hi.z),
        )
    };
    let mut opaque = 0;
    for _ in 0..2000 {
        let (q, l) = (point(&mut rng), point(&mut rng));
        let (mut values, mut stopping) = (Vec::new(), Vec::new());
        for t in every_model() {
            let lets_clear_through =
                (t.model().voxel_transmittance)(&scene.materials[1], scene.grid.voxel_size());
            for tr in [None, Some(&tree as &dyn voxlab::sparse::Regions)] {
                let v = shadow_transmittance_over(&scene, tr, t, q, l, &mut RayStats::default());
                assert!(
                    v == DVec3::ONE || v == DVec3::ZERO,
                    "{}: {v} from {q} to {l}",
                    t.name()
                );
                if lets_clear_through == 1.0 {
                    values.push(v);
                } else {
                    stopping.push(v);
                }
            }
        }
        assert!(values.iter().all(|v| *v == values[0]), "{values:?}");
        assert!(
            values.len() >= 4,
            "min-kt and beer-lambert let clear material through"
        );
        for v in &stopping {
            assert!(
                *v == stopping[0] && v.cmple(values[0]).all(),
                "{stopping:?} {values:?}"
            );
        }
        opaque += usize::from(values[0] == DVec3::ZERO);
    }
    assert!(opaque > 100 && opaque < 1900, "{opaque} of 2000 blocked");
}

/// Semi-transparent materials: the walk over the tree is the dense walk in every model.
#[test]
fn the_tree_walk_is_the_dense_walk_in_every_model() {
    let mut rng = StdRng::seed_from_u64(0x7b);
    let mut scene = seed_scene(16).unwrap();
    for m in &mut scene.materials[1..] {
        m.kt = 0.6;
        m.sigma = Some(DVec3::new(0.3, 0.1, 0.7));
    }
    let mut g = Grid::new(UVec3::new(24, 9, 31), 1.0, DVec3::ZERO).unwrap();
    let d = g.dims().as_ivec3();
    for _ in 0..6 {
        let lo = IVec3::new(
            rng.random_range(0..d.x),
            rng.random_range(0..d.y),
            rng.random_range(0..d.z),
        );
        let m = rng.random_range(1..4u8);
        for z in lo.z..d.z.min(lo.z + 9) {
            for y in lo.y..d.y.min(lo.y + 5) {
                for x in lo.x..d.x.min(lo.x + 7) {
                    g.set(IVec3::new(x, y, z), m);
                }
            }
        }
    }
    scene.grid = g;
    let tree = SparseTree::build(&scene.grid, 2);
    for t in every_model() {
        for _ in 0..500 {
            let p = |rng: &mut StdRng| {
                DVec3::new(
                    rng.random_range(-3.0..27.0),
                    rng.random_range(-3.0..12.0),
                    rng.random_range(-3.0..34.0),
                )
            };
            let (q, l) = (p(&mut rng), p(&mut rng));
            let dense = shadow_transmittance_over(&scene, None, t, q, l, &mut RayStats::default());
            let sparse = shadow_transmittance_over(
                &scene,
                Some(&tree as &dyn voxlab::sparse::Regions),
                t,
                q,
                l,
                &mut RayStats::default(),
            );
            assert!(
                (dense - sparse).abs().max_element() < 1e-12,
                "{}: {dense} against {sparse}",
                t.name()
            );
            assert!(dense.cmpge(DVec3::ZERO).all() && dense.cmple(DVec3::ONE).all());
        }
    }
}

/// GPU = CPU for every model over the parameters that change how the kernel runs.
#[test]
fn every_model_gpu_equals_cpu() {
    let mut gpu = tracer();
    for t in every_model() {
        for (i, (n, w, h, depth, traversal)) in [
            (16, 40, 24, 4, DENSE_WALK),
            (20, 24, 40, 2, SPARSE_WALK),
            (9, 32, 32, 0, DENSE_WALK),
            (18, 36, 28, 3, PROXIMITY_WALK),
            (22, 30, 26, 3, OCTANT_WALK),
            (21, 28, 30, 2, BOXES_WALK),
        ]
        .into_iter()
        .enumerate()
        {
            let mut scene = seed_scene_dims(UVec3::new(n, n - 3, n + 2)).unwrap();
            for m in &mut scene.materials[1..] {
                m.sigma = Some(DVec3::new(0.4, 0.05, 0.9));
            }
            let mut s = RenderSettings {
                width: w,
                height: h,
                max_reflection_depth: depth,
                max_refraction_depth: depth,
                traversal,
                ..Default::default()
            };
            s.features.transmittance = t;
            if i == 0 {
                // Sampled area light over several frames per dispatch.
                let c = scene.grid.centre();
                scene.lights.push(Light::Area(AreaLight {
                    emission: Default::default(),
                    shape: AreaShape::Rect {
                        width: 5.0,
                        height: 3.0,
                    },
                    position: c + DVec3::new(2.0, 14.0, 9.0),
                    normal: DVec3::new(0.0, -0.8, -0.6),
                    rotation: 0.2,
                    color: DVec3::ONE,
                    intensity: 400.0,
                }));
                s.features.shadow_model = &voxlab::technique::area::MODEL;
                s.light_samples = 2;
                s.spp = 12;
            }
            let name = format!("{} {n} {w}x{h} depth {depth} {traversal:?}", t.name());
            let g = gpu.render(&scene, &s).unwrap();
            let plan = gpu.last_plan().unwrap();
            assert_eq!(plan.transmittance.name, t.name(), "{name}: {plan}");
            let c = voxlab::cpu::render(&scene, &s);
            assert_agree(&name, &g.frame, &c.frame);
        }
        // Through a triangle surface: the smooth seed scene.
        let mut scene = seed_scene(12).unwrap();
        scene.materials[seed_ids::GLASS as usize].sigma = Some(DVec3::new(0.5, 0.1, 0.2));
        let mut s = RenderSettings {
            width: 32,
            height: 24,
            max_reflection_depth: 2,
            max_refraction_depth: 2,
            surface: SMOOTH_SURFACE,
            ..Default::default()
        };
        s.features.transmittance = t;
        let g = gpu.render(&scene, &s).unwrap();
        let c = voxlab::cpu::render(&scene, &s);
        assert_agree(&format!("{} smooth surface", t.name()), &g.frame, &c.frame);
    }
}

#[test]
fn the_stress_suite_runs_every_model() {
    let cases = voxlab::stress::generated_cases(&voxlab::stress::SuiteOptions::default()).unwrap();
    for t in every_model() {
        assert!(
            cases
                .iter()
                .any(|c| c.settings.features.transmittance == t && c.name.contains(t.name())),
            "{} has no stress case",
            t.name()
        );
    }
}
