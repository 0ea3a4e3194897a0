//! Experiment files: TOML in, a validated [`Experiment`] (scene, render settings,
//! features) out.
//!
//! Parsing is two-step: serde (with `deny_unknown_fields` everywhere) reads the text
//! into raw structs that mirror the file, then `build` checks every value against its
//! allowed range and assembles the scene. Serde's errors carry a byte span; our own
//! validation errors know the key path instead, and look it up in a `toml_edit` parse of
//! the same text to find the line. Either way every message starts with `file:line:`.
//!
//! The file format is documented by example in `experiments/baseline.toml`. The way
//! back, an [`Experiment`] written as a file that parses to it again, is [`mod@write`].

mod models;
pub mod write;

pub use write::{WriteError, relocate_scene_source, scene_source, to_toml};

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, IVec3, UVec3};
use serde::Deserialize;

use crate::settings::{self, Field, Setting};
use crate::surface::SurfaceMesh;

use crate::render::{Features, RenderSettings};
use crate::scene::seed::{
    SEED_AMBIENT, SEED_SIZE, seed_camera, seed_grid, seed_lights, seed_scene,
};
use crate::scene::{
    AreaLight, AreaShape, DENSE_MAX_VOXELS, Dielectric, Emission, Grid, Light, MAX_SPARSE_SIDE,
    Material, PointLight, SEED_SHININESS, Scene, Storage,
};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
enum RulesName {
    #[serde(rename = "consistent")]
    Consistent,
    #[serde(rename = "seed")]
    Seed,
}

/// A validated experiment: everything a tracer needs to render it. Two are equal when
/// they name, place and render the same (`source_record`, the text each was parsed
/// from, is where it came from, not what it is: a written experiment read back equals
/// the one written).
#[derive(Clone, Debug)]
pub struct Experiment {
    /// The `name` key, else the file's stem; names the default output `out/<name>.png`.
    pub name: String,
    /// The `description` key: free text for the reader, which the written experiment
    /// (every record, the viewer's saves) keeps.
    pub description: Option<String>,
    /// The file it was read from (`None` for built-in experiments).
    pub source_path: Option<PathBuf>,
    /// The text it was parsed from, as read from `source_path` or given, and its
    /// assets when read: records quote it, whatever the files hold by the time an image
    /// is written (`None` for built-in experiments, voxels set in memory, or where
    /// `source_path` was set by hand: records then read the file).
    pub source_record: Option<Arc<SourceRecord>>,
    pub scene: Scene,
    /// Render settings, the feature switches (`settings.features`) included.
    pub settings: RenderSettings,
}

impl PartialEq for Experiment {
    fn eq(&self, other: &Self) -> bool {
        // Every field named, so that a new one is not left out unseen.
        let Experiment {
            name,
            description,
            source_path,
            source_record: _,
            scene,
            settings,
        } = self;
        *name == other.name
            && *description == other.description
            && *source_path == other.source_path
            && *scene == other.scene
            && *settings == other.settings
    }
}

/// An experiment file as it was read, with what it read in turn: what an image's
/// provenance and ablate's records quote. Taken at load, so that a file edited while a
/// render or a sweep runs (or between `voxlab.load` and a render in Python) is not
/// recorded as the one the image was made from.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceRecord {
    /// The file's text as read, before overrides.
    pub text: Arc<str>,
    /// The overrides applied to it, as `KEY=VALUE`.
    pub overrides: Vec<String>,
    /// The `[scene]` table with the overrides, its paths resolved
    /// ([`write::scene_source`]).
    pub scene: toml::Table,
    /// Every file read (the experiment's own first, then its assets) with the blake3
    /// hash of its content when it was read.
    pub inputs: Vec<serde_json::Value>,
}

impl SourceRecord {
    /// The record of `text`, read from `path`, loaded with `overrides`.
    pub fn new(path: &Path, text: &str, overrides: &[Override]) -> Result<Self, ExperimentError> {
        Self::with_assets(path, text, overrides, None)
    }

    /// [`SourceRecord::new`] with the assets' hashes given where a [`SceneCache`] took
    /// them when it loaded the scene (`None`: hashed now). A viewer's edit or a sweep's
    /// point re-parses the text: it neither reads nor hashes a large mesh again.
    fn with_assets(
        path: &Path,
        text: &str,
        overrides: &[Override],
        assets: Option<Vec<serde_json::Value>>,
    ) -> Result<Self, ExperimentError> {
        let applied = apply_overrides(text, overrides)?;
        let mut inputs = vec![serde_json::json!({
            "path": path.display().to_string(),
            "blake3": blake3::hash(text.as_bytes()).to_hex().to_string(),
        })];
        inputs.extend(assets.unwrap_or_else(|| write::asset_hashes(&applied, path)));
        Ok(Self {
            text: text.into(),
            overrides: overrides.iter().map(|o| o.to_string()).collect(),
            scene: write::scene_source(&applied, path)?,
            inputs,
        })
    }
}

/// The text of the experiment file `path`: a regular file of at most
/// [`crate::input::MAX_EXPERIMENT_BYTES`], in UTF-8.
pub fn read_text(path: &Path) -> Result<String, ExperimentError> {
    let io = |error| ExperimentError::Io {
        path: path.to_path_buf(),
        error,
    };
    let bytes =
        crate::input::read_file(path, crate::input::MAX_EXPERIMENT_BYTES, "experiment file")
            .map_err(io)?;
    String::from_utf8(bytes).map_err(|e| {
        io(crate::input::ReadError::Io(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )))
    })
}

/// Why an experiment could not be loaded. Every variant's message names the file; all
/// but `Io` also name the line.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    // Not `source`: the message already holds the OS error, and anyhow's `{:#}` would
    // print it a second time.
    #[error("cannot read experiment file {}: {error}", path.display())]
    Io {
        path: PathBuf,
        error: crate::input::ReadError,
    },
    /// The text is not TOML.
    #[error("{}: malformed TOML: {message}", location(file, *line))]
    Syntax {
        file: String,
        line: Option<usize>,
        message: String,
    },
    /// A key that the format does not have.
    #[error("{}: unknown key `{key}`; allowed keys here: {allowed}", location(file, *line))]
    UnknownKey {
        file: String,
        line: Option<usize>,
        key: String,
        allowed: String,
    },
    /// A key with a value of the wrong type or outside its range, or a missing key.
    #[error("{}: {key}{message}", location(file, *line))]
    Invalid {
        file: String,
        line: Option<usize>,
        /// Dotted path, e.g. `render.width` or `lights[1].intensity`.
        key: String,
        /// Starts with ` = <value as written>: ` where a value exists, else `: `.
        message: String,
    },
}

impl ExperimentError {
    /// An `Invalid` error with what `requirement(key, message)` gives appended after
    /// "; " (what the key takes, where its message does not say); any other as it is.
    pub(crate) fn with_requirement(
        self,
        requirement: impl FnOnce(&str, &str) -> Option<String>,
    ) -> Self {
        match self {
            Self::Invalid {
                file,
                line,
                key,
                message,
            } => {
                let message = match requirement(&key, &message) {
                    Some(r) => format!("{message}; {r}"),
                    None => message,
                };
                Self::Invalid {
                    file,
                    line,
                    key,
                    message,
                }
            }
            other => other,
        }
    }

    /// The line the error points at (1-based), if it has one.
    pub fn line(&self) -> Option<usize> {
        match self {
            Self::Io { .. } => None,
            Self::Syntax { line, .. }
            | Self::UnknownKey { line, .. }
            | Self::Invalid { line, .. } => *line,
        }
    }
}

fn location(file: &str, line: Option<usize>) -> String {
    match line {
        Some(l) => format!("{file}:{l}"),
        None => file.to_string(),
    }
}

// ---------------------------------------------------------------------------------------
// The file as written (serde). Everything optional has its default in `build`, where the
// defaults depend on the grid (the seed's camera and lights are relative to it).

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawExperiment {
    name: Option<String>,
    description: Option<String>,
    #[serde(default)]
    scene: RawScene,
    #[serde(default)]
    camera: RawCamera,
    /// Absent: the seed's lights. `lights = []`: no lights at all.
    lights: Option<Vec<RawLight>>,
    #[serde(default)]
    materials: Vec<RawMaterial>,
    #[serde(default)]
    render: RawRender,
    /// `[features]`: checked against the declarations of `crate::technique`.
    features: Option<toml::Table>,
    /// The tables of the shared setting groups (`crate::technique::SETTING_GROUPS`),
    /// each checked against its declarations (`apply_groups`); serde takes each table
    /// as a field.
    cones: Option<toml::Table>,
    /// `[techniques.<name>]`: settings of plug-in techniques, checked against their
    /// declarations (`crate::technique`).
    techniques: Option<toml::Table>,
    /// `[ablate]`: the sweep of `voxlab ablate`, validated there (`crate::ablate`), so
    /// the same file also renders with `voxlab render`.
    #[allow(dead_code)]
    ablate: Option<toml::Table>,
}

/// Where the voxels come from. Only generators exist so far; file sources
/// (`vox = "path"`, `mesh = "path"`) will be further keys of `[scene]`, exclusive with
/// `generator`.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
enum Generator {
    /// The seed report's scene (section 3.2) at any grid size.
    #[default]
    Seed,
    /// An all-void grid, to be filled by `[[scene.boxes]]`.
    Empty,
}

/// Fixed-length arrays of the file. serde reads `[T; N]` from the first N elements of a
/// longer TOML array and ignores the rest (`dims = [8, 8, 8, 999]` rendered 8^3 without
/// a word), so these read the whole array and check its length.
mod exact {
    use serde::de::{Deserialize, Deserializer, Error};

    pub fn array<'de, D, T, const N: usize>(d: D) -> Result<[T; N], D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        let v = Vec::<T>::deserialize(d)?;
        let len = v.len();
        v.try_into()
            .map_err(|_| D::Error::invalid_length(len, &format!("an array of length {N}").as_str()))
    }

    pub fn option<'de, D, T, const N: usize>(d: D) -> Result<Option<[T; N]>, D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de>,
    {
        array(d).map(Some)
    }
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    /// Absent: the seed generator, unless `vox` or `mesh` gives the voxels.
    generator: Option<Generator>,
    size: Option<i64>,
    #[serde(default, deserialize_with = "exact::option")]
    dims: Option<[i64; 3]>,
    voxel_size: Option<f64>,
    #[serde(default, deserialize_with = "exact::option")]
    origin: Option<[f64; 3]>,
    #[serde(default)]
    boxes: Vec<RawBox>,
    /// A MagicaVoxel file (relative to the experiment file) instead of a generator.
    vox: Option<String>,
    /// With `vox`: load only this model (0-based), unmoved.
    model: Option<i64>,
    /// A mesh (OBJ, glTF, GLB; relative to the experiment file) to voxelize.
    mesh: Option<String>,
    /// With `mesh`: voxels along its longest axis (or give `voxel_size` instead).
    resolution: Option<i64>,
    /// With `mesh`: one material (name or index) for all its voxels.
    material: Option<MaterialRef>,
    /// `.vox` models and meshes placed into the grid (`models.rs`).
    #[serde(default)]
    models: Vec<models::RawModel>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBox {
    #[serde(deserialize_with = "exact::array")]
    min: [i64; 3],
    #[serde(deserialize_with = "exact::array")]
    max: [i64; 3],
    material: MaterialRef,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(untagged, expecting = "a material name (string) or index (integer)")]
