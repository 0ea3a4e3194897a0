//! Reconstruction `svgf` on the f64 reference (src/technique/svgf.rs): without history it
//! is the a-trous filter; a static camera's accumulation is the mean of its frames
//! (alpha 0) or their exponential average; a moving camera keeps history only where
//! the surface was seen before (disocclusion restarts it, judged by casting rays from
//! the previous eye, not by the filter's own test); a path of frames brings the image
//! nearer the converged one than one frame filtered; and the path's keys are checked.

mod common;

use common::{experiment, overridden, rmse};
use glam::DVec3;
use rand::{RngExt, SeedableRng};
use voxlab::experiment::{Experiment, Override};
use voxlab::frame::{History, PrimaryLayers, PrimaryPixel};
use voxlab::technique::svgf;
use voxlab::{Backend, Session, cpu, dda};

/// experiments/reconstruction.toml, small, one frame unless `sets` asks for a path.
fn blocks(sets: &[&str]) -> Experiment {
    let mut all = vec![
        "render.width=48",
        "render.height=40",
        "render.path_frames=1",
    ];
    all.extend_from_slice(sets);
    overridden(&experiment("reconstruction.toml"), &all)
}

/// The settings' values of svgf with `alpha` and the rest at their defaults.
fn values(alpha: f64) -> Vec<f64> {
    svgf::RECONSTRUCTION
        .settings
        .iter()
        .map(|s| if s.key == "alpha" { alpha } else { s.default })
        .collect()
}

/// Without history (one frame, or a path's first) svgf filters as atrous does at one
/// frame: the same image, bit for bit, over sizes, seeds and filter settings.
#[test]
fn without_history_it_is_the_atrous_filter() {
    for (size, seed, iterations, sigma) in
        [("16", 0, 1, 4.0), ("33", 5, 3, 1.0), ("40", 9, 5, 16.0)]
    {
        let sets = |r: &str| {
            vec![
                format!("render.width={size}"),
                format!("render.seed={seed}"),
                format!("features.reconstruction=\"{r}\""),
                format!("techniques.{r}.iterations={iterations}"),
                format!("techniques.{r}.sigma_luminance={sigma}"),
            ]
        };
        let render = |r: &str| {
            let s = sets(r);
            let refs: Vec<&str> = s.iter().map(|x| x.as_str()).collect();
            let e = blocks(&refs);
            cpu::render(&e.scene, &e.settings).frame
        };
        let (a, s) = (render("atrous"), render("svgf"));
        assert_eq!(a.pixels, s.pixels, "size {size}, seed {seed}");
    }
}

/// Layers on a fixed G-buffer seen by `camera`: every pixel a hit of a random plane,
/// its visibility drawn anew by `rng`.
fn layers_frame(
    rng: &mut impl rand::Rng,
    base: &PrimaryLayers,
    visibility: &mut Vec<DVec3>,
) -> PrimaryLayers {
    let mut out = base.clone();
    visibility.clear();
    for p in &mut out.pixels {
        let v = DVec3::new(
            rng.random_range(0.0..1.0),
            rng.random_range(0.0..1.0),
            rng.random_range(0.0..1.0),
        );
        p.direct = p.unshadowed * v;
        visibility.push(p.visibility());
    }
    out
}

fn base_layers(rng: &mut impl rand::Rng, w: u32, h: u32) -> PrimaryLayers {
    let camera = voxlab::scene::OrbitCamera {
        target: DVec3::new(5.0, 1.0, 2.0),
        distance: 30.0,
        yaw: 0.4,
        pitch: 0.5,
        vfov: 0.8,
    }
    .frame();
    let pixels = (0..w * h)
        .map(|_| PrimaryPixel {
            hit: true,
            normal: DVec3::new(
                rng.random_range(-0.3..0.3),
                1.0,
                rng.random_range(-0.3..0.3),
            )
            .normalize(),
            depth: rng.random_range(20.0..40.0),
            material: rng.random_range(1..3u8),
            direct: DVec3::ZERO,
            unshadowed: DVec3::new(
                rng.random_range(0.1..2.0),
                rng.random_range(0.1..2.0),
                rng.random_range(0.1..2.0),
            ),
            ratio_moments: [0.0; 2],
            ratio_frames: 1,
        })
        .collect();
    PrimaryLayers {
        width: w,
        height: h,
        frames: 1,
        camera,
        pixels,
    }
}

