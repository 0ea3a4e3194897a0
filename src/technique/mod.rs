//! Techniques: the parts of the rendering model that vary, each declared once.
//!
//! A *slot* is a part of the model with several implementations (how a light's
//! visibility is estimated, how a shadow segment is attenuated, what lighting terms are
//! added). A *technique* fills a slot. A shadow model is one [`ShadowModel`] value in
//! its own file (`src/technique/<name>.rs`): its name and the paper it follows, its
//! settings (each with type, default and range, from which the experiment parser, the
//! writer, the viewer's lists, `voxlab ablate`'s curves, the stress suite and `voxlab
//! techniques` follow), its plan rule, its WGSL module, the GPU data it reads (made
//! only when the plan uses it) and its f64 CPU implementation. Registering it is one
//! line in [`SHADOW_MODELS`]: the seed's `hard` shadows ([`hard`], the default), sampled
//! `area` lights ([`area`]), `cone` shadows ([`cone`]), and the plug-ins `ratio`
//! ([`ratio`]) and `sdf` ([`sdf`]). The kernel composes exactly one
//! (`shaders/shading.wgsl` calls its `light_term`).
//!
//! A transmittance model is one [`TransmittanceModel`] value in its own file (its name,
//! summary, plan rule, WGSL module `voxlab::transmittance` and f64 functions, and the
//! per-voxel transmittance the cone pyramids use), registered with one line in
//! [`TRANSMITTANCES`]: `min-kt` ([`min_kt`]), `beer-lambert` ([`beer_lambert`]) and
//! `opaque` ([`opaque`]).
//! The shadow walks (voxels, dense or sparse, and triangle surfaces; `shaders/shadow.wgsl`,
//! `shaders/shadow_surface.wgsl`, `crate::technique::shading::shadow_transmittance`) are generic over it.
//!
//! A lighting term is one [`LightingTerm`] value in its own file (name, summary, plan
//! rule, the pyramids it reads, WGSL module `voxlab::term::<name>` and f64 function),
//! registered with one line in [`LIGHTING_TERMS`]: [`ambient_occlusion`] and
//! [`indirect`]. The kernel adds every planned term's `term` at each hit (a module
//! `voxlab::lighting_terms` composed for the plan, `crate::gpu::compose`). The cone
//! techniques share the march and the pyramids (`crate::technique::cones::march`,
//! `shaders/cone.wgsl`) and the `[cones]` settings, declared in [`cones`].
//!
//! A traversal is one [`TraversalModel`] value in its own file (name, summary, plan
//! rule, its claim under `render.traversal = "auto"`, WGSL module `voxlab::regions`, and
//! the data it walks), registered with one line in [`TRAVERSALS`]: the seed's `dense`
//! DDA ([`dense`]), the `proximity` clouds ([`proximity`], a radius beside each voxel)
//! and the `sparse` 64-tree ([`sparse`], the seed's O2). Every walk, on
//! both backends, is the one DDA of `shaders/traversal.wgsl` and `crate::dda` over
//! the regions the traversal finds; all give the same visits.
//!
//! A surface is one [`SurfaceModel`] value in its own file (name, summary, plan rule,
//! and where its triangles come from), registered with one line in [`SURFACES`]: the
//! seed's `voxels` ([`voxels`]), the scene's `mesh` ([`mesh`]) and the grid's `smooth`
//! surface ([`smooth`]), the seed's O6. Triangle surfaces share the cell lists and the
//! watertight test (`crate::triangles`, `shaders/triangles.wgsl`).

pub mod ambient_occlusion;
pub mod area;
pub mod atrous;
pub mod beer_lambert;
pub mod boxes;
pub mod cone;
pub mod cones;
pub mod dense;
pub mod hard;
pub mod indirect;
pub mod mesh;
pub mod min_kt;
pub mod octant;
pub mod opaque;
pub mod proximity;
pub mod ratio;
pub mod sdf;
pub mod shading;
pub mod smooth;
pub mod solid_angle;
pub mod sparse;
pub mod sparse_octant;
pub mod svgf;
pub mod unfiltered;
pub mod voxels;

use std::collections::BTreeMap;
use std::fmt;

use glam::DVec3;

use crate::frame::RayStats;
use crate::render::{RenderSettings, Transmittance};
use crate::sampling::SampleKey;
use crate::scene::{Light, Material, Scene};

/// Shadow models, in the order they are listed and offered; the first is the default
/// (the baseline's hard shadows). One line each.
pub const SHADOW_MODELS: &[&ShadowModel] = &[
    &hard::MODEL,
    &area::MODEL,
    &cone::MODEL,
    &ratio::MODEL,
    &sdf::MODEL,
    &solid_angle::MODEL,
];

/// Lighting terms, in the order they are listed and offered. One line each.
pub const LIGHTING_TERMS: &[&LightingTerm] = &[&ambient_occlusion::TERM, &indirect::TERM];

/// Transmittance models, in the order they are listed and offered; the first is the
/// default (the baseline's). One line each.
pub const TRANSMITTANCES: &[&TransmittanceModel] =
    &[&min_kt::MODEL, &beer_lambert::MODEL, &opaque::MODEL];

/// Traversals, in the order they are listed and offered; the first is the default (the
/// baseline's), which `auto` takes unless another claims the scene. One line each.
pub const TRAVERSALS: &[&TraversalModel] = &[
    &dense::TRAVERSAL,
    &proximity::TRAVERSAL,
    &octant::TRAVERSAL,
    &boxes::TRAVERSAL,
    &sparse::TRAVERSAL,
    &sparse_octant::TRAVERSAL,
];

/// Surfaces, in the order they are listed and offered; the first is the default (the
/// baseline's voxel faces). One line each.
pub const SURFACES: &[&SurfaceModel] = &[&voxels::SURFACE, &mesh::SURFACE, &smooth::SURFACE];

/// Reconstructions, in the order they are listed and offered; the first is the default
/// (the image as traced). One line each.
pub const RECONSTRUCTIONS: &[&Reconstruction] = &[
    &unfiltered::RECONSTRUCTION,
    &atrous::RECONSTRUCTION,
    &svgf::RECONSTRUCTION,
];

/// Tables of settings several techniques share, in the order files list them. One line
/// each.
pub const SETTING_GROUPS: &[&SettingGroup] = &[&cones::GROUP];

/// A table of settings several techniques share (`[cones]`: the cone techniques' march
/// and pyramids), declared once. The parser, the writer, the viewer's panels and `voxlab
/// ablate` go through [`SETTING_GROUPS`] and name no group.
pub struct SettingGroup {
    /// Its table in experiment files, and the prefix of its keys (`cones.levels`).
    pub table: &'static str,
    /// The title of its panel in the viewer.
    pub title: &'static str,
    /// Its settings, in the order files list them.
    pub settings: &'static [GroupSetting],
    /// Whether a render with these features reads it: the viewer shows its panel then,
    /// and `voxlab ablate`'s reference keeps the experiment's values only then.
    pub used: fn(&crate::render::Features) -> bool,
}

