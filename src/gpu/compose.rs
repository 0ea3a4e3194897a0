//! Shader composition: the WGSL files under `shaders/` (one per concern) are joined by
//! naga_oil's `Composer` into one `naga::Module` per plan variant, validated by naga, and
//! handed to wgpu as IR (`ShaderSource::Naga`), so no WGSL text is re-parsed by wgpu.

use std::collections::HashMap;

use naga::valid::{Capabilities, ValidationFlags, Validator};
use naga_oil::compose::{
    ComposableModuleDescriptor, Composer, NagaModuleDescriptor, ShaderDefValue,
};

use crate::plan::Plan;

/// `voxlab::types`: the layouts shared with the host, imported by every kernel.
pub(crate) const TYPES_MODULE: (&str, &str) = (
    "shaders/types.wgsl",
    include_str!("../../shaders/types.wgsl"),
);

/// `voxlab::emission`: imported by the tracer and the radiance injection.
pub(crate) const EMISSION_MODULE: (&str, &str) = (
    "shaders/emission.wgsl",
    include_str!("../../shaders/emission.wgsl"),
);

/// `voxlab::tree`: the descent through the sparse tree, imported by the traversals
/// that walk it (`TraversalModel::walks_tree`).
const TREE_MODULE: (&str, &str) = ("shaders/tree.wgsl", include_str!("../../shaders/tree.wgsl"));

/// Importable modules in dependency order (each imports only modules above it).
/// Embedded at build time so the tracer does not depend on the working directory.
const MODULES: &[(&str, &str)] = &[
    TYPES_MODULE,
    EMISSION_MODULE,
    (
        "shaders/dielectric.wgsl",
        include_str!("../../shaders/dielectric.wgsl"),
    ),
    (
        "shaders/bindings.wgsl",
        include_str!("../../shaders/bindings.wgsl"),
    ),
    (
        "shaders/counters.wgsl",
        include_str!("../../shaders/counters.wgsl"),
    ),
    (
        "shaders/sampling.wgsl",
        include_str!("../../shaders/sampling.wgsl"),
    ),
    (
        "shaders/triangles.wgsl",
        include_str!("../../shaders/triangles.wgsl"),
    ),
    (
        "shaders/box_codes.wgsl",
        include_str!("../../shaders/box_codes.wgsl"),
    ),
    (
        "shaders/traversal.wgsl",
        include_str!("../../shaders/traversal.wgsl"),
    ),
];

/// Composed after [`MODULES`] and the plan's transmittance model (`voxlab::transmittance`,
/// which the shadow walks import), in dependency order.
const SHADOW_MODULES: &[(&str, &str)] = &[
    (
        "shaders/shadow.wgsl",
        include_str!("../../shaders/shadow.wgsl"),
    ),
    (
        "shaders/shadow_surface.wgsl",
        include_str!("../../shaders/shadow_surface.wgsl"),
    ),
    super::pyramid::CONE_MODULE,
    (
        "shaders/phong.wgsl",
        include_str!("../../shaders/phong.wgsl"),
    ),
    (
        "shaders/area_lights.wgsl",
        include_str!("../../shaders/area_lights.wgsl"),
    ),
];

/// Composed after [`SHADOW_MODULES`] and the plan's shadow model (which may import any
/// of them): the local light, which imports the model.
const SHADING: (&str, &str) = (
    "shaders/shading.wgsl",
    include_str!("../../shaders/shading.wgsl"),
);

/// The entry point's file; its entry point is `main`.
const TRACE: (&str, &str) = (
    "shaders/trace.wgsl",
    include_str!("../../shaders/trace.wgsl"),
);

pub const ENTRY_POINT: &str = "main";

/// The accumulation kernel (`shaders/accumulate.wgsl`): standalone, entry point `main`.
pub const ACCUMULATE: (&str, &str) = (
    "shaders/accumulate.wgsl",
    include_str!("../../shaders/accumulate.wgsl"),
);

#[derive(Debug, thiserror::Error)]
pub enum ShaderError {
    #[error("composing the tracer shader ({defs}):\n{message}")]
    Compose { defs: String, message: String },
    #[error("validating the composed tracer shader ({defs}):\n{message}")]
    Validate { defs: String, message: String },
}

