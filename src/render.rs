//! The render settings: the image, the ray tree's limits and rules, and the techniques
//! chosen for each slot (entries of `crate::technique`'s registries), which is why this
//! module sits in the techniques layer (docs/layout.md) and what a render gives is in
//! `crate::frame`.

/// How a shadow segment through semi-transparent voxels is attenuated (`src/trace_contract.md`):
/// one of the registered transmittance models (`crate::technique::TRANSMITTANCES`,
/// each in its own file). The default is the first, the baseline's `min-kt`.
#[derive(Clone, Copy)]
pub struct Transmittance(pub &'static crate::technique::TransmittanceModel);

impl Transmittance {
    pub fn name(self) -> &'static str {
        self.0.name
    }
    pub fn model(self) -> &'static crate::technique::TransmittanceModel {
        self.0
    }
}

impl Default for Transmittance {
    fn default() -> Self {
        Self(crate::technique::TRANSMITTANCES[0])
    }
}

// A model is its name: the registry holds one value per name.
impl PartialEq for Transmittance {
    fn eq(&self, other: &Self) -> bool {
        self.0.name == other.0.name
    }
}

impl Eq for Transmittance {}

impl std::fmt::Debug for Transmittance {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Transmittance({})", self.0.name)
    }
}

/// Which rules of the ray tree the tracers follow (`src/trace_contract.md`; the seed's code is
/// `shaders/raytracing.frag` of its repository).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Rules {
    /// voxlab's model: reflection and refraction depths counted apart, outside the grid
    /// is void (a ray leaving a non-void medium through the boundary hits void at the
    /// exit face, so padding a scene with void never changes its image), and under total
    /// internal reflection the refracted share `kt` goes to the reflection ray.
    #[default]
    Consistent,
    /// The seed's code: one recursion depth per ray, checked against both limits (a
    /// tree of 4/4 is at most 4 deep); leaving the grid is a miss; under total internal
    /// reflection GLSL's `refract` returns the zero vector, whose ray hits nothing, so
    /// the refracted share is lost and the reflection keeps its own `kr`.
    Seed,
}

impl Rules {
    pub fn name(self) -> &'static str {
        match self {
            Rules::Consistent => "consistent",
            Rules::Seed => "seed",
        }
    }
}

/// How each frame's primary ray samples its pixel: the reconstruction filter, realised
/// by distributing the rays' positions like it (filter importance sampling, A. Ernst et
/// al., "Filter Importance Sampling", IEEE RT 2006), so frames average with equal
/// weights and the accumulated image converges to the filtered one.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum PixelFilter {
    /// Every ray through the pixel centre (the seed's image, aliased).
    #[default]
    None,
    /// Uniform over a square of half-width `filter_width` pixels (0.5: the pixel).
    Box,
    /// Gaussian of standard deviation `filter_width` pixels (Box-Muller, untruncated).
    Gaussian,
}

/// How rays walk the grid (`render.traversal`): a registered traversal by name
/// (`crate::technique::TRAVERSALS`), or the plan's choice. All give the same hits; only
/// the time and the memory differ.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Traversal {
    /// The plan chooses by the grid (`crate::plan::Plan::traversal`).
    #[default]
    Auto,
    Walk(&'static crate::technique::TraversalModel),
}

impl Traversal {
    /// `auto`, then every registered traversal.
    pub fn all() -> Vec<Traversal> {
        std::iter::once(Traversal::Auto)
            .chain(Self::walks())
            .collect()
    }

    /// Every registered traversal, by name (no `auto`).
    pub fn walks() -> Vec<Traversal> {
        crate::technique::TRAVERSALS
            .iter()
            .map(|t| Traversal::Walk(t))
            .collect()
    }

    pub fn name(self) -> &'static str {
        match self {
            Traversal::Auto => "auto",
            Traversal::Walk(t) => t.name,
        }
    }

    /// The choice called `name` (`auto` or a traversal's name).
    pub fn named(name: &str) -> Option<Traversal> {
        Traversal::all().into_iter().find(|t| t.name() == name)
    }
}

/// What a ray hits (`render.surface`): a registered surface
/// (`crate::technique::SURFACES`): the voxels' faces (the baseline), or triangles found
/// through the voxels they overlap (`crate::triangles`, the seed's O6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Surface(pub &'static crate::technique::SurfaceModel);

impl Default for Surface {
    fn default() -> Self {
        Surface(crate::technique::default_surface())
    }
}

