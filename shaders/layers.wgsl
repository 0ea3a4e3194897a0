// The primary layers on the device, for a reconstruction's passes (src/gpu/reconstruct.rs):
// the bindings and what reads them. The tracer's planes (shaders/trace.wgsl, write_layers;
// five planes of the image's pixels) are decoded into a guide and a colour per pixel by
// shaders/reconstruct.wgsl's `inputs`, filtered by the reconstruction's module
// (shaders/reconstruction_<name>.wgsl, `voxlab::reconstruction`, which imports this one),
// and composed into the image by `compose`. As crate::frame::PrimaryLayers, in f32.
#define_import_path voxlab::layers

struct FilterParams {
    width: u32,
    height: u32,
    // Frames the sums are over; `accumulated`: whether `compensation` holds their
    // compensation (else the planes are one frame's values and it is unread).
    frames: u32,
    accumulated: u32,
    // The pass's index among the reconstruction's own passes (0 for `prepare`).
    pass_index: u32,
    // Whether `history_in` holds the previous frame of a camera path (a temporal
    // reconstruction's; crate::frame::History).
    has_history: u32,
    // Where this frame's and the history's depths count from (world units): the guide
    // and the history hold each primary depth less it (src/gpu/reconstruct.rs,
    // depth_origin; 0 for an eye near the grid).
    depth_origin: f32,
    previous_depth_origin: f32,
    // The reconstruction's settings in declared order (Reconstruction::values).
    settings: array<vec4<f32>, 2>,
    // This frame's camera and the history's, in the cameras' bases, each hit less its
    // depth origin along forward (src/gpu/reconstruct.rs, reprojection_rows): `camera`
    // the offset of this frame's origin from the history's in the history camera's
    // basis and tan(vfov / 2), then the change of basis (row i: the history's axis i
    // dotted with this frame's forward, right, up); `previous` tan(vfov / 2) in w, then
    // the history camera's forward, right, up.
    camera: array<vec4<f32>, 4>,
    previous: array<vec4<f32>, 4>,
}

@group(0) @binding(0) var<uniform> fp: FilterParams;
// The tracer's planes (sums over frames) and their compensation.
@group(0) @binding(1) var<storage, read> planes: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> compensation: array<vec4<f32>>;
// Two entries per pixel: (normal, depth) and (unused, unused, material, read: 1 or 0).
@group(0) @binding(3) var<storage, read_write> guide: array<vec4<f32>>;
// The pass's input and output colours: (visibility rgb, its variance), or at the end the
// composed radiance.
@group(0) @binding(4) var<storage, read> color_in: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> color_out: array<vec4<f32>>;
// A vector per pixel the reconstruction keeps between its passes (the a-trous filter:
// the depth gradient).
@group(0) @binding(6) var<storage, read_write> aux: array<vec2<f32>>;

// A temporal reconstruction's history (crate::frame::History), the previous frame's
// and this frame's: three entries per pixel, (normal, depth), (visibility rgb, length),
// (moments, material, kept: 1 or 0). Unread by the others.
@group(0) @binding(7) var<storage, read> history_in: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read_write> history_out: array<vec4<f32>>;

// The reconstruction's setting k (declared order).
fn setting(k: u32) -> f32 {
    return fp.settings[k / 4u][k % 4u];
}

// ITU-R BT.709 luminance, as crate::frame::luminance.
fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// Plane k's sum at pixel i, with its compensation.
fn plane_sum(k: u32, i: u32) -> vec4<f32> {
    let at = k * fp.width * fp.height + i;
    var s = planes[at];
    if fp.accumulated != 0u {
        s += compensation[at];
    }
    return s;
}

fn pixel_index(x: i32, y: i32) -> u32 {
    return u32(y) * fp.width + u32(x);
}

fn inside(x: i32, y: i32) -> bool {
    return x >= 0 && y >= 0 && x < i32(fp.width) && y < i32(fp.height);
}

// Whether the filter reads pixel (x, y): inside, a hit, some unshadowed light
// (PrimaryPixel::filtered).
fn filtered_at(x: i32, y: i32) -> bool {
    return inside(x, y) && guide[2u * pixel_index(x, y) + 1u].w > 0.5;
}

// The layers' means at pixel i: the image, direct and unshadowed light.
struct Means {
    radiance: vec3<f32>,
    direct: vec3<f32>,
    unshadowed: vec3<f32>,
}

fn means(i: u32) -> Means {
    let n = f32(max(fp.frames, 1u));
    var m: Means;
    m.radiance = plane_sum(0u, i).xyz / n;
    m.direct = plane_sum(1u, i).xyz / n;
    m.unshadowed = plane_sum(2u, i).xyz / n;
    return m;
}

// The frames' moments of the visibility's luminance at pixel i: (mean, mean of the
// square, frames that defined it), as PrimaryPixel::ratio_moments and ratio_frames.
fn moments(i: u32) -> vec3<f32> {
    let defined = round(plane_sum(4u, i).z);
    if defined <= 0.0 {
        return vec3<f32>(0.0);
    }
    return vec3<f32>(plane_sum(1u, i).w / defined, plane_sum(2u, i).w / defined, defined);
}

