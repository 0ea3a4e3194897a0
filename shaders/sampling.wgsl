// Counter-based random numbers for stochastic light sampling: src/sampling.rs bit for
// bit (u32 arithmetic wraps in WGSL as wrapping_* does in Rust), so the kernel and the
// CPU reference draw the same samples. Contract: "Area lights", sampling.
#define_import_path voxlab::sampling

// What the samples of one primary ray depend on (crate::cpu::SampleKey).
struct SampleKey {
    // row * width + column
    pixel: u32,
    // accumulation frame, 0..spp
    frame: u32,
}

// PCG hash (Jarzynski and Olano, JCGT 9(3), 2020).
fn pcg(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// One pcg round per word of (seed, pixel, frame, light, dimension).
fn hash(seed: u32, pixel: u32, frame: u32, light: u32, dimension: u32) -> u32 {
    var h = pcg(seed ^ 0x9e3779b9u);
    h = pcg(h ^ pixel);
    h = pcg(h ^ frame);
    h = pcg(h ^ light);
    h = pcg(h ^ dimension);
    return h;
}

// The top 24 bits as a float in [0, 1): exact in f32.
fn unit_float(h: u32) -> f32 {
    return f32(h >> 8u) * (1.0 / 16777216.0);
}

// Van der Corput radical inverse in base 2, 24 bits.
fn radical_inverse2(k: u32) -> f32 {
    return unit_float(reverseBits(k));
}

// Sample k of n for (seed, key, light): the Hammersley point (k / n, radical_inverse2(k))
// shifted toroidally by a per-(pixel, frame, light) offset (Cranley-Patterson rotation).
fn light_sample(seed: u32, key: SampleKey, light: u32, k: u32, n: u32) -> vec2<f32> {
    let du = unit_float(hash(seed, key.pixel, key.frame, light, 0u));
    let dv = unit_float(hash(seed, key.pixel, key.frame, light, 1u));
    return fract(vec2<f32>(f32(k) / f32(n) + du, radical_inverse2(k) + dv));
}

// crate::sampling::PIXEL_STREAM and R2_STEPS.
const PIXEL_STREAM: u32 = 0xffffffffu;
const R2_STEP_X: u32 = 3242174889u;
const R2_STEP_Y: u32 = 2447445414u;

// crate::sampling::pixel_sample: frame `frame`'s point of the R2 sequence, rotated per
// pixel, bit for bit (u32 arithmetic wraps).
fn pixel_sample(seed: u32, pixel: u32, frame: u32) -> vec2<f32> {
    let x = hash(seed, pixel, 0u, PIXEL_STREAM, 0u) + frame * R2_STEP_X;
    let y = hash(seed, pixel, 0u, PIXEL_STREAM, 1u) + frame * R2_STEP_Y;
    return vec2<f32>(unit_float(x), unit_float(y));
}
