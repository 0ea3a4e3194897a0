//! Details of issue 14 that the fuzz harness cannot see: what malformed-but-plausible
//! input turns into (MagicaVoxel's own reading of a .vox, a cracked closed mesh), and
//! messages and outputs at their limits.

use std::path::PathBuf;

use glam::IVec3;
use voxlab::Frame;
use voxlab::ablate::Point;
use voxlab::experiment::Experiment;
use voxlab::render::RenderSettings;
use voxlab::scene::{VoxelizeOptions, load_vox, voxelize_mesh};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxlab-hostile-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn chunk(id: &[u8; 4], content: &[u8], children: &[u8]) -> Vec<u8> {
    let mut c = id.to_vec();
    c.extend((content.len() as u32).to_le_bytes());
    c.extend((children.len() as u32).to_le_bytes());
    c.extend(content);
    c.extend(children);
    c
}

/// A .vox without a scene graph: `models` as (size, voxels of x, y, z, colour index).
fn vox(models: &[([u32; 3], Vec<[u8; 4]>)]) -> Vec<u8> {
    let mut children = Vec::new();
    for (size, voxels) in models {
        let s: Vec<u8> = size.iter().flat_map(|v| v.to_le_bytes()).collect();
        children.extend(chunk(b"SIZE", &s, &[]));
        let mut x = (voxels.len() as u32).to_le_bytes().to_vec();
        for v in voxels {
            x.extend(v);
        }
        children.extend(chunk(b"XYZI", &x, &[]));
    }
    let mut f = b"VOX ".to_vec();
    f.extend(150u32.to_le_bytes());
    f.extend(chunk(b"MAIN", &[], &children));
    f
}

fn solid(g: &voxlab::scene::Grid) -> usize {
    g.data().iter().filter(|&&m| m != 0).count()
}