impl std::ops::Deref for Surface {
    type Target = crate::technique::SurfaceModel;
    fn deref(&self) -> &Self::Target {
        self.0
    }
}

impl Surface {
    /// Every registered surface.
    pub fn all() -> Vec<Surface> {
        crate::technique::SURFACES
            .iter()
            .map(|s| Surface(s))
            .collect()
    }

    pub fn name(self) -> &'static str {
        self.0.name
    }

    /// The surface called `name`.
    pub fn named(name: &str) -> Option<Surface> {
        crate::technique::surface(name).map(Surface)
    }

    /// What [`Self::trace`] reads of `scene`, hashed: the kind, the grid's placement, its
    /// voxels (`voxels`: the grid's content hash, which the caller has taken), the
    /// materials' count and the surface's own inputs (a mesh). Equal keys list the same
    /// triangles: the GPU tracer keys its upload by it, a CPU session its kept trace.
    pub fn trace_key(self, scene: &crate::scene::Scene, voxels: blake3::Hash) -> blake3::Hash {
        let mut h = blake3::Hasher::new();
        h.update(self.name().as_bytes());
        let g = &scene.grid;
        h.update(format!("{:?}", (g.dims(), g.voxel_size(), g.origin())).as_bytes());
        h.update(voxels.as_bytes());
        h.update(&(scene.materials.len() as u64).to_le_bytes());
        (self.hash_inputs)(scene, &mut h);
        h.finalize()
    }

    /// The triangles this surface traces in `scene`, listed in its grid: none for voxels
    /// (or a mesh surface on a scene without a mesh, which the plan has refused
    /// already), the scene's mesh, or the smooth surface of its grid
    /// (`crate::surface::extract`, relaxed [`crate::surface::DEFAULT_RELAX`] times).
    pub fn trace(
        self,
        scene: &crate::scene::Scene,
    ) -> Result<Option<crate::triangles::SurfaceTrace>, crate::triangles::TriangleError> {
        let Some(triangles) = self.triangles else {
            return Ok(None);
        };
        let mesh = triangles(scene).map_err(crate::triangles::TriangleError::Extract)?;
        crate::triangles::SurfaceTrace::build(&scene.grid, scene.materials.len(), &mesh).map(Some)
    }
}

impl PixelFilter {
    pub(crate) const ALL: [PixelFilter; 3] =
        [PixelFilter::None, PixelFilter::Box, PixelFilter::Gaussian];

    pub fn name(self) -> &'static str {
        match self {
            PixelFilter::None => "none",
            PixelFilter::Box => "box",
            PixelFilter::Gaussian => "gaussian",
        }
    }

    /// `PIXEL_FILTER_*` of shaders/types.wgsl.
    pub fn code(self) -> u32 {
        match self {
            PixelFilter::None => 0,
            PixelFilter::Box => 1,
            PixelFilter::Gaussian => 2,
        }
    }

    /// The offset (pixels) from the pixel centre of frame `frame`'s primary ray.
    pub fn offset(self, width: f64, seed: u32, pixel: u32, frame: u32) -> (f64, f64) {
        let (u, v) = crate::sampling::pixel_sample(seed, pixel, frame);
        match self {
            PixelFilter::None => (0.0, 0.0),
            PixelFilter::Box => ((2.0 * u - 1.0) * width, (2.0 * v - 1.0) * width),
            PixelFilter::Gaussian => {
                let r = width * (-2.0 * (1.0 - u).ln()).sqrt();
                let (s, c) = (std::f64::consts::TAU * v).sin_cos();
                (r * c, r * s)
            }
        }
    }
}

/// Largest `filter_width` accepted, pixels.
pub(crate) const MAX_FILTER_WIDTH: f64 = 4.0;

/// Extensions beyond the seed. `Features::default()` is the baseline: hard shadows, the
/// default transmittance, no lighting term.
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    /// How each light's visibility is estimated: one of the registered shadow models
    /// (`crate::technique::SHADOW_MODELS`, each in its own file); the default is the
    /// first, the baseline's hard shadows.
    pub shadow_model: &'static crate::technique::ShadowModel,
    pub transmittance: Transmittance,
    /// The lighting terms switched on (`crate::technique::LIGHTING_TERMS`, each in its
    /// own file: ambient occlusion, indirect light), in registry order; each adds its
    /// radiance at every hit. None: the baseline.
    pub terms: Vec<&'static crate::technique::LightingTerm>,
    /// How the sampled shadow term is filtered before shading: one of the registered
    /// reconstructions (`crate::technique::RECONSTRUCTIONS`); the default is the first,
    /// none.
    pub reconstruction: &'static crate::technique::Reconstruction,
}