enum MaterialRef {
    Index(i64),
    Name(String),
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCamera {
    #[serde(default, deserialize_with = "exact::option")]
    target: Option<[f64; 3]>,
    distance: Option<f64>,
    yaw_deg: Option<f64>,
    pitch_deg: Option<f64>,
    vfov_deg: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(rename_all = "lowercase")]
enum LightType {
    Point,
    Rect,
    Disk,
    Sphere,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLight {
    #[serde(rename = "type")]
    kind: LightType,
    #[serde(deserialize_with = "exact::array")]
    position: [f64; 3],
    #[serde(default, deserialize_with = "exact::option")]
    color: Option<[f64; 3]>,
    intensity: f64,
    /// Rectangles and disks: the facing direction (any length > 0).
    #[serde(default, deserialize_with = "exact::option")]
    normal: Option<[f64; 3]>,
    /// Rectangles: full side lengths along the light's u and v axes.
    #[serde(default, deserialize_with = "exact::option")]
    size: Option<[f64; 2]>,
    /// Disks and spheres.
    radius: Option<f64>,
    /// Rectangles and disks: turn about the normal.
    rotation_deg: Option<f64>,
    /// Rectangles and disks: "isotropic" (default) or "lambertian".
    emission: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    name: String,
    #[serde(default, deserialize_with = "exact::option")]
    albedo: Option<[f64; 3]>,
    kd: Option<f64>,
    ks: Option<f64>,
    shininess: Option<f64>,
    kr: Option<f64>,
    kt: Option<f64>,
    ior: Option<f64>,
    #[serde(default, deserialize_with = "exact::option")]
    sigma: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::option")]
    emission: Option<[f64; 3]>,
    dielectric: Option<String>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRender {
    width: Option<i64>,
    height: Option<i64>,
    max_reflection_depth: Option<i64>,
    max_refraction_depth: Option<i64>,
    max_depth: Option<i64>,
    rules: Option<RulesName>,
    falloff: Option<bool>,
    falloff_min_distance: Option<f64>,
    ray_offset: Option<f64>,
    ray_cutoff: Option<f64>,
    #[serde(default, deserialize_with = "exact::option")]
    ambient: Option<[f64; 3]>,
    light_samples: Option<i64>,
    spp: Option<i64>,
    seed: Option<i64>,
    path_frames: Option<i64>,
    orbit_deg: Option<f64>,
    pixel_filter: Option<String>,
    filter_width: Option<f64>,
    traversal: Option<String>,
    walk_budget_mib: Option<i64>,
    surface: Option<String>,
}

// ---------------------------------------------------------------------------------------

impl Experiment {
    /// The seed's scene at 16^3, 512x512, depth 4/4, every feature off: what
    /// `experiments/baseline.toml` describes and what `voxlab` renders by default.
    pub fn seed_default() -> Self {
        Self {
            name: "seed".to_string(),
            description: None,
            source_path: None,
            source_record: None,
            scene: seed_scene(SEED_SIZE).expect("the seed scene at its own size is valid"),
            settings: RenderSettings::default(),
        }
    }

    /// Replaces the scene's voxels and palette (`materials`, index 0 void, every index
    /// the grid uses defined): a volume of one's own. What the file left to the seed's
    /// defaults follows the grid: a camera aimed at the old grid's centre at the seed's
    /// distance is aimed at the new one's at the new distance, and the seed's lights for
    /// the old grid become the seed's lights for the new one; what the file set stays.
    /// The triangles of a voxelized mesh go with the old grid. The experiment no longer
    /// renders from its file: `source_path` is cleared, and its records carry the grid's
    /// hash.
    pub fn set_grid(&mut self, grid: Grid, materials: Vec<Material>) -> crate::Result<()> {
        let scene_error = |m: String| crate::Error::new(crate::ErrorKind::Scene, m);
        let (old_c, old_w) = (self.scene.grid.centre(), self.scene.grid.width());
        let (c, w) = (grid.centre(), grid.width());
        let mut scene = Scene {
            grid,
            materials,
            mesh: None,
            ..self.scene.clone()
        };
        let seed_old = seed_camera(old_c, old_w);
        if scene.camera.target == seed_old.target {
            scene.camera.target = c;
        }
        if scene.camera.distance == seed_old.distance {
            scene.camera.distance = seed_camera(c, w).distance;
        }
        if scene.lights == seed_lights(old_c, old_w) {
            scene.lights = seed_lights(c, w);
        }
        scene.validate().map_err(|e| scene_error(e.0))?;
        crate::plan::check_surface(&scene, &self.settings)
            .map_err(|e| scene_error(format!("render.surface: {e}")))?;
        crate::plan::check_traversal(&scene, &self.settings)
            .map_err(|e| scene_error(format!("render.traversal: {e}")))?;
        self.scene = scene;
        self.source_path = None;
        self.source_record = None;
        Ok(())
    }

    /// Reads and validates an experiment file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, ExperimentError> {
        let path = path.as_ref();
        let text = read_text(path)?;
        let mut e = Self::from_str(&text, path)?;
        e.set_source(path, &text, &[])?;
        Ok(e)
    }

    /// Parses and validates experiment text; `path` names it in messages and gives the
    /// default name (its stem). `source_path` stays `None`: nothing was read from disk;
    /// `source_record` holds the text, so that an image's record gives its `[scene]`.
    pub fn from_str(text: &str, path: impl AsRef<Path>) -> Result<Self, ExperimentError> {
        let path = path.as_ref();
        Self::parse(text, path, None)?.recorded(text, path, &[], None)
    }

    /// The parser itself: text to a checked experiment, without its record.
    fn parse(
        text: &str,
        path: &Path,
        cache: Option<&mut SceneCache>,
    ) -> Result<Self, ExperimentError> {
        let ctx = Ctx::new(text, path);
        let raw: RawExperiment = toml::from_str(text)
            .map_err(|e| with_allowed_range(ctx.serde_error(&e), text, path))?;
        build(raw, &ctx, cache)
    }

    /// The experiment with the record of `text` (read from `path`, or named so) and
    /// `overrides` ([`SourceRecord`]).
    fn recorded(
        mut self,
        text: &str,
        path: &Path,
        overrides: &[Override],
        assets: Option<Vec<serde_json::Value>>,
    ) -> Result<Self, ExperimentError> {
        self.source_record = Some(Arc::new(SourceRecord::with_assets(
            path, text, overrides, assets,
        )?));
        Ok(self)
    }

    /// [`Experiment::from_str`], but the grid and the file palette come from `cache` when
    /// the `[scene]` table and the file's directory are the same as in the last call that
    /// loaded them: re-parsing after an edit of the lights, the camera or the materials
    /// does not reload a `.vox` file or voxelize a mesh again. The result is equal to
    /// `from_str`'s: `[[scene.boxes]]` and a mesh's `material` are applied to a copy.
    pub fn from_str_cached(
        text: &str,
        path: impl AsRef<Path>,
        cache: &mut SceneCache,
    ) -> Result<Self, ExperimentError> {
        let path = path.as_ref();
        let e = Self::parse(text, path, Some(&mut *cache))?;
        e.recorded(text, path, &[], cache.assets())
    }
}

/// A whole palette from `[[materials]]` tables alone: entry `i` is material `i + 1`
/// (0 is void), each checked as an experiment file's `[[materials]]` are, starting from
/// void's neutral values rather than the seed's. What the Python `Grid.from_numpy`
/// reads its `palette` with; `path` names the text in messages.
pub fn palette_from_str(
    text: &str,
    path: impl AsRef<Path>,
) -> Result<Vec<Material>, ExperimentError> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct RawPalette {
        #[serde(default)]
        materials: Vec<RawMaterial>,
    }
    let path = path.as_ref();
    let ctx = Ctx::new(text, path);
    let raw: RawPalette =
        toml::from_str(text).map_err(|e| with_allowed_range(ctx.serde_error(&e), text, path))?;
    let void = crate::scene::seed_palette().swap_remove(0);
    let palette = build_materials(Some(vec![void]), &raw.materials, &ctx)?;
    if palette.len() > crate::scene::MAX_MATERIALS {
        return Err(ctx.invalid(
            "materials",
            format!(
                "{} materials; at most {} besides void (u8 indices)",
                raw.materials.len(),
                crate::scene::MAX_MATERIALS - 1
            ),
        ));
    }
    Ok(palette)
}

/// One `--set KEY=VALUE`: a dotted key of the experiment file (`render.width`,
/// `features.shadow_model`, `techniques.sdf.softness`, `lights[0].intensity`) and a TOML
/// value (`64`, `0.5`, `true`, `[1, 2, 3]`, `"sdf"`; a bare word that is not TOML is
/// taken as a string, so `features.shadow_model=sdf` needs no quotes).
#[derive(Clone, Debug, PartialEq)]
pub struct Override {
    pub key: String,
    pub value: String,
}

impl std::str::FromStr for Override {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let (key, value) = s.split_once('=').ok_or_else(|| {
            format!(
                "`{}`: expected KEY=VALUE, e.g. render.width=64",
                crate::input::excerpt(s, 120)
            )
        })?;
        let key = key.trim();
        let parts = key.split('.').count();
        if parts > MAX_KEY_PARTS {
            return Err(format!(
                "`{}`: a key of {parts} dotted parts; keys have at most {MAX_KEY_PARTS} \
                 (e.g. techniques.sdf.softness)",
                crate::input::excerpt(key, 60)
            ));
        }
        let ok = !key.is_empty()
            && key.split('.').all(|seg| {
                let name = seg.split_once('[').map_or(seg, |(n, rest)| {
                    if rest
                        .strip_suffix(']')
                        .is_some_and(|i| i.parse::<usize>().is_ok())
                    {
                        n
                    } else {
                        ""
                    }
                });
                !name.is_empty()
                    && name
                        .chars()
                        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
            });
        if !ok {
            return Err(format!(
                "`{}`: a key is dotted names, with [N] after an array of tables's name \
                 (e.g. render.width, lights[0].intensity)",
                crate::input::excerpt(key, 120)
            ));
        }
        Ok(Self {
            key: key.to_string(),
            value: value.trim().to_string(),
        })
    }
}

/// Most dotted parts a `--set` key may have: the deepest key of a file is
/// `techniques.<model>.<setting>` or `ablate.sweep`; a deeper one cannot name a setting,
/// and 5,000 parts made a TOML document too deep to read back.
pub(crate) const MAX_KEY_PARTS: usize = 8;

