//! The reconstruction slot (`features.reconstruction`, src/technique/atrous.rs): "none"
//! is the image as traced; the a-trous filter is the identity on a constant, keeps the
//! edges its stops name, filters a crop as the whole image, and brings a one-sample
//! image closer to the converged one; the parser and the writer hold its keys.

mod common;

use common::{experiment, overridden, rmse};
use glam::DVec3;
use rand::{RngExt, SeedableRng};
use voxlab::cpu;
use voxlab::experiment::{Experiment, Override};
use voxlab::frame::{PrimaryLayers, PrimaryPixel};
use voxlab::plan::Plan;
use voxlab::technique::atrous;

fn small(path: &str, sets: &[&str]) -> Experiment {
    let mut all = vec!["render.width=24", "render.height=20"];
    all.extend_from_slice(sets);
    overridden(&experiment(path), &all)
}

/// Random layers: every pixel a hit (or not, at `miss` odds) with a random normal, depth,
/// one of `materials` materials and frame moments over `frames` frames.
fn random_layers(rng: &mut impl rand::Rng, w: u32, h: u32, frames: u32) -> PrimaryLayers {
    let pixels = (0..w * h)
        .map(|_| {
            let normal = DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(0.1..1.0),
            )
            .normalize();
            let unshadowed = DVec3::new(
                rng.random_range(0.01..2.0),
                rng.random_range(0.01..2.0),
                rng.random_range(0.01..2.0),
            );
            let l = rng.random_range(0.0..1.0);
            PrimaryPixel {
                hit: rng.random_range(0.0..1.0) > 0.1,
                normal,
                depth: rng.random_range(1.0..50.0),
                material: rng.random_range(1..4u8),
                direct: unshadowed * rng.random_range(0.0..1.0),
                unshadowed,
                ratio_moments: [l, l * l + rng.random_range(0.0..0.1)],
                ratio_frames: frames,
            }
        })
        .collect();
    PrimaryLayers {
        width: w,
        height: h,
        frames,
        pixels,
        ..Default::default()
    }
}

fn settings(rng: &mut impl rand::Rng) -> Vec<f64> {
    vec![
        rng.random_range(1..=8u32) as f64,
        rng.random_range(0.0..256.0),
        rng.random_range(0.0..8.0),
        rng.random_range(0.0..16.0),
    ]
}

/// A constant visibility comes back unchanged, whatever the guide, image size (1 to
/// 40 pixels a side), frame count (spatial or temporal variance) and settings.
#[test]
fn the_filter_of_a_constant_is_the_identity() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(40);
    for case in 0..60 {
        let (w, h) = (rng.random_range(1..=40), rng.random_range(1..=40));
        let frames = [1, 2, 4, 9][case % 4];
        let mut layers = random_layers(&mut rng, w, h, frames);
        let v = DVec3::new(0.3, 0.7, 0.5);
        for p in &mut layers.pixels {
            p.direct = p.unshadowed * v;
        }
        let values = settings(&mut rng);
        let out = atrous::filter(&layers, &values, &mut None);
        for (p, c) in layers.pixels.iter().zip(&out) {
            if p.filtered() {
                assert!(
                    (*c - v).abs().max_element() < 1e-12,
                    "case {case} ({w}x{h}, {frames} frames, {values:?}): {c} != {v}"
                );
            }
        }
    }
}

/// Layers of a `w` x `h` image split at column `w / 2`: visibility 0 on the left, 1 on
/// the right; both halves one plane facing the camera at depth 10, the same material,
/// noise-free frames (zero temporal variance) unless changed by the caller.
fn step(w: u32, h: u32) -> PrimaryLayers {
    let pixels = (0..w * h)
        .map(|i| {
            let right = i % w >= w / 2;
            let v = if right { 1.0 } else { 0.0 };
            PrimaryPixel {
                hit: true,
                normal: DVec3::Z,
                depth: 10.0,
                material: 1,
                direct: DVec3::splat(v),
                unshadowed: DVec3::ONE,
                ratio_moments: [v, v * v],
                ratio_frames: 8,
            }
        })
        .collect();
    PrimaryLayers {
        width: w,
        height: h,
        frames: 8,
        pixels,
        ..Default::default()
    }
}

fn assert_step_kept(layers: &PrimaryLayers, what: &str) {
    let out = atrous::filter(layers, &[5.0, 128.0, 1.0, 4.0], &mut None);
    for (i, (p, c)) in layers.pixels.iter().zip(&out).enumerate() {
        assert_eq!(*c, p.visibility(), "{what}: pixel {i} moved");
    }
}

