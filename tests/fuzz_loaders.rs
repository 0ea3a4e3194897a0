//! A mutation fuzzer over every loader, on stable Rust: experiment TOML (as render,
//! ablate with its sweeps, info and mesh read it; models placed from a `.vox` and a
//! mesh), MagicaVoxel `.vox`, OBJ with its `.mtl`, and glTF (JSON and GLB). Seeds are the real files (the
//! experiments, `experiments/data/`) and small generated meshes; each mutated input is
//! written to a file and loaded as a user would load it. No input may panic (a panic
//! escaping a loader fails the test with the input's seed and mutation), hang (each load
//! is timed) or be read past its limit. `.vox` files and meshes are also loaded straight
//! into a sparse tree (the path of grids too large to hold densely): where both loads
//! succeed, the tree must be the dense grid's.
//!
//! CI runs a bounded slice (`VOXLAB_FUZZ_ITERS`, default 8000 mutations per seed, about
//! a minute and a half on two cores, the seeds spread over a thread a core) and every case
//! under `tests/fuzz/regressions/` on every run. Run it longer:
//!
//! ```sh
//! VOXLAB_FUZZ_ITERS=20000 VOXLAB_FUZZ_SEED=7 cargo test --release --test fuzz_loaders -- --nocapture
//! ```
//!
//! A failure prints the seed file, the iteration and the RNG seed, which reproduce it;
//! keep the input under `tests/fuzz/regressions/` once fixed.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use voxlab::experiment::Experiment;
use voxlab::scene::{Grid, Storage, VoxelizeOptions, load_vox_as, voxelize_mesh};
use voxlab::sparse::SparseTree;

/// Longest one load may take before it counts as a hang.
const MAX_LOAD: Duration = Duration::from_secs(20);

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("voxlab-fuzz-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Loads `path` by its extension as voxlab does; `Err` is fine, a panic is not. `full`:
/// an experiment also as ablate, info and mesh read it.
fn load(path: &Path, full: bool) -> Result<(), String> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    match ext.as_str() {
        // The experiment as render, ablate (its [ablate] table and sweeps), info and
        // mesh read it: a surface extracted from a loaded grid is a closed 2-manifold.
        "toml" => {
            let e = Experiment::load(path).map_err(|e| e.to_string())?;
            if !full {
                return Ok(());
            }
            let _ = voxlab::ablate::load(path);
            let _ = voxlab::info::describe(path);
            // Where the placement leaves f64 too few digits for a thousandth of a voxel
            // (an origin of 1e308), distinct vertices have one position: left out.
            let g = &e.scene.grid;
            let precise = g.origin().abs().max_element() / g.voxel_size() < 1e9;
            if g.voxel_count() <= 64 * 64 * 64 && precise {
                let mesh = voxlab::surface::extract(&e.scene.grid, 4).map_err(|e| e.to_string())?;
                for m in mesh.materials() {
                    let r = mesh.manifold_report(Some(m));
                    assert!(r.is_closed(), "{}: material {m}: {r}", path.display());
                }
            }
            Ok(())
        }
        // Dense and straight into a sparse tree: when both load, the same voxels.
        "vox" => {
            let dense = load_vox_as(path, None, Storage::Dense).map_err(|e| e.to_string());
            let sparse = load_vox_as(path, None, Storage::Sparse).map_err(|e| e.to_string());
            if let (Ok(d), Ok(s)) = (&dense, &sparse) {
                same_voxels(&d.grid, &s.grid, path);
            }
            dense.map(|_| ())
        }
        _ => {
            let _ = voxlab::info::describe(path);
            let options = |storage| VoxelizeOptions {
                storage,
                ..VoxelizeOptions::count(12)
            };
            let dense = voxelize_mesh(path, &options(Storage::Dense)).map_err(|e| e.to_string());
            let sparse = voxelize_mesh(path, &options(Storage::Sparse));
            if let (Ok(d), Ok(s)) = (&dense, &sparse) {
                same_voxels(&d.grid, &s.grid, path);
                assert_eq!(d.interior_voxels, s.interior_voxels, "{}", path.display());
            }
            dense.map(|_| ())
        }
    }
}

/// A dense grid and its sparse twin hold the same tree.
fn same_voxels(dense: &Grid, sparse: &Grid, path: &Path) {
    let tree = sparse.sparse_tree().expect("loaded sparse");
    assert!(
        SparseTree::build(dense, tree.log_branch()).words() == tree.words(),
        "{}: the sparse load differs from the dense one",
        path.display()
    );
}