impl Override {
    /// `key=value` for a message: the value cut to 120 characters, as a file's values
    /// are in its messages.
    pub fn label(&self) -> String {
        format!("{}={}", self.key, crate::input::excerpt(&self.value, 120))
    }
}

impl fmt::Display for Override {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}={}", self.key, self.value)
    }
}

/// Keys that give one thing in two ways, of which a file gives one: an override of one
/// replaces the file's other, as editing the file would (`--set scene.dims=[64, 1, 64]`
/// on a file of `size = 16`, which was refused as giving both). Two overrides that give
/// both are still refused.
const ALTERNATIVE_KEYS: &[[&str; 2]] = &[
    ["scene.size", "scene.dims"],
    ["scene.resolution", "scene.voxel_size"],
];

/// `text` with each override written in: existing keys are replaced, and so is the
/// file's other way of giving the same thing (its `scene.size` under an override of
/// `scene.dims`, its `scene.resolution` under one of `scene.voxel_size`, and back);
/// missing tables and keys are added. The error is located at the override that cannot
/// be written.
pub fn apply_overrides(text: &str, overrides: &[Override]) -> Result<String, ExperimentError> {
    let Some(first) = overrides.first() else {
        return Ok(text.to_string());
    };
    let at = |o: &Override, message: String| ExperimentError::Invalid {
        file: format!("--set {}", o.label()),
        line: None,
        key: o.key.clone(),
        message: format!(": {message}"),
    };
    let mut doc: toml_edit::DocumentMut = text
        .parse()
        .map_err(|e| at(first, format!("the experiment is not TOML: {e}")))?;
    // Values written as the user wrote them ([`overflows_64_bits`]), by their marks.
    let mut raw = Vec::new();
    let taken: String = std::iter::once(text)
        .chain(overrides.iter().map(|o| o.value.as_str()))
        .collect();
    for (i, o) in overrides.iter().enumerate() {
        let fail = |message: String| at(o, message);
        let value = match o.value.parse::<toml_edit::Value>() {
            Ok(v) => v,
            Err(e) if overflows_64_bits(&o.value, e.message()) => {
                let mark = raw_mark(&taken, raw.len());
                raw.push((mark.clone(), o.value.clone()));
                toml_edit::Value::from(mark)
            }
            Err(_) => toml_edit::Value::from(o.value.as_str()),
        };
        let mut parts: Vec<&str> = o.key.split('.').collect();
        let last = parts.pop().expect("a key has a name");
        let mut table = doc.as_table_mut();
        for seg in parts {
            let (name, index) = match seg.split_once('[') {
                Some((n, rest)) => (n, rest.trim_end_matches(']').parse::<usize>().ok()),
                None => (seg, None),
            };
            let item = table.entry(name).or_insert_with(|| {
                let mut t = toml_edit::Table::new();
                t.set_implicit(true);
                toml_edit::Item::Table(t)
            });
            table = match (index, item) {
                (None, toml_edit::Item::Table(t)) => t,
                (Some(i), toml_edit::Item::ArrayOfTables(a)) => {
                    let n = a.len();
                    a.get_mut(i).ok_or_else(|| {
                        fail(format!("`{name}` has {n} entries, so [{i}] does not exist"))
                    })?
                }
                (Some(_), _) => {
                    return Err(fail(format!(
                        "`{name}` is not an array of tables in this experiment (write its \
                         [[{name}]] entries in the file to override one)"
                    )));
                }
                (None, _) => return Err(fail(format!("`{name}` is not a table"))),
            };
        }
        if last.contains('[') {
            return Err(fail(
                "the last part of the key must be a plain name".to_string(),
            ));
        }
        for pair in ALTERNATIVE_KEYS {
            let Some(k) = pair.iter().position(|key| *key == o.key) else {
                continue;
            };
            let other = pair[1 - k];
            let given_too = overrides[..i].iter().any(|earlier| earlier.key == other);
            if !given_too {
                table.remove(other.rsplit('.').next().expect("a key has a name"));
            }
        }
        table.insert(last, toml_edit::Item::Value(value));
    }
    Ok(write_raw(doc.to_string(), &raw))
}

/// Whether `value`, which toml_edit refused with `parse_error`, is TOML but for a number
/// 64 bits cannot hold (`1e400`, `99999999999999999999`, `[4, 1e999]`). Taken as a bare
/// word it would be a string, "invalid type: string" for what the user wrote as a
/// number; written into the text as it is, the parse names its key and range as it does
/// a file's ([`Ctx::past_64_bits`]). Only numbers, signs, brackets and commas: a value
/// that could carry other TOML is never written raw.
fn overflows_64_bits(value: &str, parse_error: &str) -> bool {
    is_overflow(parse_error)
        && value
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "_+-.[], ".contains(c))
}

/// Whether a message of toml or toml_edit is its refusal of a number past 64 bits.
fn is_overflow(message: &str) -> bool {
    message.contains("number overflowed")
        || message.contains(" as i128")
        || message.contains("value was too large")
}

/// A string that stands in a written document for the `n`th raw value and occurs nowhere
/// in `text` (all that goes into the document).
pub fn raw_mark(text: &str, n: usize) -> String {
    let mut mark = format!("voxlab-raw-{n}");
    while text.contains(&mark) {
        mark.push('~');
    }
    mark
}

/// `text` with each quoted mark of `raw` replaced by its value as written: how a number
/// past 64 bits, which no TOML writer takes, reaches the parser that names its key.
pub fn write_raw(mut text: String, raw: &[(String, String)]) -> String {
    for (mark, value) in raw {
        text = text.replacen(&format!("\"{mark}\""), value, 1);
    }
    text
}

impl Experiment {
    /// [`Experiment::load`] with `--set` overrides written into the text first: parsed
    /// and checked exactly like the file. An error about an overridden key names the
    /// override; any other names the file (its line may have moved where an override
    /// added a key).
    pub fn load_with(
        path: impl AsRef<Path>,
        overrides: &[Override],
    ) -> Result<Self, ExperimentError> {
        let path = path.as_ref();
        let text = read_text(path)?;
        let mut e = Self::from_str_with(&text, path, overrides)?;
        e.set_source(path, &text, overrides)?;
        Ok(e)
    }

    /// Names `path` as the file this experiment was parsed from, as `text` with
    /// `overrides`, and records them ([`SourceRecord`]): what a caller that read the
    /// file itself sets.
    pub fn set_source(
        &mut self,
        path: &Path,
        text: &str,
        overrides: &[Override],
    ) -> Result<(), ExperimentError> {
        // Parsed from this very text and path: the record made then holds.
        let labels: Vec<String> = overrides.iter().map(|o| o.to_string()).collect();
        let made = self.source_record.as_ref().is_some_and(|r| {
            *r.text == *text
                && r.overrides == labels
                && r.inputs.first().and_then(|i| i["path"].as_str())
                    == Some(path.display().to_string().as_str())
        });
        if !made {
            self.source_record = Some(Arc::new(SourceRecord::new(path, text, overrides)?));
        }
        self.source_path = Some(path.to_path_buf());
        Ok(())
    }

    /// [`Experiment::from_str`] with `--set` overrides (see [`Experiment::load_with`]).
    pub fn from_str_with(
        text: &str,
        path: impl AsRef<Path>,
        overrides: &[Override],
    ) -> Result<Self, ExperimentError> {
        Self::from_str_with_cache(text, path, overrides, &mut SceneCache::new())
    }

    /// [`Experiment::from_str_with`] with a scene cache: the file alone is parsed first,
    /// so its own errors keep their lines, and the cache keeps a .vox or mesh from being
    /// loaded twice when no override touches `[scene]`.
    pub fn from_str_with_cache(
        text: &str,
        path: impl AsRef<Path>,
        overrides: &[Override],
        cache: &mut SceneCache,
    ) -> Result<Self, ExperimentError> {
        let path = path.as_ref();
        if overrides.is_empty() {
            return Self::from_str_cached(text, path, cache);
        }
        Self::parse(text, path, Some(&mut *cache))?;
        let edited = apply_overrides(text, overrides)?;
        let e = Self::parse(&edited, path, Some(&mut *cache))
            .map_err(|e| blame_override(e, overrides))?;
        e.recorded(text, path, overrides, cache.assets())
    }
}

/// An error of an overridden experiment, located at the override when it is about one.
fn blame_override(e: ExperimentError, overrides: &[Override]) -> ExperimentError {
    let key = match &e {
        ExperimentError::Invalid { key, .. } | ExperimentError::UnknownKey { key, .. } => key,
        _ => return e,
    };
    let Some(o) = overrides.iter().rev().find(|o| {
        key == &o.key
            || key.starts_with(&format!("{}.", o.key))
            || key.starts_with(&format!("{}[", o.key))
    }) else {
        let keys: Vec<String> = overrides.iter().map(|o| o.key.clone()).collect();
        return match e {
            ExperimentError::Invalid {
                file,
                line,
                key,
                message,
            } => ExperimentError::Invalid {
                file: format!("{file} (with --set {})", keys.join(", ")),
                line,
                key,
                message,
            },
            ExperimentError::UnknownKey {
                file,
                line,
                key,
                allowed,
            } => ExperimentError::UnknownKey {
                file: format!("{file} (with --set {})", keys.join(", ")),
                line,
                key,
                allowed,
            },
            other => other,
        };
    };
    let file = format!("--set {}", o.label());
    match e {
        ExperimentError::Invalid { key, message, .. } => ExperimentError::Invalid {
            file,
            line: None,
            key,
            message,
        },
        ExperimentError::UnknownKey { key, allowed, .. } => ExperimentError::UnknownKey {
            file,
            line: None,
            key,
            allowed,
        },
        other => other,
    }
}

/// The voxels of one `[scene]` source, for [`Experiment::from_str_cached`]: the grid and
/// the file palette as the generator or the `.vox`/mesh loader made them, before boxes
/// and a mesh material are applied. Holds the last source only (a viewer edits one
/// experiment at a time; a grid can be large).
#[derive(Debug, Default)]
pub struct SceneCache {
    entry: Option<CachedScene>,
    hits: u64,
    misses: u64,
}

#[derive(Debug)]
struct CachedScene {
    /// `Debug` of the `[scene]` table as parsed, and the experiment file's directory
    /// (relative `vox`/`mesh` paths start there).
    key: String,
    grid: Grid,
    palette: Option<Vec<Material>>,
    models: Vec<models::LoadedModel>,
    mesh: Option<Arc<SurfaceMesh>>,
    /// The hashes of the files it read, taken when it read them (a record's assets).
    assets: Vec<serde_json::Value>,
}

impl SceneCache {
    /// The held scene's asset hashes, as taken when it was loaded.
    fn assets(&self) -> Option<Vec<serde_json::Value>> {
        self.entry.as_ref().map(|c| c.assets.clone())
    }

