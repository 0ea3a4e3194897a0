// Reconstruction `atrous` on the device (src/technique/atrous.rs is the contract): the
// a-trous passes of shaders/atrous.wgsl over the frames' visibility, whose variance is
// the frames' own from TEMPORAL_FRAMES frames (shaders/reconstruct.wgsl calls these).
#define_import_path voxlab::reconstruction

#import voxlab::layers::{fp, moments}
#import voxlab::atrous::{prepare_signal, iterate_signal}

fn prepare_pixel(x: i32, y: i32, i: u32) {
    prepare_signal(x, y, i, moments(i), f32(max(fp.frames, 1u)));
}

fn iterate_pixel(x: i32, y: i32, i: u32) {
    iterate_signal(x, y, i, 1 << fp.pass_index);
}