impl Default for Features {
    fn default() -> Self {
        Self {
            shadow_model: crate::technique::default_shadow_model(),
            transmittance: Transmittance::default(),
            terms: Vec::new(),
            reconstruction: crate::technique::default_reconstruction(),
        }
    }
}

impl Features {
    /// Chooses the shadow model called `name`; false, and nothing changed, for an
    /// unknown name.
    pub fn set_shadow_model(&mut self, name: &str) -> bool {
        match crate::technique::shadow_model(name) {
            Some(m) => {
                self.shadow_model = m;
                true
            }
            None => false,
        }
    }

    /// Whether the lighting term called `name` (or its short name) is on.
    pub fn term(&self, name: &str) -> bool {
        self.terms.iter().any(|t| t.name == name || t.short == name)
    }

    /// Switches the lighting term called `name` (or its short name) on or off, keeping
    /// the registry's order; false, and nothing changed, for an unknown name.
    pub fn set_term(&mut self, name: &str, on: bool) -> bool {
        let Some(term) = crate::technique::lighting_term(name) else {
            return false;
        };
        self.terms.retain(|t| t.name != term.name);
        if on {
            self.terms.push(term);
            self.terms.sort_by_key(|t| t.index());
        }
        true
    }

    /// Whether any feature needs the cone-tracing pyramids.
    pub fn cones(&self) -> bool {
        self.shadow_model.pyramid || self.terms.iter().any(|t| t.pyramid)
    }
}

/// Knobs of voxel cone tracing (`[cones]` of an experiment file; C. Crassin et al.,
/// "Interactive Indirect Illumination Using Voxel Cone Tracing", CGF 30(7), 2011).
/// Lengths in voxels. Used only when a cone feature is on.
#[derive(Clone, Debug, PartialEq)]
pub struct ConeSettings {
    /// Pyramid levels; 0 chooses automatically (`cpu::pyramid::PyramidLayout::new`).
    pub levels: u32,
    /// Step length in footprints: `dt = step_factor * d`.
    pub step_factor: f64,
    /// Shadow-cone aperture for point lights, degrees (area lights use the angle they
    /// subtend).
    pub aperture_deg: f64,
    /// Cone apex offset along the surface normal, voxels (against self-occlusion).
    pub start_offset: f64,
    /// Hemisphere cones for ambient occlusion and indirect light.
    pub ao_cones: u32,
    /// Range of the AO cones, voxels.
    pub ao_range: f64,
    /// Scale of the one-bounce indirect diffuse term.
    pub indirect_strength: f64,
}

impl Default for ConeSettings {
    /// The defaults declared with each `[cones]` key (`crate::technique::cones`).
    fn default() -> Self {
        let d = crate::technique::cones::declared_default;
        Self {
            levels: d("levels") as u32,
            step_factor: d("step_factor"),
            aperture_deg: d("aperture_deg"),
            start_offset: d("start_offset"),
            ao_cones: d("ao_cones") as u32,
            ao_range: d("ao_range"),
            indirect_strength: d("indirect_strength"),
        }
    }
}

