//! Triangle surfaces on the GPU (`render.surface`, shaders/triangles.wgsl and
//! shaders/shadow_surface.wgsl) against the f64 reference, over generated cases that vary
//! what changes how the kernel runs: the grid's resolution (cells of many or few
//! triangles), image sizes, depth limits, both transmittances, both walks, the mesh's
//! and the smooth surface, sampled area lights over many frames per dispatch; and the
//! device memory: the surfaces are held only while a plan traces them.

mod common;

use common::{MESH_SURFACE, SMOOTH_SURFACE, VOXELS_SURFACE};
use common::{assert_agree, experiment, icosphere, mesh_scene, tracer};
use glam::DVec3;
use voxlab::render::RenderSettings;
use voxlab::scene::{AreaLight, AreaShape, Light, seed_ids, seed_palette};

/// A 6 x 4 rect light above and in front of the scene's grid, facing it.
fn add_area_light(scene: &mut voxlab::scene::Scene) {
    let c = scene.grid.centre();
    scene.lights.push(Light::Area(AreaLight {
        emission: Default::default(),
        shape: AreaShape::Rect {
            width: 6.0,
            height: 4.0,
        },
        position: c + DVec3::new(0.0, 30.0, 25.0),
        normal: DVec3::new(0.0, -0.8, -0.6),
        rotation: 0.4,
        color: DVec3::ONE,
        intensity: 900.0,
    }));
}

#[test]
fn generated_spheres_agree_with_the_cpu_at_every_setting() {
    let mut gpu = tracer();
    let materials = [seed_ids::GLASS, seed_ids::SEMI_SOLID, seed_ids::SOLID];
    let resolutions = [3, 8, 20, 48];
    let sizes = [(33, 21), (48, 48), (17, 40)];
    let depths = [(0, 0), (2, 1), (4, 4)];
    let walks = voxlab::render::Traversal::walks();
    for i in 0..12usize {
        let mut m = seed_palette()[materials[i % 3] as usize].clone();
        if i % 4 == 1 {
            m.sigma = Some(DVec3::new(0.4, 1.1, 2.5));
        }
        let resolution = resolutions[i % 4];
        let scene = mesh_scene(icosphere(2 + (i % 3) as u32), vec![], m, resolution);
        let (w, h) = sizes[i % 3];
        let (refl, refr) = depths[(i / 3) % 3];
        let s = RenderSettings {
            width: w,
            height: h,
            max_reflection_depth: refl,
            max_refraction_depth: refr,
            surface: MESH_SURFACE,
            // Every registered walk in turn.
            traversal: walks[i % walks.len()],
            features: voxlab::Features {
                transmittance: if i % 4 == 1 {
                    voxlab::technique::beer_lambert::ID
                } else {
                    voxlab::technique::min_kt::ID
                },
                ..Default::default()
            },
            ..Default::default()
        };
        let g = gpu
            .render(&scene, &s)
            .unwrap_or_else(|e| panic!("case {i}: {e:#}"));
        let plan = gpu.last_plan().unwrap();
        assert_eq!(plan.surface, MESH_SURFACE, "{plan}");
        let c = voxlab::cpu::render(&scene, &s);
        assert_agree(
            &format!(
                "case {i}: sphere at {resolution}, {w}x{h}, depth {refl}/{refr}, {:?}, {:?}",
                s.traversal, s.features.transmittance
            ),
            &g.frame,
            &c.frame,
        );
    }
}

#[test]
fn the_bunny_mesh_and_the_smooth_deer_under_area_lights_over_many_frames() {
    let mut gpu = tracer();
    for (file, surface) in [
        ("bunny_glass.toml", MESH_SURFACE),
        ("deer_area_light.toml", SMOOTH_SURFACE),
    ] {
        let mut e = experiment(file);
        add_area_light(&mut e.scene);
        let s = &mut e.settings;
        s.width = 40;
        s.height = 40;
        s.surface = surface;
        s.features.shadow_model = &voxlab::technique::area::MODEL;
        s.light_samples = 2;
        s.spp = 24;
        let g = gpu.render(&e.scene, &e.settings).unwrap();
        let cpu = voxlab::cpu::render(&e.scene, &e.settings);
        assert_agree(
            &format!("{file} as {surface:?}, 24 frames"),
            &g.frame,
            &cpu.frame,
        );
    }
}

