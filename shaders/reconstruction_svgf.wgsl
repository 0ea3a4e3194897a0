// Reconstruction `svgf` on the device (src/technique/svgf.rs is the contract; this is its
// f32 twin): `prepare_pixel` accumulates each pixel's visibility onto its reprojected
// history and writes the new history, then the a-trous passes of shaders/atrous.wgsl
// run over the accumulated signal (iterate pass 0 prepares them, passes 1.. filter).
#define_import_path voxlab::reconstruction

#import voxlab::layers::{fp, guide, color_in, color_out, setting, luminance, filtered_at, history_in, history_out}
#import voxlab::atrous::{prepare_signal, iterate_signal}

// As svgf::MIN_HISTORY_WEIGHT.
const MIN_HISTORY_WEIGHT: f32 = 0.01;

// Pixel (x, y)'s ray through its centre in its camera's basis (forward, right, up),
// unnormalised (crate::scene::CameraFrame::primary_dir). The reprojection works in
// the cameras' bases, their offset and change of basis given in f64 by the host
// (src/gpu/reconstruct.rs, reprojection_rows): in world coordinates a far eye's
// narrow view kept a ray's sideways part to a few digits.
fn centre_ray(tan_half_vfov: f32, x: i32, y: i32) -> vec3<f32> {
    let w = f32(fp.width);
    let h = f32(fp.height);
    let sx = 2.0 * (f32(x) + 0.5) / w - 1.0;
    let sy = 1.0 - 2.0 * (f32(y) + 0.5) / h;
    return vec3<f32>(1.0, sx * tan_half_vfov * (w / h), sy * tan_half_vfov);
}

// The hit `origin + relative` along pixel (x, y)'s ray in its camera's basis about its
// eye, less `origin` along forward: the depth's large part stays out of f32 sums.
fn hit_at(tan_half_vfov: f32, x: i32, y: i32, origin: f32, relative: f32) -> vec3<f32> {
    let c = centre_ray(tan_half_vfov, x, y);
    let side = dot(c.yz, c.yz);
    let len = sqrt(1.0 + side);
    let depth = origin + relative;
    // depth / len - origin, with len - 1 = side / (len + 1).
    let forward = (relative - origin * side / (len + 1.0)) / len;
    return vec3<f32>(forward, depth * c.y / len, depth * c.z / len);
}

struct Reprojected {
    found: bool,
    visibility: vec3<f32>,
    moments: vec2<f32>,
    length: f32,
}