/// A static camera: with alpha 0 the accumulated visibility after N frames is their
/// mean (and the length N); with alpha > 0 it is the exponential average that starts
/// as the mean for 1 / alpha frames. Over image sizes, frame counts and alphas.
#[test]
fn a_static_camera_accumulates_the_mean_of_its_frames() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for (w, h, frames, alpha) in [
        (8, 8, 1, 0.0),
        (13, 7, 6, 0.0),
        (32, 24, 20, 0.0),
        (16, 16, 12, 0.2),
        (9, 17, 5, 0.5),
    ] {
        let base = base_layers(&mut rng, w, h);
        let mut history: Option<History> = None;
        let mut expected = vec![DVec3::ZERO; (w * h) as usize];
        let mut sums = vec![DVec3::ZERO; (w * h) as usize];
        let mut visibility = Vec::new();
        for n in 1..=frames {
            let layers = layers_frame(&mut rng, &base, &mut visibility);
            let next = svgf::accumulate(&layers, history.as_ref(), &values(alpha));
            for (k, v) in visibility.iter().enumerate() {
                sums[k] += *v;
                let a = f64::max(alpha, 1.0 / n as f64);
                expected[k] = if n == 1 {
                    *v
                } else {
                    expected[k] + a * (*v - expected[k])
                };
            }
            history = Some(next);
        }
        let history = history.unwrap();
        for (k, p) in history.pixels.iter().enumerate() {
            assert!(p.kept);
            assert!(
                (p.length - frames as f64).abs() < 1e-9,
                "{w}x{h}: length {}",
                p.length
            );
            let want = if alpha == 0.0 {
                sums[k] / frames as f64
            } else {
                expected[k]
            };
            assert!(
                (p.visibility - want).abs().max_element() < 1e-9,
                "{w}x{h}, {frames} frames, alpha {alpha}: pixel {k} {} against {want}",
                p.visibility
            );
        }
    }
}

/// A history of another size, or none, restarts: every length 1.
#[test]
fn a_history_of_another_size_is_not_read() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut v = Vec::new();
    let base = base_layers(&mut rng, 8, 8);
    let small = layers_frame(&mut rng, &base, &mut v);
    let h = svgf::accumulate(&small, None, &values(0.2));
    let base = base_layers(&mut rng, 9, 8);
    let large = layers_frame(&mut rng, &base, &mut v);
    let next = svgf::accumulate(&large, Some(&h), &values(0.2));
    assert!(next.pixels.iter().all(|p| p.length == 1.0));
}

/// Where the previous camera's pixel ray hits `x`'s image position: the continuous
/// pixel, or `None` behind it.
fn projected(h: &History, x: DVec3) -> Option<(f64, f64)> {
    let cam = &h.camera;
    let v = x - cam.eye;
    let f = v.dot(cam.forward);
    if f <= 0.0 {
        return None;
    }
    let (w, hh) = (h.width as f64, h.height as f64);
    let sx = v.dot(cam.right) / (f * cam.tan_half_vfov * (w / hh));
    let sy = v.dot(cam.up) / (f * cam.tan_half_vfov);
    Some(((sx + 1.0) * 0.5 * w - 0.5, (1.0 - sy) * 0.5 * hh - 0.5))
}

