// A reconstruction's passes (src/gpu/reconstruct.rs), one entry point each: `inputs`
// decodes the tracer's planes, the reconstruction's `prepare_pixel` runs once and its
// `iterate_pixel` once per pass (voxlab::reconstruction, the plan's
// shaders/reconstruction_<name>.wgsl), and `compose` writes the image, as
// crate::technique::Reconstruction::apply.

#import voxlab::layers::{fp, guide, color_in, color_out, luminance, plane_sum, means}
#import voxlab::reconstruction::{prepare_pixel, iterate_pixel}

// Decodes pixel i: its guide, and its visibility (variance 0: the reconstruction's own
// `prepare` estimates it, from the frames' moments, `moments`, or otherwise).
@compute @workgroup_size(8, 8, 1)
fn inputs(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= fp.width || gid.y >= fp.height {
        return;
    }
    let i = gid.y * fp.width + gid.x;
    let m = means(i);
    let g = plane_sum(3u, i);
    let kind = plane_sum(4u, i);
    let hit = kind.y > 0.5;
    let filtered = hit && luminance(m.unshadowed) > 0.0;
    guide[2u * i] = g;
    guide[2u * i + 1u] = vec4<f32>(0.0, 0.0, round(kind.x), select(0.0, 1.0, filtered));
    let c = select(vec3<f32>(0.0), m.direct / m.unshadowed, m.unshadowed > vec3<f32>(0.0));
    color_out[i] = vec4<f32>(c, 0.0);
}

@compute @workgroup_size(8, 8, 1)
fn prepare(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= fp.width || gid.y >= fp.height {
        return;
    }
    prepare_pixel(i32(gid.x), i32(gid.y), gid.y * fp.width + gid.x);
}

@compute @workgroup_size(8, 8, 1)
fn iterate(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= fp.width || gid.y >= fp.height {
        return;
    }
    iterate_pixel(i32(gid.x), i32(gid.y), gid.y * fp.width + gid.x);
}

// The image: the mean radiance with, where the filter read the pixel, the direct light
// replaced by the unshadowed light times the filtered visibility.
@compute @workgroup_size(8, 8, 1)
fn compose(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= fp.width || gid.y >= fp.height {
        return;
    }
    let i = gid.y * fp.width + gid.x;
    let m = means(i);
    var out = m.radiance;
    if guide[2u * i + 1u].w > 0.5 {
        out = m.radiance - m.direct + m.unshadowed * color_in[i].xyz;
    }
    color_out[i] = vec4<f32>(out, 1.0);
}