// The history at pixel (x, y), reprojected (svgf::reproject); `local` the hit in the
// current camera's basis about its eye, less its depth origin (hit_at).
fn reproject(x: i32, y: i32, local: vec3<f32>, normal: vec3<f32>, material: f32) -> Reprojected {
    var out: Reprojected;
    out.found = false;
    let w = f32(fp.width);
    let h = f32(fp.height);
    // x_p - eye' in the previous camera's basis, less its depth origin along forward.
    let v = fp.camera[0].xyz + vec3<f32>(dot(fp.camera[1].xyz, local), dot(fp.camera[2].xyz, local), dot(fp.camera[3].xyz, local));
    let f = fp.previous_depth_origin + v.x;
    if !(f > 0.0) {
        return out;
    }
    let tan_previous = fp.previous[0].w;
    let sx = v.y / (f * tan_previous * (w / h));
    let sy = v.z / (f * tan_previous);
    let u = (sx + 1.0) * 0.5 * w - 0.5;
    let t = (1.0 - sy) * 0.5 * h - 0.5;
    // Far outside (or not finite): no tap can be inside.
    if !(abs(u) < 1e7 && abs(t) < 1e7) {
        return out;
    }
    let u0 = floor(u);
    let t0 = floor(t);
    let fu = u - u0;
    let ft = t - t0;
    var sw = 0.0;
    var sc = vec3<f32>(0.0);
    var sm = vec2<f32>(0.0);
    var sn = 0.0;
    // The lengths are mixed about the first read tap's (svgf's contract).
    var n0 = -1.0;
    for (var k = 0; k < 4; k++) {
        let dx = k % 2;
        let dy = k / 2;
        let qx = i32(u0) + dx;
        let qy = i32(t0) + dy;
        if qx < 0 || qy < 0 || qx >= i32(fp.width) || qy >= i32(fp.height) {
            continue;
        }
        let j = 3u * (u32(qy) * fp.width + u32(qx));
        let g = history_in[j];
        let a = history_in[j + 1u];
        let b = history_in[j + 2u];
        if b.w < 0.5 || b.z != material || dot(normal, g.xyz) < setting(6u) {
            continue;
        }
        // The tap's hit (less the previous depth origin along forward) and its normal
        // in the previous camera's basis.
        let xq = hit_at(tan_previous, qx, qy, fp.previous_depth_origin, g.w);
        let nq = vec3<f32>(dot(g.xyz, fp.previous[1].xyz), dot(g.xyz, fp.previous[2].xyz), dot(g.xyz, fp.previous[3].xyz));
        if abs(dot(v - xq, nq)) > setting(5u) * (fp.previous_depth_origin + g.w) {
            continue;
        }
        let weight = select(1.0 - fu, fu, dx > 0) * select(1.0 - ft, ft, dy > 0);
        sw += weight;
        sc += weight * a.xyz;
        sm += weight * b.xy;
        if n0 < 0.0 {
            n0 = a.w;
        }
        sn += weight * (a.w - n0);
    }
    if sw >= MIN_HISTORY_WEIGHT {
        out.found = true;
        out.visibility = sc / sw;
        out.moments = sm / sw;
        out.length = n0 + sn / sw;
    }
    return out;
}

// svgf::effective_samples.
fn effective_samples(length: f32) -> f32 {
    let alpha = setting(4u);
    if alpha > 0.0 {
        return min(length, (2.0 - alpha) / alpha);
    }
    return length;
}

// The temporal accumulation (svgf::accumulate): the new history, and the accumulated
// signal as the a-trous passes' input.
fn prepare_pixel(x: i32, y: i32, i: u32) {
    let c = color_in[i].xyz;
    if !filtered_at(x, y) {
        history_out[3u * i + 2u] = vec4<f32>(0.0);
        color_out[i] = vec4<f32>(c, 0.0);
        return;
    }
    let g = guide[2u * i];
    let material = guide[2u * i + 1u].z;
    let local = hit_at(fp.camera[0].w, x, y, fp.depth_origin, g.w);
    let l = luminance(c);
    var visibility = c;
    var moments = vec2<f32>(l, l * l);
    var length = 1.0;
    if fp.has_history != 0u {
        let r = reproject(x, y, local, g.xyz, material);
        if r.found {
            length = r.length + 1.0;
            let a = max(setting(4u), 1.0 / length);
            visibility = r.visibility + a * (c - r.visibility);
            moments = r.moments + a * (vec2<f32>(l, l * l) - r.moments);
        }
    }
    history_out[3u * i] = g;
    history_out[3u * i + 1u] = vec4<f32>(visibility, length);
    history_out[3u * i + 2u] = vec4<f32>(moments, material, 1.0);
    color_out[i] = vec4<f32>(visibility, 0.0);
}

fn iterate_pixel(x: i32, y: i32, i: u32) {
    if fp.pass_index == 0u {
        let a = history_out[3u * i + 1u];
        let b = history_out[3u * i + 2u];
        let n = effective_samples(a.w);
        // Below TEMPORAL_FRAMES samples atrous' spatial estimate is read, undivided.
        prepare_signal(x, y, i, vec3<f32>(b.xy, n), 1.0);
        return;
    }
    iterate_signal(x, y, i, 1 << (fp.pass_index - 1u));
}
