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

// The clipped polygon, relative to p: a rectangle cut by a plane has at most 5 corners.
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

// Appends v where `on`.
fn poly_push(v: vec3<f32>, on: bool) {
    poly0 = select(poly0, v, on && poly_len == 0u);
    poly1 = select(poly1, v, on && poly_len == 1u);
    poly2 = select(poly2, v, on && poly_len == 2u);
    poly3 = select(poly3, v, on && poly_len == 3u);
    poly4 = select(poly4, v, on && poly_len == 4u);
    poly_len += select(0u, 1u, on);
}

// Corner i < 5.
fn poly_at(i: u32) -> vec3<f32> {
    var v = poly0;
    v = select(v, poly1, i == 1u);
    v = select(v, poly2, i == 2u);
    v = select(v, poly3, i == 3u);
    v = select(v, poly4, i == 4u);
    return v;
}

// One edge of Sutherland-Hodgman against n . x >= 0 (relative coordinates). The
// crossing is computed either way and kept only where the edge crosses.
fn clip_edge(a: vec3<f32>, b: vec3<f32>, n: vec3<f32>) {
    let da = dot(n, a);
    let db = dot(n, b);
    poly_push(a, da >= 0.0);
    poly_push(a + da / (da - db) * (b - a), (da >= 0.0) != (db >= 0.0));
}

fn triangle_solid_angle(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>) -> f32 {
    let la = length(a);
    let lb = length(b);
    let lc = length(c);
    let num = abs(dot(a, cross(b, c)));
    let den = la * lb * lc + dot(a, b) * lc + dot(a, c) * lb + dot(b, c) * la;
    return 2.0 * atan2(num, den);
}

// The in-plane field of edge i: -m_e ln((r_a + r_b + L) / (r_a + r_b - L)).
fn edge_field(i: u32, normal: vec3<f32>) -> vec3<f32> {
    if i >= poly_len {
        return vec3<f32>(0.0);
    }
    let a = poly_at(i);
    let b = poly_at((i + 1u) % poly_len);
    let e = b - a;
    let len = length(e);
    if !(len > 0.0) {
        return vec3<f32>(0.0);
    }
    let ra = length(a);
    let rb = length(b);
    let gap = max(2.0 * (ra * rb + dot(a, b)), 1e-30);
    let l = 2.0 * log(ra + rb + len) - log(gap);
    return -(cross(e, normal) / len) * l;
}

// n . F over the rectangle (centre c, axes au, av, unit normal ne) clipped to the
// half-space in front of p (module notes of src/technique/ratio.rs). No loops: at most
// 5 corners, 3 fan triangles and 5 edges, written out.
// The rectangle (centre c, axes au, av) relative to p, clipped to the half-space in
// front of p, into `poly`.
fn clip_rect(p: vec3<f32>, n: vec3<f32>, c: vec3<f32>, au: vec3<f32>, av: vec3<f32>) {
    let c0 = c - 0.5 * au - 0.5 * av - p;
    let c1 = c + 0.5 * au - 0.5 * av - p;
    let c2 = c + 0.5 * au + 0.5 * av - p;
    let c3 = c - 0.5 * au + 0.5 * av - p;
    poly_len = 0u;
    clip_edge(c0, c1, n);
    clip_edge(c1, c2, n);
    clip_edge(c2, c3, n);
    clip_edge(c3, c0, n);
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
    let h = dot(ne, poly0);
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
    let a = poly_at(i);
    let b = poly_at((i + 1u) % poly_len);
    let g = cross(a, b);
    let len = length(g);
    if !(len > 0.0) {
        return 0.0;
    }
    return atan2(len, dot(a, b)) * dot(n, g) / len;
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