/// A step edge survives whole where a stop names it: a material edge, a crease
/// (normals at right angles), and a luminance step of zero variance on one plane. Where
/// none does (a noisy step on one plane), the filter blurs it: the stops are what keeps
/// it.
#[test]
fn edge_stopping_keeps_a_step_edge() {
    let (w, h) = (32, 16);
    assert_step_kept(&step(w, h), "luminance step, no variance");

    let mut material = step(w, h);
    for (i, p) in material.pixels.iter_mut().enumerate() {
        p.ratio_moments = [0.5, 0.5];
        if i as u32 % w >= w / 2 {
            p.material = 2;
        }
    }
    assert_step_kept(&material, "material edge");

    let mut crease = step(w, h);
    for (i, p) in crease.pixels.iter_mut().enumerate() {
        p.ratio_moments = [0.5, 0.5];
        if i as u32 % w >= w / 2 {
            p.normal = DVec3::X;
        }
    }
    assert_step_kept(&crease, "crease");

    // The same step with variance and nothing else to stop at is blurred.
    let mut noisy = step(w, h);
    for p in &mut noisy.pixels {
        p.ratio_moments = [0.5, 0.5];
    }
    let out = atrous::filter(&noisy, &[5.0, 128.0, 1.0, 4.0], &mut None);
    let edge = (h / 2 * w + w / 2 - 1) as usize;
    assert!(
        out[edge].x > 0.01,
        "a noisy step on one plane should blur: {}",
        out[edge]
    );
}

/// The filter reads no pixel it rejects: a pixel with no hit or no unshadowed light
/// changes nothing around it, whatever its (garbage) values.
#[test]
fn rejected_pixels_are_not_read() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(41);
    let layers = random_layers(&mut rng, 23, 17, 1);
    let values = [3.0, 64.0, 1.0, 4.0];
    let a = atrous::filter(&layers, &values, &mut None);
    let mut garbage = layers.clone();
    for p in &mut garbage.pixels {
        if !p.filtered() {
            p.direct = DVec3::splat(1e30);
            p.depth = -7.0;
            p.normal = DVec3::new(3.0, -9.0, 0.0);
            p.ratio_moments = [1e9, -4.0];
        }
    }
    let b = atrous::filter(&garbage, &values, &mut None);
    for (i, p) in layers.pixels.iter().enumerate() {
        if p.filtered() {
            assert_eq!(a[i], b[i], "pixel {i}");
        }
    }
}

/// `reach` is how far the filter reads: a pixel changed just outside it changes nothing
/// at the centre, and one just inside it can.
#[test]
fn the_reach_bounds_what_a_pixel_reads() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    for iterations in 1..=4u32 {
        let r = atrous::reach(iterations);
        let side = 2 * r + 5;
        let mut layers = random_layers(&mut rng, side, side, 1);
        for p in &mut layers.pixels {
            p.hit = true;
            p.material = 1;
            p.normal = DVec3::Z;
        }
        let values = [iterations as f64, 128.0, 1.0, 1e6];
        let centre = ((side / 2) * side + side / 2) as usize;
        let base = atrous::filter(&layers, &values, &mut None)[centre];
        let mut outside = layers.clone();
        outside.pixels[((side / 2) * side + side / 2 + r + 1) as usize].direct = DVec3::ZERO;
        assert_eq!(
            atrous::filter(&outside, &values, &mut None)[centre],
            base,
            "{iterations}"
        );
    }
}

/// "none", named or by default, gives the image as traced, and "atrous" under a shadow
/// model that samples nothing is left out by the plan: the same image bit for bit.
#[test]
fn none_and_a_left_out_filter_are_the_image_as_traced() {
    for (path, sets) in [
        ("area_lights.toml", &[][..]),
        ("ratio.toml", &[][..]),
        ("baseline.toml", &[][..]),
        ("area_lights.toml", &["features.shadow_model=hard"][..]),
        ("sdf.toml", &[][..]),
    ] {
        let base = small(path, sets);
        let traced = cpu::render(&base.scene, &base.settings).frame;
        for r in ["none", "atrous"] {
            let set = format!("features.reconstruction={r}");
            let mut all = sets.to_vec();
            all.push(&set);
            let e = small(path, &all);
            let plan = Plan::new(&e.scene, &e.settings);
            if plan.reconstruction.name != "none" {
                continue;
            }
            let img = cpu::render(&e.scene, &e.settings).frame;
            assert_eq!(img, traced, "{path} {sets:?} {r}");
            if r == "atrous" {
                assert!(
                    format!("{plan}").contains("reconstruction atrous"),
                    "{path}: the plan should say why: {plan}"
                );
            }
        }
    }
}

