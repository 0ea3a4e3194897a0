//! `voxlab export --to mitsuba` (src/export.rs): the merged faces are exactly the
//! voxel faces between different media, wound toward the side they are seen from; the
//! approximations are listed and `--strict` refuses them; the command writes all or
//! nothing and never over its input. Mitsuba's own reading and rendering of the
//! exports is tested from Python (python/tests/test_mitsuba.py).

use std::collections::HashSet;
use std::path::Path;
use std::process::{Command, Output};

use glam::{DVec3, IVec3, UVec3};
use rand::{RngExt, SeedableRng};
use voxlab::experiment::Experiment;
use voxlab::export::{greedy_faces, mitsuba};
use voxlab::scene::{Grid, Material, VOID, seed_palette};

fn voxlab() -> Command {
    Command::new(env!("CARGO_BIN_EXE_voxlab"))
}

/// `voxlab export EXPERIMENT --to mitsuba DIR [extra...]`, run to completion.
fn export(experiment: &Path, dir: &Path, extra: &[&str]) -> Output {
    voxlab()
        .arg("export")
        .arg(experiment)
        .args(["--to", "mitsuba"])
        .arg(dir)
        .args(extra)
        .output()
        .unwrap()
}

/// A unit face: the voxel that owns it and the direction it faces (axis, sign).
type Face = (IVec3, usize, i32);

/// The faces the export must write: of voxel a toward b, when a is not void, differs
/// from b, and b is void or glass in front of an opaque a (between two glasses, the
/// lower index).
fn expected_faces(grid: &Grid, materials: &[Material]) -> HashSet<(Face, u8)> {
    let d = grid.dims().as_ivec3();
    let clear = |m: u8| materials[m as usize].kt > 0.0;
    let mut faces = HashSet::new();
    for z in 0..d.z {
        for y in 0..d.y {
            for x in 0..d.x {
                let a = IVec3::new(x, y, z);
                let ma = grid.get(a);
                for axis in 0..3 {
                    for sign in [-1, 1] {
                        let mut b = a;
                        b[axis] += sign;
                        let mb = grid.get(b);
                        let owns = ma != VOID
                            && ma != mb
                            && (mb == VOID
                                || (!clear(ma) && clear(mb))
                                || (clear(ma) && clear(mb) && ma < mb));
                        if owns {
                            faces.insert(((a, axis, sign), ma));
                        }
                    }
                }
            }
        }
    }
    faces
}

/// The unit faces the exported triangles cover (each quad is two triangles in a row),
/// and a check that each faces the way its owner's outside is.
fn covered_faces(grid: &Grid, per: &[(u8, Vec<[DVec3; 3]>)]) -> Vec<(Face, u8)> {
    let mut out = Vec::new();
    for (m, tris) in per {
        assert_eq!(tris.len() % 2, 0);
        for quad in tris.chunks(2) {
            let n = (quad[0][1] - quad[0][0])
                .cross(quad[0][2] - quad[0][0])
                .normalize();
            let n2 = (quad[1][1] - quad[1][0])
                .cross(quad[1][2] - quad[1][0])
                .normalize();
            assert!(
                (n - n2).length() < 1e-9,
                "the quad's two triangles disagree"
            );
            let axis = n.abs().max_position();
            let sign = n[axis].signum() as i32;
            let pts: Vec<DVec3> = quad.iter().flatten().map(|&p| grid.to_local(p)).collect();
            let lo = pts.iter().fold(DVec3::INFINITY, |a, &b| a.min(b));
            let hi = pts.iter().fold(DVec3::NEG_INFINITY, |a, &b| a.max(b));
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let plane = lo[axis].round() as i32;
            let owner_layer = if sign > 0 { plane - 1 } else { plane };
            for i in lo[u].round() as i32..hi[u].round() as i32 {
                for j in lo[v].round() as i32..hi[v].round() as i32 {
                    let mut a = IVec3::ZERO;
                    a[axis] = owner_layer;
                    a[u] = i;
                    a[v] = j;
                    out.push(((a, axis, sign), *m));
                }
            }
        }
    }
    out
}

