//! `voxlab ablate`: error against run time for every shadow model and its quality knob
//! (`docs/ablation.md`), measured against a converged reference.
//!
//! The reference is the reference shadow model (`crate::technique::reference_shadow_model`:
//! stochastic area lighting) at `[ablate] reference_spp`, rendered in two
//! halves with independent seeds: their mean is the reference, and half their RMSE
//! estimates its own noise (the error floor of every measurement). It is cached on disk
//! under a blake3 hash of everything that changes its pixels, so a second run only pays
//! for the sweep.
//!
//! The sweep is a list of [`SWEEPS`]: the baseline, then the curves each shadow model
//! declares (`crate::technique::ShadowModel::ablate`: a label and a knob), then
//! `[ablate] sweep`. A new shadow model brings its curves in its own file; the lists of
//! `[ablate]` its curves name are read and checked against the settings they set.
//!
//! Each point is rendered `warmup` times untimed, then `runs` times; its time is the
//! median over the runs of trace time plus setup time, as a [`Session`] times a render
//! (`Session::render_scene`). Trace time: GPU, device time from timestamp queries where
//! the adapter has them, else wall time around a synchronised submit; CPU, the reference
//! tracer's wall time. Setup time: one full build of the cone pyramids per image, on the GPU outside
//! its timed trace (`build_pyramid`, then a synchronising readback of the coarsest
//! level), so a cone point pays what a scene that changes every frame pays. (The GPU
//! tracer reuses its pyramids between renders of an unchanged scene, so its own renders
//! after the warm-up would charge almost nothing.) On the CPU, a cone point's setup is
//! what its render prepared before the trace: its pyramids, built afresh every render
//! (the walk's data a session keeps, as the GPU tracer does). Its error is
//! RMSE and PSNR on linear radiance and the FLIP mean (NVIDIA's implementation,
//! `nv-flip`) on the displayed sRGB-encoded 8-bit image (`metrics::flip`). Everything is deterministic but the times.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{Result, anyhow, bail};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Deserialize;

use crate::experiment::{Experiment, ExperimentError, write};

pub mod external;
mod grid;
pub mod plot;
pub mod tasks;
mod text;
use crate::frame::Frame;
use crate::metrics::{Domain, compare};
use crate::output::write_frame_with_provenance;
use crate::plan::Plan;
use crate::render::{Features, RenderSettings, Transmittance};
use crate::scene::{Light, PointLight, Scene};
use crate::session::{Backend, Session};
use crate::settings::Setting;
use crate::settings::ablate::{REFERENCE_SPP, RUNS, SEEDS, SPP, WARMUP};
use crate::technique::Knob;

/// Part of the reference cache key. Bump it whenever a tracer's model changes what an
/// image looks like (shading, sampling, transmittance): cached references made by the
/// old code are then rebuilt instead of silently reused. 2: the specular gate, rays
/// split where they leave the grid, the seed camera's VIEW_OFFSET (issue 13).
pub(crate) const MODEL_VERSION: u32 = 2;

/// Seeds of the reference's two halves, offset from the experiment's seed so their
/// samples are independent of the swept points' (which use the experiment's seed).
/// Nested samples would share noise with the reference and understate the error.
const REFERENCE_SEED_OFFSETS: [u32; 2] = [0x9E37_79B9, 0x3C6E_F372];

// ---------------------------------------------------------------------------------------
// Configuration: the `[ablate]` table.

/// Which tracer renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendChoice {
    /// The GPU where its kernel supports the configuration, else the CPU reference
    /// (labelled as a fallback in every output).
    Auto,
    Gpu,
    Cpu,
}

impl BackendChoice {
    pub fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Gpu => "gpu",
            Self::Cpu => "cpu",
        }
    }
}

/// The validated `[ablate]` table; every key is optional.
#[derive(Clone, Debug, PartialEq)]
pub struct AblateConfig {
    /// Samples per pixel of the reference (>= 2, split in two halves; at least the
    /// largest swept spp, ideally 16x it so its own noise is a quarter of the last
    /// point's error or less).
    pub reference_spp: u32,
    /// The stochastic sweep, ascending.
    pub spp: Vec<u32>,
    /// Independent seeds per point (`render.seed + k`, k < seeds): each seed's error
    /// and time is a row of the CSV; tables and plots give their mean with a 95 %
    /// interval (Student's t over the seeds).
    pub seeds: u32,
    /// Timed renders per point and seed; the median is that seed's time.
    pub runs: u32,
    /// Untimed renders before them (pipeline builds, uploads, caches).
    pub warmup: u32,
    /// Transmittance models rendered as fixed points with hard shadows.
    pub transmittance: Vec<Transmittance>,
    /// Reconstructions each sampling shadow model's spp curve is drawn with too (a
    /// curve `<label> + <name>` each): by default every registered one but `none`.
    pub reconstruction: Vec<&'static crate::technique::Reconstruction>,
    pub backend: BackendChoice,
    /// The reference's tracer: `cpu` (the f64 oracle) or `gpu`.
    pub reference_backend: BackendChoice,
    /// The value lists of the shadow models' curves over shared settings
    /// (`crate::technique::Knob::Shared`): list name (`cone_step_factor`) -> values,
    /// ascending; empty leaves the curve out.
    pub lists: BTreeMap<String, Vec<f64>>,
    /// `[ablate] sweep`: a curve over the values of any experiment key, each point the
    /// experiment with `--set key=value` (its settings, parsed and checked as the file).
    pub sweeps: Vec<KeySweep>,
    /// `[ablate] reference = "path.exr"` with `reference_by = "..."`: a converged image
    /// another renderer made (relative paths from the experiment file's directory).
    /// Every point is also measured against it, and the distance of voxlab's own
    /// reference to it is reported as that reference's bias.
    pub external: Option<ExternalSpec>,
    /// The `--set` overrides the run was loaded with (`key=value`, in order; [`load_with`]):
    /// not a key of the table, but written into every output's record, so that a
    /// figure made with `--set render.orbit_deg=0.5` says so beside its source file.
    pub overrides: Vec<String>,
}

/// An external reference as `[ablate]` names it.
#[derive(Clone, Debug, PartialEq)]
pub struct ExternalSpec {
    pub path: PathBuf,
    /// Which renderer made it, at what settings: the plots and tables say so.
    pub by: String,
}

/// One curve of `[ablate] sweep`: a key of the experiment file and its values.
#[derive(Clone, Debug, PartialEq)]
pub struct KeySweep {
    pub key: String,
    pub points: Vec<SweepValue>,
}

/// One value of a key sweep: as written, the render settings it gives, and the scene
/// when it changes the scene (a camera, a light, a material): such a point is measured
/// against a converged reference of its own scene.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepValue {
    pub value: String,
    pub settings: RenderSettings,
    pub scene: Option<std::sync::Arc<Scene>>,
}

/// The `[ablate]` lists the shadow models' curves declare: list name, the shared
/// setting it sets, its default values.
fn shared_lists() -> impl Iterator<Item = (&'static str, &'static str, &'static [f64])> {
    crate::technique::SHADOW_MODELS
        .iter()
        .flat_map(|m| m.ablate)
        .filter_map(|c| match c.knob {
            Knob::Shared { key, list, default } => Some((list, key, default)),
            _ => None,
        })
}

impl AblateConfig {
    /// The values of the `[ablate]` list `name` (empty when none is declared).
    pub fn list(&self, name: &str) -> &[f64] {
        self.lists.get(name).map_or(&[], Vec::as_slice)
    }
}

impl Default for AblateConfig {
    fn default() -> Self {
        Self {
            reference_spp: REFERENCE_SPP.default as u32,
            spp: (0..=8).map(|k| 1 << k).collect(),
            seeds: SEEDS.default as u32,
            runs: RUNS.default as u32,
            warmup: WARMUP.default as u32,
            // Every registered model.
            transmittance: crate::technique::TRANSMITTANCES
                .iter()
                .map(|&m| Transmittance(m))
                .collect(),
            reconstruction: crate::technique::RECONSTRUCTIONS[1..].to_vec(),
            backend: BackendChoice::Auto,
            reference_backend: BackendChoice::Cpu,
            lists: shared_lists()
                .map(|(list, _, default)| (list.to_string(), default.to_vec()))
                .collect(),
            sweeps: Vec::new(),
            external: None,
            overrides: Vec::new(),
        }
    }
}

// Not `deny_unknown_fields`: the shadow models' lists land in `lists`, whose keys are
// checked against their declarations (AblateConfig::from_str).
#[derive(Debug, Default, Deserialize)]
struct RawAblate {
    reference_spp: Option<i64>,
    spp: Option<Vec<i64>>,
    seeds: Option<i64>,
    runs: Option<i64>,
    warmup: Option<i64>,
    transmittance: Option<Vec<String>>,
    reconstruction: Option<Vec<String>>,
    backend: Option<String>,
    reference_backend: Option<String>,
    reference: Option<String>,
    reference_by: Option<String>,
    sweep: Option<toml::Table>,
    #[serde(flatten)]
    lists: BTreeMap<String, toml::Value>,
}

/// The fixed keys of `[ablate]`, in the order its messages list them.
const ABLATE_KEYS: &[&str] = &[
    "reference_spp",
    "spp",
    "seeds",
    "runs",
    "warmup",
    "transmittance",
    "reconstruction",
    "backend",
    "reference_backend",
    "reference",
    "reference_by",
    "sweep",
];

/// The rest of the file is the experiment's, read by `Experiment::load`.
#[derive(Debug, Deserialize)]
struct RawFile {
    ablate: Option<RawAblate>,
}

/// Keys of `[ablate]` as the experiment's locator names them (`ablate.<key>`).
struct Locator<'a>(crate::experiment::Ctx<'a>);

impl<'a> Locator<'a> {
    fn new(text: &'a str, path: &Path) -> Self {
        Self(crate::experiment::Ctx::new(text, path))
    }

    /// The line of `ablate.<key>` (the table's line if the key is absent).
    fn line(&self, key: &str) -> Option<usize> {
        self.0.line_of_key(&format!("ablate.{key}"))
    }

    fn invalid(&self, key: &str, requirement: impl std::fmt::Display) -> ExperimentError {
        self.0.invalid(&format!("ablate.{key}"), requirement)
    }

    /// Serde's error, and for a declared number of the wrong type (`seeds = 1.5`, `spp =
    /// [1, "2"]`) what the key takes, as the experiment's keys say it.
    fn serde_error(&self, e: &toml::de::Error) -> ExperimentError {
        self.0.serde_error(e).with_requirement(|key, message| {
            message
                .contains("invalid type")
                .then(|| crate::settings::ablate::declared_range(key))
                .flatten()
        })
    }
}

