// The ratio estimator (Heitz, Hill and McGuire, I3D 2018): a rectangle light's
// unshadowed diffuse light in closed form times the sampled ratio of shadowed to
// unshadowed light; other area lights sampled as the area model does, points at their
// centres. The contract and the formulas: src/technique/ratio.rs. Grid-local units:
// lengths in voxels, so falloff multiplies squared lengths by voxel_size^2; the field
// integral F is dimensionless and the area is divided by voxel_size^2.
#define_import_path voxlab::shadow_model

#import voxlab::types::{Material, Light, LIGHT_RECT, EMISSION_LAMBERTIAN}
#import voxlab::bindings::params
#import voxlab::counters::{count_shadow, loop_cut, loop_guard}
#import voxlab::sampling::{SampleKey, light_sample}
#import voxlab::area_lights::{sample_point, sampled_light}
#import voxlab::phong::shadow_to
#import voxlab::emission::emitted_share

// crate::technique::ratio::SMALL_LIGHT
const SMALL_LIGHT: f32 = 1e-3;

// The clipped polygon: its corners as offsets from the light's centre, which lies at
// `poly_centre` from p. The closed forms below sum edge terms that cancel down to the
// light's solid angle; a cross product of two corners seen from p (long, nearly parallel
// vectors when the light is small or far) loses in f32 the digits that survive the sum,
// so each is expanded about the centre, `(C + a) x (C + b) = C x (b - a) + a x b`, whose
// terms hold them: a rect of side 0.01 some 15 voxels away was 0.64 off the reference's
// image (tests/gpu_extremes.rs, `a_small_rect_light_under_the_ratio_estimator`).
// A rectangle cut by a plane has at most 5 corners.
// Five variables at constant slots, not an array: an array read or written at the
// per-lane index poly_len is a loop over the SIMD vector's lanes with a branch a lane on
// a software driver, as the ray stack's was. A push is a select into every slot and a
// read at a per-lane index a chain of selects, so the corners and their order are the
// same and so is the result; on lavapipe the ratio frame took 0.38x the time at 4 light
// samples (docs/benchmarks.md, "The ratio estimator's polygon").
var<private> poly0: vec3<f32>;
var<private> poly1: vec3<f32>;
var<private> poly2: vec3<f32>;
var<private> poly3: vec3<f32>;
var<private> poly4: vec3<f32>;
var<private> poly_len: u32;
var<private> poly_centre: vec3<f32>;

// Appends v where `on`.
fn poly_push(v: vec3<f32>, on: bool) {
    poly0 = select(poly0, v, on && poly_len == 0u);
    poly1 = select(poly1, v, on && poly_len == 1u);
    poly2 = select(poly2, v, on && poly_len == 2u);
    poly3 = select(poly3, v, on && poly_len == 3u);
    poly4 = select(poly4, v, on && poly_len == 4u);
    poly_len += select(0u, 1u, on);
}

// Corner i < 5, as an offset from the centre.
fn poly_at(i: u32) -> vec3<f32> {
    var v = poly0;
    v = select(v, poly1, i == 1u);
    v = select(v, poly2, i == 2u);
    v = select(v, poly3, i == 3u);
    v = select(v, poly4, i == 4u);
    return v;
}

// (C + a) x (C + b) for offsets a, b, expanded so that no term cancels.
fn corner_cross(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return cross(poly_centre, b - a) + cross(a, b);
}

// One edge of Sutherland-Hodgman against n . x >= 0, x = C + offset; `nc` is n . C. The
// crossing is computed either way and kept only where the edge crosses.
fn clip_edge(a: vec3<f32>, b: vec3<f32>, n: vec3<f32>, nc: f32) {
    let da = nc + dot(n, a);
    let db = nc + dot(n, b);
    poly_push(a, da >= 0.0);
    poly_push(a + da / (da - db) * (b - a), (da >= 0.0) != (db >= 0.0));
}