#[test]
fn the_surfaces_are_on_the_device_only_while_a_plan_traces_them() {
    let mut gpu = tracer();
    let e = experiment("bunny_glass.toml");
    let mut s = e.settings.clone();
    s.width = 16;
    s.height = 16;
    s.surface = MESH_SURFACE;
    gpu.render(&e.scene, &s).unwrap();
    let with = gpu.last_memory().unwrap();
    assert!(with.surfaces > 0, "{with}");
    s.surface = VOXELS_SURFACE;
    let off = gpu.render(&e.scene, &s).unwrap();
    let without = gpu.last_memory().unwrap();
    assert_eq!(without.surfaces, 0, "{without}");
    // Back to voxels, the dense walk reads the untagged grid again: the image is the
    // voxels' (a stale tagged voxel buffer would show as misses).
    let cpu = voxlab::cpu::render(&e.scene, &s);
    assert_agree("voxels after triangles", &off.frame, &cpu.frame);
}

#[test]
fn every_unroll_of_the_walks_gives_the_same_image_through_many_cells() {
    // The seed scene's smooth surface: thin glass, so rays cross many cells, each of
    // which ends a loop iteration of the walks; an early version ended such walks
    // after max_steps / DDA_UNROLL iterations (8 % of the pixels wrong at 8).
    let e = experiment("baseline.toml");
    let mut s = e.settings.clone();
    s.width = 40;
    s.height = 40;
    s.surface = SMOOTH_SURFACE;
    let cpu = voxlab::cpu::render(&e.scene, &s);
    for unroll in [1, 2, 4, 8] {
        let mut gpu = tracer();
        gpu.set_dda_unroll(unroll).unwrap();
        let g = gpu.render(&e.scene, &s).unwrap();
        assert_eq!(gpu.dda_unroll(), unroll, "no retry at another unroll");
        assert_agree(
            &format!("seed scene, smooth, DDA_UNROLL {unroll}"),
            &g.frame,
            &cpu.frame,
        );
    }
}

#[test]
fn every_shadow_model_and_lighting_term_shades_triangles_alike_on_both_tracers() {
    // The bunny's mesh under an area light, with every way a light's visibility can be
    // estimated: sampled, each plug-in model, cones; and cone-traced AO.
    let mut e = experiment("bunny_glass.toml");
    add_area_light(&mut e.scene);
    let mut base = e.settings.clone();
    base.width = 20;
    base.height = 20;
    base.surface = MESH_SURFACE;
    base.light_samples = 1;
    base.spp = 2;
    let mut variants: Vec<(String, RenderSettings)> = Vec::new();
    for m in voxlab::technique::SHADOW_MODELS {
        let mut s = base.clone();
        s.features.shadow_model = m;
        variants.push((format!("shadow model {}", m.name), s));
    }
    let mut cones = base.clone();
    cones.features.shadow_model = &voxlab::technique::cone::MODEL;
    cones.features.set_term("ambient_occlusion", true);
    variants.push(("cone shadows and AO".into(), cones));
    let mut gpu = tracer();
    for (name, s) in variants {
        let start = std::time::Instant::now();
        let g = gpu
            .render(&e.scene, &s)
            .unwrap_or_else(|err| panic!("{name}: {err:#}"));
        let plan = gpu.last_plan().unwrap();
        assert_eq!(plan.surface, MESH_SURFACE, "{name}: {plan}");
        let cpu = voxlab::cpu::render(&e.scene, &s);
        assert_agree(&format!("bunny mesh, {name}"), &g.frame, &cpu.frame);
        eprintln!("  {name}: {:.1} s", start.elapsed().as_secs_f64());
    }
}

