// The Whitted tracer's entry point: one invocation per pixel walks the ray tree depth
// first with an explicit stack (WGSL has no recursion). As the composition is linear,
// adding throughput * local at every hit gives the seed's ray-tree image exactly.
// Contract: "Primary rays", "Shading a hit", "Stack".
//
// Shader defs (src/plan.rs): REFLECTION, REFRACTION, SHADOWS, EMISSION, ACCUMULATE,
// COUNT_RAYS, RAY_CUTOFF, RAY_STACK_SIZE, PRIMARY_LAYERS (the layers a reconstruction
// filters, beside the radiance), LIGHTING_TERMS (the plan's terms, summed by the module
// src/gpu/compose.rs writes), CONES (shaders/cone.wgsl, group 1, when the shadow model
// or a term reads the pyramids). The shadow, transmittance and light models live in their own files
// (shading.wgsl and phong.wgsl compose them); this file only walks the ray tree of one
// frame of one pixel.

#import voxlab::types::{BIG, Material, PIXEL_FILTER_BOX, PIXEL_FILTER_GAUSSIAN}
#import voxlab::dielectric::split_weights
#import voxlab::bindings::{params, materials, output}
#import voxlab::traversal::{cast_ray, leaves_grid}
#ifdef TRIANGLES
#import voxlab::triangles::shadow_medium
#endif
#import voxlab::counters::{count_primary, count_secondary, count_untraced, flush_counts, loop_cut, loop_guard, shadows_clear}
#import voxlab::sampling::{SampleKey, pixel_sample}
#ifdef CONES
#import voxlab::cone::cone_loop_cut
#endif
#ifdef SHADOWS
#import voxlab::shading::local_light
#endif
#import voxlab::lighting_terms::lighting_terms

struct RayEntry {
    origin: vec3<f32>,
    // Reflection depth a and refraction depth b of the contract.
    depth_reflection: u32,
    dir: vec3<f32>,
    depth_refraction: u32,
    throughput: vec3<f32>,
    medium: u32,
}

// A stack entry: a RayEntry with its depths and medium packed in one word (each below
// 256: depths at most render::MAX_DEPTH_LIMIT, materials at most 256).
struct StackEntry {
    origin: vec3<f32>,
    packed: u32,
    dir: vec3<f32>,
    throughput: vec3<f32>,
}

// Up to 9 entries (depth limits up to 8/8) the stack is a shift register: its top is
// entry 0, and a push moves every entry down one and a pop up one, all at constant
// indices. An entry read or written at the per-lane index sp is instead a loop over
// the SIMD vector's lanes with a branch a lane on a software driver (the profile in
// docs/sparse-traversal.md, "What each change to the kernel bought"), run at every pass
// of the ray-tree loop whether or not a lane pushes or pops. On lavapipe the shift
// took 0.84x to 0.92x the seed scene's frame (16^3 under both rules, 64^3 under
// voxlab's; stacks of 4 and 5) and was not slower at 9 (docs/benchmarks.md, "The ray
// stack"). Deeper stacks keep the index: a shift's
// moves grow with the size, and lavapipe's loop limit cuts deeper trees, so no larger
// size was measured.
var<private> stack: array<StackEntry, #{RAY_STACK_SIZE}>;
var<private> sp: u32;
// The ray a hit spawned last (its reflection), traced next without going through the
// stack: the order is the stack's, as if pushed and popped at once. Measured when an
// entry was always written and read at the per-lane index, which a software driver
// pays for on every SIMD lane (seed_rules at 512x512 on lavapipe, medians of five
// alternated runs: 16^3 98.5 to 95.0 ms per frame, 64^3 233 to 230; packing the entry,
// StackEntry, then 95.3 to 93.4 and 233 to 230).
var<private> next_ray: RayEntry;
var<private> has_next: bool;

#ifdef PRIMARY_LAYERS
// What the primary ray found, for a reconstruction (crate::frame::PrimaryLayers): its
// hit (world distance, shading normal, shading material) and the local light there as
// shaded and with every shadow segment clear. Zero where it missed.
var<private> primary_hit: bool;
var<private> primary_normal: vec3<f32>;
var<private> primary_depth: f32;
var<private> primary_material: u32;
var<private> primary_direct: vec3<f32>;
var<private> primary_unshadowed: vec3<f32>;