/// One setting of a [`SettingGroup`] and the field of `RenderSettings` it is.
pub(crate) type GroupSetting = crate::settings::Field<RenderSettings>;

impl SettingGroup {
    /// Its setting `key` (without the table's prefix).
    pub fn setting(&self, key: &str) -> Option<&'static GroupSetting> {
        self.settings.iter().find(|g| g.setting.key == key)
    }

    /// Sets every one of its settings in `settings` to the declared default.
    pub(crate) fn reset(&self, settings: &mut RenderSettings) {
        for g in self.settings {
            (g.set)(settings, g.setting.default);
        }
    }
}

/// A part of the model with several implementations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    /// How the visibility of a light from a surface point is estimated.
    Shadow,
    /// How a shadow segment through semi-transparent voxels is attenuated.
    Transmittance,
    /// Terms added to the local light at every diffuse hit.
    Lighting,
    /// How rays walk the grid to the voxels they visit.
    Traversal,
    /// What rays hit: voxel faces or triangles.
    Surface,
    /// How the sampled shadow term is filtered before shading.
    Reconstruction,
}

impl Slot {
    pub fn name(self) -> &'static str {
        match self {
            Slot::Shadow => "shadow model",
            Slot::Transmittance => "transmittance",
            Slot::Lighting => "lighting term",
            Slot::Traversal => "traversal",
            Slot::Surface => "surface",
            Slot::Reconstruction => "reconstruction",
        }
    }

    /// The experiment key that chooses the slot's technique.
    pub fn key(self) -> &'static str {
        match self {
            Slot::Shadow => "features.shadow_model",
            Slot::Transmittance => "features.transmittance",
            Slot::Lighting => "features.<name> = true",
            Slot::Traversal => "render.traversal",
            Slot::Surface => "render.surface",
            Slot::Reconstruction => "features.reconstruction",
        }
    }
}

pub use crate::settings::{Kind, Setting};

/// The settings of plug-in techniques as the experiment gives them: technique name ->
/// key -> value. A key left out takes its declared default ([`TechniqueParams::get`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TechniqueParams {
    values: BTreeMap<String, BTreeMap<String, f64>>,
}

impl TechniqueParams {
    /// The value of `setting` of technique `name`: as set, else its default.
    pub fn get(&self, name: &str, setting: &Setting) -> f64 {
        self.values
            .get(name)
            .and_then(|t| t.get(setting.key))
            .copied()
            .unwrap_or(setting.default)
    }

    /// Sets a value (checked by the caller against the setting's range).
    pub fn set(&mut self, name: &str, key: &str, v: f64) {
        self.values
            .entry(name.to_string())
            .or_default()
            .insert(key.to_string(), v);
    }

    /// The values set, by technique.
    pub fn iter(&self) -> impl Iterator<Item = (&str, &BTreeMap<String, f64>)> {
        self.values.iter().map(|(k, v)| (k.as_str(), v))
    }
}

/// What a shadow model's CPU implementation is asked for one light at one hit.
pub struct LightQuery<'a> {
    pub scene: &'a Scene,
    pub settings: &'a RenderSettings,
    /// The shading material.
    pub material: &'a Material,
    /// The hit point, its unit normal (facing the ray) and the ray's unit direction.
    pub p: DVec3,
    pub n: DVec3,
    pub d: DVec3,
    /// Where shadow rays start: `p + eps n`.
    pub q: DVec3,
    pub key: SampleKey,
    /// The light's index and the light.
    pub index: u32,
    pub light: &'a Light,
    /// How shadow segments walk the scene (`crate::technique::shading::shadow_transmittance`): the
    /// sparse tree and the triangle surfaces when planned, and the medium at `q`.
    pub walk: crate::technique::shading::ShadowWalk<'a>,
    /// The cone pyramids, when the plan built them (for a model with `pyramid`).
    pub cones: Option<&'a crate::technique::cones::march::ConeScene>,
}

/// A shadow model's f64 reference, made once per render (its per-scene data built).
pub trait CpuShadow: Send + Sync {
    /// Light `at.light`'s local radiance at the hit before albedo: visibility times
    /// `E (kd diffuse + ks specular)` (`crate::technique::shading::unshadowed`), however the model
    /// estimates it. Counts its shadow rays and voxel steps in `stats`.
    fn light_term(&self, at: &LightQuery, stats: &mut RayStats) -> DVec3;
}

/// How a technique's `technique_data` is made.
#[derive(Clone, Copy)]
pub enum GpuData {
    /// On the host, uploaded as it is.
    Host(fn(&Scene, &[f64]) -> Vec<f32>),
    /// On the device, by compute passes the technique encodes and submits; the buffer
    /// returned has `STORAGE` and `COPY_SRC` usage. An error fails the render.
    Device(fn(&GpuBuild) -> anyhow::Result<wgpu::Buffer>),
}

/// What a technique's device build is given.
pub struct GpuBuild<'a> {
    pub device: &'a wgpu::Device,
    pub queue: &'a wgpu::Queue,
    /// The voxel grid as uploaded: one material index per voxel (R8Uint, dims).
    pub grid: &'a wgpu::TextureView,
    pub scene: &'a Scene,
    /// The values of the model's `data_settings`, in order.
    pub params: &'a [f64],
}