impl AblateConfig {
    /// Reads `[ablate]` from experiment text (absent: the defaults).
    ///
    /// One function because it reads the `[ablate]` keys one after another, each checked
    /// against the ones read before it (the reference's spp against the sweep's largest)
    /// and located in the file where it is read.
    pub fn from_str(text: &str, path: impl AsRef<Path>) -> Result<Self, ExperimentError> {
        let loc = Locator::new(text, path.as_ref());
        let raw: RawFile = toml::from_str(text).map_err(|e| loc.serde_error(&e))?;
        let raw = raw.ablate.unwrap_or_default();
        let mut c = Self::default();
        // Every declared range lies within u32.
        let int = |s: &Setting, v: i64| -> Result<u32, ExperimentError> {
            s.check(v as f64)
                .map(|v| v as u32)
                .map_err(|req| loc.invalid(s.key, req))
        };
        if let Some(list) = &raw.spp {
            if list.is_empty() {
                return Err(loc.invalid("spp", "must list at least one sample count"));
            }
            let mut out = Vec::new();
            for &v in list {
                let v = int(&SPP, v)
                    .map_err(|_| loc.invalid("spp", format!("every entry {}", SPP.range_text())))?;
                if out.last().is_some_and(|&last| v <= last) {
                    return Err(loc.invalid("spp", "must be strictly ascending"));
                }
                out.push(v);
            }
            c.spp = out;
        }
        if let Some(v) = raw.reference_spp {
            c.reference_spp = int(&REFERENCE_SPP, v)?;
        }
        let top = *c.spp.last().expect("spp is not empty");
        if c.reference_spp < top {
            return Err(loc.invalid(
                "reference_spp",
                format!(
                    "must be at least the largest swept spp ({top}); 16x that keeps the \
                     reference's own noise under a quarter of the last point's error"
                ),
            ));
        }
        if let Some(v) = raw.seeds {
            c.seeds = int(&SEEDS, v)?;
        }
        if let Some(v) = raw.runs {
            c.runs = int(&RUNS, v)?;
        }
        if let Some(v) = raw.warmup {
            c.warmup = int(&WARMUP, v)?;
        }
        if let Some(list) = &raw.transmittance {
            let mut out = Vec::new();
            for name in list {
                let Some(t) = crate::technique::transmittance(name) else {
                    let names = crate::technique::transmittance_names();
                    return Err(loc.invalid(
                        "transmittance",
                        format!("every entry must be one of \"{}\"", names.join("\", \"")),
                    ));
                };
                if out.contains(&t) {
                    return Err(loc.invalid("transmittance", "lists a model twice"));
                }
                out.push(t);
            }
            c.transmittance = out;
        }
        if let Some(list) = &raw.reconstruction {
            let mut out = Vec::new();
            let names = crate::technique::RECONSTRUCTIONS[1..]
                .iter()
                .map(|r| r.name)
                .collect::<Vec<_>>();
            for name in list {
                let r = crate::technique::reconstruction(name)
                    .filter(|r| *r != crate::technique::default_reconstruction())
                    .ok_or_else(|| {
                        loc.invalid(
                            "reconstruction",
                            format!(
                                "every entry must be one of \"{}\" (the curves without one \
                                 are always drawn)",
                                names.join("\", \"")
                            ),
                        )
                    })?;
                if out.contains(&r) {
                    return Err(loc.invalid("reconstruction", "lists a reconstruction twice"));
                }
                out.push(r);
            }
            c.reconstruction = out;
        }
        let backend = |key: &str, v: &str, auto: bool| match v {
            "auto" if auto => Ok(BackendChoice::Auto),
            "gpu" => Ok(BackendChoice::Gpu),
            "cpu" => Ok(BackendChoice::Cpu),
            _ => Err(loc.invalid(
                key,
                if auto {
                    "must be \"auto\", \"gpu\" or \"cpu\""
                } else {
                    "must be \"cpu\" (the f64 oracle) or \"gpu\""
                },
            )),
        };
        if let Some(v) = &raw.backend {
            c.backend = backend("backend", v, true)?;
        }
        if let Some(v) = &raw.reference_backend {
            c.reference_backend = backend("reference_backend", v, false)?;
        }
        match (&raw.reference, &raw.reference_by) {
            (None, None) => {}
            (Some(_), None) => {
                return Err(loc.invalid(
                    "reference",
                    "needs reference_by: the renderer that made it and how \
                     (\"Mitsuba 3.9.1, scalar_rgb, 4096 spp\"), which the plots name",
                ));
            }
            (None, Some(_)) => {
                return Err(loc.invalid(
                    "reference_by",
                    "names the renderer of `reference`, which is not given",
                ));
            }
            (Some(file), Some(by)) => {
                if !file.to_ascii_lowercase().ends_with(".exr") {
                    return Err(loc.invalid(
                        "reference",
                        "must be an OpenEXR file (.exr): a reference is linear radiance, and \
                         PNG and other 8-bit formats hold display-encoded colour",
                    ));
                }
                if by.trim().is_empty() || by.len() > 200 || by.contains('\n') {
                    return Err(
                        loc.invalid("reference_by", "must be one line of 1 to 200 characters")
                    );
                }
                let dir = path.as_ref().parent().unwrap_or(Path::new(""));
                c.external = Some(ExternalSpec {
                    path: dir.join(file),
                    by: by.trim().to_string(),
                });
            }
        }
        // Float lists: every entry in range, strictly ascending; empty is allowed.
        let floats = |key: &str,
                      list: &[f64],
                      ok: &dyn Fn(f64) -> bool,
                      range: &str|
         -> Result<Vec<f64>, ExperimentError> {
            let mut out: Vec<f64> = Vec::new();
            for &v in list {
                if !(v.is_finite() && ok(v)) {
                    return Err(
                        loc.invalid(key, format!("every entry must be a number in {range}"))
                    );
                }
                if out.last().is_some_and(|&last| v <= last) {
                    return Err(loc.invalid(key, "must be strictly ascending"));
                }
                out.push(v);
            }
            Ok(out)
        };
        // The shadow models' lists, each entry in the range its setting declares.
        for (name, value) in &raw.lists {
            let Some((_, key, _)) = shared_lists().find(|(list, _, _)| list == name) else {
                return Err(ExperimentError::UnknownKey {
                    file: loc.0.file.clone(),
                    line: loc.line(name),
                    key: format!("ablate.{name}"),
                    allowed: ABLATE_KEYS
                        .iter()
                        .copied()
                        .chain(shared_lists().map(|(list, _, _)| list))
                        .collect::<Vec<_>>()
                        .join(", "),
                });
            };
            let setting =
                crate::technique::shared_setting(key).expect("a curve's knob is declared");
            let ok = |x: f64| setting.check(x).is_ok();
            let range = setting
                .range_text()
                .trim_start_matches("must be a finite number in ")
                .to_string();
            let list: Vec<f64> = match value.as_array() {
                Some(a) => a
                    .iter()
                    .map(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
                    .collect::<Option<_>>()
                    .ok_or_else(|| {
                        loc.invalid(name, format!("every entry must be a number in {range}"))
                    })?,
                None => return Err(loc.invalid(name, "must be a list of numbers")),
            };
            c.lists
                .insert(name.clone(), floats(name, &list, &ok, &range)?);
        }
        if let Some(table) = &raw.sweep {
            c.sweeps = key_sweeps(table, text, path.as_ref(), &loc)?;
        }
        Ok(c)
    }
}

/// `[ablate] sweep = { "key" = [values] }`: each value written into the experiment as
/// `--set key=value` and parsed; a value the file would refuse is refused here with the
/// parser's message, and a key that changes the scene or the image size (whose error
/// against the reference would measure the change, not the quality) is refused.
fn key_sweeps(
    table: &toml::Table,
    text: &str,
    path: &Path,
    loc: &Locator,
) -> Result<Vec<KeySweep>, ExperimentError> {
    use crate::experiment::{Override, SceneCache};
    let mut cache = SceneCache::new();
    let base = Experiment::from_str_cached(text, path, &mut cache)?;
    let mut out = Vec::new();
    for (key, values) in table {
        let what = |m: String| loc.invalid("sweep", format!("\"{key}\": {m}"));
        let Some(values) = values.as_array().filter(|v| !v.is_empty()) else {
            return Err(what("must be a non-empty list of values".to_string()));
        };
        let mut points = Vec::new();
        for v in values {
            let written = match v {
                toml::Value::String(s) => s.clone(),
                other => other.to_string(),
            };
            // Two equal values would be two rows of one file name, the second image
            // over the first: refused, naming the value.
            if points.iter().any(|p: &SweepValue| p.value == written) {
                return Err(what(format!(
                    "{} is listed twice; each value of a sweep is one point (list each once)",
                    crate::input::excerpt(&written, 60)
                )));
            }
            let o: Override = format!("{key}={written}").parse().map_err(what)?;
            let e =
                Experiment::from_str_with_cache(text, path, std::slice::from_ref(&o), &mut cache)
                    .map_err(|e| what(e.to_string()))?;
            if (e.settings.width, e.settings.height) != (base.settings.width, base.settings.height)
            {
                return Err(what(format!(
                    "{written} changes the image size; the points of a sweep are images of \
                     one size (give render.width and render.height in the file)"
                )));
            }
            // A key the rendered plan never reads would draw a flat curve that looks
            // like a finding: refused before anything renders.
            crate::plan::Plan::new(&e.scene, &e.settings)
                .reads(key, &e.settings.features)
                .map_err(what)?;
            let scene = (e.scene != base.scene).then(|| std::sync::Arc::new(e.scene));
            points.push(SweepValue {
                value: written,
                settings: e.settings,
                scene,
            });
        }
        out.push(KeySweep {
            key: key.clone(),
            points,
        });
    }
    Ok(out)
}

/// Reads an experiment file and its `[ablate]` table; also returns the text (copied
/// into the outputs as it was).
pub fn load(path: impl AsRef<Path>) -> Result<(Experiment, AblateConfig, String), ExperimentError> {
    load_with(path, &[])
}

/// [`load`] with `--set` overrides written into the text first (the `[ablate]` table's
/// keys included); the text returned is the overridden one, as it was measured.
pub fn load_with(
    path: impl AsRef<Path>,
    overrides: &[crate::experiment::Override],
) -> Result<(Experiment, AblateConfig, String), ExperimentError> {
    let path = path.as_ref();
    let experiment = Experiment::load_with(path, overrides)?;
    // The [ablate] table from the text the experiment was parsed from, not a second read.
    let text = match &experiment.source_record {
        Some(r) => r.text.to_string(),
        None => crate::experiment::read_text(path)?,
    };
    let text = crate::experiment::apply_overrides(&text, overrides)?;
    let mut config = AblateConfig::from_str(&text, path)?;
    config.overrides = overrides.iter().map(|o| o.to_string()).collect();
    Ok((experiment, config, text))
}

/// [`load_with`] for experiment text without a file (Python's text and dicts): `label`
/// names it in messages and places the assets it names, as `Experiment::from_str_with`.
pub fn load_text_with(
    text: &str,
    label: impl AsRef<Path>,
    overrides: &[crate::experiment::Override],
) -> Result<(Experiment, AblateConfig, String), ExperimentError> {
    let label = label.as_ref();
    let experiment = Experiment::from_str_with(text, label, overrides)?;
    let text = crate::experiment::apply_overrides(text, overrides)?;
    let mut config = AblateConfig::from_str(&text, label)?;
    config.overrides = overrides.iter().map(|o| o.to_string()).collect();
    Ok((experiment, config, text))
}

// ---------------------------------------------------------------------------------------
// The sweep.

/// One configuration to measure.
#[derive(Clone, Debug)]
pub struct Point {
    /// The curve it belongs to in the plot, e.g. `stochastic (beer-lambert)`.
    pub model: String,
    /// The quality knob (`spp`) or, for fixed points, what tells them apart.
    pub knob: String,
    pub value: String,
    pub settings: RenderSettings,
    /// Render the scene with every area light replaced by a point light at its centre
    /// (same colour and intensity), so a point light's cone aperture can be swept.
    pub lights_as_points: bool,
    /// A scene of its own (a key sweep over the camera, a light, ...), measured against
    /// its own converged reference; `None`: the experiment's.
    pub scene: Option<std::sync::Arc<Scene>>,
}

impl Point {
    /// The point as reports name it: the curve, and `knob=value` where it has a knob.
    pub fn label(&self) -> String {
        if self.knob == "-" {
            self.model.clone()
        } else {
            format!("{} {}={}", self.model, self.knob, self.value)
        }
    }

