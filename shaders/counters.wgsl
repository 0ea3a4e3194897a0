// Ray counting (COUNT_RAYS). Counts accumulate per invocation in private memory and are
// added to the global 64-bit counters once at the end, so the atomics stay few. Without
// COUNT_RAYS every function is empty and the compiler drops the calls.
#define_import_path voxlab::counters

#import voxlab::bindings::{counters, params}

// Index of the counter of invocations whose loops the driver cut short (see loop_cut).
const LOOPS_CUT: u32 = 8u;

// Set when a loop of this invocation ended without meeting any of its own exit
// conditions. Mesa's software rasteriser (llvmpipe, lavapipe) builds every shader with
// one loop limiter per SIMD vector of invocations, shared by all of its loops
// (LP_MAX_TGSI_LOOP_ITERATIONS = 65535 back edges, src/gallium/auxiliary/gallivm/
// lp_bld_limits.h and lp_bld_ir_common.c, lp_exec_endloop); once it runs out, every loop
// leaves at its next back edge, silently. Each loop of the tracer checks after it ends
// that it ended for a reason of its own and calls this otherwise, so a cut walk is an
// error on the host (src/gpu/mod.rs), never a wrong image.
//
// The same driver runs a SIMD vector's loop body under a mask of the lanes still in it,
// every statement of the body whatever the mask (an `if` is a mask, never a jump), and
// tests for a lane left only at the back edge (lp_exec_endloop). A loop that tests its
// exit at the top (`for (; cond; ...)`, `loop { if !cond { break; } ... }`) therefore
// runs its whole body once more after its last lane is done: the pass in which every
// lane fails the test. For the walks that is one idle step per walk, for the light loop
// one idle light (its Phong term and a shadow walk's set-up and step), for the ray tree
// one idle ray. So every loop of the tracer that runs at least once tests its exit at
// the bottom (`continuing { ...; break if done; }`): the back edge then finds no lane
// and leaves (seed_rules at 16^3, 512x512, lavapipe: README "What each change to the
// kernel bought").
var<private> loops_cut: bool;

fn loop_cut() {
    loops_cut = true;
}

// What keeps those checks in the driver's code: every loop leaves with
// `break if <its exit> || loop_guard()`. The limiter is added below NIR (in gallivm's
// LLVM IR), so to Mesa's NIR optimiser a loop whose only exit is `break if done` proves
// `done` after it, and the check `if !done { loop_cut(); }` is dead code to it (likely
// nir_opt_if, which replaces a condition's uses in the blocks its branch dominates;
// release builds of Mesa print no NIR to show it). So it was for the cone marches,
// whose check tests the exit's own boolean: at `cones.step_factor = 1e-4` they came
// back wrong on lavapipe with no cut reported, and are refused since
// (tests/loop_limit.rs). With wgpu's loop counter (force_loop_bounding, dropped in
// src/gpu/mod.rs) every loop had a second exit and the checks stood.
// `params.loop_guard` is always 0 but a uniform, so no compiler can drop it, and the
// loop's exit no longer proves what the check after it tests.
fn loop_guard() -> bool {
    return params.loop_guard != 0u;
}

// primary, secondary, shadow, voxel steps. One invocation's counts fit u32 easily.
var<private> local_counts: vec4<u32>;

fn count_primary() {
#ifdef COUNT_RAYS
    local_counts.x += 1u;
#endif
}

fn count_secondary() {
#ifdef COUNT_RAYS
    local_counts.y += 1u;
#endif
}

// Set while the kernel shades the primary hit a second time with every shadow segment
// clear (PRIMARY_LAYERS, shaders/trace.wgsl): shaders/phong.wgsl's shadow_to then walks
// nothing, and the shadow rays of that pass, which are not traced, are not counted.
var<private> shadows_clear: bool;

fn count_shadow() {
#ifdef COUNT_RAYS
#ifdef PRIMARY_LAYERS
    if shadows_clear {
        return;
    }
#endif
    local_counts.z += 1u;
#endif
}

fn count_step() {
#ifdef COUNT_RAYS
    local_counts.w += 1u;
#endif
}

// A secondary ray counted without being traced (trace.wgsl, spawn: it leaves the grid
// where it starts), also counted by count_secondary.
var<private> local_untraced: u32;
fn count_untraced() {
#ifdef COUNT_RAYS
    local_untraced += 1u;
#endif
}

#ifdef COUNT_RAYS
// A 64-bit add from two u32 atomics: the old low word tells exactly whether this add
// carried, because each atomicAdd is applied alone.
fn add64(i: u32, v: u32) {
    if v == 0u {
        return;
    }
    let old = atomicAdd(&counters[2u * i], v);
    if old + v < old {
        atomicAdd(&counters[2u * i + 1u], 1u);
    }
}
#endif

fn flush_counts() {
    if loops_cut {
        atomicAdd(&counters[LOOPS_CUT], 1u);
    }
#ifdef COUNT_RAYS
    add64(0u, local_counts.x);
    add64(1u, local_counts.y);
    add64(2u, local_counts.z);
    add64(3u, local_counts.w);
    add64(5u, local_untraced);
#endif
}