/// Random grids of opaque, glass and void voxels, dense and offset and scaled: the
/// merged quads cover every face the rule asks for exactly once, and nothing else.
#[test]
fn merged_faces_are_the_faces_between_media() {
    let mut materials = seed_palette();
    let glass = materials.iter().position(|m| m.kt > 0.0).unwrap() as u8;
    let mut other_glass = materials[glass as usize].clone();
    other_glass.name = "other glass".into();
    materials.push(other_glass);
    let ids: Vec<u8> = vec![VOID, VOID, VOID, 1, 2, glass, (materials.len() - 1) as u8];
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    for case in 0..40 {
        let dims = UVec3::new(
            rng.random_range(1..9),
            rng.random_range(1..9),
            rng.random_range(1..9),
        );
        let mut grid =
            Grid::new(dims, 0.25 + case as f64 * 0.1, DVec3::new(-3.0, 1.5, 0.25)).unwrap();
        // Blocks of one material so merging has something to merge.
        let block = rng.random_range(1..4);
        for z in 0..dims.z as i32 {
            for y in 0..dims.y as i32 {
                for x in 0..dims.x as i32 {
                    let key = (x / block, y / block, z / block);
                    let h = (key.0 * 73856093) ^ (key.1 * 19349663) ^ (key.2 * 83492791) ^ case;
                    let m = ids[(h.unsigned_abs() as usize + rng.random_range(0..2)) % ids.len()];
                    grid.set(IVec3::new(x, y, z), m);
                }
            }
        }
        let per = greedy_faces(&grid, &materials, usize::MAX).unwrap();
        let covered = covered_faces(&grid, &per);
        let unique: HashSet<_> = covered.iter().copied().collect();
        assert_eq!(
            unique.len(),
            covered.len(),
            "case {case}: a face written twice"
        );
        assert_eq!(unique, expected_faces(&grid, &materials), "case {case}");
        let unit_faces = covered.len();
        let triangles: usize = per.iter().map(|(_, t)| t.len()).sum();
        assert!(
            triangles <= 2 * unit_faces,
            "case {case}: merging added triangles"
        );
    }
    // A solid box merges to one quad per side.
    let mut grid = Grid::new(UVec3::new(5, 4, 3), 1.0, DVec3::ZERO).unwrap();
    for z in 0..3 {
        for y in 0..4 {
            for x in 0..5 {
                grid.set(IVec3::new(x, y, z), 1);
            }
        }
    }
    let per = greedy_faces(&grid, &materials, usize::MAX).unwrap();
    assert_eq!(per.len(), 1);
    assert_eq!(per[0].1.len(), 12);
    // The limit on triangles is a refusal, not a truncation.
    assert!(greedy_faces(&grid, &materials, 11).is_none());
}

const DIFFUSE: &str = r#"
[scene]
generator = "empty"
dims = [8, 4, 8]

[[scene.boxes]]
min = [0, 0, 0]
max = [8, 1, 8]
material = "matte"

[[materials]]
name = "matte"
albedo = [0.5, 0.6, 0.7]
kd = 1.0
ks = 0.0
kr = 0.0
kt = 0.0

[[lights]]
type = "rect"
position = [4.0, 6.0, 4.0]
size = [2.0, 1.0]
intensity = 50.0
emission = "lambertian"

[render]
ambient = [0.0, 0.0, 0.0]
pixel_filter = "box"
filter_width = 0.5
"#;

