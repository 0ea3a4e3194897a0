// Shadow visibility, `beer-lambert` transmittance (BEER_LAMBERT): T = exp(-sum sigma_m
// len_m) per RGB channel, with len_m the exact length of the segment inside each voxel
// from the DDA (no fixed-step marching). The optical depth is summed first and
// exponentiated once, so a huge depth gives exactly 0 and never a negative or NaN value;
// a material with kt = 0 is opaque. As crate::cpu::shadow_beer_lambert; the walk is
// shadow.wgsl's (same voxels, same limits). Contract: "Shading a hit", shadow ray.
#define_import_path voxlab::shadow_beer_lambert

#import voxlab::bindings::{materials, voxel_material, voxel_inside}
#import voxlab::traversal::{enter, dda_init, dda_axis, dda_advance, max_steps}

// Absorption per voxel unit; void's entry is uploaded too (zero unless it transmits
// less than fully, which the palette never allows).
fn sigma_of(m: u32) -> vec3<f32> {
    let mat = materials[m];
    return vec3<f32>(mat.sigma_r, mat.sigma_g, mat.sigma_b);
}

fn opaque(m: u32) -> bool {
    return materials[m].kt <= 0.0;
}

// Transmittance of the segment from q along d (unit) of length len > 0.
fn transmittance_rgb(q: vec3<f32>, d: vec3<f32>, len: f32) -> vec3<f32> {
    let e = enter(q, d);
    if !e.valid || !(e.t < len) {
        return vec3<f32>(1.0);
    }
    var m = voxel_material(e.voxel);
    if opaque(m) {
        return vec3<f32>(0.0);
    }
    // The voxel being crossed: its absorption and where the segment entered it.
    var sigma = sigma_of(m);
    var t0 = e.t;
    var t_end = t0;
    var depth = vec3<f32>(0.0);
    var s = dda_init(q, d, e.voxel);
    let n = max_steps();
    for (var i = 0u; i < n; i++) {
        let a = dda_axis(s.t_max);
        let t = s.t_max[a];
        if !(t < len) {
            t_end = len;
            break;
        }
        dda_advance(&s, a);
        if !voxel_inside(s.voxel) {
            t_end = t;
            break;
        }
        depth += sigma * (t - t0);
        m = voxel_material(s.voxel);
        if opaque(m) {
            return vec3<f32>(0.0);
        }
        sigma = sigma_of(m);
        t0 = t;
    }
    depth += sigma * max(min(t_end, len) - t0, 0.0);
    return exp(-depth);
}