/// A plug-in shadow model: everything about it, in one value.
pub struct ShadowModel {
    /// Its name in experiment files (`[features] shadow_model`), lists and file names.
    pub name: &'static str,
    /// What it is, one line, with the paper or section it follows.
    pub summary: &'static str,
    /// Its label in the viewer's lists, a few words.
    pub title: &'static str,
    /// Its settings (`[techniques.<name>]`).
    pub settings: &'static [Setting],
    /// Whether each frame draws new light samples, so `spp` frames are accumulated.
    pub stochastic: bool,
    /// The plan rule, given that shadow rays are in: `Err(reason)` leaves the model out
    /// of this scene (every light is then shaded by hard shadows at its centre).
    pub plan: fn(&Scene, &RenderSettings) -> Result<(), String>,
    /// Its WGSL module (path, source): `#define_import_path voxlab::shadow_model` with
    /// `fn light_term(q, p, n, d: vec3<f32>, light: Light, j: u32, s: Material, key:
    /// SampleKey) -> vec3<f32>`, the GPU twin of [`CpuShadow::light_term`]. It may read
    /// `technique_data` (shaders/bindings.wgsl), filled by `gpu_data`.
    pub wgsl: (&'static str, &'static str),
    /// The data the kernel reads from `technique_data`, made when the plan uses the
    /// model and its inputs changed. `None`: it reads none.
    pub gpu_data: Option<GpuData>,
    /// The keys of its `settings` that `gpu_data` reads, given to it in this order
    /// (`GpuBuild::params`): its inputs with the scene, so the data is made again when
    /// one of these changes and kept when another setting does (a sweep of a shading
    /// setting does not rebuild it).
    pub data_settings: &'static [&'static str],
    /// Makes the CPU implementation for a render.
    pub cpu: fn(&Scene, &RenderSettings) -> Box<dyn CpuShadow>,
    /// The curves `voxlab ablate` draws of it (error against time), in order.
    pub ablate: &'static [AblateCurve],
    /// What reports say of it for a scene, beyond its settings (the cone model: the
    /// aperture an area light's cone has); `None`: nothing.
    pub describe: Option<fn(&Scene, &RenderSettings) -> Option<String>>,
    /// How printed plans name it (`AREA_LIGHTS`, `SHADOW_MODEL(sdf)`); empty for the
    /// default, which the baseline's plans do not name.
    pub label: &'static str,
    /// Its retired `[features]` switch (`area_lights = true`): a file that still has it
    /// gets an error that gives the `shadow_model` line to write instead.
    pub switch: Option<&'static str>,
    /// Settings it reads from the shared tables, as `table.key` (`render.spp`,
    /// `cones.levels`): listed with its own `[techniques.<name>]` ones.
    pub shared_settings: &'static [&'static str],
    /// Whether it casts shadow rays through the transmittance model. A model that does
    /// not (cones) leaves the transmittance model out of the plan.
    pub shadow_rays: bool,
    /// Whether it reads the cone pyramids (`LightQuery::cones`; shaders/cone.wgsl):
    /// the plan builds them for it.
    pub pyramid: bool,
}

impl ShadowModel {
    /// Its setting `key`.
    pub fn setting(&self, key: &str) -> Option<&'static Setting> {
        self.settings.iter().find(|s| s.key == key)
    }

    /// The value of its setting `key` in `settings` (declared default if unset).
    pub fn value(&self, settings: &RenderSettings, key: &str) -> f64 {
        let s = self
            .setting(key)
            .unwrap_or_else(|| panic!("{} has no setting {key}", self.name));
        settings.technique_params.get(self.name, s)
    }

    /// Its settings as the kernel reads them: `params.technique` (shaders/types.wgsl),
    /// in declared order, as f32, zero past the last. Every setting a model declares
    /// reaches its WGSL this way, with no packing of its own (`technique_setting(i)`,
    /// shaders/bindings.wgsl).
    pub fn gpu_settings(&self, settings: &RenderSettings) -> [f32; MAX_GPU_SETTINGS] {
        let mut out = [0.0; MAX_GPU_SETTINGS];
        for (o, s) in out.iter_mut().zip(self.settings) {
            *o = settings.technique_params.get(self.name, s) as f32;
        }
        out
    }
}

/// A reconstruction: how the shadow term of a shadow model that samples it (stochastic,
/// with shadow rays) is filtered before it is shaded, guided by the primary hits'
/// G-buffer. The tracer separates the primary hit's local light from the rest of the
/// radiance (`crate::frame::PrimaryLayers`); the image is then the rest plus the
/// unshadowed light times the filtered visibility ratio (Heitz, Hill and McGuire, I3D
/// 2018, who denoise the ratio, not the radiance). One value in its own file,
/// registered with one line in [`RECONSTRUCTIONS`]; the default, `none`, makes no
/// layers and leaves the image as traced.
pub struct Reconstruction {
    /// Its name in experiment files (`[features] reconstruction`) and lists.
    pub name: &'static str,
    /// What it is, one line, with the paper it follows.
    pub summary: &'static str,
    /// Its label in the viewer's lists, a few words.
    pub title: &'static str,
    /// Its settings (`[techniques.<name>]`).
    pub settings: &'static [Setting],
    /// The filter in f64: every pixel's visibility ratio
    /// (`crate::frame::PrimaryPixel::visibility`) filtered, given the values of its
    /// settings in declared order; only the pixels `PrimaryPixel::filtered` accepts are
    /// read and used. `None`: the image as traced, and no layers are made.
    pub cpu: Option<ReconstructionFilter>,
    /// Its WGSL module (path, source), the GPU twin of `cpu`: `#define_import_path
    /// voxlab::reconstruction` with `fn prepare_pixel(x: i32, y: i32, i: u32)` (run once
    /// per pixel) and `fn iterate_pixel(x: i32, y: i32, i: u32)` (`gpu_passes` times,
    /// `fp.pass_index` counting from 0), importing `voxlab::layers` (shaders/layers.wgsl:
    /// the decoded layers, the colour ping-pong, its settings as `setting(k)`);
    /// shaders/reconstruct.wgsl runs them between decoding the layers and composing.
    pub wgsl: Option<(&'static str, &'static str)>,
    /// WGSL modules its module imports besides `voxlab::layers` (path, source): a
    /// filter it shares with another reconstruction (`shaders/atrous.wgsl`).
    pub wgsl_imports: &'static [(&'static str, &'static str)],
    /// How many times `iterate` runs, given the values of its settings.
    pub gpu_passes: fn(&[f64]) -> u32,
    /// How far from a pixel (in pixels, per axis) the filter reads, given the values of
    /// its settings: a crop of the image is filtered as the whole image is when it is
    /// traced this much wider.
    pub reach: fn(&[f64]) -> u32,
    /// How printed plans name it; empty for the default.
    pub label: &'static str,
    /// Whether it reads the previous frames of a camera path (`[render] path_frames`),
    /// reprojected (`crate::frame::History`): it then reads the whole image, whatever
    /// crop is asked for, since a moving camera brings any pixel anywhere.
    pub temporal: bool,
}

/// A reconstruction's f64 filter: the layers and its settings' values in, every
/// pixel's filtered visibility out ([`Reconstruction::cpu`]).
/// A temporal one reads and replaces `history` (the previous frame of a camera path;
/// `None` where the path starts); the others leave it alone.
pub type ReconstructionFilter =
    fn(&crate::frame::PrimaryLayers, &[f64], &mut Option<crate::frame::History>) -> Vec<DVec3>;