/// Whether the previous camera saw `x` itself: inside its image and the first hit of
/// the ray from its eye towards `x` (the grid's own cast, not the filter's test).
fn seen_from(scene: &voxlab::scene::Scene, h: &History, x: DVec3) -> bool {
    let Some((u, t)) = projected(h, x) else {
        return false;
    };
    if u < -0.5 || t < -0.5 || u >= h.width as f64 - 0.5 || t >= h.height as f64 - 0.5 {
        return false;
    }
    let v = x - h.camera.eye;
    let (hit, _) = dda::cast(&scene.grid, h.camera.eye, v.normalize(), 0);
    hit.is_some_and(|hit| hit.t >= v.length() * (1.0 - 1e-3))
}

/// Whether the previous camera saw `x`'s surface (the plane through `x` with normal
/// `n`) at none of the pixels around where `x` projects: the rays through the centres
/// of those 3x3 pixels, cast in the grid, all hit elsewhere (or nothing). A history
/// there could only come from another surface: a ghost.
fn surface_unseen(scene: &voxlab::scene::Scene, h: &History, x: DVec3, n: DVec3) -> bool {
    let Some((u, t)) = projected(h, x) else {
        return true;
    };
    let (cx, cy) = (u.round() as i64, t.round() as i64);
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (qx, qy) = (cx + dx, cy + dy);
            if qx < 0 || qy < 0 || qx >= h.width as i64 || qy >= h.height as i64 {
                continue;
            }
            let dir = h
                .camera
                .primary_dir(qx as u32, qy as u32, h.width, h.height);
            let (hit, _) = dda::cast(&scene.grid, h.camera.eye, dir, 0);
            if let Some(hit) = hit {
                let at = h.camera.eye + hit.t * dir;
                if hit.normal.dot(n) > 0.99 && (at - x).dot(n).abs() < 1e-3 * hit.t {
                    return false;
                }
            }
        }
    }
    true
}

/// A moving camera past the blocks: a pixel whose surface the previous frame saw
/// nowhere near where it projects (hidden behind a block, or outside its image)
/// restarts its history, so nothing of another surface shows there as a ghost; a pixel
/// whose point it saw keeps its history (most of them: bilinear taps that straddle an
/// edge may drop it). Over orbit steps both ways.
#[test]
fn disocclusion_restarts_the_history() {
    for orbit in [-20.0, 30.0, 45.0] {
        // Low over the floor, so the blocks hide much of it.
        let e = blocks(&[
            "render.width=64",
            "render.height=64",
            "camera.pitch_deg=12",
            "features.reconstruction=\"svgf\"",
            "render.path_frames=2",
            &format!("render.orbit_deg={orbit}"),
        ]);
        let mut history = None;
        let mut scene = e.scene.clone();
        let (camera, s) = e.settings.path_pose(&e.scene.camera, 0);
        scene.camera = camera;
        cpu::render_with_history(&scene, &s, None, &mut history);
        let previous = history.clone().expect("svgf keeps a history");
        cpu::render_with_history(&e.scene, &e.settings, None, &mut history);
        let now = history.expect("kept");
        let (mut disoccluded, mut seen, mut kept, mut near) = (0, 0, 0, 0);
        for y in 0..now.height {
            for x in 0..now.width {
                let p = &now.pixels[(y * now.width + x) as usize];
                if !p.kept {
                    continue;
                }
                let dir = now.camera.primary_dir(x, y, now.width, now.height);
                let position = now.camera.eye + p.depth * dir;
                if seen_from(&e.scene, &previous, position) {
                    seen += 1;
                    kept += (p.length > 1.5) as u32;
                } else if !surface_unseen(&e.scene, &previous, position, p.normal) {
                    near += 1;
                } else {
                    disoccluded += 1;
                    assert_eq!(
                        p.length, 1.0,
                        "orbit {orbit}: pixel ({x}, {y})'s surface was not seen before, yet it keeps history"
                    );
                }
            }
        }
        eprintln!(
            "orbit {orbit}: {disoccluded} disoccluded, {near} hidden beside their surface seen, {kept} of {seen} seen kept"
        );
        assert!(
            disoccluded >= 20,
            "orbit {orbit}: too few disoccluded pixels to test: {disoccluded}"
        );
        assert!(
            kept as f64 >= 0.85 * seen as f64,
            "orbit {orbit}: only {kept} of {seen} pixels seen before keep their history"
        );
    }
}

