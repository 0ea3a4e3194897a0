// Cone tracing through the pre-filtered pyramids (C. Crassin et al., "Interactive
// Indirect Illumination Using Voxel Cone Tracing", CGF 30(7) 2011, section 4). The f64
// reference is src/cpu/cone.rs; the two must change together. Grid-local units.
//
// Sampling: level l of a pyramid is mip l of a texture whose base is padded with empty
// voxels to a multiple of 2^(levels-1) (`padded`), so uv = x / padded addresses the same
// point at every mip. Texels outside the texture count as empty: textureSampleLevel with
// clamp-to-edge, times a per-axis border weight clamp(min(c + 1/2, n + 1/2 - c), 0, 1)
// (c the texel coordinate, n the mip's size). Within half a texel of the edge the
// clamped filter returns the edge texel where zero-border filtering returns it times
// that weight, and the factor is constant across the other two axes, so the product is
// exactly trilinear filtering with a zero border. Levels are sampled at integer lods
// and blended here (the border weight differs per level): quadrilinear filtering.
//
// Shader defs: RADIANCE_PYRAMID (the radiance pyramid and gathering). The techniques
// built on it call in from their own files: the cone shadow model
// (shaders/shadow_cone.wgsl, `shadow_visibility` with `light_radius`) and the lighting
// terms (shaders/term_*.wgsl, `ambient_occlusion`, `indirect_light`).
#define_import_path voxlab::cone

struct ConeParams {
    // The textures' level-0 size (the grid's dims padded), voxels.
    padded: vec3<f32>,
    levels: u32,
    // The grid's dims.
    dims: vec3<f32>,
    // Step length in footprints.
    step_factor: f32,
    // Apex offset along the normal, voxels.
    start_offset: f32,
    ao_cones: u32,
    // AO cones' range, voxels.
    ao_range: f32,
    // tan(theta / 2) of the hemisphere cones.
    hemi_tan_half: f32,
    indirect_strength: f32,
    // Indirect cones' range, voxels.
    indirect_range: f32,
    // tan(theta / 2) of point lights' shadow cones.
    point_tan_half: f32,
    // Always 0: the loops here leave on their own exit condition or this (loop_guard).
    loop_guard: u32,
}

struct ConeResult {
    occlusion: f32,
    radiance: vec3<f32>,
}

// Set when a loop here ended without meeting any of its own exit conditions: the
// software driver's loop limit (shaders/counters.wgsl, loop_cut, which the tracer's
// entry point calls for it; this module is also composed without the counters).
var<private> cone_loop_cut: bool;

// Always false, and no compiler can know it: each loop here leaves with `break if <its
// exit> || loop_guard()`, so the check after it is not dead code to the driver's
// optimiser (shaders/counters.wgsl, loop_guard, whose uniform this module, composed
// without the tracer's bindings too, does not see).
fn loop_guard() -> bool {
    return cone.loop_guard != 0u;
}

const OCCLUSION_CUTOFF: f32 = 0.99;
const MAX_CONE_STEPS: u32 = 4096u;
const GOLDEN_ANGLE: f32 = 2.399963229728653;

@group(1) @binding(0) var<uniform> cone: ConeParams;
@group(1) @binding(1) var opacity_tex: texture_3d<f32>;
@group(1) @binding(2) var radiance_tex: texture_3d<f32>;
@group(1) @binding(3) var pyramid_sampler: sampler;
// Each light's radius in voxels (0 for point lights; a rectangle's half-diagonal).
@group(1) @binding(4) var<storage, read> light_radius: array<f32>;

fn border_weight(c: vec3<f32>, n: vec3<f32>) -> f32 {
    let w = clamp(min(c + 0.5, n + 0.5 - c), vec3<f32>(0.0), vec3<f32>(1.0));
    return w.x * w.y * w.z;
}

