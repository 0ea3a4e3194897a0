//! Counter-based random numbers for stochastic light sampling, computed identically by
//! the WGSL kernel (`shaders/sampling.wgsl`) and the CPU reference, so the two draw the
//! same samples and their stochastic images agree to float error.
//!
//! Each number is a pure function of (seed, pixel, frame, light, dimension): no state,
//! no order dependence, any pixel can be recomputed alone.

/// PCG hash (M. Jarzynski and M. Olano, "Hash Functions for GPU Rendering", JCGT 9(3),
/// 2020): a 32-bit permutation with good avalanche for one-word input.
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Hash of the key, one `pcg` round per word so that every word changes the result.
pub fn hash(seed: u32, pixel: u32, frame: u32, light: u32, dimension: u32) -> u32 {
    let mut h = pcg(seed ^ 0x9e37_79b9);
    for word in [pixel, frame, light, dimension] {
        h = pcg(h ^ word);
    }
    h
}

/// The top 24 bits as a float in [0, 1): exact in f32 and f64 alike.
pub fn unit_float(h: u32) -> f64 {
    (h >> 8) as f64 * (1.0 / 16_777_216.0)
}

/// Van der Corput radical inverse in base 2 (bit reversal), 24 bits like `unit_float`.
pub fn radical_inverse2(k: u32) -> f64 {
    unit_float(k.reverse_bits())
}

/// Sample `k` of `n` on the unit square for one (pixel, frame, light): the Hammersley
/// point `(k / n, radical_inverse2(k))` shifted toroidally by a random offset
/// (Cranley-Patterson rotation). The set is stratified (one point per 1/n column, a
/// (0, m, 2)-net when n is a power of two) and each point is uniform, so the estimate is
/// unbiased; frames draw independent offsets.
pub fn light_sample(seed: u32, pixel: u32, frame: u32, light: u32, k: u32, n: u32) -> (f64, f64) {
    let du = unit_float(hash(seed, pixel, frame, light, 0));
    let dv = unit_float(hash(seed, pixel, frame, light, 1));
    let fract = |x: f64| x - x.floor();
    (
        fract(k as f64 / n as f64 + du),
        fract(radical_inverse2(k) + dv),
    )
}

/// The `light` word of the pixel samples' hash: no light has this index.
pub(crate) const PIXEL_STREAM: u32 = u32::MAX;

/// The R2 sequence's steps (M. Roberts, "The Unreasonable Effectiveness of
/// Quasirandom Sequences", 2018: `1/g` and `1/g^2`, g the plastic number) in 32-bit fixed
/// point, so the kernel's u32 arithmetic gives the CPU's points bit for bit.
const R2_STEPS: [u32; 2] = [3_242_174_889, 2_447_445_414];

/// Frame `frame`'s point in the unit square for one pixel: the R2 sequence over frames
/// (low discrepancy however many frames there are), rotated per pixel by a random
/// offset (Cranley-Patterson), so pixels draw independent sequences.
pub(crate) fn pixel_sample(seed: u32, pixel: u32, frame: u32) -> (f64, f64) {
    let at = |d: usize| {
        hash(seed, pixel, 0, PIXEL_STREAM, d as u32).wrapping_add(frame.wrapping_mul(R2_STEPS[d]))
    };
    (unit_float(at(0)), unit_float(at(1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg_matches_the_published_reference_values() {
        // Values of the JCGT paper's pcg_hash, computed by hand from its definition.
        assert_eq!(pcg(0), 129_708_002);
        assert_ne!(pcg(1), pcg(0));
    }

    #[test]
    fn samples_are_uniform_and_stratified() {
        let n = 16;
        let mut mean = (0.0, 0.0);
        let mut columns = [0usize; 16];
        for pixel in 0..4096u32 {
            for k in 0..n {
                let (s, t) = light_sample(7, pixel, 0, 0, k, n);
                assert!((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t));
                mean.0 += s;
                mean.1 += t;
                if pixel == 0 {
                    columns[(s * n as f64) as usize] += 1;
                }
            }
        }
        let count = 4096.0 * n as f64;
        assert!((mean.0 / count - 0.5).abs() < 0.01 && (mean.1 / count - 0.5).abs() < 0.01);
        assert!(
            columns.iter().all(|&c| c == 1),
            "one sample per column: {columns:?}"
        );
    }
}

/// What the light samples of one primary ray depend on (see `crate::sampling`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SampleKey {
    /// `row * width + column`.
    pub pixel: u32,
    /// The accumulation frame, `0..spp`.
    pub frame: u32,
}
