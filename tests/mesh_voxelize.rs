//! Mesh loading and voxelization: real data (the Stanford bunny), exact small cases,
//! glTF, open meshes, and clear errors on bad input.

mod common;

use std::path::{Path, PathBuf};

use glam::{DVec3, IVec3, UVec3};
use voxlab::scene::mesh::{TriangleMesh, voxelize};
use voxlab::scene::voxelize::signed_volume;
use voxlab::scene::{
    Material, Resolution, VoxelizeOptions, load_mesh, seed_palette, voxelize_mesh,
};

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxlab-mesh-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn solid_count(g: &voxlab::scene::Grid) -> usize {
    g.data().iter().filter(|&&m| m != 0).count()
}

/// Bunny at 32 and 64: closed, so filled watertight. A conservative voxelization
/// contains the mesh, so its volume is at least the mesh's (divergence theorem); it
/// exceeds it by a shell about 0.75 voxel thick over the surface (27 % at 32, 13 % at
/// 64 for the bunny), so the excess relative to the voxel size is bounded and roughly
/// halves from 32 to 64. A leaking fill would leave the interior void and fall far
/// below the mesh volume.
#[test]
fn bunny_is_filled_watertight() {
    let path = common::example_data("bunny.obj");
    let mesh = load_mesh(&path).unwrap();
    assert_eq!(mesh.triangles.len(), 3674);
    let v_mesh = signed_volume(&mesh.triangles).abs();
    let area: f64 = mesh
        .triangles
        .iter()
        .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
        .sum();
    let mut excess = Vec::new();
    for n in [32, 64] {
        let v = voxelize_mesh(&path, &VoxelizeOptions::count(n)).unwrap();
        assert!(v.closed, "the bunny is closed: {:?}", v.warnings);
        assert!(v.warnings.is_empty(), "{:?}", v.warnings);
        assert_eq!(v.grid.dims().max_element(), n);
        assert!(v.interior_voxels > 0);
        let h = v.grid.voxel_size();
        let v_vox = solid_count(&v.grid) as f64 * h.powi(3);
        assert_eq!(solid_count(&v.grid), v.shell_voxels + v.interior_voxels);
        // The outward shell: between 0 and a full voxel diagonal thick over the surface.
        let shell = (v_vox - v_mesh) / (area * h);
        println!(
            "bunny at {n}: voxels {:.6} mesh {:.6} ({:+.2} %), shell {shell:.3} voxel widths",
            v_vox,
            v_mesh,
            100.0 * (v_vox / v_mesh - 1.0)
        );
        // A rigorous bracket: the solid contains the mesh, and the filled voxels
        // (which touch no triangle) lie inside it.
        let v_in = v.interior_voxels as f64 * h.powi(3);
        assert!(v_in <= v_mesh && v_mesh <= v_vox, "{v_in} {v_mesh} {v_vox}");
        // The shell straddles the surface about evenly, so the bracket's midpoint is
        // close: within a few percent even at 32.
        let mid = 0.5 * (v_in + v_vox);
        println!("  bracket midpoint {:+.2} %", 100.0 * (mid / v_mesh - 1.0));
        assert!(
            (mid / v_mesh - 1.0).abs() < 0.03,
            "midpoint {mid} vs {v_mesh}"
        );
        assert!(
            shell < 3f64.sqrt(),
            "shell {shell} thicker than a voxel diagonal"
        );
        excess.push(v_vox / v_mesh - 1.0);
    }
    // Convergence: the relative excess falls roughly as 1 / n.
    assert!(
        excess[1] < 0.65 * excess[0],
        "excess {excess:?} does not converge like 1/n"
    );
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

const CUBE_OBJ: &str = "\
v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8
";

#[test]
fn unit_cube_gives_exactly_the_expected_voxels() {
    let dir = temp_dir("cube");
    let p = write(&dir, "cube.obj", CUBE_OBJ);
    for n in [1, 4, 10] {
        let v = voxelize_mesh(&p, &VoxelizeOptions::count(n)).unwrap();
        assert!(v.closed);
        assert_eq!(v.grid.dims(), UVec3::splat(n));
        assert_eq!(v.grid.origin(), DVec3::ZERO);
        assert!((v.grid.voxel_size() - 1.0 / n as f64).abs() < 1e-15);
        assert_eq!(solid_count(&v.grid), (n * n * n) as usize);
        let inner = n.saturating_sub(2).pow(3) as usize;
        assert_eq!(v.interior_voxels, inner, "n = {n}");
        assert_eq!(v.shell_voxels, (n * n * n) as usize - inner);
    }
    // By voxel size, with faces inside voxels: 0.3 gives ceil(1 / 0.3) = 4 per side.
    let v = voxelize_mesh(
        &p,
        &VoxelizeOptions {
            resolution: Resolution::VoxelSize(0.3),
            material: None,
            storage: voxlab::scene::Storage::Auto,
        },
    )
    .unwrap();
    assert_eq!(v.grid.dims(), UVec3::splat(4));
    assert_eq!(solid_count(&v.grid), 64);
}

/// An icosphere OBJ (closed), radius 1, centred at the origin: `common::icosphere`'s
/// soup, three vertices a face (the voxelizer welds them by position).
fn icosphere(subdivisions: u32) -> String {
    let mut obj = String::new();
    for (i, t) in common::icosphere(subdivisions).iter().enumerate() {
        for p in t {
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        obj += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
    }
    obj
}

#[test]
fn sphere_volume_brackets_and_converges() {
    let dir = temp_dir("sphere");
    let p = write(&dir, "sphere.obj", &icosphere(4));
    let mesh = load_mesh(&p).unwrap();
    let v_mesh = signed_volume(&mesh.triangles);
    assert!(v_mesh > 0.0, "outward winding");
    let mut rel = Vec::new();
    for n in [32, 64, 128] {
        let v = voxelize_mesh(&p, &VoxelizeOptions::count(n)).unwrap();
        assert!(v.closed, "{:?}", v.warnings);
        let h = v.grid.voxel_size();
        let v_vox = solid_count(&v.grid) as f64 * h.powi(3);
        // Everything strictly inside the shell lies inside the sphere.
        let v_in = v.interior_voxels as f64 * h.powi(3);
        println!(
            "sphere at {n}: solid {:+.2} %, interior {:+.2} %",
            100.0 * (v_vox / v_mesh - 1.0),
            100.0 * (v_in / v_mesh - 1.0)
        );
        assert!(v_in <= v_mesh && v_mesh <= v_vox);
        rel.push(v_vox / v_mesh - 1.0);
    }
    // A half-to-one voxel shell over area 4 pi r^2 on a radius of n / 2 voxels:
    // about 3 * 0.75 / (n / 2); 128 voxels across stays within 5 %.
    assert!(rel[2] < 0.05, "{rel:?}");
    assert!(rel[1] < 0.6 * rel[0] && rel[2] < 0.6 * rel[1], "{rel:?}");
}

/// The issue asks for a sphere's volume within 1 % of 4/3 pi r^3 at resolution 128. A
/// conservative voxelization cannot give that by counting voxels (every voxel the
/// surface touches is solid: +3.5 % at 128, see above), but it brackets the volume
/// between its interior and its interior plus shell, and the surface cuts the shell
/// voxels about in half on average: interior + shell / 2 estimates the volume.
#[test]
fn sphere_volume_estimate_within_one_percent_at_128() {
    let dir = temp_dir("sphere128");
    // Subdivision 5 (20,480 faces): its own volume is within 0.1 % of the sphere's.
    let p = write(&dir, "sphere.obj", &icosphere(5));
    let v = voxelize_mesh(&p, &VoxelizeOptions::count(128)).unwrap();
    let h3 = v.grid.voxel_size().powi(3);
    let estimate = (v.interior_voxels as f64 + 0.5 * v.shell_voxels as f64) * h3;
    let exact = 4.0 / 3.0 * std::f64::consts::PI;
    let rel = estimate / exact - 1.0;
    println!(
        "sphere at 128: interior + shell/2 = {:+.3} % of 4/3 pi r^3",
        100.0 * rel
    );
    assert!(rel.abs() < 0.01, "{rel}");
}

#[test]
fn open_quad_keeps_its_shell_and_warns() {
    let dir = temp_dir("quad");
    let p = write(
        &dir,
        "quad.obj",
        "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 0 1 0\nf 1 2 3 4\n",
    );
    let v = voxelize_mesh(&p, &VoxelizeOptions::count(8)).unwrap();
    assert!(!v.closed);
    assert_eq!(v.interior_voxels, 0);
    assert_eq!(v.warnings.len(), 1, "{:?}", v.warnings);
    let w = &v.warnings[0];
    assert!(w.contains("not closed") && w.contains("quad.obj"), "{w}");
    assert!(w.contains("4 edges"), "{w}");
    // A flat quad: one layer, 8 x 4 voxels.
    assert_eq!(v.grid.dims(), UVec3::new(8, 4, 1));
    assert_eq!(solid_count(&v.grid), 32);
}

#[test]
fn mtl_colours_become_materials_and_an_override_replaces_them() {
    let dir = temp_dir("mtl");
    write(
        &dir,
        "two.mtl",
        "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n",
    );
    // Two separate closed tetrahedra, one per material.
    let obj = "mtllib two.mtl\n\
        v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
        v 3 0 0\nv 4 0 0\nv 3 1 0\nv 3 0 1\n\
        usemtl red\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n\
        usemtl blue\nf 5 7 6\nf 5 6 8\nf 5 8 7\nf 6 7 8\n";
    let p = write(&dir, "two.obj", obj);
    let v = voxelize_mesh(&p, &VoxelizeOptions::count(16)).unwrap();
    assert!(v.closed, "{:?}", v.warnings);
    assert_eq!(v.materials.len(), 3);
    let by_name = |n: &str| v.materials.iter().position(|m| m.name == n).unwrap() as u8;
    let (red, blue) = (by_name("red"), by_name("blue"));
    assert_eq!(v.materials[red as usize].albedo, DVec3::X);
    assert_eq!(v.materials[blue as usize].albedo, DVec3::Z);
    assert_eq!(v.grid.material_at(DVec3::new(0.1, 0.1, 0.1)), red);
    assert_eq!(v.grid.material_at(DVec3::new(3.1, 0.1, 0.1)), blue);

    let glass = seed_palette()[1].clone();
    let o = voxelize_mesh(
        &p,
        &VoxelizeOptions {
            resolution: Resolution::Count(16),
            material: Some(glass.clone()),
            storage: voxlab::scene::Storage::Auto,
        },
    )
    .unwrap();
    assert_eq!(o.materials, vec![seed_palette()[0].clone(), glass]);
    assert_eq!(o.grid.max_material(), 1);
    assert_eq!(solid_count(&o.grid), solid_count(&v.grid));
}

/// Standard base64 (RFC 4648) with padding, for an embedded glTF buffer.
fn base64(data: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A unit cube as an indexed glTF mesh, under a node translated by (10, 20, 30) and a
/// parent node scaled by 2, with a red base colour.
fn cube_gltf() -> String {
    let pos: [[f32; 3]; 8] = [
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.],
        [0., 0., 1.],
        [1., 0., 1.],
        [1., 1., 1.],
        [0., 1., 1.],
    ];
    let idx: [u16; 36] = [
        0, 3, 2, 0, 2, 1, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6,
        3, 0, 4, 3, 4, 7,
    ];
    let mut buf: Vec<u8> = pos.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    buf.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [
    {{"scale": [2, 2, 2], "children": [1]}},
    {{"translation": [10, 20, 30], "mesh": 0}}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "material": 0}}]}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorFactor": [1, 0, 0, 1]}}}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 96}},
    {{"buffer": 0, "byteOffset": 96, "byteLength": 72}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 1]}},
    {{"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}}
  ]
}}"#,
        len = buf.len(),
        b64 = base64(&buf)
    )
}

