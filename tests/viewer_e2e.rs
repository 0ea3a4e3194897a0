//! End to end: `voxlab view` in a real window on a virtual X server (Xvfb), on the
//! software adapter, in its scripted mode: it orbits the camera, accumulates frames on
//! both sides, saves each side's image with the experiment file it exported and a
//! capture of the window, and closes. `voxlab render` of each exported file must give
//! the saved image exactly.
//!
//! Xvfb is installed by tests/run.sh; without it this test fails (it is never skipped).
#![cfg(feature = "viewer")]

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use voxlab::experiment::Experiment;
use voxlab::output::read_png;

/// A small area-light scene: the seed geometry with a rectangular key light, 96x72 so
/// lavapipe renders the frames in moments.
const EXPERIMENT: &str = r#"
name = "e2e"
[scene]
generator = "seed"
size = 16

[[lights]]
type = "rect"
position = [22.4, 20.8, 24.0]
normal = [-0.9, -0.8, -1.0]
size = [6.0, 6.0]
color = [1.0, 0.8, 0.7]
intensity = 384.0
[[lights]]
type = "point"
position = [-3.2, 17.6, 24.0]
color = [0.7, 0.8, 1.0]
intensity = 256.0

[render]
width = 96
height = 72
light_samples = 2

[features]
shadow_model = "area"
"#;

/// A virtual X server on a display of its own, stopped on drop.
struct Xvfb {
    child: Child,
    display: String,
}