// The solid angle of the triangle C + a, C + b, C + c (Van Oosterom and Strackee), its
// triple product expanded about the centre: C . ((b - a) x (c - a)) + a . (b x c).
fn triangle_solid_angle(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    let ca = poly_centre + a;
    let cb = poly_centre + b;
    let cc = poly_centre + c;
    let la = length(ca);
    let lb = length(cb);
    let lc = length(cc);
    let num = abs(dot(poly_centre, cross(b - a, c - a)) + dot(a, cross(b, c)));
    let den = la * lb * lc + dot(ca, cb) * lc + dot(ca, cc) * lb + dot(cb, cc) * la;
    return 2.0 * atan2(num, den);
}

// ln(1 + x) for x >= 0 to f32's relative precision where x is small (WGSL has no
// log1p): 2 atanh(z), z = x / (2 + x), by its series below 0.1, where four terms leave
// z^8 / 9 < 1e-11. Not Goldberg's `log(u) x / (u - 1)`: the driver may fold (1 + x) - 1
// into x (Mesa's NIR rewrites inexact float arithmetic), which left a rect of side 0.01
// 15 voxels away 10 % off.
fn log1p_small(x: f32) -> f32 {
    if x >= 0.1 {
        return log(1.0 + x);
    }
    let z = x / (2.0 + x);
    let z2 = z * z;
    return 2.0 * z * (1.0 + z2 * (1.0 / 3.0 + z2 * (0.2 + z2 / 7.0)));
}

// The in-plane field of edge i: -m_e ln((r_a + r_b + L) / (r_a + r_b - L)), the
// logarithm as ln(1 + 2 L / g) with g = r_a + r_b - L, which cancels only where a and b
// point apart (p near the edge's line); there g = 2 |a x b|^2 / ((r_a r_b - a . b)
// (r_a + r_b + L)).
fn edge_field(i: u32, normal: vec3<f32>) -> vec3<f32> {
    if i >= poly_len {
        return vec3<f32>(0.0);
    }
    let oa = poly_at(i);
    let ob = poly_at((i + 1u) % poly_len);
    let e = ob - oa;
    let len = length(e);
    if !(len > 0.0) {
        return vec3<f32>(0.0);
    }
    let a = poly_centre + oa;
    let b = poly_centre + ob;
    let ra = length(a);
    let rb = length(b);
    let ab = dot(a, b);
    var g = ra + rb - len;
    if ab < 0.0 {
        let axb = corner_cross(oa, ob);
        g = 2.0 * dot(axb, axb) / ((ra * rb - ab) * (ra + rb + len));
    }
    let l = log1p_small(2.0 * len / max(g, 1e-30));
    return -(cross(e, normal) / len) * l;
}

// n . F over the rectangle (centre c, axes au, av, unit normal ne) clipped to the
// half-space in front of p (module notes of src/technique/ratio.rs). No loops: at most
// 5 corners, 3 fan triangles and 5 edges, written out.
// The rectangle (centre c, axes au, av) seen from p, clipped to the half-space in front
// of p, into `poly` (offsets) and `poly_centre`.
fn clip_rect(p: vec3<f32>, n: vec3<f32>, c: vec3<f32>, au: vec3<f32>, av: vec3<f32>) {
    poly_centre = c - p;
    let nc = dot(n, poly_centre);
    let c0 = -0.5 * au - 0.5 * av;
    let c1 = 0.5 * au - 0.5 * av;
    let c2 = 0.5 * au + 0.5 * av;
    let c3 = -0.5 * au + 0.5 * av;
    poly_len = 0u;
    clip_edge(c0, c1, n, nc);
    clip_edge(c1, c2, n, nc);
    clip_edge(c2, c3, n, nc);
    clip_edge(c3, c0, n, nc);
}

fn clipped_field(p: vec3<f32>, n: vec3<f32>, c: vec3<f32>, au: vec3<f32>, av: vec3<f32>, ne: vec3<f32>) -> f32 {
    clip_rect(p, n, c, au, av);
    if poly_len < 3u {
        return 0.0;
    }
    var omega = triangle_solid_angle(poly0, poly1, poly2);
    if poly_len > 3u {
        omega += triangle_solid_angle(poly0, poly2, poly3);
    }
    if poly_len > 4u {
        omega += triangle_solid_angle(poly0, poly3, poly4);
    }
    let h = dot(ne, poly_centre + poly0);
    var field = select(-1.0, 1.0, h >= 0.0) * omega * ne;
    field += edge_field(0u, ne) + edge_field(1u, ne) + edge_field(2u, ne);
    field += edge_field(3u, ne) + edge_field(4u, ne);
    return dot(n, field);
}