fn opacity_level(x: vec3<f32>, l: u32) -> f32 {
    let s = f32(1u << l);
    let a = textureSampleLevel(opacity_tex, pyramid_sampler, x / cone.padded, f32(l)).r;
    return a * border_weight(x / s, cone.padded / s);
}

fn opacity_at(x: vec3<f32>, lod: f32) -> f32 {
    let lc = clamp(lod, 0.0, f32(cone.levels - 1u));
    let l0 = floor(lc);
    let f = lc - l0;
    let a = opacity_level(x, u32(l0));
    if f == 0.0 {
        return a;
    }
    return a + (opacity_level(x, u32(l0) + 1u) - a) * f;
}

#ifdef RADIANCE_PYRAMID
fn radiance_level(x: vec3<f32>, l: u32) -> vec4<f32> {
    let s = f32(1u << l);
    let c = textureSampleLevel(radiance_tex, pyramid_sampler, x / cone.padded, f32(l));
    return c * border_weight(x / s, cone.padded / s);
}

fn radiance_at(x: vec3<f32>, lod: f32) -> vec4<f32> {
    let lc = clamp(lod, 0.0, f32(cone.levels - 1u));
    let l0 = floor(lc);
    let f = lc - l0;
    let a = radiance_level(x, u32(l0));
    if f == 0.0 {
        return a;
    }
    return a + (radiance_level(x, u32(l0) + 1u) - a) * f;
}
#endif

// Every later sample is empty: beyond the grid on some axis by more than any footprint
// the pyramid resolves, and moving away.
fn leaving(x: vec3<f32>, w: vec3<f32>) -> bool {
    let m = f32(1u << cone.levels);
    let lo = (x < vec3<f32>(-m)) & (w <= vec3<f32>(0.0));
    let hi = (x > cone.dims + m) & (w >= vec3<f32>(0.0));
    return any(lo | hi);
}

// A cone march in progress: the distance reached, the steps taken, the result so far.
struct March {
    t: f32,
    i: u32,
    r: ConeResult,
}

// One step of `march`: true when the march is over (MAX_CONE_STEPS taken, past
// max_dist, leaving the pyramid, or opaque).
fn march_step(m: ptr<function, March>, o: vec3<f32>, w: vec3<f32>, tan_half: f32, max_dist: f32, gather: bool) -> bool {
    if (*m).i >= MAX_CONE_STEPS {
        return true;
    }
    (*m).i += 1u;
    let t = (*m).t;
    if !(t < max_dist) {
        return true;
    }
    let k = cone.step_factor;
    let d = max(2.0 * t * tan_half, 1.0);
    let x = o + t * w;
    if leaving(x, w) {
        return true;
    }
    let lod = log2(d);
    var a = 0.0;
    var c = vec3<f32>(0.0);
#ifdef RADIANCE_PYRAMID
    if gather {
        let s = radiance_at(x, lod);
        a = s.w;
        c = s.xyz;
    } else {
        a = opacity_at(x, lod);
    }
#else
    a = opacity_at(x, lod);
#endif
    a = clamp(a, 0.0, 1.0);
    // Opacity of a slab step_factor texels thick.
    let ac = 1.0 - pow(1.0 - a, k);
    if gather {
        var ratio = k;
        if a > 1.0e-4 {
            ratio = ac / a;
        }
        (*m).r.radiance += (1.0 - (*m).r.occlusion) * c * ratio;
    }
    (*m).r.occlusion += (1.0 - (*m).r.occlusion) * ac;
    if (*m).r.occlusion >= OCCLUSION_CUTOFF {
        (*m).r.occlusion = 1.0;
        return true;
    }
    (*m).t = t + k * d;
    return false;
}

