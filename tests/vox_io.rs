//! MagicaVoxel import and export: real files (deer.vox, dot_vox's resources), the
//! scene graph, materials, axes, round trips, and clear errors on bad input.

mod common;

use std::path::{Path, PathBuf};

use dot_vox::{Color, Dict, DotVoxData, Frame, Layer, Model, SceneNode, ShapeModel, Size, Voxel};
use glam::{DVec3, IVec3, UVec3};
use voxlab::scene::mesh::VoxelizeOptions;
use voxlab::scene::{Grid, Material, load_vox, seed_palette, voxelize_mesh, write_vox};

/// The `.vox` files shipped inside the dot_vox package (after `cargo fetch`).
fn dot_vox_resources() -> PathBuf {
    let home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cargo")))
        .expect("neither CARGO_HOME nor HOME is set");
    let src = home.join("registry/src");
    let found = std::fs::read_dir(&src).ok().and_then(|dirs| {
        dirs.flatten()
            .map(|d| d.path().join("dot_vox-5.2.0/src/resources"))
            .find(|p| p.is_dir())
    });
    found.unwrap_or_else(|| {
        panic!(
            "dot_vox 5.2.0's resources not found under {}: run `cargo fetch`",
            src.display()
        )
    })
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxlab-vox-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn solid(g: &Grid) -> usize {
    g.data().iter().filter(|&&m| m != 0).count()
}

/// The RGBA chunk read straight from the file's bytes, independently of dot_vox:
/// entry k is colour index k + 1.
fn raw_palette(bytes: &[u8]) -> Vec<[u8; 4]> {
    let at = bytes
        .windows(4)
        .position(|w| w == b"RGBA")
        .expect("RGBA chunk");
    bytes[at + 12..at + 12 + 1024]
        .chunks(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect()
}

#[test]
fn deer_loads_with_documented_axes_and_palette() {
    let path = common::example_data("deer.vox");
    let s = load_vox(&path, None).unwrap();
    assert_eq!(s.model_count, 1);
    assert_eq!(solid(&s.grid), 355);
    // MagicaVoxel 26 x 9 x 27 (z up) -> voxlab (x, z, y) = 26 x 27 x 9 (y up).
    assert_eq!(s.grid.dims(), UVec3::new(26, 27, 9));
    assert_eq!(s.grid.voxel_size(), 1.0);
    assert_eq!(s.grid.origin(), DVec3::ZERO);
    // 30 palette colours, plus void.
    assert_eq!(s.materials.len(), 31);
    assert_eq!(s.palette_index.len(), 31);

    // The file's first voxel is (13, 5, 9) with colour 94 (read with a hex viewer):
    // voxlab (x, z, 9 - 1 - y) = (13, 9, 3).
    let bytes = std::fs::read(&path).unwrap();
    let pal = raw_palette(&bytes);
    let m = s.grid.get(IVec3::new(13, 9, 3));
    assert_ne!(m, 0);
    assert_eq!(s.palette_index[m as usize], 94);
    let c = pal[93];
    let want = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) / 255.0;
    assert_eq!(s.materials[m as usize].albedo, want);
    assert_eq!(s.materials[m as usize].kd, 0.8);
    assert_eq!(s.materials[m as usize].emission, DVec3::ZERO);

    // Up is up: the file's highest voxels (z = 21, antler tips, e.g. (8, 2, 21)) are
    // voxlab's highest, y = 21, and its lowest (z = 0, e.g. the hoof (18, 3, 0)) lie
    // at y = 0.
    assert_ne!(s.grid.get(IVec3::new(8, 21, 6)), 0);
    assert_ne!(s.grid.get(IVec3::new(18, 0, 5)), 0);
    let highest = (0..27)
        .rev()
        .find(|&y| (0..26).any(|x| (0..9).any(|z| s.grid.get(IVec3::new(x, y, z)) != 0)))
        .unwrap();
    assert_eq!(highest, 21);

    // Every voxel of the raw XYZI chunk lands where the mapping says, with its colour.
    let at = bytes.windows(4).position(|w| w == b"XYZI").unwrap();
    let n = u32::from_le_bytes(bytes[at + 12..at + 16].try_into().unwrap()) as usize;
    assert_eq!(n, 355);
    for k in 0..n {
        let v = &bytes[at + 16 + 4 * k..at + 20 + 4 * k];
        let g = IVec3::new(v[0] as i32, v[2] as i32, 8 - v[1] as i32);
        assert_eq!(s.palette_index[s.grid.get(g) as usize], v[3], "voxel {v:?}");
    }
}

#[test]
fn every_dot_vox_resource_loads_or_fails_clearly() {
    let dir = dot_vox_resources();
    let mut loaded = 0;
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        let p = e.path();
        if p.extension().is_none_or(|x| x != "vox") {
            continue;
        }
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        match load_vox(&p, None) {
            Ok(s) => {
                assert_ne!(name, "not_a.vox");
                assert!(solid(&s.grid) > 0, "{name}");
                assert!(
                    (s.grid.max_material() as usize) < s.materials.len(),
                    "{name}"
                );
                loaded += 1;
            }
            Err(err) => {
                assert_eq!(name, "not_a.vox", "{err}");
                let msg = err.to_string();
                assert!(
                    msg.contains("not_a.vox") && msg.contains("not a valid MagicaVoxel"),
                    "{msg}"
                );
            }
        }
    }
    assert_eq!(
        loaded, 5,
        "axes, metal-material, placeholder(-with-materials), single-voxel"
    );
}

