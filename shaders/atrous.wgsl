// The edge-avoiding a-trous passes on the device (src/technique/atrous.rs, whose module
// documentation is the contract; this is its f32 twin), over whatever signal the
// reconstruction put in the colour buffer: `atrous` the frames' visibility
// (shaders/reconstruction_atrous.wgsl), `svgf` its temporal accumulation
// (shaders/reconstruction_svgf.wgsl). `prepare_signal` finds each pixel's depth gradient
// and variance, then `iterate_signal` runs once per pass.
#define_import_path voxlab::atrous

#import voxlab::layers::{fp, guide, color_in, color_out, aux, setting, luminance, pixel_index, inside, filtered_at}

// As atrous::TEMPORAL_FRAMES, EPS_DEPTH, EPS_LUMINANCE and VARIANCE_FLOOR.
const TEMPORAL_FRAMES: f32 = 4.0;
const EPS_DEPTH: f32 = 1e-6;
const EPS_LUMINANCE: f32 = 1e-10;
const VARIANCE_FLOOR: f32 = 1e-5;

// atrous::moments_variance: f32's rounding of equal values' moments counts as zero.
fn moments_variance(m1: f32, m2: f32) -> f32 {
    let v = m2 - m1 * m1;
    return select(0.0, v, v > VARIANCE_FLOOR * m2);
}

struct Guide {
    normal: vec3<f32>,
    depth: f32,
    material: f32,
}

fn guide_at(i: u32) -> Guide {
    let a = guide[2u * i];
    var g: Guide;
    g.normal = a.xyz;
    g.depth = a.w;
    g.material = guide[2u * i + 1u].z;
    return g;
}

// The edge stops of geometry between p (depth gradient `gradient`) and q = p + offset:
// w_z w_n w_m.
fn geometric(p: Guide, gradient: vec2<f32>, q: Guide, offset: vec2<f32>) -> f32 {
    if p.material != q.material {
        return 0.0;
    }
    let along = dot(gradient, offset);
    let wz = exp(-abs(p.depth - q.depth) / max(setting(2u) * abs(along) + EPS_DEPTH * abs(fp.depth_origin + p.depth), 1e-30));
    // pow(0, 0) is undefined in WGSL; the reference's max(0, n.n')^0 is 1.
    var wn = 1.0;
    if setting(1u) > 0.0 {
        wn = pow(max(dot(p.normal, q.normal), 0.0), setting(1u));
    }
    return wz * wn;
}

// The smaller one-sided difference of depth towards the read neighbours along (dx, dy)
// (the forward one on a tie, as the reference), 0 where none is read.
fn slope(x: i32, y: i32, dx: i32, dy: i32, depth: f32) -> f32 {
    var best = 0.0;
    var found = false;
    if filtered_at(x + dx, y + dy) {
        best = guide[2u * pixel_index(x + dx, y + dy)].w - depth;
        found = true;
    }
    if filtered_at(x - dx, y - dy) {
        let d = -(guide[2u * pixel_index(x - dx, y - dy)].w - depth);
        if !found || abs(d) < abs(best) {
            best = d;
        }
    }
    return best;
}

// Pixel i's depth gradient (into `aux`) and its input's variance (into the colour's w):
// `m` holds the temporal moments (mean, mean square, frames whose mean the input is),
// read when `m.z` reaches TEMPORAL_FRAMES; `samples` divides the spatial estimate.
fn prepare_signal(x: i32, y: i32, i: u32, m: vec3<f32>, samples: f32) {
    let c = color_in[i].xyz;
    if !filtered_at(x, y) {
        aux[i] = vec2<f32>(0.0);
        color_out[i] = vec4<f32>(c, 0.0);
        return;
    }
    let p = guide_at(i);
    let gradient = vec2<f32>(slope(x, y, 1, 0, p.depth), slope(x, y, 0, 1, p.depth));
    aux[i] = gradient;
    var variance = 0.0;
    if m.z >= TEMPORAL_FRAMES {
        variance = moments_variance(m.x, m.y) / m.z;
    } else {
        var sw = 0.0;
        var s1 = 0.0;
        var s2 = 0.0;
        for (var dy = -3; dy <= 3; dy++) {
            for (var dx = -3; dx <= 3; dx++) {
                if !filtered_at(x + dx, y + dy) {
                    continue;
                }
                let j = pixel_index(x + dx, y + dy);
                let w = geometric(p, gradient, guide_at(j), vec2<f32>(f32(dx), f32(dy)));
                let l = luminance(color_in[j].xyz);
                sw += w;
                s1 += w * l;
                s2 += w * l * l;
            }
        }
        variance = moments_variance(s1 / sw, s2 / sw) / samples;
    }
    color_out[i] = vec4<f32>(c, variance);
}

// The B3 spline's taps (1, 4, 6, 4, 1) / 16 at k = 0..4.
fn b3(k: i32) -> f32 {
    let d = abs(k - 2);
    return select(select(1.0 / 16.0, 1.0 / 4.0, d == 1), 3.0 / 8.0, d == 0);
}

// One a-trous pass at pixel i, reading pixels `step` apart.
fn iterate_signal(x: i32, y: i32, i: u32, step: i32) {
    if !filtered_at(x, y) {
        color_out[i] = color_in[i];
        return;
    }
    // G(var): the variance's 3x3 Gaussian over the pixels read.
    var kw = 0.0;
    var kv = 0.0;
    for (var dy = -1; dy <= 1; dy++) {
        for (var dx = -1; dx <= 1; dx++) {
            if filtered_at(x + dx, y + dy) {
                let k = (0.5 - 0.25 * f32(abs(dx))) * (0.5 - 0.25 * f32(abs(dy)));
                kw += k;
                kv += k * color_in[pixel_index(x + dx, y + dy)].w;
            }
        }
    }
    let p = guide_at(i);
    let gradient = aux[i];
    let lp = luminance(color_in[i].xyz);
    let spread = setting(3u) * sqrt(kv / kw) + EPS_LUMINANCE;
    var sw = 0.0;
    var sc = vec3<f32>(0.0);
    var sv = 0.0;
    for (var ty = 0; ty < 5; ty++) {
        for (var tx = 0; tx < 5; tx++) {
            let ox = (tx - 2) * step;
            let oy = (ty - 2) * step;
            if !filtered_at(x + ox, y + oy) {
                continue;
            }
            let j = pixel_index(x + ox, y + oy);
            let q = color_in[j];
            let wl = exp(-abs(lp - luminance(q.xyz)) / spread);
            let w = b3(tx) * b3(ty) * geometric(p, gradient, guide_at(j), vec2<f32>(f32(ox), f32(oy))) * wl;
            sw += w;
            sc += w * q.xyz;
            sv += w * w * q.w;
        }
    }
    color_out[i] = vec4<f32>(sc / sw, sv / (sw * sw));
}
