// Transmittance `beer-lambert` (src/technique/beer_lambert.rs, whose f64 twin it is):
// T = exp(-sum sigma_m len_m) per RGB channel, len_m the exact length of the segment in
// each material; the optical depth is summed and exponentiated once, so a huge depth
// gives exactly 0; kt = 0 is opaque; void absorbs nothing. The interface is
// transmittance_min_kt.wgsl's.
#define_import_path voxlab::transmittance

#import voxlab::bindings::materials

// The optical depth so far, the current material's absorption and where it began.
struct Absorb {
    depth: vec3<f32>,
    sigma: vec3<f32>,
    t: f32,
}

fn absorb_start() -> Absorb {
    return Absorb(vec3<f32>(0.0), vec3<f32>(0.0), 0.0);
}

fn absorb_pass(w: ptr<function, Absorb>, t: f32, m: u32) -> bool {
    (*w).depth += (*w).sigma * max(t - (*w).t, 0.0);
    (*w).t = t;
    if m == 0u {
        (*w).sigma = vec3<f32>(0.0);
        return false;
    }
    let mat = materials[m];
    if mat.kt <= 0.0 {
        return true;
    }
    (*w).sigma = vec3<f32>(mat.sigma_r, mat.sigma_g, mat.sigma_b);
    return false;
}

fn absorb_result(w: Absorb, t_end: f32) -> vec3<f32> {
    return exp(-(w.depth + w.sigma * max(t_end - w.t, 0.0)));
}
