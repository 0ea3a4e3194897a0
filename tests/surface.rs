//! Smooth surfaces of the voxels (`voxlab mesh`, src/surface.rs): closed, near the shape
//! the voxels came from, outward, and written in files other readers load.

mod common;

use std::path::PathBuf;
use std::process::Command;

use glam::{DVec3, IVec3, UVec3};
use voxlab::scene::{Grid, load_vox};
use voxlab::surface::{DEFAULT_RELAX, extract};

/// A sphere of radius `r` voxelized at `n`^3 (a voxel is in when its centre is).
fn sphere(n: u32, r: f64) -> (Grid, DVec3) {
    let mut g = Grid::new(UVec3::splat(n), 1.0, DVec3::ZERO).unwrap();
    let c = DVec3::splat(n as f64 / 2.0);
    for z in 0..n as i32 {
        for y in 0..n as i32 {
            for x in 0..n as i32 {
                let p = DVec3::new(x as f64, y as f64, z as f64) + 0.5;
                if (p - c).length() <= r {
                    g.set(IVec3::new(x, y, z), 1);
                }
            }
        }
    }
    (g, c)
}

/// Mean and largest distance of the mesh's vertices from the sphere.
fn sphere_error(mesh: &voxlab::surface::SurfaceMesh, c: DVec3, r: f64) -> (f64, f64) {
    let d: Vec<f64> = mesh
        .positions
        .iter()
        .map(|p| ((*p - c).length() - r).abs())
        .collect();
    (
        d.iter().sum::<f64>() / d.len() as f64,
        d.iter().copied().fold(0.0, f64::max),
    )
}

#[test]
fn a_voxelized_sphere_gives_a_closed_outward_surface_within_a_voxel_of_the_sphere() {
    let r = 28.0;
    let (g, c) = sphere(64, r);
    let staircase = extract(&g, 0).unwrap();
    let smooth = extract(&g, DEFAULT_RELAX).unwrap();
    for mesh in [&staircase, &smooth] {
        assert_eq!(mesh.materials(), vec![1]);
        assert_eq!(mesh.open_edges(1), 0, "closed");
        assert_eq!(
            mesh.non_manifold_edges(1),
            0,
            "a sphere's voxels touch by faces"
        );
        // Euler characteristic of a sphere: V - E + F = 2.
        let (v, f) = (mesh.positions.len() as i64, mesh.triangles.len() as i64);
        assert_eq!(v - 3 * f / 2 + f, 2, "one sphere-like surface");
        // Every normal points out of the sphere.
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            assert!(n.dot(*p - c) > 0.0, "normal {n} at {p}");
        }
        // Counter-clockwise seen from outside: the enclosed volume is positive and
        // close to the ball's.
        let volume: f64 = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, cc] = t.map(|i| mesh.positions[i as usize] - c);
                a.dot(b.cross(cc)) / 6.0
            })
            .sum();
        let ball = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!(
            (volume / ball - 1.0).abs() < 0.02,
            "volume {volume} against {ball}"
        );
    }
    let (mean0, max0) = sphere_error(&staircase, c, r);
    let (mean, max) = sphere_error(&smooth, c, r);
    // Smoothness: the angle between each vertex normal and the sphere's.
    let angle = |m: &voxlab::surface::SurfaceMesh| {
        m.positions
            .iter()
            .zip(&m.normals)
            .map(|(p, n)| {
                n.dot((*p - c).normalize())
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            })
            .sum::<f64>()
            / m.positions.len() as f64
    };
    let (a0, a) = (angle(&staircase), angle(&smooth));
    println!(
        "distance from the sphere (voxels): staircase mean {mean0:.3} max {max0:.3}, \
         relaxed mean {mean:.3} max {max:.3}; normal error: {a0:.2} -> {a:.2} degrees"
    );
    assert!(max0 <= 1.0 && max <= 1.0, "within one voxel: {max0} {max}");
    // Measured: 0.118 -> 0.057 voxels, 7.73 -> 2.86 degrees.
    assert!(
        mean < 0.6 * mean0,
        "relaxing moves it towards the sphere: {mean} against {mean0}"
    );
    assert!(
        a < 0.5 * a0,
        "relaxing smooths the normals: {a} against {a0} degrees"
    );
}