#[test]
fn scene_graph_places_every_model_of_axes_vox() {
    let p = dot_vox_resources().join("axes.vox");
    let all = load_vox(&p, None).unwrap();
    assert_eq!(all.model_count, 4);
    // Models 0-2 are instanced three times each by the scene graph, model 3 once.
    let counts: Vec<usize> = (0..4)
        .map(|k| solid(&load_vox(&p, Some(k)).unwrap().grid))
        .collect();
    assert_eq!(counts, vec![920, 1640, 1480, 332]);
    let placed = solid(&all.grid);
    assert!(
        placed > counts.iter().sum::<usize>(),
        "{placed}: instances missing"
    );
    // A chosen model comes alone, in its own SIZE: 40^3 (z-up to y-up is a no-op on
    // a cube's dimensions) and 32^3.
    assert_eq!(load_vox(&p, Some(0)).unwrap().grid.dims(), UVec3::splat(40));
    assert_eq!(load_vox(&p, Some(3)).unwrap().grid.dims(), UVec3::splat(32));
    let e = load_vox(&p, Some(4)).unwrap_err().to_string();
    assert!(
        e.contains("axes.vox") && e.contains("model 4") && e.contains("0..=3"),
        "{e}"
    );
}

/// A file with one model and a scene graph of the given frame attributes.
fn one_model_file(model: Model, frame: &[(&str, &str)]) -> DotVoxData {
    let mut f = Dict::new();
    for (k, v) in frame {
        f.insert(k.to_string(), v.to_string());
    }
    let mut palette = dot_vox::DEFAULT_PALETTE.to_vec();
    palette[0] = Color {
        r: 255,
        g: 0,
        b: 0,
        a: 255,
    };
    palette[1] = Color {
        r: 0,
        g: 0,
        b: 255,
        a: 255,
    };
    DotVoxData {
        version: 150,
        index_map: vec![],
        models: vec![model],
        palette,
        materials: vec![],
        scenes: vec![
            SceneNode::Transform {
                attributes: Dict::new(),
                frames: vec![Frame::new(Dict::new())],
                child: 1,
                layer_id: u32::MAX,
            },
            SceneNode::Group {
                attributes: Dict::new(),
                children: vec![2],
            },
            SceneNode::Transform {
                attributes: Dict::new(),
                frames: vec![Frame::new(f)],
                child: 3,
                layer_id: 0,
            },
            SceneNode::Shape {
                attributes: Dict::new(),
                models: vec![ShapeModel {
                    model_id: 0,
                    attributes: Dict::new(),
                }],
            },
        ],
        layers: vec![Layer {
            attributes: Dict::new(),
        }],
    }
}

