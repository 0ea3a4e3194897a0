// Reconstruction `svgf` on the device (src/technique/svgf.rs is the contract; this is its
// f32 twin): `prepare_pixel` accumulates each pixel's visibility onto its reprojected
// history and writes the new history, then the a-trous passes of shaders/atrous.wgsl
// run over the accumulated signal (iterate pass 0 prepares them, passes 1.. filter).
#define_import_path voxlab::reconstruction

#import voxlab::layers::{fp, guide, color_in, color_out, setting, luminance, filtered_at, history_in, history_out}
#import voxlab::atrous::{prepare_signal, iterate_signal}

// As svgf::MIN_HISTORY_WEIGHT.
const MIN_HISTORY_WEIGHT: f32 = 0.01;

struct Camera {
    eye: vec3<f32>,
    tan_half_vfov: f32,
    forward: vec3<f32>,
    right: vec3<f32>,
    up: vec3<f32>,
}

fn camera(c: array<vec4<f32>, 4>) -> Camera {
    var out: Camera;
    out.eye = c[0].xyz;
    out.tan_half_vfov = c[0].w;
    out.forward = c[1].xyz;
    out.right = c[2].xyz;
    out.up = c[3].xyz;
    return out;
}

// The ray through pixel (x, y)'s centre (crate::scene::CameraFrame::primary_dir).
fn centre_dir(c: Camera, x: i32, y: i32) -> vec3<f32> {
    let w = f32(fp.width);
    let h = f32(fp.height);
    let sx = 2.0 * (f32(x) + 0.5) / w - 1.0;
    let sy = 1.0 - 2.0 * (f32(y) + 0.5) / h;
    return normalize(c.forward + (sx * c.tan_half_vfov * (w / h)) * c.right + (sy * c.tan_half_vfov) * c.up);
}

struct Reprojected {
    found: bool,
    visibility: vec3<f32>,
    moments: vec2<f32>,
    length: f32,
}

// The history at pixel (x, y), reprojected (svgf::reproject).
fn reproject(x: i32, y: i32, position: vec3<f32>, normal: vec3<f32>, material: f32) -> Reprojected {
    var out: Reprojected;
    out.found = false;
    let cam = camera(fp.previous);
    let w = f32(fp.width);
    let h = f32(fp.height);
    let v = position - cam.eye;
    let f = dot(v, cam.forward);
    if !(f > 0.0) {
        return out;
    }
    let sx = dot(v, cam.right) / (f * cam.tan_half_vfov * (w / h));
    let sy = dot(v, cam.up) / (f * cam.tan_half_vfov);
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
        let xq = cam.eye + g.w * centre_dir(cam, qx, qy);
        if abs(dot(position - xq, g.xyz)) > setting(5u) * g.w {
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
    let cam = camera(fp.camera);
    let position = cam.eye + g.w * centre_dir(cam, x, y);
    let l = luminance(c);
    var visibility = c;
    var moments = vec2<f32>(l, l * l);
    var length = 1.0;
    if fp.has_history != 0u {
        let r = reproject(x, y, position, g.xyz, material);
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
