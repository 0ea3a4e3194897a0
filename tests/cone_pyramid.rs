//! Cone-tracing pyramids and cones on the GPU against the f64 reference
//! (`voxlab::technique::cones::pyramid`, `voxlab::technique::cones::march`).
//!
//! Tolerances (f16 storage):
//! - opacity: built in f32 and rounded to f16 once, so `|gpu - cpu| <= 2^-10 |cpu| + 2^-24`
//!   (one f16 rounding, either mode, plus f16's subnormal spacing);
//! - radiance: each level is filtered from the f16 level below, and every value is
//!   non-negative, so level l is within `(l + 2) 2^-10 |cpu| + 1e-6` (one rounding per
//!   level plus f32 injection arithmetic);
//! - cones (the probe runs `shaders/cone.wgsl` itself): see `gpu_cones_match_cpu_cones`.

mod common;

use common::tracer;
use glam::{DVec3, IVec3, UVec3};
use voxlab::RenderSettings;
use voxlab::gpu::GpuTracer;
use voxlab::gpu::pyramid::ConeQuery;
use voxlab::render::ConeSettings;
use voxlab::scene::{Grid, Scene, seed_palette, seed_scene};
use voxlab::technique::cones::march::{self as cone, ConeParams};
use voxlab::technique::cones::pyramid::{Pyramid, PyramidLayout};

/// A grid of `dims` filled pseudo-randomly (a fixed LCG) with the seed palette's glass,
/// semi-solid and solid at `fill` density, lit by the seed's lights for a 16^3 grid moved
/// off the half-voxel coordinates they sit on: from a face centre to a light at x.5 a
/// shadow ray can pass exactly through a voxel edge, a tie that f32 and f64 rounding
/// break differently (a different voxel visited, a different visibility), which is
/// DDA behaviour the contract accepts, not pyramid error.
fn random_scene(dims: UVec3, fill: f64, seed: u64) -> Scene {
    let mut s = seed_scene(16).unwrap();
    for l in &mut s.lights {
        if let voxlab::scene::Light::Point(p) = l {
            p.position += DVec3::new(0.1234, 0.0567, 0.0891);
        }
    }
    let mut g = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
    let mut x = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    for v in g.data_mut() {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let u = (x >> 11) as f64 / (1u64 << 53) as f64;
        *v = if u < fill {
            1 + ((x >> 3) % 3) as u8
        } else {
            0
        };
    }
    s.grid = g;
    s.materials = seed_palette();
    s
}

fn settings() -> RenderSettings {
    RenderSettings::default()
}

fn check_pyramid(gpu: &mut GpuTracer, name: &str, scene: &Scene, levels: u32, radiance: bool) {
    let layout = PyramidLayout::new(scene.grid.dims(), levels);
    let cpu = Pyramid::build(scene, &settings(), layout, radiance);
    let g = gpu
        .build_pyramid(scene, &settings(), layout, radiance)
        .unwrap_or_else(|e| panic!("{name}: {e:#}"));
    for l in 0..layout.levels {
        let td = layout.texture_dims(l);
        let ld = layout.level_dims(l);
        let data = gpu.read_pyramid_level(&g, false, l).unwrap();
        let mut worst = 0.0f64;
        for z in 0..td.z {
            for y in 0..td.y {
                for x in 0..td.x {
                    let gv = data[(x + td.x * (y + td.y * z)) as usize] as f64;
                    let inside = x < ld.x && y < ld.y && z < ld.z;
                    let cv = if inside {
                        cpu.opacity[l as usize][(x + ld.x * (y + ld.y * z)) as usize]
                    } else {
                        0.0
                    };
                    let tol = cv.abs() / 1024.0 + 2f64.powi(-24);
                    assert!(
                        (gv - cv).abs() <= tol,
                        "{name}: opacity level {l} texel ({x},{y},{z}): gpu {gv} cpu {cv}{}",
                        if inside { "" } else { " (padding)" }
                    );
                    worst = worst.max((gv - cv).abs());
                }
            }
        }
        if radiance {
            let data = gpu.read_pyramid_level(&g, true, l).unwrap();
            let rad = &cpu.radiance.as_ref().unwrap()[l as usize];
            for z in 0..td.z {
                for y in 0..td.y {
                    for x in 0..td.x {
                        let i = (x + td.x * (y + td.y * z)) as usize;
                        let inside = x < ld.x && y < ld.y && z < ld.z;
                        for c in 0..4 {
                            let gv = data[4 * i + c] as f64;
                            let cv = if inside {
                                rad[(x + ld.x * (y + ld.y * z)) as usize][c]
                            } else {
                                0.0
                            };
                            let tol = (l + 2) as f64 / 1024.0 * cv.abs() + 1e-6;
                            assert!(
                                (gv - cv).abs() <= tol,
                                "{name}: radiance level {l} texel ({x},{y},{z}) channel {c}: \
                                 gpu {gv} cpu {cv}"
                            );
                        }
                    }
                }
            }
        }
    }
}