/// An exact scene exports with no approximation, the units the module states (lights
/// pi times brighter, radiance over the area) and one mesh; every approximation has
/// its key, and strict refuses them all at once.
#[test]
fn approximations_are_listed_and_strict_refuses_them() {
    let e = Experiment::from_str(DIFFUSE, "diffuse.toml").unwrap();
    let out = mitsuba(&e, true).unwrap();
    assert!(out.approximations.is_empty(), "{:?}", out.approximations);
    let xml = String::from_utf8(out.files[0].1.clone()).unwrap();
    let l = 50.0 * std::f64::consts::PI / 2.0;
    assert!(xml.contains(&format!("value=\"{l}, {l}, {l}\"")), "{xml}");
    assert!(xml.contains("<rectangle") || xml.contains("type=\"rectangle\""));
    assert!(xml.contains("<integer name=\"max_depth\" value=\"2\"/>"));
    assert_eq!(out.files.len(), 2);

    let text = DIFFUSE
        .replace("ks = 0.0", "ks = 0.3")
        .replace("emission = \"lambertian\"", "emission = \"isotropic\"")
        .replace("ambient = [0.0, 0.0, 0.0]", "ambient = [0.1, 0.1, 0.1]")
        .replace("pixel_filter = \"box\"", "pixel_filter = \"none\"");
    let e = Experiment::from_str(&text, "approx.toml").unwrap();
    let keys: Vec<String> = mitsuba(&e, false)
        .unwrap()
        .approximations
        .into_iter()
        .map(|a| a.key)
        .collect();
    for key in [
        "materials[matte].ks",
        "lights[0].emission",
        "render.ambient",
        "render.pixel_filter",
    ] {
        assert!(keys.iter().any(|k| k == key), "{key} not in {keys:?}");
    }
    let msg = mitsuba(&e, true).unwrap_err().to_string();
    assert!(msg.starts_with("approx: --strict:"), "{msg}");
    for key in &keys {
        assert!(msg.contains(key.as_str()), "{msg} lacks {key}");
    }
}

/// Mitsuba's sensor clips its rays to [near_clip, far_clip], by default 0.01 to 1e4: a
/// camera 1e5 away rendered black there. The export writes the range that holds the
/// scene, says when f32 cannot hold the eye well (a shifted image) or at all (refused).
#[test]
fn the_sensor_sees_the_scene_at_any_distance() {
    let clip = |xml: &str, name: &str| -> f64 {
        let at = xml
            .find(&format!("name=\"{name}\" value=\""))
            .unwrap_or_else(|| panic!("no {name} in {xml}"));
        let rest = &xml[at + name.len() + 15..];
        rest[..rest.find('"').unwrap()].parse().unwrap()
    };
    for (distance, vfov) in [(20.0, 40.0), (1e5, 1.0), (0.05, 40.0)] {
        let text = format!(
            "{DIFFUSE}\n[camera]\ntarget = [4.0, 1.0, 4.0]\ndistance = {distance}\nvfov_deg = {vfov}\n"
        );
        let e = Experiment::from_str(&text, "far.toml").unwrap();
        let out = mitsuba(&e, true).unwrap();
        let xml = String::from_utf8(out.files[0].1.clone()).unwrap();
        let (near, far) = (clip(&xml, "near_clip"), clip(&xml, "far_clip"));
        // The floor's box holds the target, so its farthest corner is at least
        // `distance` from the eye and at most its diagonal farther.
        let diagonal = (8.0f64 * 8.0 + 1.0 + 8.0 * 8.0).sqrt();
        assert!(far >= distance, "{distance}: far_clip {far}");
        assert!(
            far <= 1.01 * (distance + diagonal),
            "{distance}: far_clip {far}"
        );
        // The floor under the eye (the eye is above it at every distance here).
        assert!(
            near > 0.0 && near < distance.max(0.5),
            "{distance}: near_clip {near}"
        );
    }
    let at = |distance: f64| {
        let text = format!(
            "{DIFFUSE}\n[camera]\ntarget = [4.0, 1.0, 4.0]\ndistance = {distance:e}\nvfov_deg = 1e-6\n"
        );
        mitsuba(&Experiment::from_str(&text, "far.toml").unwrap(), false)
    };
    // Each approximation as `key: mapping`.
    let listed = |out: voxlab::export::MitsubaScene| -> Vec<String> {
        out.approximations
            .into_iter()
            .map(|a| format!("{}: {}", a.key, a.mapping))
            .collect()
    };
    let keys = listed(at(1e9).unwrap());
    assert!(
        keys.iter()
            .any(|k| k.starts_with("camera.distance") && k.contains("of a pixel")),
        "{keys:?}"
    );
    // An eye on the floor's top (in its plane, inside it): the near clip is listed, and
    // no shift of "inf" pixels.
    let text =
        format!("{DIFFUSE}\n[camera]\ntarget = [4.0, 1.0, 4.0]\ndistance = 2\npitch_deg = 0\n");
    let on = listed(mitsuba(&Experiment::from_str(&text, "on.toml").unwrap(), false).unwrap());
    assert!(
        on.iter().any(|k| k.contains("near_clip")) && !on.iter().any(|k| k.contains("inf")),
        "{on:?}"
    );
    let e = at(1e39).map(|_| ()).unwrap_err();
    assert!(
        matches!(&e, voxlab::export::ExportError::OutOfRange { key, .. } if key == "camera.distance"),
        "{e}"
    );
}