    /// A file-name-safe name, unique within a sweep: the model, then `knob-value` unless
    /// the model's name already says them (`stochastic_beer-lambert_spp-00016`,
    /// `cone_at_light_s_aperture_beer-lambert_step_factor-0.5`).
    pub fn slug(&self) -> String {
        let mut raw = self.model.clone();
        if self.knob != "-" && !self.model.contains(&self.value) {
            match self.value.parse::<u32>() {
                // Zero-padded so a directory listing sorts like the curve.
                Ok(n) => raw += &format!(" {}-{n:05}", self.knob),
                Err(_) => raw += &format!(" {}-{}", self.knob, self.value),
            }
        }
        let mut s = String::new();
        for c in raw.chars() {
            match c {
                'a'..='z' | 'A'..='Z' | '0'..='9' | '-' | '.' => s.push(c),
                _ if !s.ends_with('_') => s.push('_'),
                _ => {}
            }
        }
        let s = s.trim_matches('_').to_string();
        // A value such as 1e-300 prints as 300 digits: long names are cut and keep a
        // hash of the whole so they stay unique and within file-name limits.
        if s.len() <= 80 {
            return s;
        }
        let hash = blake3::hash(raw.as_bytes()).to_hex();
        format!("{}-{}", &s[..64], &hash[..12])
    }
}

/// A model's points from the experiment and the `[ablate]` table.
pub struct Sweep {
    pub name: &'static str,
    pub points: fn(&Experiment, &AblateConfig) -> Vec<Point>,
}

/// Every sweep, in the order of the outputs: the baseline, then each shadow model's
/// curves (`crate::technique::ShadowModel::ablate`), then `[ablate] sweep`.
pub const SWEEPS: &[Sweep] = &[
    Sweep {
        name: "baseline",
        points: baseline_points,
    },
    Sweep {
        name: "shadow models",
        points: model_points,
    },
];

/// Every feature off: what the seed renders.
fn baseline_points(e: &Experiment, _: &AblateConfig) -> Vec<Point> {
    let settings = RenderSettings {
        features: Features::default(),
        spp: 1,
        ..e.settings.clone()
    };
    vec![Point {
        model: "baseline (all off)".into(),
        knob: "-".into(),
        value: "-".into(),
        settings,
        lights_as_points: false,
        scene: None,
    }]
}

/// The curves every shadow model declares, in registry order: the reference's features
/// with the model, at one frame unless it samples, over the curve's knob.
fn model_points(e: &Experiment, c: &AblateConfig) -> Vec<Point> {
    let mut out = Vec::new();
    for m in crate::technique::SHADOW_MODELS {
        let mut features = reference_features(e);
        features.shadow_model = m;
        let base = RenderSettings {
            features,
            spp: if m.stochastic { e.settings.spp } else { 1 },
            ..e.settings.clone()
        };
        for curve in m.ablate {
            let point = |settings: RenderSettings, knob: &str, value: String| Point {
                model: format!(
                    "{} ({})",
                    curve.label,
                    settings.features.transmittance.name()
                ),
                knob: knob.into(),
                value,
                settings,
                lights_as_points: curve.lights_as_points,
                scene: None,
            };
            match curve.knob {
                Knob::Spp => {
                    out.extend(c.spp.iter().map(|&n| {
                        let s = RenderSettings {
                            spp: n,
                            ..base.clone()
                        };
                        point(s, "spp", n.to_string())
                    }));
                    // The same curve filtered by each reconstruction, where the model
                    // samples shadow rays for it to filter.
                    let filtered = if m.stochastic && m.shadow_rays {
                        c.reconstruction.as_slice()
                    } else {
                        &[]
                    };
                    for &r in filtered {
                        out.extend(c.spp.iter().map(|&n| {
                            let mut s = RenderSettings {
                                spp: n,
                                ..base.clone()
                            };
                            s.features.reconstruction = r;
                            Point {
                                model: format!(
                                    "{} + {} ({})",
                                    curve.label,
                                    r.name,
                                    s.features.transmittance.name()
                                ),
                                ..point(s, "spp", n.to_string())
                            }
                        }));
                    }
                }
                Knob::Transmittance => out.extend(c.transmittance.iter().map(|&t| {
                    let mut s = base.clone();
                    s.features.transmittance = t;
                    point(s, "transmittance", t.name().into())
                })),
                Knob::Own(key) => {
                    let Some(setting) = m.setting(key) else {
                        continue;
                    };
                    out.extend(setting.sweep.iter().map(|&v| {
                        let mut s = base.clone();
                        s.technique_params.set(m.name, key, v);
                        point(s, key, format!("{v}"))
                    }));
                }
                Knob::Shared { key, list, .. } => {
                    let short = key.rsplit('.').next().unwrap_or(key);
                    out.extend(c.list(list).iter().map(|&v| {
                        let mut s = base.clone();
                        crate::technique::set_shared(&mut s, key, v);
                        point(s, short, format!("{v}"))
                    }));
                }
            }
        }
    }
    out
}

/// The scene with every area light replaced by a point light at its centre, of the
/// same colour and intensity (an area light emits isotropically, so the cone model's
/// shading of it at its centre is exactly this point light's).
pub fn lights_as_points(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    for l in &mut s.lights {
        if let Light::Area(a) = l {
            *l = Light::Point(PointLight {
                position: a.position,
                color: a.color,
                intensity: a.intensity,
            });
        }
    }
    s
}

/// The reference's features: the experiment's, with the reference shadow model
/// (`crate::technique::reference_shadow_model`, the one that converges) and no
/// reconstruction (a filter would bias what the points converge to; the filtered curves
/// set theirs).
fn reference_features(e: &Experiment) -> Features {
    Features {
        shadow_model: crate::technique::reference_shadow_model(),
        reconstruction: crate::technique::default_reconstruction(),
        ..e.settings.features.clone()
    }
}

/// The curves of `[ablate] sweep`: the experiment with one key set to each value.
fn key_sweep_points(_: &Experiment, c: &AblateConfig) -> Vec<Point> {
    c.sweeps
        .iter()
        .flat_map(|k| {
            k.points.iter().map(|v| Point {
                model: format!("sweep {}", k.key),
                knob: k.key.clone(),
                value: v.value.clone(),
                settings: v.settings.clone(),
                lights_as_points: false,
                scene: v.scene.clone(),
            })
        })
        .collect()
}

/// All points of all sweeps, the plug-in shadow models' and `[ablate] sweep`'s last.
pub fn points(e: &Experiment, c: &AblateConfig) -> Vec<Point> {
    SWEEPS
        .iter()
        .flat_map(|s| (s.points)(e, c))
        .chain(key_sweep_points(e, c))
        .collect()
}

// ---------------------------------------------------------------------------------------
// Rendering on either tracer.

struct Tracers {
    gpu: Option<Session>,
    cpu: Session,
    /// Why there is no GPU session.
    gpu_error: Option<String>,
}

struct Rendered {
    frame: Frame,
    time: Duration,
    /// `gpu` or `cpu`.
    backend: &'static str,
    /// Set when `auto` fell back to the CPU: the GPU's reason.
    fallback: Option<String>,
    plan: Plan,
    /// GPU points: `time` comes from timestamp queries (else wall time).
    timestamps: bool,
    /// CPU points: what the render prepared before its trace (the cone pyramids, a
    /// walk's data), outside `time` (`RenderOutput::setup_time`).
    cpu_setup: Duration,
    /// Under a camera path, FLIP of the image against the path's frame before it.
    path_flicker: Option<f64>,
}

impl Rendered {
    fn of(image: crate::session::Image, backend: &'static str, fallback: Option<String>) -> Self {
        Rendered {
            path_flicker: image
                .previous
                .as_ref()
                .map(|previous| crate::metrics::flip(previous, &image.frame).0),
            frame: image.frame,
            // Device time from timestamp queries where the adapter has them, else wall
            // time around the synchronised submit (the session's timer).
            time: image.trace_time,
            backend,
            fallback,
            plan: image.plan,
            timestamps: image.device_timed,
            cpu_setup: image.setup_time,
        }
    }
}

impl Tracers {
    /// The CPU reference alone; `why` says why there is no GPU.
    fn cpu_only(why: &str) -> Self {
        Self {
            gpu: None,
            cpu: Session::cpu(),
            gpu_error: Some(why.into()),
        }
    }

    fn new(c: &AblateConfig) -> Result<Self> {
        if c.backend == BackendChoice::Cpu && c.reference_backend == BackendChoice::Cpu {
            return Ok(Self::cpu_only("not requested ([ablate] backend = \"cpu\")"));
        }
        let cpu = Session::cpu();
        match Session::new(Backend::Gpu) {
            Ok(t) => Ok(Self {
                gpu: Some(t),
                cpu,
                gpu_error: None,
            }),
            Err(e)
                if c.backend == BackendChoice::Auto
                    && c.reference_backend != BackendChoice::Gpu =>
            {
                Ok(Self {
                    gpu: None,
                    cpu,
                    gpu_error: Some(e.to_string()),
                })
            }
            Err(e) => Err(anyhow::Error::new(e).context("[ablate] asks for the GPU backend")),
        }
    }

    fn adapter(&self) -> String {
        match (&self.gpu, &self.gpu_error) {
            (Some(g), _) => g.gpu().map(|g| g.adapter_summary()).unwrap_or_default(),
            (None, Some(e)) => format!("none ({e})"),
            (None, None) => "none".into(),
        }
    }

    /// Renders on `choice`; `Auto` tries the GPU and falls back to the CPU when the GPU
    /// is missing or refuses the configuration.
    fn render(
        &mut self,
        choice: BackendChoice,
        scene: &Scene,
        s: &RenderSettings,
    ) -> Result<Rendered> {
        let gpu_reason = match (choice, self.gpu.as_mut()) {
            (BackendChoice::Cpu, _) => None,
            (_, Some(gpu)) => match gpu.render_scene(scene, s) {
                Ok(image) => return Ok(Rendered::of(image, "gpu", None)),
                Err(e) if choice == BackendChoice::Auto => Some(e.to_string()),
                Err(e) => return Err(anyhow::Error::new(e)),
            },
            (BackendChoice::Gpu, None) => bail!(
                "no GPU tracer: {}",
                self.gpu_error.as_deref().unwrap_or("unknown")
            ),
            (BackendChoice::Auto, None) => Some(format!(
                "no GPU: {}",
                self.gpu_error.as_deref().unwrap_or("unknown")
            )),
        };
        let image = self.cpu.render_scene(scene, s)?;
        Ok(Rendered::of(image, "cpu", gpu_reason))
    }

