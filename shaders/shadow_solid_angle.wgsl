// Rect lights sampled uniformly in solid angle (src/technique/solid_angle.rs, Urena,
// Fajardo and King, EGSR 2013, Algorithm 1); every other light as the area model
// samples it (shaders/area_lights.wgsl `sampled_light`). Grid-local units: lengths in
// voxels; the weight r^3 S / (A h) is a ratio of them.
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light, LIGHT_RECT}
#import voxlab::bindings::params
#import voxlab::counters::{loop_cut, loop_guard}
#import voxlab::sampling::{SampleKey, light_sample}
#import voxlab::area_lights::sampled_light
#import voxlab::phong::point_contribution
#import voxlab::emission::emitted

// crate::technique::solid_angle::SMALL_RECT and EDGE_ON
const SMALL_RECT: f32 = 0.3;
const EDGE_ON: f32 = 0.1;
const TAU: f32 = 6.283185307179586;

struct SphericalRect {
    o: vec3<f32>,
    x: vec3<f32>,
    y: vec3<f32>,
    z: vec3<f32>,
    plane_z: f32,
    lo_x: f32,
    lo_y: f32,
    hi_x: f32,
    hi_y: f32,
    b_lo: f32,
    b_lo_plane_sq: f32,
    b_hi: f32,
    k: f32,
    s: f32,
}

fn edge_angle(a: vec3<f32>, b: vec3<f32>) -> f32 {
    return acos(clamp(-dot(a, b), -1.0, 1.0));
}

// SphericalRect::new; s <= 0 marks a rectangle not to sample this way.
fn spherical_rect(o: vec3<f32>, corner: vec3<f32>, ex: vec3<f32>, ey: vec3<f32>) -> SphericalRect {
    var r: SphericalRect;
    let exl = length(ex);
    let eyl = length(ey);
    r.o = o;
    r.x = ex / exl;
    r.y = ey / eyl;
    r.z = cross(r.x, r.y);
    let d = corner - o;
    r.plane_z = dot(d, r.z);
    if r.plane_z > 0.0 {
        r.z = -r.z;
        r.plane_z = -r.plane_z;
    }
    r.lo_x = dot(d, r.x);
    r.lo_y = dot(d, r.y);
    r.hi_x = r.lo_x + exl;
    r.hi_y = r.lo_y + eyl;
    let v00 = vec3<f32>(r.lo_x, r.lo_y, r.plane_z);
    let v01 = vec3<f32>(r.lo_x, r.hi_y, r.plane_z);
    let v10 = vec3<f32>(r.hi_x, r.lo_y, r.plane_z);
    let v11 = vec3<f32>(r.hi_x, r.hi_y, r.plane_z);
    let n0 = normalize(cross(v00, v10));
    let n1 = normalize(cross(v10, v11));
    let n2 = normalize(cross(v11, v01));
    let n3 = normalize(cross(v01, v00));
    r.b_lo = n0.z;
    r.b_lo_plane_sq = n0.x * n0.x + n0.y * n0.y;
    r.b_hi = n2.z;
    r.k = TAU - edge_angle(n2, n3) - edge_angle(n3, n0);
    r.s = edge_angle(n0, n1) + edge_angle(n1, n2) - r.k;
    return r;
}

// SphericalRect::sample.
fn sample_rect(r: SphericalRect, uv: vec2<f32>) -> vec3<f32> {
    let au = uv.x * r.s + r.k;
    let fu = (cos(au) * r.b_lo - r.b_hi) / sin(au);
    // SphericalRect::sample: the paper's cu, xu with 1 - cu^2 written out.
    var xu = -r.plane_z / sqrt(max(fu * fu - r.b_lo_plane_sq, 0.0));
    if fu < 0.0 {
        xu = -xu;
    }
    xu = clamp(xu, r.lo_x, r.hi_x);
    let d = sqrt(xu * xu + r.plane_z * r.plane_z);
    let h0 = r.lo_y / sqrt(d * d + r.lo_y * r.lo_y);
    let h1 = r.hi_y / sqrt(d * d + r.hi_y * r.hi_y);
    let hv = h0 + uv.y * (h1 - h0);
    let hv2 = hv * hv;
    var yv = r.hi_y;
    if hv2 < 1.0 - 1e-6 {
        yv = hv * d / sqrt(1.0 - hv2);
    }
    return r.o + xu * r.x + yv * r.y + r.plane_z * r.z;
}

fn light_term(
    q: vec3<f32>,
    p: vec3<f32>,
    n: vec3<f32>,
    d: vec3<f32>,
    light: Light,
    j: u32,
    s: Material,
    key: SampleKey,
) -> vec3<f32> {
    let size = length(light.axis_u + light.axis_v);
    let ne = normalize(cross(light.axis_u, light.axis_v));
    // solid_angle::of_light: rects of non-zero size, not too small or edge-on.
    let sampled_in_solid_angle = light.kind == LIGHT_RECT && length(light.axis_u) > 0.0
        && length(light.axis_v) > 0.0 && size >= SMALL_RECT * length(light.position - p)
        && abs(dot(ne, p - light.position)) >= EDGE_ON * size;
    if !sampled_in_solid_angle {
        return sampled_light(q, p, n, d, light, j, s, key);
    }
    let corner = light.position - 0.5 * light.axis_u - 0.5 * light.axis_v;
    let r = spherical_rect(p, corner, light.axis_u, light.axis_v);
    if !(r.s > 0.0) {
        return sampled_light(q, p, n, d, light, j, s, key);
    }
    let area = length(cross(light.axis_u, light.axis_v));
    let h = -r.plane_z;
    let count = max(params.light_samples, 1u);
    var sum = vec3<f32>(0.0);
    var k = 0u;
    // count >= 1: the exit is tested at the bottom (shaders/counters.wgsl).
    loop {
        let x = sample_rect(r, light_sample(params.seed, key, j, k, count));
        let dist = length(x - p);
        let w = dist * dist * dist * r.s / (area * h);
        sum += point_contribution(q, p, n, d, x, emitted(light, x, p) * w, s);
        continuing {
            k++;
            break if k >= count || loop_guard();
        }
    }
    // Only the driver's loop limit ends it early (shaders/counters.wgsl).
    if k < count {
        loop_cut();
    }
    return sum / f32(count);
}