/// Settings that are not part of the scene (`src/trace_contract.md`, baseline constants).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Reflection and refraction have separate depth limits (seed: 4 and 4).
    pub max_reflection_depth: u32,
    pub max_refraction_depth: u32,
    /// Total depth of the ray tree: a secondary ray is spawned only while its parent's
    /// reflection plus refraction depth is below it. `None`: no limit beyond the two
    /// above. Separate limits let a glass scene's tree grow with its mixed paths
    /// (2^(a+b) rays at 4/4 and beyond); this bounds it.
    pub max_depth: Option<u32>,
    /// The ray-tree rules: voxlab's consistent model or the seed's.
    pub rules: Rules,
    /// Inverse-square falloff of point lights.
    pub falloff: bool,
    /// `E = I / max(d^2, d_min^2)`: `d_min` in world units, so a light at distance 0 stays finite.
    pub falloff_min_distance: f64,
    /// Secondary and shadow rays start this many voxel widths off the surface (seed: 0.001).
    pub ray_offset: f64,
    /// Adaptive depth control (Hall and Greenberg 1983): a secondary ray whose path
    /// weight falls below this is not traced, nor a light whose largest contribution
    /// times the path weight does (`crate::ray_cutoff`). 0 traces the whole tree.
    pub ray_cutoff: f64,
    pub features: Features,
    /// Samples per pixel, light and frame on each sampled area light (stratified).
    pub light_samples: u32,
    /// Frames accumulated into the image; each draws new light samples. The total
    /// samples per pixel and area light are `spp * light_samples`.
    pub spp: u32,
    /// Seeds the sample hash, so two experiments can draw independent samples.
    pub seed: u32,
    /// Frames of a camera path rendered for one image, the image being the last
    /// (`crate::Session::render`): a temporal reconstruction's history. 1: no path.
    pub path_frames: u32,
    /// Degrees the camera's yaw turns from one frame of the path to the next, about
    /// its target; the last frame is the experiment's camera.
    pub orbit_deg: f64,
    /// Cone-tracing knobs, used only when a cone feature is on.
    pub cones: ConeSettings,
    /// Settings of plug-in techniques (`[techniques.<name>]`).
    pub technique_params: crate::technique::TechniqueParams,
    /// How primary rays sample their pixels (anti-aliasing); `None` is the baseline.
    pub pixel_filter: PixelFilter,
    /// The filter's half-width (box) or standard deviation (Gaussian), pixels.
    pub filter_width: f64,
    /// Dense DDA, sparse tree, or the plan's choice.
    pub traversal: Traversal,
    /// The most MiB each binding of a traversal's own data may take where it chooses what
    /// to hold (the sparse octant walk's codes, in up to
    /// [`crate::technique::WALK_MORE_BINDINGS`] bindings beside its tree and cut): 0 is
    /// the tracer's own budget, the device's largest binding on the GPU and lavapipe's
    /// 128 MiB on the CPU reference (`crate::technique::walk_budget`). The image is the
    /// same at any budget; the steps are not.
    pub walk_budget_mib: u32,
    /// Voxel faces, or triangles found through the voxels.
    pub surface: Surface,
}

/// Largest `light_samples` and `spp` accepted.
pub const MAX_SAMPLES: u32 = 1 << 16;

/// Largest depth limit accepted: the ray stack holds `max_reflection + max_refraction + 1`
/// entries, and the ray tree grows as 2^depth.
pub const MAX_DEPTH_LIMIT: u32 = 16;

/// Largest `max_depth` accepted: the two limits' sum at most.
pub(crate) const MAX_TOTAL_DEPTH_LIMIT: u32 = 2 * MAX_DEPTH_LIMIT;

/// Largest `path_frames` accepted.
pub const MAX_PATH_FRAMES: u32 = 1024;

/// Largest image side accepted.
pub const MAX_IMAGE_SIDE: u32 = 16384;

impl Default for RenderSettings {
    /// The seed's settings: 512x512, depth 4/4, falloff on.
    fn default() -> Self {
        let mut s = Self {
            width: 512,
            height: 512,
            max_reflection_depth: 4,
            max_refraction_depth: 4,
            max_depth: None,
            rules: Rules::Consistent,
            falloff: true,
            falloff_min_distance: 0.01,
            ray_offset: 0.001,
            ray_cutoff: 0.0,
            features: Features::default(),
            light_samples: 1,
            spp: 1,
            seed: 0,
            path_frames: 1,
            orbit_deg: 0.0,
            cones: ConeSettings::default(),
            technique_params: Default::default(),
            pixel_filter: PixelFilter::None,
            filter_width: 0.5,
            traversal: Traversal::Auto,
            walk_budget_mib: 0,
            surface: Surface::default(),
        };
        // The numbers' defaults are declared once, with their ranges.
        for f in crate::settings::RENDER {
            (f.set)(&mut s, f.setting.default);
        }
        s
    }
}

impl RenderSettings {
    /// Frame `k` of the camera path (`path_frames`, `orbit_deg`) that ends at `camera`
    /// and these settings: the camera turned by `(k + 1 - path_frames) orbit_deg`
    /// about its target, and the seed as many steps back (wrapping), so each frame
    /// draws new samples and the last is the experiment's own render.
    pub fn path_pose(
        &self,
        camera: &crate::scene::OrbitCamera,
        k: u32,
    ) -> (crate::scene::OrbitCamera, RenderSettings) {
        let back = self.path_frames.max(1) - 1 - k.min(self.path_frames.max(1) - 1);
        let camera = crate::scene::OrbitCamera {
            yaw: camera.yaw - (back as f64 * self.orbit_deg).to_radians(),
            ..camera.clone()
        };
        let settings = RenderSettings {
            seed: self.seed.wrapping_sub(back),
            ..self.clone()
        };
        (camera, settings)
    }

