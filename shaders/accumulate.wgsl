// Progressive accumulation (ACCUMULATE): the tracer writes each frame of a dispatch to its
// own slice of a buffer (shaders/trace.wgsl, one invocation per pixel and frame), and this
// kernel adds the slices to each pixel's running sum in frame order, in f32 with
// Kahan-Babuska (Neumaier) compensation. The sum and its compensation stay in their
// buffers between dispatches, so a render of many frames may be split into several
// dispatches without changing the sum. The host divides by the number of frames at
// readback (in f64): nothing is rounded to 8 bits until the image is written.
// Contract: "Progressive accumulation".
//
// The loop below runs `frame_count` times in every invocation alike, and the host caps
// frame_count (MAX_FRAMES_PER_DISPATCH in src/gpu/mod.rs) far below the software
// driver's loop limit (shaders/counters.wgsl), so no driver can cut it short.

struct ReduceParams {
    pixels: u32,
    // Pixels per row of the dispatch grid (invocations along x of all its workgroups).
    row: u32,
    // Frames frame_begin .. frame_begin + frame_count; frame_begin 0 starts the sums.
    frame_begin: u32,
    frame_count: u32,
}

@group(0) @binding(0) var<uniform> rp: ReduceParams;
// frame_count slices of `pixels` vec4, frame by frame.
@group(0) @binding(1) var<storage, read> frames: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> sums: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> compensation: array<vec4<f32>>;

// All four components are summed: the radiance's fourth is unused, the primary
// layers' planes use it (shaders/trace.wgsl, write_layers).
struct Sum {
    sum: vec4<f32>,
    c: vec4<f32>,
}

// Neumaier's variant of Kahan summation: exact to the last bit of the running sum for
// any order of magnitudes.
fn add(a: ptr<function, Sum>, x: vec4<f32>) {
    let s = (*a).sum;
    let t = s + x;
    let big = abs(s) >= abs(x);
    (*a).c += select((x - t) + s, (s - t) + x, big);
    (*a).sum = t;
}

@compute @workgroup_size(64, 1, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.y * rp.row + gid.x;
    if i >= rp.pixels {
        return;
    }
    var a: Sum;
    a.sum = vec4<f32>(0.0);
    a.c = vec4<f32>(0.0);
    if rp.frame_begin > 0u {
        a.sum = sums[i];
        a.c = compensation[i];
    }
    for (var f = 0u; f < rp.frame_count; f++) {
        add(&a, frames[f * rp.pixels + i]);
    }
    sums[i] = a.sum;
    compensation[i] = a.c;
}