fn defs_string(plan: &Plan) -> String {
    plan.shader_defs()
        .iter()
        .map(|(k, v)| format!("{k}={v:?}"))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Composes `entry` with importable `modules` (in dependency order) under `defs`;
/// the error is naga_oil's report. Not validated.
pub(super) fn compose(
    modules: &[(&str, &str)],
    entry: (&str, &str),
    defs: HashMap<String, ShaderDefValue>,
) -> Result<naga::Module, String> {
    let mut composer = Composer::default();
    for (path, source) in modules {
        let source = expand_walk_steps(source);
        if let Err(e) = composer.add_composable_module(ComposableModuleDescriptor {
            source: &source,
            file_path: path,
            shader_defs: defs.clone(),
            ..Default::default()
        }) {
            return Err(e.emit_to_string(&composer));
        }
    }
    let entry_source = expand_walk_steps(entry.1);
    let module = composer.make_naga_module(NagaModuleDescriptor {
        source: &entry_source,
        file_path: entry.0,
        shader_defs: defs,
        ..Default::default()
    });
    module.map_err(|e| e.emit_to_string(&composer))
}

/// The directive that writes a walk's unrolled steps, so the four walks (`cast_ray`, the
/// shadow walks, the distance-field penumbra) share one template: a line
/// `#walk_steps done = step(args);` becomes that statement, then `if !done { done =
/// step(args); }` repeated to `DDA_UNROLL` steps (1, 2, 4 or 8) under naga_oil's `#if`.
/// The expansion adds lines, so a composition error's line number in a file that uses
/// the directive counts them.
const WALK_STEPS: &str = "#walk_steps ";

/// `source` with every [`WALK_STEPS`] line expanded (unchanged, and not copied, when it
/// has none).
pub(super) fn expand_walk_steps(source: &str) -> std::borrow::Cow<'_, str> {
    if !source.contains(WALK_STEPS) {
        return std::borrow::Cow::Borrowed(source);
    }
    let mut out = String::with_capacity(source.len() + 1024);
    for line in source.lines() {
        let trimmed = line.trim_start();
        let Some(statement) = trimmed.strip_prefix(WALK_STEPS) else {
            out += line;
            out.push('\n');
            continue;
        };
        let indent = &line[..line.len() - trimmed.len()];
        let flag = statement
            .split_once(" = ")
            .map_or("done", |(name, _)| name.trim());
        let again = format!("{indent}if !{flag} {{ {} }}\n", statement.trim());
        out += &format!("{indent}{}\n", statement.trim());
        for (at_least, repeats) in [(2, 1), (4, 2), (8, 4)] {
            out += &format!("#if DDA_UNROLL >= {at_least}\n");
            for _ in 0..repeats {
                out += &again;
            }
            out += "#endif\n";
        }
    }
    std::borrow::Cow::Owned(out)
}

/// `voxlab::lighting_terms` for `plan`: `fn lighting_terms(p, n, s) -> vec3<f32>`, the
/// sum of the planned terms' `term` (src/technique/), in registry order. Written per
/// plan because a shader cannot list modules it does not know; without terms it
/// returns 0 and `LIGHTING_TERMS` leaves its call out.
fn lighting_terms_module(plan: &Plan) -> String {
    let mut imports = String::new();
    let mut sum = String::from("vec3<f32>(0.0)");
    for (i, t) in plan.terms.iter().enumerate() {
        let path = t
            .wgsl
            .1
            .lines()
            .find_map(|l| l.trim().strip_prefix("#define_import_path "))
            .expect("a lighting term's module declares its import path")
            .trim();
        imports += &format!("#import {path}::{{term as term_{i}}}\n");
        sum += &format!(" + term_{i}(p, n, s)");
    }
    format!(
        "#define_import_path voxlab::lighting_terms\n\
         #import voxlab::types::Material\n\
         {imports}\n\
         fn lighting_terms(p: vec3<f32>, n: vec3<f32>, s: Material) -> vec3<f32> {{\n    \
         return {sum};\n}}\n"
    )
}

/// Composes and validates the tracer kernel for `plan`. Pure CPU: no device needed.
pub fn compose_shader(plan: &Plan) -> Result<naga::Module, ShaderError> {
    let defs: HashMap<_, _> = plan.shader_defs().into_iter().collect();
    let mut modules = MODULES.to_vec();
    // The traversal's regions, which the walks (shaders/traversal.wgsl, the last of
    // MODULES) import.
    modules.insert(modules.len() - 1, plan.traversal.wgsl);
    if plan.traversal.walks_tree {
        modules.insert(modules.len() - 2, TREE_MODULE);
    }
    modules.push(plan.transmittance.wgsl);
    modules.extend_from_slice(SHADOW_MODULES);
    modules.push(plan.shadow_model.wgsl);
    modules.push(SHADING);
    modules.extend(plan.terms.iter().map(|t| t.wgsl));
    let terms = lighting_terms_module(plan);
    modules.push(("voxlab::lighting_terms (src/gpu/compose.rs)", &terms));
    let module = compose(&modules, TRACE, defs).map_err(|message| ShaderError::Compose {
        defs: defs_string(plan),
        message,
    })?;
    validate(&module).map_err(|message| ShaderError::Validate {
        defs: defs_string(plan),
        message,
    })?;
    Ok(module)
}