#[test]
fn gltf_with_embedded_buffer_voxelizes_with_node_transforms() {
    let dir = temp_dir("gltf");
    let p = write(&dir, "cube.gltf", &cube_gltf());
    let v = voxelize_mesh(&p, &VoxelizeOptions::count(8)).unwrap();
    assert!(v.closed, "{:?}", v.warnings);
    assert_eq!(v.triangle_count, 12);
    // Scale 2 after translation 10, 20, 30: the cube spans [20, 22] x [40, 42] x [60, 62].
    assert!((v.grid.origin() - DVec3::new(20.0, 40.0, 60.0)).length() < 1e-9);
    assert!((v.grid.voxel_size() - 0.25).abs() < 1e-12);
    assert_eq!(v.grid.dims(), UVec3::splat(8));
    assert_eq!(solid_count(&v.grid), 512);
    assert_eq!(v.materials[1].albedo, DVec3::X);
}

#[test]
fn the_same_voxels_whatever_the_triangle_order() {
    // Interior material comes from the nearest shell voxel, but occupancy never
    // depends on the order in which triangles are visited.
    let path = common::example_data("bunny.obj");
    let mesh = load_mesh(&path).unwrap();
    let mut rev = mesh.clone();
    rev.triangles.reverse();
    let a = voxelize(&mesh, &VoxelizeOptions::count(24)).unwrap();
    let b = voxelize(&rev, &VoxelizeOptions::count(24)).unwrap();
    assert_eq!(a.grid, b.grid);
}