/// A static path of frames, filtered, is nearer the converged image than one frame
/// filtered, which is nearer than one frame as traced; and the session's path ends at
/// the experiment's own frame (same seed, same camera): with one frame of history it
/// is the single render.
#[test]
fn a_path_of_frames_brings_the_image_nearer_the_converged_one() {
    let reference = {
        let e = blocks(&["features.reconstruction=\"none\"", "render.spp=512"]);
        cpu::render(&e.scene, &e.settings).frame
    };
    let mut session = Session::new(Backend::Cpu).unwrap();
    let mut error = |sets: &[&str]| {
        let e = blocks(sets);
        rmse(&session.render(&e).unwrap().frame, &reference)
    };
    let raw = error(&["features.reconstruction=\"none\""]);
    let one = error(&[
        "features.reconstruction=\"svgf\"",
        "techniques.svgf.iterations=3",
    ]);
    let path = error(&[
        "features.reconstruction=\"svgf\"",
        "render.path_frames=16",
        "techniques.svgf.alpha=0.0",
        "techniques.svgf.iterations=3",
    ]);
    let orbit = error(&[
        "features.reconstruction=\"svgf\"",
        "render.path_frames=16",
        "render.orbit_deg=0.5",
        "techniques.svgf.iterations=3",
    ]);
    eprintln!(
        "RMSE: raw {raw:.5}, svgf one frame {one:.5}, 16 static {path:.5}, 16 on an orbit {orbit:.5}"
    );
    assert!(
        path < raw && path < one && orbit < one,
        "the path's frames should help"
    );
}

/// The path's image is its last frame; the frame before it is kept for frame-to-frame
/// measures, and a path of one frame keeps none.
#[test]
fn the_path_ends_at_the_experiment_camera() {
    let mut session = Session::new(Backend::Cpu).unwrap();
    let single = blocks(&["features.reconstruction=\"none\""]);
    let image = session.render(&single).unwrap();
    assert!(image.previous.is_none());
    let path = blocks(&[
        "features.reconstruction=\"none\"",
        "render.path_frames=3",
        "render.orbit_deg=2",
    ]);
    let last = session.render(&path).unwrap();
    assert_eq!(last.frame.pixels, image.frame.pixels);
    let before = last
        .previous
        .expect("a path keeps the frame before its last");
    let (camera, s) = path.settings.path_pose(&path.scene.camera, 1);
    let mut scene = path.scene.clone();
    scene.camera = camera;
    assert_eq!(before.pixels, cpu::render(&scene, &s).frame.pixels);
}

/// The path's keys and svgf's settings are checked like every other: the file, the
/// key and the range named.
#[test]
fn the_keys_are_checked() {
    for (set, words) in [
        ("render.path_frames=0", "path_frames"),
        ("render.path_frames=100000", "path_frames"),
        ("render.orbit_deg=500", "orbit_deg"),
        ("render.orbit_deg=nan", "orbit_deg"),
        ("techniques.svgf.alpha=1.5", "alpha"),
        ("techniques.svgf.depth_tolerance=-1", "depth_tolerance"),
        ("techniques.svgf.depth_tolerance=0", "depth_tolerance"),
        ("techniques.svgf.normal_tolerance=2", "normal_tolerance"),
        ("techniques.svgf.normal_tolerance=1", "normal_tolerance"),
    ] {
        let e = experiment("reconstruction.toml");
        let text = std::fs::read_to_string(e.source_path.as_ref().unwrap()).unwrap();
        let o: Override = match set.parse() {
            Ok(o) => o,
            Err(err) => panic!("{set}: {err}"),
        };
        let err = Experiment::from_str_with(&text, e.source_path.as_ref().unwrap(), &[o])
            .err()
            .unwrap_or_else(|| panic!("{set} should be refused"));
        let msg = format!("{err}");
        assert!(
            msg.contains(words) && msg.contains("must be"),
            "{set}: {msg}"
        );
    }
}