/// A point of light `light` drawn uniformly over its shape (its position for a point).
fn point_on(light: &voxlab::scene::Light, rng: &mut impl RngExt) -> DVec3 {
    use voxlab::scene::{AreaShape, Light};
    let Light::Area(a) = light else {
        return light.position();
    };
    let (u, v, _) = a.frame();
    match a.shape {
        AreaShape::Rect { width, height } => {
            a.position
                + (rng.random::<f64>() - 0.5) * width * u
                + (rng.random::<f64>() - 0.5) * height * v
        }
        AreaShape::Disk { radius } => {
            let (r, phi) = (
                radius * rng.random::<f64>().sqrt(),
                std::f64::consts::TAU * rng.random::<f64>(),
            );
            a.position + r * (phi.cos() * u + phi.sin() * v)
        }
        AreaShape::Sphere { .. } => unreachable!("no spheres drawn here"),
    }
}

/// Whether segment `p`..`q` crosses light `light`'s rectangle or disk.
fn crosses(light: &voxlab::scene::Light, p: DVec3, q: DVec3) -> bool {
    use voxlab::scene::{AreaShape, Light};
    let Light::Area(a) = light else {
        return false;
    };
    let (u, v, n) = a.frame();
    let (dp, dq) = (n.dot(p - a.position), n.dot(q - a.position));
    if (dp > 0.0) == (dq > 0.0) {
        return false;
    }
    let x = p + (q - p) * (dp / (dp - dq)) - a.position;
    match a.shape {
        AreaShape::Rect { width, height } => {
            x.dot(u).abs() <= 0.5 * width && x.dot(v).abs() <= 0.5 * height
        }
        AreaShape::Disk { radius } => x.length() <= radius,
        AreaShape::Sphere { .. } => unreachable!("no spheres drawn here"),
    }
}