impl Xvfb {
    fn start() -> Self {
        let found = Command::new("sh")
            .args(["-c", "command -v Xvfb"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false);
        assert!(
            found,
            "Xvfb not found: the viewer's end-to-end test needs it (tests/run.sh installs \
             the Debian package xvfb)"
        );
        // A display number unlikely to be taken, tried until one starts.
        let base = 200 + (std::process::id() % 500);
        for n in base..base + 20 {
            if Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
                continue;
            }
            let display = format!(":{n}");
            let mut child = Command::new("Xvfb")
                .args([&display, "-screen", "0", "1280x900x24", "-nolisten", "tcp"])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("Xvfb starts");
            let socket = PathBuf::from(format!("/tmp/.X11-unix/X{n}"));
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_secs(10) {
                if socket.exists() {
                    return Self { child, display };
                }
                if let Ok(Some(_)) = child.try_wait() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        panic!(
            "no Xvfb display could be started on :{base}..:{}",
            base + 20
        );
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs the binary with a time limit; returns (success, stdout, stderr).
fn run_voxlab(args: &[&str], display: Option<&str>, limit: Duration) -> (bool, String, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_voxlab"));
    cmd.args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        // The window must go to our X server, whatever the machine's session is.
        .env_remove("WAYLAND_DISPLAY");
    if let Some(d) = display {
        cmd.env("DISPLAY", d);
    }
    let mut child = cmd.spawn().expect("the voxlab binary runs");
    let t0 = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("waiting for voxlab") {
            let out = child.wait_with_output().expect("voxlab output");
            let _ = status;
            return (
                out.status.success(),
                String::from_utf8_lossy(&out.stdout).into_owned(),
                String::from_utf8_lossy(&out.stderr).into_owned(),
            );
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let out = child.wait_with_output().expect("voxlab output");
            panic!(
                "voxlab {args:?} ran past {limit:?}\nstdout:\n{}\nstderr:\n{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn scripted_viewer_saves_what_render_reproduces() {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("viewer-e2e");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let exp = dir.join("e2e.toml");
    std::fs::write(&exp, EXPERIMENT).unwrap();
    let save = dir.join("saved");

    let x = Xvfb::start();
    let (ok, stdout, stderr) = run_voxlab(
        &[
            "view",
            exp.to_str().unwrap(),
            "--left",
            "hard,min-kt",
            "--right",
            "area,beer-lambert,samples=2",
            "--orbit",
            "30,-10",
            "--window",
            "900x650",
            "--frames",
            "5",
            "--save-dir",
            save.to_str().unwrap(),
        ],
        Some(&x.display),
        Duration::from_secs(300),
    );
    assert!(
        ok,
        "voxlab view failed\nstdout:\n{stdout}\nstderr:\n{stderr}"
    );
    for f in [
        "e2e-001-left.png",
        "e2e-001-left.toml",
        "e2e-001-right.png",
        "e2e-001-right.toml",
        "e2e-001-window.png",
    ] {
        assert!(
            stdout.contains(&format!("saved {}", save.join(f).display())),
            "no `saved` line for {f} in:\n{stdout}"
        );
    }

    let original = Experiment::load(&exp).unwrap();
    // The right side sampled its area light over 5 frames; the left has nothing to
    // sample (hard shadows) and is one frame. The orbit is in both.
    let right = Experiment::load(save.join("e2e-001-right.toml")).unwrap();
    assert_eq!(right.settings.spp, 5);
    assert_eq!(right.settings.light_samples, 2);
    assert!((right.settings.features.shadow_model.name == "area"));
    assert_eq!(
        right.settings.features.transmittance,
        voxlab::technique::beer_lambert::ID
    );
    let left = Experiment::load(save.join("e2e-001-left.toml")).unwrap();
    assert!(
        left.settings.features.shadow_model.name != "area"
            && left.settings.features.shadow_model.name != "cone"
    );
    assert_eq!((left.settings.width, left.settings.height), (96, 72));
    for e in [&left, &right] {
        let yaw = e.scene.camera.yaw.to_degrees() - original.scene.camera.yaw.to_degrees();
        let pitch = e.scene.camera.pitch.to_degrees() - original.scene.camera.pitch.to_degrees();
        assert!(
            (yaw - 30.0).abs() < 1e-6,
            "yaw turned by {yaw} degrees, not 30"
        );
        assert!(
            (pitch + 10.0).abs() < 1e-6,
            "pitch turned by {pitch} degrees, not -10"
        );
        assert_eq!(e.scene.lights, original.scene.lights);
        assert_eq!(e.scene.grid, original.scene.grid);
    }

    // What the viewer saved is what `voxlab render` makes of the exported file.
    for side in ["left", "right"] {
        let rendered = dir.join(format!("render-{side}.png"));
        let toml = save.join(format!("e2e-001-{side}.toml"));
        let (ok, out, err) = run_voxlab(
            &[
                "render",
                toml.to_str().unwrap(),
                "--out",
                rendered.to_str().unwrap(),
            ],
            None,
            Duration::from_secs(120),
        );
        assert!(ok, "voxlab render {side} failed\n{out}\n{err}");
        let saved = read_png(save.join(format!("e2e-001-{side}.png"))).unwrap();
        let again = read_png(&rendered).unwrap();
        assert_eq!((saved.width, saved.height), (96, 72));
        let differing = saved
            .pixels
            .iter()
            .zip(&again.pixels)
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(
            differing, 0,
            "{side}: {differing} pixels of the viewer's image differ from `voxlab render` \
             of its exported file"
        );
    }
    // The two sides really differ (soft against hard shadows).
    let l = read_png(save.join("e2e-001-left.png")).unwrap();
    let r = read_png(save.join("e2e-001-right.png")).unwrap();
    assert!(
        l.pixels != r.pixels,
        "the two sides rendered the same image"
    );

    // The capture's record: the build and the files saved with it.
    let rec: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(save.join("e2e-001-window.png.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(rec["revision"], voxlab::revision::revision());
    let with = rec["saved_with"].as_array().unwrap();
    assert!(
        with.iter()
            .any(|p| p.as_str().unwrap().ends_with("e2e-001-left.png")),
        "{rec}"
    );
    // The window capture is the window: larger than the image, and not blank.
    let capture = read_png(save.join("e2e-001-window.png")).unwrap();
    assert!(
        capture.width >= 600 && capture.height >= 400,
        "window capture is {}x{}",
        capture.width,
        capture.height
    );
    let first = capture.pixels[0];
    assert!(
        capture.pixels.iter().any(|p| *p != first),
        "the window capture is one colour"
    );

    // A scripted run whose save fails ends with the save's error: it waited for a
    // window capture that a failed save never asks for, and ran until killed.
    let unwritable = exp.join("saved");
    let (ok, stdout, stderr) = run_voxlab(
        &[
            "view",
            exp.to_str().unwrap(),
            "--frames",
            "1",
            "--save-dir",
            unwritable.to_str().unwrap(),
        ],
        Some(&x.display),
        Duration::from_secs(120),
    );
    assert!(
        !ok && stderr.contains("save failed: cannot create"),
        "stdout:\n{stdout}\nstderr:\n{stderr}"
    );
    assert!(!unwritable.exists());
}