// Planes per pixel and frame in `output` (crate::plan::PRIMARY_LAYER_SLICES).
const LAYER_SLICES: u32 = 5u;

// ITU-R BT.709 luminance, as crate::frame::luminance.
fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// The visibility ratio per channel, 0 where a channel has no unshadowed light
// (PrimaryPixel::visibility).
fn visibility(direct: vec3<f32>, unshadowed: vec3<f32>) -> vec3<f32> {
    return select(vec3<f32>(0.0), direct / unshadowed, unshadowed > vec3<f32>(0.0));
}

// The radiance and the four planes of the primary layers of pixel i in frame z: the
// direct light and the luminance of its visibility, the unshadowed light and that
// luminance squared, frame 0's normal and depth, and frame 0's material and hit with
// this frame's count of a defined visibility. Summed over frames by
// shaders/accumulate.wgsl like the radiance: the G-buffer is written in frame 0 alone,
// so its sum is frame 0's.
fn write_layers(z: u32, i: u32, frame: u32, radiance: vec3<f32>) {
    let plane = params.width * params.height;
    let base = z * plane * LAYER_SLICES + i;
    output[base] = vec4<f32>(radiance, 1.0);
    var l = 0.0;
    var defined = 0.0;
    if luminance(primary_unshadowed) > 0.0 {
        l = luminance(visibility(primary_direct, primary_unshadowed));
        defined = 1.0;
    }
    output[base + plane] = vec4<f32>(primary_direct, l);
    output[base + 2u * plane] = vec4<f32>(primary_unshadowed, l * l);
    var guide = vec4<f32>(0.0);
    var kind = vec4<f32>(0.0, 0.0, defined, 0.0);
    if frame == 0u {
        guide = vec4<f32>(primary_normal, primary_depth);
        kind.x = f32(primary_material);
        kind.y = select(0.0, 1.0, primary_hit);
    }
    output[base + 3u * plane] = guide;
    output[base + 4u * plane] = kind;
}
#endif

fn push(r: RayEntry) {
    // The plan sizes the stack to the depth limits, so this never drops a ray; the test
    // only keeps a wrong size from writing out of bounds.
    if sp < #{RAY_STACK_SIZE}u {
        let packed = r.depth_reflection | (r.depth_refraction << 8u) | (r.medium << 16u);
        let entry = StackEntry(r.origin, packed, r.dir, r.throughput);
#if RAY_STACK_SIZE <= 9
#if RAY_STACK_SIZE > 8
        stack[8] = stack[7];
#endif
#if RAY_STACK_SIZE > 7
        stack[7] = stack[6];
#endif
#if RAY_STACK_SIZE > 6
        stack[6] = stack[5];
#endif
#if RAY_STACK_SIZE > 5
        stack[5] = stack[4];
#endif
#if RAY_STACK_SIZE > 4
        stack[4] = stack[3];
#endif
#if RAY_STACK_SIZE > 3
        stack[3] = stack[2];
#endif
#if RAY_STACK_SIZE > 2
        stack[2] = stack[1];
#endif
#if RAY_STACK_SIZE > 1
        stack[1] = stack[0];
#endif
        stack[0] = entry;
#else
        stack[sp] = entry;
#endif
        sp += 1u;
        count_secondary();
    }
}

// Whether ray r may spawn a reflection (`reflection`) or a refraction ray: the depth
// limits under the rules in force, and the total limit. As RenderSettings::may_spawn.
fn may_spawn(r: RayEntry, reflection: bool) -> bool {
    let depth = r.depth_reflection + r.depth_refraction;
    if depth >= params.max_total_depth {
        return false;
    }
#ifdef SEED_RULES
    // Under the seed's rules the one recursion depth a + b meets both limits.
    let own = depth;
#else
    let own = select(r.depth_refraction, r.depth_reflection, reflection);
#endif
    return own < select(params.max_refraction_depth, params.max_reflection_depth, reflection);
}