/// Mitsuba's area emitters are shapes that stop shadow rays; voxlab's lights are not (a
/// scene with one light between the floor and another rendered 19 % darker in Mitsuba,
/// exported as exact). Over generated lights, every light whose shape some shadow ray
/// toward another light crosses (drawn from the surfaces' points to the light's) is
/// listed, under its `position`, and strict refuses it; lights side by side are not.
#[test]
fn a_light_shape_in_the_way_of_another_lights_shadow_rays_is_approximated() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    let (mut crossed, mut clear) = (0, 0);
    for case in 0..500 {
        let light = |rng: &mut rand::rngs::StdRng, kinds: &[&str]| -> String {
            let p = DVec3::new(
                rng.random_range(-6.0..14.0),
                rng.random_range(1.5..14.0),
                rng.random_range(-6.0..14.0),
            );
            let n = DVec3::new(4.0, 0.0, 4.0) - p
                + DVec3::new(
                    rng.random_range(-6.0..6.0),
                    rng.random_range(-6.0..6.0),
                    rng.random_range(-6.0..6.0),
                );
            let head = format!(
                "[[lights]]\nposition = [{}, {}, {}]\nintensity = 50.0\n",
                p.x, p.y, p.z
            );
            match kinds[rng.random_range(0..kinds.len())] {
                "point" => head + "type = \"point\"\n",
                kind => {
                    let shape = if kind == "rect" {
                        format!(
                            "size = [{}, {}]\nrotation_deg = {}\n",
                            rng.random_range(0.2..6.0),
                            rng.random_range(0.2..6.0),
                            rng.random_range(-180.0..180.0)
                        )
                    } else {
                        format!("radius = {}\n", rng.random_range(0.1..3.0))
                    };
                    format!(
                        "{head}type = \"{kind}\"\nnormal = [{}, {}, {}]\nemission = \"lambertian\"\n{shape}",
                        n.x, n.y, n.z
                    )
                }
            }
        };
        let lights = [
            light(&mut rng, &["point", "rect", "disk"]),
            light(&mut rng, &["rect", "disk"]),
        ];
        let (lo, hi, top) = (
            rng.random_range(0..5),
            rng.random_range(5..8),
            rng.random_range(2..5),
        );
        let text = DIFFUSE.replace(
            "[[lights]]\ntype = \"rect\"\nposition = [4.0, 6.0, 4.0]\nsize = [2.0, 1.0]\nintensity = 50.0\nemission = \"lambertian\"\n",
            &format!(
                "[[scene.boxes]]\nmin = [{lo}, 1, {lo}]\nmax = [{hi}, {top}, {hi}]\nmaterial = \"matte\"\n\n{}\n{}",
                lights[0],
                lights[1]
            ),
        );
        let e = Experiment::from_str(&text, "two.toml").unwrap();
        assert_eq!(e.scene.lights.len(), 2, "{text}");
        // Shadow rays toward light 0 from points of the floor and the box (their faces).
        let boxes = [
            (DVec3::ZERO, DVec3::new(8.0, 1.0, 8.0)),
            (
                DVec3::new(lo as f64, 1.0, lo as f64),
                DVec3::new(hi as f64, top as f64, hi as f64),
            ),
        ];
        let hits = (0..4000)
            .filter(|_| {
                let (a, b) = boxes[rng.random_range(0..2)];
                let mut p = a + (b - a) * DVec3::new(rng.random(), rng.random(), rng.random());
                let axis = rng.random_range(0..3);
                p[axis] = if rng.random::<bool>() {
                    a[axis]
                } else {
                    b[axis]
                };
                crosses(
                    &e.scene.lights[1],
                    p,
                    point_on(&e.scene.lights[0], &mut rng),
                )
            })
            .count();
        let listed = mitsuba(&e, false)
            .unwrap()
            .approximations
            .into_iter()
            .any(|a| a.key == "lights[1].position" && a.mapping.contains("lights[0]"));
        if hits > 0 {
            crossed += 1;
            assert!(
                listed,
                "case {case}: {hits} shadow rays cross light 1:\n{text}"
            );
            let msg = mitsuba(&e, true).unwrap_err().to_string();
            assert!(msg.contains("lights[1].position"), "{msg}");
        } else if !listed {
            clear += 1;
        }
    }
    // Both outcomes occur, so the test has power both ways.
    assert!(
        crossed >= 20 && clear >= 20,
        "crossed {crossed}, clear {clear}"
    );

    // Two rects side by side above the scene, facing down: neither stands in the way.
    let side_by_side = DIFFUSE.replace(
        "emission = \"lambertian\"\n",
        "emission = \"lambertian\"\nnormal = [0.0, -1.0, 0.0]\n\n[[lights]]\ntype = \"rect\"\nposition = [14.0, 6.0, 4.0]\nnormal = [0.0, -1.0, 0.0]\nsize = [2.0, 1.0]\nintensity = 50.0\nemission = \"lambertian\"\n",
    );
    let e = Experiment::from_str(&side_by_side, "side.toml").unwrap();
    assert_eq!(e.scene.lights.len(), 2);
    let out = mitsuba(&e, true).unwrap();
    assert!(out.approximations.is_empty(), "{:?}", out.approximations);
}

/// `DIFFUSE` with a box from (2, 1, 2) to `max` of the material `material` (its
/// `[[materials]]` keys, `name` first) on the floor.
fn with_glass_box(max: [u32; 3], material: &str) -> String {
    let name = material
        .strip_prefix("name = \"")
        .and_then(|rest| rest.split('"').next())
        .expect("the material's name first");
    DIFFUSE.replace(
        "[[lights]]",
        &format!(
            "[[scene.boxes]]\nmin = [2, 1, 2]\nmax = {max:?}\nmaterial = \"{name}\"\n\n\
             [[materials]]\n{material}\n\n[[lights]]"
        ),
    )
}