fn save(dir: &Path, name: &str, d: &DotVoxData) -> PathBuf {
    let p = dir.join(name);
    let mut bytes = Vec::new();
    d.write_vox(&mut bytes).unwrap();
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A 3 x 1 x 1 bar, red at x = 0 and blue at x = 2 (colour indices 1 and 2).
fn bar() -> Model {
    Model {
        size: Size { x: 3, y: 1, z: 1 },
        voxels: vec![
            Voxel {
                x: 0,
                y: 0,
                z: 0,
                i: 0,
            },
            Voxel {
                x: 2,
                y: 0,
                z: 0,
                i: 1,
            },
        ],
    }
}

#[test]
fn rotation_byte_turns_the_model() {
    let dir = temp_dir("rot");
    // _r = 17: row 0 takes -y, row 1 takes +x, row 2 +z: a quarter turn about z that
    // maps the bar's +x onto MagicaVoxel +y. Red (local x = 0) goes to y = -1, blue
    // to y = +1 (pivot floor(3 / 2) = 1, centres at -0.5 and +1.5 -> cells -1 and 1).
    let p = save(&dir, "rot.vox", &one_model_file(bar(), &[("_r", "17")]));
    let s = load_vox(&p, None).unwrap();
    // MagicaVoxel extent 1 x 3 x 1 -> voxlab (x, z, y) = 1 x 1 x 3, and voxlab z runs
    // against MagicaVoxel y: blue (y = 1, the maximum) at z = 0, red at z = 2.
    assert_eq!(s.grid.dims(), UVec3::new(1, 1, 3));
    let colour = |z: i32| s.materials[s.grid.get(IVec3::new(0, 0, z)) as usize].albedo;
    assert_eq!(colour(0), DVec3::Z);
    assert_eq!(colour(1), DVec3::ZERO);
    assert_eq!(colour(2), DVec3::X);

    // Without rotation the bar lies along x, red first.
    let p = save(
        &dir,
        "plain.vox",
        &one_model_file(bar(), &[("_t", "5 -7 3")]),
    );
    let s = load_vox(&p, None).unwrap();
    assert_eq!(s.grid.dims(), UVec3::new(3, 1, 1));
    assert_eq!(
        s.materials[s.grid.get(IVec3::ZERO) as usize].albedo,
        DVec3::X
    );
    assert_eq!(
        s.materials[s.grid.get(IVec3::new(2, 0, 0)) as usize].albedo,
        DVec3::Z
    );

    // A flip (_r = 4 + 16: row 0 negated) mirrors x: blue first.
    let p = save(&dir, "flip.vox", &one_model_file(bar(), &[("_r", "20")]));
    let s = load_vox(&p, None).unwrap();
    assert_eq!(
        s.materials[s.grid.get(IVec3::ZERO) as usize].albedo,
        DVec3::Z
    );

    // Malformed rotation bytes and translations are errors, not panics.
    for (k, v) in [
        ("_r", "3"),
        ("_r", "5"),
        ("_r", "300"),
        ("_r", "x"),
        ("_t", "1 2"),
    ] {
        let p = save(&dir, "bad.vox", &one_model_file(bar(), &[(k, v)]));
        let e = load_vox(&p, None).unwrap_err().to_string();
        assert!(e.contains("bad.vox") && e.contains(k), "{k} = {v}: {e}");
    }
}

fn with_matl(props: &[(&str, &str)]) -> DotVoxData {
    let mut d = one_model_file(bar(), &[]);
    let mut m = Dict::new();
    for (k, v) in props {
        m.insert(k.to_string(), v.to_string());
    }
    // MATL ids are colour indices: the blue voxel has colour 2.
    d.materials.push(dot_vox::Material {
        id: 2,
        properties: m,
    });
    d
}

fn blue_material(dir: &Path, props: &[(&str, &str)]) -> Material {
    let p = save(dir, "m.vox", &with_matl(props));
    let s = load_vox(&p, None).unwrap();
    let m = s.grid.get(IVec3::new(2, 0, 0));
    assert_eq!(s.palette_index[m as usize], 2);
    s.materials[m as usize].clone()
}

#[test]
fn magicavoxel_materials_map_onto_voxlab() {
    let dir = temp_dir("matl");
    // Glass: _ior is ior - 1; _ri, where present, is the index itself.
    let g = blue_material(
        &dir,
        &[("_type", "_glass"), ("_trans", "0.6"), ("_ior", "0.5")],
    );
    assert_eq!((g.kt, g.ior), (0.6, 1.5));
    assert!(g.name.contains("glass"));
    let g = blue_material(
        &dir,
        &[
            ("_type", "_glass"),
            ("_alpha", "0.3"),
            ("_ri", "1.33"),
            ("_ior", "0.33"),
        ],
    );
    assert_eq!((g.kt, g.ior), (0.3, 1.33));
    // Metal: kr from _metal, ks from roughness.
    let m = blue_material(
        &dir,
        &[("_type", "_metal"), ("_metal", "0.9"), ("_rough", "0.25")],
    );
    assert_eq!((m.kr, m.ks, m.kt), (0.9, 0.75, 0.0));
    assert!((m.kd - 0.08).abs() < 1e-12);
    // Emissive: radiance = albedo * _emit * (1 + _flux).
    let e = blue_material(
        &dir,
        &[("_type", "_emit"), ("_emit", "0.5"), ("_flux", "1")],
    );
    assert_eq!(e.emission, DVec3::new(0.0, 0.0, 1.0));
    assert_eq!(e.kt, 0.0);
    // Anything else is diffuse; a non-numeric value is ignored, not fatal.
    let d = blue_material(&dir, &[("_type", "_blend"), ("_metal", "lots")]);
    assert_eq!((d.kd, d.ks, d.kr, d.kt), (0.8, 0.1, 0.0, 0.0));
    assert_eq!(d.emission, DVec3::ZERO);

    // The real file: colour 85 is an old-style metal whose _weight is its metalness.
    let p = dot_vox_resources().join("metal-material.vox");
    let s = load_vox(&p, None).unwrap();
    let k = s
        .palette_index
        .iter()
        .position(|&i| i == 85)
        .expect("colour 85 used");
    let m = &s.materials[k];
    assert!(
        (m.kr - 0.526316).abs() < 1e-6 && (m.ks - (1.0 - 0.252632)).abs() < 1e-6,
        "{m:?}"
    );
}

#[test]
fn bunny_round_trips_through_vox() {
    let v = voxelize_mesh(
        common::example_data("bunny.obj"),
        &VoxelizeOptions::count(64),
    )
    .unwrap();
    let dir = temp_dir("bunny");
    let p = dir.join("bunny.vox");
    write_vox(&p, &v.grid, &v.materials).unwrap();
    // dot_vox (a third reader) sees one model within MagicaVoxel's 256 limit.
    let raw = dot_vox::load(p.to_str().unwrap()).unwrap();
    assert_eq!(raw.models.len(), 1);
    assert_eq!(raw.palette.len(), 256);
    let back = load_vox(&p, None).unwrap();
    assert_eq!(back.grid.dims(), v.grid.dims());
    assert_eq!(back.grid.data(), v.grid.data());
    assert_eq!(back.materials[1].albedo, v.materials[1].albedo);
    assert!(
        !dir.read_dir()
            .unwrap()
            .flatten()
            .any(|e| e.file_name().to_string_lossy().contains("tmp"))
    );
}

/// Deterministic sparse content in several materials, including glass.
fn pattern_grid(dims: UVec3) -> (Grid, Vec<Material>) {
    let mut g = Grid::new(dims, 0.5, DVec3::new(1.0, 2.0, 3.0)).unwrap();
    for z in 0..dims.z as i32 {
        for y in 0..dims.y as i32 {
            for x in 0..dims.x as i32 {
                let h = (x.wrapping_mul(73856093)
                    ^ y.wrapping_mul(19349663)
                    ^ z.wrapping_mul(83492791)) as u32
                    % 97;
                if h < 4 {
                    g.set(IVec3::new(x, y, z), 1 + h as u8 % 3);
                }
            }
        }
    }
    // The far corners, so the extent is exactly the grid's.
    g.set(IVec3::ZERO, 1);
    g.set(dims.as_ivec3() - 1, 2);
    let mut mats = seed_palette();
    mats[2].albedo = DVec3::new(0.2, 0.4, 0.6);
    (g, mats)
}

#[test]
fn grids_beyond_256_are_split_and_reassembled() {
    let dims = UVec3::new(300, 5, 260);
    let (g, mats) = pattern_grid(dims);
    let dir = temp_dir("split");
    let p = dir.join("big.vox");
    write_vox(&p, &g, &mats).unwrap();
    let raw = dot_vox::load(p.to_str().unwrap()).unwrap();
    // MagicaVoxel space is (x, z, y) = 300 x 260 x 5: 2 x 2 x 1 blocks.
    assert_eq!(raw.models.len(), 4);
    assert!(
        raw.models
            .iter()
            .all(|m| m.size.x <= 256 && m.size.y <= 256 && m.size.z <= 256)
    );
    let back = load_vox(&p, None).unwrap();
    assert_eq!(back.grid.dims(), dims);
    // Materials come back numbered by colour index, which is the voxlab index.
    assert_eq!(back.grid.data(), g.data());
    assert_eq!(
        back.materials[2].albedo,
        DVec3::new(51.0, 102.0, 153.0) / 255.0
    );
    // The seed's glass keeps its transmission and index of refraction.
    assert!((back.materials[1].kt - 0.8).abs() < 1e-12);
    assert!((back.materials[1].ior - 1.5).abs() < 1e-12);
}

#[test]
fn writing_fails_cleanly() {
    let (g, mats) = pattern_grid(UVec3::new(4, 4, 4));
    let dir = temp_dir("write-fail");
    let p = dir.join("no/such/dir/out.vox");
    let e = write_vox(&p, &g, &mats).unwrap_err().to_string();
    assert!(e.contains("out.vox") && e.contains("cannot write"), "{e}");
    let e = write_vox(dir.join("few.vox"), &g, &mats[..2])
        .unwrap_err()
        .to_string();
    assert!(e.contains("few.vox") && e.contains("material"), "{e}");
    assert!(!dir.join("few.vox").exists());
}

#[test]
fn bad_vox_files_give_clear_errors_and_never_panic() {
    let dir = temp_dir("hostile");
    let e = load_vox(dir.join("missing.vox"), None)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("missing.vox") && e.contains("cannot read"),
        "{e}"
    );

    let e = load_vox(common::example_data("deer.vox"), Some(1))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("deer.vox") && e.contains("model 1") && e.contains("0..=0"),
        "{e}"
    );

    // Truncations and corruptions of real files: an error naming the file, or a
    // grid whose materials cover it. Never a panic, never an unbounded allocation.
    let p = dir.join("h.vox");
    for src in [
        common::example_data("deer.vox"),
        dot_vox_resources().join("axes.vox"),
    ] {
        let good = std::fs::read(&src).unwrap();
        let mut cuts: Vec<usize> = (0..good.len().min(4000)).step_by(7).collect();
        cuts.extend((0..good.len()).step_by(997));
        for cut in cuts {
            std::fs::write(&p, &good[..cut]).unwrap();
            check(&p);
        }
        let mut state = 12345u64;
        for _ in 0..300 {
            let mut bad = good.clone();
            for _ in 0..4 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let i = (state >> 33) as usize % bad.len();
                bad[i] = (state >> 20) as u8;
            }
            std::fs::write(&p, &bad).unwrap();
            check(&p);
        }
    }

    // A model claiming 2^31 voxels per side with a voxel beyond its size, and models
    // translated far apart: refused before allocating.
    let mut d = one_model_file(bar(), &[]);
    d.models[0].size = Size { x: 2, y: 1, z: 1 };
    let e = load_vox(save(&dir, "outside.vox", &d), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("outside its size"), "{e}");
    let d = one_model_file(bar(), &[("_t", "2000000000 0 0")]);
    let mut d2 = d;
    d2.scenes[1] = SceneNode::Group {
        attributes: Dict::new(),
        children: vec![2, 4],
    };
    let mut far = Dict::new();
    far.insert("_t".into(), "-2000000000 0 0".into());
    d2.scenes.push(SceneNode::Transform {
        attributes: Dict::new(),
        frames: vec![Frame::new(far)],
        child: 3,
        layer_id: 0,
    });
    let e = load_vox(save(&dir, "far.vox", &d2), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("far.vox") && e.contains("too large"), "{e}");

    // Two bars 4000 apart on every axis span 6.4e10 voxels: held as a sparse tree, of
    // four voxels, without a dense grid; 4200 apart, past a sparse grid's side, refused.
    for (reach, loads) in [(2000, true), (2100, false)] {
        let near = format!("{reach} {reach} {reach}");
        let mut d = one_model_file(bar(), &[("_t", near.as_str())]);
        d.scenes[1] = SceneNode::Group {
            attributes: Dict::new(),
            children: vec![2, 4],
        };
        let mut far = Dict::new();
        far.insert("_t".into(), format!("-{reach} -{reach} -{reach}"));
        d.scenes.push(SceneNode::Transform {
            attributes: Dict::new(),
            frames: vec![Frame::new(far)],
            child: 3,
            layer_id: 0,
        });
        let r = load_vox(save(&dir, "apart.vox", &d), None);
        if loads {
            let s = r.unwrap();
            assert!(s.grid.is_sparse(), "{}", s.grid.dims());
            assert_eq!(s.grid.material_counts()[1..].iter().sum::<u64>(), 4);
            assert!(s.grid.host_bytes() < 1 << 16, "{}", s.grid.host_bytes());
        } else {
            let e = r.unwrap_err().to_string();
            assert!(e.contains("apart.vox") && e.contains("4096"), "{e}");
        }
    }

    // A scene graph that refers to itself.
    let mut d = one_model_file(bar(), &[]);
    d.scenes[1] = SceneNode::Group {
        attributes: Dict::new(),
        children: vec![0],
    };
    let e = load_vox(save(&dir, "cycle.vox", &d), None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cycle.vox") && e.contains("deeper"), "{e}");
}

