// Levels 1.. of the cone-tracing pyramids (src/gpu/pyramid.rs; reference:
// src/cpu/pyramid.rs). Box filter: a parent is the mean of its 2x2x2 children, children
// outside the finer level's dims counting as empty, so odd sizes conserve the level's
// total opacity mass (sum times texel volume 8^l).
//
// - reduce_r: opacity, f32 buffer of level l -> f32 buffer of level l + 1 (the opacity
//   is built in f32 and rounded to f16 once, by pack_r).
// - pack_r: an f32 level -> f16 pairs in a staging buffer whose rows are padded to the
//   256-byte alignment a buffer-to-texture copy needs (R16Float is not a storage format
//   in WebGPU, so the texture is filled by a copy).
// - reduce_rgba: radiance, mip l -> mip l + 1 of the RGBA16Float texture (a storage
//   format), read back through a view of mip l: each level is filtered from the f16 one
//   below it.

struct Level {
    src_dims: vec3<u32>,
    // Row pitch of the staging buffer, in u32 words (pack_r).
    pitch_words: u32,
    dst_dims: vec3<u32>,
    pad: u32,
}

@group(0) @binding(0) var<uniform> lv: Level;
@group(0) @binding(1) var<storage, read> src_r: array<f32>;
@group(0) @binding(2) var<storage, read_write> dst_r: array<f32>;
@group(0) @binding(3) var src_rgba: texture_3d<f32>;
@group(0) @binding(4) var dst_rgba: texture_storage_3d<rgba16float, write>;
@group(0) @binding(5) var<storage, read_write> staging: array<u32>;

fn idx(d: vec3<u32>, v: vec3<u32>) -> u32 {
    return v.x + d.x * (v.y + d.y * v.z);
}

@compute @workgroup_size(4, 4, 4)
fn reduce_r(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid >= lv.dst_dims) {
        return;
    }
    var s = 0.0;
    for (var c = 0u; c < 8u; c++) {
        let ch = 2u * gid + vec3<u32>(c & 1u, (c >> 1u) & 1u, c >> 2u);
        if all(ch < lv.src_dims) {
            s += src_r[idx(lv.src_dims, ch)];
        }
    }
    dst_r[idx(lv.dst_dims, gid)] = s * 0.125;
}

@compute @workgroup_size(4, 4, 4)
fn reduce_rgba(@builtin(global_invocation_id) gid: vec3<u32>) {
    if any(gid >= lv.dst_dims) {
        return;
    }
    var s = vec4<f32>(0.0);
    for (var c = 0u; c < 8u; c++) {
        let ch = 2u * gid + vec3<u32>(c & 1u, (c >> 1u) & 1u, c >> 2u);
        if all(ch < lv.src_dims) {
            s += textureLoad(src_rgba, vec3<i32>(ch), 0);
        }
    }
    textureStore(dst_rgba, vec3<i32>(gid), s * 0.125);
}

// One invocation per staging word: texels 2x and 2x + 1 of row (y, z) of the level in
// src_r (dims src_dims); the odd last word of a row pads with 0.
@compute @workgroup_size(4, 4, 4)
fn pack_r(@builtin(global_invocation_id) gid: vec3<u32>) {
    let d = lv.src_dims;
    if gid.x >= (d.x + 1u) / 2u || gid.y >= d.y || gid.z >= d.z {
        return;
    }
    let x0 = 2u * gid.x;
    let row = d.x * (gid.y + d.y * gid.z);
    let a = src_r[row + x0];
    var b = 0.0;
    if x0 + 1u < d.x {
        b = src_r[row + x0 + 1u];
    }
    staging[(gid.y + d.y * gid.z) * lv.pitch_words + gid.x] = pack2x16float(vec2<f32>(a, b));
}