/// voxlab's shadow rays that start in a transparent voxel stop there under opaque
/// shadows (the transmittance counts the start voxel); Mitsuba's reach a light inside
/// the same glass. A light in glass, or an area light reaching into it, is listed under
/// its position; one beside the glass, or in void, is not.
#[test]
fn a_light_inside_glass_is_approximated() {
    let glass = with_glass_box(
        [6, 4, 6],
        "name = \"glass\"\nkd = 0.0\nks = 0.0\nkr = 1.0\nkt = 0.9\nior = 1.5\ndielectric = \"fresnel\"",
    );
    let listed = |light: &str| -> bool {
        let text = glass.replace("position = [4.0, 6.0, 4.0]", light);
        let e = Experiment::from_str(&text, "glass.toml").unwrap();
        mitsuba(&e, false)
            .unwrap()
            .approximations
            .iter()
            .any(|a| a.key == "lights[0].position" && a.mapping.contains("glass's voxels"))
    };
    assert!(
        !listed("position = [4.0, 6.0, 4.0]"),
        "above the glass, in void"
    );
    assert!(
        listed("position = [4.0, 2.5, 4.0]"),
        "a rect inside the glass"
    );
    // The rect (2 x 1, facing +y) at the glass's top reaches into it; lifted clear of
    // it by a hair, it does not (its box widened by a millionth of a voxel).
    assert!(
        listed("position = [4.0, 4.0, 4.0]"),
        "a rect on the glass's top face"
    );
    assert!(
        !listed("position = [4.0, 4.00001, 4.0]"),
        "a rect just above the glass"
    );
    assert!(
        listed("position = [6.4, 3.0, 4.0]"),
        "a rect whose side reaches into it"
    );
    assert!(
        !listed("position = [7.1, 3.0, 4.0]"),
        "a rect beside the glass"
    );
}

/// The `scene.xml` the export writes for an experiment's text (approximations allowed).
fn scene_xml(text: &str) -> String {
    let e = Experiment::from_str(text, "scene.toml").unwrap();
    String::from_utf8(mitsuba(&e, false).unwrap().files[0].1.clone()).unwrap()
}

/// Glass is Mitsuba's dielectric of `specular_reflectance = kr` and
/// `specular_transmittance = kt`: exact only as a Fresnel dielectric without a diffuse
/// term, against void, with shadows that stop at it; each other case is listed with
/// its key, and the index is written as given (below 1 too).
#[test]
fn glass_is_exact_only_as_a_path_tracer_sees_it() {
    let base = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/mitsuba/glass_block.toml"),
    )
    .unwrap();
    let keys = |text: &str| -> Vec<String> {
        let e = Experiment::from_str(text, "glass.toml").unwrap();
        mitsuba(&e, false)
            .unwrap()
            .approximations
            .into_iter()
            .map(|a| a.key)
            .filter(|k| k != "materials")
            .collect()
    };
    assert_eq!(keys(&base), Vec::<String>::new());
    let xml = scene_xml(&base);
    for want in [
        "<float name=\"int_ior\" value=\"1.5\"/>",
        "<spectrum name=\"specular_reflectance\" value=\"1\"/>",
        "<spectrum name=\"specular_transmittance\" value=\"0.9\"/>",
    ] {
        assert!(xml.contains(want), "{want} not in {xml}");
    }
    let cases = [
        (
            "dielectric = \"fresnel\"",
            "dielectric = \"fixed\"",
            "materials[glass].dielectric",
        ),
        (
            "transmittance = \"opaque\"",
            "transmittance = \"min-kt\"",
            "features.transmittance",
        ),
        (
            "transmittance = \"opaque\"",
            "transmittance = \"beer-lambert\"",
            "features.transmittance",
        ),
        (
            "kd = 0.0\nks = 0.0\nkr = 1.0",
            "kd = 0.2\nks = 0.0\nkr = 1.0",
            "materials[glass].kd",
        ),
        ("ior = 1.5", "ior = 1.0", "materials[glass].ior"),
    ];
    for (from, to, key) in cases {
        assert!(base.contains(from), "{from}");
        let got = keys(&base.replace(from, to));
        assert_eq!(got, vec![key.to_string()], "{to}");
    }
    // A diffuse term fits a blend of diffuse and dielectric exactly while kd max(albedo)
    // + max(kr, kt) <= 1.
    let blend = base.replace(
        "kd = 0.0\nks = 0.0\nkr = 1.0\nkt = 0.9",
        "kd = 0.2\nks = 0.0\nkr = 0.3\nkt = 0.6",
    );
    assert_eq!(keys(&blend), Vec::<String>::new());
    let xml = scene_xml(&blend);
    for want in [
        "<bsdf type=\"blendbsdf\" id=\"material1\">",
        "<float name=\"weight\" value=\"0.6\"/>",
        "<spectrum name=\"specular_transmittance\" value=\"1\"/>",
        "<spectrum name=\"specular_reflectance\" value=\"0.5\"/>",
    ] {
        assert!(xml.contains(want), "{want} not in {xml}");
    }
    // Two glasses touching: their interface is one dielectric against vacuum.
    let two = base.replace(
        "[[materials]]\nname = \"floor\"",
        "[[scene.boxes]]\nmin = [14, 1, 8]\nmax = [16, 6, 14]\nmaterial = \"semi-solid\"\n\n\
         [[materials]]\nname = \"semi-solid\"\nkd = 0.0\nks = 0.0\ndielectric = \"fresnel\"\n\n\
         [[materials]]\nname = \"floor\"",
    );
    let got = keys(&two);
    assert!(got.contains(&"materials[glass].ior".to_string()), "{got:?}");
    // An index below 1 is written as it is (it was clamped to 1 once, silently).
    let xml = scene_xml(&base.replace("ior = 1.5", "ior = 0.7"));
    assert!(
        xml.contains("<float name=\"int_ior\" value=\"0.7\"/>"),
        "{xml}"
    );
}

