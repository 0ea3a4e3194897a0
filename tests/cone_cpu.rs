//! The f64 cone tracer (`voxlab::technique::cones::march`) and its pyramids (`voxlab::technique::cones::pyramid`)
//! on cases with known answers.

use glam::{DVec3, IVec3, UVec3};
use voxlab::RenderSettings;
use voxlab::frame::RayStats;
use voxlab::scene::{Grid, Scene, seed_ids, seed_scene};
use voxlab::technique::cones::march::{self as cone, ConeParams};
use voxlab::technique::cones::pyramid::{Pyramid, PyramidLayout, sample_level};

fn params() -> ConeParams {
    ConeParams {
        step_factor: 0.5,
        start_offset: 1.0,
    }
}

fn with_grid(dims: UVec3) -> Scene {
    let mut s = seed_scene(16).unwrap();
    s.grid = Grid::new(dims, 1.0, DVec3::ZERO).unwrap();
    s
}

#[test]
fn layouts_pad_to_the_coarsest_texel_and_halve_with_ceil() {
    let l = PyramidLayout::new(UVec3::new(7, 5, 9), 4);
    assert_eq!(l.levels, 4);
    assert_eq!(l.padded, UVec3::new(8, 8, 16));
    assert_eq!(l.level_dims(1), UVec3::new(4, 3, 5));
    assert_eq!(l.level_dims(3), UVec3::new(1, 1, 2));
    assert_eq!(l.texture_dims(3), UVec3::new(1, 1, 2));
    // Auto: 256^3 needs no padding and takes the default cap of 8 levels; 1^3 one level.
    let l = PyramidLayout::new(UVec3::splat(256), 0);
    assert_eq!((l.levels, l.padded), (8, UVec3::splat(256)));
    assert_eq!(PyramidLayout::new(UVec3::ONE, 0).levels, 1);
    // Auto never pads beyond twice the grid.
    for d in [3u32, 17, 33, 100, 257] {
        let l = PyramidLayout::new(UVec3::splat(d), 0);
        let ratio = (l.padded.as_dvec3() / d as f64).element_product();
        assert!(ratio <= 2.0, "{d}: {l:?}");
    }
}

#[test]
fn box_filter_conserves_opacity_mass_at_every_level() {
    for dims in [
        UVec3::new(7, 5, 9),
        UVec3::splat(33),
        UVec3::ONE,
        UVec3::new(1, 6, 3),
    ] {
        let mut s = with_grid(dims);
        let mut x = 7u64;
        for v in s.grid.data_mut() {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
            *v = ((x >> 33) % 4) as u8;
        }
        let layout = PyramidLayout::new(dims, 6);
        let p = Pyramid::build(&s, &RenderSettings::default(), layout, false);
        let mass0: f64 = p.opacity[0].iter().sum();
        for l in 0..layout.levels {
            let m: f64 = p.opacity[l as usize].iter().sum::<f64>() * 8f64.powi(l as i32);
            assert!(
                (m - mass0).abs() <= 1e-9 * mass0.max(1.0),
                "{dims} level {l}: {m} vs {mass0}"
            );
            assert_eq!(
                p.opacity[l as usize].len() as u32,
                layout.level_dims(l).element_product()
            );
        }
    }
}

#[test]
fn trilinear_sampling_has_an_empty_border() {
    // One texel of value 1: at its centre 1, at its face 1/2, half a texel out 0.
    let data = [1.0f64];
    let s = |c: DVec3| sample_level(&data, UVec3::ONE, c, 0.0, |a, w| a * w, |a, b| a + b);
    assert_eq!(s(DVec3::splat(0.5)), 1.0);
    assert_eq!(s(DVec3::new(0.0, 0.5, 0.5)), 0.5);
    assert_eq!(s(DVec3::new(1.0, 1.0, 0.5)), 0.25);
    assert_eq!(s(DVec3::new(-0.5, 0.5, 0.5)), 0.0);
    assert_eq!(s(DVec3::new(1.25, 0.5, 0.5)), 0.25);
}

#[test]
fn ao_is_exactly_one_in_an_empty_grid() {
    let s = with_grid(UVec3::new(16, 9, 12));
    let layout = PyramidLayout::new(s.grid.dims(), 0);
    let p = Pyramid::build(&s, &RenderSettings::default(), layout, true);
    for (pt, n) in [
        (DVec3::new(8.0, 4.0, 6.0), DVec3::Y),
        (DVec3::new(0.0, 0.0, 0.0), DVec3::X),
        (DVec3::new(16.0, 9.0, 12.0), -DVec3::Z),
    ] {
        for k in [1, 5, 16] {
            assert_eq!(cone::ambient_occlusion(&p, &params(), pt, n, k, 8.0), 1.0);
            assert_eq!(cone::indirect(&p, &params(), pt, n, k, 30.0), DVec3::ZERO);
        }
    }
}