/// An OBJ of two objects, a tetrahedron whose corners name normals and a box of quads,
/// with the file's normals first (a common exporter's layout). `box_normal` is what the
/// box's corners say: "" (none), "given" (each face's own normal, named) or "wrong" (the
/// tetrahedron's (1, 1, 1), named).
fn mixed_obj(box_normal: &str) -> String {
    let mut s = String::from(
        "vn -1 -1 -1\nvn 1 0 0\nvn 0 1 0\nvn 0 0 1\nvn 1 1 1\n\
         vn -1 0 0\nvn 1 0 0\nvn 0 -1 0\nvn 0 1 0\nvn 0 0 -1\nvn 0 0 1\n\
         o tet\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
         f 1//1 3//3 2//2\nf 1//1 2//2 4//4\nf 1//1 4//4 3//3\nf 2//5 3//5 4//5\n\
         o box\nv 2 0 0\nv 3 0 0\nv 3 1 0\nv 2 1 0\nv 2 0 1\nv 3 0 1\nv 3 1 1\nv 2 1 1\n",
    );
    // Each face's corners, counter-clockwise from outside, and its normal's index.
    let faces = [
        ([5, 8, 7, 6], 10),
        ([9, 10, 11, 12], 11),
        ([5, 6, 10, 9], 8),
        ([8, 12, 11, 7], 9),
        ([5, 9, 12, 8], 6),
        ([6, 7, 11, 10], 7),
    ];
    for (corners, n) in faces {
        s.push('f');
        for c in corners {
            match box_normal {
                "" => s.push_str(&format!(" {c}")),
                "given" => s.push_str(&format!(" {c}//{n}")),
                _ => s.push_str(&format!(" {c}//5")),
            }
        }
        s.push('\n');
    }
    s
}

/// Faces without normals in a file that has normals are shaded with their own face's
/// normal, on both tracers: exactly as if the file named that normal, and not as the
/// normal tobj fills in for them (another face's).
#[test]
fn faces_without_normals_are_shaded_with_their_face_normal() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("gpu_mixed_normals");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let load = |name: &str, box_normal: &str| {
        std::fs::write(dir.join(format!("{name}.obj")), mixed_obj(box_normal)).unwrap();
        let toml = format!(
            "[scene]\nmesh = \"{name}.obj\"\nresolution = 12\n\
             [render]\nsurface = \"mesh\"\nwidth = 40\nheight = 28\n"
        );
        std::fs::write(dir.join(format!("{name}.toml")), toml).unwrap();
        voxlab::experiment::Experiment::load(dir.join(format!("{name}.toml")))
            .unwrap_or_else(|e| panic!("{e}"))
    };
    let (none, given, wrong) = (
        load("none", ""),
        load("given", "given"),
        load("wrong", "wrong"),
    );
    // The loader: the box's corners have no normal (zero: the face's is used).
    let mesh = none.scene.mesh.as_ref().unwrap();
    assert_eq!(mesh.triangles.len(), 4 + 12);
    for t in &mesh.triangles[4..] {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let face = (b - a).cross(c - a).normalize();
        for &i in t {
            assert_eq!(mesh.normals[i as usize], face, "a box corner's normal");
        }
    }
    let mut gpu = tracer();
    let render = |gpu: &mut voxlab::gpu::GpuTracer, e: &voxlab::experiment::Experiment| {
        let g = gpu
            .render(&e.scene, &e.settings)
            .unwrap_or_else(|e| panic!("{e:#}"));
        (g.frame, voxlab::cpu::render(&e.scene, &e.settings).frame)
    };
    let (g_none, c_none) = render(&mut gpu, &none);
    let (g_given, c_given) = render(&mut gpu, &given);
    let (_, c_wrong) = render(&mut gpu, &wrong);
    assert_eq!(
        c_none.pixels, c_given.pixels,
        "CPU: no normal against the face's, named"
    );
    assert_eq!(
        g_none.pixels, g_given.pixels,
        "GPU: no normal against the face's, named"
    );
    assert_agree("mixed normals, GPU against CPU", &g_none, &c_none);
    // The test can fail: a borrowed normal changes the box's pixels.
    let changed = c_wrong
        .pixels
        .iter()
        .zip(&c_given.pixels)
        .filter(|(a, b)| a != b)
        .count();
    assert!(changed > 20, "a wrong normal changed only {changed} pixels");
}