#[test]
fn a_vox_voxel_of_colour_index_0_is_empty() {
    let dir = temp_dir("index0");
    let p = dir.join("a.vox");
    std::fs::write(
        &p,
        vox(&[([3, 1, 1], vec![[0, 0, 0, 0], [1, 0, 0, 5], [2, 0, 0, 0]])]),
    )
    .unwrap();
    let v = load_vox(&p, None).unwrap();
    assert_eq!(solid(&v.grid), 1, "index 0 loaded as a solid voxel");
    assert_eq!(v.palette_index, vec![0, 5]);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn an_old_multi_model_vox_shows_frame_0() {
    let dir = temp_dir("frames");
    let p = dir.join("frames.vox");
    std::fs::write(
        &p,
        vox(&[
            ([2, 2, 2], vec![[0, 0, 0, 1]]),
            ([2, 2, 2], vec![[1, 1, 1, 2], [0, 1, 1, 2]]),
        ]),
    )
    .unwrap();
    let v = load_vox(&p, None).unwrap();
    assert_eq!(v.model_count, 2);
    assert_eq!(solid(&v.grid), 1, "frames overlaid");
    // Frame 1 is still there when asked for.
    assert_eq!(solid(&load_vox(&p, Some(1)).unwrap().grid), 2);
    std::fs::remove_dir_all(&dir).ok();
}

/// A cube whose top face does not share its vertices with the sides (a crack of 1e-7,
/// so its edges are open topologically) still comes out solid.
#[test]
fn a_cracked_closed_cube_comes_out_solid_with_a_warning() {
    let dir = temp_dir("crack");
    let e = 1e-7;
    let obj = format!(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
         v {e} {} {e}\nv {} {} {e}\nv {} {} {}\nv {e} {} {}\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 1 5 8 4\nf 9 12 11 10\n",
        1.0 + e,
        1.0 - e,
        1.0 + e,
        1.0 - e,
        1.0 + e,
        1.0 - e,
        1.0 + e,
        1.0 - e,
    );
    let p = dir.join("cracked.obj");
    std::fs::write(&p, obj).unwrap();
    let v = voxelize_mesh(&p, &VoxelizeOptions::count(16)).unwrap();
    assert!(!v.closed);
    assert!(
        v.warnings.iter().any(|w| w.contains("not closed")),
        "{:?}",
        v.warnings
    );
    let d = v.grid.dims();
    let centre = IVec3::new(d.x as i32 / 2, d.y as i32 / 2, d.z as i32 / 2);
    assert_ne!(v.grid.get(centre), 0, "the inside was left empty");
    assert!(v.interior_voxels > 0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn output_names_at_the_file_name_limit_are_written() {
    let dir = temp_dir("names");
    let name = format!("{}.png", "n".repeat(251));
    assert_eq!(name.len(), 255);
    let p = dir.join(&name);
    voxlab::output::write_frame(&Frame::new(2, 2), &p).unwrap();
    assert!(p.exists());
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(left.len(), 1, "a temporary file was left behind");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn quoted_values_in_errors_are_cut() {
    let long = "x".repeat(10_000_000);
    let text = format!("name = \"{long}\"\n");
    let e = Experiment::from_str(&text, "x.toml")
        .unwrap_err()
        .to_string();
    assert!(e.len() < 2000, "a {}-byte message", e.len());
    assert!(e.contains("x.toml:1") && e.contains("name"), "{e}");
}

#[test]
fn ablation_point_names_stay_short_and_unique() {
    let point = |value: f64| Point {
        model: "cone at set aperture".into(),
        knob: "aperture_deg".into(),
        value: format!("{value}"),
        settings: RenderSettings::default(),
        lights_as_points: true,
        scene: None,
    };
    let a = point(1e-300).slug();
    let b = point(2e-300).slug();
    assert!(a.len() <= 80, "{a}");
    assert_ne!(a, b);
    assert_eq!(point(4.0).slug(), "cone_at_set_aperture_aperture_deg-00004");
}

/// Ctrl-C while an image is being written leaves neither the image nor its hidden
/// temporary file, nor the default `out/` directory where the write made it, and exits
/// 130.
#[cfg(unix)]
#[test]
fn an_interrupted_write_leaves_nothing_behind() {
    for out_exists in [true, false] {
        interrupt_a_write(out_exists);
    }
}

#[cfg(unix)]
fn interrupt_a_write(out_exists: bool) {
    let dir = temp_dir(&format!("interrupt-{out_exists}"));
    let exp = dir.join("empty.toml");
    // A one-voxel empty scene: the trace is instant, the 8000x8000 EXR takes a while.
    std::fs::write(
        &exp,
        "lights = []\n[scene]\ngenerator = \"empty\"\nsize = 1\n[render]\nwidth = 8000\nheight = 8000\n",
    )
    .unwrap();
    let out = dir.join("out");
    if out_exists {
        std::fs::create_dir_all(&out).unwrap();
    }
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .current_dir(&dir)
        .args([
            "render",
            "empty.toml",
            "--backend",
            "cpu",
            "--out",
            "out/big.exr",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    let tmp_seen = loop {
        let any = std::fs::read_dir(&out).is_ok_and(|mut d| {
            d.any(|e| e.unwrap().file_name().to_string_lossy().ends_with(".tmp"))
        });
        if any || start.elapsed().as_secs() > 60 {
            break any;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    assert!(tmp_seen, "the write never started");
    let ok = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap()
        .success();
    assert!(ok);
    let status = child.wait().unwrap();
    let left = |d: &std::path::Path| -> Vec<_> {
        std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect()
    };
    // The write may have finished just before the signal: then the image is whole.
    if status.success() {
        assert_eq!(left(&out).len(), 1, "{:?}", left(&out));
    } else {
        assert_eq!(status.code(), Some(130), "{status:?}");
        if out_exists {
            assert!(left(&out).is_empty(), "left behind: {:?}", left(&out));
        } else {
            assert!(!out.exists(), "left behind: out/ holding {:?}", left(&out));
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_duplicate_key_is_named() {
    let e = Experiment::from_str("name = \"a\"\nname = \"b\"\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("x.toml:2") && e.contains("duplicate key `name`"),
        "{e}"
    );
    let e = Experiment::from_str("[render]\nwidth = 8\n[render]\nheight = 8\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("x.toml:3") && e.contains("duplicate key `render`"),
        "{e}"
    );
}

#[test]
fn a_required_extension_is_the_reason_given() {
    let dir = temp_dir("draco");
    let p = dir.join("draco.gltf");
    std::fs::write(
        &p,
        r#"{"asset":{"version":"2.0"},"extensionsUsed":["KHR_draco_mesh_compression"],
"extensionsRequired":["KHR_draco_mesh_compression"],
"accessors":[{"componentType":5126,"count":3,"type":"VEC3"}],
"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}]}"#,
    )
    .unwrap();
    let e = voxelize_mesh(&p, &VoxelizeOptions::count(4))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("requires the extension(s) KHR_draco_mesh_compression")
            && !e.contains("Missing"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn obj_and_mtl_errors_name_their_line() {
    let dir = temp_dir("objline");
    let p = dir.join("bad.obj");
    std::fs::write(&p, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 x 2\nf 1 2 3\n").unwrap();
    let e = voxelize_mesh(&p, &VoxelizeOptions::count(4))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("bad.obj") && e.contains("line 4 (\"v 1 x 2\")"),
        "{e}"
    );
    let p = dir.join("m.obj");
    std::fs::write(
        &p,
        "mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl a\nNs 10\nKd 0.5\n").unwrap();
    let e = voxelize_mesh(&p, &VoxelizeOptions::count(4))
        .unwrap_err()
        .to_string();
    assert!(e.contains("m.mtl, line 3 (\"Kd 0.5\")"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The OBJ format continues a line that ends in a backslash (trimesh reads it so);
/// voxlab refused it ("position parse error"). Continued lines read as one, LF or CRLF,
/// a comment's continuation stays comment, and later lines keep their numbers in errors.
#[test]
fn an_obj_line_ending_in_a_backslash_continues() {
    let dir = temp_dir("objcont");
    let read = |name: &str, text: &str| {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        voxlab::scene::load_mesh(&p).map_err(|e| e.to_string())
    };
    for (name, text) in [
        ("lf.obj", "v 0 0 0\nv 2 0 \\\n0\nv 0 3 0\nf 1 \\\n2 3\n"),
        (
            "crlf.obj",
            "v 0 0 0\r\nv 2 0 \\\r\n0\r\nv 0 3 0\r\nf 1 2 3\r\n",
        ),
        (
            "comment.obj",
            "# v 9 9 9 as part of a comment \\\nv 9 9 9\nv 0 0 0\nv 2 0 0\nv 0 3 0\nf 1 2 3\n",
        ),
    ] {
        let mesh = read(name, text).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(mesh.triangles.len(), 1, "{name}");
        let t = mesh.triangles[0];
        assert_eq!(
            [t[0].to_array(), t[1].to_array(), t[2].to_array()],
            [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 3.0, 0.0]],
            "{name}"
        );
    }
    let e = read(
        "bad.obj",
        "v 0 0 0\nv 1 0 \\\n0\nv 0 1 0\nf 1 2 3\nv 1 x 1\n",
    )
    .unwrap_err();
    assert!(e.contains("line 6 (\"v 1 x 1\")"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// An OBJ whose `mtllib` cannot be read (missing, a directory, a device, a FIFO) is
/// refused with the library's path and why: dropping it would lose every material.
#[test]
fn an_unreadable_material_library_refuses_the_mesh() {
    let dir = temp_dir("mtl_unreadable");
    let obj = "mtllib m.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let p = dir.join("m.obj");
    std::fs::write(&p, obj).unwrap();
    let mtl = dir.join("m.mtl");
    let refused = |what: &str| {
        let e = voxelize_mesh(&p, &VoxelizeOptions::count(4))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.obj") && e.contains("material library") && e.contains("m.mtl"),
            "{what}: {e}"
        );
    };
    refused("missing");
    std::fs::create_dir(&mtl).unwrap();
    refused("a directory");
    std::fs::remove_dir(&mtl).unwrap();
    std::os::unix::fs::symlink("/dev/null", &mtl).unwrap();
    refused("a device");
    std::fs::remove_file(&mtl).unwrap();
    let made = std::process::Command::new("mkfifo")
        .arg(&mtl)
        .status()
        .unwrap();
    assert!(made.success());
    refused("a FIFO");
    std::fs::remove_file(&mtl).unwrap();
    // Readable, it gives its material.
    std::fs::write(&mtl, "newmtl a\nKd 0.2 0.4 0.6\n").unwrap();
    assert!(voxelize_mesh(&p, &VoxelizeOptions::count(4)).is_ok());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_malformed_vox_chunk_is_named_with_its_offset() {
    let deer = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("experiments/data/deer.vox");
    let mut b = std::fs::read(&deer).expect("experiments/data/deer.vox");
    let i = b.windows(4).position(|w| w == b"XYZI").unwrap();
    let n = u32::from_le_bytes(b[i + 12..i + 16].try_into().unwrap());
    b[i + 12..i + 16].copy_from_slice(&(n + 1).to_le_bytes());
    let dir = temp_dir("xyzi");
    let p = dir.join("bad.vox");
    std::fs::write(&p, &b).unwrap();
    let e = load_vox(&p, None).unwrap_err().to_string();
    assert!(
        e.contains("bad.vox") && e.contains(&format!("chunk \"XYZI\" at byte {i}")),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_type_error_states_the_allowed_range() {
    let e = Experiment::from_str("[render]\nwidth = \"x\"\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("x.toml:2") && e.contains("expected an integer") && e.contains("1..=16384"),
        "{e}"
    );
    let e = Experiment::from_str("[camera]\ndistance = \"far\"\n", "x.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("expected a number") && e.contains("> 0"), "{e}");
}

/// Keys of arrays of tables and keys that take arrays state what they take too: the
/// shape (a vector's 3 numbers, a rect's 2 sides) and the range of each number, in the
/// `[[table]]` form and the inline one, for any entry of the array.
#[test]
fn a_type_error_in_an_array_states_its_shape_and_range() {
    let rect = "type = \"rect\", position = [1, 2, 3], intensity = 1, normal = [0, -1, 0]";
    let point = "type = \"point\", position = [1, 2, 3], intensity = 1";
    let cases = [
        // (file, key, what the message must say)
        (
            format!("lights = [{{{point}}}, {{{rect}, size = 2}}]\n"),
            "lights[1].size",
            "an array of 2 numbers: each side must be a finite number >= 0",
        ),
        (
            format!("lights = [{{{rect}, size = [1, 2, 3]}}]\n"),
            "lights[0].size",
            "an array of 2 numbers: each side",
        ),
        (
            format!("lights = [{{{point}, color = true}}]\n"),
            "lights[0].color",
            "an array of 3 numbers: every component must be a finite number >= 0",
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [1, 2]\nintensity = 1\n".to_string(),
            "lights[0].position",
            "expected an array of length 3; an array of 3 numbers",
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [1, 2, 3]\nintensity = 1\n\
             [[lights]]\ntype = \"point\"\nposition = [1, 2, 3]\nintensity = \"bright\"\n"
                .to_string(),
            "lights[1].intensity",
            "expected a number; must be a finite number >= 0",
        ),
        (
            "[[materials]]\nname = \"a\"\n[[materials]]\nname = \"b\"\nkd = \"half\"\n".to_string(),
            "materials[1].kd",
            "expected a number; must be a finite number in [0, 1]",
        ),
        (
            "[[materials]]\nname = \"a\"\nsigma = [1, 2, 3, 4]\n".to_string(),
            "materials[0].sigma",
            "an array of 3 numbers: every component must be a finite number >= 0",
        ),
        (
            "[[materials]]\nname = \"a\"\nalbedo = 0.5\n".to_string(),
            "materials[0].albedo",
            "an array of 3 numbers: every component",
        ),
        (
            "[camera]\ntarget = 4\n".to_string(),
            "camera.target",
            "expected a sequence; an array of 3 numbers",
        ),
        // An entry's range is its array's.
        (
            "[scene]\ndims = [8, 2.5, 8]\n".to_string(),
            "scene.dims[1] = 2.5",
            "expected an integer; every side must be an integer in 1..=268435456 (voxels)",
        ),
        (
            "[scene]\nsize = \"big\"\n".to_string(),
            "scene.size",
            "expected an integer; must be an integer in 1..=4096 (voxels)",
        ),
    ];
    for (text, key, says) in cases {
        let e = Experiment::from_str(&text, "x.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains(key) && e.contains(says), "{text}\n{e}");
    }
}

/// A mesh of the wrong scale is named as such (its size and the voxel it would give),
/// not as "too large".
#[test]
fn a_mesh_of_the_wrong_scale_says_so() {
    let dir = temp_dir("scale");
    for (scale, what) in [("1e-30", "tiny"), ("1e30", "huge")] {
        let p = dir.join(format!("{what}.obj"));
        std::fs::write(
            &p,
            format!(
                "v 0 0 0\nv {scale} 0 0\nv 0 {scale} 0\nv 0 0 {scale}\n\
                 f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
            ),
        )
        .unwrap();
        let e = voxelize_mesh(&p, &VoxelizeOptions::count(8))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            !e.contains("too large")
                && e.contains("voxel size must be in")
                && e.contains("scale the mesh"),
            "{what}: {e}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// glTF buffer URIs: a file: URI names the file it names; other schemes are refused
/// by name, never read as a relative path.
#[test]
fn gltf_buffer_uris_with_a_scheme() {
    let dir = temp_dir("gltf_uri");
    // One triangle: three f32 positions.
    let mut bin = Vec::new();
    for v in [0f32, 0., 0., 1., 0., 0., 0., 1., 0.] {
        bin.extend(v.to_le_bytes());
    }
    let bin_path = dir.join("tri.bin");
    std::fs::write(&bin_path, &bin).unwrap();
    let gltf = |uri: &str| {
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":"{uri}","byteLength":36}}],
            "bufferViews":[{{"buffer":0,"byteLength":36}}],
            "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",
              "min":[0,0,0],"max":[1,1,0]}}],
            "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],
            "nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
        )
    };
    let p = dir.join("m.gltf");
    for uri in [
        format!("file://{}", bin_path.display()),
        format!("file://localhost{}", bin_path.display()),
        "tri.bin".to_string(),
    ] {
        std::fs::write(&p, gltf(&uri)).unwrap();
        let m = voxlab::scene::load_mesh(&p).unwrap_or_else(|e| panic!("{uri}: {e}"));
        assert_eq!(m.triangles.len(), 1, "{uri}");
    }
    for (uri, says) in [
        ("http://example.invalid/tri.bin", "http: URI"),
        ("file://otherhost/tri.bin", "another host"),
    ] {
        std::fs::write(&p, gltf(uri)).unwrap();
        let e = voxlab::scene::load_mesh(&p)
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(says), "{uri}: {e}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