fn err_of(r: Result<voxlab::scene::Voxelized, voxlab::scene::LoadError>) -> String {
    let e = r.expect_err("expected an error");
    e.to_string()
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = temp_dir("errors");
    let cube = write(&dir, "cube.obj", CUBE_OBJ);

    let missing = dir.join("nope.obj");
    let e = err_of(voxelize_mesh(&missing, &VoxelizeOptions::count(8)));
    assert!(e.contains("nope.obj") && e.contains("cannot read"), "{e}");

    let e = err_of(voxelize_mesh(&cube, &VoxelizeOptions::count(0)));
    assert!(
        e.contains("cube.obj") && e.contains("resolution 0") && e.contains("1..="),
        "{e}"
    );

    for s in [f64::NAN, 0.0, -1.0, f64::INFINITY] {
        let o = VoxelizeOptions {
            resolution: Resolution::VoxelSize(s),
            material: None,
            storage: voxlab::scene::Storage::Auto,
        };
        let e = err_of(voxelize_mesh(&cube, &o));
        assert!(
            e.contains("cube.obj") && e.contains("finite number > 0"),
            "{s}: {e}"
        );
    }

    // Too fine: beyond MAX_VOXELS, refused before allocating.
    let o = VoxelizeOptions {
        resolution: Resolution::VoxelSize(1e-4),
        material: None,
        storage: voxlab::scene::Storage::Auto,
    };
    let e = err_of(voxelize_mesh(&cube, &o));
    assert!(e.contains("too large") && e.contains("at most"), "{e}");
    let e = err_of(voxelize_mesh(&cube, &VoxelizeOptions::count(1 << 16)));
    assert!(e.contains("too large"), "{e}");

    let empty = write(&dir, "empty.obj", "v 0 0 0\nv 1 0 0\n");
    let e = err_of(voxelize_mesh(&empty, &VoxelizeOptions::count(8)));
    assert!(e.contains("empty.obj") && e.contains("no triangles"), "{e}");

    let point = write(&dir, "point.obj", "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n");
    let e = err_of(voxelize_mesh(&point, &VoxelizeOptions::count(8)));
    assert!(e.contains("single point"), "{e}");

    let bad_index = write(&dir, "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    let e = err_of(voxelize_mesh(&bad_index, &VoxelizeOptions::count(8)));
    assert!(e.contains("bad.obj"), "{e}");

    let nan = write(&dir, "nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    let e = err_of(voxelize_mesh(&nan, &VoxelizeOptions::count(8)));
    assert!(e.contains("nan.obj"), "{e}");

    let unknown = write(&dir, "mesh.stl", "solid x\n");
    let e = err_of(voxelize_mesh(&unknown, &VoxelizeOptions::count(8)));
    assert!(
        e.contains("mesh.stl") && e.contains(".obj, .gltf or .glb"),
        "{e}"
    );

    let garbage = write(&dir, "garbage.gltf", "{ this is not json");
    let e = err_of(voxelize_mesh(&garbage, &VoxelizeOptions::count(8)));
    assert!(e.contains("garbage.gltf") && e.contains("glTF"), "{e}");

    let glb = dir.join("garbage.glb");
    std::fs::write(&glb, b"glTF\x02\x00\x00\x00\xff\xff\xff\xff").unwrap();
    let e = err_of(voxelize_mesh(&glb, &VoxelizeOptions::count(8)));
    assert!(e.contains("garbage.glb"), "{e}");
}

#[test]
fn hostile_gltf_never_panics() {
    // Truncations and byte flips of a valid file: an error or a result, never a panic.
    let dir = temp_dir("hostile-gltf");
    let good = cube_gltf();
    let p = dir.join("h.gltf");
    for cut in (0..good.len()).step_by(37) {
        std::fs::write(&p, &good[..cut]).unwrap();
        let _ = voxelize_mesh(&p, &VoxelizeOptions::count(4));
    }
    // Accessors that claim more than their buffers hold.
    for (from, to) in [
        ("\"count\": 8", "\"count\": 800"),
        ("\"count\": 36", "\"count\": 3600"),
        ("\"byteLength\": 72", "\"byteLength\": 7200"),
        ("\"byteOffset\": 96", "\"byteOffset\": 960"),
    ] {
        std::fs::write(&p, good.replace(from, to)).unwrap();
        match voxelize_mesh(&p, &VoxelizeOptions::count(4)) {
            Ok(_) => panic!("{to}: accepted"),
            Err(e) => assert!(e.to_string().contains("h.gltf"), "{e}"),
        }
    }
}

#[test]
fn in_memory_mesh_with_material_indices_out_of_order() {
    let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
    let mesh = TriangleMesh {
        triangles: vec![tri],
        normals: vec![],
        material_of: vec![0],
        materials: vec![Material {
            name: "m".into(),
            ..seed_palette()[3].clone()
        }],
        warnings: vec![],
    };
    let v = voxelize(&mesh, &VoxelizeOptions::count(4)).unwrap();
    assert!(!v.closed);
    assert_eq!(v.grid.get(IVec3::ZERO), 1);
    assert_eq!(v.materials[1].name, "m");
}

/// `cube_gltf`'s cube with its positions stored as glTF component type `ctype` (5120
/// BYTE to 5126 FLOAT), as `KHR_mesh_quantization` stores them (each element padded to
/// 4 bytes, the buffer view's `byteStride`): normalized integers hold the corner 1 as
/// the type's largest value, plain integers as 1. `required` lists the extension.
fn quantized_cube_gltf(ctype: u32, normalized: bool, required: bool) -> String {
    let (size, one): (usize, f64) = match ctype {
        5120 => (1, 127.0),
        5121 => (1, 255.0),
        5122 => (2, 32767.0),
        5123 => (2, 65535.0),
        _ => (4, 1.0),
    };
    let one = if normalized { one } else { 1.0 };
    let stride = (3 * size).div_ceil(4) * 4;
    let mut buf = Vec::new();
    for i in 0..8u32 {
        let corner = [i & 1, (i >> 1) & 1, (i >> 2) & 1].map(|c| c as f64 * one);
        for c in corner {
            match size {
                1 => buf.push(c as u8),
                2 => buf.extend((c as u16).to_le_bytes()),
                _ => buf.extend((c as f32).to_le_bytes()),
            }
        }
        buf.resize(buf.len() + stride - 3 * size, 0);
    }
    let positions = buf.len();
    // The 12 faces over corners numbered x + 2y + 4z.
    let idx: [u16; 36] = [
        0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2,
        1, 3, 7, 1, 7, 5,
    ];
    buf.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    let ext = if required {
        r#""extensionsUsed": ["KHR_mesh_quantization"],
  "extensionsRequired": ["KHR_mesh_quantization"],"#
    } else {
        ""
    };
    format!(
        r#"{{
  "asset": {{"version": "2.0"}}, {ext}
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [
    {{"scale": [2, 2, 2], "children": [1]}},
    {{"translation": [10, 20, 30], "mesh": 0}}
  ],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": {positions}, "byteStride": {stride}}},
    {{"buffer": 0, "byteOffset": {positions}, "byteLength": 72}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": {ctype}, "normalized": {normalized}, "count": 8,
      "type": "VEC3", "min": [0, 0, 0], "max": [{one}, {one}, {one}]}},
    {{"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}}
  ]
}}"#,
        len = buf.len(),
        b64 = base64(&buf)
    )
}