    /// Entries of the kernel's ray stack: the most refraction rays its depth-first walk
    /// of the fullest tree holds at once (`tests::deepest_stack`). A hit pushes its
    /// refraction ray and traces its reflection ray next without the stack
    /// (shaders/trace.wgsl), and a popped ray's own pushes replace it, so the stack
    /// holds one ray for each hit of the current chain of reflections: the chain's
    /// first a + 1 hits under the total limit push, under the seed's rules only those
    /// below depth b. At least 1 (an array of none is not WGSL). Each entry costs the
    /// software driver time on every SIMD lane (docs/sparse-traversal.md, "What each
    /// change to the kernel bought": seed_rules at 16^3, 9 entries to 5 made a frame
    /// 1.02x as fast).
    pub fn ray_stack_size(&self) -> u32 {
        let (a, b) = (self.max_reflection_depth, self.max_refraction_depth);
        let pushes = match self.rules {
            _ if b == 0 => 0,
            Rules::Consistent => a + 1,
            Rules::Seed => (a + 1).min(b),
        };
        pushes.min(self.total_depth_limit()).max(1)
    }

    /// The total depth limit in force: `max_depth`, or the sum of the two limits (which
    /// no tree can exceed) when it is not set.
    pub(crate) fn total_depth_limit(&self) -> u32 {
        let sum = self.max_reflection_depth + self.max_refraction_depth;
        self.max_depth.map_or(sum, |d| d.min(sum))
    }

    /// Whether a ray whose reflection and refraction depths are `(a, b)` may spawn a
    /// reflection (`reflection`) or a refraction ray, under [`Self::rules`] and the
    /// total limit. Under the seed's rules its one recursion depth is `a + b`.
    pub fn may_spawn(&self, a: u32, b: u32, reflection: bool) -> bool {
        let depth = a + b;
        if depth >= self.total_depth_limit() {
            return false;
        }
        match (self.rules, reflection) {
            (Rules::Consistent, true) => a < self.max_reflection_depth,
            (Rules::Consistent, false) => b < self.max_refraction_depth,
            (Rules::Seed, true) => depth < self.max_reflection_depth,
            (Rules::Seed, false) => depth < self.max_refraction_depth,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The deepest the kernel's ray stack gets (shaders/trace.wgsl: a hit pushes its
    /// refraction ray and traces its reflection ray next, without the stack) over the
    /// fullest tree the limits allow, every ray hitting and spawning all it may. A real
    /// tree is part of this one and its walk holds part of what this walk holds.
    fn deepest_stack(s: &RenderSettings) -> usize {
        let mut stack: Vec<(u32, u32)> = Vec::new();
        let mut next = Some((0, 0));
        let mut deepest = 0;
        while let Some((a, b)) = next.take().or_else(|| stack.pop()) {
            if s.may_spawn(a, b, false) {
                stack.push((a, b + 1));
                deepest = deepest.max(stack.len());
            }
            if s.may_spawn(a, b, true) {
                next = Some((a + 1, b));
            }
        }
        deepest
    }

    /// The stack the kernel is given holds every tree the limits allow, and no more
    /// than the fullest one needs, under both rules, every pair of depth limits up to 6
    /// and total limits below, at and above their sum.
    #[test]
    fn the_ray_stack_fits_the_deepest_tree_exactly() {
        for rules in [Rules::Consistent, Rules::Seed] {
            for a in 0..=6 {
                for b in 0..=6 {
                    for max_depth in [None, Some(0), Some(1), Some(2), Some(3), Some(a + b)] {
                        let s = RenderSettings {
                            rules,
                            max_reflection_depth: a,
                            max_refraction_depth: b,
                            max_depth,
                            ..Default::default()
                        };
                        let deepest = deepest_stack(&s).max(1);
                        assert_eq!(
                            s.ray_stack_size() as usize,
                            deepest,
                            "{rules:?}, depth limits {a}/{b}, max_depth {max_depth:?}"
                        );
                    }
                }
            }
        }
    }
}