#[test]
fn every_material_of_a_vox_model_is_closed() {
    let v = load_vox(common::example_data("deer.vox"), None).unwrap();
    let mesh = extract(&v.grid, DEFAULT_RELAX).unwrap();
    let used = v.grid.materials_used();
    let expected: Vec<u8> = (1..=255u8).filter(|&m| used[m as usize]).collect();
    assert_eq!(mesh.materials(), expected, "a surface per material used");
    for m in expected {
        assert_eq!(mesh.open_edges(m), 0, "material {m}");
    }
    // Vertices stay within a voxel of the voxels: inside the grid's box widened by one.
    let lo = v.grid.world_min() - DVec3::splat(v.grid.voxel_size());
    let hi = v.grid.world_max() + DVec3::splat(v.grid.voxel_size());
    assert!(
        mesh.positions
            .iter()
            .all(|p| p.cmpge(lo).all() && p.cmple(hi).all())
    );
}

#[test]
fn a_grid_too_large_is_refused_before_any_work() {
    // Not allocated: only the dims are read.
    let g = Grid::new(UVec3::new(1024, 1024, 128), 1.0, DVec3::ZERO).unwrap();
    let e = extract(&g, 1).unwrap_err().to_string();
    assert!(
        e.contains("134217728 voxels") && e.contains("MAX_SURFACE_VOXELS"),
        "{e}"
    );
}

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("surface-{name}"));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn voxlab(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_voxlab"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn voxlab_mesh_writes_obj_and_ply_that_load_again() {
    let dir = scratch("cli");
    let exp = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/experiments/deer_area_light.toml"
    );
    let obj = dir.join("deer.obj");
    let (ok, out, err) = voxlab(&["mesh", exp, "--out", obj.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(!out.contains("open edges"), "{out}");
    let e = voxlab::experiment::Experiment::load(exp).unwrap();
    let mesh = extract(&e.scene.grid, DEFAULT_RELAX).unwrap();
    assert!(
        out.contains(&format!("{} triangles", mesh.triangles.len())),
        "{out}"
    );
    // voxlab's own mesh loader (tobj) reads it back, with its materials (the MTL).
    let loaded = voxlab::scene::load_mesh(&obj).unwrap();
    assert_eq!(loaded.triangles.len(), mesh.triangles.len());
    assert!(dir.join("deer.mtl").is_file());
    // Its record beside it: the build, the relaxation, and every file the experiment
    // reads with its hash (the experiment and its .vox).
    let rec: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("deer.obj.json")).unwrap()).unwrap();
    assert_eq!(rec["made_by"], "voxlab mesh");
    assert_eq!(rec["revision"], voxlab::revision::revision());
    assert_eq!(rec["relax"], DEFAULT_RELAX);
    assert_eq!(rec["triangles"], mesh.triangles.len());
    let inputs = rec["inputs"].as_array().unwrap();
    assert!(inputs.len() >= 2, "{rec}");
    for i in inputs {
        let path = i["path"].as_str().unwrap();
        let hash = blake3::hash(&std::fs::read(path).unwrap())
            .to_hex()
            .to_string();
        assert_eq!(i["blake3"], hash, "{rec}");
    }
    // PLY: the header's counts, then exactly the binary body they imply.
    let ply = dir.join("deer.ply");
    let (ok, _, err) = voxlab(&["mesh", exp, "--out", ply.to_str().unwrap(), "--relax", "3"]);
    assert!(ok, "{err}");
    let bytes = std::fs::read(&ply).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    let count = |what: &str| -> usize {
        header
            .lines()
            .find_map(|l| l.strip_prefix(&format!("element {what} ")))
            .unwrap()
            .parse()
            .unwrap()
    };
    let (v, f) = (count("vertex"), count("face"));
    assert_eq!((v, f), (mesh.positions.len(), mesh.triangles.len()));
    assert_eq!(bytes.len() - end, v * 24 + f * 14, "{header}");
    // Bad outputs are refused before any work, with nothing written.
    let (ok, _, err) = voxlab(&["mesh", exp, "--out", dir.join("x.stl").to_str().unwrap()]);
    assert!(!ok && err.contains(".obj or .ply"), "{err}");
    let (ok, _, err) = voxlab(&["mesh", exp, "--out", dir.join("no/x.obj").to_str().unwrap()]);
    assert!(!ok && err.contains("does not exist"), "{err}");
    assert!(!dir.join("x.stl").exists() && !dir.join("no").exists());
}

