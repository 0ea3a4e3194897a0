// The distance field of the sdf shadow model, built on the device: the exact squared
// Euclidean distance transform of the opaque voxels (P. Felzenszwalb and D. Huttenlocher,
// "Distance Transforms of Sampled Functions", Theory of Computing 8, 2012), one pass per
// axis, one invocation per line, the lower envelope of parabolas kept in scratch
// buffers; then `D = sqrt(d^2) - 1/2` (0 on occluders, NO_OCCLUDER without any). The
// CPU reference builds its own in f64 (src/technique/sdf.rs); squared distances are
// integers, exact in f32 below 2^24. Standalone: no imports.

struct EdtParams {
    dims: vec3<u32>,
    // 0, 1, 2: the axis of this pass's lines; 3: the finishing pass.
    axis: u32,
}

@group(0) @binding(0) var<uniform> ep: EdtParams;
@group(0) @binding(1) var grid: texture_3d<u32>;
// Per material: 1 when opaque (kt <= 0, not void).
@group(0) @binding(2) var<storage, read> opaque: array<u32>;
@group(0) @binding(3) var<storage, read> src: array<f32>;
@group(0) @binding(4) var<storage, read_write> dst: array<f32>;
// Scratch of the envelopes: per line, n parabola roots and n + 1 boundaries.
@group(0) @binding(5) var<storage, read_write> roots: array<u32>;
@group(0) @binding(6) var<storage, read_write> bounds: array<f32>;
// Set when the driver's loop limit (shaders/counters.wgsl) cut a loop short.
@group(0) @binding(7) var<storage, read_write> cut: array<atomic<u32>, 1>;

// No occluder on the line (yet): larger than any squared distance.
const FAR: f32 = 1.0e30;
// D where the grid has no occluder at all (f32::MAX, as the host writes it).
const NO_OCCLUDER: f32 = 3.4028235e38;

fn line_length() -> u32 {
    return ep.dims[ep.axis];
}

fn lines() -> u32 {
    return ep.dims.x * ep.dims.y * ep.dims.z / line_length();
}

// The voxel index of sample i of line `line` (x fastest).
fn index(line: u32, i: u32) -> u32 {
    let d = ep.dims;
    var v: vec3<u32>;
    if ep.axis == 0u {
        v = vec3<u32>(i, line % d.y, line / d.y);
    } else if ep.axis == 1u {
        v = vec3<u32>(line % d.x, i, line / d.x);
    } else {
        v = vec3<u32>(line % d.x, line / d.x, i);
    }
    return v.x + d.x * (v.y + d.y * v.z);
}

fn f_at(line: u32, i: u32) -> f32 {
    let at = index(line, i);
    if ep.axis == 0u {
        let d = ep.dims;
        let v = vec3<i32>(vec3<u32>(at % d.x, (at / d.x) % d.y, at / (d.x * d.y)));
        return select(FAR, 0.0, opaque[textureLoad(grid, v, 0).r] != 0u);
    }
    return src[at];
}

fn mark_cut() {
    atomicStore(&cut[0], 1u);
}

@compute @workgroup_size(64, 1, 1)
fn envelope(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let line = gid.x + gid.y * groups.x * 64u;
    if line >= lines() {
        return;
    }
    let n = line_length();
    let rv = line * n;
    let bz = line * (n + 1u);
    var first = 0u;
    for (; first < n; first++) {
        if f_at(line, first) < FAR {
            break;
        }
    }
    if first == n {
        var q = 0u;
        for (; q < n; q++) {
            dst[index(line, q)] = FAR;
        }
        if q < n {
            mark_cut();
        }
        return;
    }
    var k = 0u;
    roots[rv] = first;
    bounds[bz] = -FAR;
    bounds[bz + 1u] = FAR;
    var q = first + 1u;
    for (; q < n; q++) {
        let fq = f_at(line, q);
        if fq >= FAR {
            continue;
        }
        // Drop the parabolas the new one hides (bounds[0] is -FAR: k stays >= 0).
        var s = 0.0;
        var settled = false;
        loop {
            let p = roots[rv + k];
            s = ((fq + f32(q * q)) - (f_at(line, p) + f32(p * p))) / (2.0 * f32(q - p));
            if k > 0u && s <= bounds[bz + k] {
                k -= 1u;
            } else {
                settled = true;
                break;
            }
        }
        if !settled {
            mark_cut();
        }
        k += 1u;
        roots[rv + k] = q;
        bounds[bz + k] = s;
        bounds[bz + k + 1u] = FAR;
    }
    if q < n {
        mark_cut();
    }
    k = 0u;
    var i = 0u;
    for (; i < n; i++) {
        while bounds[bz + k + 1u] < f32(i) {
            k += 1u;
        }
        let p = roots[rv + k];
        let d = f32(i) - f32(p);
        dst[index(line, i)] = d * d + f_at(line, p);
    }
    if i < n {
        mark_cut();
    }
}

// D of every voxel from its squared distance, in place (src is unused).
@compute @workgroup_size(64, 1, 1)
fn finish(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.x + gid.y * groups.x * 64u;
    if i >= ep.dims.x * ep.dims.y * ep.dims.z {
        return;
    }
    let d2 = dst[i];
    if d2 == 0.0 {
        return;
    }
    dst[i] = select(sqrt(d2) - 0.5, NO_OCCLUDER, d2 >= FAR);
}
