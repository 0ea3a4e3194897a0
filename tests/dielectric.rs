//! Fresnel dielectrics (`[[materials]] dielectric = "fresnel"`, src/scene/material.rs;
//! shaders/dielectric.wgsl): the reflectance against an independent form of Fresnel's
//! equations and its known values, both tracers against the closed form of a slab seen
//! inside an emissive shell (every ray ends on the shell, so a pixel is the emission
//! times the sum of its tree's weights: `kr F + kt (1 - F)`, read back per pixel), and
//! GPU = CPU over generated scenes (indices below and above 1, kr and kt near 0 and 1,
//! depth limits, both rules, every transmittance model, the ray cutoff on and off).
//!
//! Runs on whatever adapter wgpu finds (lavapipe in CI); a missing adapter fails.

mod common;

use common::{assert_same_tree, tracer};
use rand::{RngExt, SeedableRng};
use voxlab::RenderSettings;
use voxlab::experiment::Experiment;
use voxlab::frame::Frame;
use voxlab::scene::{Dielectric, fresnel_dielectric, seed_scene};

/// Fresnel's reflectance for unpolarised light in Cook and Torrance's form (ACM TOG
/// 1982, eq. 9), with `n = n_t / n_i` and `g^2 = n^2 + c^2 - 1` (total internal
/// reflection where `g^2 < 0`): a different algebra from the `r_s`, `r_p` of the one
/// under test.
fn cook_torrance(c: f64, n: f64) -> f64 {
    let g2 = n * n + c * c - 1.0;
    if g2 < 0.0 {
        return 1.0;
    }
    let g = g2.sqrt();
    let a = (g - c) / (g + c);
    let b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0);
    0.5 * a * a * (1.0 + b * b)
}

#[test]
fn the_reflectance_is_fresnels() {
    // Over angles and indices either side of 1 (eta = n_i / n_t).
    for k in 0..=200 {
        let c = k as f64 / 200.0;
        for eta in [0.3, 0.5, 1.0 / 1.5, 0.9, 0.999, 1.0, 1.001, 1.2, 1.5, 2.4] {
            let f = fresnel_dielectric(c, eta);
            assert!((0.0..=1.0).contains(&f), "F({c}, {eta}) = {f}");
            if c > 0.0 {
                let want = cook_torrance(c, 1.0 / eta);
                assert!((f - want).abs() < 1e-12, "F({c}, {eta}) = {f}, want {want}");
            }
        }
    }
    for n in [1.1f64, 1.33, 1.5, 2.4] {
        // Normal incidence, either way through the interface.
        let r0 = ((n - 1.0) / (n + 1.0)).powi(2);
        assert!((fresnel_dielectric(1.0, 1.0 / n) - r0).abs() < 1e-15);
        assert!((fresnel_dielectric(1.0, n) - r0).abs() < 1e-15);
        // At Brewster's angle the p-polarised half vanishes: F = r_s^2 / 2.
        let brewster = n.atan();
        let (ci, ct) = (brewster.cos(), (brewster.sin() / n).asin().cos());
        let r_s = (ci - n * ct) / (ci + n * ct);
        assert!((fresnel_dielectric(ci, 1.0 / n) - 0.5 * r_s * r_s).abs() < 1e-12);
        // Reciprocity: the same interface seen from the other side at the refracted
        // angle reflects the same share.
        for k in 1..20 {
            let ci = k as f64 / 20.0;
            let st = (1.0 - ci * ci).sqrt() / n;
            let ct = (1.0 - st * st).sqrt();
            let there = fresnel_dielectric(ci, 1.0 / n);
            let back = fresnel_dielectric(ct, n);
            assert!((there - back).abs() < 1e-12, "{n} {ci}: {there} {back}");
        }
        // Beyond the critical angle, inside the denser medium: total reflection.
        let critical = (1.0 / n).asin();
        assert_eq!(fresnel_dielectric((critical + 1e-6).cos(), n), 1.0);
        assert!(fresnel_dielectric((critical - 1e-3).cos(), n) < 1.0);
        // Grazing incidence reflects everything.
        assert_eq!(fresnel_dielectric(0.0, 1.0 / n), 1.0);
    }
    // An index-matched interface reflects nothing.
    assert!(fresnel_dielectric(0.3, 1.0) < 1e-30);
}