    pub fn new() -> Self {
        Self::default()
    }

    /// Scenes held: 0 or 1.
    pub fn len(&self) -> usize {
        usize::from(self.entry.is_some())
    }

    pub fn is_empty(&self) -> bool {
        self.entry.is_none()
    }

    /// Parses that reused the held grid.
    pub fn hits(&self) -> u64 {
        self.hits
    }

    /// Parses that built or loaded the grid (and then held it).
    pub fn misses(&self) -> u64 {
        self.misses
    }

    /// Forgets the held scene (e.g. after the `.vox` or mesh file changed on disk); the
    /// counters stay.
    pub fn clear(&mut self) {
        self.entry = None;
    }
}

/// What an experiment's name may be, in the words of the messages.
pub(crate) const NAME_RULE: &str =
    "1 to 128 characters from A-Z a-z 0-9 - _ . (not starting with '.')";

/// Whether `name` is an experiment's name ([`NAME_RULE`]): it names the default output
/// file, so it is a file name on every system.
pub(crate) fn is_valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= 128
        && !name.starts_with('.')
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
}

/// The name of an experiment whose file gives none: its file's stem, each character
/// [`NAME_RULE`] does not take (a space, `<`, a letter outside ASCII) and a leading '.'
/// as '_', cut to 128 characters. A stem taken as it was ("my scene", Python's
/// "<dict>") rendered and then failed to write the image.
pub(crate) fn name_from_stem(stem: &str) -> String {
    let name: String = stem
        .chars()
        .enumerate()
        .map(|(i, c)| {
            let allowed = c.is_ascii_alphanumeric() || "-_.".contains(c);
            if allowed && !(i == 0 && c == '.') {
                c
            } else {
                '_'
            }
        })
        .take(128)
        .collect();
    if name.is_empty() {
        "experiment".to_string()
    } else {
        name
    }
}

/// What error messages need: the file's name, and the text to find lines in. The one
/// TOML locator: the experiment's parser and `[ablate]`'s (`crate::ablate`) both name
/// `file:line: key = value: requirement` through it.
pub(crate) struct Ctx<'a> {
    pub(crate) file: String,
    stem: String,
    text: &'a str,
    /// `None` only if toml_edit rejects what toml accepted; lines are then left out.
    doc: Option<toml_edit::Document<String>>,
}

impl<'a> Ctx<'a> {
    pub(crate) fn new(text: &'a str, path: &Path) -> Self {
        Self {
            file: path.display().to_string(),
            stem: path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "experiment".to_string()),
            text,
            doc: toml_edit::Document::parse(text.to_string()).ok(),
        }
    }

    fn line_of(&self, offset: usize) -> usize {
        let offset = offset.min(self.text.len());
        self.text.as_bytes()[..offset]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1
    }

    /// The span of the value at `path`, or of the nearest enclosing item that has one
    /// (a missing key points at its table).
    fn span_of(&self, path: &str) -> Option<Range<usize>> {
        let doc = self.doc.as_ref()?;
        let mut item = doc.as_item();
        let mut best = None;
        for seg in path.split('.') {
            let (key, index) = match seg.split_once('[') {
                Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
                None => (seg, None),
            };
            let Some((k, child)) = get_key_value(item, key) else {
                break;
            };
            best = child.span().or(k.span()).or(best);
            item = child;
            if let Some(i) = index {
                match item.get(i) {
                    Some(child) => {
                        best = child.span().or(best);
                        item = child;
                    }
                    None => break,
                }
            }
        }
        best
    }

    /// The value as written in the file, for messages (`nan`, `-1`, `[0, 0, 0]`).
    fn raw_value(&self, path: &str) -> Option<String> {
        let doc = self.doc.as_ref()?;
        let mut item = doc.as_item();
        for seg in path.split('.') {
            let (key, index) = match seg.split_once('[') {
                Some((k, rest)) => (k, rest.trim_end_matches(']').parse::<usize>().ok()),
                None => (seg, None),
            };
            item = get_key_value(item, key)?.1;
            if let Some(i) = index {
                item = item.get(i)?;
            }
        }
        let span = item.as_value()?.span()?;
        self.text.get(span).map(|s| s.trim().to_string())
    }

    /// The line of the value at `path` (or of the nearest enclosing table the file has).
    pub(crate) fn line_of_key(&self, path: &str) -> Option<usize> {
        self.span_of(path).map(|s| self.line_of(s.start))
    }

    /// `key = value: what is allowed`, at the key's line.
    pub(crate) fn invalid(&self, key: &str, requirement: impl fmt::Display) -> ExperimentError {
        // Quoted values are cut: a 10 MB `name` must not make a 10 MB message.
        let requirement = crate::input::excerpt(&requirement.to_string(), 400);
        let message = match self.raw_value(key) {
            Some(v) => format!(
                " = {}: {requirement}",
                crate::input::excerpt(&v.to_string(), 120)
            ),
            None => format!(": {requirement}"),
        };
        ExperimentError::Invalid {
            file: self.file.clone(),
            line: self.span_of(key).map(|s| self.line_of(s.start)),
            key: key.to_string(),
            message,
        }
    }

    /// A number 64 bits cannot hold (`1e400`, `99999999999999999999`), which toml refuses
    /// as malformed, without its key: the text with that number quoted is TOML, and its
    /// key is the one whose value covers the span. `None` for any other syntax error. The
    /// key's range is asked of its check, as for a type error ([`allowed_range`]).
    fn past_64_bits(
        &self,
        span: &Range<usize>,
        msg: &str,
        line: Option<usize>,
    ) -> Option<ExperimentError> {
        if !is_overflow(msg) {
            return None;
        }
        let number = self.text.get(span.clone())?.trim();
        if number.is_empty() || number.contains(['"', '\'', '\n']) {
            return None;
        }
        let start = span.start + self.text[span.clone()].find(number)?;
        let quoted = format!(
            "{}\"{number}\"{}",
            &self.text[..start],
            &self.text[start + number.len()..]
        );
        // A Document keeps the spans (a DocumentMut drops them).
        let doc = toml_edit::Document::parse(quoted.as_str()).ok()?;
        let key = path_at(doc.as_item(), &(start..start + number.len() + 2), "")?;
        let mut message = format!(
            " = {}: {PAST_64_BITS} (a number is at most 1.8e308 in size, an integer from \
             -2^63 to 2^63 - 1)",
            crate::input::excerpt(number, 120)
        );
        // Asked of the quoted text (the file itself is not TOML); `[ablate]`'s numbers,
        // which the experiment's checks do not read, of their declarations.
        if let Some(r) = allowed_range(&key, PAST_64_BITS, &quoted, Path::new(&self.file))
            .or_else(|| crate::settings::ablate::declared_range(&key))
        {
            message = format!("{message}; {r}");
        }
        Some(ExperimentError::Invalid {
            file: self.file.clone(),
            line,
            key,
            message,
        })
    }

    /// Converts serde's error (type mismatches, unknown or missing keys, bad syntax) into
    /// ours, naming the key at its span.
    pub(crate) fn serde_error(&self, e: &toml::de::Error) -> ExperimentError {
        let span = e.span();
        let line = span.as_ref().map(|s| self.line_of(s.start));
        // Serde names Rust types; a researcher writing TOML thinks in integers and numbers.
        let msg = e
            .message()
            .trim()
            .replace("expected i64", "expected an integer")
            .replace("expected f64", "expected a number");
        // Serde quotes a float in full: 1e308 as 309 digits.
        let msg = match msg.split_once("floating point `") {
            Some((head, rest)) => match rest.split_once('`') {
                Some((number, tail)) => match number.parse::<f64>() {
                    Ok(v) => format!(
                        "{head}floating point `{}`{tail}",
                        crate::input::short_number(v)
                    ),
                    Err(_) => msg.clone(),
                },
                None => msg.clone(),
            },
            None => msg,
        };
        // Serde names our structs ("expected struct RawRender"): to the file, a table.
        let msg = match msg.find("expected struct Raw") {
            Some(at) => format!("{}expected a table", &msg[..at]),
            None => msg,
        };
        // serde quotes the whole value ("invalid type: string \"...\""): cut at 120 as
        // the value itself is.
        let msg = match (msg.find(" \""), msg.rfind("\", ")) {
            (Some(a), Some(b)) if b > a + 2 => format!(
                "{} \"{}\"{}",
                &msg[..a],
                crate::input::excerpt(&msg[a + 2..b], 120),
                &msg[b + 1..]
            ),
            _ => msg,
        };
        let mut msg = crate::input::excerpt(&msg, 400);
        // toml says "duplicate key" without the key: its span covers the key's text (the
        // header's for a table defined twice).
        if msg == "duplicate key"
            && let Some(name) = span.as_ref().and_then(|s| self.text.get(s.clone()))
        {
            let name = name.trim().trim_matches(['[', ']']).trim();
            msg = format!(
                "duplicate key `{}`: each key (and each table) may be given once",
                crate::input::excerpt(name, 80)
            );
        }
        let Some(doc) = self.doc.as_ref() else {
            if let Some(e) = span.as_ref().and_then(|s| self.past_64_bits(s, &msg, line)) {
                return e;
            }
            // serde may stop at a type error (`width = [1, 1e400]`) before the number
            // the document's own parse refuses.
            if let Err(p) = toml_edit::Document::parse(self.text)
                && let Some(s) = p.span()
                && let Some(e) = self.past_64_bits(&s, p.message(), Some(self.line_of(s.start)))
            {
                return e;
            }
            return ExperimentError::Syntax {
                file: self.file.clone(),
                line,
                message: msg,
            };
        };
        let key = span
            .as_ref()
            .and_then(|s| path_at(doc.as_item(), s, ""))
            .unwrap_or_default();
        if let Some(rest) = msg.strip_prefix("unknown field `") {
            let (name, expected) = rest.split_once('`').unwrap_or((rest, ""));
            let allowed = allowed_list(expected);
            // The span covers the unknown key itself, so `key` already ends with it.
            let key = if key.is_empty() {
                name.to_string()
            } else {
                key
            };
            return ExperimentError::UnknownKey {
                file: self.file.clone(),
                line,
                key,
                allowed,
            };
        }
        if key.is_empty() {
            // Top-level problems (a missing top-level key) have no key to name.
            return ExperimentError::Invalid {
                file: self.file.clone(),
                line,
                key: "(top level)".to_string(),
                message: format!(": {msg}"),
            };
        }
        ExperimentError::Invalid {
            file: self.file.clone(),
            line,
            message: match self.raw_value(&key) {
                Some(v) => format!(" = {}: {msg}", crate::input::excerpt(&v.to_string(), 120)),
                None => format!(": {msg}"),
            },
            key,
        }
    }
}

