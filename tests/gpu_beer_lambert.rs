//! Beer-Lambert transmittance on the GPU kernel against the f64 CPU reference: a lit
//! floor seen past slabs 1, 2 and 4 voxels thick, with point and area lights, and
//! optical depths from 1e-6 to 1e4.
//!
//! Tolerance (tests/gpu_agreement.rs's): fewer than 0.5 % of pixels over 2/255 on the
//! displayed image, mean absolute difference below 1e-3.

mod common;

use common::{linear, tracer};
use voxlab::Frame;
use voxlab::experiment::Experiment;
use voxlab::gpu::GpuTracer;

/// A white floor under a tinted slab `thickness` voxels thick (y in [5, 5 + t)) over
/// part of it, lit from above by `light` (a [[lights]] entry), seen obliquely so both
/// the floor in the slab's shadow and the slab are in view.
fn slab_scene(thickness: u32, sigma: Option<[f64; 3]>, light: &str, bl: bool) -> Experiment {
    let sigma = sigma.map_or(String::new(), |s| {
        format!("sigma = [{:e}, {:e}, {:e}]", s[0], s[1], s[2])
    });
    let text = format!(
        r#"
[scene]
generator = "empty"
dims = [16, 12, 16]
voxel_size = 0.5
origin = [-2.0, 0.0, 1.0]
[[scene.boxes]]
min = [0, 0, 0]
max = [16, 1, 16]
material = "floor"
[[scene.boxes]]
min = [3, 5, 3]
max = [11, {top}, 11]
material = "tint"
[[materials]]
name = "floor"
kd = 0.9
ks = 0.1
[[materials]]
name = "tint"
albedo = [0.9, 0.8, 0.5]
kd = 0.1
ks = 0.5
kr = 0.1
kt = 0.6
ior = 1.0
{sigma}
[camera]
target = [2.0, 1.0, 5.0]
distance = 20.0
yaw_deg = 150.0
pitch_deg = 40.0
{light}
[render]
width = 64
height = 64
[features]
shadow_model = "area"
transmittance = "{model}"
"#,
        top = 5 + thickness,
        model = if bl { "beer-lambert" } else { "min-kt" },
    );
    Experiment::from_str(&text, "slab.toml").unwrap_or_else(|e| panic!("{e}"))
}

const POINT: &str = r#"[[lights]]
type = "point"
position = [2.5, 9.0, 4.0]
intensity = 40.0"#;
const RECT: &str = r#"[[lights]]
type = "rect"
position = [2.5, 9.0, 4.0]
normal = [0.0, -1.0, 0.0]
size = [2.0, 1.5]
intensity = 40.0"#;

/// The GPU-vs-CPU tolerance, and no negative radiance on the GPU.
#[track_caller]
fn assert_agree(name: &str, g: &Frame, c: &Frame) {
    assert!(g.all_finite() && c.all_finite(), "{name}: NaN or inf");
    assert!(
        g.pixels.iter().all(|p| p.iter().all(|&v| v >= 0.0)),
        "{name}: negative radiance on the GPU"
    );
    common::assert_agree(name, g, c);
}

#[test]
fn lit_floor_behind_slabs_matches_the_cpu() {
    let mut gpu = tracer();
    for light in [POINT, RECT] {
        for t in [1, 2, 4] {
            let mut images = Vec::new();
            for bl in [false, true] {
                let mut e = slab_scene(t, None, light, bl);
                e.settings.light_samples = 2;
                e.settings.spp = 2;
                let g = gpu.render(&e.scene, &e.settings).unwrap().frame;
                let plan = gpu.last_plan().unwrap().clone();
                assert_eq!(plan.transmittance.name == "beer-lambert", bl, "{plan}");
                let c = voxlab::cpu::render(&e.scene, &e.settings).frame;
                let name = format!(
                    "{} light, slab {t}, {}",
                    if light == POINT { "point" } else { "rect" },
                    e.settings.features.transmittance.name()
                );
                assert_agree(&name, &g, &c);
                images.push(g);
            }
            // One voxel: Beer-Lambert is min-kt (default sigma) up to the obliquity of
            // the shadow rays; thicker slabs are darker under Beer-Lambert.
            let mean = |f: &Frame| {
                f.pixels
                    .iter()
                    .map(|p| p.iter().sum::<f32>() as f64)
                    .sum::<f64>()
                    / f.pixels.len() as f64
            };
            let (mk, bl) = (mean(&images[0]), mean(&images[1]));
            eprintln!("slab {t}: mean min-kt {mk:.5}, beer-lambert {bl:.5}");
            if t > 1 {
                assert!(
                    bl < mk,
                    "slab {t}: beer-lambert {bl} not darker than min-kt {mk}"
                );
            }
        }
    }
}

/// Optical depth 1e4 transmits exactly 0, as a sigma of 1e30 does: sigma 1e4 per world
/// unit through a slab one world unit thick. Shadow rays that cross the whole slab have a
/// depth of at least 1e4; only those that clip an edge of it by less than ~0.01 can see
/// a smaller depth, so at most a handful of pixels may differ. Depth 1e-6 transmits
/// 1 - 1e-6: within f32 of no absorption at all. Finite and non-negative throughout.
#[test]
fn extreme_optical_depths_are_exact_and_finite_on_the_gpu() {
    let mut gpu = tracer();
    let render = |gpu: &mut GpuTracer, sigma: f64| {
        let e = slab_scene(2, Some([sigma; 3]), POINT, true);
        assert_eq!(
            e.settings.features.transmittance,
            voxlab::technique::beer_lambert::ID
        );
        let g = gpu.render(&e.scene, &e.settings).unwrap().frame;
        assert_eq!(gpu.last_plan().unwrap().transmittance.name, "beer-lambert");
        let c = voxlab::cpu::render(&e.scene, &e.settings).frame;
        assert_agree(&format!("sigma {sigma:e}"), &g, &c);
        g
    };
    // The slab is 2 voxels of 0.5: 1 world unit thick, so depth >= sigma.
    let thick = render(&mut gpu, 1e4);
    let infinite = render(&mut gpu, 1e30);
    let d = linear(&thick, &infinite, 0.0);
    eprintln!("sigma 1e4 vs 1e30: {d}");
    assert!(
        d.fraction_over() < 0.005,
        "optical depth 1e4 does not transmit exactly 0: {d}"
    );

    let thin = render(&mut gpu, 1e-6);
    let clear = render(&mut gpu, 0.0);
    let d = linear(&thin, &clear, 1e-5);
    assert!(d.max_abs < 1e-5, "optical depth 1e-6 vs 0: {d}");
}
