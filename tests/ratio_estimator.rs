//! The ratio estimator (src/technique/ratio.rs) beyond what tests/shadow_models.rs
//! holds every shadow model to: its closed form against quadrature, noise-free light
//! where nothing occludes, and convergence to the sampled area lights' reference.

mod common;

use common::rmse;
use glam::DVec3;
use rand::{RngExt, SeedableRng};
use voxlab::scene::{AreaLight, AreaShape, Grid, Light, Scene, seed_palette, seed_scene};
use voxlab::technique::ratio::clipped_field;
use voxlab::{RenderSettings, cpu};

/// `int max(n.l, 0) / r^2 dA` over the rectangle by the midpoint rule on a k x k grid.
fn quadrature(p: DVec3, n: DVec3, c: DVec3, u: DVec3, v: DVec3, k: usize) -> f64 {
    let da = u.cross(v).length() / (k * k) as f64;
    let mut sum = 0.0;
    for i in 0..k {
        for j in 0..k {
            let s = (i as f64 + 0.5) / k as f64 - 0.5;
            let t = (j as f64 + 0.5) / k as f64 - 0.5;
            let x = c + s * u + t * v;
            let to = x - p;
            let r2 = to.length_squared();
            sum += (n.dot(to) / r2.sqrt()).max(0.0) / r2 * da;
        }
    }
    sum
}

/// The closed form equals quadrature (to 1e-3 relative, or 1e-6 absolute) for random
/// points, normals and rectangles: in front, behind, cut by the tangent plane, close
/// to the light and far from it.
#[test]
fn the_closed_form_is_the_integral() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut cut = 0;
    for case in 0..400 {
        let c = DVec3::new(
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
        );
        let ne = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        let helper = if ne.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
        let u0 = helper.cross(ne).normalize();
        let v0 = ne.cross(u0);
        let (w, h) = (rng.random_range(0.1..3.0), rng.random_range(0.1..3.0));
        let (u, v) = (u0 * w, v0 * h);
        let p = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if (p - c).dot(ne).abs() < 0.3 {
            continue; // the quadrature needs the singularity kept away
        }
        let n = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        let corners = [
            c - 0.5 * u - 0.5 * v,
            c + 0.5 * u - 0.5 * v,
            c + 0.5 * u + 0.5 * v,
            c - 0.5 * u + 0.5 * v,
        ];
        let signs: Vec<bool> = corners.iter().map(|&x| n.dot(x - p) >= 0.0).collect();
        if signs.iter().any(|&s| s) && signs.iter().any(|&s| !s) {
            cut += 1;
        }
        let exact = clipped_field(p, n, &corners, ne);
        let numeric = quadrature(p, n, c, u, v, 600);
        let err = (exact - numeric).abs();
        assert!(
            err <= 1e-3 * numeric.abs() + 1e-6,
            "case {case}: closed form {exact}, quadrature {numeric}"
        );
    }
    assert!(cut > 50, "only {cut} rectangles cut by the tangent plane");
}

/// A floor lit by a rectangle light with nothing in between: the diffuse image of one
/// sample per pixel does not depend on the seed (no noise), and is the converged
/// sampled area light's.
#[test]
fn unoccluded_diffuse_light_is_free_of_noise() {
    let mut palette = seed_palette();
    palette[1].ks = 0.0;
    palette[1].kr = 0.0;
    palette[1].kt = 0.0;
    palette[1].kd = 1.0;
    let mut grid = Grid::new(glam::UVec3::new(16, 2, 16), 1.0, DVec3::ZERO).unwrap();
    for z in 0..16 {
        for x in 0..16 {
            grid.set(glam::IVec3::new(x, 0, z), 1);
        }
    }
    let mut scene = seed_scene(16).unwrap();
    scene = Scene {
        grid,
        materials: palette,
        lights: vec![Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Rect {
                width: 6.0,
                height: 3.0,
            },
            position: DVec3::new(8.0, 6.0, 8.0),
            normal: DVec3::new(0.3, -1.0, 0.2).normalize(),
            rotation: 0.5,
            color: DVec3::ONE,
            intensity: 40.0,
        })],
        ..scene
    };
    scene.camera.target = DVec3::new(8.0, 0.0, 8.0);
    scene.camera.distance = 18.0;
    let mut st = RenderSettings {
        width: 32,
        height: 32,
        light_samples: 1,
        spp: 1,
        ..Default::default()
    };
    st.features.set_shadow_model("ratio");
    let a = cpu::render(&scene, &st).frame;
    st.seed = 99;
    let b = cpu::render(&scene, &st).frame;
    assert_eq!(
        a, b,
        "the unoccluded ratio estimate changed with the samples"
    );
    st.features.set_shadow_model("area");
    st.light_samples = 64;
    st.spp = 64;
    let reference = cpu::render(&scene, &st).frame;
    let r = rmse(&a, &reference);
    assert!(r < 2e-3, "ratio against the converged area light: RMSE {r}");
}

/// On the seed scene with rectangle lights (occluders, glass, mirrors; 2 x 1.5, so the
/// third, inside the grid, crosses no surface: where a light cuts through a surface its
/// samples' 1/r^2 has unbounded variance and neither estimator converges in a test's
/// time), the ratio
/// estimate approaches the sampled area lights' converged image as the samples grow
/// (its bias goes with the per-frame sample count), and at few samples it is closer
/// than the area model at the same count.
#[test]
fn converges_to_the_area_lights_reference() {
    let mut scene = seed_scene(16).unwrap();
    let c = scene.grid.centre();
    for l in &mut scene.lights {
        let Light::Point(p) = l.clone() else { continue };
        *l = Light::Area(AreaLight {
            emission: Default::default(),
            shape: AreaShape::Rect {
                width: 2.0,
                height: 1.5,
            },
            position: p.position,
            normal: (c - p.position).normalize(),
            rotation: 0.4,
            color: p.color,
            intensity: p.intensity,
        });
    }
    let render = |model: &str, samples: u32, spp: u32, seed: u32| {
        let mut st = RenderSettings {
            width: 32,
            height: 32,
            light_samples: samples,
            spp,
            seed,
            ..Default::default()
        };
        st.features.set_shadow_model(model);
        cpu::render(&scene, &st).frame
    };
    let reference = render("area", 64, 64, 1234);
    let errors: Vec<f64> = [1, 4, 16, 64]
        .iter()
        .map(|&n| rmse(&render("ratio", n, 4, 0), &reference))
        .collect();
    println!("ratio RMSE at 1, 4, 16, 64 samples x 4 frames: {errors:?}");
    assert!(errors.windows(2).all(|w| w[1] < w[0]), "{errors:?}");
    assert!(errors[3] < 4e-3, "{errors:?}");
    let area = rmse(&render("area", 1, 4, 0), &reference);
    assert!(
        errors[0] < area,
        "ratio {} against area {area} at 1 sample x 4 frames",
        errors[0]
    );
}
