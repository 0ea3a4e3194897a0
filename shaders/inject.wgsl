// Level 0 of the cone-tracing pyramids (src/gpu/pyramid.rs; reference: src/cpu/pyramid.rs).
// Composed with voxlab::types only: it reads the tracer's material and light buffers
// (the same layouts, uploaded once), and has its own bindings and min-kt shadow walk.
//
// - opacity_base: alpha of each voxel's material (a per-material table computed on the
//   host from the transmittance model) into an f32 buffer, x-fastest.
// - radiance_base: the voxel's diffuse outgoing radiance under direct light, averaged
//   over its exposed faces (C. Crassin et al., "Interactive Indirect Illumination Using
//   Voxel Cone Tracing", CGF 30(7) 2011, section 3.2, light injection), premultiplied by
//   its alpha, alpha in w, into mip 0 of an RGBA16Float storage texture. Everything in
//   grid-local coordinates (voxel units), as the tracer.

#import voxlab::types::{BIG, Material, Light}
#import voxlab::emission::emitted

struct InjectParams {
    dims: vec3<u32>,
    num_lights: u32,
    // Shadow rays start this far off the face (voxels).
    eps: f32,
    voxel_size: f32,
    falloff_min_dist_sq: f32,
    falloff: u32,
}

@group(0) @binding(0) var<uniform> ip: InjectParams;
@group(0) @binding(1) var grid: texture_3d<u32>;
@group(0) @binding(2) var<storage, read> mats: array<Material>;
@group(0) @binding(3) var<storage, read> lights: array<Light>;
@group(0) @binding(4) var<storage, read_write> opacity_out: array<f32>;
@group(0) @binding(5) var radiance_out: texture_storage_3d<rgba16float, write>;
// Opacity per material, from the transmittance model (not a field of Material: the
// tracer does not read it).
@group(0) @binding(6) var<storage, read> alpha: array<f32>;

fn inside(v: vec3<i32>) -> bool {
    return all(v >= vec3<i32>(0)) && all(v < vec3<i32>(ip.dims));
}

fn material_at(v: vec3<i32>) -> u32 {
    if !inside(v) {
        return 0u;
    }
    return textureLoad(grid, v, 0).r;
}

fn kt_of(m: u32) -> f32 {
    if m == 0u {
        return 1.0;
    }
    return mats[m].kt;
}

// min-kt transmittance of the segment from q (inside the grid or on it) along unit d of
// length len: the contract's shadow ray (src/trace_contract.md), start voxel included.
fn shadow_min_kt(q: vec3<f32>, d: vec3<f32>, len: f32) -> f32 {
    // Entry into the grid's box by slabs (q may lie just outside, on an exposed face).
    let hi = vec3<f32>(ip.dims);
    var t_enter = 0.0;
    var t_exit = BIG;
    for (var a = 0; a < 3; a++) {
        if d[a] == 0.0 {
            if q[a] < 0.0 || q[a] > hi[a] {
                return 1.0;
            }
        } else {
            let t0 = (0.0 - q[a]) / d[a];
            let t1 = (hi[a] - q[a]) / d[a];
            t_enter = max(t_enter, min(t0, t1));
            t_exit = min(t_exit, max(t0, t1));
        }
    }
    if t_enter > t_exit || !(t_enter < len) {
        return 1.0;
    }
    var v = clamp(vec3<i32>(floor(q + t_enter * d)), vec3<i32>(0), vec3<i32>(ip.dims) - 1);
    var tr = kt_of(material_at(v));
    if tr <= 0.0 {
        return 0.0;
    }
    var step = vec3<i32>(0);
    var t_max = vec3<f32>(BIG);
    var t_delta = vec3<f32>(BIG);
    for (var a = 0; a < 3; a++) {
        if d[a] != 0.0 {
            let positive = d[a] > 0.0;
            step[a] = select(-1, 1, positive);
            let boundary = f32(v[a] + select(0, 1, positive));
            t_max[a] = min((boundary - q[a]) / d[a], BIG);
            t_delta[a] = min(1.0 / abs(d[a]), BIG);
        }
    }
    let n = ip.dims.x + ip.dims.y + ip.dims.z + 3u;
    for (var i = 0u; i < n; i++) {
        var a = 2;
        if t_max.x <= t_max.y && t_max.x <= t_max.z {
            a = 0;
        } else if t_max.y <= t_max.z {
            a = 1;
        }
        if !(t_max[a] < len) {
            break;
        }
        v[a] += step[a];
        t_max[a] += t_delta[a];
        if !inside(v) {
            break;
        }
        tr = min(tr, kt_of(material_at(v)));
        if tr <= 0.0 {
            return 0.0;
        }
    }
    return tr;
}

@compute @workgroup_size(4, 4, 4)
fn opacity_base(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid >= ip.dims) {
        return;
    }
    let m = textureLoad(grid, vec3<i32>(gid), 0).r;
    opacity_out[gid.x + ip.dims.x * (gid.y + ip.dims.y * gid.z)] = alpha[m];
}

@compute @workgroup_size(4, 4, 4)
fn radiance_base(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid >= ip.dims) {
        return;
    }
    let v = vec3<i32>(gid);
    let id = textureLoad(grid, v, 0).r;
    let mat = mats[id];
    let a = alpha[id];
    var out = vec3<f32>(0.0);
    if id != 0u && mat.kd > 0.0 {
        let centre = vec3<f32>(v) + 0.5;
        var faces = 0u;
        var sum = vec3<f32>(0.0);
        // Same face order as src/cpu/pyramid.rs FACES: -x, +x, -y, +y, -z, +z.
        for (var f = 0; f < 6; f++) {
            var ni = vec3<i32>(0);
            ni[f / 2] = select(-1, 1, (f & 1) == 1);
            if material_at(v + ni) != 0u {
                continue;
            }
            faces += 1u;
            let n = vec3<f32>(ni);
            let c = centre + 0.5 * n;
            let q = c + ip.eps * n;
            for (var j = 0u; j < ip.num_lights; j++) {
                let light = lights[j];
                let to = light.position - c;
                let dl = length(to);
                var l = n;
                if dl > 0.0 {
                    l = to / dl;
                }
                let nl = dot(n, l);
                if nl <= 0.0 {
                    continue;
                }
                let to_q = light.position - q;
                let len = length(to_q);
                var vis = 1.0;
                if len > 0.0 {
                    vis = shadow_min_kt(q, to_q / len, len);
                }
                if vis <= 0.0 {
                    continue;
                }
                var e = emitted(light, light.position, c);
                if ip.falloff != 0u {
                    e = e / max(dl * dl * ip.voxel_size * ip.voxel_size, ip.falloff_min_dist_sq);
                }
                sum += vis * e * nl;
            }
        }
        if faces > 0u {
            out = mat.albedo * mat.kd * sum / f32(faces);
        }
    }
    textureStore(radiance_out, v, vec4<f32>(out * a, a));
}