#[test]
fn ao_is_near_zero_deep_inside_a_closed_cavity() {
    // A solid 32^3 block with a closed 6^3 hollow at its centre (walls 13 voxels thick);
    // points on the hollow's floor, wall and ceiling see only walls within the AO range.
    // The range (16) reaches well into the walls: coarse levels blur the hollow's edge
    // into half-empty texels, so a range that ends at the wall leaves visible light
    // (about 0.15 at range 8 with 8 cones), the dilution the method is known for.
    let mut s = with_grid(UVec3::splat(32));
    s.grid.data_mut().fill(seed_ids::SOLID);
    for z in 13..19 {
        for y in 13..19 {
            for x in 13..19 {
                s.grid.set(IVec3::new(x, y, z), 0);
            }
        }
    }
    let layout = PyramidLayout::new(s.grid.dims(), 0);
    let p = Pyramid::build(&s, &RenderSettings::default(), layout, false);
    let pts = [
        (DVec3::new(16.0, 13.0, 16.0), DVec3::Y),
        (DVec3::new(13.0, 15.0, 17.0), DVec3::X),
        (DVec3::new(18.0, 19.0, 14.0), -DVec3::Y),
    ];
    let mut worst = 0.0f64;
    for (pt, n) in pts {
        for k in [4, 8, 16] {
            let ao = cone::ambient_occlusion(&p, &params(), pt, n, k, 16.0);
            println!("{pt} {n} K={k}: AO {ao:.4}");
            worst = worst.max(ao);
        }
    }
    assert!(worst < 0.05, "AO inside a closed cavity: {worst}");
    // The same floor point with everything above the floor removed sees the sky.
    let mut s2 = with_grid(UVec3::splat(32));
    for z in 0..32 {
        for y in 0..13 {
            for x in 0..32 {
                s2.grid.set(IVec3::new(x, y, z), seed_ids::SOLID);
            }
        }
    }
    let p = Pyramid::build(&s2, &RenderSettings::default(), layout, false);
    let ao = cone::ambient_occlusion(&p, &params(), pts[0].0, DVec3::Y, 8, 8.0);
    println!("open floor: AO {ao:.3}");
    assert!(ao > 0.6, "AO on an open floor: {ao}");
}

/// Hard-shadow visibility (the baseline's min-kt shadow ray) against cone visibility for
/// shrinking apertures, over surface points of the seed scene and its three lights: the
/// mean error falls monotonically and ends small.
#[test]
fn shrinking_cones_approach_the_hard_shadow() {
    let scene = seed_scene(16).unwrap();
    let g = &scene.grid;
    let layout = PyramidLayout::new(g.dims(), 0);
    let p = Pyramid::build(&scene, &RenderSettings::default(), layout, false);
    let mut pts = Vec::new();
    for z in 0..16 {
        for y in 0..16 {
            for x in 0..16 {
                let v = IVec3::new(x, y, z);
                if g.get(v) != seed_ids::SOLID {
                    continue;
                }
                for f in voxlab::scene::FACES {
                    if g.get(v + f) == 0 {
                        pts.push((v.as_dvec3() + 0.5 + 0.5 * f.as_dvec3(), f.as_dvec3()));
                    }
                }
            }
        }
    }
    let mut stats = RayStats::default();
    let mut errors = Vec::new();
    // Below about 3 degrees every footprint inside this 16^3 grid is one voxel, so 2.5
    // and 0 give the same march: the limit is reached there, not approached further.
    for deg in [40.0f64, 20.0, 10.0, 5.0, 2.5, 0.0] {
        let th = (deg.to_radians() / 2.0).tan();
        let mut err = 0.0;
        let mut n = 0;
        for &(pt, nrm) in &pts {
            for light in &scene.lights {
                let lp = g.to_local(light.position());
                if nrm.dot(lp - pt) <= 0.0 {
                    continue;
                }
                let q = pt + 0.001 * nrm;
                let hard =
                    voxlab::cpu::shadow_min_kt(&scene, g.to_world(q), light.position(), &mut stats);
                let soft = cone::shadow_visibility(&p, &params(), pt, nrm, lp, th);
                err += (soft - hard).abs();
                n += 1;
            }
        }
        errors.push((deg, err / n as f64));
    }
    println!("aperture (deg), mean |cone - hard|: {errors:?}");
    for w in errors[..5].windows(2) {
        assert!(w[1].1 < w[0].1, "error did not fall: {errors:?}");
    }
    assert!(errors[5].1 <= errors[4].1, "{errors:?}");
    assert!(errors.last().unwrap().1 < 0.15, "{errors:?}");
}