/// A type error ("invalid type: string, expected an integer") with the key's allowed
/// range added. The range is declared once, by the check that parses the key: the text is
/// parsed again with the value replaced by one of the right type that no range admits
/// (the smallest integer, or -1e300; for an array, that many -1e300s), and that check's
/// requirement is quoted. An array's shape is said ("an array of 2 numbers") where the
/// probe finds it, whether or not its numbers have a range; a scalar key whose check
/// admits the probe keeps the message as it was.
fn with_allowed_range(e: ExperimentError, text: &str, path: &Path) -> ExperimentError {
    e.with_requirement(|key, message| allowed_range(key, message, text, path))
}

/// What [`Ctx::past_64_bits`] says of a number toml cannot hold.
const PAST_64_BITS: &str = "past what 64 bits hold";

/// What `key` takes, asked of its check by a probe ([`with_allowed_range`]).
fn allowed_range(key: &str, message: &str, text: &str, path: &Path) -> Option<String> {
    let numbers = |n: usize| {
        let array: toml_edit::Array = std::iter::repeat_n(-1e300, n).collect();
        (toml_edit::value(array), Some(n))
    };
    // Serde names an array's length only when the value was one of another length.
    let stated_length = message
        .split_once("expected an array of length ")
        .and_then(|(_, n)| n.trim().parse::<usize>().ok());
    let probes = if message.contains(PAST_64_BITS) {
        // Whichever the key takes: the other probe is refused before its check.
        vec![
            (toml_edit::value(i64::MIN), None),
            (toml_edit::value(-1e300), None),
        ]
    } else if message.contains("expected an integer") {
        vec![(toml_edit::value(i64::MIN), None)]
    } else if message.contains("expected a number") {
        vec![(toml_edit::value(-1e300), None)]
    } else if let Some(n) = stated_length {
        vec![numbers(n)]
    } else if message.contains("expected a sequence") {
        // Every array of numbers in the model is a vector or a rect's sides.
        vec![numbers(3), numbers(2)]
    } else {
        Vec::new()
    };
    probes.into_iter().find_map(|(value, length)| {
        let mut doc: toml_edit::DocumentMut = text.parse().ok()?;
        *item_at_mut(&mut doc, key)? = value;
        let probed = doc.to_string();
        // A length serde refuses is not the key's: try the next.
        let raw: RawExperiment = toml::from_str(&probed).ok()?;
        let requirement = match build(raw, &Ctx::new(&probed, path), None) {
            // An entry's probe may be refused under its array (`scene.dims[1]`: "scene.dims:
            // every side ...").
            Err(ExperimentError::Invalid {
                key: k, message: m, ..
            }) if k == key
                || key
                    .strip_prefix(k.as_str())
                    .is_some_and(|r| r.starts_with('[')) =>
            {
                m.rsplit_once(": ").map(|(_, req)| req.to_string())
            }
            _ => None,
        };
        match (length, requirement) {
            (Some(n), Some(r)) => Some(format!("an array of {n} numbers: {r}")),
            (Some(n), None) => Some(format!("an array of {n} numbers")),
            (None, r) => r,
        }
    })
}

/// The item a key names (`render.width`, `lights[0].size`), where the document has it.
fn item_at_mut<'a>(
    doc: &'a mut toml_edit::DocumentMut,
    key: &str,
) -> Option<&'a mut toml_edit::Item> {
    enum Step<'k> {
        Name(&'k str),
        At(usize),
    }
    let mut steps = Vec::new();
    for part in key.split('.') {
        match part.strip_suffix(']').and_then(|p| p.split_once('[')) {
            Some((name, at)) => {
                steps.push(Step::Name(name));
                steps.push(Step::At(at.parse().ok()?));
            }
            None => steps.push(Step::Name(part)),
        }
    }
    // Looked up first without changing anything: a mutable lookup by name inserts the
    // name where it is missing.
    let mut item = doc.as_item();
    for step in &steps {
        item = match step {
            Step::Name(name) => item.get(*name)?,
            Step::At(at) => item.get(*at)?,
        };
    }
    let mut item = doc.as_item_mut();
    for step in &steps {
        item = match step {
            Step::Name(name) => item.get_mut(*name)?,
            Step::At(at) => item.get_mut(*at)?,
        };
    }
    Some(item)
}

/// Serde lists the expected fields as ", expected one of `a`, `b`" or ", expected `a`"
/// or ", there are no fields"; keep just the names.
fn allowed_list(expected: &str) -> String {
    let names: Vec<&str> = expected.split('`').skip(1).step_by(2).collect();
    if names.is_empty() {
        "none (this table has no keys yet)".to_string()
    } else {
        names.join(", ")
    }
}

fn get_key_value<'d>(
    item: &'d toml_edit::Item,
    key: &str,
) -> Option<(&'d toml_edit::Key, &'d toml_edit::Item)> {
    match item {
        toml_edit::Item::Table(t) => t.get_key_value(key),
        toml_edit::Item::Value(toml_edit::Value::InlineTable(t)) => t.get_key_value(key),
        _ => None,
    }
}

fn contains(outer: &Range<usize>, inner: &Range<usize>) -> bool {
    outer.start <= inner.start && inner.start < outer.end.max(outer.start + 1)
}

/// The dotted path of the innermost key or value whose span holds `span`.
fn path_at(item: &toml_edit::Item, span: &Range<usize>, prefix: &str) -> Option<String> {
    let keys: Vec<String> = match item {
        toml_edit::Item::Table(t) => t.iter().map(|(k, _)| k.to_string()).collect(),
        toml_edit::Item::Value(toml_edit::Value::InlineTable(t)) => {
            t.iter().map(|(k, _)| k.to_string()).collect()
        }
        toml_edit::Item::ArrayOfTables(_) | toml_edit::Item::Value(toml_edit::Value::Array(_)) => {
            let mut i = 0;
            while let Some(child) = item.get(i) {
                let path = format!("{prefix}[{i}]");
                if let Some(p) = path_at(child, span, &path) {
                    return Some(p);
                }
                if child.span().is_some_and(|s| contains(&s, span)) {
                    return Some(path);
                }
                i += 1;
            }
            return None;
        }
        _ => return None,
    };
    for k in keys {
        let Some((key, child)) = get_key_value(item, &k) else {
            continue;
        };
        let path = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        if let Some(p) = path_at(child, span, &path) {
            return Some(p);
        }
        let hit = |s: Option<Range<usize>>| s.is_some_and(|s| contains(&s, span));
        if hit(key.span()) || hit(child.span()) {
            return Some(path);
        }
    }
    None
}

// ---------------------------------------------------------------------------------------
// Validation and assembly.

fn vec3_where(
    ctx: &Ctx,
    key: &str,
    v: [f64; 3],
    ok: impl Fn(f64) -> bool,
    what: &str,
) -> Result<DVec3, ExperimentError> {
    if v.iter().all(|&c| c.is_finite() && ok(c)) {
        Ok(DVec3::from_array(v))
    } else {
        Err(ctx.invalid(
            key,
            format!("every component must be a finite number {what}"),
        ))
    }
}

/// The value named `name` among `all` (by `name_of`), `default` when the key is absent;
/// an unknown name is an error that lists every allowed one.
fn choice<T: Copy>(
    ctx: &Ctx,
    key: &str,
    name: Option<&str>,
    default: T,
    all: &[T],
    name_of: fn(T) -> &'static str,
) -> Result<T, ExperimentError> {
    let Some(name) = name else {
        return Ok(default);
    };
    all.iter()
        .copied()
        .find(|&v| name_of(v) == name)
        .ok_or_else(|| {
            let names: Vec<String> = all.iter().map(|&v| format!("\"{}\"", name_of(v))).collect();
            let (last, rest) = names.split_last().expect("a choice has values");
            let allowed = if rest.is_empty() {
                last.clone()
            } else {
                format!("{} or {last}", rest.join(", "))
            };
            ctx.invalid(key, format!("must be {allowed}"))
        })
}

fn int_in(
    ctx: &Ctx,
    key: &str,
    v: i64,
    range: std::ops::RangeInclusive<i64>,
) -> Result<u32, ExperimentError> {
    if range.contains(&v) {
        // Every range used here lies within u32.
        Ok(v as u32)
    } else {
        Err(ctx.invalid(
            key,
            format!("must be an integer in {}..={}", range.start(), range.end()),
        ))
    }
}

/// `v` checked against its declaration `setting` (`crate::settings`), under `key`.
fn declared(ctx: &Ctx, key: &str, setting: &Setting, v: f64) -> Result<f64, ExperimentError> {
    setting.check(v).map_err(|req| ctx.invalid(key, req))
}

/// The values `given` (key, value if the file has it) of the declared `fields` of
/// `table`, checked and set in `target`.
fn apply_fields<T>(
    fields: &'static [Field<T>],
    table: &str,
    given: &[(&str, Option<f64>)],
    target: &mut T,
    ctx: &Ctx,
) -> Result<(), ExperimentError> {
    for f in fields {
        let value = given.iter().find(|(k, _)| *k == f.key());
        debug_assert!(
            value.is_some(),
            "the file has no key for {table}.{}",
            f.key()
        );
        if let Some(&(_, Some(v))) = value {
            let v = declared(ctx, &format!("{table}.{}", f.key()), &f.setting, v)?;
            (f.set)(target, v);
        }
    }
    Ok(())
}

/// The grid and file palette of `[scene]`: `load_scene_file`, else `build_grid`; from the
/// cache when it holds the same source.
fn scene_voxels(
    s: &RawScene,
    ctx: &Ctx,
    cache: Option<&mut SceneCache>,
) -> Result<SceneVoxels, ExperimentError> {
    let load = || -> Result<SceneVoxels, ExperimentError> {
        let (grid, palette, mesh) = match load_scene_file(s, ctx)? {
            Some((g, p, m)) => (g, Some(p), m.map(Arc::new)),
            None => (build_grid(s, ctx)?, None, None),
        };
        let models = models::load_models(&s.models, ctx, grid.dims())?;
        Ok((grid, palette, models, mesh))
    };
    let Some(cache) = cache else {
        return load();
    };
    let dir = Path::new(&ctx.file).parent().unwrap_or(Path::new(""));
    let key = format!("{s:?}\n{}", dir.display());
    if let Some(c) = cache.entry.as_ref().filter(|c| c.key == key) {
        cache.hits += 1;
        return Ok((
            c.grid.clone(),
            c.palette.clone(),
            c.models.clone(),
            c.mesh.clone(),
        ));
    }
    let (grid, palette, models, mesh) = load()?;
    cache.misses += 1;
    cache.entry = Some(CachedScene {
        key,
        grid: grid.clone(),
        palette: palette.clone(),
        models: models.clone(),
        mesh: mesh.clone(),
        assets: write::asset_hashes(ctx.text, Path::new(&ctx.file)),
    });
    Ok((grid, palette, models, mesh))
}

/// The grid, the file palette (if a file gave the grid), the loaded models and the
/// mesh the grid was voxelized from (`scene.mesh`).
type SceneVoxels = (
    Grid,
    Option<Vec<Material>>,
    Vec<models::LoadedModel>,
    Option<Arc<SurfaceMesh>>,
);