struct Scratch(std::path::PathBuf);
impl Scratch {
    fn path(&self) -> &std::path::Path {
        &self.0
    }
}

/// The command: writes scene.xml, meshes and a record; refuses a file as the
/// directory, its own input as an output, and a failure midway leaves nothing.
#[test]
fn the_command_writes_all_or_nothing() {
    let root = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("export-command");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let dir = Scratch(root);
    let exp = dir.path().join("diffuse.toml");
    std::fs::write(&exp, DIFFUSE).unwrap();
    let out = dir.path().join("mitsuba");
    let run = export(&exp, &out, &["--strict"]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("0 approximation(s)"), "{stdout}");
    let record: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("scene.xml.json")).unwrap()).unwrap();
    assert_eq!(record["made_by"], "voxlab export --to mitsuba");
    assert!(out.join("meshes").read_dir().unwrap().count() == 1);

    // meshes/ is a file: the meshes cannot be written, and no scene.xml is left.
    let blocked = dir.path().join("blocked");
    std::fs::create_dir(&blocked).unwrap();
    std::fs::write(blocked.join("meshes"), "in the way").unwrap();
    let run = export(&exp, &blocked, &[]);
    assert!(!run.status.success());
    let mut left: Vec<String> = std::fs::read_dir(&blocked)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, ["meshes"], "a failed export left files behind");

    // An over-long directory name: an error naming it, nothing created; an odd but
    // valid one (spaces, non-ASCII) is written as any other.
    let long = dir.path().join("d".repeat(300));
    let run = export(&exp, &long, &[]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && stderr.contains("too long"),
        "{stderr}"
    );
    assert!(!long.exists());
    let odd = dir.path().join("odd name é ✓");
    let run = export(&exp, &odd, &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(odd.join("scene.xml").is_file() && odd.join("scene.xml.json").is_file());

    // Strict with an approximation: an error naming the key, nothing written.
    let approx = dir.path().join("approx.toml");
    std::fs::write(&approx, DIFFUSE.replace("ks = 0.0", "ks = 0.5")).unwrap();
    let target = dir.path().join("strict");
    let run = voxlab()
        .args([
            "export",
            approx.to_str().unwrap(),
            "--to",
            "mitsuba",
            "--strict",
        ])
        .arg(&target)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && stderr.contains("materials[matte].ks"),
        "{stderr}"
    );
    assert!(!target.exists());

    // A value Mitsuba's 32-bit floats cannot hold is refused with its key, not written
    // as infinity; the largest that fits is written.
    let huge = dir.path().join("huge.toml");
    std::fs::write(
        &huge,
        DIFFUSE.replace("intensity = 50.0", "intensity = 1e300"),
    )
    .unwrap();
    let target = dir.path().join("huge");
    let run = export(&huge, &target, &[]);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "1e300 exported");
    assert!(
        stderr.contains("huge.toml") && stderr.contains("lights[0].intensity"),
        "{stderr}"
    );
    assert!(!target.exists());
    std::fs::write(
        &huge,
        DIFFUSE.replace("intensity = 50.0", "intensity = 1e37"),
    )
    .unwrap();
    let run = export(&huge, &target, &[]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let xml = std::fs::read_to_string(target.join("scene.xml")).unwrap();
    assert!(!xml.contains("inf") && !xml.contains("NaN"), "{xml}");
}