/// A display's own path (the viewer: `Session::render_frames` as the camera moves)
/// accumulates like a render's path: the same frames shown one after another, the
/// history kept between them, give the path's image; emptying the history starts anew.
#[test]
fn a_display_path_accumulates_like_a_render_path() {
    let e = blocks(&[
        "features.reconstruction=\"svgf\"",
        "render.path_frames=3",
        "render.orbit_deg=4",
    ]);
    let mut session = Session::new(Backend::Cpu).unwrap();
    let path = session.render(&e).unwrap();
    session.reset_history();
    let mut last = None;
    for k in 0..3 {
        let (camera, s) = e.settings.path_pose(&e.scene.camera, k);
        let mut scene = e.scene.clone();
        scene.camera = camera;
        last = Some(session.render_frames(&scene, &s, 0..1).unwrap());
    }
    assert_eq!(last.unwrap().frame.pixels, path.frame.pixels);
    // Without the history the last frame alone is atrous-like, not the path's image.
    session.reset_history();
    let alone = session.render_frames(&e.scene, &e.settings, 0..1).unwrap();
    assert_ne!(alone.frame.pixels, path.frame.pixels);
}

/// `voxlab render` says when an image is a path's last frame, and what the frames
/// before it were for.
#[test]
fn render_says_the_image_is_the_path_end() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("svgf-cli");
    std::fs::create_dir_all(&dir).unwrap();
    let file = experiment("reconstruction.toml").source_path.unwrap();
    let run = |reconstruction: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_voxlab"))
            .args(["render", file.to_str().unwrap(), "--backend", "cpu"])
            .args(["--width", "24", "--height", "16", "--out"])
            .arg(dir.join(format!("{reconstruction}.png")))
            .args([
                "--set",
                &format!("features.reconstruction=\"{reconstruction}\""),
            ])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr)
    };
    let svgf = run("svgf");
    assert!(
        svgf.contains("path:       8 frames")
            && svgf.contains("the 7 before it give its reconstruction's history"),
        "{svgf}"
    );
    let atrous = run("atrous");
    assert!(atrous.contains("only the last is rendered"), "{atrous}");
}

/// Taps that hold one length mix to exactly that length, whatever their weights: the
/// variance switches to the temporal estimate at `TEMPORAL_FRAMES` on the mixed
/// length, and the GPU's f32 must see the integer the reference sees (summed plainly,
/// taps of length 3 mixed to 2.9999999999999996 at some pixels). A G-buffer seen again
/// from cameras turned a little, so the taps' bilinear weights are arbitrary; every
/// pixel that finds history has exactly `n + 1`.
#[test]
fn taps_of_one_length_mix_to_that_length_exactly() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let mut found = 0;
    for n in [1.0, 3.0, 7.0, 100.0] {
        let base = base_layers(&mut rng, 24, 16);
        let mut visibility = Vec::new();
        let first = layers_frame(&mut rng, &base, &mut visibility);
        let mut h = svgf::accumulate(&first, None, &values(0.0));
        for p in &mut h.pixels {
            p.length = n;
        }
        for turn in [1e-3, 4e-3, 1.3e-2] {
            let mut turned = layers_frame(&mut rng, &base, &mut visibility);
            let c = &mut turned.camera;
            let (s, co) = f64::sin_cos(turn);
            let v = c.forward;
            c.forward = DVec3::new(co * v.x + s * v.z, v.y, -s * v.x + co * v.z);
            let r = c.right;
            c.right = DVec3::new(co * r.x + s * r.z, r.y, -s * r.x + co * r.z);
            let next = svgf::accumulate(&turned, Some(&h), &values(0.0));
            for p in next.pixels.iter().filter(|p| p.length != 1.0) {
                found += 1;
                assert_eq!(p.length, n + 1.0, "history of length {n}, turned {turn}");
            }
        }
    }
    assert!(found > 500, "only {found} pixels found history");
}
