//! Area lights on the CPU reference (the oracle): degenerate settings are the baseline
//! exactly, the estimator converges as N^-1/2, and bad input is rejected or finite.

use glam::DVec3;
use voxlab::experiment::Experiment;
use voxlab::metrics::{Domain, compare};
use voxlab::scene::{AreaLight, AreaShape, Light, Scene, seed_scene};
use voxlab::{Frame, RenderSettings};

fn as_area_lights(scene: &mut Scene, shape: AreaShape) {
    let c = scene.grid.centre();
    for l in &mut scene.lights {
        let Light::Point(p) = l.clone() else { continue };
        *l = Light::Area(AreaLight {
            emission: Default::default(),
            shape,
            position: p.position,
            normal: (c - p.position).normalize(),
            rotation: 0.3,
            color: p.color,
            intensity: p.intensity,
        });
    }
}

fn sampled(width: u32, light_samples: u32, spp: u32) -> RenderSettings {
    let mut s = RenderSettings {
        width,
        height: width,
        light_samples,
        spp,
        ..Default::default()
    };
    s.features.shadow_model = &voxlab::technique::area::MODEL;
    s
}

const SHAPES: [AreaShape; 3] = [
    AreaShape::Rect {
        width: 0.0,
        height: 0.0,
    },
    AreaShape::Disk { radius: 0.0 },
    AreaShape::Sphere { radius: 0.0 },
];

/// Size 0, or sampling off: exactly the hard-shadow image of the point lights at the
/// centres (the same code path, so bit for bit).
#[test]
fn size_zero_or_sampling_off_is_the_point_light_image_exactly() {
    let scene = seed_scene(16).unwrap();
    let settings = sampled(48, 4, 3);
    let point = voxlab::cpu::render(&scene, &settings).frame;
    for shape in SHAPES {
        let mut s = scene.clone();
        as_area_lights(&mut s, shape);
        assert_eq!(voxlab::cpu::render(&s, &settings).frame, point, "{shape:?}");
    }
    let mut s = scene.clone();
    as_area_lights(
        &mut s,
        AreaShape::Rect {
            width: 4.0,
            height: 2.0,
        },
    );
    let mut off = settings.clone();
    off.features.shadow_model = voxlab::technique::default_shadow_model();
    assert_eq!(voxlab::cpu::render(&s, &off).frame, point);
}

/// A vanishing light converges to the point light: size 1e-7 moves every sample by at
/// most 1e-7, so only shadow rays that graze an edge to within that can change.
#[test]
fn vanishing_area_lights_converge_to_the_point_light() {
    let scene = seed_scene(16).unwrap();
    let settings = sampled(48, 2, 2);
    let point = voxlab::cpu::render(&scene, &settings).frame;
    for shape in [
        AreaShape::Rect {
            width: 1e-7,
            height: 1e-7,
        },
        AreaShape::Disk { radius: 1e-7 },
        AreaShape::Sphere { radius: 1e-7 },
    ] {
        let mut s = scene.clone();
        as_area_lights(&mut s, shape);
        let f = voxlab::cpu::render(&s, &settings).frame;
        let d = compare(&f, &point, Domain::Linear, 1e-4).unwrap();
        assert!(
            d.max_abs < 1e-4 || d.fraction_over() < 0.002,
            "{shape:?}: {d}"
        );
        assert!(d.mean_abs < 1e-6, "{shape:?}: {d}");
    }
}