/// Validation with the capabilities of plain WebGPU: the kernel needs nothing more.
pub fn validate(module: &naga::Module) -> Result<naga::valid::ModuleInfo, String> {
    Validator::new(ValidationFlags::all(), Capabilities::empty())
        .validate(module)
        .map_err(|e| format!("{e:?}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn walk_steps_unroll_to_one_two_four_and_eight_steps() {
        let src = "fn f() {\n    loop {\n        #walk_steps done = step(&s, 1.0);\n    }\n}\n";
        let out = expand_walk_steps(src);
        let calls = out.matches("step(&s, 1.0)").count();
        assert_eq!(calls, 1 + 1 + 2 + 4, "{out}");
        assert_eq!(out.matches("if !done { done = step(&s, 1.0); }").count(), 7);
        assert!(out.contains("\n        done = step(&s, 1.0);\n#if DDA_UNROLL >= 2\n"));
        assert!(!out.contains("#walk_steps"));
        // Without the directive, the source is passed through as it is.
        let plain = "fn g() {}\n";
        assert!(matches!(
            expand_walk_steps(plain),
            std::borrow::Cow::Borrowed(_)
        ));
        // No file under shaders/ writes the unrolled steps by hand any more.
        for (path, text) in MODULES.iter().chain(SHADOW_MODULES) {
            assert!(
                !text.contains("#if DDA_UNROLL >= 2"),
                "{path} unrolls by hand"
            );
        }
    }

    /// Composes `plan`'s kernel and writes it as SPIR-V, as wgpu's Vulkan backend does
    /// when it makes the pipeline: naga's SPIR-V writer refuses (panics on) some IR its
    /// validator accepts, such as a pointer to a struct member passed as an argument.
    fn compose_to_spirv(plan: &Plan) -> naga::Module {
        let module = compose_shader(plan).unwrap_or_else(|e| panic!("{e}"));
        let info = validate(&module).unwrap();
        naga::back::spv::write_vec(&module, &info, &naga::back::spv::Options::default(), None)
            .unwrap_or_else(|e| panic!("SPIR-V of {plan}: {e}"));
        module
    }

    #[test]
    fn every_plan_variant_composes_and_validates() {
        for stack in [1, 9] {
            for mut plan in Plan::all_variants(stack) {
                // Both rules, without doubling the variants: the seed's with the larger
                // stack (tests/gpu_frames.rs renders both at random depth limits).
                plan.seed_rules = stack > 1;
                for traversal in crate::technique::TRAVERSALS {
                    plan.traversal = traversal;
                    plan.tree_levels = if traversal.walks_tree { 3 } else { 0 };
                    let module = compose_to_spirv(&plan);
                    assert!(
                        module.entry_points.iter().any(|e| e.name == ENTRY_POINT),
                        "no entry point for {plan}"
                    );
                }
            }
        }
    }

    /// The kernel's uniform material table holds every material a scene may define:
    /// the host pads its upload to that length (`GpuTracer::upload_scene`).
    #[test]
    fn the_material_table_has_a_slot_for_every_material() {
        let plan = Plan::all_variants(9).pop().unwrap();
        let module = compose_shader(&plan).unwrap_or_else(|e| panic!("{e}"));
        let (_, materials) = module
            .global_variables
            .iter()
            // naga_oil decorates an imported name with its module's.
            .find(|(_, g)| {
                g.name
                    .as_deref()
                    .is_some_and(|n| n.starts_with("materials"))
            })
            .expect("the kernel reads the materials");
        assert_eq!(materials.space, naga::AddressSpace::Uniform);
        let naga::TypeInner::Array { size, .. } = module.types[materials.ty].inner else {
            panic!("materials is an array");
        };
        let naga::ArraySize::Constant(n) = size else {
            panic!("a uniform array has a fixed length");
        };
        assert_eq!(n.get() as usize, crate::scene::MAX_MATERIALS);
    }

    #[test]
    fn sparse_variants_compose_at_every_depth() {
        for levels in 1..=crate::sparse::MAX_GPU_LEVELS {
            for mut plan in [
                Plan::all_variants(9).pop().unwrap(),
                Plan::all_variants(1)[0].clone(),
            ] {
                plan.traversal = crate::technique::traversal("sparse").unwrap();
                plan.tree_levels = levels;
                compose_to_spirv(&plan);
            }
        }
    }

    /// The sparse octant walk's kernels (without codes, with them, with the cells'
    /// heads) with its codes in `walk_data` or in one to three further bindings.
    #[test]
    fn sparse_octant_kernels_compose() {
        let mut plan = Plan::all_variants(9).pop().unwrap();
        plan.traversal = crate::technique::traversal("sparse_octant").unwrap();
        for levels in 1..=3 {
            for variant in 0..=2 {
                for more in 0..=crate::technique::WALK_MORE_BINDINGS as u32 {
                    plan.tree_levels = levels;
                    plan.walk_variant = variant;
                    plan.walk_more_bindings = more;
                    compose_to_spirv(&plan);
                }
            }
        }
    }

    #[test]
    fn left_out_code_is_absent() {
        // Without REFLECTION, REFRACTION and SHADOWS the module has no transmittance walk.
        let bare = &Plan::all_variants(1)[0];
        let full = Plan::all_variants(9).pop().unwrap();
        let n_bare = compose_shader(bare).unwrap().functions.len();
        let n_full = compose_shader(&full).unwrap().functions.len();
        assert!(n_bare < n_full, "bare {n_bare} functions, full {n_full}");
    }
}
