//! The robust formulations the stress suite calls for (issue 6), each with a test that
//! fails under the naive formulation: zero direction components, rays that start on voxel
//! boundaries, optical depth summed and exponentiated once, a light at distance 0,
//! grazing refraction and total internal reflection, and precision far from the origin.
//! Each was checked by breaking the formulation in the tracer and watching it fail.

mod common;

use common::{linear, tracer};
use glam::{DVec3, IVec3, UVec3};
use voxlab::cpu::{refract, shadow_beer_lambert};
use voxlab::dda::{Dda, cast};
use voxlab::scene::{Grid, Light, Material, PointLight, Scene, seed_scene, seed_scene_dims};
use voxlab::stress::{SuiteOptions, TOLERANCE, cases, run_case};
use voxlab::{RayStats, RenderSettings};

fn settings(w: u32, h: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        ..Default::default()
    }
}

fn material(name: &str, kd: f64, kt: f64) -> Material {
    Material {
        name: name.into(),
        albedo: DVec3::ONE,
        kd,
        ks: 0.0,
        shininess: 150.0,
        kr: 0.0,
        kt,
        ior: 1.0,
        sigma: None,
        emission: DVec3::ZERO,
        dielectric: Default::default(),
    }
}

// --- Zero direction components --------------------------------------------------------

#[test]
fn cpu_rays_in_a_face_plane_with_zero_components_enter_the_grid() {
    // The naive slab test divides by d[a] = 0: (lo - o) / 0 is 0/0 = NaN on the face
    // plane, and the ray misses a grid it runs along.
    let mut g = Grid::new(UVec3::new(4, 3, 2), 1.0, DVec3::ZERO).unwrap();
    g.set(IVec3::new(2, 0, 0), 1);
    g.set(IVec3::new(3, 2, 1), 1);
    for (o, hit_voxel, hit_t) in [
        // On the bottom face plane y = 0 and z = 0 (an edge of the box), moving +x.
        (DVec3::new(-1.0, 0.0, 0.0), IVec3::new(2, 0, 0), 3.0),
        // On the top face plane y = 3 (inside the closed slab), z = 2 (its other edge).
        (DVec3::new(-2.0, 3.0, 2.0), IVec3::new(3, 2, 1), 5.0),
    ] {
        let visits: Vec<_> = Dda::new(&g, o, DVec3::X, f64::INFINITY).collect();
        assert_eq!(visits.len(), 4, "ray {o}: {visits:?}");
        assert!(visits.iter().all(|v| v.t_enter.is_finite()));
        let (hit, steps) = cast(&g, o, DVec3::X, 0);
        let hit = hit.unwrap_or_else(|| panic!("ray {o} along a face plane missed"));
        assert_eq!(
            (hit.voxel, hit.t, hit.normal),
            (hit_voxel, hit_t, -DVec3::X)
        );
        assert!(steps <= 4);
    }
}

/// The seed grid seen from a point on its bottom face plane (y = 0), looking down -z
/// with an odd image: the centre row's rays have dy == 0 exactly and run in the plane.
fn on_face_plane_scene() -> Scene {
    let mut s = seed_scene(16).unwrap();
    s.camera.target = DVec3::new(8.0, 0.0, 8.0);
    s.camera.distance = 24.0;
    s.camera.yaw = 0.0;
    s.camera.pitch = 0.0;
    s.camera.vfov = 60f64.to_radians();
    s
}

#[test]
fn gpu_rays_in_a_face_plane_with_zero_components_match_the_oracle() {
    let scene = on_face_plane_scene();
    let st = settings(33, 33);
    let g = tracer().render(&scene, &st).unwrap().frame;
    let c = voxlab::cpu::render(&scene, &st).frame;
    assert!(g.all_finite(), "GPU image not finite");
    // The centre row runs along the grid's face; the oracle sees the frame there.
    let centre: Vec<_> = (0..33).map(|i| (g.get(i, 16), c.get(i, 16))).collect();
    let ambient = scene.ambient.as_vec3().to_array();
    assert!(
        centre.iter().any(|(_, c)| *c != ambient),
        "the oracle should see the grid along the face plane"
    );
    for (i, (g, c)) in centre.iter().enumerate() {
        for k in 0..3 {
            assert!(
                (g[k] - c[k]).abs() <= TOLERANCE as f32,
                "centre row pixel {i}: GPU {g:?}, CPU {c:?}"
            );
        }
    }
}