/// One function because it is the order of validation: render settings, the scene,
/// materials, lights and models, each step reading what the earlier ones checked; each
/// key's own check lives with its declaration (`crate::settings`).
fn build(
    raw: RawExperiment,
    ctx: &Ctx,
    cache: Option<&mut SceneCache>,
) -> Result<Experiment, ExperimentError> {
    let name = match raw.name {
        Some(n) if is_valid_name(&n) => n,
        Some(_) => {
            return Err(ctx.invalid(
                "name",
                format!("must be {NAME_RULE}: it names the output file"),
            ));
        }
        None => name_from_stem(&ctx.stem),
    };

    // Render settings first: the ambient colour belongs to the scene.
    let r = &raw.render;
    let d = RenderSettings::default();
    let mut settings = RenderSettings {
        max_depth: r
            .max_depth
            .map(|v| declared(ctx, "render.max_depth", &settings::MAX_DEPTH, v as f64))
            .transpose()?
            .map(|v| v as u32),
        rules: match r.rules {
            None | Some(RulesName::Consistent) => crate::render::Rules::Consistent,
            Some(RulesName::Seed) => crate::render::Rules::Seed,
        },
        falloff: r.falloff.unwrap_or(d.falloff),
        features: build_features(raw.features.as_ref(), ctx)?,
        technique_params: build_technique_params(raw.techniques.as_ref(), ctx)?,
        // The shared groups' fields: their defaults here, the file's by apply_groups.
        cones: d.cones.clone(),
        pixel_filter: choice(
            ctx,
            "render.pixel_filter",
            r.pixel_filter.as_deref(),
            d.pixel_filter,
            &crate::render::PixelFilter::ALL,
            crate::render::PixelFilter::name,
        )?,
        traversal: choice(
            ctx,
            "render.traversal",
            r.traversal.as_deref(),
            d.traversal,
            &crate::render::Traversal::all(),
            crate::render::Traversal::name,
        )?,
        surface: choice(
            ctx,
            "render.surface",
            r.surface.as_deref(),
            d.surface,
            &crate::render::Surface::all(),
            crate::render::Surface::name,
        )?,
        ..d
    };
    let int = |v: Option<i64>| v.map(|v| v as f64);
    let given = [
        ("width", int(r.width)),
        ("height", int(r.height)),
        ("max_reflection_depth", int(r.max_reflection_depth)),
        ("max_refraction_depth", int(r.max_refraction_depth)),
        ("light_samples", int(r.light_samples)),
        ("spp", int(r.spp)),
        ("seed", int(r.seed)),
        ("path_frames", int(r.path_frames)),
        ("orbit_deg", r.orbit_deg),
        ("filter_width", r.filter_width),
        ("falloff_min_distance", r.falloff_min_distance),
        ("ray_offset", r.ray_offset),
        ("ray_cutoff", r.ray_cutoff),
        ("walk_budget_mib", int(r.walk_budget_mib)),
    ];
    apply_fields(settings::RENDER, "render", &given, &mut settings, ctx)?;
    // serde takes each group's table as a field of RawExperiment.
    apply_groups(&[("cones", raw.cones.as_ref())], &mut settings, ctx)?;
    let ambient = match r.ambient {
        Some(a) => vec3_where(ctx, "render.ambient", a, |x| x >= 0.0, ">= 0")?,
        None => SEED_AMBIENT,
    };

    let (grid, file_palette, loaded_models, mesh) = scene_voxels(&raw.scene, ctx, cache)?;
    let c = grid.centre();
    let w = grid.width();

    let seed_cam = seed_camera(c, w);
    let cam = &raw.camera;
    let mut camera = seed_cam.clone();
    if let Some(t) = cam.target {
        camera.target = vec3_where(ctx, "camera.target", t, |_| true, "")?;
    }
    let given = [
        ("distance", cam.distance),
        ("yaw_deg", cam.yaw_deg),
        ("pitch_deg", cam.pitch_deg),
        ("vfov_deg", cam.vfov_deg),
    ];
    apply_fields(settings::CAMERA, "camera", &given, &mut camera, ctx)?;

    let lights = match &raw.lights {
        None => seed_lights(c, w),
        Some(ls) => ls
            .iter()
            .enumerate()
            .map(|(i, l)| {
                let key = |k: &str| format!("lights[{i}].{k}");
                build_light(l, ctx, &key)
            })
            .collect::<Result<_, ExperimentError>>()?,
    };

    let (file_palette, model_maps) = if raw.scene.models.is_empty() {
        (file_palette, Vec::new())
    } else {
        let mut palette = file_palette.unwrap_or_else(crate::scene::seed_palette);
        let maps = models::extend_palette(&raw.scene.models, &loaded_models, &mut palette, ctx)?;
        (Some(palette), maps)
    };
    let materials = build_materials(file_palette, &raw.materials, ctx)?;
    let mut scene = Scene {
        grid,
        materials,
        lights,
        camera,
        ambient,
        mesh,
    };
    apply_mesh_material(&mut scene, &raw.scene, ctx)?;
    models::place_models(
        &mut scene,
        &raw.scene.models,
        &loaded_models,
        model_maps,
        ctx,
    )?;
    fill_boxes(&mut scene, &raw.scene.boxes, ctx)?;
    // Everything above checks its own key; this catches what only the whole can tell
    // (a future generator using more materials than are defined).
    scene.validate().map_err(|e| ctx.invalid("scene", e))?;
    crate::plan::check_surface(&scene, &settings).map_err(|e| ctx.invalid("render.surface", e))?;
    crate::plan::check_traversal(&scene, &settings)
        .map_err(|e| ctx.invalid("render.traversal", e))?;
    crate::plan::check_sparse_grid(&scene, &settings).map_err(|(k, e)| ctx.invalid(k, e))?;
    // Cone pyramids scale with the grid: estimated before any render builds them.
    let plan = crate::plan::Plan::new(&scene, &settings);
    if let Some(layout) = plan.pyramid {
        use crate::technique::cones::pyramid::{MAX_PYRAMID_BYTES, cpu_pyramid_bytes};
        let indirect = plan.radiance_pyramid();
        let bytes = cpu_pyramid_bytes(&layout, indirect);
        if bytes > MAX_PYRAMID_BYTES {
            let d = scene.grid.dims();
            return Err(ctx.invalid(
                "features",
                format!(
                    "cone tracing on a {}x{}x{} grid needs pyramids of {bytes} bytes (the f64 \
                     reference's), more than the {MAX_PYRAMID_BYTES} allowed: use a smaller \
                     grid or turn the cone features off",
                    d.x, d.y, d.z
                ),
            ));
        }
    }

    Ok(Experiment {
        name,
        description: raw.description,
        source_path: None,
        source_record: None,
        scene,
        settings,
    })
}

/// `[features]`: every key one of `crate::technique::feature_keys` (the slots'
/// choices by name, the shadow models' older switches, the lighting terms' flags). A
/// shadow model is chosen once: by `shadow_model` or by one switch set to true.
fn build_features(t: Option<&toml::Table>, ctx: &Ctx) -> Result<Features, ExperimentError> {
    use crate::technique::{
        LIGHTING_TERMS, SHADOW_MODELS, feature_keys, shadow_model_names, transmittance,
        transmittance_names,
    };
    let mut features = Features::default();
    let Some(t) = t else {
        return Ok(features);
    };
    for (k, v) in t {
        let key = format!("features.{k}");
        let text = |names: Vec<&str>| {
            v.as_str().map(str::to_string).ok_or_else(|| {
                ctx.invalid(
                    &key,
                    format!("must be a string, one of: {}", names.join(", ")),
                )
            })
        };
        let boolean = || {
            v.as_bool()
                .ok_or_else(|| ctx.invalid(&key, "must be true or false"))
        };
        match k.as_str() {
            "shadow_model" => {
                let name = text(shadow_model_names())?;
                if !features.set_shadow_model(&name) {
                    return Err(ctx.invalid(
                        &key,
                        format!(
                            "no such shadow model; allowed: {}",
                            shadow_model_names().join(", ")
                        ),
                    ));
                }
            }
            "reconstruction" => {
                let names = crate::technique::reconstruction_names();
                let name = text(names.clone())?;
                features.reconstruction =
                    crate::technique::reconstruction(&name).ok_or_else(|| {
                        ctx.invalid(
                            &key,
                            format!("no such reconstruction; allowed: {}", names.join(", ")),
                        )
                    })?;
            }
            "transmittance" => {
                let name = text(transmittance_names())?;
                features.transmittance = transmittance(&name).ok_or_else(|| {
                    ctx.invalid(
                        &key,
                        format!(
                            "no such transmittance model; allowed: {}",
                            transmittance_names().join(", ")
                        ),
                    )
                })?;
            }
            _ => {
                // A shadow model's retired switch: one key, shadow_model, chooses every
                // model, so `--set features.shadow_model=X` works on every file.
                if let Some(m) = SHADOW_MODELS.iter().find(|m| m.switch == Some(k)) {
                    return Err(ctx.invalid(
                        &key,
                        if boolean()? {
                            format!(
                                "was replaced by features.shadow_model = \"{}\"; write that \
                                 instead",
                                m.name
                            )
                        } else {
                            format!(
                                "was replaced by features.shadow_model (false chose nothing: \
                                 remove the line; \"{}\" is the default)",
                                crate::technique::default_shadow_model().name
                            )
                        },
                    ));
                }
                let Some(term) = LIGHTING_TERMS.iter().find(|t| t.name == k) else {
                    return Err(ExperimentError::UnknownKey {
                        file: ctx.file.clone(),
                        line: ctx.span_of(&key).map(|s| ctx.line_of(s.start)),
                        key,
                        allowed: feature_keys().join(", "),
                    });
                };
                features.set_term(term.name, boolean()?);
            }
        }
    }
    Ok(features)
}

/// `[techniques.<name>]`: every key a declared setting of that plug-in technique, every
/// value of its type and in its range (`crate::technique::Setting`).
fn build_technique_params(
    t: Option<&toml::Table>,
    ctx: &Ctx,
) -> Result<crate::technique::TechniqueParams, ExperimentError> {
    use crate::technique::{technique_table, technique_table_names};
    let mut params = crate::technique::TechniqueParams::default();
    let Some(t) = t else {
        return Ok(params);
    };
    let names = || technique_table_names().join(", ");
    for (name, table) in t {
        let key = format!("techniques.{name}");
        let Some((_, settings)) = technique_table(name) else {
            return Err(ExperimentError::UnknownKey {
                file: ctx.file.clone(),
                line: ctx.span_of(&key).map(|s| ctx.line_of(s.start)),
                key,
                allowed: names(),
            });
        };
        let Some(table) = table.as_table() else {
            return Err(ctx.invalid(&key, "must be a table of the technique's settings"));
        };
        let declared: Vec<&crate::technique::Setting> = settings.iter().collect();
        for (setting, v) in declared_values(table, &key, &declared, ctx)? {
            params.set(name, setting.key, v);
        }
    }
    Ok(params)
}