/// Loads `path` (`load`) and fails the test on a panic or a hang, naming `what`.
fn must_not_crash(path: &Path, full: bool, what: &str) -> Result<(), String> {
    let start = Instant::now();
    let r = std::panic::catch_unwind(|| load(path, full));
    let took = start.elapsed();
    let r = r.unwrap_or_else(|_| panic!("{what}: loading {} panicked", path.display()));
    assert!(took < MAX_LOAD, "{what}: loading took {took:?}");
    // A message quotes a number short: Rust's `Display` writes 1e308 as 309 digits.
    if let Err(message) = &r {
        let digits = message
            .split(|c: char| !c.is_ascii_digit())
            .map(str::len)
            .max();
        assert!(digits < Some(300), "{what}: {message}");
    }
    r
}

/// A fuzz case: the file to load, and the files it is made of (name, bytes).
type Case = (PathBuf, Vec<(String, Vec<u8>)>);

const EXTREMES: &[&str] = &[
    "0",
    "-1",
    "-0",
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "4294967296",
    "65536",
    "1e-300",
    "\"\"",
    "[]",
    "{}",
    "true",
];

/// One random mutation of `data`: flip, insert, delete, duplicate, truncate, or replace a
/// number with an extreme value.
fn mutate(rng: &mut StdRng, data: &mut Vec<u8>) {
    let n = data.len();
    match rng.random_range(0..7) {
        0 if n > 0 => {
            let i = rng.random_range(0..n);
            data[i] ^= 1 << rng.random_range(0..8);
        }
        1 => {
            let i = rng.random_range(0..=n);
            let b: u8 = rng.random();
            data.insert(i, b);
        }
        2 if n > 1 => {
            let i = rng.random_range(0..n);
            let len = rng.random_range(1..=(n - i).min(64));
            data.drain(i..i + len);
        }
        3 if n > 1 => {
            let i = rng.random_range(0..n);
            let len = rng.random_range(1..=(n - i).min(256));
            let chunk = data[i..i + len].to_vec();
            let at = rng.random_range(0..=data.len());
            data.splice(at..at, chunk);
        }
        4 if n > 1 => {
            data.truncate(rng.random_range(0..n));
        }
        5 => {
            // A number in a text format becomes an extreme value.
            let digits: Vec<usize> = (0..n).filter(|&i| data[i].is_ascii_digit()).collect();
            if digits.is_empty() {
                return;
            }
            let mut i = digits[rng.random_range(0..digits.len())];
            while i > 0 && (data[i - 1].is_ascii_digit() || data[i - 1] == b'.') {
                i -= 1;
            }
            let mut j = i;
            while j < n && (data[j].is_ascii_digit() || data[j] == b'.' || data[j] == b'e') {
                j += 1;
            }
            let v = EXTREMES[rng.random_range(0..EXTREMES.len())];
            data.splice(i..j, v.bytes());
        }
        _ if n >= 4 => {
            // A 32-bit little-endian word (a binary size or count) becomes extreme.
            let i = rng.random_range(0..n - 3);
            let v: u32 =
                [0, 1, 0x7fff_ffff, 0xffff_ffff, 0x8000_0000, 256, 257][rng.random_range(0..7)];
            data[i..i + 4].copy_from_slice(&v.to_le_bytes());
        }
        _ => {}
    }
}