    /// Setup time of a render that `plan` describes and its trace time leaves out: one
    /// full build of the cone pyramids on the GPU (outside the timed trace; the tracer
    /// caches them between renders of an unchanged scene, so they are built here afresh,
    /// as a changing scene would need), timed through a synchronising readback of the
    /// coarsest level. Zero without a cone feature. On the CPU, what the render itself
    /// prepared before its trace, its pyramids built afresh every render (its walk's
    /// data the session keeps between renders of one grid).
    fn setup_time(&mut self, r: &Rendered, scene: &Scene, s: &RenderSettings) -> Result<Duration> {
        if r.backend == "cpu" {
            // As on the GPU, only a render with pyramids counts a setup.
            return Ok(if r.plan.pyramid.is_some() {
                r.cpu_setup
            } else {
                Duration::ZERO
            });
        }
        let (Some(layout), Some(gpu)) =
            (r.plan.pyramid, self.gpu.as_mut().and_then(|g| g.gpu_mut()))
        else {
            return Ok(Duration::ZERO);
        };
        let start = std::time::Instant::now();
        let pyr = gpu.build_pyramid(scene, s, layout, r.plan.radiance_pyramid())?;
        gpu.read_pyramid_level(&pyr, false, layout.levels - 1)?;
        Ok(start.elapsed())
    }
}

// ---------------------------------------------------------------------------------------
// The reference and its cache.

/// The converged reference and where it came from.
#[derive(Clone, Debug)]
pub struct Reference {
    pub frame: Frame,
    /// The cache key (blake3, hex).
    pub key: String,
    /// The cached EXR.
    pub path: PathBuf,
    /// True when it was read from the cache instead of rendered.
    pub reused: bool,
    pub spp: u32,
    pub backend: String,
    /// Estimated RMSE of the reference against the converged image: half the RMSE
    /// between its two independent halves.
    pub noise_rmse: f64,
    /// FLIP of each half against the whole reference, averaged: what a converged point
    /// would measure, about (each half differs from the whole by exactly the
    /// reference's own noise, `(a - b) / 2`). The FLIP panel's floor.
    pub flip_floor: f64,
    /// Render time of both halves (when it was rendered; from the cache's record else).
    pub seconds: f64,
}

/// Settings of the reference's two halves.
fn reference_halves(e: &Experiment, c: &AblateConfig) -> [RenderSettings; 2] {
    let features = reference_features(e);
    // A shared group's knobs (the cone knobs) change the reference only where its
    // features read them (AO, indirect light); left at their defaults otherwise, so
    // sweeping them keeps the cached reference.
    let half = |k: usize, spp: u32| {
        let mut s = RenderSettings {
            features: features.clone(),
            spp,
            seed: e.settings.seed.wrapping_add(REFERENCE_SEED_OFFSETS[k]),
            // The converged image of the experiment's own camera: no path before it.
            path_frames: 1,
            orbit_deg: 0.0,
            ..e.settings.clone()
        };
        for g in crate::technique::SETTING_GROUPS {
            if !(g.used)(&features) {
                g.reset(&mut s);
            }
        }
        s
    };
    let a = c.reference_spp / 2;
    [half(0, a), half(1, c.reference_spp - a)]
}

/// The cache key: everything that changes the reference's pixels ([`content_key`]).
pub(crate) fn reference_key(scene: &Scene, halves: &[RenderSettings; 2], backend: &str) -> String {
    content_key("reference", scene, &format!("halves {halves:?}"), backend)
}

/// A blake3 key of `scene`, of `what` is made of it, of `settings` (their `Debug` text)
/// and of the renderer `backend`. The destructuring below stops compiling when `Scene`
/// gains a field, so the key cannot forget it; materials, lights and camera enter
/// through their `Debug` form, which names every field (a Rust release that prints them
/// differently only costs a rebuild).
pub(crate) fn content_key(what: &str, scene: &Scene, settings: &str, backend: &str) -> String {
    let Scene {
        grid,
        materials,
        lights,
        camera,
        ambient,
        mesh,
    } = scene;
    let mut h = blake3::Hasher::new();
    let mut text = format!(
        "voxlab ablate {what}\nmodel {MODEL_VERSION}\nbackend {backend}\n\
         grid {:?} {:?} {:?}\n",
        grid.dims(),
        grid.voxel_size(),
        grid.origin()
    );
    h.update(text.as_bytes());
    // A dense grid's voxels as they are (the key of earlier references); a sparse one's
    // by its tree's hash.
    match grid.dense() {
        Some(d) => h.update(d),
        None => h.update(grid.content_hash().as_bytes()),
    };
    // The mesh only when there is one, so a voxel scene's key is what it was.
    if let Some(m) = mesh {
        h.update(b"\nmesh");
        m.hash_into(&mut h);
    }
    text.clear();
    let _ = write!(
        text,
        "\nmaterials {materials:?}\nlights {lights:?}\ncamera {camera:?}\nambient {ambient:?}\n\
         {settings}\n"
    );
    h.update(text.as_bytes());
    h.finalize().to_hex().to_string()
}

/// What the cache records next to the EXR.
#[derive(Debug, serde::Serialize, Deserialize)]
struct ReferenceMeta {
    key: String,
    spp: u32,
    backend: String,
    noise_rmse: f64,
    /// A cache written before the floor was recorded lacks it and is rendered again.
    flip_floor: f64,
    seconds: f64,
    model_version: u32,
}

fn backend_label(tracers: &Tracers, choice: BackendChoice) -> String {
    match (choice, tracers.gpu.as_ref().and_then(|g| g.gpu())) {
        (BackendChoice::Gpu, Some(g)) => format!("gpu {}", g.adapter_summary()),
        // The CPU image does not depend on the thread count (pixels are independent).
        _ => "cpu f64".to_string(),
    }
}

// ---------------------------------------------------------------------------------------
// Measuring.

/// One measured point: a row of the CSV.
#[derive(Clone, Debug)]
pub struct Row {
    pub model: String,
    pub knob: String,
    pub value: String,
    pub spp: u32,
    pub light_samples: u32,
    /// The shadow model the plan used (`hard`, `area`, `cone` or a plug-in's name).
    pub shadow_model: &'static str,
    /// The settings that model reads, as `key=value` (its shared ones, `cones.
    /// step_factor`, and its own, `techniques.sdf.softness`), in its declared order.
    pub model_settings: Vec<(String, f64)>,
    /// What the model says of this point, if anything (`ShadowModel::describe`: the
    /// aperture an area light's cone has).
    pub model_note: Option<String>,
    pub transmittance: &'static str,
    /// The reconstruction the plan used (`none`: the image as traced).
    pub reconstruction: &'static str,
    /// `gpu` or `cpu`.
    pub backend: &'static str,
    /// Why `auto` rendered on the CPU, if it did.
    pub fallback: Option<String>,
    pub timer: &'static str,
    /// The plotted time: the median over runs of trace + setup.
    pub ms_median: f64,
    /// Trace + setup of each run.
    pub ms_runs: Vec<f64>,
    /// Median trace time alone.
    pub trace_ms_median: f64,
    /// Median setup time the trace time leaves out (the GPU's cone pyramids; else 0).
    pub setup_ms_median: f64,
    pub lights_as_points: bool,
    pub rmse: f64,
    /// `sqrt(max(0, rmse^2 - noise^2))`: the RMSE against the converged image, the
    /// reference's own noise (`Reference::noise_rmse`, independent of the point's)
    /// taken out.
    pub rmse_corrected: f64,
    pub psnr: f64,
    /// Mean LDR-FLIP on the display's sRGB values as floats (`metrics::flip`).
    pub flip_mean: f64,
    /// The same on the display images quantised to 8 bits (`metrics::flip_8bit`, what a
    /// FLIP of two PNGs measures).
    pub flip8_mean: f64,
    /// FLIP between consecutive frames. Under a camera path (`render.path_frames > 1`),
    /// of the image against the path's frame before it (on an orbit the motion is in
    /// it too: a deterministic model's flicker is the motion's alone); otherwise of this
    /// seed's image against the previous seed's, the same point with fresh samples, the
    /// change a static camera shows from one image to the next (0 for a deterministic
    /// model; `None` for the first seed). In a summary, the mean over the seeds.
    pub flicker: Option<f64>,
    /// The seed this row was rendered with (`render.seed + k`), and `k`.
    pub seed: u32,
    pub seed_index: u32,
    /// A point's summary over its seeds: the mean in the fields above and the 95 %
    /// interval of each; `None` in a row of one seed.
    pub interval: Option<Interval>,
    /// Measured against a reference of its own scene (a key sweep that changes the
    /// scene): that reference's noise RMSE. `None`: the experiment's reference.
    pub own_reference: Option<f64>,
    pub plan: String,
    /// The PNG, relative to the output directory.
    pub image: String,
    #[doc(hidden)]
    pub frame: Frame,
    /// The errors against the external reference (`[ablate] reference`), for the rows
    /// of the experiment's own scene.
    pub external: Option<external::Errors>,
    /// The adapter (or CPU) that rendered and timed this row: a sweep spread over
    /// workers may have several.
    pub adapter: String,
}

pub use crate::metrics::flip;

/// Half-widths of the 95 % intervals of a point's means over its seeds (Student's t,
/// `crate::metrics::mean_interval`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Seeds behind the means.
    pub seeds: u32,
    pub ms: f64,
    pub rmse: f64,
    pub rmse_corrected: f64,
    pub flip: f64,
    /// Of `Row::flicker`'s mean (0 with fewer than two pairs).
    pub flicker: f64,
}

/// One summary per point, in the order of the rows: the mean over its seeds of time and
/// every error, with the 95 % interval of each; the image and plan of its first seed.
pub fn summarize(rows: &[Row]) -> Vec<Row> {
    let mut out: Vec<Row> = Vec::new();
    let mut groups: Vec<Vec<&Row>> = Vec::new();
    for r in rows {
        match groups.iter_mut().find(|g| {
            let f = g[0];
            (&f.model, &f.knob, &f.value) == (&r.model, &r.knob, &r.value)
        }) {
            Some(g) => g.push(r),
            None => groups.push(vec![r]),
        }
    }
    for g in groups {
        let stat = |f: fn(&Row) -> f64| {
            let v: Vec<f64> = g.iter().map(|r| f(r)).collect();
            crate::metrics::mean_interval(&v)
        };
        let (ms, ms_ci) = stat(|r| r.ms_median);
        let (rmse, rmse_ci) = stat(|r| r.rmse);
        let (corrected, corrected_ci) = stat(|r| r.rmse_corrected);
        let (flip, flip_ci) = stat(|r| r.flip_mean);
        let flickers: Vec<f64> = g.iter().filter_map(|r| r.flicker).collect();
        let (flicker, flicker_ci) = match flickers.len() {
            0 => (None, 0.0),
            1 => (Some(flickers[0]), 0.0),
            _ => {
                let (m, h) = crate::metrics::mean_interval(&flickers);
                (Some(m), h)
            }
        };
        let first = g[0];
        let mut row = first.clone();
        row.ms_median = ms;
        row.trace_ms_median = stat(|r| r.trace_ms_median).0;
        row.setup_ms_median = stat(|r| r.setup_ms_median).0;
        row.ms_runs = g.iter().flat_map(|r| r.ms_runs.iter().copied()).collect();
        row.rmse = rmse;
        row.rmse_corrected = corrected;
        row.psnr = stat(|r| r.psnr).0;
        row.flip_mean = flip;
        row.flip8_mean = stat(|r| r.flip8_mean).0;
        row.flicker = flicker;
        row.interval = (g.len() > 1).then_some(Interval {
            seeds: g.len() as u32,
            ms: ms_ci,
            rmse: rmse_ci,
            rmse_corrected: corrected_ci,
            flip: flip_ci,
            flicker: flicker_ci,
        });
        out.push(row);
    }
    out
}