/// Two tetrahedra, as a soup welded by position, sharing `shared` of their corners:
/// the check's own failing cases.
fn two_tetrahedra(offset: DVec3) -> voxlab::surface::SurfaceMesh {
    let tet = |o: DVec3| {
        let [a, b, c, d] = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z].map(|p| p + o);
        [[a, c, b], [a, b, d], [a, d, c], [b, c, d]]
    };
    let tris: Vec<[DVec3; 3]> = tet(DVec3::ZERO).into_iter().chain(tet(offset)).collect();
    voxlab::surface::SurfaceMesh::from_soup(&tris, &[], &vec![1; tris.len()])
}

#[test]
fn the_manifold_check_finds_what_trimesh_and_open3d_find() {
    // Apart: two closed manifolds.
    let apart = two_tetrahedra(DVec3::splat(5.0));
    assert!(
        apart.is_closed(Some(1)),
        "{}",
        apart.manifold_report(Some(1))
    );
    // Touching at one corner (welded): a non-manifold vertex, every edge fine.
    let r = two_tetrahedra(DVec3::new(1.0, 0.0, 0.0) - DVec3::ZERO).manifold_report(Some(1));
    assert_eq!(r.non_manifold_vertices, 1, "{r:?}");
    assert_eq!((r.open_edges, r.non_manifold_edges), (0, 0), "{r:?}");
    assert!(!r.is_closed());
    // One triangle gone: three open edges. Flipped: inconsistent winding.
    let mut open = two_tetrahedra(DVec3::splat(5.0));
    open.triangles.pop();
    let r = open.manifold_report(Some(1));
    assert_eq!(r.open_edges, 3, "{r:?}");
    let mut flipped = two_tetrahedra(DVec3::splat(5.0));
    flipped.triangles[0].swap(1, 2);
    let r = flipped.manifold_report(Some(1));
    assert_eq!(r.inconsistent_edges, 3, "{r:?}");
    // Inside out: a negative volume.
    let mut inverted = two_tetrahedra(DVec3::splat(5.0));
    for t in &mut inverted.triangles {
        t.swap(1, 2);
    }
    assert!(inverted.manifold_report(Some(1)).volume < 0.0);
    assert!(!inverted.is_closed(Some(1)));
}

/// Voxels that touch only along an edge or at a corner (the places where surface nets
/// without splitting made four triangles share an edge or pinched a vertex), and random
/// grids full of such places: every material's surface and the solid surface are closed
/// 2-manifolds, at every relaxation.
#[test]
fn surfaces_of_edge_and_corner_contacts_are_closed_manifolds() {
    use rand::{RngExt, SeedableRng};
    let mut cases: Vec<(String, Grid)> = Vec::new();
    for (name, a, b) in [
        ("edge", IVec3::new(1, 1, 1), IVec3::new(2, 2, 1)),
        ("corner", IVec3::new(1, 1, 1), IVec3::new(2, 2, 2)),
        ("edge y-z", IVec3::new(1, 1, 1), IVec3::new(1, 2, 2)),
    ] {
        for other in [1u8, 2] {
            let mut g = Grid::new(UVec3::splat(4), 1.0, DVec3::ZERO).unwrap();
            g.set(a, 1);
            g.set(b, other);
            cases.push((format!("{name}, materials 1 and {other}"), g));
        }
    }
    // A checkerboard: every pair of neighbours of a colour meets along edges.
    let mut g = Grid::new(UVec3::new(6, 5, 4), 1.0, DVec3::ZERO).unwrap();
    for z in 0..4 {
        for y in 0..5 {
            for x in 0..6 {
                if (x + y + z) % 2 == 0 {
                    g.set(IVec3::new(x, y, z), 1);
                }
            }
        }
    }
    cases.push(("checkerboard".into(), g));
    let mut rng = rand::rngs::StdRng::seed_from_u64(34);
    for i in 0..24 {
        let d = UVec3::new(
            rng.random_range(2..9),
            rng.random_range(2..9),
            rng.random_range(2..9),
        );
        let density = rng.random_range(0.2..0.7);
        let materials = 1 + i % 3;
        let mut g = Grid::new(d, 1.0, DVec3::ZERO).unwrap();
        for z in 0..d.z as i32 {
            for y in 0..d.y as i32 {
                for x in 0..d.x as i32 {
                    if rng.random_bool(density) {
                        g.set(
                            IVec3::new(x, y, z),
                            1 + rng.random_range(0..materials) as u8,
                        );
                    }
                }
            }
        }
        cases.push((format!("random {i}: {d}, density {density:.2}"), g));
    }
    for (name, g) in &cases {
        for relax in [0, 1, 8, DEFAULT_RELAX] {
            let mesh = extract(g, relax).unwrap();
            for m in mesh.materials() {
                let r = mesh.manifold_report(Some(m));
                assert!(r.is_closed(), "{name}, relax {relax}, material {m}: {r}");
            }
            let solid = voxlab::surface::extract_solid(g, relax).unwrap();
            let r = solid.manifold_report(None);
            assert!(
                r.is_closed() || solid.triangles.is_empty(),
                "{name}, relax {relax}, solid: {r}"
            );
        }
    }
}