/// gltfpack writes positions as integers and normals as normalized bytes
/// (`KHR_mesh_quantization`); every integer type, normalized or not, with the extension
/// required or (as some exporters do) not declared, gives the float cube's voxels.
/// Before, a required extension was refused and an undeclared one gave no triangles.
#[test]
fn quantized_gltf_positions_give_the_float_cubes_voxels() {
    let dir = temp_dir("gltf-quantized");
    let float = voxelize_mesh(
        write(&dir, "f.gltf", &quantized_cube_gltf(5126, false, false)),
        &VoxelizeOptions::count(8),
    )
    .unwrap();
    assert_eq!(solid_count(&float.grid), 512);
    assert!(float.warnings.is_empty(), "{:?}", float.warnings);
    for ctype in [5120, 5121, 5122, 5123] {
        for normalized in [false, true] {
            for required in [false, true] {
                let case = format!("{ctype} normalized {normalized} required {required}");
                let p = write(
                    &dir,
                    "q.gltf",
                    &quantized_cube_gltf(ctype, normalized, required),
                );
                let v = voxelize_mesh(&p, &VoxelizeOptions::count(8))
                    .unwrap_or_else(|e| panic!("{case}: {e}"));
                assert_eq!(v.triangle_count, 12, "{case}");
                assert!(
                    (v.grid.origin() - float.grid.origin()).length() < 1e-12,
                    "{case}: origin {}",
                    v.grid.origin()
                );
                assert!(
                    (v.grid.voxel_size() - float.grid.voxel_size()).abs() < 1e-12,
                    "{case}"
                );
                assert_eq!(v.grid.data(), float.grid.data(), "{case}");
                // A file that uses the integers without declaring the extension breaks
                // the specification: read, and said so.
                let warned = v.warnings.iter().any(|w| {
                    w.contains("POSITION accessor 0 holds") && w.contains("does not declare")
                });
                assert_eq!(warned, !required, "{case}: {:?}", v.warnings);
            }
        }
    }
}