fn median_ms(times: &[Duration]) -> f64 {
    let mut v: Vec<f64> = times.iter().map(|t| t.as_secs_f64() * 1e3).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// The row of one seed of `point`: its last render and timed runs `r` against
/// `reference`.
fn point_row(
    point: &Point,
    scene: &Scene,
    s: &RenderSettings,
    r: tasks::SeedRender,
    reference: &Frame,
    noise_rmse: f64,
) -> Result<Row> {
    let d = compare(reference, &r.frame, Domain::Linear, 0.0)
        .ok_or_else(|| anyhow!("point and reference differ in size"))?;
    let (flip_mean, _) = flip(reference, &r.frame);
    let times: Vec<Duration> = r
        .times_ns
        .iter()
        .map(|&t| Duration::from_nanos(t))
        .collect();
    let setups: Vec<Duration> = r
        .setups_ns
        .iter()
        .map(|&t| Duration::from_nanos(t))
        .collect();
    if times.is_empty() || times.len() != setups.len() {
        bail!(
            "{}: {} times and {} setup times",
            point.label(),
            times.len(),
            setups.len()
        );
    }
    let totals: Vec<Duration> = times.iter().zip(&setups).map(|(t, u)| *t + *u).collect();
    let m = crate::technique::shadow_model(&r.shadow_model)
        .ok_or_else(|| anyhow!("{}: no shadow model {:?}", point.label(), r.shadow_model))?;
    let reconstruction = crate::technique::reconstruction(&r.reconstruction).ok_or_else(|| {
        anyhow!(
            "{}: no reconstruction {:?}",
            point.label(),
            r.reconstruction
        )
    })?;
    let backend = match r.backend.as_str() {
        "gpu" => "gpu",
        "cpu" => "cpu",
        other => bail!("{}: backend {other:?}", point.label()),
    };
    let model_settings = m
        .shared_settings
        .iter()
        .filter_map(|&k| Some((k.to_string(), crate::technique::get_shared(s, k)?)))
        .chain(m.settings.iter().map(|st| {
            (
                format!("techniques.{}.{}", m.name, st.key),
                s.technique_params.get(m.name, st),
            )
        }))
        .chain(reconstruction.settings.iter().map(|st| {
            (
                format!("techniques.{}.{}", reconstruction.name, st.key),
                s.technique_params.get(reconstruction.name, st),
            )
        }))
        .collect();
    Ok(Row {
        model: point.model.clone(),
        knob: point.knob.clone(),
        value: point.value.clone(),
        spp: s.spp,
        light_samples: s.light_samples,
        shadow_model: m.name,
        model_settings,
        model_note: m.describe.and_then(|f| f(scene, s)),
        transmittance: s.features.transmittance.name(),
        reconstruction: reconstruction.name,
        backend,
        fallback: r.fallback,
        timer: match (backend, r.timestamps, r.pyramid) {
            ("gpu", true, false) => "timestamp queries",
            ("gpu", true, true) => "timestamp queries + pyramid build",
            ("gpu", false, false) => "wall around a synchronised submit",
            ("gpu", false, true) => "wall around a synchronised submit + pyramid build",
            _ => "wall (cpu::render)",
        },
        ms_median: median_ms(&totals),
        ms_runs: totals.iter().map(|t| t.as_secs_f64() * 1e3).collect(),
        trace_ms_median: median_ms(&times),
        setup_ms_median: median_ms(&setups),
        lights_as_points: point.lights_as_points,
        rmse: d.rmse,
        rmse_corrected: (d.rmse * d.rmse - noise_rmse * noise_rmse).max(0.0).sqrt(),
        psnr: d.psnr,
        flip_mean,
        flip8_mean: crate::metrics::flip_8bit(reference, &r.frame),
        flicker: None,
        seed: s.seed,
        seed_index: 0,
        interval: None,
        own_reference: None,
        plan: r.plan,
        image: format!("images/{}.png", point.slug()),
        frame: r.frame,
        external: None,
        adapter: String::new(),
    })
}

// ---------------------------------------------------------------------------------------
// The run.

/// The sweep's progress: a bar in estimated microseconds of work, each render costed by
/// calibration renders of the reference and of each curve before the sweep starts,
/// and an ETA from the cost still to do at the rate measured so far (the calibration's
/// before anything is done), so a long reference render shows a sensible wait instead
/// of none. Off a terminal, `--progress` prints it as lines.
struct Meter {
    bar: ProgressBar,
    lines: bool,
    start: Instant,
    /// What a render of the reference costs, and of each curve's points (by the
    /// curve's name), in microseconds (`calibrate`).
    reference: RenderCost,
    curves: HashMap<String, RenderCost>,
    /// Told the work done (in the bar's units), and asked whether to stop.
    watch: Option<std::sync::Arc<crate::progress::Watch>>,
}

impl Meter {
    /// A meter that shows nothing and never stops the work (a worker's, whose driver
    /// follows the sweep).
    fn silent() -> Self {
        Self {
            bar: ProgressBar::hidden(),
            lines: false,
            start: Instant::now(),
            reference: RenderCost::UNCALIBRATED,
            curves: HashMap::new(),
            watch: None,
        }
    }

    /// An error when the sweep was asked to stop (between renders).
    fn check(&self) -> Result<()> {
        if self.watch.as_ref().is_some_and(|w| w.stopped()) {
            bail!("ablate stopped on request");
        }
        Ok(())
    }

    fn reference_cost(&self, spp: u32) -> u64 {
        self.reference.of(spp).ceil() as u64
    }

    /// One render of a point of curve `model` at `spp` samples.
    fn point_cost(&self, model: &str, spp: u32) -> u64 {
        let c = self.curves.get(model).copied();
        c.unwrap_or(RenderCost::UNCALIBRATED).of(spp).ceil() as u64
    }

    /// Time still to wait: the estimated work left at the rate measured so far.
    fn eta(&self) -> Duration {
        let (done, total) = (self.bar.position(), self.bar.length().unwrap_or(0));
        let left = total.saturating_sub(done) as f64;
        let rate = if done > 0 {
            self.start.elapsed().as_secs_f64() / done as f64
        } else {
            1e-6
        };
        Duration::from_secs_f64(left * rate)
    }

    fn status(&self, what: &str) -> String {
        let t = self.eta().as_secs();
        format!("{what}; about {}m {:02}s left", t / 60, t % 60)
    }

    /// Says what is being rendered now.
    fn working_on(&self, what: &str) {
        self.bar.set_message(self.status(what));
    }

    /// Records `cost` more done.
    fn advance(&self, cost: u64) {
        self.bar.inc(cost);
        if let Some(w) = &self.watch {
            w.report(self.bar.position(), self.bar.length().unwrap_or(0));
        }
        if let Some(what) = self.bar.message().split(';').next() {
            self.bar.set_message(self.status(what));
        }
    }

    /// A line of the `--progress` log off a terminal.
    fn line(&self, text: &str) {
        if self.lines {
            let (done, total) = (self.bar.position(), self.bar.length().unwrap_or(1).max(1));
            eprintln!("[{:>3}%] {}", 100 * done / total, self.status(text));
        }
    }
}

pub struct AblateOptions {
    pub out_dir: PathBuf,
    /// How messages name the option that gave `out_dir`: `"--out"` (the command line),
    /// `"out"` (Python's keyword argument).
    pub out_option: &'static str,
    /// Where references are cached; default `<out_dir>/cache`.
    pub cache_dir: Option<PathBuf>,
    /// Show a progress bar when standard error is a terminal.
    pub progress: bool,
    /// Off a terminal, print the progress as lines (`voxlab ablate --progress`).
    pub log: bool,
    /// Follows the sweep from another thread and may stop it between renders (the
    /// Python bindings' Ctrl-C): the images and references done stay, no table is written.
    pub watch: Option<std::sync::Arc<crate::progress::Watch>>,
    /// Take the points an earlier run of the same sweep left in the cache directory
    /// (`voxlab ablate --resume`): only the missing ones are rendered.
    pub resume: bool,
}

/// What a run measured and wrote.
pub struct AblateReport {
    pub reference: Reference,
    /// Every point and seed: the CSV's rows.
    pub rows: Vec<Row>,
    /// Every point's mean over its seeds with its intervals (`summarize`): the table's
    /// and the plot's rows.
    pub summaries: Vec<Row>,
    pub adapter: String,
    pub git_revision: String,
    /// Every file written, relative to the output directory.
    pub files: Vec<String>,
    /// The markdown table (also in `table.md`).
    pub table: String,
    /// The external reference (`[ablate] reference`), its bias line, and the rows of
    /// the experiment's own scene measured against it (`ablation-external.csv`).
    pub external: Option<(external::External, Vec<Row>)>,
}

/// The files a run writes directly into its output directory (the point images go under
/// `images/`, the references under the cache directory).
pub const OUTPUT_FILES: &[&str] = &[
    "grid.png",
    "grid.png.json",
    "ablation.csv",
    "ablation.csv.json",
    "plot.png",
    "plot.png.json",
    "plot.svg",
    "plot.svg.json",
    "table.md",
    "table.md.json",
    "table.tex",
    "table.tex.json",
    "experiment.toml",
    "resolved.toml",
    "run.txt",
];

/// Refuses, before anything is written, a run whose outputs would replace one of the
/// files the experiment reads (`voxlab ablate DIR/resolved.toml --out DIR`, an
/// experiment named `run.txt`, a model kept under `images/`).
fn refuse_to_overwrite_inputs(
    e: &Experiment,
    source: Option<&str>,
    opts: &AblateOptions,
    cache_dir: &Path,
) -> Result<()> {
    let out = &opts.out_dir;
    let out_given = crate::output::given(opts.out_option, out);
    let text = match (source, &e.source_path) {
        (Some(t), _) => t.to_string(),
        (None, Some(path)) => crate::experiment::read_text(path).unwrap_or_default(),
        (None, None) => return Ok(()),
    };
    let inputs = crate::experiment::write::experiment_inputs(e, &text);
    let outputs: Vec<PathBuf> = OUTPUT_FILES.iter().map(|f| out.join(f)).collect();
    if let Some((o, i)) = crate::experiment::write::overwrites(&outputs, &inputs) {
        bail!(
            "{out_given}: ablate would write {}, which is the experiment's input {}; \
             choose another output directory",
            o.display(),
            i.display()
        );
    }
    for dir in [out.join("images"), cache_dir.to_path_buf()] {
        let Ok(dir) = std::fs::canonicalize(&dir) else {
            continue;
        };
        if let Some(i) = inputs
            .iter()
            .find(|i| std::fs::canonicalize(i).is_ok_and(|c| c.starts_with(&dir)))
        {
            bail!(
                "{out_given}: the experiment's input {} lies in {}, where ablate writes; \
                 choose another output directory",
                i.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// What one render of a curve's points costs, in microseconds: a part that does not
/// depend on the samples (the filter's passes, a path's frames' fixed work, the
/// readback) and one per sample.
#[derive(Clone, Copy, Debug)]
struct RenderCost {
    fixed_us: f64,
    sample_us: f64,
}

impl RenderCost {
    /// A sample a unit: the meter's scale where nothing was calibrated (a worker's).
    const UNCALIBRATED: Self = Self {
        fixed_us: 0.0,
        sample_us: 1.0,
    };

    fn of(self, spp: u32) -> f64 {
        self.fixed_us + f64::from(spp.max(1)) * self.sample_us
    }
}

/// The [`RenderCost`] of the reference (on its backend; when it is to be rendered) and
/// of each curve of `points` (its first point), from renders at 1 and 2 samples: the
/// scale of the progress bar and the first ETA. Costing every point by the experiment's own
/// settings times its samples overestimated a filtered sweep about ninefold (the
/// filter's fixed cost counted once a sample, the costliest curve's for every curve).
fn calibrate<'p>(
    e: &Experiment,
    c: &AblateConfig,
    reference_to_render: bool,
    points: impl IntoIterator<Item = &'p Point>,
    tracers: &mut Tracers,
) -> Result<(RenderCost, HashMap<String, RenderCost>)> {
    let with_spp = |s: &RenderSettings, spp: u32| RenderSettings { spp, ..s.clone() };
    let mut timed = |backend: BackendChoice, scene: &Scene, s: &RenderSettings| -> Result<f64> {
        let t = Instant::now();
        tracers.render(backend, scene, s)?;
        Ok(t.elapsed().as_secs_f64() * 1e6)
    };
    // At 1 and 2 samples, each after an untimed render on a GPU: a render of more than
    // one sample is another kernel (it accumulates), built at its first render.
    let mut cost_of = |backend: BackendChoice, scene: &Scene, s: &RenderSettings| {
        let (one, two) = (with_spp(s, 1), with_spp(s, 2));
        if backend != BackendChoice::Cpu {
            timed(backend, scene, &one)?;
            timed(backend, scene, &two)?;
        }
        let t1 = timed(backend, scene, &one)?.max(1.0);
        let t2 = timed(backend, scene, &two)?.max(1.0);
        // A noisy machine can time the second render faster: a sample then costs at
        // least a tenth of the first render.
        let sample_us = (t2 - t1).max(0.1 * t1);
        anyhow::Ok(RenderCost {
            fixed_us: (t1 - sample_us).max(0.0),
            sample_us,
        })
    };
    let reference = if reference_to_render {
        cost_of(c.reference_backend, &e.scene, &reference_halves(e, c)[0])?
    } else {
        RenderCost::UNCALIBRATED
    };
    let mut curves = HashMap::new();
    for p in points {
        if !curves.contains_key(&p.model) {
            let cost = cost_of(c.backend, &tasks::point_scene(e, p), &p.settings)?;
            curves.insert(p.model.clone(), cost);
        }
    }
    Ok((reference, curves))
}

/// Runs the whole ablation of `e` and writes its outputs under `opts.out_dir`.
/// `source` is the experiment file's text, copied into the outputs.
pub fn run(
    e: &Experiment,
    c: &AblateConfig,
    source: Option<&str>,
    opts: &AblateOptions,
) -> Result<AblateReport> {
    // The checks that need no tracer come first: nothing is opened or rendered for a
    // sweep that cannot run.
    let external = tasks::Driver::check(e, c, source, opts)?;
    let mut worker = tasks::Worker::new(c)?;
    let adapter = worker.adapter();
    let label = worker.reference_label(c);
    let mut driver = tasks::Driver::checked(e, c, source, opts, &label, external)?;
    // One band per reference half: the whole image, as a single process renders it.
    let todo = driver.tasks(1);
    // Only what is still to do is calibrated: a cached reference, or a curve whose points
    // a resumed sweep has, costs nothing to render.
    let reference_to_render = todo
        .iter()
        .any(|t| matches!(t, tasks::Task::ReferenceTile { .. }));
    let to_render = todo.iter().filter_map(|t| match t {
        tasks::Task::Point { index } => Some(&driver.schedule.points[*index]),
        tasks::Task::ReferenceTile { .. } => None,
    });
    let (reference_cost, curves) =
        calibrate(e, c, reference_to_render, to_render, worker.tracers_mut())?;
    let cost = |t: &tasks::Task| -> f64 {
        match t {
            tasks::Task::ReferenceTile {
                reference, half, ..
            } => reference_cost.of(driver.schedule.references[*reference].halves[*half].spp),
            tasks::Task::Point { index } => {
                let p = &driver.schedule.points[*index];
                f64::from(c.warmup + c.seeds * c.runs) * curves[&p.model].of(p.settings.spp)
            }
        }
    };
    let estimate: f64 = todo.iter().map(cost).sum();
    let reference_estimate: f64 = todo
        .iter()
        .filter(|t| matches!(t, tasks::Task::ReferenceTile { .. }))
        .map(cost)
        .sum();
    let minutes = |us: f64| {
        let s = (us / 1e6).round() as u64;
        format!("{}m {:02}s", s / 60, s % 60)
    };
    let points = driver.schedule.points.len();
    // The plan, before anything long starts.
    eprintln!(
        "ablate {}: {} points x {} seeds x {} runs (+{} warm-up) at {}x{} on {}; reference {} spp \
         on {} (reused when cached){}; about {} in all ({} of it the reference), by \
         calibration renders of the reference and of each curve at 1 and 2 spp",
        e.name,
        points,
        c.seeds,
        c.runs,
        c.warmup,
        e.settings.width,
        e.settings.height,
        c.backend.name(),
        c.reference_spp,
        c.reference_backend.name(),
        if opts.resume {
            format!("; {} of the points resumed from the cache", driver.resumed)
        } else {
            String::new()
        },
        minutes(estimate),
        minutes(reference_estimate),
    );
    let bar = if opts.progress && std::io::stderr().is_terminal() {
        let pb = ProgressBar::new(1);
        pb.set_style(
            ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {percent:>3}% {msg}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        pb.enable_steady_tick(Duration::from_millis(500));
        pb
    } else {
        ProgressBar::hidden()
    };
    let lines = opts.log && bar.is_hidden();
    let progress = Meter {
        bar,
        lines,
        start: Instant::now(),
        reference: reference_cost,
        curves,
        watch: opts.watch.clone(),
    };
    progress.bar.set_length(estimate.ceil().max(1.0) as u64);
    for t in &todo {
        progress.check()?;
        if let tasks::Task::ReferenceTile {
            reference, half, ..
        } = t
        {
            let spp = driver.schedule.references[*reference].halves[*half].spp;
            progress.working_on(&format!(
                "reference, {} spp on {}",
                c.reference_spp,
                c.reference_backend.name()
            ));
            let output = worker.run_metered(e, c, &driver.schedule, t, &progress)?;
            driver.put(output)?;
            progress.line(&format!("reference half of {spp} spp rendered"));
            if let Some(r) = driver.reference(*reference) {
                progress.line(&format!(
                    "reference: {} spp on {}, rendered ({}), noise rmse {:.3e}",
                    r.spp,
                    r.backend,
                    r.path.display(),
                    r.noise_rmse
                ));
            }
            continue;
        }
        let output = worker.run_metered(e, c, &driver.schedule, t, &progress)?;
        if let tasks::TaskOutput::Point(p) = &output {
            let label = driver.schedule.points[p.index].label();
            for s in &p.seeds {
                let totals: Vec<Duration> = s
                    .times_ns
                    .iter()
                    .zip(&s.setups_ns)
                    .map(|(a, b)| Duration::from_nanos(a + b))
                    .collect();
                progress.line(&format!(
                    "{label} seed {}: {:.2} ms ({})",
                    s.seed,
                    median_ms(&totals),
                    s.backend
                ));
            }
        }
        driver.put(output)?;
    }
    progress.bar.finish_and_clear();
    driver.finish(&adapter)
}

/// The files a run with an external reference writes besides [`OUTPUT_FILES`].
pub const EXTERNAL_FILES: &[&str] = &[
    "ablation-external.csv",
    "plot-external.png",
    "plot-external.svg",
    "external.txt",
];

/// The outputs against the external reference: its CSV (the same columns), its plot
/// (titled with the renderer that made it, the bias line under it in `external.txt`).
fn write_external(
    e: &Experiment,
    r: &Reference,
    x: &external::External,
    rows: &[Row],
    out: &Path,
    files: &mut Vec<String>,
) -> Result<()> {
    write_text(&out.join("ablation-external.csv"), &csv(rows, r))?;
    let summaries = summarize(rows);
    let title = format!(
        "{}: error against time, reference by {} ({}x{})",
        e.name, x.spec.by, e.settings.width, e.settings.height
    );
    let (png, svg) = plot::plot(&summaries, &title, None)?;
    write_png(&out.join("plot-external.png"), &png)?;
    write_text(&out.join("plot-external.svg"), &svg)?;
    let text = format!(
        "external reference: {} ({}, blake3 {})\nreference bias: {}\n\n\
         ablation-external.csv and plot-external.png measure every point of the \
         experiment's own scene against it (the curves with scenes of their own keep \
         voxlab's references). Its noise is unknown: RMSE - noise is the RMSE.\n",
        x.spec.path.display(),
        x.spec.by,
        x.blake3,
        x.bias_line(r)
    );
    write_text(&out.join("external.txt"), &text)?;
    files.extend(EXTERNAL_FILES.iter().map(|f| f.to_string()));
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Outputs.

/// Writes `text` to `path` through a temporary file and a rename.
fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    Ok(crate::output::write_file(path, bytes)?)
}

fn write_text(path: &Path, text: &str) -> Result<()> {
    write_bytes(path, text.as_bytes())
}

fn write_png(path: &Path, img: &image::RgbImage) -> Result<()> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)?;
    write_bytes(path, bytes.get_ref())
}

/// Every column of `ablation.csv` and what it holds: the header, and the column
/// definitions its sidecar `ablation.csv.json` gives.
pub const CSV_SCHEMA: [(&str, &str); 32] = [
    ("model", "the curve the point belongs to"),
    (
        "knob",
        "the quality knob the curve sweeps; - for a fixed point",
    ),
    ("value", "the knob's value"),
    ("spp", "frames accumulated (samples per pixel)"),
    (
        "light_samples",
        "shadow rays per area light per hit and frame",
    ),
    (
        "shadow_model",
        "the registry name of the shadow model the plan used",
    ),
    (
        "model_settings",
        "key=value of each setting that model reads, ;-separated",
    ),
    ("transmittance", "the transmittance model"),
    (
        "reconstruction",
        "the reconstruction the plan used (none: the image as traced)",
    ),
    ("backend", "gpu or cpu"),
    ("timer", "what measured the time"),
    (
        "ms_median",
        "this seed's median over its runs of trace + setup, ms",
    ),
    ("ms_runs", "each timed run's trace + setup, ms, ;-separated"),
    ("runs", "timed runs of this seed"),
    ("trace_ms_median", "median trace time, ms"),
    (
        "setup_ms_median",
        "median setup the trace time leaves out (cone pyramid builds), ms",
    ),
    (
        "lights_as_points",
        "area lights replaced by point lights at their centres",
    ),
    ("seed", "render.seed of this row"),
    (
        "seed_index",
        "k of seed = the experiment's render.seed + k; the image is k = 0's",
    ),
    (
        "rmse",
        "root mean square error against the reference, linear radiance, over pixels and channels",
    ),
    (
        "rmse_corrected",
        "sqrt(max(0, rmse^2 - reference_noise_rmse^2)): the reference's own noise taken out",
    ),
    ("psnr", "10 log10(1 / mse), peak 1, dB"),
    (
        "flip_mean",
        "mean LDR-FLIP (Andersson et al. 2020), 67 px/degree, of the display values (clamped to [0, 1], sRGB-encoded) as floats",
    ),
    (
        "flip8_mean",
        "the same on the display values quantised to 8 bits (NVIDIA's nv-flip)",
    ),
    (
        "flicker_flip",
        "FLIP between consecutive frames: under a camera path (render.path_frames > 1) of the \
         image against the path's frame before it (motion included on an orbit); otherwise \
         of this seed's image against the previous seed's (fresh samples, same point: the \
         change a static camera shows from image to image; 0 when deterministic; empty for \
         the first seed)",
    ),
    ("reference_spp", "samples per pixel of the reference"),
    (
        "reference_noise_rmse",
        "the reference's own RMSE against the converged image: half the RMSE between its two halves",
    ),
    (
        "reference_flip_floor",
        "FLIP of each half of the reference against the whole, averaged: the FLIP floor",
    ),
    (
        "own_reference",
        "measured against a reference of its own scene (a key sweep that changes the scene)",
    ),
    (
        "image",
        "the first seed's PNG, relative to the output directory",
    ),
    (
        "fallback",
        "why backend auto rendered on the CPU, if it did",
    ),
    (
        "adapter",
        "the adapter (or CPU) that rendered and timed the row: a sweep spread over workers may have several",
    ),
];

/// The header of `ablation.csv` (`CSV_SCHEMA`'s names).
pub const CSV_COLUMNS: [&str; CSV_SCHEMA.len()] = {
    let mut out = [""; CSV_SCHEMA.len()];
    let mut i = 0;
    while i < out.len() {
        out[i] = CSV_SCHEMA[i].0;
        i += 1;
    }
    out
};

/// What `ablation.csv` is: its columns' definitions and what made it (revision,
/// adapter, experiment with its assets' hashes, size, seeds, runs, reference).
fn csv_sidecar(
    e: &Experiment,
    c: &AblateConfig,
    r: &Reference,
    adapter: &str,
    rev: &str,
) -> serde_json::Value {
    // As the files were when the sweep read them (a file edited while it ran is not
    // the one it measured).
    let recorded = e
        .source_record
        .as_ref()
        .filter(|r| r.overrides == c.overrides);
    let assets = match recorded {
        Some(r) => r.inputs.clone(),
        None => e
            .source_path
            .as_ref()
            .and_then(|p| {
                let text = crate::experiment::read_text(p).ok()?;
                Some(crate::experiment::write::input_hashes(&text, p))
            })
            .unwrap_or_default(),
    };
    serde_json::json!({
        "file": "ablation.csv",
        "voxlab": env!("CARGO_PKG_VERSION"),
        "revision": rev,
        "adapter": adapter,
        "cpu": crate::cpu::backend_summary(),
        "experiment": e.name,
        "source": e.source_path.as_ref().map(|p| p.display().to_string()),
        "assets": assets,
        "overrides": c.overrides,
        "width": e.settings.width,
        "height": e.settings.height,
        "seed": e.settings.seed,
        "seeds": c.seeds,
        "runs": c.runs,
        "warmup": c.warmup,
        "reference": {
            "spp": r.spp,
            "backend": r.backend,
            "key": r.key,
            "noise_rmse": r.noise_rmse,
            "flip_floor": r.flip_floor,
            "reused": r.reused,
        },
        // The external reference, when given: its file (hashed) and its renderer.
        "external_reference": c.external.as_ref().map(|x| serde_json::json!({
            "by": x.by,
            "file": crate::output::file_record(&x.path),
        })),
        "rows": "one per point and seed; table.md, table.tex and the plot give each point's mean over its seeds with the half-width of its 95 % interval (Student's t)",
        "columns": CSV_SCHEMA
            .iter()
            .map(|(name, meaning)| serde_json::json!({"name": name, "meaning": meaning}))
            .collect::<Vec<_>>(),
    })
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

fn csv(rows: &[Row], r: &Reference) -> String {
    let mut out = CSV_COLUMNS.join(",") + "\n";
    for row in rows {
        let runs: Vec<String> = row.ms_runs.iter().map(|t| format!("{t:.4}")).collect();
        let fields = [
            row.model.clone(),
            row.knob.clone(),
            row.value.clone(),
            row.spp.to_string(),
            row.light_samples.to_string(),
            row.shadow_model.to_string(),
            row.model_settings
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect::<Vec<_>>()
                .join(";"),
            row.transmittance.to_string(),
            row.reconstruction.to_string(),
            row.backend.to_string(),
            row.timer.to_string(),
            format!("{:.4}", row.ms_median),
            runs.join(";"),
            row.ms_runs.len().to_string(),
            format!("{:.4}", row.trace_ms_median),
            format!("{:.4}", row.setup_ms_median),
            row.lights_as_points.to_string(),
            row.seed.to_string(),
            row.seed_index.to_string(),
            format!("{:.9e}", row.rmse),
            format!("{:.9e}", row.rmse_corrected),
            format!("{:.6}", row.psnr),
            format!("{:.9e}", row.flip_mean),
            format!("{:.9e}", row.flip8_mean),
            row.flicker.map_or(String::new(), |f| format!("{f:.9e}")),
            r.spp.to_string(),
            format!("{:.9e}", row.own_reference.unwrap_or(r.noise_rmse)),
            format!("{:.9e}", r.flip_floor),
            row.own_reference.is_some().to_string(),
            row.image.clone(),
            row.fallback
                .as_deref()
                .map(|f| f.lines().next().unwrap_or(""))
                .unwrap_or("")
                .to_string(),
            row.adapter.clone(),
        ];
        let fields: Vec<String> = fields.iter().map(|f| csv_field(f)).collect();
        out += &fields.join(",");
        out += "\n";
    }
    out
}

/// `mean ± half` in the precision `digits` gives (`e` for scientific), or the mean alone
/// without an interval.
fn pm(mean: f64, half: Option<f64>, sci: bool, digits: usize) -> String {
    let f = |v: f64| {
        if sci {
            format!("{v:.digits$e}")
        } else {
            format!("{v:.digits$}")
        }
    };
    match half {
        Some(h) => format!("{} ± {}", f(mean), f(h)),
        None => f(mean),
    }
}

fn table(e: &Experiment, rows: &[Row], r: &Reference, adapter: &str, rev: &str) -> String {
    let seeds = rows
        .iter()
        .filter_map(|r| r.interval)
        .map(|i| i.seeds)
        .max();
    let mut t = format!(
        "Ablation of `{}`: {}x{}, depth {}/{}, light_samples {}; reference {} spp \
         (stochastic area lights, {}; its own noise: RMSE {:.2e}, FLIP floor {:.4}). \
         GPU: {adapter}. Revision {rev}.\n\n\
         {}\
         Time: per seed the median over runs of trace + setup, in ms. Setup is \
         one full cone pyramid build per image, timed apart from the GPU's trace (what a \
         scene that changes every frame pays; 0 without cones, and on the CPU, whose \
         trace time holds it). RMSE - noise: the RMSE with the reference's own noise \
         taken out, sqrt(RMSE^2 - noise^2). The floors: a converged point would measure \
         the reference's noise RMSE and about the FLIP floor (each half of the \
         reference against the whole); no point can be shown to be closer.\n\n\
         Pareto: the points no other point beats in both mean time and mean error (RMSE, \
         FLIP); where intervals overlap, the order is not established.\n\n\
         {}\n\n\
         | model | knob | value | backend | ms (trace + setup) | runs min..max | trace ms | setup ms | RMSE | RMSE - noise | PSNR dB | FLIP mean | flicker (FLIP) | Pareto |\n\
         |---|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n",
        e.name,
        e.settings.width,
        e.settings.height,
        e.settings.max_reflection_depth,
        e.settings.max_refraction_depth,
        e.settings.light_samples,
        r.spp,
        r.backend,
        r.noise_rmse,
        r.flip_floor,
        match seeds {
            Some(n) => format!(
                "Each point: the mean over {n} seeds, ± the half-width of its 95 % \
                 interval (Student's t over the seeds; the CSV has every seed's row).\n\n"
            ),
            None => "Each point: one seed (no interval; `[ablate] seeds` >= 2 gives \
                     95 % intervals).\n\n"
                .to_string(),
        },
        if e.settings.path_frames > 1 {
            format!(
                "Flicker: FLIP of each image against the frame before it on the camera path \
                 ({} frames, the camera turning {} degrees per frame; the time, rays and \
                 image are the last frame's, the frames before it warm-up).{}",
                e.settings.path_frames,
                e.settings.orbit_deg,
                if e.settings.orbit_deg != 0.0 {
                    " The motion is in it: a deterministic model's flicker is the motion's \
                     share alone."
                } else {
                    ""
                }
            )
        } else {
            "Flicker: FLIP of each seed's image against the previous seed's (the same point \
             with fresh samples: what a static camera shows changing from image to image; \
             0 for a deterministic model)."
                .to_string()
        },
    );
    let rmse_front = pareto_front(rows, |r| r.rmse);
    let flip_front = pareto_front(rows, |r| r.flip_mean);
    for (i, row) in rows.iter().enumerate() {
        let backend = match row.fallback {
            Some(_) => "cpu (fallback)",
            None => row.backend,
        };
        let (lo, hi) = ms_spread(row);
        let front = match (rmse_front[i], flip_front[i]) {
            (true, true) => "RMSE, FLIP",
            (true, false) => "RMSE",
            (false, true) => "FLIP",
            (false, false) => "",
        };
        let ci = row.interval;
        let _ = writeln!(
            t,
            "| {} | {} | {} | {backend} | {} | {lo:.1}..{hi:.1} | {:.2} | {:.2} | {} | {} | {:.2} | {} | {} | {front} |",
            row.model,
            row.knob,
            row.value,
            pm(row.ms_median, ci.map(|c| c.ms), false, 2),
            row.trace_ms_median,
            row.setup_ms_median,
            pm(row.rmse, ci.map(|c| c.rmse), true, 3),
            pm(row.rmse_corrected, ci.map(|c| c.rmse_corrected), true, 3),
            row.psnr,
            pm(row.flip_mean, ci.map(|c| c.flip), false, 4),
            row.flicker.map_or("-".to_string(), |f| pm(
                f,
                ci.map(|c| c.flicker).filter(|&h| h > 0.0),
                false,
                4
            )),
        );
    }
    // What each shadow model with points says of itself, then of its curves.
    for m in crate::technique::SHADOW_MODELS {
        let mine: Vec<&Row> = rows.iter().filter(|r| r.shadow_model == m.name).collect();
        let curves: Vec<String> = m
            .ablate
            .iter()
            .filter(|c| !c.about.is_empty())
            .filter(|c| {
                mine.iter()
                    .any(|r| r.model.starts_with(&format!("{} (", c.label)))
            })
            .map(|c| format!("\"{}\": {}", c.label, c.about))
            .collect();
        let note = mine.iter().find_map(|r| r.model_note.clone());
        if note.is_none() && curves.is_empty() {
            continue;
        }
        let _ = writeln!(
            t,
            "\n{}",
            note.into_iter().chain(curves).collect::<Vec<_>>().join(" ")
        );
    }
    if rows.iter().any(|r| r.own_reference.is_some()) {
        let _ = write!(
            t,
            "\nPoints of a key sweep whose value changes the scene (a camera, a light, a \
             material) are measured against a converged reference of their own scene, \
             rendered and cached like the experiment's (CSV: own_reference, and its noise in \
             reference_noise_rmse).\n"
        );
    }
    if let Some(f) = rows.iter().find_map(|r| r.fallback.as_deref()) {
        let _ = write!(
            t,
            "\n\"cpu (fallback)\": the GPU refused the configuration, so the CPU reference \
             rendered it and its time is CPU time: {}\n",
            f.lines().next().unwrap_or("")
        );
    }
    t
}

/// Which rows lie on the Pareto front of `metric` against time: no other row is at
/// least as fast and at least as accurate, and better in one. In row order.
pub fn pareto_front(rows: &[Row], metric: fn(&Row) -> f64) -> Vec<bool> {
    rows.iter()
        .map(|a| {
            let (ta, ea) = (a.ms_median, metric(a));
            ta.is_finite()
                && ea.is_finite()
                && !rows.iter().any(|b| {
                    let (tb, eb) = (b.ms_median, metric(b));
                    tb <= ta && eb <= ea && (tb < ta || eb < ea)
                })
        })
        .collect()
}

/// The spread of a row's timed runs: (min, max) of trace + setup, ms.
pub(crate) fn ms_spread(row: &Row) -> (f64, f64) {
    row.ms_runs
        .iter()
        .fold((row.ms_median, row.ms_median), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// Text for LaTeX: its special characters escaped.
fn latex_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '\\' => out += r"\textbackslash{}",
            '&' | '%' | '$' | '#' | '_' | '{' | '}' => {
                out.push('\\');
                out.push(c);
            }
            '~' => out += r"\textasciitilde{}",
            '^' => out += r"\textasciicircum{}",
            _ => out.push(c),
        }
    }
    out
}

/// The table as LaTeX (booktabs; `\usepackage{booktabs}`): one row per point, the time
/// with the spread of its runs, the points on the RMSE Pareto front in bold.
fn latex_table(e: &Experiment, rows: &[Row], r: &Reference) -> String {
    let front = pareto_front(rows, |r| r.rmse);
    let mut t = format!(
        "% voxlab ablate: {name}. Needs \\usepackage{{booktabs}}.\n\
         \\begin{{table}}\n\\centering\n\\small\n\
         \\caption{{Error against time, {name}: {w}$\\times${h}, reference {spp} spp (its own \
         noise: RMSE {noise:.2e}). {seeds}Time: median of trace + setup over the runs. \
         Bold: on the Pareto front of the mean RMSE against the mean time.}}\n\
         \\label{{tab:ablate-{label}}}\n\
         \\begin{{tabular}}{{lllrrrr}}\n\\toprule\n\
         Model & Knob & Value & Time (ms) & RMSE & PSNR (dB) & FLIP \\\\\n\\midrule\n",
        name = latex_escape(&e.name),
        w = e.settings.width,
        h = e.settings.height,
        spp = r.spp,
        noise = r.noise_rmse,
        label = e.name.replace(|c: char| !c.is_ascii_alphanumeric(), "-"),
        seeds = match rows.iter().find_map(|r| r.interval) {
            Some(i) => format!(
                "Mean over {} seeds $\\pm$ the half-width of the 95\\,\\% interval. ",
                i.seeds
            ),
            None => "One seed per point. ".to_string(),
        },
    );
    let mut previous: Option<&str> = None;
    for (row, on_front) in rows.iter().zip(front) {
        if previous.is_some_and(|m| m != row.model) {
            t += "\\addlinespace\n";
        }
        previous = Some(&row.model);
        let ci = row.interval;
        let bold = |s: String| {
            if on_front {
                format!("\\textbf{{{s}}}")
            } else {
                s
            }
        };
        let _ = writeln!(
            t,
            "{} & {} & {} & {} & {} & {:.2} & {} \\\\",
            latex_escape(&row.model),
            latex_escape(&row.knob),
            latex_escape(&row.value),
            bold(pm(row.ms_median, ci.map(|c| c.ms), false, 1).replace('±', "$\\pm$")),
            bold(pm(row.rmse, ci.map(|c| c.rmse), true, 2).replace('±', "$\\pm$")),
            row.psnr,
            pm(row.flip_mean, ci.map(|c| c.flip), false, 4).replace('±', "$\\pm$"),
        );
    }
    t += "\\bottomrule\n\\end{tabular}\n\\end{table}\n";
    t
}

/// `[x, y, z]` as TOML.
fn v3(v: glam::DVec3) -> toml::Value {
    toml::Value::Array(vec![v.x.into(), v.y.into(), v.z.into()])
}

/// What was rendered, as TOML: the scene's resolved values (the voxels by hash), the
/// settings, the `[ablate]` table with its defaults filled in, and every point.
fn resolved_toml(e: &Experiment, c: &AblateConfig, rows: &[Row], r: &Reference) -> String {
    use toml::{Table, Value};
    let mut doc = Table::new();
    doc.insert("name".into(), e.name.clone().into());
    let g = &e.scene.grid;
    let mut scene = Table::new();
    let d = g.dims();
    scene.insert(
        "dims".into(),
        Value::Array(vec![
            i64::from(d.x).into(),
            i64::from(d.y).into(),
            i64::from(d.z).into(),
        ]),
    );
    scene.insert("voxel_size".into(), g.voxel_size().into());
    scene.insert("origin".into(), v3(g.origin()));
    scene.insert(
        "voxels_blake3".into(),
        g.content_hash().to_hex().to_string().into(),
    );
    doc.insert("scene".into(), scene.into());
    // Camera, lights, materials, render settings and cone knobs as `to_toml` writes
    // them; sigma resolved (the default derived from kt filled in), and no `spp` (each
    // point has its own).
    doc.insert("camera".into(), write::camera_table(&e.scene.camera).into());
    let lights: Vec<Value> = e
        .scene
        .lights
        .iter()
        .map(|l| write::light_table(l).into())
        .collect();
    doc.insert("lights".into(), lights.into());
    let materials: Vec<Value> = e
        .scene
        .materials
        .iter()
        .skip(1)
        .map(|m| {
            let mut t = write::material_table(m);
            t.insert("sigma".into(), v3(m.absorption(g.voxel_size())));
            t.into()
        })
        .collect();
    doc.insert("materials".into(), materials.into());
    let s = &e.settings;
    let mut render = write::render_table(s, e.scene.ambient);
    render.remove("spp");
    doc.insert("render".into(), render.into());
    for g in crate::technique::SETTING_GROUPS {
        doc.insert(g.table.into(), write::group_table(g, s).into());
    }
    let mut ablate = Table::new();
    ablate.insert("reference_spp".into(), i64::from(c.reference_spp).into());
    ablate.insert(
        "spp".into(),
        c.spp
            .iter()
            .map(|&n| i64::from(n))
            .collect::<Vec<_>>()
            .into(),
    );
    ablate.insert("seeds".into(), i64::from(c.seeds).into());
    ablate.insert("runs".into(), i64::from(c.runs).into());
    ablate.insert("warmup".into(), i64::from(c.warmup).into());
    ablate.insert(
        "transmittance".into(),
        c.transmittance
            .iter()
            .map(|t| t.name())
            .collect::<Vec<_>>()
            .into(),
    );
    ablate.insert(
        "reconstruction".into(),
        c.reconstruction
            .iter()
            .map(|r| r.name)
            .collect::<Vec<_>>()
            .into(),
    );
    for (list, values) in &c.lists {
        ablate.insert(list.clone(), values.clone().into());
    }
    ablate.insert("backend".into(), c.backend.name().into());
    ablate.insert(
        "reference_backend".into(),
        c.reference_backend.name().into(),
    );
    doc.insert("ablate".into(), ablate.into());
    let mut reference = Table::new();
    reference.insert("key_blake3".into(), r.key.clone().into());
    reference.insert("backend".into(), r.backend.clone().into());
    reference.insert(
        "seeds".into(),
        REFERENCE_SEED_OFFSETS
            .iter()
            .map(|o| i64::from(s.seed.wrapping_add(*o)))
            .collect::<Vec<_>>()
            .into(),
    );
    reference.insert("noise_rmse".into(), r.noise_rmse.into());
    doc.insert("reference".into(), reference.into());
    let points: Vec<Value> = rows
        .iter()
        .map(|row| {
            let mut t = Table::new();
            t.insert("model".into(), row.model.clone().into());
            t.insert("knob".into(), row.knob.clone().into());
            t.insert("value".into(), row.value.clone().into());
            t.insert("shadow_model".into(), row.shadow_model.into());
            let settings: Table = row
                .model_settings
                .iter()
                .map(|(k, v)| (k.clone(), Value::Float(*v)))
                .collect();
            t.insert("model_settings".into(), settings.into());
            t.insert("transmittance".into(), row.transmittance.into());
            t.insert("reconstruction".into(), row.reconstruction.into());
            t.insert("spp".into(), i64::from(row.spp).into());
            t.insert("lights_as_points".into(), row.lights_as_points.into());
            t.insert("seed".into(), i64::from(s.seed).into());
            t.insert("backend".into(), row.backend.into());
            t.insert("image".into(), row.image.clone().into());
            t.into()
        })
        .collect();
    doc.insert("points".into(), points.into());
    format!(
        "# What `voxlab ablate` rendered for `{}`, resolved: defaults filled in, the\n\
         # voxels by hash. The file as written is experiment.toml beside this one.\n\n{}",
        e.name,
        toml::to_string(&doc).unwrap_or_else(|err| format!("# cannot write: {err}\n"))
    )
}

/// One function because it is the run's list of outputs (images, maps, CSV, figures,
/// tables, the resolved experiment), each one call to a writer that stands alone, all
/// sharing the run's record built at the top.
#[allow(clippy::too_many_arguments)]
fn write_outputs(
    e: &Experiment,
    c: &AblateConfig,
    source: Option<&str>,
    r: &Reference,
    seed_rows: &[Row],
    rows: &[Row],
    adapter: &str,
    rev: &str,
    out: &Path,
    files: &mut Vec<String>,
) -> Result<()> {
    let mut record = |name: &str| files.push(name.to_string());
    // What made every output, beside it (`<file>.json`) and in each PNG image: the
    // run's record (the CSV's sidecar without the columns), and for a point's image
    // the point and its first seed.
    let mut run_record = csv_sidecar(e, c, r, adapter, rev);
    if let Some(map) = run_record.as_object_mut() {
        map.remove("columns");
        map.remove("file");
        map.insert("made_by".into(), "voxlab ablate".into());
    }
    let linear = crate::frame::DisplayTransform {
        encoding: crate::frame::DisplayEncoding::Linear,
        exposure: 0.0,
    };
    let mut image = |frame: &Frame, name: &str, what: serde_json::Value| -> Result<()> {
        let mut rec = run_record.clone();
        if let Some(map) = rec.as_object_mut() {
            map.insert("image".into(), what);
        }
        write_frame_with_provenance(
            frame,
            out.join(name),
            &serde_json::to_string_pretty(&rec)?,
            linear,
        )?;
        record(name);
        record(&format!("{name}.json"));
        Ok(())
    };
    for name in ["images/reference.png", "images/reference.exr"] {
        image(&r.frame, name, serde_json::json!("the converged reference"))?;
    }
    // Every seed's row in the CSV; a point's summary over its seeds everywhere else.
    for row in rows {
        let png = row.image.clone();
        let exr = png.replace(".png", ".exr");
        let what = serde_json::json!({
            "model": row.model,
            "knob": row.knob,
            "value": row.value,
            "shadow_model": row.shadow_model,
            "model_settings": row.model_settings.iter().map(|(k, v)| format!("{k}={v}")).collect::<Vec<_>>(),
            "spp": row.spp,
            "seed": row.seed,
            "backend": row.backend,
            "plan": row.plan,
        });
        image(&row.frame, &png, what.clone())?;
        image(&row.frame, &exr, what)?;
    }
    for row in rows {
        let flip_png = row.image.replace("images/", "flip/");
        let (_, map) = flip(&r.frame, &row.frame);
        write_png(&out.join(&flip_png), &map)?;
        record(&flip_png);
        // The map's record: the run's, and which two images it compares.
        let mut rec = run_record.clone();
        if let Some(map) = rec.as_object_mut() {
            map.insert(
                "image".into(),
                serde_json::json!({
                    "flip_map_of": row.image,
                    "against": "images/reference.png",
                    "model": row.model,
                    "value": row.value,
                    "seed": row.seed,
                }),
            );
        }
        let json = format!("{flip_png}.json");
        write_text(&out.join(&json), &serde_json::to_string_pretty(&rec)?)?;
        record(&json);
    }
    write_png(&out.join("grid.png"), &grid::grid_image(r, rows))?;
    record("grid.png");
    write_text(&out.join("ablation.csv"), &csv(seed_rows, r))?;
    record("ablation.csv");
    let sidecar = csv_sidecar(e, c, r, adapter, rev);
    write_text(
        &out.join("ablation.csv.json"),
        &serde_json::to_string_pretty(&sidecar)?,
    )?;
    record("ablation.csv.json");
    let title = format!(
        "{}: error against time ({}x{}, reference {} spp)",
        e.name, e.settings.width, e.settings.height, r.spp
    );
    let (png, svg) = plot::plot(rows, &title, Some((r.noise_rmse, r.flip_floor)))?;
    write_png(&out.join("plot.png"), &png)?;
    write_text(&out.join("plot.svg"), &svg)?;
    record("plot.png");
    record("plot.svg");
    write_text(&out.join("table.md"), &table(e, rows, r, adapter, rev))?;
    record("table.md");
    write_text(&out.join("table.tex"), &latex_table(e, rows, r))?;
    record("table.tex");
    if let Some(text) = source {
        write_text(&out.join("experiment.toml"), text)?;
        record("experiment.toml");
    }
    write_text(&out.join("resolved.toml"), &resolved_toml(e, c, rows, r))?;
    record("resolved.toml");
    let mut run = format!(
        "git revision: {rev}\noverrides: {}\nadapter: {adapter}\ncpu: {}\n\
         model version: {MODEL_VERSION}\n\
         reference: {} spp, {}, {} ({}), noise rmse {:.3e}, {:.2} s to render\n\
         timer: GPU points: the trace's compute passes timed by timestamp queries where \
         the adapter has them, else wall time around a synchronised submit (see each \
         row's timer column), plus for cone points the pyramid build \
         (GpuTracer::build_pyramid, a full build per image, and a synchronising readback \
         of its coarsest level), outside the render's timed trace; CPU points: wall time of \
         cpu::render (pyramids included). Median of {} runs after {} warm-up renders.\n\n\
         plans:\n",
        if c.overrides.is_empty() {
            "none".to_string()
        } else {
            c.overrides.join(" ")
        },
        crate::cpu::backend_summary(),
        r.spp,
        r.backend,
        if r.reused { "reused" } else { "rendered" },
        r.path.display(),
        r.noise_rmse,
        r.seconds,
        c.runs,
        c.warmup,
    );
    for row in rows {
        let _ = writeln!(
            run,
            "- {} {}={} on {}{}\n  {}",
            row.model,
            row.knob,
            row.value,
            row.backend,
            row.fallback
                .as_deref()
                .map(|f| format!(" (fallback: {})", f.lines().next().unwrap_or("")))
                .unwrap_or_default(),
            row.plan.replace('\n', "\n  ")
        );
    }
    write_text(&out.join("run.txt"), &run)?;
    record("run.txt");
    // The figures and tables, once written: the run's record beside each.
    for name in ["grid.png", "plot.png", "plot.svg", "table.md", "table.tex"] {
        let json = format!("{name}.json");
        write_text(
            &out.join(&json),
            &serde_json::to_string_pretty(&run_record)?,
        )?;
        record(&json);
    }
    Ok(())
}