/// A slab of glass (x and z across the grid, y from 1 to 6) inside a shell of emissive
/// voxels of radiance `E = 1`, the camera above it: a ray that reaches the slab's top
/// reflects to the shell and refracts into the slab onto the shell's floor or walls,
/// so its pixel is `kr F + kt (1 - F)` (`fresnel`) or `kr + kt` (`fixed`).
fn shell(ior: f64, kr: f64, kt: f64, dielectric: &str) -> Experiment {
    let text = format!(
        r#"
[scene]
generator = "empty"
dims = [16, 16, 16]
[[scene.boxes]]
min = [0, 0, 0]
max = [16, 16, 16]
material = "shell"
[[scene.boxes]]
min = [1, 1, 1]
max = [15, 15, 15]
material = "void"
[[scene.boxes]]
min = [1, 1, 1]
max = [15, 6, 15]
material = "slab"
[[materials]]
name = "shell"
kd = 0.0
ks = 0.0
emission = [1.0, 1.0, 1.0]
[[materials]]
name = "slab"
kd = 0.0
ks = 0.0
kr = {kr}
kt = {kt}
ior = {ior}
dielectric = "{dielectric}"
[camera]
target = [8.0, 6.0, 8.0]
distance = 6.0
pitch_deg = 40.0
yaw_deg = 10.0
[render]
width = 40
height = 40
ambient = [0.0, 0.0, 0.0]
ray_cutoff = 0.0
"#
    );
    Experiment::from_str(&text, "shell.toml").unwrap()
}

/// Per pixel whose centre ray meets the slab's top away from its edges: the cosine of
/// its angle of incidence.
fn slab_pixels(e: &Experiment) -> Vec<(usize, f64)> {
    let s = &e.settings;
    let cam = e.scene.camera.frame();
    let origin = e.scene.grid.world_min();
    let vs = e.scene.grid.voxel_size();
    let top = origin.y + 6.0 * vs;
    let inside = |v: f64, o: f64| v > o + 1.05 * vs && v < o + 14.95 * vs;
    let mut out = Vec::new();
    for j in 0..s.height {
        for i in 0..s.width {
            let d = cam.primary_dir(i, j, s.width, s.height);
            if d.y >= 0.0 {
                continue;
            }
            let p = cam.eye + (top - cam.eye.y) / d.y * d;
            if inside(p.x, origin.x) && inside(p.z, origin.z) {
                out.push(((j * s.width + i) as usize, -d.y));
            }
        }
    }
    out
}

fn check(name: &str, e: &Experiment, frame: &Frame, tol: f64, want: impl Fn(f64) -> f64) {
    let pixels = slab_pixels(e);
    assert!(
        pixels.len() > 400,
        "{name}: {} pixels see the slab",
        pixels.len()
    );
    for &(k, c) in &pixels {
        let got = frame.pixels[k];
        let w = want(c);
        for ch in got {
            assert!(
                (ch as f64 - w).abs() <= tol,
                "{name}: pixel {k} (cos {c:.4}) is {got:?}, the tree's weights sum to {w}"
            );
        }
    }
}