/// A closed tetrahedron as OBJ with a material library, and as glTF (JSON with a data URI,
/// and GLB).
fn generated_seeds(dir: &Path) -> Vec<Case> {
    let obj = "mtllib tet.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
               f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let mtl = "newmtl red\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nNs 10\n";
    let positions: Vec<f32> = vec![0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.];
    let indices: Vec<u16> = vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    let mut bin: Vec<u8> = positions.iter().flat_map(|f| f.to_le_bytes()).collect();
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let json = |uri: Option<String>| {
        let buffer = match uri {
            Some(u) => format!(r#"{{"uri":"{u}","byteLength":{}}}"#, bin.len()),
            None => format!(r#"{{"byteLength":{}}}"#, bin.len()),
        };
        format!(
            r#"{{"asset":{{"version":"2.0"}},"buffers":[{buffer}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":48}},{{"buffer":0,"byteOffset":48,"byteLength":24}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,1,1]}},
{{"bufferView":1,"componentType":5123,"count":12,"type":"SCALAR"}}],
"materials":[{{"pbrMetallicRoughness":{{"baseColorFactor":[0.2,0.6,0.9,1]}}}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"material":0}}]}}],
"nodes":[{{"mesh":0,"translation":[1,2,3]}}],"scenes":[{{"nodes":[0]}}],"scene":0}}"#
        )
    };
    let b64 = base64_encode(&bin);
    let gltf = json(Some(format!("data:application/octet-stream;base64,{b64}")));
    // GLB: header, JSON chunk (padded with spaces), BIN chunk.
    let mut j = json(None).into_bytes();
    while j.len() % 4 != 0 {
        j.push(b' ');
    }
    let mut glb = Vec::new();
    let total = 12 + 8 + j.len() + 8 + bin.len();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend((total as u32).to_le_bytes());
    glb.extend((j.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&j);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    // [[scene.models]] (a .vox and a mesh, offset, scale, material) and an [ablate]
    // table with a key sweep: the keys render, info, mesh and ablate read.
    let models = "[scene]\ngenerator = \"empty\"\ndims = [40, 32, 24]\n\
                  [[scene.models]]\nvox = \"deer.vox\"\noffset = [2, 1, 3]\nname = \"deer\"\n\
                  [[scene.models]]\nmesh = \"tet.obj\"\nresolution = 8\noffset = [30, 2, 2]\n\
                  material = \"glass\"\n\
                  [[scene.boxes]]\nmin = [0, 0, 0]\nmax = [40, 1, 24]\nmaterial = \"solid\"\n\
                  [[lights]]\ntype = \"rect\"\nposition = [20, 30, 12]\nnormal = [0, -1, 0]\n\
                  size = [4, 4]\nintensity = 300\n\
                  [render]\nwidth = 16\nheight = 16\n\
                  [ablate]\nreference_spp = 8\nspp = [1, 2]\nruns = 1\n\
                  sweep = { \"render.light_samples\" = [1, 2], \"techniques.sdf.softness\" = [0.5] }\n\
                  [features]\nshadow_model = \"sdf\"\n";
    let deer = std::fs::read(manifest().join("experiments/data/deer.vox")).unwrap();
    vec![
        (
            dir.join("models.toml"),
            vec![
                ("models.toml".into(), models.as_bytes().to_vec()),
                ("deer.vox".into(), deer),
                ("tet.obj".into(), obj.as_bytes().to_vec()),
                ("tet.mtl".into(), mtl.as_bytes().to_vec()),
            ],
        ),
        (
            dir.join("tet.obj"),
            vec![
                ("tet.obj".into(), obj.as_bytes().to_vec()),
                ("tet.mtl".into(), mtl.as_bytes().to_vec()),
            ],
        ),
        (
            dir.join("tet.gltf"),
            vec![("tet.gltf".into(), gltf.into_bytes())],
        ),
        (dir.join("tet.glb"), vec![("tet.glb".into(), glb)]),
    ]
}