/// Every shipped experiment's surfaces, as `voxlab mesh` writes them and as
/// `render.surface = "smooth"` traces them.
#[test]
fn every_shipped_experiments_surfaces_are_closed_manifolds() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut n = 0;
    let files = std::fs::read_dir(root.join("experiments"))
        .unwrap()
        .chain(std::fs::read_dir(root.join("experiments/stress")).unwrap());
    for entry in files {
        let p = entry.unwrap().path();
        if p.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let e = voxlab::experiment::Experiment::load(&p).unwrap_or_else(|e| panic!("{e}"));
        if e.scene.grid.voxel_count() > 4_000_000 {
            continue; // bunny_512: its 128 version is the bunny_glass experiment
        }
        let mesh = extract(&e.scene.grid, DEFAULT_RELAX).unwrap();
        for m in mesh.materials() {
            let r = mesh.manifold_report(Some(m));
            assert!(r.is_closed(), "{}: material {m}: {r}", p.display());
        }
        let solid = voxlab::surface::extract_solid(&e.scene.grid, DEFAULT_RELAX).unwrap();
        let r = solid.manifold_report(None);
        assert!(r.is_closed(), "{}: solid: {r}", p.display());
        n += 1;
    }
    assert!(n >= 20, "{n} experiments");
}

/// The smooth surface against the shape its voxels came from (an analytic sphere and
/// torus, `surface::fidelity`): the default relaxation is closer than plain marching
/// cubes of the same voxels (Chamfer distance, and no further at its worst point), each
/// more relaxation brings it closer, and relaxing keeps the voxels' volume.
#[test]
fn relaxed_surfaces_are_closer_to_the_shape_than_marching_cubes() {
    use voxlab::surface::fidelity::{Shape, fidelity, marching_cubes};
    for n in [32u32, 48] {
        for shape in [Shape::sphere_in(n), Shape::torus_in(n)] {
            let g = shape.voxelize(n);
            let what = format!("{} at {n}", shape.name());
            let mc = marching_cubes(&g, Some(1));
            assert!(
                mc.is_closed(Some(1)),
                "{what}: {}",
                mc.manifold_report(Some(1))
            );
            let mc = fidelity(&mc, &shape);
            let mut last = f64::INFINITY;
            for relax in [0, 16, DEFAULT_RELAX] {
                let mesh = extract(&g, relax).unwrap();
                let f = fidelity(&mesh, &shape);
                println!("{what}: relaxed {relax}: {f:?}; marching cubes {mc:?}");
                assert!(f.chamfer < last, "{what}: {relax} passes moved it away");
                last = f.chamfer;
                if relax > 0 {
                    let voxels = g.data().iter().filter(|&&m| m != 0).count() as f64;
                    let volume: f64 = mesh
                        .triangles
                        .iter()
                        .map(|t| {
                            let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
                            a.dot(b.cross(c)) / 6.0
                        })
                        .sum();
                    assert!(
                        (volume / voxels - 1.0).abs() < 1e-6,
                        "{what}, {relax} passes: volume {volume} against the voxels' {voxels}"
                    );
                }
            }
            let smooth = fidelity(&extract(&g, DEFAULT_RELAX).unwrap(), &shape);
            assert!(
                smooth.chamfer < 0.7 * mc.chamfer,
                "{what}: Chamfer {} against marching cubes' {}",
                smooth.chamfer,
                mc.chamfer
            );
            assert!(
                smooth.hausdorff < mc.hausdorff + 0.05,
                "{what}: Hausdorff {} against marching cubes' {}",
                smooth.hausdorff,
                mc.hausdorff
            );
        }
    }
}