// gamma n . (a x b) / |a x b| of edge i of the clipped polygon (Lambert's formula).
fn lambert_edge(i: u32, n: vec3<f32>) -> f32 {
    if i >= poly_len {
        return 0.0;
    }
    let oa = poly_at(i);
    let ob = poly_at((i + 1u) % poly_len);
    let g = corner_cross(oa, ob);
    let len = length(g);
    if !(len > 0.0) {
        return 0.0;
    }
    return atan2(len, dot(poly_centre + oa, poly_centre + ob)) * dot(n, g) / len;
}

// The projected solid angle of the rectangle clipped to the hemisphere of n, for a
// Lambertian rectangle (crate::technique::ratio::projected_solid_angle).
fn projected_solid_angle(p: vec3<f32>, n: vec3<f32>, c: vec3<f32>, au: vec3<f32>, av: vec3<f32>) -> f32 {
    clip_rect(p, n, c, au, av);
    if poly_len < 3u {
        return 0.0;
    }
    let sum = lambert_edge(0u, n) + lambert_edge(1u, n) + lambert_edge(2u, n)
        + lambert_edge(3u, n) + lambert_edge(4u, n);
    return 0.5 * abs(sum);
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
    let analytic = light.kind == LIGHT_RECT && length(light.axis_u) > 0.0
        && length(light.axis_v) > 0.0 && params.falloff != 0u;
    if !analytic {
        // Points at their centres, other shapes sampled: the area model's estimate.
        return sampled_light(q, p, n, d, light, j, s, key);
    }
    let count = max(params.light_samples, 1u);
    var shadowed = vec3<f32>(0.0);
    var free = 0.0;
    var specular = vec3<f32>(0.0);
    var visible = vec3<f32>(0.0);
    let vs2 = params.voxel_size * params.voxel_size;
    var k = 0u;
    // count >= 1: the exit is tested at the bottom (shaders/counters.wgsl).
    loop {
        let x = sample_point(light, light_sample(params.seed, key, j, k, count));
        count_shadow();
        let vis = shadow_to(q, x);
        let to = x - p;
        let dl = length(to);
        var l = n;
        if dl > 0.0 {
            l = to / dl;
        }
        let e = emitted_share(light, x, p) / max(dl * dl * vs2, params.falloff_min_dist_sq);
        let nl = dot(n, l);
        let f = e * max(nl, 0.0);
        let rd = dot(l - 2.0 * nl * n, d);
        if nl > 0.0 && rd > 0.0 {
            specular += vis * e * s.ks * pow(rd, s.shininess);
        }
        shadowed += vis * f;
        free += f;
        visible += vis;
        continuing {
            k++;
            break if k >= count || loop_guard();
        }
    }
    // Only the driver's loop limit ends it early (shaders/counters.wgsl).
    if k < count {
        loop_cut();
    }
    var ratio = visible / f32(count);
    if free > 0.0 {
        ratio = shadowed / free;
    }
    // A light seen at under SMALL_LIGHT radians: the samples' mean (ratio.rs).
    if length(light.axis_u + light.axis_v) < SMALL_LIGHT * length(light.position - p) {
        return light.radiance * (s.kd * shadowed + specular) / f32(count);
    }
    let normal_area = cross(light.axis_u, light.axis_v);
    let area = length(normal_area);
    let ne = normal_area / area;
    var irradiance = 0.0;
    if light.emission != EMISSION_LAMBERTIAN {
        irradiance = clipped_field(p, n, light.position, light.axis_u, light.axis_v, ne);
    } else if dot(ne, p - light.position) > 0.0 {
        irradiance = projected_solid_angle(p, n, light.position, light.axis_u, light.axis_v);
    }
    irradiance /= area * vs2;
    return light.radiance * (s.kd * irradiance * ratio + specular / f32(count));
}