// One cone from apex o along unit w, tan(theta/2) = tan_half, up to max_dist; gathers
// radiance when `gather` (RADIANCE_PYRAMID only). Steps as src/cpu/cone.rs `march`, four per
// loop iteration: the software driver's loop limit counts back edges, not work
// (shaders/counters.wgsl).
fn march(o: vec3<f32>, w: vec3<f32>, tan_half: f32, max_dist: f32, gather: bool) -> ConeResult {
    var m: March;
    m.t = 0.0;
    m.i = 0u;
    m.r.occlusion = 0.0;
    m.r.radiance = vec3<f32>(0.0);
    var done = false;
    // Exit tested at the bottom (shaders/counters.wgsl).
    loop {
        done = march_step(&m, o, w, tan_half, max_dist, gather);
        if !done { done = march_step(&m, o, w, tan_half, max_dist, gather); }
        if !done { done = march_step(&m, o, w, tan_half, max_dist, gather); }
        if !done { done = march_step(&m, o, w, tan_half, max_dist, gather); }
        continuing {
            break if done || loop_guard();
        }
    }
    // Every step count ends the march (MAX_CONE_STEPS), so the loop ends with `done`;
    // any other way out is the driver's loop limit (shaders/counters.wgsl).
    if !done {
        cone_loop_cut = true;
    }
    return m.r;
}

fn tangent_frame(n: vec3<f32>) -> mat2x3<f32> {
    var helper = vec3<f32>(1.0, 0.0, 0.0);
    if abs(n.x) >= 0.9 {
        helper = vec3<f32>(0.0, 1.0, 0.0);
    }
    let t1 = normalize(cross(helper, n));
    return mat2x3<f32>(t1, cross(n, t1));
}

// Cosine-weighted hemisphere direction k of count (Malley's method on a golden spiral).
fn hemisphere_dir(n: vec3<f32>, k: u32, count: u32) -> vec3<f32> {
    let f = tangent_frame(n);
    let r = sqrt((f32(k) + 0.5) / f32(count));
    let phi = f32(k) * GOLDEN_ANGLE;
    let z = sqrt(max(1.0 - r * r, 0.0));
    return normalize(r * cos(phi) * f[0] + r * sin(phi) * f[1] + z * n);
}

// Mean visibility of the AO cones at surface point p with normal n.
fn ambient_occlusion(p: vec3<f32>, n: vec3<f32>) -> f32 {
    let o = p + cone.start_offset * n;
    var sum = 0.0;
    var k = 0u;
    // ao_cones >= 1 (src/technique/cones.rs): the exit is tested at the bottom.
    loop {
        let w = hemisphere_dir(n, k, cone.ao_cones);
        sum += 1.0 - march(o, w, cone.hemi_tan_half, cone.ao_range, false).occlusion;
        continuing {
            k++;
            break if k >= cone.ao_cones || loop_guard();
        }
    }
    if k < cone.ao_cones {
        cone_loop_cut = true;
    }
    return sum / f32(cone.ao_cones);
}

#ifdef RADIANCE_PYRAMID
// Mean radiance gathered by the hemisphere cones at p.
fn indirect_light(p: vec3<f32>, n: vec3<f32>) -> vec3<f32> {
    let o = p + cone.start_offset * n;
    var sum = vec3<f32>(0.0);
    var k = 0u;
    // ao_cones >= 1 (src/technique/cones.rs): the exit is tested at the bottom.
    loop {
        let w = hemisphere_dir(n, k, cone.ao_cones);
        sum += march(o, w, cone.hemi_tan_half, cone.indirect_range, true).radiance;
        continuing {
            k++;
            break if k >= cone.ao_cones || loop_guard();
        }
    }
    if k < cone.ao_cones {
        cone_loop_cut = true;
    }
    return sum / f32(cone.ao_cones);
}
#endif

// Visibility 1 - occ of a cone from p (normal n) to the light at l with tan_half.
fn shadow_visibility(p: vec3<f32>, n: vec3<f32>, l: vec3<f32>, tan_half: f32) -> f32 {
    let o = p + cone.start_offset * n;
    let to = l - o;
    let len = length(to);
    if len == 0.0 {
        return 1.0;
    }
    return 1.0 - march(o, to / len, tan_half, len, false).occlusion;
}