// --- Rays that start on voxel boundaries -----------------------------------------------

/// Renders a stress case by name and checks that it passes.
fn suite_case_passes(name: &str) {
    let all = cases(&SuiteOptions::default()).unwrap();
    let case = all.iter().find(|c| c.name == name).unwrap();
    let mut gpu = tracer();
    let row = run_case(Some(&mut gpu), case);
    let d = row.diff.unwrap();
    println!(
        "{name}: {} px over, {} ill-conditioned, {} over among the others, max {:.2e}",
        d.pixels_over, row.ill_conditioned, row.over_well_conditioned, d.max_abs
    );
    assert_eq!(
        row.verdict(),
        voxlab::stress::Verdict::Pass,
        "{name}: {:?}",
        row.verdict()
    );
}

#[test]
fn gpu_eye_on_the_grids_corner_and_face_enters_at_t_zero() {
    // The entry voxel floor(o + t d) is clamped into the grid: from the corner (16, 16, 16)
    // it is voxel 16 on every axis otherwise, outside the grid, and every ray misses.
    for name in ["eye-on-grid-corner", "eye-on-grid-face", "eye-on-lattice"] {
        suite_case_passes(name);
    }
}

#[test]
fn gpu_counts_the_same_voxel_steps_from_a_lattice_point() {
    // From a lattice point in an empty grid every ray walks to the boundary; a skipped
    // voxel (stepping two axes at once at a tie) or a repeated one (visiting a start or
    // entry voxel twice, or one outside the grid) changes the count of steps. Every ray
    // starts on a voxel corner (three ties at t = 0); the view is turned off the lattice
    // axes, so no ray meets another edge exactly where f32 and f64 could break a tie
    // differently (at the grid's boundary that changes the count by one, legitimately).
    let mut scene = seed_scene_dims(UVec3::new(12, 10, 14)).unwrap();
    scene.grid.data_mut().fill(0);
    scene.lights.clear();
    for eye in [
        // Inside, on a corner where eight voxels meet.
        DVec3::new(6.0, 5.0, 11.0),
        // On the grid's own corner (12, 10, 14), outside by the contract's `<`.
        DVec3::new(12.0, 10.0, 14.0),
    ] {
        // The orbit camera's eye is target + distance * dir(yaw, pitch): put the target
        // where that lands the eye exactly on the lattice point.
        scene.camera.distance = 1.0;
        scene.camera.yaw = 0.3;
        scene.camera.pitch = 0.2;
        scene.camera.vfov = 100f64.to_radians();
        scene.camera.target = DVec3::ZERO;
        scene.camera.target = eye - scene.camera.eye();
        assert_eq!(scene.camera.eye(), eye);
        let st = settings(31, 31);
        let g = tracer().render_counted(&scene, &st).unwrap();
        let c = voxlab::cpu::render(&scene, &st);
        println!(
            "eye {}: GPU {} steps, CPU {}",
            scene.camera.eye(),
            g.stats.voxel_steps,
            c.stats.voxel_steps
        );
        assert!(c.stats.voxel_steps > 0);
        assert_eq!(g.stats.voxel_steps, c.stats.voxel_steps);
    }
}

// --- Optical depth, summed and exponentiated once ------------------------------------

/// A tube of `n` fog voxels (kt 1, sigma per world unit) along x, a white wall at x = 0
/// and a light in the last fog voxel; the eye in the fog, looking at the wall.
fn fog_tube(n: u32, sigma: f64) -> Scene {
    let mut grid = Grid::new(UVec3::new(n, 3, 3), 1.0, DVec3::ZERO).unwrap();
    grid.set(IVec3::new(0, 1, 1), 1);
    for x in 1..n as i32 {
        grid.set(IVec3::new(x, 1, 1), 2);
    }
    let mut fog = material("fog", 0.0, 1.0);
    fog.sigma = Some(DVec3::splat(sigma));
    let mut s = seed_scene(4).unwrap();
    s.grid = grid;
    s.materials = vec![material("void", 0.0, 1.0), material("wall", 1.0, 0.0), fog];
    s.lights = vec![Light::Point(PointLight {
        position: DVec3::new(n as f64 - 0.5, 1.5, 1.5),
        color: DVec3::ONE,
        intensity: 1000.0,
    })];
    s.ambient = DVec3::ZERO;
    s.camera.target = DVec3::new(0.0, 1.5, 1.5);
    s.camera.distance = n as f64 - 3.0;
    s.camera.yaw = 90f64.to_radians();
    s.camera.pitch = 0.0;
    s.camera.vfov = 0.01f64.to_radians();
    s
}