impl Reconstruction {
    /// Its setting `key`.
    pub fn setting(&self, key: &str) -> Option<&'static Setting> {
        self.settings.iter().find(|s| s.key == key)
    }

    /// The values of its settings in `settings`, in declared order (defaults where
    /// unset).
    pub fn values(&self, settings: &RenderSettings) -> Vec<f64> {
        self.settings
            .iter()
            .map(|s| settings.technique_params.get(self.name, s))
            .collect()
    }

    /// The image whose per-pixel means over the frames are `means` (and, for a temporal
    /// reconstruction, the path's `history`, which it updates), with the shadow term
    /// filtered: at a pixel the filter reads, the rest of the radiance (`mean -
    /// direct`) plus `unshadowed` times the filtered visibility ratio; elsewhere the
    /// mean. The image itself when the reconstruction has no filter.
    pub fn apply(
        &self,
        layers: &crate::frame::PrimaryLayers,
        means: &[DVec3],
        settings: &RenderSettings,
        history: &mut Option<crate::frame::History>,
    ) -> Vec<DVec3> {
        let Some(filter) = self.cpu else {
            return means.to_vec();
        };
        let visibility = filter(layers, &self.values(settings), history);
        layers
            .pixels
            .iter()
            .zip(means)
            .zip(visibility)
            .map(|((p, &mean), v)| {
                if p.filtered() {
                    mean - p.direct + p.unshadowed * v
                } else {
                    mean
                }
            })
            .collect()
    }
}

/// The reconstruction called `name`.
pub fn reconstruction(name: &str) -> Option<&'static Reconstruction> {
    RECONSTRUCTIONS.iter().copied().find(|r| r.name == name)
}

/// Names `[features] reconstruction` may take, in registry order.
pub fn reconstruction_names() -> Vec<&'static str> {
    RECONSTRUCTIONS.iter().map(|r| r.name).collect()
}

/// The default reconstruction: none, the image as traced.
pub fn default_reconstruction() -> &'static Reconstruction {
    RECONSTRUCTIONS[0]
}

/// The declared settings of the technique called `name` that has a
/// `[techniques.<name>]` table (a shadow model or a reconstruction), with the slot it
/// fills.
pub fn technique_table(name: &str) -> Option<(Slot, &'static [Setting])> {
    shadow_model(name)
        .map(|m| (Slot::Shadow, m.settings))
        .or_else(|| reconstruction(name).map(|r| (Slot::Reconstruction, r.settings)))
}

/// Names of the techniques with a `[techniques.<name>]` table, in listing order.
pub fn technique_table_names() -> Vec<&'static str> {
    SHADOW_MODELS
        .iter()
        .map(|m| m.name)
        .chain(RECONSTRUCTIONS.iter().map(|r| r.name))
        .collect()
}

/// The most settings a shadow model may declare: the size of `params.technique`
/// (shaders/types.wgsl). The registry's tests check every model against it.
pub const MAX_GPU_SETTINGS: usize = 4;

/// What a curve of `voxlab ablate` sweeps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Knob {
    /// The `[ablate] spp` list: the frames a stochastic model accumulates.
    Spp,
    /// The `[ablate] transmittance` list: one point per transmittance model.
    Transmittance,
    /// One of the model's own settings, over its declared `sweep`.
    Own(&'static str),
    /// A setting of a shared table (`cones.step_factor`, [`shared_setting`]) over the
    /// `[ablate]` list called `list` (`cone_step_factor`), `default` when the file
    /// gives none; an empty list leaves the curve out.
    Shared {
        key: &'static str,
        list: &'static str,
        default: &'static [f64],
    },
}

/// One curve `voxlab ablate` draws of a shadow model: the reference's features with
/// this model, at one frame unless it samples, over its knob.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AblateCurve {
    /// The curve's name in outputs, before ` (<transmittance>)`.
    pub label: &'static str,
    pub knob: Knob,
    /// Every area light replaced by a point light at its centre, of the same colour and
    /// intensity (to sweep what a point light's model does with them).
    pub lights_as_points: bool,
    /// What the report says of the curve, one sentence (empty: nothing).
    pub about: &'static str,
}

/// The shadow model whose converged image is `voxlab ablate`'s reference: sampled area
/// lights, the estimator every soft shadow model here approximates.
pub fn reference_shadow_model() -> &'static ShadowModel {
    &area::MODEL
}

/// The declaration of a shared table's setting by `table.key` (`cones.step_factor`),
/// where one is declared ([`cones`]).
pub fn shared_setting(key: &str) -> Option<&'static Setting> {
    group_key(key).map(|c| &c.setting)
}

/// The group setting `<table>.<key>`.
fn group_key(key: &str) -> Option<&'static GroupSetting> {
    let (table, key) = key.split_once('.')?;
    SETTING_GROUPS
        .iter()
        .find(|g| g.table == table)?
        .setting(key)
}

/// The value of the shared setting `key` in `settings`: a group's key, or the
/// `[render]` sample counts models read.
pub fn get_shared(settings: &RenderSettings, key: &str) -> Option<f64> {
    match key {
        "render.light_samples" => Some(f64::from(settings.light_samples)),
        "render.spp" => Some(f64::from(settings.spp)),
        _ => group_key(key).map(|c| (c.get)(settings)),
    }
}

/// Sets the shared setting `key` in `settings` (checked by the caller); false for an
/// unknown key.
pub(crate) fn set_shared(settings: &mut RenderSettings, key: &str, v: f64) -> bool {
    match group_key(key) {
        Some(c) => {
            (c.set)(settings, v);
            true
        }
        None => false,
    }
}

/// A technique is its name: each registry holds one value per name, so two values are
/// the same technique when their names are, and print as their name. Its index in its
/// registry keys the kernel variant (a lighting term's is its bit in the key).
macro_rules! named_by_name {
    ($($t:ident in $registry:ident),*) => {$(
        impl $t {
            /// Its index in its registry.
            pub fn index(&self) -> u32 {
                $registry
                    .iter()
                    .position(|m| m.name == self.name)
                    .expect("registered") as u32
            }
        }

        impl PartialEq for $t {
            fn eq(&self, other: &Self) -> bool {
                self.name == other.name
            }
        }

        impl Eq for $t {}

        impl fmt::Debug for $t {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, concat!(stringify!($t), "({})"), self.name)
            }
        }
    )*};
}

named_by_name!(
    ShadowModel in SHADOW_MODELS,
    TransmittanceModel in TRANSMITTANCES,
    LightingTerm in LIGHTING_TERMS,
    TraversalModel in TRAVERSALS,
    SurfaceModel in SURFACES,
    Reconstruction in RECONSTRUCTIONS
);

/// The plug-in shadow model called `name`.
pub fn shadow_model(name: &str) -> Option<&'static ShadowModel> {
    SHADOW_MODELS.iter().copied().find(|m| m.name == name)
}

/// The state of one shadow segment's attenuation, as a transmittance model keeps it
/// (each model gives the fields its own meaning, in its file).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AbsorbState {
    pub value: DVec3,
    pub sigma: DVec3,
    pub t: f64,
}