/// A crop of a filtered image (what the GPU tests compare cheaply) is the whole image's
/// crop bit for bit: the region is traced as far wider as the filter reads.
#[test]
fn a_crop_is_filtered_as_the_whole_image() {
    let e = small(
        "mitsuba/rect_blocks.toml",
        &[
            "render.width=40",
            "render.height=32",
            "features.shadow_model=ratio",
            "features.reconstruction=atrous",
            "techniques.atrous.iterations=2",
            "render.spp=1",
            "render.light_samples=1",
        ],
    );
    assert_eq!(
        Plan::new(&e.scene, &e.settings).reconstruction.name,
        "atrous"
    );
    let whole = cpu::render(&e.scene, &e.settings).frame;
    for (cols, rows) in [
        (0..40, 0..32),
        (3..17, 5..9),
        (30..40, 20..32),
        (0..1, 31..32),
    ] {
        let crop = cpu::render_region(&e.scene, &e.settings, cols.clone(), rows.clone()).frame;
        for (j, y) in rows.clone().enumerate() {
            for (i, x) in cols.clone().enumerate() {
                assert_eq!(
                    crop.get(i as u32, j as u32),
                    whole.get(x, y),
                    "pixel {x},{y} of crop {cols:?} x {rows:?}"
                );
            }
        }
    }
}

/// On the blocks under a rect light at one light sample and one frame, the filtered
/// image is nearer the converged image of the same estimator (1024 frames) than the
/// image as traced: by three tenths of the error at least for the ratio estimator, whose
/// unshadowed light is exact; by a tenth for the sampled area lights, whose unshadowed
/// estimate keeps its own noise (docs/reconstruction.md; measured 0.02907 to 0.01451
/// and 0.04524 to 0.03666).
#[test]
fn the_filter_brings_one_sample_nearer_the_converged_image() {
    for (model, gain) in [("ratio", 0.7), ("area", 0.9)] {
        let model = format!("features.shadow_model={model}");
        let base = [
            "render.width=64",
            "render.height=64",
            "render.light_samples=1",
            "render.pixel_filter=none",
            model.as_str(),
        ];
        let e = |sets: &[&str]| {
            let mut all = base.to_vec();
            all.extend_from_slice(sets);
            overridden(&experiment("mitsuba/rect_blocks.toml"), &all)
        };
        let converged = e(&["render.spp=1024"]);
        let converged = cpu::render(&converged.scene, &converged.settings).frame;
        let raw = e(&["render.spp=1"]);
        let raw = cpu::render(&raw.scene, &raw.settings).frame;
        let filtered = e(&[
            "render.spp=1",
            "features.reconstruction=atrous",
            "techniques.atrous.iterations=2",
        ]);
        let filtered = cpu::render(&filtered.scene, &filtered.settings).frame;
        let (before, after) = (rmse(&raw, &converged), rmse(&filtered, &converged));
        eprintln!("{model}: rmse {before:.5} as traced, {after:.5} filtered");
        assert!(
            after < gain * before,
            "{model}: rmse {before:.5} as traced, {after:.5} filtered"
        );
    }
}

/// The keys: a name not registered, settings out of range or of the wrong type, and
/// settings of a filter the experiment does not use are errors that name the key and
/// what is allowed; the writer writes what the parser reads.
#[test]
fn the_keys_are_checked_and_written_back() {
    let e = experiment("ratio.toml");
    let text = std::fs::read_to_string(e.source_path.as_ref().unwrap()).unwrap();
    let err = |sets: &[&str]| {
        let overrides: Vec<Override> = sets.iter().map(|s| s.parse().unwrap()).collect();
        Experiment::from_str_with(&text, "ratio.toml", &overrides)
            .err()
            .unwrap_or_else(|| panic!("{sets:?} should fail"))
            .to_string()
    };
    let m = err(&["features.reconstruction=\"svgf2\""]);
    assert!(
        m.contains("features.reconstruction") && m.contains("atrous"),
        "{m}"
    );
    let m = err(&["features.reconstruction=3"]);
    assert!(m.contains("must be a string"), "{m}");
    for bad in ["0", "9", "2.5", "\"x\""] {
        let m = err(&[&format!("techniques.atrous.iterations={bad}")]);
        assert!(m.contains("techniques.atrous.iterations"), "{bad}: {m}");
    }
    let m = err(&["techniques.atrous.sigma_depth=-1"]);
    assert!(m.contains("sigma_depth") && m.contains("0"), "{m}");
    let m = err(&["techniques.atrous.radius=2"]);
    assert!(m.contains("radius") && m.contains("iterations"), "{m}");

    let set = overridden(
        &e,
        &[
            "features.reconstruction=atrous",
            "techniques.atrous.iterations=3",
            "techniques.atrous.sigma_luminance=2.5",
        ],
    );
    let source =
        voxlab::experiment::write::scene_source(&text, e.source_path.as_ref().unwrap()).unwrap();
    let written = voxlab::experiment::write::to_toml(&set, &source).unwrap();
    let back = Experiment::from_str(&written, "written.toml").unwrap();
    assert_eq!(back.settings.features.reconstruction.name, "atrous");
    assert_eq!(
        back.settings.technique_params,
        set.settings.technique_params
    );
    assert!(written.contains("iterations = 3"), "{written}");
}
