// The reaches of a box's twelve-bit code (crate::technique::boxes::REACHES), read by the
// walks whose regions are boxes: the box field's voxels (traversal_boxes.wgsl) and the
// sparse octant walk's uniform cells and the children below them
// (traversal_sparse_octant.wgsl).
#define_import_path voxlab::box_codes

// Where octant o's box code sits in its plane's word (plane o / 2, above the material's
// byte; crate::technique::boxes::plane_bits): the box field's voxels and the sparse
// octant walk's children below its cut.
fn plane_shift(o: u32) -> u32 {
    return 8u + 12u * (o & 1u);
}

// The reaches along x, y and z of the box whose code is the lowest twelve bits of
// `code`: four bits a reach, x lowest; code k stands for reach k below 2, else
// (2 + k % 2) << (k / 2 - 1).
fn box_reach(code: u32) -> vec3<i32> {
    let k = (vec3<u32>(code) >> vec3<u32>(0u, 4u, 8u)) & vec3<u32>(15u);
    let scaled = (2u + (k & vec3<u32>(1u))) << (max(k >> vec3<u32>(1u), vec3<u32>(1u)) - 1u);
    return vec3<i32>(select(k, scaled, k >= vec3<u32>(2u)));
}