#[test]
fn a_slab_in_an_emissive_shell_shows_the_sum_of_its_weights() {
    let mut gpu = tracer();
    // (ior, kr, kt): air to glass; to an index below air's, where rays past 36.9
    // degrees are totally reflected; an index-matched slab, which reflects nothing.
    for (ior, kr, kt) in [
        (1.5, 1.0, 0.5),
        (1.5, 0.3, 0.9),
        (0.6, 1.0, 0.5),
        (1.0, 1.0, 0.7),
    ] {
        let e = shell(ior, kr, kt, "fresnel");
        assert_eq!(
            e.scene.materials.last().unwrap().dielectric,
            Dielectric::Fresnel
        );
        let want = |c: f64| {
            let f = fresnel_dielectric(c, 1.0 / ior);
            kr * f + kt * (1.0 - f)
        };
        let name = format!("fresnel ior {ior}, kr {kr}, kt {kt}");
        let cpu = voxlab::cpu::render(&e.scene, &e.settings);
        check(&format!("{name}, CPU"), &e, &cpu.frame, 1e-6, want);
        let g = gpu.render(&e.scene, &e.settings).unwrap();
        check(&format!("{name}, GPU"), &e, &g.frame, 2e-4, want);
        if ior == 0.6 {
            // Both regimes are in the image.
            let critical = (1.0f64 - 0.6 * 0.6).sqrt();
            let cs: Vec<f64> = slab_pixels(&e).iter().map(|p| p.1).collect();
            assert!(
                cs.iter().any(|&c| c < critical - 0.03) && cs.iter().any(|&c| c > critical + 0.03)
            );
        }
        // The seed's fixed weights in the same scene: kr + kt whatever the angle (no
        // total internal reflection from outside when ior >= 1).
        if ior >= 1.0 {
            let fixed = shell(ior, kr, kt, "fixed");
            let cpu = voxlab::cpu::render(&fixed.scene, &fixed.settings);
            check(
                &format!("fixed ior {ior}"),
                &fixed,
                &cpu.frame,
                1e-6,
                |_| kr + kt,
            );
        }
    }
}

/// GPU = CPU with Fresnel dielectrics over generated seed scenes.
#[test]
fn gpu_equals_cpu_over_generated_cases() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(0xd1e1);
    let mut gpu = tracer();
    let near = [0.0, 1e-3, 0.05, 0.5, 0.95, 0.999, 1.0];
    let iors = [0.5, 0.8, 1.0, 1.0001, 1.33, 1.5, 2.4];
    let transmittances = ["min-kt", "beer-lambert", "opaque"];
    for case in 0..12 {
        let mut scene = seed_scene(16).unwrap();
        for m in scene.materials.iter_mut().skip(1) {
            m.kr = near[rng.random_range(0..near.len())];
            m.kt = near[rng.random_range(1..near.len())];
            m.ior = iors[rng.random_range(0..iors.len())];
            if rng.random_bool(0.8) {
                m.dielectric = Dielectric::Fresnel;
            }
        }
        let mut s = RenderSettings {
            width: 32,
            height: 32,
            ..Default::default()
        };
        s.ray_cutoff = [0.0, 1e-3, 0.05][case % 3];
        s.max_reflection_depth = rng.random_range(0..7);
        s.max_refraction_depth = rng.random_range(0..7);
        if rng.random_bool(0.25) {
            s.rules = voxlab::render::Rules::Seed;
        }
        s.features.transmittance =
            voxlab::technique::transmittance(transmittances[case % 3]).expect("registered");
        let name = format!(
            "case {case}: cutoff {}, depth {}/{}, {:?}, {}, materials {:?}",
            s.ray_cutoff,
            s.max_reflection_depth,
            s.max_refraction_depth,
            s.rules,
            s.features.transmittance.name(),
            scene.materials[1..]
                .iter()
                .map(|m| (m.kr, m.kt, m.ior, m.dielectric.name()))
                .collect::<Vec<_>>()
        );
        let c = voxlab::cpu::render(&scene, &s);
        let g = gpu.render_counted(&scene, &s).unwrap();
        assert_same_tree(&name, &g, &c);
    }
}

/// The key is read, written back and refused with its allowed names.
#[test]
fn the_key_round_trips_and_refuses_other_names() {
    let e = shell(1.5, 1.0, 0.9, "fresnel");
    let written = voxlab::experiment::write::to_toml(&e, &toml::Table::new()).unwrap();
    assert!(written.contains("dielectric = \"fresnel\""), "{written}");
    let back = Experiment::from_str(&written, "back.toml").unwrap();
    assert_eq!(back.scene.materials, e.scene.materials);
    let text = "[[materials]]\nname = \"glass\"\ndielectric = \"schlick\"\n";
    let err = Experiment::from_str(text, "bad.toml")
        .unwrap_err()
        .to_string();
    for want in [
        "bad.toml",
        "materials[0].dielectric",
        "\"fixed\"",
        "\"fresnel\"",
        "schlick",
    ] {
        assert!(err.contains(want), "{want} not in: {err}");
    }
    // The default is the seed's.
    assert!(
        seed_scene(16)
            .unwrap()
            .materials
            .iter()
            .all(|m| m.dielectric == Dielectric::Fixed)
    );
}