/// Normalized normals by the glTF specification's rules (3.11): a signed byte c is
/// max(c / 127, -1), so -128 and -127 are both -1; then the node's inverse transpose.
/// The third normal is not of unit length (the validator would say so): the loader
/// normalizes after the transform, and only a component of -128 beside others shows
/// the clamp.
#[test]
fn quantized_gltf_normals_are_dequantized() {
    let dir = temp_dir("gltf-quantized-normals");
    let normals: [[i8; 3]; 3] = [[0, 0, 127], [0, -128, 0], [90, 90, -128]];
    for (ctype, size) in [(5120u32, 1usize), (5122, 2)] {
        let mut buf: Vec<u8> = [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]]
            .iter()
            .flatten()
            .flat_map(|x| x.to_le_bytes())
            .collect();
        for n in normals {
            for c in n {
                if size == 1 {
                    buf.push(c as u8);
                } else {
                    // The same directions in shorts: 127 -> 32767, -128 -> -32768.
                    let s = if c == -128 {
                        -32768i16
                    } else {
                        (c as i32 * 32767 / 127) as i16
                    };
                    buf.extend(s.to_le_bytes());
                }
            }
            buf.resize(buf.len() + 4 - (3 * size) % 4, 0);
        }
        let nlen = buf.len() - 36;
        let text = format!(
            r#"{{"asset": {{"version": "2.0"}},
  "extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],
  "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0, "scale": [1, 1, 4]}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1}}}}]}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": {nlen}, "byteStride": {stride}}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": {ctype}, "normalized": true, "count": 3,
      "type": "VEC3"}}]}}"#,
            len = buf.len(),
            b64 = base64(&buf),
            stride = nlen / 3,
        );
        let mesh = load_mesh(write(&dir, "n.gltf", &text)).unwrap();
        let got = mesh.normals[0];
        // The third: (90/127, 90/127, -1), not -128/127, under the inverse transpose of scale (1, 1, 4).
        let a = 90.0 / 127.0;
        let want = [DVec3::Z, -DVec3::Y, DVec3::new(a, a, -0.25).normalize()];
        for (g, w) in got.iter().zip(want) {
            // The shorts hold the bytes' directions to within 1/32767 a component.
            assert!((*g - w).length() < 1e-4, "type {ctype}: {g} against {w}");
        }
    }
}

