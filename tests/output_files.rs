//! Output files as other tools read them, and outputs that fail: an EXR is a scanline
//! file; an image whose record cannot be written leaves neither behind; an OBJ that
//! cannot be written leaves no MTL; a write that fails leaves no directory it made.

use std::path::{Path, PathBuf};

use voxlab::frame::{DisplayTransform, Frame};
use voxlab::output::{read_exr, write_frame, write_frame_with_provenance};

fn dir(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn frame(w: u32, h: u32) -> Frame {
    let mut f = Frame::new(w, h);
    for (i, p) in f.pixels.iter_mut().enumerate() {
        *p = [i as f32 * 0.25, -1.5 + i as f32, 1e6 / (1.0 + i as f32)];
    }
    f
}

/// The names in `d`, sorted.
fn names(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// The EXR header's attributes (name, type) and its version flags, read by the
/// format's definition (OpenEXR "File Layout"), not by the crate that wrote it.
fn exr_header(bytes: &[u8]) -> (u32, Vec<(String, String)>) {
    assert_eq!(&bytes[..4], &[0x76, 0x2f, 0x31, 0x01], "EXR magic number");
    let version = u32::from_le_bytes(bytes[4..8].try_into().unwrap());
    let mut at = 8;
    let mut attrs = Vec::new();
    let cstr = |at: &mut usize| {
        let end = bytes[*at..].iter().position(|&b| b == 0).unwrap() + *at;
        let s = String::from_utf8(bytes[*at..end].to_vec()).unwrap();
        *at = end + 1;
        s
    };
    loop {
        let name = cstr(&mut at);
        if name.is_empty() {
            break;
        }
        let kind = cstr(&mut at);
        let size = u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize;
        at += 4 + size;
        attrs.push((name, kind));
    }
    (version, attrs)
}

#[test]
fn an_exr_is_a_scanline_file_of_the_linear_values() {
    let d = dir("output_exr");
    for (w, h) in [(1, 1), (7, 3), (70, 65)] {
        let f = frame(w, h);
        let p = d.join(format!("f{w}x{h}.exr"));
        write_frame(&f, &p).unwrap();
        let (version, attrs) = exr_header(&std::fs::read(&p).unwrap());
        assert_eq!(version & 0xff, 2, "EXR version 2");
        assert_eq!(version & 0x200, 0, "single-part tiled flag set: {attrs:?}");
        assert!(!attrs.iter().any(|(n, _)| n == "tiles"), "{attrs:?}");
        let order = attrs.iter().find(|(n, _)| n == "lineOrder");
        assert!(order.is_some(), "{attrs:?}");
        assert_eq!(read_exr(&p).unwrap().pixels, f.pixels);
    }
}

/// A legal image name whose `.json` record would be one byte too long: refused before
/// anything is written, so neither the image nor a temporary file is left.
#[test]
fn an_image_whose_record_cannot_be_named_is_not_written() {
    let d = dir("output_long_name");
    for ext in ["png", "exr"] {
        for len in [251usize, 254, 255] {
            let stem = "n".repeat(len - ext.len() - 1);
            let p = d.join(format!("{stem}.{ext}"));
            let e =
                write_frame_with_provenance(&frame(4, 3), &p, "{}", DisplayTransform::default())
                    .unwrap_err()
                    .to_string();
            assert!(e.contains(".json") && e.contains("file name"), "{len}: {e}");
            assert!(names(&d).is_empty(), "{len}: left {:?}", names(&d));
        }
        // 250 bytes: both fit.
        let p = d.join(format!("{}.{ext}", "n".repeat(250 - ext.len() - 1)));
        write_frame_with_provenance(&frame(4, 3), &p, "{}", DisplayTransform::default()).unwrap();
        assert_eq!(names(&d).len(), 2, "{:?}", names(&d));
        for n in names(&d) {
            std::fs::remove_file(d.join(n)).unwrap();
        }
    }
}

/// An OBJ that cannot be put in place (its name is a directory) leaves no MTL, and the
/// message says the cause once.
#[test]
fn an_obj_that_cannot_be_written_leaves_no_mtl() {
    let d = dir("output_obj");
    let grid = voxlab::scene::seed_scene(8).unwrap().grid;
    let mesh = voxlab::surface::extract(&grid, 0).unwrap();
    let materials = voxlab::scene::seed_palette();
    std::fs::create_dir(d.join("m.obj")).unwrap();
    let e = voxlab::surface::write_mesh(&mesh, &materials, &d.join("m.obj"))
        .unwrap_err()
        .to_string();
    assert_eq!(e.matches("m.obj").count(), 1, "{e}");
    assert_eq!(names(&d), vec!["m.obj".to_string()], "{e}");
    std::fs::remove_dir(d.join("m.obj")).unwrap();
    voxlab::surface::write_mesh(&mesh, &materials, &d.join("m.obj")).unwrap();
    assert_eq!(names(&d), vec!["m.mtl".to_string(), "m.obj".to_string()]);
}

/// A write that fails removes the directories it created for its files (deepest and
/// upper ones, whichever file made them), and keeps those that were there before and
/// any that hold other files.
#[test]
fn a_failed_write_leaves_no_directory_it_made() {
    use voxlab::output::{Fill, OutputError, bytes_fill, write_together};
    let d = dir("output_dirs");
    let fail = |path: &Path| -> Fill<'static> {
        let path = path.to_path_buf();
        Box::new(move |_tmp: &Path| {
            Err(OutputError::WriteFile {
                path,
                error: std::io::Error::other("a full disk"),
            })
        })
    };
    // The first file makes a/b, the second a/b/c/d and fails: all four go.
    let first = d.join("a/b/x.txt");
    let second = d.join("a/b/c/d/y.txt");
    let e = write_together(vec![
        (first.clone(), bytes_fill(&first, b"x")),
        (second.clone(), fail(&second)),
    ])
    .unwrap_err();
    assert!(e.to_string().contains("a full disk"), "{e}");
    assert!(names(&d).is_empty(), "left: {:?}", names(&d));

    // The failure at the rename (the name is a directory) removes them too.
    std::fs::create_dir_all(d.join("kept")).unwrap();
    let good = d.join("kept/new/x.txt");
    let blocked = d.join("kept/new2/y.txt");
    std::fs::create_dir_all(d.join("kept/new2/y.txt/inside")).unwrap();
    let e = write_together(vec![
        (good.clone(), bytes_fill(&good, b"x")),
        (blocked.clone(), bytes_fill(&blocked, b"y")),
    ])
    .unwrap_err();
    assert!(e.to_string().contains("y.txt"), "{e}");
    // kept/ was there, kept/new2 holds the blocking directory: both stay.
    assert_eq!(names(&d.join("kept")), vec!["new2".to_string()], "{e}");

    // A directory made by the call that another writer has put a file into stays.
    let shared = d.join("shared/z.txt");
    let other = d.join("shared/other.txt");
    let e = write_together(vec![(
        shared.clone(),
        Box::new(move |_tmp: &Path| {
            std::fs::write(&other, b"someone else's").unwrap();
            Err(OutputError::WriteFile {
                path: PathBuf::from("z.txt"),
                error: std::io::Error::other("a full disk"),
            })
        }) as Fill<'static>,
    )])
    .unwrap_err();
    assert!(e.to_string().contains("a full disk"), "{e}");
    assert_eq!(names(&d.join("shared")), vec!["other.txt".to_string()]);

    // And a write that succeeds keeps the directories it made.
    let fine = d.join("p/q/r.txt");
    write_together(vec![(fine.clone(), bytes_fill(&fine, b"r"))]).unwrap();
    assert_eq!(std::fs::read(&fine).unwrap(), b"r");
}