fn base64_encode(bytes: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Seeds: (the file to load, the files of the case: name and bytes). The first file of
/// a case is the one mutated; the others (a material library) are written as they are,
/// or mutated in turn for the material library.
fn seeds(dir: &Path) -> Vec<Case> {
    let mut out = generated_seeds(dir);
    let mut tomls: Vec<PathBuf> = std::fs::read_dir(manifest().join("experiments"))
        .unwrap()
        .chain(std::fs::read_dir(manifest().join("experiments/stress")).unwrap())
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    tomls.sort();
    for p in tomls {
        let name = p.file_name().unwrap().to_string_lossy().to_string();
        out.push((dir.join(&name), vec![(name, std::fs::read(&p).unwrap())]));
    }
    let data = manifest().join("experiments/data");
    for name in ["deer.vox", "bunny.obj"] {
        let p = data.join(name);
        assert!(p.exists(), "test data {} is missing", p.display());
        out.push((
            dir.join(name),
            vec![(name.into(), std::fs::read(&p).unwrap())],
        ));
    }
    out
}

#[test]
fn mutated_inputs_never_panic_or_hang() {
    let iters: usize = std::env::var("VOXLAB_FUZZ_ITERS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(8000);
    let seed: u64 = std::env::var("VOXLAB_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(14);
    let dir = scratch("mutations");
    let start = Instant::now();
    let mut cases = seeds(&dir);
    // The real meshes and volumes, the costliest loads, first: no thread ends alone
    // with the bunny.
    cases.reverse();
    // The cases over a thread a core, each thread in a folder of its own (cases share
    // file names: a material library, the deer). A case's mutations depend on its
    // iteration alone, so a failure reproduces on any number of threads.
    let next = std::sync::atomic::AtomicUsize::new(0);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let (loads, errors) = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|t| {
                let (dir, cases, next) = (dir.join(format!("thread-{t}")), &cases, &next);
                scope.spawn(move || {
                    std::fs::create_dir_all(&dir).unwrap();
                    let (mut loads, mut errors) = (0, 0);
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(case) = cases.get(i) else {
                            return (loads, errors);
                        };
                        let (l, e) = mutate_case(case, &dir, iters, seed);
                        (loads, errors) = (loads + l, errors + e);
                    }
                })
            })
            .collect();
        workers.into_iter().fold((0, 0), |(l, e), w| {
            let (wl, we) = w
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (l + wl, e + we)
        })
    });
    println!(
        "{loads} mutated inputs in {:.1} s on {threads} threads: {errors} refused with an \
         error, none panicked or hung",
        start.elapsed().as_secs_f64()
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Loads `iters` mutations of the case `(target, files)` written into `dir`: the loads
/// and how many were refused with an error.
fn mutate_case((target, files): &Case, dir: &Path, iters: usize, seed: u64) -> (usize, usize) {
    let target = dir.join(target.file_name().unwrap());
    let (mut loads, mut errors) = (0, 0);
    // The big bunny gets fewer mutations: each load voxelizes 3674 triangles.
    // The composed experiment a quarter: each load voxelizes, places, extracts a
    // surface and parses the ablation table.
    let n = if files[0].1.len() > 50_000 {
        iters / 5
    } else if files.len() > 2 {
        iters / 4
    } else {
        iters
    };
    for it in 0..n {
        let mut rng = StdRng::seed_from_u64(seed ^ (it as u64).wrapping_mul(0x9e37_79b9));
        // Which file of the case is mutated: the material library now and then.
        let k = if files.len() > 1 && rng.random_bool(0.3) {
            1
        } else {
            0
        };
        for (i, (name, bytes)) in files.iter().enumerate() {
            let mut b = bytes.clone();
            if i == k {
                for _ in 0..rng.random_range(1..4) {
                    mutate(&mut rng, &mut b);
                }
            }
            std::fs::write(dir.join(name), &b).unwrap();
        }
        let what = format!(
            "seed file {}, iteration {it}, VOXLAB_FUZZ_SEED={seed}",
            files[0].0
        );
        loads += 1;
        // Every fourth experiment also as ablate, info and mesh read it: the slice
        // stays within CI's time.
        if must_not_crash(&target, it % 4 == 0, &what).is_err() {
            errors += 1;
        }
    }
    (loads, errors)
}

/// Every case kept under tests/fuzz/regressions/ (each crash found, with its description
/// in the README there): loading gives an error or a scene, never a panic.
#[test]
fn regression_cases_give_errors_not_crashes() {
    let dir = manifest().join("tests/fuzz/regressions");
    let mut cases: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension().is_some_and(|e| {
                ["toml", "vox", "obj", "gltf", "glb"].contains(&e.to_string_lossy().as_ref())
            })
        })
        .collect();
    cases.sort();
    assert!(
        cases.len() >= 6,
        "regression cases missing under {}",
        dir.display()
    );
    for case in &cases {
        let r = must_not_crash(case, true, &case.display().to_string());
        let e = r.expect_err("every regression case is malformed input and must be refused");
        println!("{}: {e}", case.file_name().unwrap().to_string_lossy());
        assert!(
            e.contains(&case.file_name().unwrap().to_string_lossy().to_string()),
            "{}: the error does not name the file: {e}",
            case.display()
        );
    }
}

/// Devices, FIFOs and links to them are refused at once, whatever loader reads them.
#[cfg(unix)]
#[test]
fn devices_and_fifos_are_refused_at_once() {
    let dir = scratch("devices");
    for ext in ["toml", "vox", "obj", "gltf"] {
        let link = dir.join(format!("zero.{ext}"));
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = must_not_crash(&link, true, "a link to /dev/zero").unwrap_err();
        assert!(e.contains("not a regular file"), "{ext}: {e}");
    }
    let fifo = dir.join("fifo.toml");
    let ok = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success();
    assert!(ok, "mkfifo failed");
    let e = must_not_crash(&fifo, true, "a FIFO").unwrap_err();
    assert!(e.contains("FIFO"), "{e}");
    // A material library and a glTF buffer that are /dev/zero.
    std::fs::write(
        dir.join("m.obj"),
        "mtllib zero.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.mtl")).unwrap();
    // Refused, naming the library: dropping it would lose every material.
    let e = must_not_crash(&dir.join("m.obj"), true, "mtllib /dev/zero").unwrap_err();
    assert!(
        e.contains("material library") && e.contains("not a regular file"),
        "{e}"
    );
    std::fs::write(
        dir.join("b.gltf"),
        r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"zero.bin","byteLength":4}]}"#,
    )
    .unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.bin")).unwrap();
    let e = must_not_crash(&dir.join("b.gltf"), true, "a buffer /dev/zero").unwrap_err();
    assert!(e.contains("not a regular file"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}