/// The shared groups' tables (`tables`: each group's table name and the file's table,
/// if given) into `settings`, each key checked against its declaration; keys left out
/// keep the defaults.
fn apply_groups(
    tables: &[(&str, Option<&toml::Table>)],
    settings: &mut RenderSettings,
    ctx: &Ctx,
) -> Result<(), ExperimentError> {
    for g in crate::technique::SETTING_GROUPS {
        let given = tables.iter().find(|(name, _)| *name == g.table);
        debug_assert!(
            given.is_some(),
            "RawExperiment has no field for [{}]",
            g.table
        );
        let Some(t) = given.and_then(|(_, t)| *t) else {
            continue;
        };
        let declared: Vec<&crate::technique::Setting> =
            g.settings.iter().map(|c| &c.setting).collect();
        for (setting, v) in declared_values(t, g.table, &declared, ctx)? {
            let c = g.setting(setting.key).expect("declared");
            (c.set)(settings, v);
        }
    }
    Ok(())
}

/// The values of a table of declared settings (`[cones]`, `[techniques.<name>]`):
/// every key one of `settings`, every value a number of its type in its range, else an
/// error naming the file, the line, the key and the allowed keys or range.
fn declared_values(
    t: &toml::Table,
    table: &str,
    settings: &[&'static crate::technique::Setting],
    ctx: &Ctx,
) -> Result<Vec<(&'static crate::technique::Setting, f64)>, ExperimentError> {
    let mut out = Vec::new();
    for (k, v) in t {
        let key = format!("{table}.{k}");
        let Some(&setting) = settings.iter().find(|s| s.key == k) else {
            let allowed: Vec<&str> = settings.iter().map(|s| s.key).collect();
            return Err(ExperimentError::UnknownKey {
                file: ctx.file.clone(),
                line: ctx.span_of(&key).map(|s| ctx.line_of(s.start)),
                key,
                allowed: if allowed.is_empty() {
                    "none (this table has no keys yet)".to_string()
                } else {
                    allowed.join(", ")
                },
            });
        };
        let value = match v {
            toml::Value::Integer(i) => Some(*i as f64),
            toml::Value::Float(x) => Some(*x),
            _ => None,
        };
        match value
            .ok_or_else(|| setting.range_text())
            .and_then(|x| setting.check(x))
        {
            Ok(x) => out.push((setting, x)),
            Err(req) => return Err(ctx.invalid(&key, req)),
        }
    }
    Ok(out)
}

/// `|n.n - 1|` up to which a light's normal counts as unit and is kept as written: far
/// above the few ulps `normalize` leaves, far below what a change of the written digits
/// of a normal that is not unit can reach (a normal this close to unit length is unit
/// to rounding, and `AreaLight::frame` normalizes it again anyway).
const UNIT_NORMAL_TOLERANCE: f64 = 1e-12;

/// One `[[lights]]` entry. Keys that do not belong to the light's type are errors, so a
/// `radius` on a rectangle never passes silently.
fn build_light(
    l: &RawLight,
    ctx: &Ctx,
    key: &dyn Fn(&str) -> String,
) -> Result<Light, ExperimentError> {
    let allowed: &[&str] = match l.kind {
        LightType::Point => &[],
        LightType::Rect => &["normal", "size", "rotation_deg", "emission"],
        LightType::Disk => &["normal", "radius", "rotation_deg", "emission"],
        LightType::Sphere => &["radius"],
    };
    for (name, given) in [
        ("normal", l.normal.is_some()),
        ("size", l.size.is_some()),
        ("radius", l.radius.is_some()),
        ("rotation_deg", l.rotation_deg.is_some()),
        ("emission", l.emission.is_some()),
    ] {
        if given && !allowed.contains(&name) {
            let mut keys = vec!["type", "position", "color", "intensity"];
            keys.extend_from_slice(allowed);
            return Err(ctx.invalid(
                &key(name),
                format!(
                    "is not a key of a {:?} light; allowed: {}",
                    l.kind,
                    keys.join(", ")
                ),
            ));
        }
    }
    let position = vec3_where(ctx, &key("position"), l.position, |_| true, "")?;
    let color = match l.color {
        Some(col) => vec3_where(ctx, &key("color"), col, |x| x >= 0.0, ">= 0")?,
        None => DVec3::ONE,
    };
    let intensity = declared(
        ctx,
        &key("intensity"),
        &settings::LIGHT_INTENSITY,
        l.intensity,
    )?;
    let non_negative = |k: &str, v: f64| declared(ctx, &key(k), &settings::LIGHT_RADIUS, v);
    let shape = match l.kind {
        LightType::Point => {
            return Ok(Light::Point(PointLight {
                position,
                color,
                intensity,
            }));
        }
        LightType::Rect => {
            let [w, h] = l.size.ok_or_else(|| {
                ctx.invalid(
                    &key("size"),
                    "is required for a rect light: [width, height], each >= 0",
                )
            })?;
            if settings::LIGHT_SIDE.check(w).is_err() || settings::LIGHT_SIDE.check(h).is_err() {
                return Err(ctx.invalid(
                    &key("size"),
                    format!("each side {}", settings::LIGHT_SIDE.range_text()),
                ));
            }
            AreaShape::Rect {
                width: w,
                height: h,
            }
        }
        LightType::Disk => AreaShape::Disk {
            radius: non_negative(
                "radius",
                l.radius.ok_or_else(|| {
                    ctx.invalid(
                        &key("radius"),
                        "is required for a disk light: a finite number >= 0",
                    )
                })?,
            )?,
        },
        LightType::Sphere => AreaShape::Sphere {
            radius: non_negative(
                "radius",
                l.radius.ok_or_else(|| {
                    ctx.invalid(
                        &key("radius"),
                        "is required for a sphere light: a finite number >= 0",
                    )
                })?,
            )?,
        },
    };
    // Rectangles and disks face down (-y) unless told otherwise.
    let normal = match l.normal {
        Some(n) => {
            let v = vec3_where(ctx, &key("normal"), n, |_| true, "")?;
            if v.length_squared() == 0.0 || !v.length_squared().is_finite() {
                return Err(ctx.invalid(&key("normal"), "must be a finite, non-zero vector"));
            }
            // A normal that is unit to rounding is kept as written: normalize() is not
            // idempotent in floating point (it moves ~15 % of unit vectors by an ulp), so
            // a parsed normal written back (`write::to_toml`) must parse to the same bits.
            if (v.length_squared() - 1.0).abs() <= UNIT_NORMAL_TOLERANCE {
                v
            } else {
                v.normalize()
            }
        }
        None => -DVec3::Y,
    };
    let rotation = match l.rotation_deg {
        Some(v) => settings::radians(declared(
            ctx,
            &key("rotation_deg"),
            &settings::LIGHT_ROTATION,
            v,
        )?),
        None => 0.0,
    };
    let emission = match l.emission.as_deref() {
        None => Emission::default(),
        Some(name) => Emission::from_name(name).ok_or_else(|| {
            ctx.invalid(
                &key("emission"),
                format!(
                    "must be one of {}; got {name:?}",
                    Emission::NAMES.map(|n| format!("{n:?}")).join(", ")
                ),
            )
        })?,
    };
    Ok(Light::Area(AreaLight {
        emission,
        shape,
        position,
        normal,
        rotation,
        color,
        intensity,
    }))
}

/// `[scene] vox = "path"` (optional `model`) or `mesh = "path"` (`resolution` or
/// `voxel_size`, optional `material`): the grid and the palette come from the file
/// (relative paths start at the experiment file's directory). `voxel_size` rescales a
/// `.vox` grid; `origin` moves either. With a mesh `material`, the palette is the
/// seed's (plus `[[materials]]`), as for a generator. Mesh warnings (an open mesh)
/// are printed to stderr. `None` when the scene comes from a generator.
fn load_scene_file(s: &RawScene, ctx: &Ctx) -> Result<Option<LoadedScene>, ExperimentError> {
    use crate::scene::{Resolution, VoxelizeOptions, load_vox, voxelize_mesh};
    let not_without = |present: bool, key: &str, needs: &str| {
        if present {
            Err(ctx.invalid(key, format!("only applies with scene.{needs}")))
        } else {
            Ok(())
        }
    };
    not_without(s.model.is_some() && s.vox.is_none(), "scene.model", "vox")?;
    not_without(
        s.resolution.is_some() && s.mesh.is_none(),
        "scene.resolution",
        "mesh",
    )?;
    not_without(
        s.material.is_some() && s.mesh.is_none(),
        "scene.material",
        "mesh",
    )?;
    let key = match (&s.vox, &s.mesh) {
        (None, None) => return Ok(None),
        (Some(_), Some(_)) => {
            return Err(ctx.invalid(
                "scene.mesh",
                "give either scene.vox or scene.mesh, not both",
            ));
        }
        (Some(_), None) => "scene.vox",
        (None, Some(_)) => "scene.mesh",
    };
    if !s.models.is_empty() {
        return Err(ctx.invalid(
            "scene.models",
            format!(
                "not used with {key}, which is the whole grid: give the grid with scene.size \
                 or scene.dims and place the file as a model"
            ),
        ));
    }
    for (present, k) in [
        (s.generator.is_some(), "scene.generator"),
        (s.size.is_some(), "scene.size"),
        (s.dims.is_some(), "scene.dims"),
    ] {
        if present {
            return Err(ctx.invalid(k, format!("not used with {key}: the file gives the voxels")));
        }
    }
    let dir = Path::new(&ctx.file).parent().unwrap_or(Path::new(""));
    let (grid, palette, mesh) = if let Some(p) = &s.vox {
        let model = match s.model {
            Some(m) => Some(declared(ctx, "scene.model", &settings::VOX_MODEL, m as f64)? as usize),
            None => None,
        };
        let v = load_vox(dir.join(p), model).map_err(|e| ctx.invalid(key, e))?;
        let mut grid = v.grid;
        if let Some(vs) = s.voxel_size {
            let vs = declared(ctx, "scene.voxel_size", &settings::SCENE_VOXEL_SIZE, vs)?;
            grid = grid
                .placed(vs, grid.origin())
                .map_err(|e| ctx.invalid("scene.voxel_size", e))?;
        }
        (grid, v.materials, None)
    } else {
        let p = s.mesh.as_deref().unwrap_or_default();
        let resolution = match (s.resolution, s.voxel_size) {
            (Some(_), Some(_)) => {
                return Err(ctx.invalid(
                    "scene.voxel_size",
                    "give either scene.resolution or scene.voxel_size for a mesh, not both",
                ));
            }
            (Some(n), None) => Resolution::Count(declared(
                ctx,
                "scene.resolution",
                &settings::SCENE_RESOLUTION,
                n as f64,
            )? as u32),
            (None, Some(v)) => Resolution::VoxelSize(declared(
                ctx,
                "scene.voxel_size",
                &settings::SCENE_VOXEL_SIZE,
                v,
            )?),
            (None, None) => {
                return Err(ctx.invalid(
                    "scene.mesh",
                    "needs scene.resolution (voxels along the longest axis) or scene.voxel_size",
                ));
            }
        };
        // With a material given, every voxel is material 1 for now; the index in the
        // final palette is set once `[[materials]]` are known (apply_mesh_material).
        let options = VoxelizeOptions {
            resolution,
            material: s
                .material
                .as_ref()
                .map(|_| crate::scene::seed_palette()[1].clone()),
            storage: Storage::Auto,
        };
        let v = voxelize_mesh(dir.join(p), &options).map_err(|e| ctx.invalid(key, e))?;
        for w in &v.warnings {
            eprintln!("warning: {}: {w}", ctx.file);
        }
        let palette = match s.material {
            Some(_) => crate::scene::seed_palette(),
            None => v.materials,
        };
        (v.grid, palette, Some(v.surface))
    };
    let (grid, mesh) = match s.origin {
        Some(o) => {
            let origin = vec3_where(ctx, "scene.origin", o, |_| true, "")?;
            let g = grid
                .placed(grid.voxel_size(), origin)
                .map_err(|e| ctx.invalid("scene.origin", e))?;
            // The triangles move with their voxels.
            let mesh = mesh.map(|m| m.translated(origin - grid.origin()));
            (g, mesh)
        }
        None => (grid, mesh),
    };
    Ok(Some((grid, palette, mesh)))
}

/// A `[scene]` file's grid, palette and (for a mesh) triangles.
type LoadedScene = (Grid, Vec<Material>, Option<SurfaceMesh>);

/// A mesh's `material`, resolved in the final palette, given to all its voxels.
fn apply_mesh_material(scene: &mut Scene, s: &RawScene, ctx: &Ctx) -> Result<(), ExperimentError> {
    let (Some(_), Some(r)) = (&s.mesh, &s.material) else {
        return Ok(());
    };
    let k = models::resolve_material(scene, r, "scene.material", ctx)?;
    scene.grid.map_materials(|m| if m != 0 { k } else { m });
    if let Some(mesh) = &mut scene.mesh {
        Arc::make_mut(mesh).triangle_material.fill(k);
    }
    Ok(())
}

fn build_grid(s: &RawScene, ctx: &Ctx) -> Result<Grid, ExperimentError> {
    let dims = match (s.size, s.dims) {
        (Some(_), Some(_)) => {
            return Err(ctx.invalid(
                "scene.dims",
                "give either scene.size or scene.dims, not both",
            ));
        }
        (Some(n), None) => {
            UVec3::splat(declared(ctx, "scene.size", &settings::SCENE_SIZE, n as f64)? as u32)
        }
        (None, Some(d)) => {
            if let Some(Err(req)) = d
                .iter()
                .map(|&n| settings::SCENE_SIDE.check(n as f64))
                .find(Result::is_err)
            {
                return Err(ctx.invalid("scene.dims", format!("every side {req}")));
            }
            UVec3::new(d[0] as u32, d[1] as u32, d[2] as u32)
        }
        (None, None) => UVec3::splat(SEED_SIZE),
    };
    let count = dims.as_u64vec3().element_product();
    // Beyond DENSE_MAX_VOXELS the generators build the sparse tree directly.
    let sparse = Storage::Auto.is_sparse_for(count);
    if sparse && dims.max_element() > MAX_SPARSE_SIDE {
        let key = if s.size.is_some() {
            "scene.size"
        } else {
            "scene.dims"
        };
        return Err(ctx.invalid(
            key,
            format!(
                "{}x{}x{} = {count} voxels: more than {DENSE_MAX_VOXELS} are held as a sparse \
                 tree, whose sides are at most {MAX_SPARSE_SIDE} (scene::MAX_SPARSE_SIDE)",
                dims.x, dims.y, dims.z
            ),
        ));
    }
    let voxel_size = match s.voxel_size {
        Some(v) => declared(ctx, "scene.voxel_size", &settings::SCENE_VOXEL_SIZE, v)?,
        None => settings::SCENE_VOXEL_SIZE.default,
    };
    let origin = match s.origin {
        Some(o) => vec3_where(ctx, "scene.origin", o, |_| true, "")?,
        None => DVec3::ZERO,
    };
    let grid = match s.generator.unwrap_or_default() {
        Generator::Seed => seed_grid(dims, voxel_size, origin),
        Generator::Empty if sparse => Grid::from_tree(
            crate::sparse::BrickSource::new(dims).into_tree(crate::sparse::GPU_LOG_BRANCH),
            voxel_size,
            origin,
        ),
        Generator::Empty => Grid::new(dims, voxel_size, origin),
    };
    grid.map_err(|e| ctx.invalid("scene", e))
}

/// The seed palette, then each `[[materials]]` entry in order: a name already in the
/// palette overrides that material (keys left out keep its values), a new name is
/// appended (keys left out take the defaults documented in baseline.toml).
fn build_materials(
    base: Option<Vec<Material>>,
    raw: &[RawMaterial],
    ctx: &Ctx,
) -> Result<Vec<Material>, ExperimentError> {
    // A `.vox` or mesh scene starts from the file's palette instead of the seed's.
    let mut palette = base.unwrap_or_else(crate::scene::seed_palette);
    let mut seen: Vec<&str> = Vec::new();
    for (i, m) in raw.iter().enumerate() {
        let key = |k: &str| format!("materials[{i}].{k}");
        if m.name.is_empty() {
            return Err(ctx.invalid(&key("name"), "must not be empty"));
        }
        if seen.contains(&m.name.as_str()) {
            return Err(ctx.invalid(&key("name"), "is defined twice in [[materials]]"));
        }
        seen.push(&m.name);
        let existing = palette.iter().position(|p| p.name == m.name);
        if existing == Some(0) {
            return Err(ctx.invalid(
                &key("name"),
                "material 0 (void) is empty space and cannot be changed",
            ));
        }
        let mut mat = match existing {
            Some(idx) => palette[idx].clone(),
            // Built from void's clone so fields the file cannot set yet (whatever later
            // issues add to Material) get void's neutral values.
            None => {
                let mut new = palette[0].clone();
                new.name = m.name.clone();
                new.albedo = DVec3::ONE;
                (new.kd, new.ks, new.shininess) = (0.0, 0.0, SEED_SHININESS);
                (new.kr, new.kt, new.ior, new.sigma) = (0.0, 0.0, 1.0, None);
                new
            }
        };
        if let Some(a) = m.albedo {
            mat.albedo = vec3_where(ctx, &key("albedo"), a, |x| x >= 0.0, ">= 0")?;
        }
        let given = [
            ("kd", m.kd),
            ("ks", m.ks),
            ("shininess", m.shininess),
            ("kr", m.kr),
            ("kt", m.kt),
            ("ior", m.ior),
        ];
        apply_fields(
            settings::MATERIAL,
            &format!("materials[{i}]"),
            &given,
            &mut mat,
            ctx,
        )?;
        if let Some(s) = m.sigma {
            mat.sigma = Some(vec3_where(
                ctx,
                &key("sigma"),
                s,
                |x| x >= 0.0,
                ">= 0 (absorption per world unit)",
            )?);
        }
        if let Some(e) = m.emission {
            mat.emission = vec3_where(ctx, &key("emission"), e, |x| x >= 0.0, ">= 0 (radiance)")?;
        }
        if let Some(name) = m.dielectric.as_deref() {
            mat.dielectric = Dielectric::from_name(name).ok_or_else(|| {
                ctx.invalid(
                    &key("dielectric"),
                    format!(
                        "must be one of {}; got {name:?}",
                        Dielectric::NAMES.map(|n| format!("{n:?}")).join(", ")
                    ),
                )
            })?;
        }
        match existing {
            Some(idx) => palette[idx] = mat,
            None => {
                if palette.len() >= 256 {
                    return Err(ctx.invalid(
                        &key("name"),
                        "too many materials: at most 256 including void (u8 indices)",
                    ));
                }
                palette.push(mat);
            }
        }
    }
    Ok(palette)
}

fn fill_boxes(scene: &mut Scene, boxes: &[RawBox], ctx: &Ctx) -> Result<(), ExperimentError> {
    let dims = scene.grid.dims();
    let mut sparse_boxes = Vec::new();
    for (i, b) in boxes.iter().enumerate() {
        let key = |k: &str| format!("scene.boxes[{i}].{k}");
        let n = scene.materials.len();
        let material = match &b.material {
            MaterialRef::Index(idx) => {
                int_in(ctx, &key("material"), *idx, 0..=(n as i64 - 1))? as u8
            }
            MaterialRef::Name(name) => match scene.materials.iter().position(|m| &m.name == name) {
                Some(idx) => idx as u8,
                None => {
                    let names: Vec<&str> =
                        scene.materials.iter().map(|m| m.name.as_str()).collect();
                    return Err(ctx.invalid(
                        &key("material"),
                        format!("no such material; defined: {}", names.join(", ")),
                    ));
                }
            },
        };
        for a in 0..3 {
            let dim = i64::from(dims[a]);
            if !(0 <= b.min[a] && b.min[a] <= b.max[a] && b.max[a] <= dim) {
                let bad = if (0..=dim).contains(&b.min[a]) {
                    "max"
                } else {
                    "min"
                };
                return Err(ctx.invalid(
                    &key(bad),
                    format!(
                        "the box must satisfy 0 <= min <= max <= dims = [{}, {}, {}] on every axis (min inclusive, max exclusive)",
                        dims.x, dims.y, dims.z
                    ),
                ));
            }
        }
        let corner = |c: [i64; 3]| IVec3::new(c[0] as i32, c[1] as i32, c[2] as i32);
        if scene.grid.is_sparse() {
            // Written all at once below, over the tree.
            sparse_boxes.push((corner(b.min), corner(b.max), material));
            continue;
        }
        for z in b.min[2]..b.max[2] {
            for y in b.min[1]..b.max[1] {
                for x in b.min[0]..b.max[0] {
                    scene
                        .grid
                        .set(IVec3::new(x as i32, y as i32, z as i32), material);
                }
            }
        }
    }
    if let Some(tree) = scene
        .grid
        .sparse_tree()
        .filter(|_| !sparse_boxes.is_empty())
    {
        let overlay = crate::sparse::BoxOverlay {
            base: tree.as_ref(),
            boxes: &sparse_boxes,
        };
        let tree = crate::sparse::SparseTree::build(&overlay, crate::sparse::GPU_LOG_BRANCH);
        let g = &scene.grid;
        scene.grid = Grid::from_tree(tree, g.voxel_size(), g.origin())
            .map_err(|e| ctx.invalid("scene.boxes", e))?;
    }
    Ok(())
}