#[test]
fn gpu_pyramids_equal_cpu_pyramids_odd_sizes_included() {
    let mut gpu = tracer();
    check_pyramid(
        &mut gpu,
        "7x5x9, 4 levels",
        &random_scene(UVec3::new(7, 5, 9), 0.4, 1),
        4,
        true,
    );
    check_pyramid(
        &mut gpu,
        "33^3, auto levels",
        &random_scene(UVec3::splat(33), 0.3, 2),
        0,
        true,
    );
    check_pyramid(
        &mut gpu,
        "33^3, 6 levels",
        &random_scene(UVec3::splat(33), 0.3, 3),
        6,
        false,
    );
    check_pyramid(
        &mut gpu,
        "1x1x1",
        &random_scene(UVec3::ONE, 1.0, 4),
        0,
        true,
    );
    check_pyramid(&mut gpu, "seed 16^3", &seed_scene(16).unwrap(), 0, true);
}

#[test]
fn grid_256_cubed_builds_and_its_opacity_matches() {
    let mut gpu = tracer();
    let scene = seed_scene(256).unwrap();
    let layout = PyramidLayout::new(scene.grid.dims(), 0);
    assert_eq!(layout.levels, 8);
    let g = gpu
        .build_pyramid(&scene, &settings(), layout, true)
        .unwrap();
    let line = voxlab::technique::cones::pyramid::memory_line(&layout, true);
    println!("{line}");
    // 8/7 of 2 + 8 bytes per voxel, less the levels beyond the eighth.
    let bpv = g.bytes() as f64 / (256f64 * 256.0 * 256.0);
    assert!(
        (bpv - 10.0 * (1.0 - 0.125f64.powi(8)) / 0.875).abs() < 1e-9,
        "{bpv}"
    );
    let cpu = Pyramid::build(&scene, &settings(), layout, false);
    for l in [0, 3, 7] {
        let data = gpu.read_pyramid_level(&g, false, l).unwrap();
        for (i, (&gv, &cv)) in data.iter().zip(&cpu.opacity[l as usize]).enumerate() {
            let (gv, cv) = (gv as f64, cv);
            assert!(
                (gv - cv).abs() <= cv / 1024.0 + 2f64.powi(-24),
                "level {l} texel {i}: gpu {gv} cpu {cv}"
            );
        }
    }
    // Radiance is finite and somewhere lit.
    let top = gpu.read_pyramid_level(&g, true, 7).unwrap();
    assert!(top.iter().all(|v| v.is_finite()));
    assert!(top.chunks(4).any(|c| c[0] > 0.0));
}

/// Queries in the seed scene: marches from random interior points in random directions
/// with random apertures, AO and indirect at surface points, and shadow cones.
fn queries(scene: &Scene) -> Vec<ConeQuery> {
    let mut x: u64 = 12345;
    let mut rnd = || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let dims = scene.grid.dims().as_dvec3();
    let mut out = Vec::new();
    for i in 0..192 {
        let o = DVec3::new(rnd(), rnd(), rnd()) * dims;
        let w = DVec3::new(rnd() - 0.5, rnd() - 0.5, rnd() - 0.5).normalize();
        let tan_half = (rnd() * 40f64).to_radians().tan();
        out.push(ConeQuery {
            origin: o.as_vec3().to_array(),
            mode: i % 2,
            dir: w.as_vec3().to_array(),
            tan_half: tan_half as f32,
            target: [0.0; 3],
            max_dist: (rnd() * 30.0) as f32,
        });
    }
    // Surface points: voxel faces that border void.
    let g = &scene.grid;
    let faces = voxlab::scene::FACES;
    let mut surface = Vec::new();
    for z in 0..g.dims().z as i32 {
        for y in 0..g.dims().y as i32 {
            for xx in 0..g.dims().x as i32 {
                let v = IVec3::new(xx, y, z);
                if g.get(v) == 0 {
                    continue;
                }
                for f in faces {
                    if g.get(v + f) == 0 {
                        surface.push((v.as_dvec3() + 0.5 + 0.5 * f.as_dvec3(), f.as_dvec3()));
                    }
                }
            }
        }
    }
    let light = g.to_local(scene.lights[0].position());
    for k in 0..96 {
        let (p, n) = surface[(k * 7919) % surface.len()];
        out.push(ConeQuery {
            origin: p.as_vec3().to_array(),
            mode: 2 + (k % 3) as u32,
            dir: n.as_vec3().to_array(),
            tan_half: (5f64).to_radians().tan() as f32,
            target: light.as_vec3().to_array(),
            max_dist: 0.0,
        });
    }
    out
}