// A ray's weight for the ray cutoff (crate::ray_cutoff): its throughput, the same in
// every channel (kr and kt are scalars), a product of f32 factors from 1.
fn weight(throughput: vec3<f32>) -> f32 {
    return max(throughput.x, max(throughput.y, throughput.z));
}

// Whether a ray of this throughput is traced: always, unless the ray cutoff is in and
// its weight is below it (contract: "Ray cutoff").
fn traced(throughput: vec3<f32>) -> bool {
#ifdef RAY_CUTOFF
    return weight(throughput) >= params.ray_cutoff;
#else
    return true;
#endif
}

// |v| without squaring v's components: from its largest one, so that a vector whose
// components' squares are no f32 (below about 1e-19) keeps its length. As
// crate::cpu::scaled_length.
fn scaled_length(v: vec3<f32>) -> f32 {
    let m = max(abs(v.x), max(abs(v.y), abs(v.z)));
    return select(0.0, m * length(v / m), m > 0.0);
}

// Pushes the refraction ray, then the reflection ray (contract order), for a hit of
// ray r at p with shading normal n and the surface's own normal ng (the rays start off
// the surface along it) on material h, shaded by s. A ray that leaves the grid from
// where it starts (leaves_grid) is counted and not traced: it would hit nothing, and
// tracing it costs a pass of the ray-tree loop, which on a software driver's lanes is a
// whole hit's shading. Under voxlab's rules every ray refracted out of a pane on the
// grid's boundary is one (docs/benchmarks.md, "Where the default model's time goes").
fn spawn(r: RayEntry, p: vec3<f32>, n: vec3<f32>, ng: vec3<f32>, h: u32, s: Material) {
    let d = r.dir;
    var w_r = s.kr;
    if s.kt > 0.0 {
        let eta = materials[r.medium].ior / materials[h].ior;
        let c = -dot(n, d);
        // sin of the incidence from the ray's part along the surface, not 1 - c * c:
        // in f32 that loses a near-normal ray's sin^2 below about 1e-7, and with it the
        // critical angle of a large eta (an ior of 1e3 drew 11 % of the seed scene's
        // pixels apart from the f64 reference). On a voxel face, whose normal is an
        // axis, the part is exact. The refracted sine eta sin_i is squared after the
        // product: eta^2 leaves f32 past an eta of 1.8e19, where eta sin_i need not.
        // And sin_i is the part's length taken at its own scale: squared, the part of a
        // ray that entered a pane of ior 1e30 (1e-30 a component) is no f32 at all.
        let along = d + c * n;
        let sin_t = eta * scaled_length(along);
        let k = 1.0 - sin_t * sin_t;
        // The material's split (dielectric.wgsl); k < 0: total internal reflection.
        let w = split_weights(s, c, sin_t, eta, k < 0.0);
        w_r = w.x;
        if k >= 0.0 && w.y > 0.0 {
#ifdef REFRACTION
            if may_spawn(r, false) && traced(r.throughput * w.y) {
                var t: RayEntry;
                t.origin = p - params.eps * ng;
                // eta d + (eta c - sqrt(k)) n, its two parts apart: eta d and eta c n
                // cancel along n, which a large eta leaves to rounding.
                t.dir = normalize(eta * along - sqrt(k) * n);
                t.throughput = r.throughput * w.y;
                t.depth_reflection = r.depth_reflection;
                t.depth_refraction = r.depth_refraction + 1u;
                t.medium = h;
                if leaves_grid(t.origin, t.dir) {
                    count_secondary();
                    count_untraced();
                } else {
                    push(t);
                }
            }
#endif
        }
    }
#ifdef REFLECTION
    if w_r > 0.0 && may_spawn(r, true) && traced(r.throughput * w_r) {
        var f: RayEntry;
        f.origin = p + params.eps * ng;
        f.dir = d - 2.0 * dot(d, n) * n;
        f.throughput = r.throughput * w_r;
        f.depth_reflection = r.depth_reflection + 1u;
        f.depth_refraction = r.depth_refraction;
        f.medium = r.medium;
        next_ray = f;
        has_next = !leaves_grid(f.origin, f.dir);
        count_secondary();
        if !has_next {
            count_untraced();
        }
    }
#endif
}