/// A transmittance model: how a shadow segment through semi-transparent materials is
/// attenuated, everything about it in one value. The shadow walks (the voxel walk,
/// dense or sparse, and the triangle surfaces' medium walk) pass it the materials the
/// segment goes through, in order, and ask for the result.
pub struct TransmittanceModel {
    /// Its name in experiment files (`[features] transmittance`) and lists.
    pub name: &'static str,
    /// What it is, one line, with the law or paper it follows.
    pub summary: &'static str,
    /// The experiment keys it reads, as `table.key` (listing).
    pub settings: &'static [&'static str],
    /// The plan rule, given that shadow rays are in: `Err(reason)` leaves it out for the
    /// default model (one that would give the same values, or cannot run).
    pub plan: fn(&Scene, &RenderSettings) -> Result<(), String>,
    /// Its WGSL module (path, source): `#define_import_path voxlab::transmittance` with
    /// `struct Absorb`, `fn absorb_start() -> Absorb`, `fn absorb_pass(w: ptr<function,
    /// Absorb>, t: f32, m: u32) -> bool` and `fn absorb_result(w: Absorb, t_end: f32) ->
    /// vec3<f32>`, the GPU twins of the three functions below.
    pub wgsl: (&'static str, &'static str),
    /// The state before the segment.
    pub start: fn() -> AbsorbState,
    /// The segment passes into material `index` (`material`) at distance `t` (in the
    /// world, grid of `voxel_size`); true once nothing more can pass (the result is 0).
    pub pass: fn(&mut AbsorbState, t: f64, index: u8, material: &Material, voxel_size: f64) -> bool,
    /// The RGB transmittance of the segment ending at `t_end`.
    pub result: fn(&AbsorbState, t_end: f64) -> DVec3,
    /// The transmittance across one voxel of a material, for the cone pyramids'
    /// opacity `1 - T` (`crate::technique::cones::pyramid::material_alpha`).
    pub voxel_transmittance: fn(&Material, voxel_size: f64) -> f64,
    /// What an exporter to a renderer with participating media writes inside a
    /// transparent material (`crate::export`): the extinction coefficient per world
    /// unit of a homogeneous absorbing interior, or `None` when the model has no
    /// distance in it.
    pub interior_extinction: fn(&Material, voxel_size: f64) -> Option<DVec3>,
}

impl TransmittanceModel {
    /// A fresh absorber of this model for one shadow segment: what the walks pass the
    /// segment's media to (`crate::triangles::Absorber`).
    pub fn absorber(&'static self) -> ModelAbsorber {
        ModelAbsorber {
            model: self,
            state: (self.start)(),
        }
    }
}

/// One shadow segment's state under a transmittance model.
pub struct ModelAbsorber {
    model: &'static TransmittanceModel,
    state: AbsorbState,
}

impl crate::triangles::Absorber for ModelAbsorber {
    fn pass(&mut self, t: f64, index: u8, material: &Material, voxel_size: f64) -> bool {
        (self.model.pass)(&mut self.state, t, index, material, voxel_size)
    }
    fn result(&self, t_end: f64) -> DVec3 {
        (self.model.result)(&self.state, t_end)
    }
}

/// What a lighting term's CPU implementation is asked at one diffuse-or-not hit.
pub struct TermQuery<'a> {
    pub scene: &'a Scene,
    pub settings: &'a RenderSettings,
    /// The shading material.
    pub material: &'a Material,
    /// The hit point (world) and its unit shading normal (facing the ray).
    pub p: DVec3,
    pub n: DVec3,
    /// The cone pyramids, when the plan built them (for a term with `pyramid`).
    pub cones: Option<&'a crate::technique::cones::march::ConeScene>,
}

impl<'a> TermQuery<'a> {
    /// For a term gathered by hemisphere cones from diffuse hits: the pyramids and the
    /// grid-local hit point, or `None` where the material is not diffuse (the term adds
    /// nothing there). The plan builds the pyramids for every term with `pyramid`.
    pub(crate) fn diffuse_cone_hit(
        &self,
    ) -> Option<(&'a crate::technique::cones::march::ConeScene, DVec3)> {
        if self.material.kd <= 0.0 {
            return None;
        }
        let cones = self
            .cones
            .expect("the plan builds the pyramids for cone terms");
        Some((cones, self.scene.grid.to_local(self.p)))
    }
}

/// A lighting term: radiance added at every hit on top of the local light, everything
/// about it in one value. Any number of terms may be on at once.
pub struct LightingTerm {
    /// Its name, which is also its `[features]` switch (`ambient_occlusion = true`).
    pub name: &'static str,
    /// A short name the viewer's `--left`/`--right` lists also take (`ao`).
    pub short: &'static str,
    /// What it is, one line, with the paper or section it follows.
    pub summary: &'static str,
    /// How printed plans name it (`AMBIENT_OCCLUSION`).
    pub label: &'static str,
    /// Settings it reads from the shared tables, as `table.key` (`cones.ao_cones`).
    pub shared_settings: &'static [&'static str],
    /// The plan rule, given that the term is switched on: `Err(reason)` leaves it out.
    pub plan: fn(&Scene, &RenderSettings) -> Result<(), String>,
    /// Whether it reads the cone pyramids (the plan builds them for it), and the
    /// radiance pyramid too (light injected into the voxels).
    pub pyramid: bool,
    pub radiance_pyramid: bool,
    /// Its WGSL module (path, source): `#define_import_path voxlab::term::<name>` with
    /// `fn term(p: vec3<f32>, n: vec3<f32>, s: Material) -> vec3<f32>` (grid-local `p`,
    /// the radiance it adds before the ray's throughput), the twin of `cpu`.
    pub wgsl: (&'static str, &'static str),
    /// Its f64 reference: the radiance it adds at the hit, before throughput.
    pub cpu: fn(&TermQuery) -> DVec3,
    /// The most it can add at one hit (any channel), before throughput: what a ray cut
    /// by the ray cutoff can cost (`crate::ray_cutoff::Bounds`).
    pub bound: fn(&TermBound) -> f64,
}

/// What a lighting term's bound is computed from.
pub struct TermBound<'a> {
    /// The scene's ambient colour, largest channel.
    pub ambient: f64,
    /// The most the lights add at one hit (`crate::ray_cutoff::light_bound`, summed).
    pub direct: f64,
    /// The largest `max(albedo) kd` of a shading material.
    pub diffuse: f64,
    pub settings: &'a RenderSettings,
}

/// The lighting term called `name` (or its short name).
pub(crate) fn lighting_term(name: &str) -> Option<&'static LightingTerm> {
    LIGHTING_TERMS
        .iter()
        .copied()
        .find(|t| t.name == name || t.short == name)
}

