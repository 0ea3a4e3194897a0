//! Beer-Lambert transmittance on the CPU reference (the oracle): one voxel transmits kt
//! (the min-kt value), n voxels kt^n, segment lengths are exact per voxel, and extreme
//! optical depths are exact and finite.

use glam::{DVec3, IVec3, UVec3};
use voxlab::RayStats;
use voxlab::cpu::{shadow_beer_lambert, shadow_min_kt};
use voxlab::scene::{Grid, Material, Scene, seed_scene};

const KT: f64 = 0.6;

/// An 8x12x8 grid of voxels of `voxel_size` at a non-zero origin, void but for a
/// horizontal slab of `thickness` voxels (y in [4, 4 + thickness)) of a material with
/// refractivity KT and absorption `sigma` (None: the default, one voxel transmits KT).
fn slab(thickness: i32, voxel_size: f64, sigma: Option<DVec3>) -> Scene {
    let mut scene = seed_scene(1).unwrap();
    let origin = DVec3::new(-3.0, 1.5, 2.0);
    scene.grid = Grid::new(UVec3::new(8, 12, 8), voxel_size, origin).unwrap();
    scene.materials.push(Material {
        name: "slab".into(),
        kt: KT,
        sigma,
        ..scene.materials[1].clone()
    });
    let id = (scene.materials.len() - 1) as u8;
    for x in 0..8 {
        for z in 0..8 {
            for y in 4..4 + thickness {
                scene.grid.set(IVec3::new(x, y, z), id);
            }
        }
    }
    scene
}

/// A shadow segment perpendicular to the slab, through it, from below to above (world).
fn vertical(scene: &Scene) -> (DVec3, DVec3) {
    let g = &scene.grid;
    let q = g.to_world(DVec3::new(3.3, 0.7, 4.6));
    let light = g.to_world(DVec3::new(3.3, 11.5, 4.6));
    (q, light)
}

#[test]
fn slabs_of_one_two_and_four_voxels_transmit_kt_to_the_thickness() {
    for voxel_size in [1.0, 0.25, 3.0] {
        for t in [1, 2, 4] {
            let scene = slab(t, voxel_size, None);
            let (q, light) = vertical(&scene);
            let mut stats = RayStats::default();
            let bl = shadow_beer_lambert(&scene, q, light, &mut stats);
            let mk = shadow_min_kt(&scene, q, light, &mut stats);
            let want = KT.powi(t);
            for c in 0..3 {
                assert!(
                    (bl[c] - want).abs() < 1e-6,
                    "voxel {voxel_size}, {t} voxels: {bl} vs kt^{t} = {want}"
                );
            }
            // min-kt does not see thickness.
            assert_eq!(mk, KT);
            if t == 1 {
                // One voxel: exactly what min-kt gives (to float error of exp(ln kt)).
                assert!(
                    (bl - DVec3::splat(mk)).abs().max_element() < 1e-12,
                    "{bl} vs {mk}"
                );
            }
            // The segment also crosses void above and below: nothing absorbs there.
            assert!(stats.voxel_steps > 0);
        }
    }
}

/// Exact per-voxel lengths: an oblique segment through a slab of thickness t crosses
/// t / cos(theta) of it, whatever voxels it zig-zags through.
#[test]
fn oblique_segments_use_exact_lengths() {
    let sigma = DVec3::new(0.3, 0.1, 0.05);
    for t in [1, 3] {
        let scene = slab(t, 0.5, Some(sigma));
        let g = &scene.grid;
        let q = g.to_world(DVec3::new(0.4, 0.3, 1.1));
        let light = g.to_world(DVec3::new(7.1, 11.2, 5.9));
        let d = (light - q).normalize();
        let len = t as f64 * 0.5 / d.y; // world length inside the slab
        let want = (-sigma * len).exp();
        let got = shadow_beer_lambert(&scene, q, light, &mut RayStats::default());
        assert!((got - want).abs().max_element() < 1e-12, "{got} vs {want}");
    }
}

/// Optical depth 1e4 gives exactly 0; 1e-6 gives 1 - 1e-6; opaque (kt = 0) is 0 under
/// every sigma; never negative or NaN.
#[test]
fn extreme_optical_depths_are_exact_and_finite() {
    // One voxel of width 1 crossed perpendicularly: depth = sigma * 1.
    for (depth, want) in [(1e4, 0.0), (1e-6, 1.0 - 1e-6), (0.0, 1.0), (1e300, 0.0)] {
        let scene = slab(1, 1.0, Some(DVec3::splat(depth)));
        let (q, light) = vertical(&scene);
        let got = shadow_beer_lambert(&scene, q, light, &mut RayStats::default());
        for c in 0..3 {
            assert!(got[c].is_finite() && got[c] >= 0.0, "depth {depth}: {got}");
            if want == 0.0 {
                assert_eq!(got[c], 0.0, "depth {depth}");
            } else {
                assert!((got[c] - want).abs() < 1e-12, "depth {depth}: {got}");
            }
        }
    }
    let mut scene = slab(2, 1.0, Some(DVec3::ZERO));
    let last = scene.materials.len() - 1;
    scene.materials[last].kt = 0.0;
    let (q, light) = vertical(&scene);
    assert_eq!(
        shadow_beer_lambert(&scene, q, light, &mut RayStats::default()),
        DVec3::ZERO
    );
    // A segment of length 0 is unshadowed.
    assert_eq!(
        shadow_beer_lambert(&scene, q, q, &mut RayStats::default()),
        DVec3::ONE
    );
}

/// A segment that starts or ends inside the slab counts only its part inside.
#[test]
fn segments_ending_inside_the_slab_count_their_part() {
    let sigma = DVec3::splat(0.7);
    let scene = slab(4, 1.0, Some(sigma));
    let g = &scene.grid;
    // From y = 0.7 to y = 5.25: 1.25 voxels inside the slab (y in [4, 5.25]).
    let q = g.to_world(DVec3::new(3.3, 0.7, 4.6));
    let light = g.to_world(DVec3::new(3.3, 5.25, 4.6));
    let got = shadow_beer_lambert(&scene, q, light, &mut RayStats::default());
    let want = (-sigma * 1.25).exp();
    assert!((got - want).abs().max_element() < 1e-12, "{got} vs {want}");
    // Starting inside: from y = 6.5 up, 1.5 voxels inside.
    let q = g.to_world(DVec3::new(3.3, 6.5, 4.6));
    let light = g.to_world(DVec3::new(3.3, 11.0, 4.6));
    let got = shadow_beer_lambert(&scene, q, light, &mut RayStats::default());
    let want = (-sigma * 1.5).exp();
    assert!((got - want).abs().max_element() < 1e-12, "{got} vs {want}");
}