/// Glass under Beer-Lambert gets a homogeneous absorbing interior (its sigma, per world
/// unit) and the volumetric integrator; under min-kt, whose kt is per crossing, none.
/// A sigma beyond 32-bit floats is refused with its key.
#[test]
fn beer_lambert_glass_gets_an_absorbing_interior() {
    let glass = with_glass_box(
        [4, 3, 4],
        "name = \"clear\"\nkd = 0.0\nks = 0.0\nkr = 0.1\nkt = 0.9\nior = 1.5\nsigma = [0.5, 0.25, 0.125]",
    );
    let e = Experiment::from_str(
        &format!("{glass}\n[features]\ntransmittance = \"beer-lambert\"\n"),
        "bl.toml",
    )
    .unwrap();
    let xml = String::from_utf8(mitsuba(&e, false).unwrap().files[0].1.clone()).unwrap();
    assert!(xml.contains("type=\"volpath\""), "{xml}");
    assert!(
        xml.contains("<rgb name=\"sigma_t\" value=\"1, 0.5, 0.25\"/>"),
        "{xml}"
    );
    assert!(
        xml.contains("<float name=\"scale\" value=\"0.5\"/>"),
        "{xml}"
    );
    assert!(xml.contains("<ref name=\"interior\""), "{xml}");
    let e = Experiment::from_str(&glass, "minkt.toml").unwrap();
    let xml = String::from_utf8(mitsuba(&e, false).unwrap().files[0].1.clone()).unwrap();
    assert!(
        xml.contains("type=\"path\"") && !xml.contains("<medium"),
        "{xml}"
    );
    let huge = glass.replace("sigma = [0.5, 0.25, 0.125]", "sigma = [1e300, 0.0, 0.0]");
    let e = Experiment::from_str(
        &format!("{huge}\n[features]\ntransmittance = \"beer-lambert\"\n"),
        "huge.toml",
    )
    .unwrap();
    let msg = mitsuba(&e, false).unwrap_err().to_string();
    assert!(msg.contains("materials[clear].sigma"), "{msg}");
}

/// An export's record names what it read and the voxels it wrote: text parsed without a
/// file (Python's dicts and text) hashes its mesh as a file's would (it listed no
/// inputs), and voxels set in memory, which no text gives, are named by their hash.
#[test]
fn the_record_names_the_inputs_of_text_and_the_voxels_written() {
    let root = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("export-record");
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(&root).unwrap();
    let mesh = root.join("tet.obj");
    std::fs::write(
        &mesh,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let text = format!(
        "[scene]\nmesh = {:?}\nresolution = 4\nmaterial = \"solid\"\n",
        mesh.display().to_string()
    );
    let record = |e: &Experiment, out: &str| -> serde_json::Value {
        let dir = root.join(out);
        voxlab::export::write_mitsuba(e, &text, &dir, false).unwrap();
        serde_json::from_slice(&std::fs::read(dir.join("scene.xml.json")).unwrap()).unwrap()
    };
    let e = Experiment::from_str(&text, "<dict>").unwrap();
    let r = record(&e, "text");
    let inputs: Vec<&str> = r["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["path"].as_str().unwrap())
        .collect();
    assert_eq!(inputs, [mesh.display().to_string()], "{r:#}");
    assert_eq!(r["grid"], e.scene.grid.record());
    // Other voxels set in memory: the record names those.
    let mut moved = e.clone();
    let other = Grid::new(UVec3::new(3, 2, 1), 1.0, DVec3::ZERO).unwrap();
    moved
        .set_grid(other.clone(), e.scene.materials.clone())
        .unwrap();
    let r = record(&moved, "memory");
    assert_eq!(
        r["grid"]["blake3"],
        other.content_hash().to_hex().to_string()
    );
    assert_ne!(r["grid"], record(&e, "text-again")["grid"]);
    let _ = std::fs::remove_dir_all(&root);
}