/// The `[features]` keys: `shadow_model`, `transmittance`, `reconstruction`, then every lighting
/// term's (the shadow models' retired switches are refused with their replacement).
pub fn feature_keys() -> Vec<&'static str> {
    ["shadow_model", "transmittance", "reconstruction"]
        .into_iter()
        .chain(LIGHTING_TERMS.iter().map(|t| t.name))
        .collect()
}

/// The transmittance model called `name`.
pub fn transmittance(name: &str) -> Option<Transmittance> {
    TRANSMITTANCES
        .iter()
        .copied()
        .find(|m| m.name == name)
        .map(Transmittance)
}

/// Names `[features] transmittance` may take.
pub(crate) fn transmittance_names() -> Vec<&'static str> {
    TRANSMITTANCES.iter().map(|m| m.name).collect()
}

/// Names a `[features] shadow_model` may take, in registry order.
pub fn shadow_model_names() -> Vec<&'static str> {
    SHADOW_MODELS.iter().map(|m| m.name).collect()
}

/// The default shadow model: the baseline's.
pub fn default_shadow_model() -> &'static ShadowModel {
    SHADOW_MODELS[0]
}

/// A traversal's data of a grid: its regions for the f64 walks, its words for the
/// kernel. The second argument is the most bytes each binding of the data may take
/// where the traversal chooses what to hold (the sparse octant walk's codes): the
/// device's largest binding on the GPU, [`HOST_WALK_BYTES`] on the CPU reference.
pub(crate) type WalkData =
    fn(&crate::scene::Grid, usize) -> std::sync::Arc<dyn crate::sparse::Regions>;

/// What a walk's data is built from: the traversal, the grid's dims and the hash of
/// the voxels it walks, and the budget it is built within ([`walk_budget`]). The hash
/// is of the voxels alone, so the dims tell apart grids of one byte string in other
/// shapes (a volume reshaped, or empty grids of as many voxels), whose data differ.
/// Two builds of one key are the same data: the GPU tracer keeps its builds by it, and
/// the CPU reference walks one the GPU tracer holds rather than building it again
/// (`crate::cpu::render_region_reusing`).
#[derive(Clone, Copy)]
pub struct WalkKey {
    traversal: &'static TraversalModel,
    dims: glam::UVec3,
    hash: blake3::Hash,
    budget: usize,
}

impl WalkKey {
    /// The key of `traversal`'s data of `grid` within `budget` bytes a binding.
    pub fn new(
        traversal: &'static TraversalModel,
        grid: &crate::scene::Grid,
        budget: usize,
    ) -> Self {
        Self::hashed(traversal, grid, grid.content_hash(), budget)
    }

    /// [`Self::new`] with the grid's hash taken already (`hash` must be
    /// `grid.content_hash()`).
    pub(crate) fn hashed(
        traversal: &'static TraversalModel,
        grid: &crate::scene::Grid,
        hash: blake3::Hash,
        budget: usize,
    ) -> Self {
        Self {
            traversal,
            dims: grid.dims(),
            hash,
            budget,
        }
    }

    /// The bytes a binding the data is built within.
    pub fn budget(&self) -> usize {
        self.budget
    }

    /// Whether builds of the two keys are the same data.
    pub fn same(&self, other: &WalkKey) -> bool {
        std::ptr::eq(self.traversal, other.traversal)
            && self.dims == other.dims
            && self.hash == other.hash
            && self.budget == other.budget
    }
}

/// Walks' data a tracer keeps built on the host (`WalkBuilds`): two, so that two walks
/// of one grid alternate without building again (at 1024^3 about 32 MiB each).
pub const WALK_BUILDS_KEPT: usize = 2;

/// Walks' data kept built, by [`WalkKey`]: the latest `kept` builds, so that renders of
/// one grid, or of walks of it that alternate, build each once. The GPU tracer keeps
/// its builds in one, and so does a CPU
/// [`crate::Session`], whose renders otherwise built the data afresh every call (0.6 s
/// at 256^3 for a trace of a millisecond).
pub(crate) struct WalkBuilds {
    kept: usize,
    /// The oldest first.
    builds: Vec<(WalkKey, std::sync::Arc<dyn crate::sparse::Regions>)>,
    built: u64,
}

impl WalkBuilds {
    pub(crate) fn new(kept: usize) -> Self {
        Self {
            kept,
            builds: Vec::new(),
            built: 0,
        }
    }

    /// The build of `key`, where one is kept.
    pub(crate) fn find(&self, key: &WalkKey) -> Option<std::sync::Arc<dyn crate::sparse::Regions>> {
        self.builds
            .iter()
            .find(|(k, _)| k.same(key))
            .map(|(_, data)| data.clone())
    }

    /// The build of `key`: the one kept, or `build`'s, kept in place of the oldest;
    /// either way the latest now.
    pub(crate) fn get_or_build(
        &mut self,
        key: WalkKey,
        build: impl FnOnce() -> std::sync::Arc<dyn crate::sparse::Regions>,
    ) -> std::sync::Arc<dyn crate::sparse::Regions> {
        let data = match self.builds.iter().position(|(k, _)| k.same(&key)) {
            Some(i) => self.builds.remove(i).1,
            None => {
                self.built += 1;
                build()
            }
        };
        self.builds.push((key, data.clone()));
        if self.builds.len() > self.kept {
            self.builds.remove(0);
        }
        data
    }

    /// Builds made since this was made: a render that found its key adds none.
    pub(crate) fn built(&self) -> u64 {
        self.built
    }
}

/// The walk data budget of the CPU reference: lavapipe's largest binding (128 MiB, also
/// wgpu's default limit), so that the reference walks what the software driver walks,
/// step for step.
pub const HOST_WALK_BYTES: usize = 128 << 20;

/// The bindings beyond `walk_data` that hold a walk's further words
/// (`crate::sparse::Regions::device_more_words`; `walk_more_0` to `walk_more_2` in
/// shaders/bindings.wgsl): the sparse octant walk's codes where they do not fit beside
/// its tree and cut, those of a grid of voxel noise, whose blocks of codes are nearly all
/// distinct (`tests/gpu_sparse.rs`; the seed scene's 2048^3 fits after its tree and
/// cut, 7.5 MiB beside 120 MiB).
pub const WALK_MORE_BINDINGS: usize = 3;

/// The words of each binding that holds a walk's further words, for a walk built
/// within `budget` bytes a binding: the kernel finds word `i` in binding `i / n` at
/// `i % n`. A build holds at most [`WALK_MORE_BINDINGS`] times this many.
pub fn walk_part_words(budget: usize) -> usize {
    (budget / 4).min(u32::MAX as usize)
}