/// Vertex attributes that are not three numbers of a byte, short or float are refused
/// with the accessor and what is allowed, not read as something else.
#[test]
fn gltf_positions_of_a_wrong_type_are_refused() {
    let dir = temp_dir("gltf-wrong-type");
    let good = quantized_cube_gltf(5126, false, false);
    for (from, to, says) in [
        (
            r#""componentType": 5126, "normalized""#,
            r#""componentType": 5125, "normalized""#,
            "POSITION accessor 0 is UNSIGNED_INT",
        ),
        (
            r#""type": "VEC3", "min""#,
            r#""type": "VEC4", "min""#,
            "POSITION accessor 0 is VEC4; it must be VEC3",
        ),
    ] {
        assert!(good.contains(from), "{from}");
        let p = write(&dir, "bad.gltf", &good.replace(from, to));
        let e = err_of(voxelize_mesh(&p, &VoxelizeOptions::count(4)));
        assert!(e.contains("bad.gltf") && e.contains(says), "{e}");
    }
}

/// `cube_gltf`'s unit cube (no node transform) with one morph target that moves every
/// vertex by (1, 0, 0) and, optionally, one that moves it by (0, 0, -1) stored as
/// normalized bytes; `mesh_weights` and `node_weights` as given.
fn morphed_cube_gltf(mesh_weights: &str, node_weights: &str, byte_target: bool) -> String {
    let mut buf = Vec::new();
    for i in 0..8u32 {
        for c in [i & 1, (i >> 1) & 1, (i >> 2) & 1] {
            buf.extend((c as f32).to_le_bytes());
        }
    }
    for _ in 0..8 {
        for c in [1f32, 0., 0.] {
            buf.extend(c.to_le_bytes());
        }
    }
    let bytes_at = buf.len();
    for _ in 0..8 {
        buf.extend([0u8, 0, (-127i8) as u8, 0]);
    }
    let idx_at = buf.len();
    let idx: [u16; 36] = [
        0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4, 2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2,
        1, 3, 7, 1, 7, 5,
    ];
    buf.extend(idx.iter().flat_map(|i| i.to_le_bytes()));
    let targets = if byte_target {
        r#"[{"POSITION": 1}, {"POSITION": 2}]"#
    } else {
        r#"[{"POSITION": 1}]"#
    };
    let ext = if byte_target {
        r#""extensionsUsed": ["KHR_mesh_quantization"],
  "extensionsRequired": ["KHR_mesh_quantization"],"#
    } else {
        ""
    };
    format!(
        r#"{{"asset": {{"version": "2.0"}}, {ext}
  "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0 {node_weights}}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 3,
    "targets": {targets}}}] {mesh_weights}}}],
  "buffers": [{{"byteLength": {len}, "uri": "data:application/octet-stream;base64,{b64}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 96}},
    {{"buffer": 0, "byteOffset": 96, "byteLength": 96}},
    {{"buffer": 0, "byteOffset": {bytes_at}, "byteLength": 32, "byteStride": 4}},
    {{"buffer": 0, "byteOffset": {idx_at}, "byteLength": 72}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 1]}},
    {{"bufferView": 1, "componentType": 5126, "count": 8, "type": "VEC3",
      "min": [1, 0, 0], "max": [1, 0, 0]}},
    {{"bufferView": 2, "componentType": 5120, "normalized": true, "count": 8,
      "type": "VEC3", "min": [0, 0, -127], "max": [0, 0, -127]}},
    {{"bufferView": 3, "componentType": 5123, "count": 36, "type": "SCALAR"}}
  ]
}}"#,
        len = buf.len(),
        b64 = base64(&buf)
    )
}