#[test]
fn cpu_optical_depth_gives_exact_zero_and_one_minus_epsilon() {
    let n = 200u32;
    let q = DVec3::new(1.001, 1.5, 1.5);
    let light = DVec3::new(n as f64 - 0.5, 1.5, 1.5);
    let len = (light - q).length();
    let mut stats = RayStats::default();
    let mut last = 1.0;
    for k in -9..=5 {
        let depth = 10f64.powi(k);
        let scene = fog_tube(n, depth / len);
        let t = shadow_beer_lambert(&scene, q, light, &mut stats);
        assert!(
            t.x.is_finite() && t.x >= 0.0 && t.x <= 1.0,
            "depth {depth}: T {t}"
        );
        assert!(t.x <= last, "depth {depth}: T {t} not monotone");
        last = t.x;
        if k == -6 {
            assert!((t.x - (1.0 - 1e-6)).abs() < 1e-12, "depth 1e-6: T {}", t.x);
        }
    }
    let scene = fog_tube(n, 1e4 / len);
    assert_eq!(
        shadow_beer_lambert(&scene, q, light, &mut stats),
        DVec3::ZERO
    );
}

#[test]
fn gpu_optical_depth_is_summed_then_exponentiated() {
    // 199 fog voxels, 5e-9 of optical depth each: in f32, exp(-5e-9) is exactly 1, so a
    // product of per-voxel transmittances gives 1; the sum, exponentiated once, gives
    // 1 - 1e-6. The wall's brightness under fog, over its brightness without, is T.
    let n = 200u32;
    let st = RenderSettings {
        features: voxlab::Features {
            transmittance: voxlab::technique::beer_lambert::ID,
            ..Default::default()
        },
        ..settings(3, 3)
    };
    let mut gpu = tracer();
    let clear = gpu.render(&fog_tube(n, 0.0), &st).unwrap().frame;
    let len = n as f64 - 0.5 - 1.001;
    for (depth, want) in [(1e-6f64, 1.0 - 1e-6), (1e4, 0.0)] {
        let scene = fog_tube(n, depth / len);
        let fog = gpu.render(&scene, &st).unwrap().frame;
        let cpu = voxlab::cpu::render(&scene, &st).frame;
        let (f, c, o) = (fog.get(1, 1), clear.get(1, 1), cpu.get(1, 1));
        assert!(c[0] > 0.01, "the wall must be lit: {c:?}");
        let t = f[0] as f64 / c[0] as f64;
        println!("optical depth {depth:e}: GPU T = {t:.9}, want {want:.9}");
        if want == 0.0 {
            assert_eq!(f, [0.0; 3]);
            assert_eq!(o, [0.0; 3]);
        } else {
            assert!(t < 1.0, "T rounded to 1: the depth was not summed first");
            // Three f32 roundings (the depth sum, exp, the product): a few ulps of 1.
            assert!((t - want).abs() < 3e-7, "T = {t}, want {want}");
            assert!((f[0] - o[0]).abs() <= 2.0 * f32::EPSILON * o[0]);
        }
    }
}

// --- The inverse-square singularity ---------------------------------------------------

#[test]
fn light_at_distance_zero_is_held_by_the_minimum_distance() {
    // A solid floor; the light sits exactly where the centre ray hits it (dl = 0). Without
    // max(d^2, d_min^2) E is infinite; without l = n the direction is 0/0.
    let mut grid = Grid::new(UVec3::new(5, 5, 3), 1.0, DVec3::ZERO).unwrap();
    for y in 0..5 {
        for x in 0..5 {
            grid.set(IVec3::new(x, y, 0), 3);
        }
    }
    let mut s = seed_scene(4).unwrap();
    s.grid = grid;
    let intensity = 5e-5;
    s.lights = vec![Light::Point(PointLight {
        position: DVec3::new(2.5, 2.5, 1.0),
        color: DVec3::ONE,
        intensity,
    })];
    s.camera.target = DVec3::new(2.5, 2.5, 1.0);
    s.camera.distance = 4.0;
    s.camera.yaw = 0.0;
    s.camera.pitch = 0.0;
    s.camera.vfov = 60f64.to_radians();
    let st = RenderSettings {
        max_reflection_depth: 0,
        max_refraction_depth: 0,
        ..settings(9, 9)
    };
    let solid = &s.materials[3];
    // dl = 0: l = n, diffuse 1, r = -n = d, specular 1; E = I / d_min^2.
    let want = s.ambient.x
        + solid.albedo.x * intensity / st.falloff_min_distance.powi(2) * (solid.kd + solid.ks);
    let c = voxlab::cpu::render(&s, &st).frame;
    let g = tracer().render(&s, &st).unwrap().frame;
    assert!(c.all_finite() && g.all_finite());
    assert!(
        (c.get(4, 4)[0] as f64 - want).abs() < 1e-6,
        "CPU {:?}",
        c.get(4, 4)
    );
    assert!(
        (g.get(4, 4)[0] as f64 - want).abs() < 1e-5,
        "GPU {:?}",
        g.get(4, 4)
    );
    let d = linear(&g, &c, 1e-4);
    assert_eq!(d.pixels_over, 0, "{d}");
}

