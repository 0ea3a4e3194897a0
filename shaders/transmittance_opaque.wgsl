// Transmittance `opaque` (src/technique/opaque.rs, whose f32 twin it is): any non-void
// material stops a shadow segment; void transmits fully. The interface is
// transmittance_min_kt.wgsl's.
#define_import_path voxlab::transmittance

struct Absorb {
    clear: f32,
}

fn absorb_start() -> Absorb {
    return Absorb(1.0);
}

fn absorb_pass(w: ptr<function, Absorb>, t: f32, m: u32) -> bool {
    if m != 0u {
        (*w).clear = 0.0;
    }
    return m != 0u;
}

fn absorb_result(w: Absorb, t_end: f32) -> vec3<f32> {
    return vec3<f32>(w.clear);
}
