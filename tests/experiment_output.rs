//! Image output: png and exr round trips, atomic writes, clear errors.

use std::path::PathBuf;

use voxlab::Frame;
use voxlab::output::{OutputError, read_exr, read_frame, read_png, write_frame};

/// A fresh directory under the target dir (no tempfile dependency); removed first so
/// reruns start clean.
fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("output-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A small frame with values below 0, inside [0, 1] and above 1 (radiance is unbounded).
fn test_frame() -> Frame {
    let (w, h) = (7, 5);
    let mut f = Frame::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            f.pixels[i] = [
                x as f32 / (w - 1) as f32 * 1.5 - 0.25,
                y as f32 / (h - 1) as f32,
                0.123_456_79 * (i as f32),
            ];
        }
    }
    f
}

fn no_temp_files(dir: &std::path::Path) -> bool {
    std::fs::read_dir(dir)
        .unwrap()
        .all(|e| !e.unwrap().file_name().to_string_lossy().ends_with(".tmp"))
}

#[test]
fn png_stores_the_clamped_8bit_frame() {
    let dir = scratch("png");
    let f = test_frame();
    let path = dir.join("nested/deeper/a.png");
    write_frame(&f, &path).unwrap();
    let back = read_png(&path).unwrap();
    assert_eq!((back.width, back.height), (f.width, f.height));
    let expected: Vec<u8> = f.to_rgb8();
    let got: Vec<u8> = back
        .pixels
        .iter()
        .flat_map(|p| p.map(|c| (c * 255.0).round() as u8))
        .collect();
    assert_eq!(got, expected);
    // No tone mapping, no gamma: 0.5 is stored as 128.
    let mut half = Frame::new(1, 1);
    half.pixels[0] = [0.5, 2.0, -1.0];
    let p = dir.join("half.png");
    write_frame(&half, &p).unwrap();
    assert_eq!(read_png(&p).unwrap().pixels[0], [128.0 / 255.0, 1.0, 0.0]);
    assert!(no_temp_files(&dir));
}

#[test]
fn exr_stores_linear_radiance_exactly() {
    let dir = scratch("exr");
    let f = test_frame();
    let path = dir.join("a.exr");
    write_frame(&f, &path).unwrap();
    assert_eq!(read_exr(&path).unwrap(), f);
    assert_eq!(read_frame(&path).unwrap(), f);
    // Upper-case extensions work too.
    let upper = dir.join("b.EXR");
    write_frame(&f, &upper).unwrap();
    assert_eq!(read_frame(&upper).unwrap(), f);
    assert!(no_temp_files(&dir));
}

#[test]
fn overwriting_replaces_the_whole_file() {
    let dir = scratch("overwrite");
    let path = dir.join("a.png");
    write_frame(&Frame::new(64, 64), &path).unwrap();
    let f = test_frame();
    write_frame(&f, &path).unwrap();
    assert_eq!(read_png(&path).unwrap().width, f.width);
}

#[test]
fn unknown_extension_is_an_error_naming_the_path() {
    let dir = scratch("ext");
    for name in ["a.jpg", "noext"] {
        let path = dir.join(name);
        let e = write_frame(&test_frame(), &path).unwrap_err();
        assert!(matches!(e, OutputError::UnknownExtension { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(msg.contains(&path.display().to_string()), "{msg}");
        assert!(msg.contains(".png") && msg.contains(".exr"), "{msg}");
        assert!(!path.exists());
    }
}

#[test]
fn unwritable_path_leaves_no_file() {
    let dir = scratch("unwritable");
    // A parent that is a regular file cannot become a directory: this fails for every
    // user, root included (permission bits do not stop root).
    let blocker = dir.join("file");
    std::fs::write(&blocker, b"not a directory").unwrap();
    let path = blocker.join("a.png");
    let e = write_frame(&test_frame(), &path).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains(&path.display().to_string()), "{msg}");
    assert!(!path.exists());

    // The target name is an existing directory: the temporary file is written, the
    // rename fails, and neither it nor anything else is left behind.
    let target = dir.join("taken.png");
    std::fs::create_dir(&target).unwrap();
    std::fs::write(target.join("keep"), b"x").unwrap();
    let e = write_frame(&test_frame(), &target).unwrap_err();
    assert!(e.to_string().contains("taken.png"), "{e}");
    assert!(target.is_dir());
    assert!(no_temp_files(&dir));
}

#[test]
fn reading_a_missing_or_corrupt_file_is_an_error_naming_it() {
    let dir = scratch("read");
    let missing = dir.join("missing.png");
    assert!(
        read_png(&missing)
            .unwrap_err()
            .to_string()
            .contains("missing.png")
    );
    let corrupt = dir.join("corrupt.exr");
    std::fs::write(&corrupt, b"not an exr").unwrap();
    assert!(
        read_exr(&corrupt)
            .unwrap_err()
            .to_string()
            .contains("corrupt.exr")
    );
}