// --- Grazing refraction and total internal reflection -------------------------------

#[test]
fn refraction_near_grazing_and_the_critical_angle_is_finite_and_unit() {
    let n = DVec3::Y;
    for eta in [1.0f64 / 6.0, 1.0 / 1.5, 1.0, 1.5, 6.0] {
        let mut cosines: Vec<f64> = vec![0.0, 1e-300, 1e-16, 1e-8, 1e-4, 0.1, 0.5, 0.9, 1.0];
        if eta > 1.0 {
            // Exactly at the critical angle, and an ulp or two either side.
            let c = (1.0 - 1.0 / (eta * eta)).sqrt();
            for k in -2i64..=2 {
                cosines.push(f64::from_bits((c.to_bits() as i64 + k) as u64));
            }
        }
        for c in cosines {
            let d = DVec3::new((1.0 - c * c).sqrt(), -c, 0.0);
            let k = 1.0 - eta * eta * (1.0 - c * c);
            match refract(d, n, eta) {
                None => assert!(k < 0.0, "eta {eta}, cos {c}: TIR with k = {k}"),
                Some(t) => {
                    assert!(t.is_finite(), "eta {eta}, cos {c}: {t}");
                    assert!(
                        (t.length() - 1.0).abs() < 1e-12,
                        "eta {eta}, cos {c}: |t| {}",
                        t.length()
                    );
                    assert!(t.y <= 0.0, "eta {eta}, cos {c}: refracted backwards {t}");
                    // Snell: sin t2 = eta sin t1 (tangential components).
                    assert!((t.x - eta * d.x).abs() < 1e-9, "eta {eta}, cos {c}: {t}");
                }
            }
        }
    }
}

#[test]
fn gpu_grazing_and_total_internal_reflection_match_the_oracle() {
    for name in [
        "grazing",
        "inside-glass-tir",
        "ior-6-tir",
        "camera-in-glass",
    ] {
        suite_case_passes(name);
    }
}

// --- Precision far from the origin -------------------------------------------------

#[test]
fn gpu_image_does_not_depend_on_where_the_grid_sits() {
    // At 1e6 an f32 world coordinate is good to 1/16 of a voxel: a kernel tracing in
    // world f32 would move the eye and the lights and blur every face. In grid-local
    // coordinates the image is the one at the origin.
    let at = |origin: DVec3| {
        let mut s = seed_scene(16).unwrap();
        s.grid = voxlab::scene::seed::seed_grid(UVec3::splat(16), 1.0, origin).unwrap();
        let (c, w) = (s.grid.centre(), s.grid.width());
        s.lights = voxlab::scene::seed::seed_lights(c, w);
        s.camera = voxlab::scene::seed::seed_camera(c, w);
        s
    };
    let st = settings(64, 64);
    let mut gpu = tracer();
    let home = gpu.render(&at(DVec3::ZERO), &st).unwrap().frame;
    for origin in [DVec3::splat(1e5), DVec3::new(1e6, -1e6, 1e6)] {
        let far = gpu.render(&at(origin), &st).unwrap().frame;
        let d = linear(&far, &home, 1e-5);
        println!("origin {origin}: {d}");
        assert!(far.all_finite());
        assert_eq!(d.pixels_over, 0, "origin {origin}: {d}");
        assert!(d.max_abs < 1e-5, "origin {origin}: {d}");
    }
}