fn cpu_query(pyr: &Pyramid, c: &ConeSettings, q: &ConeQuery) -> [f64; 4] {
    let params = ConeParams {
        step_factor: c.step_factor,
        start_offset: c.start_offset,
    };
    let o = glam::Vec3::from_array(q.origin).as_dvec3();
    let w = glam::Vec3::from_array(q.dir).as_dvec3();
    let th = q.tan_half as f64;
    match q.mode {
        0 => [
            cone::march(pyr, &params, o, w, th, q.max_dist as f64, false).occlusion,
            0.0,
            0.0,
            0.0,
        ],
        1 => {
            let r = cone::march(pyr, &params, o, w, th, q.max_dist as f64, true);
            [r.radiance.x, r.radiance.y, r.radiance.z, r.occlusion]
        }
        2 => [
            cone::ambient_occlusion(pyr, &params, o, w, c.ao_cones, c.ao_range),
            0.0,
            0.0,
            0.0,
        ],
        3 => {
            let range = voxlab::gpu::pyramid::indirect_range(&pyr.layout);
            let r = cone::indirect(pyr, &params, o, w, c.ao_cones, range);
            [r.x, r.y, r.z, 0.0]
        }
        _ => {
            let l = glam::Vec3::from_array(q.target).as_dvec3();
            [
                cone::shadow_visibility(pyr, &params, o, w, l, th),
                0.0,
                0.0,
                0.0,
            ]
        }
    }
}

/// The probe runs the WGSL march on the same queries as the f64 march. They differ by
/// f16 storage (relative 2^-10 per sample), f32 sample positions, and the hardware's
/// filter weights (often 8-bit fixed point); rarely a sample lands on the other side of
/// the 0.99 cut-off, which snaps occlusion by up to 0.01. Bounds: occlusion and AO within
/// 0.02 on every query and 0.002 on average; radiance within 2 % of the largest value
/// plus 1e-4.
#[test]
fn gpu_cones_match_cpu_cones() {
    let mut gpu = tracer();
    let scene = seed_scene(16).unwrap();
    let layout = PyramidLayout::new(scene.grid.dims(), 0);
    let cpu = Pyramid::build(&scene, &settings(), layout, true);
    let g = gpu
        .build_pyramid(&scene, &settings(), layout, true)
        .unwrap();
    let c = ConeSettings::default();
    let qs = queries(&scene);
    let out = gpu.cone_probe(&g, &c, &qs).unwrap();
    let mut sum = 0.0;
    let mut worst: (f64, usize) = (0.0, 0);
    let rmax = qs
        .iter()
        .map(|q| cpu_query(&cpu, &c, q))
        .zip(&qs)
        .filter(|(_, q)| q.mode == 1 || q.mode == 3)
        .map(|(r, _)| r[0].max(r[1]).max(r[2]))
        .fold(0.0, f64::max);
    assert!(rmax > 0.0, "no query gathered radiance");
    for (i, (q, gv)) in qs.iter().zip(&out).enumerate() {
        let cv = cpu_query(&cpu, &c, q);
        let (scalar, rgb) = match q.mode {
            1 => (3, true),
            3 => (usize::MAX, true),
            _ => (0, false),
        };
        if scalar != usize::MAX {
            let e = (gv[scalar] as f64 - cv[scalar]).abs();
            sum += e;
            if e > worst.0 {
                worst = (e, i);
            }
            assert!(
                e <= 0.02,
                "query {i} mode {}: gpu {gv:?} cpu {cv:?}",
                q.mode
            );
        }
        if rgb {
            for k in 0..3 {
                let e = (gv[k] as f64 - cv[k]).abs();
                assert!(
                    e <= 0.02 * rmax + 1e-4,
                    "query {i} mode {} channel {k}: gpu {gv:?} cpu {cv:?} (largest {rmax})",
                    q.mode
                );
            }
        }
    }
    let mean = sum / qs.len() as f64;
    println!(
        "cone probe: mean |occlusion error| {mean:.2e}, worst {:.2e} (query {})",
        worst.0, worst.1
    );
    assert!(mean <= 0.002, "mean occlusion error {mean}");
}

#[test]
fn gpu_ao_is_exactly_one_in_an_empty_grid() {
    let mut gpu = tracer();
    let mut scene = seed_scene(16).unwrap();
    scene.grid.data_mut().fill(0);
    let layout = PyramidLayout::new(scene.grid.dims(), 0);
    let g = gpu
        .build_pyramid(&scene, &settings(), layout, false)
        .unwrap();
    let qs: Vec<ConeQuery> = [
        (DVec3::splat(8.0), DVec3::Y),
        (DVec3::new(0.0, 3.5, 7.0), DVec3::X),
    ]
    .iter()
    .map(|(p, n)| ConeQuery {
        origin: p.as_vec3().to_array(),
        mode: 2,
        dir: n.as_vec3().to_array(),
        tan_half: 0.0,
        target: [0.0; 3],
        max_dist: 0.0,
    })
    .collect();
    for r in gpu.cone_probe(&g, &ConeSettings::default(), &qs).unwrap() {
        assert_eq!(r[0], 1.0);
    }
}
