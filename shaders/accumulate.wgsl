// Progressive accumulation (ACCUMULATE): the frames of a pixel are summed in f32 with
// Kahan-Babuska (Neumaier) compensation, and the sum and its compensation live in the
// `output` and `compensation` buffers between dispatches, so a render of many frames may
// be split into several dispatches without changing the sum. The host divides by the
// number of frames at readback (in f64): nothing is rounded to 8 bits until the image is
// written. Contract: "Progressive accumulation".
#define_import_path voxlab::accumulate

#import voxlab::bindings::{params, output, compensation}

struct Sum {
    sum: vec3<f32>,
    c: vec3<f32>,
}

// The running sum of pixel i: zero on the first dispatch, else what the last one left.
fn load_sum(i: u32) -> Sum {
    var a: Sum;
    a.sum = vec3<f32>(0.0);
    a.c = vec3<f32>(0.0);
    if params.frame_begin > 0u {
        a.sum = output[i].xyz;
        a.c = compensation[i].xyz;
    }
    return a;
}

// Neumaier's variant of Kahan summation: exact to the last bit of the running sum for
// any order of magnitudes.
fn add(a: ptr<function, Sum>, x: vec3<f32>) {
    let s = (*a).sum;
    let t = s + x;
    let big = abs(s) >= abs(x);
    (*a).c += select((x - t) + s, (s - t) + x, big);
    (*a).sum = t;
}

fn store_sum(i: u32, a: Sum) {
    output[i] = vec4<f32>(a.sum, 1.0);
    compensation[i] = vec4<f32>(a.c, 0.0);
}