/// The budget a render's walk data is built within, in bytes a binding:
/// `render.walk_budget_mib` where it is set, else `own`, the tracer's (the device's
/// largest binding, or [`HOST_WALK_BYTES`] on the CPU reference). Set alike on both
/// tracers, it gives them the same data on any device, step for step.
pub fn walk_budget(settings: &crate::render::RenderSettings, own: usize) -> usize {
    match settings.walk_budget_mib {
        0 => own,
        mib => (mib as usize) << 20,
    }
}

/// A traversal's claim on a scene under `render.traversal = "auto"`: `Ok(why)` or
/// `Err(why not)`.
pub(crate) type AutoClaim = fn(&Scene) -> Result<String, String>;

/// The plan rule of a traversal that walks the dense grid (`what` it reads, for the
/// reason): no grid held only as its sparse tree.
pub(crate) fn dense_grid_only(scene: &Scene, what: &str) -> Result<(), String> {
    if !scene.grid.is_sparse() {
        return Ok(());
    }
    let d = scene.grid.dims();
    Err(format!(
        "it reads {what}, and this {}x{}x{} grid is held only as its sparse tree (more than \
         {} voxels)",
        d.x,
        d.y,
        d.z,
        crate::scene::DENSE_MAX_VOXELS
    ))
}

/// The claim of a walk over the dense grid on grids whose largest side is `from` or
/// more (none held only as the tree), with its reason.
pub(crate) fn claim_dense_from_side(scene: &Scene, from: u32) -> Result<String, String> {
    dense_grid_only(scene, "the dense grid")?;
    claim_from_side(scene, from)
}

/// The bytes of a buffer of `per_voxel` bytes a voxel of a grid of `dims`, in whole
/// vec4<u32>s: what a walk over the dense grid (its voxels, a field beside them) binds.
pub(crate) fn per_voxel_bytes(dims: glam::UVec3, per_voxel: u64) -> u64 {
    (per_voxel * dims.as_u64vec3().element_product()).next_multiple_of(16)
}

/// The claim on grids whose largest side is `from` or more, with its reason.
pub(crate) fn claim_from_side(scene: &Scene, from: u32) -> Result<String, String> {
    let side = scene.grid.dims().max_element();
    if side >= from {
        Ok(format!("the grid's largest side {side} is {from} or more"))
    } else {
        Err(format!("the grid's largest side {side} is below {from}"))
    }
}

/// A traversal: how rays walk the grid, everything about it in one value. Every
/// traversal gives the dense DDA's visits (voxels, distances, faces), so images do not
/// depend on it; only the time and the memory do. A walk asks it for the uniform region
/// around the voxel it is in and leaves a region of the ray's medium whole
/// (`shaders/traversal.wgsl`'s `dda_region`/`dda_skip`, `crate::dda::Dda`).
pub struct TraversalModel {
    /// Its name in experiment files (`render.traversal`) and lists.
    pub name: &'static str,
    /// What it is, one line, with the paper or section it follows.
    pub summary: &'static str,
    /// How printed plans describe it (`dense DDA`).
    pub label: &'static str,
    /// Whether it can walk this scene: `Err(reason)` when not (the experiment loader
    /// refuses it when asked for by name; `auto` passes it by).
    pub plan: fn(&Scene, &RenderSettings) -> Result<(), String>,
    /// Its claim under `render.traversal = "auto"`: `Ok(why)` when it should walk this
    /// scene, `Err(why not)`; `None` for the default, which walks what no other claims.
    /// Of several claims the last registered wins.
    pub auto: Option<AutoClaim>,
    /// Its WGSL module (path, source): `#define_import_path voxlab::regions` with `const
    /// REGIONS_ARE_VOXELS: bool`, `struct RegionCursor` (what it keeps between look-ups),
    /// `fn region_cursor(step: vec3<i32>) -> RegionCursor` (for a walk of that step) and
    /// `fn region_at(c: ptr<function, RegionCursor>, v: vec3<i32>) -> Region`
    /// (shaders/types.wgsl), the region around voxel `v`.
    pub wgsl: (&'static str, &'static str),
    /// Whether it walks the grid's sparse tree (`crate::sparse`): its module is
    /// composed with `TREE_LEVELS`, and it walks grids held only as their tree.
    pub walks_tree: bool,
    /// For a tree walk whose descents start below the root: the most levels one descent
    /// takes on a grid of these dims (`TREE_LEVELS`, `crate::plan::tree_levels`); `None`:
    /// the tree's depth.
    pub descent_levels: Option<fn(glam::UVec3) -> u32>,
    /// Its data of a grid, built once per render and in place of the dense grid's
    /// voxel buffer: the f64 walks ask it for regions (`crate::sparse::Regions`, the
    /// twin of its `region_at`), the kernel reads its words (`Regions::device_words`,
    /// bound as `walk_data`). `None`: the voxel buffer, one voxel a region. Only the
    /// data the plan's traversal walks is made and uploaded.
    pub data: Option<WalkData>,
    /// The bytes the kernel binds for a grid of these dims, where the voxels do not
    /// change them (the voxel buffer, a field per voxel); `None` where they do (the
    /// tree). Under `"auto"` a walk whose bytes the device cannot bind gives way to the
    /// tree walk (`crate::gpu`).
    pub device_bytes: Option<fn(glam::UVec3) -> u64>,
}

impl TraversalModel {
    /// Whether a device that binds at most `max_bytes` in one buffer binds what this
    /// walk reads of a grid of `dims` (the tree walk binds any grid).
    pub fn binds_within(&self, dims: glam::UVec3, max_bytes: u64) -> bool {
        self.device_bytes.is_none_or(|b| b(dims) <= max_bytes)
    }
}

/// The traversal called `name`.
pub fn traversal(name: &str) -> Option<&'static TraversalModel> {
    TRAVERSALS.iter().copied().find(|t| t.name == name)
}

/// The default traversal: the baseline's.
pub fn default_traversal() -> &'static TraversalModel {
    TRAVERSALS[0]
}

/// Where a triangle surface's triangles come from, in world coordinates.
pub(crate) type SurfaceTriangles =
    fn(&Scene) -> Result<std::borrow::Cow<'_, crate::surface::SurfaceMesh>, String>;

