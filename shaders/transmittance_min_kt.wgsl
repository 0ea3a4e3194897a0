// Transmittance `min-kt` (src/technique/min_kt.rs, whose f64 twin it is): the smallest
// kt of the materials a shadow segment passes through; void transmits fully.
// The interface every transmittance module gives the shadow walks (shadow.wgsl,
// shadow_surface.wgsl): a state, what passing into a material at distance t does to it
// (true once nothing more can pass), and the RGB transmittance when the segment ends.
#define_import_path voxlab::transmittance

#import voxlab::bindings::materials

struct Absorb {
    kt: f32,
}

fn absorb_start() -> Absorb {
    return Absorb(1.0);
}

fn absorb_pass(w: ptr<function, Absorb>, t: f32, m: u32) -> bool {
    if m != 0u {
        (*w).kt = min((*w).kt, materials[m].kt);
    }
    return (*w).kt <= 0.0;
}

fn absorb_result(w: Absorb, t_end: f32) -> vec3<f32> {
    return vec3<f32>(w.kt);
}