/// A mesh's shape is its base plus its morph targets by their weights (glTF 2.0,
/// 3.7.2.2): the node's weights over the mesh's, none meaning 0. Before, the targets
/// were left out and a file exported with shape keys set lost its shape, silently.
#[test]
fn gltf_morph_targets_move_the_shape_by_their_weights() {
    let dir = temp_dir("gltf-morph");
    let lower = |text: String| {
        let mesh = load_mesh(write(&dir, "m.gltf", &text)).unwrap();
        let mut lo = DVec3::splat(f64::INFINITY);
        for t in &mesh.triangles {
            for v in t {
                lo = lo.min(*v);
            }
        }
        lo
    };
    let w = |s: &str| format!(r#", "weights": {s}"#);
    for (mesh_weights, node_weights, byte, want) in [
        (String::new(), String::new(), false, DVec3::ZERO),
        (w("[0.5]"), String::new(), false, DVec3::new(0.5, 0.0, 0.0)),
        (w("[0.5]"), w("[-2]"), false, DVec3::new(-2.0, 0.0, 0.0)),
        (
            w("[0.25, 1]"),
            String::new(),
            true,
            DVec3::new(0.25, 0.0, -1.0),
        ),
        (
            String::new(),
            w("[0, 0.5]"),
            true,
            DVec3::new(0.0, 0.0, -0.5),
        ),
    ] {
        let got = lower(morphed_cube_gltf(&mesh_weights, &node_weights, byte));
        assert!(
            (got - want).length() < 1e-12,
            "mesh {mesh_weights:?} node {node_weights:?}: {got} against {want}"
        );
    }
}

/// Skinning is not applied: the mesh is read under its node's transform, and the loader
/// says so, since a skinning viewer ignores that transform and poses the mesh.
#[test]
fn a_skinned_gltf_mesh_is_read_with_a_warning() {
    let dir = temp_dir("gltf-skin");
    let good = cube_gltf();
    let from = r#"{"translation": [10, 20, 30], "mesh": 0}"#;
    assert!(good.contains(from));
    let text = good
        .replace(
            from,
            r#"{"translation": [10, 20, 30], "mesh": 0, "skin": 0}, {"translation": [0, 1, 0]}"#,
        )
        .replace(
            r#""scene": 0,"#,
            r#""scene": 0, "skins": [{"joints": [2]}],"#,
        );
    let mesh = load_mesh(write(&dir, "s.gltf", &text)).unwrap();
    assert_eq!(mesh.triangles.len(), 12);
    assert!(
        mesh.warnings
            .iter()
            .any(|w| w.contains("node 1's mesh 0 is skinned")),
        "{:?}",
        mesh.warnings
    );
    assert!(
        load_mesh(write(&dir, "c.gltf", &good))
            .unwrap()
            .warnings
            .is_empty()
    );
}

/// A GLB whose one mesh (a strip of 2^20 triangles, one byte an index) is placed by
/// `nodes` nodes: a 1 MiB file that asks for nodes x 2^20 triangles. `claim`, if given,
/// is the index accessor's count in place of the strip's.
fn many_placements_glb(nodes: usize, claim: Option<usize>) -> Vec<u8> {
    let strip = (1usize << 20) + 2;
    let mut bin: Vec<u8> = [[0f32, 0., 0.], [1., 0., 0.], [0., 1., 0.]]
        .iter()
        .flatten()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    bin.extend((0..strip).map(|i| (i % 3) as u8));
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let node_list: Vec<String> = (0..nodes)
        .map(|k| format!(r#"{{"mesh": 0, "translation": [0, 0, {k}]}}"#))
        .collect();
    let mut json = format!(
        r#"{{"asset": {{"version": "2.0"}},
  "scenes": [{{"nodes": [{roots}]}}], "nodes": [{node_list}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1, "mode": 5}}]}}],
  "buffers": [{{"byteLength": {len}}}],
  "bufferViews": [{{"buffer": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": {strip}}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5121, "count": {count}, "type": "SCALAR"}}]}}"#,
        roots = (0..nodes)
            .map(|k| k.to_string())
            .collect::<Vec<_>>()
            .join(","),
        node_list = node_list.join(","),
        len = bin.len(),
        count = claim.unwrap_or(strip),
    );
    while !json.len().is_multiple_of(4) {
        json.push(' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(json.as_bytes());
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(bin);
    glb
}

/// Nodes that place one mesh many times could ask a small file for more triangles than
/// memory holds (a 1.2 MB glTF asking for 2e8 aborted voxlab at 8 GB): the count is
/// taken from the accessors before any triangle is read, and bounded.
#[test]
fn a_gltf_placing_too_many_triangles_is_refused_before_reading() {
    let dir = temp_dir("gltf-placements");
    let p = dir.join("few.glb");
    std::fs::write(&p, many_placements_glb(2, None)).unwrap();
    assert_eq!(load_mesh(&p).unwrap().triangles.len(), 2 << 20);
    let over = voxlab::scene::mesh::MAX_MESH_TRIANGLES / (1 << 20) + 1;
    let p = dir.join("many.glb");
    std::fs::write(&p, many_placements_glb(over, None)).unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(
        e.contains("many.glb")
            && e.contains(&format!("places {} triangles", over << 20))
            && e.contains("at most 67108864"),
        "{e}"
    );
    // Refused from the declared counts, before reading: an index accessor that claims
    // more than its buffer view holds gets the count's error, not the short read's.
    let claim = voxlab::scene::mesh::MAX_MESH_TRIANGLES + 3;
    std::fs::write(&p, many_placements_glb(1, Some(claim))).unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(
        e.contains(&format!("places {} triangles", claim - 2)),
        "{e}"
    );
    // Below the bound, the same lie is the short read's.
    std::fs::write(&p, many_placements_glb(1, Some(3 << 20))).unwrap();
    let e = load_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("claims more elements"), "{e}");
}