// Radiance of the primary ray from origin along dir (ambient included) for one frame;
// t0: the eye's distance to origin along the ray less params.primary_advance, the
// depth origin the primary layers count from (src/gpu/reconstruct.rs, depth_origin).
fn trace_pixel(origin: vec3<f32>, t0: f32, dir: vec3<f32>, key: SampleKey) -> vec3<f32> {
    var primary: RayEntry;
    primary.origin = origin;
    primary.dir = dir;
    primary.throughput = vec3<f32>(1.0);
    primary.depth_reflection = 0u;
    primary.depth_refraction = 0u;
    primary.medium = params.eye_medium;
    count_primary();

    var radiance = params.ambient;
    sp = 0u;
    has_next = false;
    // Set when the tree is done: any other way out is the driver's loop limit.
    var finished = false;
#ifdef PRIMARY_LAYERS
    // Only the first ray traced is the primary ray.
    var first = true;
#endif
    // The ray being traced; the next is taken at the bottom of the loop, which ends
    // there once the tree is done, so no idle ray follows the last (shaders/
    // counters.wgsl).
    var r = primary;
    loop {
        let hit = cast_ray(r.origin, r.dir, r.medium, BIG);
        if !hit.hit {
            continue;
        }
        let p = r.origin + hit.t * r.dir;
        let n = hit.normal;
        // Passing into void, the ray is shaded by the medium it leaves, so the inside
        // face of glass shades as glass.
        var si = hit.material;
        if si == 0u {
            si = r.medium;
        }
        let s = materials[si];
#ifdef EMISSION
        // Emission is seen, not cast: an emissive voxel lights nothing else.
        radiance += r.throughput * s.emission;
#endif
#ifdef SHADOWS
#ifdef TRIANGLES
        shadow_medium = r.medium;
#endif
        let local = local_light(p, n, hit.geometric, r.dir, s, key, weight(r.throughput));
        radiance += r.throughput * local;
#ifdef PRIMARY_LAYERS
        if first {
            primary_direct = local;
            shadows_clear = true;
            primary_unshadowed = local_light(p, n, hit.geometric, r.dir, s, key, weight(r.throughput));
            shadows_clear = false;
        }
#endif
#endif
#ifdef PRIMARY_LAYERS
        if first {
            primary_hit = true;
            primary_normal = n;
            primary_depth = (t0 + hit.t) * params.voxel_size;
            primary_material = si;
        }
#endif
        // The lighting terms (src/technique/: ambient occlusion, indirect light).
#ifdef LIGHTING_TERMS
        radiance += r.throughput * lighting_terms(p, n, s);
#endif
        // No `#if A || B` in naga_oil: spawn whenever either kind of secondary ray is in.
#ifdef REFLECTION
        spawn(r, p, n, hit.geometric, hit.material, s);
#else
#ifdef REFRACTION
        spawn(r, p, n, hit.geometric, hit.material, s);
#endif
#endif
        // The next ray: the reflection just spawned, else the top of the stack.
        continuing {
#ifdef PRIMARY_LAYERS
            first = false;
#endif
            if has_next {
                r = next_ray;
                has_next = false;
            } else if sp > 0u {
                sp -= 1u;
#if RAY_STACK_SIZE <= 9
                let e = stack[0];
#if RAY_STACK_SIZE > 1
                stack[0] = stack[1];
#endif
#if RAY_STACK_SIZE > 2
                stack[1] = stack[2];
#endif
#if RAY_STACK_SIZE > 3
                stack[2] = stack[3];
#endif
#if RAY_STACK_SIZE > 4
                stack[3] = stack[4];
#endif
#if RAY_STACK_SIZE > 5
                stack[4] = stack[5];
#endif
#if RAY_STACK_SIZE > 6
                stack[5] = stack[6];
#endif
#if RAY_STACK_SIZE > 7
                stack[6] = stack[7];
#endif
#if RAY_STACK_SIZE > 8
                stack[7] = stack[8];
#endif
#else
                let e = stack[sp];
#endif
                r.origin = e.origin;
                r.dir = e.dir;
                r.throughput = e.throughput;
                r.depth_reflection = e.packed & 255u;
                r.depth_refraction = (e.packed >> 8u) & 255u;
                r.medium = e.packed >> 16u;
            } else {
                finished = true;
            }
            break if finished || loop_guard();
        }
    }
    if !finished {
        loop_cut();
    }
    return radiance;
}