/// A soft shadow: a floor, a pillar and a rectangle light overhead; primary rays and
/// shadow rays only (depth 0), so every pixel's noise is the light sampling's.
fn soft_shadow_scene() -> Experiment {
    Experiment::from_str(
        r#"
[scene]
generator = "empty"
dims = [16, 12, 16]
[[scene.boxes]]
min = [0, 0, 0]
max = [16, 1, 16]
material = "solid"
[[scene.boxes]]
min = [6, 1, 6]
max = [9, 7, 9]
material = "solid"
[camera]
target = [8.0, 2.0, 8.0]
distance = 30.0
yaw_deg = 20.0
pitch_deg = 50.0
[[lights]]
type = "rect"
position = [10.0, 14.0, 10.0]
normal = [0.0, -1.0, 0.0]
size = [6.0, 4.0]
intensity = 300.0
[render]
max_reflection_depth = 0
max_refraction_depth = 0
[features]
shadow_model = "area"
"#,
        "soft_shadow.toml",
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

fn rmse(a: &Frame, b: &Frame) -> f64 {
    compare(a, b, Domain::Linear, 1.0).unwrap().rmse
}

/// Convergence: the RMSE of an N-sample image (spp = N frames of one sample) against a
/// converged reference falls as N^-1/2; the fitted log-log slope over N = 4, 16, 64, 256
/// is within 0.15 of -0.5. The reference (another seed, so independent of the images
/// measured) takes 16 frames of 256 stratified samples: 4096 samples whose stratification
/// leaves far less error than the 256-sample image's.
#[test]
fn soft_shadow_rmse_falls_as_one_over_sqrt_n() {
    let e = soft_shadow_scene();
    let mut reference = e.settings.clone();
    (reference.width, reference.height) = (48, 48);
    reference.light_samples = 256;
    reference.spp = 16;
    reference.seed = 12345;
    let r = voxlab::cpu::render(&e.scene, &reference).frame;

    let ns = [4u32, 16, 64, 256];
    let mut pts = Vec::new();
    for n in ns {
        let mut s = reference.clone();
        s.light_samples = 1;
        s.spp = n;
        s.seed = 1;
        let f = voxlab::cpu::render(&e.scene, &s).frame;
        let err = rmse(&f, &r);
        eprintln!("N = {n}: RMSE {err:.4e}");
        pts.push(((n as f64).ln(), err.ln()));
    }
    let k = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / k;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / k;
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>()
        / pts.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    eprintln!("log-log slope {slope:.3}");
    assert!(
        (slope + 0.5).abs() < 0.15,
        "slope {slope:.3}, expected -0.5 +- 0.15"
    );
}

/// Bad input: negative or NaN sizes and zero samples are errors of the experiment
/// loader, naming the key.
#[test]
fn bad_sizes_and_zero_samples_are_rejected() {
    let light = |kind: &str, extra: &str| {
        format!(
            "[[lights]]\ntype = \"{kind}\"\nposition = [0, 0, 0]\nintensity = 1\n{extra}\n\
             [features]\nshadow_model = \"area\"\n"
        )
    };
    let cases = [
        (light("rect", "size = [-1.0, 1.0]"), "lights[0].size"),
        (light("rect", "size = [1.0, nan]"), "lights[0].size"),
        (light("rect", "size = [inf, 1.0]"), "lights[0].size"),
        (light("disk", "radius = -0.5"), "lights[0].radius"),
        (light("disk", "radius = nan"), "lights[0].radius"),
        (light("sphere", "radius = -1.0"), "lights[0].radius"),
        (light("sphere", "radius = nan"), "lights[0].radius"),
        (
            light("sphere", "radius = 1.0\n[render]\nlight_samples = 0"),
            "render.light_samples",
        ),
        (
            light("sphere", "radius = 1.0\n[render]\nspp = 0"),
            "render.spp",
        ),
        (
            light("sphere", "radius = 1.0\n[render]\nlight_samples = -4"),
            "render.light_samples",
        ),
    ];
    for (text, key) in cases {
        match Experiment::from_str(&text, "x.toml") {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains(key), "{msg:?} does not name {key}");
            }
        }
    }
    // Size 0 is valid: a point light.
    let e = Experiment::from_str(&light("sphere", "radius = 0.0"), "x.toml").unwrap();
    assert!(!e.scene.lights[0].is_area());
}

/// A sphere light around the corner of a solid voxel: samples inside the voxel are
/// shadowed, the others light; finite everywhere (the GPU side is in gpu_area_lights.rs).
#[test]
fn sphere_light_inside_an_opaque_voxel_is_finite() {
    let mut scene = seed_scene(16).unwrap();
    scene.lights = vec![Light::Area(AreaLight {
        emission: Default::default(),
        shape: AreaShape::Sphere { radius: 0.8 },
        position: DVec3::new(0.5, 0.5, 8.0),
        normal: DVec3::Y,
        rotation: 0.0,
        color: DVec3::ONE,
        intensity: 200.0,
    })];
    let f = voxlab::cpu::render(&scene, &sampled(32, 4, 2)).frame;
    assert!(f.all_finite());
    assert!(f.pixels.iter().all(|p| p.iter().all(|&c| c >= 0.0)));
}