/// A surface: what rays hit, everything about it in one value. The default hits the
/// voxels' faces; the others trace triangles found through the voxels they overlap
/// (`crate::triangles`, `shaders/triangles.wgsl`, `TRIANGLES`) and differ only in where
/// the triangles come from.
pub struct SurfaceModel {
    /// Its name in experiment files (`render.surface`) and lists.
    pub name: &'static str,
    /// What it is, one line, with the paper or section it follows.
    pub summary: &'static str,
    /// How printed plans describe it (`triangles of the scene's mesh`).
    pub label: &'static str,
    /// Its own plan rule, beside the limits every triangle surface shares
    /// (`crate::plan::check_surface`): `Err(reason)` gives voxels instead (the
    /// experiment loader refuses it).
    pub plan: fn(&Scene, &RenderSettings) -> Result<(), String>,
    /// Its triangles; `None` for the voxels' faces.
    pub triangles: Option<SurfaceTriangles>,
    /// What its triangles depend on beyond the grid (the scene's mesh), hashed into the
    /// device's cache key.
    pub hash_inputs: fn(&Scene, &mut blake3::Hasher),
}

impl SurfaceModel {
    /// Whether rays hit triangles (not the voxels' faces).
    pub fn traces_triangles(&self) -> bool {
        self.triangles.is_some()
    }
}

/// The surface called `name`.
pub fn surface(name: &str) -> Option<&'static SurfaceModel> {
    SURFACES.iter().copied().find(|t| t.name == name)
}

/// The default surface: the baseline's voxel faces.
pub fn default_surface() -> &'static SurfaceModel {
    SURFACES[0]
}

/// One row of the listing: name, slot, how it is switched on, settings, summary.
#[derive(Clone, Debug, PartialEq)]
pub struct ListingRow {
    pub name: &'static str,
    pub slot: Slot,
    pub switch: String,
    pub settings: Vec<String>,
    pub summary: &'static str,
}

/// Every technique: the shadow models, the transmittance models, the lighting terms.
pub fn listing() -> Vec<ListingRow> {
    let shadow = SHADOW_MODELS.iter().map(|m| ListingRow {
        name: m.name,
        slot: Slot::Shadow,
        switch: format!("features.shadow_model = \"{}\"", m.name),
        settings: m
            .shared_settings
            .iter()
            .map(|s| s.to_string())
            .chain(
                m.settings
                    .iter()
                    .map(|s| format!("techniques.{}.{}", m.name, s.key)),
            )
            .collect(),
        summary: m.summary,
    });
    let transmittances = TRANSMITTANCES.iter().map(|m| ListingRow {
        name: m.name,
        slot: Slot::Transmittance,
        switch: format!("features.transmittance = \"{}\"", m.name),
        settings: m.settings.iter().map(|s| s.to_string()).collect(),
        summary: m.summary,
    });
    let terms = LIGHTING_TERMS.iter().map(|t| ListingRow {
        name: t.name,
        slot: Slot::Lighting,
        switch: format!("features.{} = true", t.name),
        settings: t.shared_settings.iter().map(|s| s.to_string()).collect(),
        summary: t.summary,
    });
    let traversals = TRAVERSALS.iter().map(|t| ListingRow {
        name: t.name,
        slot: Slot::Traversal,
        switch: format!("render.traversal = \"{}\"", t.name),
        settings: Vec::new(),
        summary: t.summary,
    });
    let surfaces = SURFACES.iter().map(|t| ListingRow {
        name: t.name,
        slot: Slot::Surface,
        switch: format!("render.surface = \"{}\"", t.name),
        settings: Vec::new(),
        summary: t.summary,
    });
    let reconstructions = RECONSTRUCTIONS.iter().map(|r| ListingRow {
        name: r.name,
        slot: Slot::Reconstruction,
        switch: format!("features.reconstruction = \"{}\"", r.name),
        settings: r
            .settings
            .iter()
            .map(|s| format!("techniques.{}.{}", r.name, s.key))
            .collect(),
        summary: r.summary,
    });
    shadow
        .chain(transmittances)
        .chain(terms)
        .chain(traversals)
        .chain(surfaces)
        .chain(reconstructions)
        .collect()
}

/// The listing as a markdown table (what `voxlab techniques --markdown` prints and the
/// table of docs/techniques.md must equal).
pub fn listing_markdown() -> String {
    let mut out = String::from(
        "| technique | slot | switch | settings | what it is |\n|---|---|---|---|---|\n",
    );
    for r in listing() {
        let settings = if r.settings.is_empty() {
            "-".to_string()
        } else {
            r.settings
                .iter()
                .map(|s| format!("`{s}`"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out += &format!(
            "| {} | {} | `{}` | {} | {} |\n",
            r.name,
            r.slot.name(),
            r.switch,
            settings,
            r.summary
        );
    }
    out
}

/// The declaration of `key`, one of `r.settings`, with the table it is in
/// (`[techniques.sdf]`, `[render]`); `None` for a key that is no number.
fn declared_setting(r: &ListingRow, key: &str) -> Option<(String, &'static Setting)> {
    let own = technique_table(r.name).and_then(|(_, settings)| {
        let k = key.strip_prefix(&format!("techniques.{}.", r.name))?;
        let s = settings.iter().find(|s| s.key == k)?;
        Some((format!("[techniques.{}]", r.name), s))
    });
    own.or_else(|| {
        let (table, k) = key.split_once('.')?;
        // `render.*` keys are the render table's fields; the others a shared group's.
        let declared = match table {
            "render" => crate::settings::RENDER
                .iter()
                .find(|f| f.setting.key == k)
                .map(|f| &f.setting),
            _ => shared_setting(key),
        };
        Some((format!("[{table}]"), declared?))
    })
}

/// The listing as records (`voxlab techniques --json`, the Python `techniques()`): per
/// technique its name, slot, switch and summary (with the paper it follows), and each
/// setting's key, type, default (`null` where it has none), range and unit.
pub fn listing_json() -> serde_json::Value {
    let rows: Vec<serde_json::Value> = listing()
        .iter()
        .map(|r| {
            let settings: Vec<serde_json::Value> = r
                .settings
                .iter()
                .map(|key| match declared_setting(r, key) {
                    Some((_, s)) => s.json(key),
                    None => serde_json::json!({ "key": key }),
                })
                .collect();
            serde_json::json!({
                "name": r.name,
                "slot": r.slot.name(),
                "switch": r.switch,
                "summary": r.summary,
                "settings": settings,
            })
        })
        .collect();
    serde_json::Value::Array(rows)
}

/// The listing as plain text, with each plug-in setting's type, default and range.
pub fn listing_text() -> String {
    let mut out = String::new();
    for r in listing() {
        out += &format!(
            "{} ({}; {})\n  {}\n",
            r.name,
            r.slot.name(),
            r.switch,
            r.summary
        );
        for key in &r.settings {
            out += &match declared_setting(&r, key) {
                Some((table, s)) => format!(
                    "  {table} {} = {} ({}; {})\n",
                    s.key,
                    s.default,
                    s.range_text().trim_start_matches("must be "),
                    s.doc
                ),
                None => format!("  {key}\n"),
            };
        }
    }
    out
}