// One invocation per pixel and frame: the frames of a dispatch are its z, never a loop
// in one invocation, so what one invocation does (and what the driver's loop limit sees,
// shaders/counters.wgsl) is one frame's ray tree however many frames a dispatch holds.
//
// Which pixel an invocation traces. Workgroup (x, y) is the 8x8 tile x * groups.y + y of
// the image's raster order: the host dispatches the tiles in stripes so that the
// software driver's threads, each handed a contiguous run of workgroups, get equal
// shares of the image (DISPATCH_STRIPES, src/gpu/mod.rs). In a tile, each run of 8
// invocations (the software driver's SIMD vector, filled in local index order) is a
// 4x2 block rather than a row of 8: nearer rays take more alike paths, and a vector
// runs until its slowest lane is done.
@compute @workgroup_size(8, 8, 1)
fn main(
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
) {
    let tiles_x = (params.width + 7u) / 8u;
    let tile = wid.x * groups.y + wid.y;
    let block = li / 8u;
    let gid = vec3<u32>(
        (tile % tiles_x) * 8u + (block % 2u) * 4u + li % 4u,
        (tile / tiles_x) * 8u + (block / 2u) * 2u + (li % 8u) / 4u,
        wid.z,
    );
    if gid.x >= params.width || gid.y >= params.height || gid.z >= params.frame_count {
        return;
    }
    let i = gid.y * params.width + gid.x;
    // Pixel centre, rows from the top (CameraFrame::primary_dir), moved per frame by the
    // pixel filter (PixelFilter::offset).
    var offset = vec2<f32>(0.5);
#ifdef PIXEL_FILTER
    let uv = pixel_sample(params.seed, i, params.frame_begin + gid.z);
    if params.pixel_filter == PIXEL_FILTER_BOX {
        offset += (2.0 * uv - 1.0) * params.filter_width;
    } else if params.pixel_filter == PIXEL_FILTER_GAUSSIAN {
        let r = params.filter_width * sqrt(-2.0 * log(1.0 - uv.x));
        let phi = 6.283185307179586 * uv.y;
        offset += r * vec2<f32>(cos(phi), sin(phi));
    }
#endif
    let sx = 2.0 * (f32(gid.x) + offset.x) / f32(params.width) - 1.0;
    let sy = 1.0 - 2.0 * (f32(gid.y) + offset.y) / f32(params.height);
    let along = params.forward + sx * params.right_scaled + sy * params.up_scaled;
    let dir = normalize(along);
    // The eye, or for a far one the point `primary_advance` along the pixel's way (the
    // part along `forward` added on the host in f64): an eye placed in f32 far out is
    // only as precise as its ulp. Exactly the eye and 0 when primary_advance is 0.
    let across = sx * params.right_scaled + sy * params.up_scaled;
    let origin = params.eye + params.primary_advance * across;
    // The way to origin less the advance: advance (|along| - 1), with |along|^2 = 1 +
    // |across|^2 (across is orthogonal to forward), so that a far eye's depth keeps
    // its digits in f32 (0 when primary_advance is 0).
    let t0 = params.primary_advance * dot(across, across) / (length(along) + 1.0);
    var key: SampleKey;
    key.pixel = i;
    key.frame = params.frame_begin + gid.z;
    let radiance = trace_pixel(origin, t0, dir, key);
#ifdef CONES
    if cone_loop_cut {
        loop_cut();
    }
#endif
    // ACCUMULATE: frame z's slice of `output`; shaders/accumulate.wgsl adds the slices to
    // the running sums in frame order. Otherwise one frame, the image itself.
#ifdef PRIMARY_LAYERS
    write_layers(gid.z, i, key.frame, radiance);
#else
    output[gid.z * params.width * params.height + i] = vec4<f32>(radiance, 1.0);
#endif
    flush_counts();
}