fn check(p: &Path) {
    match load_vox(p, None) {
        Ok(s) => assert!((s.grid.max_material() as usize) < s.materials.len()),
        Err(e) => assert!(e.to_string().contains("h.vox"), "{e}"),
    }
}

/// Nodes and layers marked hidden leave their models out, as in MagicaVoxel (and as
/// ogt_vox reads them); a file whose graph hides every model is refused for that
/// reason (it was called "every model placed has an empty size").
#[test]
fn hidden_nodes_and_layers_leave_their_models_out() {
    let dir = temp_dir("hidden");
    let hide = |d: &mut DotVoxData, node: usize| {
        if let SceneNode::Transform { attributes, .. } = &mut d.scenes[node] {
            attributes.insert("_hidden".into(), "1".into());
        }
    };
    // A second model (a single voxel) beside the bar, under its own transform node.
    let two = || {
        let mut d = one_model_file(bar(), &[]);
        d.models.push(Model {
            size: Size { x: 1, y: 1, z: 1 },
            voxels: vec![Voxel {
                x: 0,
                y: 0,
                z: 0,
                i: 1,
            }],
        });
        let mut f = Dict::new();
        f.insert("_t".into(), "0 0 5".into());
        d.scenes.push(SceneNode::Transform {
            attributes: Dict::new(),
            frames: vec![Frame::new(f)],
            child: 5,
            layer_id: 1,
        });
        d.scenes.push(SceneNode::Shape {
            attributes: Dict::new(),
            models: vec![ShapeModel {
                model_id: 1,
                attributes: Dict::new(),
            }],
        });
        if let SceneNode::Group { children, .. } = &mut d.scenes[1] {
            children.push(4);
        }
        d.layers.push(Layer {
            attributes: Dict::new(),
        });
        d
    };
    let both = load_vox(save(&dir, "both.vox", &two()), None).unwrap();
    assert_eq!(solid(&both.grid), 3);
    // The single voxel's node hidden, or its layer: the bar alone.
    let mut d = two();
    hide(&mut d, 4);
    let s = load_vox(save(&dir, "node.vox", &d), None).unwrap();
    assert_eq!((s.grid.dims(), solid(&s.grid)), (UVec3::new(3, 1, 1), 2));
    let mut d = two();
    d.layers[1].attributes.insert("_hidden".into(), "1".into());
    let s = load_vox(save(&dir, "layer.vox", &d), None).unwrap();
    assert_eq!((s.grid.dims(), solid(&s.grid)), (UVec3::new(3, 1, 1), 2));
    // The group's node hidden: nothing shows.
    let mut d = two();
    hide(&mut d, 0);
    let p = save(&dir, "none.vox", &d);
    let e = load_vox(&p, None).unwrap_err().to_string();
    assert!(
        e.contains("none.vox") && e.contains("shows none of its 2 model(s)"),
        "{e}"
    );
    // A model chosen by index is loaded whatever the graph hides.
    assert_eq!(solid(&load_vox(&p, Some(0)).unwrap().grid), 2);
}
