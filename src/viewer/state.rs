//! What the viewer shows, apart from its widgets: the scene both sides share, each
//! side's settings, the orbit camera, and the adaptive resolution. Nothing here needs a
//! window or a GPU, so the logic is tested on its own (`tests/viewer_state.rs`).
//!
//! Exactness: the viewer never renders an `Experiment` it built by hand. After every
//! edit it writes the experiment as TOML (`experiment::write::to_toml`) and parses that
//! text back (`Experiment::from_str_cached`); the parsed experiment is what the workers
//! render. So the file the viewer exports is, by construction, the one that
//! `voxlab render` reproduces.

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Result, anyhow};

use crate::experiment::write::{relocate_scene_source, to_toml};
use crate::experiment::{Experiment, SceneCache};
use crate::render::{Features, RenderSettings};
use crate::scene::{Light, OrbitCamera};

/// The two halves of the split view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Side {
    Left,
    Right,
}

impl Side {
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];

    pub fn index(self) -> usize {
        match self {
            Side::Left => 0,
            Side::Right => 1,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }
}

/// How a side computes light visibility: a shadow model by its `[features]
/// shadow_model` name, built-in or plug-in (`crate::technique`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShadowModel(pub &'static str);

impl ShadowModel {
    /// Every shadow model, in registry order.
    pub fn all() -> Vec<ShadowModel> {
        crate::technique::shadow_model_names()
            .into_iter()
            .map(ShadowModel)
            .collect()
    }

    /// Its label in the viewer (the model's `title`).
    pub fn name(self) -> &'static str {
        crate::technique::shadow_model(self.0).map_or(self.0, |m| m.title)
    }

    pub fn of(f: &Features) -> Self {
        ShadowModel(f.shadow_model.name)
    }

    pub fn apply(self, f: &mut Features) {
        let known = f.set_shadow_model(self.0);
        debug_assert!(known, "{} is a registered shadow model", self.0);
    }
}

/// What each side chooses for itself; everything else is shared.
#[derive(Clone, Debug, PartialEq)]
pub struct SideSettings {
    pub features: Features,
    /// The side's values of the shared setting groups (`[cones]`,
    /// `crate::technique::SETTING_GROUPS`): only those fields are read.
    pub groups: RenderSettings,
    /// Settings of plug-in techniques (`[techniques.<name>]`).
    pub technique_params: crate::technique::TechniqueParams,
    /// Light samples per pixel, light and frame (`render.light_samples`).
    pub light_samples: u32,
    /// Accumulation stops after this many frames (the `render.spp` cap).
    pub max_spp: u32,
}

impl SideSettings {
    pub fn from_settings(s: &RenderSettings, max_spp: u32) -> Self {
        Self {
            features: s.features.clone(),
            groups: s.clone(),
            technique_params: s.technique_params.clone(),
            light_samples: s.light_samples,
            max_spp,
        }
    }

    /// Parses a comma-separated feature list (`--left`, `--right`): a shadow model's
    /// name (`hard`, `area`, `cone` or a plug-in's), a transmittance model's
    /// (`min-kt`, `beer-lambert`), a reconstruction's (`none`, `atrous`), a lighting
    /// term's (`ambient_occlusion` or `ao`, `indirect`), `samples=N`.
    pub fn parse_list(&mut self, list: &str) -> Result<()> {
        use crate::technique::{LIGHTING_TERMS, transmittance};
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            if self.features.set_shadow_model(item) {
                continue;
            }
            if let Some(t) = transmittance(item) {
                self.features.transmittance = t;
                continue;
            }
            if let Some(r) = crate::technique::reconstruction(item) {
                self.features.reconstruction = r;
                continue;
            }
            if self.features.set_term(item, true) {
                continue;
            }
            let Some(n) = item.strip_prefix("samples=") else {
                let terms: Vec<String> = LIGHTING_TERMS
                    .iter()
                    .map(|t| match t.short {
                        s if s == t.name => s.to_string(),
                        s => format!("{s}, {}", t.name),
                    })
                    .collect();
                return Err(anyhow!(
                    "feature list item `{item}`: allowed are {}, {}, {}, {}, samples=N",
                    crate::technique::shadow_model_names().join(", "),
                    crate::technique::transmittance_names().join(", "),
                    crate::technique::reconstruction_names().join(", "),
                    terms.join(", ")
                ));
            };
            self.light_samples = n
                .parse::<u32>()
                .ok()
                .filter(|n| (1..=crate::render::MAX_SAMPLES).contains(n))
                .ok_or_else(|| {
                    anyhow!(
                        "feature list item `{item}`: samples must be an integer in 1..={}",
                        crate::render::MAX_SAMPLES
                    )
                })?;
        }
        Ok(())
    }
}

/// Largest accumulation cap the viewer offers: what `render.spp` takes, so a file's spp
/// is the cap it asks for, never cut to a smaller one.
pub const MAX_VIEW_SPP: u32 = crate::render::MAX_SAMPLES;

/// Default accumulation cap per side, when the experiment's spp is 1 (its default).
pub const DEFAULT_VIEW_SPP: u32 = 256;

/// Pitch stays short of the poles, where the orbit's "right" axis turns over.
pub(crate) const MAX_PITCH_DEG: f64 = 89.0;

/// `to`, moved from `from` by the user, kept within `lo..=hi` only where the move heads
/// past them: a limit stops a drag or a zoom, and never moves a value the experiment
/// file gave beyond it (the viewer once jumped a file's camera distance of 1e6 grid
/// widths to 1e3 at the first notch of the wheel).
pub(crate) fn towards_limits(from: f64, to: f64, lo: f64, hi: f64) -> f64 {
    if to > from {
        to.min(hi.max(from))
    } else {
        to.max(lo.min(from))
    }
}

/// Orbit speed: degrees per pixel dragged.
pub(crate) const DEGREES_PER_PIXEL: f64 = 0.4;

/// The viewer's model: the shared experiment and the two sides.
pub struct ViewerState {
    /// Where the experiment came from (`None`: the built-in seed scene); names errors
    /// and exports.
    pub source_path: Option<PathBuf>,
    /// The experiment as edited: scene (grid, materials, lights, camera, ambient) and
    /// the shared render settings (size, depth limits, falloff, offsets, seed). Its
    /// per-side settings are ignored; `sides` has them.
    pub base: Experiment,
    /// The `[scene]` table (where the voxels come from), with absolute paths.
    pub scene_source: toml::Table,
    pub sides: [SideSettings; 2],
    /// The camera to go back to (the experiment's).
    pub home_camera: OrbitCamera,
    /// Position of the divider, as a fraction of the image width.
    pub divider: f32,
    /// Counts the changes of each side's experiment; a render result of an older
    /// generation is stale.
    pub generation: [u64; 2],
    /// What each side renders: `base` with the side's settings, spp = its cap, written
    /// and parsed back.
    rendered: [Arc<Experiment>; 2],
    cache: SceneCache,
}

/// What the right side shows when `--right` does not say: the words `voxlab view
/// --help` and docs/viewer.md use, read from here (`ViewerState::new` does it).
pub const DEFAULT_RIGHT_SIDE: &str = "the first shadow model after the default whose plan \
keeps it for the scene (sampled area lights where the scene has an area light of non-zero \
size, else cone shadows), with Beer-Lambert transmittance where that model casts shadow \
rays; the default, hard shadows, when the file already asks for exactly that";

impl ViewerState {
    /// Starts from an experiment and the text it was read from (`None`: the seed).
    pub fn new(base: Experiment, text: Option<&str>, source_path: Option<PathBuf>) -> Result<Self> {
        let scene_source = match (text, &source_path) {
            (Some(t), Some(p)) => crate::experiment::write::scene_source(t, p)?,
            _ => toml::Table::new(),
        };
        // The file's spp caps the accumulation where it asks for more than one frame;
        // 1 is also the default, so it leaves the viewer's own cap.
        let cap = match base.settings.spp {
            0 | 1 => DEFAULT_VIEW_SPP,
            n => n,
        };
        let left = SideSettings::from_settings(&base.settings, cap);
        let mut right = left.clone();
        // A useful first comparison: what the file asks for against the first shadow
        // model after the default whose plan rule keeps it for this scene (sampled area
        // lights where the scene has some of non-zero size, else cones, which soften
        // point lights too), with the first transmittance model after the default that
        // its plan keeps; or against the default when the file already asks for that.
        let mut other = right.features.clone();
        let (scene, settings) = (&base.scene, &base.settings);
        let default = crate::technique::default_shadow_model();
        if let Some(&m) = crate::technique::SHADOW_MODELS[1..]
            .iter()
            .find(|m| (m.plan)(scene, settings).is_ok())
        {
            other.shadow_model = m;
            let transmittance = crate::technique::TRANSMITTANCES[1..]
                .iter()
                .find(|t| (t.plan)(scene, settings).is_ok());
            if let Some(&t) = transmittance.filter(|_| m.shadow_rays) {
                other.transmittance = crate::render::Transmittance(t);
            }
        }
        if other == right.features {
            other.shadow_model = default;
        }
        right.features = other;
        let home_camera = base.scene.camera.clone();
        let placeholder = Arc::new(base.clone());
        let mut s = Self {
            source_path,
            base,
            scene_source,
            sides: [left, right],
            home_camera,
            divider: 0.5,
            generation: [0, 0],
            rendered: [placeholder.clone(), placeholder],
            cache: SceneCache::default(),
        };
        s.commit(&Side::BOTH)?;
        Ok(s)
    }

    /// The experiment `side` renders: accumulation capped at its `max_spp`.
    pub fn rendered(&self, side: Side) -> &Arc<Experiment> {
        &self.rendered[side.index()]
    }

    /// The experiment of `side` with its settings, `spp` frames and the given image
    /// size, not yet canonical.
    fn side_experiment(&self, side: Side, spp: u32, width: u32, height: u32) -> Experiment {
        let s = &self.sides[side.index()];
        let mut e = self.base.clone();
        e.settings.features = s.features.clone();
        for g in crate::technique::SETTING_GROUPS {
            for c in g.settings {
                (c.set)(&mut e.settings, (c.get)(&s.groups));
            }
        }
        e.settings.technique_params = s.technique_params.clone();
        e.settings.light_samples = s.light_samples;
        e.settings.spp = spp.max(1);
        e.settings.width = width;
        e.settings.height = height;
        e
    }

    fn path_for_messages(&self) -> PathBuf {
        self.source_path
            .clone()
            .unwrap_or_else(|| PathBuf::from("<viewer>"))
    }

    /// Writes `e` as TOML and parses it back: the experiment the text describes.
    fn canonical(&mut self, e: &Experiment) -> Result<(String, Experiment)> {
        let text = to_toml(e, &self.scene_source)?;
        let path = self.path_for_messages();
        let parsed = Experiment::from_str_cached(&text, &path, &mut self.cache)
            .map_err(|err| anyhow!("{err}"))?;
        Ok((text, parsed))
    }

    /// Makes the edits to `base` and `sides` take effect on `sides`: their experiments
    /// are rebuilt through the TOML round trip and their generations advance. On an
    /// error (a value the file format rejects) the rendered experiments and the
    /// generations stay as they were and the message says which key; the edit itself
    /// stays in `base`/`sides` for the caller to undo (the window does).
    pub fn commit(&mut self, sides: &[Side]) -> Result<()> {
        let mut fresh = Vec::new();
        for &side in sides {
            let cap = self.sides[side.index()].max_spp;
            let (w, h) = (self.base.settings.width, self.base.settings.height);
            let e = self.side_experiment(side, cap, w, h);
            let (_, parsed) = self.canonical(&e)?;
            fresh.push((side, parsed));
        }
        for (side, parsed) in fresh {
            // The shared part of the parsed experiment is the canonical form of `base`:
            // keep it, so the next edit starts from values the file format writes.
            self.base.scene = parsed.scene.clone();
            self.rendered[side.index()] = Arc::new(parsed);
            self.generation[side.index()] += 1;
        }
        Ok(())
    }

    /// A change of the shared scene or settings restarts both sides.
    pub fn commit_shared(&mut self) -> Result<()> {
        self.commit(&Side::BOTH)
    }

    /// The experiment file that reproduces `side`'s image: its settings, `spp` frames
    /// accumulated, at `width` x `height` (the resolution the image was traced at),
    /// with scene paths relative to `dest_dir` where possible. Returns the text and
    /// the experiment it parses to.
    pub fn export(
        &mut self,
        side: Side,
        spp: u32,
        width: u32,
        height: u32,
        dest_dir: Option<&std::path::Path>,
    ) -> Result<(String, Experiment)> {
        let e = self.side_experiment(side, spp, width, height);
        let source = match dest_dir {
            Some(d) => relocate_scene_source(&self.scene_source, d),
            None => self.scene_source.clone(),
        };
        let text = to_toml(&e, &source)?;
        // Relative scene paths resolve from the file's directory: the export's.
        let path = match dest_dir {
            Some(d) => d.join(format!("{}.toml", e.name)),
            None => self.path_for_messages(),
        };
        let parsed = Experiment::from_str_cached(&text, &path, &mut self.cache)
            .map_err(|err| anyhow!("{err}"))?;
        Ok((text, parsed))
    }

    /// Turns the camera by a drag of `dx`, `dy` pixels (right and down positive).
    pub fn orbit_pixels(&mut self, dx: f32, dy: f32) -> Result<()> {
        self.orbit_degrees(
            -(dx as f64) * DEGREES_PER_PIXEL,
            dy as f64 * DEGREES_PER_PIXEL,
        )
    }

    /// Turns the camera by `yaw` and `pitch` degrees (a turn towards a pole stops short of
    /// it; a file's pitch past that limit, which the file may give, is kept until the
    /// pitch is turned back).
    pub fn orbit_degrees(&mut self, yaw: f64, pitch: f64) -> Result<()> {
        let cam = &mut self.base.scene.camera;
        let yaw_deg = (cam.yaw.to_degrees() + yaw).rem_euclid(360.0);
        let pitch_deg = towards_limits(
            cam.pitch.to_degrees(),
            cam.pitch.to_degrees() + pitch,
            -MAX_PITCH_DEG,
            MAX_PITCH_DEG,
        );
        // Rounded to a millionth of a degree so the file shows short numbers.
        cam.yaw = crate::settings::radians(round6(yaw_deg));
        cam.pitch = crate::settings::radians(round6(pitch_deg));
        self.commit_shared()
    }

    /// Zooms by `steps` notches (positive: closer); each notch is 10 % of the distance.
    /// A zoom stops at 1e-3 and 1e3 grid widths; a file's distance beyond them is
    /// zoomed from where it is, not moved to the limit.
    pub fn zoom(&mut self, steps: f32) -> Result<()> {
        let cam = &mut self.base.scene.camera;
        let d = cam.distance * 0.9f64.powf(steps as f64);
        let w = self.base.scene.grid.width();
        cam.distance = towards_limits(cam.distance, d, 1e-3 * w, 1e3 * w);
        self.commit_shared()
    }

    /// Back to the experiment's camera.
    pub fn reset_camera(&mut self) -> Result<()> {
        self.base.scene.camera = self.home_camera.clone();
        self.commit_shared()
    }
}

fn round6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// Image scales the adaptive resolution chooses from (fractions of each side).
pub const SCALES: [f32; 7] = [1.0, 0.75, 0.5, 0.375, 0.25, 0.1875, 0.125];

/// Chooses the resolution scale that keeps one frame of both sides within a time
/// budget while the view changes, so dragging stays responsive on a software adapter;
/// once the view has been still for `settle_s`, the full resolution accumulates.
#[derive(Clone, Debug)]
pub struct AdaptiveScale {
    pub enabled: bool,
    /// Target time of one frame (of the slower side) while interacting, ms.
    pub budget_ms: f64,
    /// Seconds of stillness before going back to full resolution.
    pub settle_s: f64,
    /// Measured cost, ns per pixel per frame (exponential average over sides).
    cost_ns_per_pixel: Option<f64>,
}

impl Default for AdaptiveScale {
    fn default() -> Self {
        Self {
            enabled: true,
            budget_ms: 50.0,
            settle_s: 0.3,
            cost_ns_per_pixel: None,
        }
    }
}

impl AdaptiveScale {
    /// Records a frame of `pixels` pixels that took `ms`.
    pub fn observe(&mut self, pixels: u64, ms: f64) {
        if pixels == 0 || !(ms.is_finite() && ms > 0.0) {
            return;
        }
        let c = ms * 1e6 / pixels as f64;
        self.cost_ns_per_pixel = Some(match self.cost_ns_per_pixel {
            None => c,
            Some(old) => 0.7 * old + 0.3 * c,
        });
    }

    pub fn cost_ns_per_pixel(&self) -> Option<f64> {
        self.cost_ns_per_pixel
    }

    /// The scale for an image of `pixels` at full size: 1 when still (or disabled),
    /// else the largest of `SCALES` whose predicted frame time fits the budget
    /// (the smallest when none does; a quarter before anything was measured).
    pub fn scale(&self, pixels: u64, interacting: bool) -> f32 {
        if !self.enabled || !interacting {
            return 1.0;
        }
        let Some(c) = self.cost_ns_per_pixel else {
            return 0.25;
        };
        SCALES
            .iter()
            .copied()
            .find(|&s| c * pixels as f64 * (s as f64).powi(2) * 1e-6 <= self.budget_ms)
            .unwrap_or(SCALES[SCALES.len() - 1])
    }
}

/// The traced size of a `width` x `height` image at `scale` (each side at least 1).
pub fn scaled_size(width: u32, height: u32, scale: f32) -> (u32, u32) {
    let s = |n: u32| ((n as f64 * scale as f64).round() as u32).clamp(1, n.max(1));
    (s(width), s(height))
}

/// The light types an experiment file knows, for the light panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightKind {
    Point,
    Rect,
    Disk,
    Sphere,
}

impl LightKind {
    pub(crate) const ALL: [LightKind; 4] = [
        LightKind::Point,
        LightKind::Rect,
        LightKind::Disk,
        LightKind::Sphere,
    ];

    pub fn name(self) -> &'static str {
        match self {
            LightKind::Point => "point",
            LightKind::Rect => "rect",
            LightKind::Disk => "disk",
            LightKind::Sphere => "sphere",
        }
    }

    pub fn of(light: &Light) -> Self {
        match light {
            Light::Point(_) => LightKind::Point,
            Light::Area(a) => match a.shape {
                crate::scene::AreaShape::Rect { .. } => LightKind::Rect,
                crate::scene::AreaShape::Disk { .. } => LightKind::Disk,
                crate::scene::AreaShape::Sphere { .. } => LightKind::Sphere,
            },
        }
    }

    /// `light` as this kind: position, colour and intensity kept; an area light keeps
    /// its normal and turn, and its extent where the shapes share one (a rectangle's
    /// half width becomes a radius and back); a point light becoming an area light
    /// faces the grid's centre `toward` with extent `size`.
    pub fn convert(self, light: &Light, toward: glam::DVec3, size: f64) -> Light {
        use crate::scene::{AreaLight, AreaShape, PointLight};
        let (position, color, intensity) = (light.position(), light.color(), light.intensity());
        let (normal, rotation, extent) = match light {
            Light::Point(_) => {
                let n = (toward - position).normalize_or_zero();
                let n = if n == glam::DVec3::ZERO {
                    glam::DVec3::NEG_Y
                } else {
                    n
                };
                (n, 0.0, size)
            }
            Light::Area(a) => {
                let extent = match a.shape {
                    AreaShape::Rect { width, height } => width.max(height),
                    AreaShape::Disk { radius } | AreaShape::Sphere { radius } => 2.0 * radius,
                };
                (a.normal, a.rotation, extent)
            }
        };
        let shape = match self {
            LightKind::Point => {
                return Light::Point(PointLight {
                    position,
                    color,
                    intensity,
                });
            }
            LightKind::Rect => AreaShape::Rect {
                width: extent,
                height: extent,
            },
            LightKind::Disk => AreaShape::Disk {
                radius: 0.5 * extent,
            },
            LightKind::Sphere => AreaShape::Sphere {
                radius: 0.5 * extent,
            },
        };
        // A rectangle or disk keeps how it emits; a sphere is isotropic (AreaLight).
        let emission = match light {
            Light::Area(a) if self != LightKind::Sphere => a.emission,
            _ => Default::default(),
        };
        Light::Area(AreaLight {
            emission,
            shape,
            position,
            normal,
            rotation,
            color,
            intensity,
        })
    }
}

impl ViewerState {
    /// A new light of `kind` above the grid (one grid width over its centre), white,
    /// as bright at the centre as the seed's key light; area lights a quarter of the
    /// grid wide, facing down.
    pub fn add_light(&mut self, kind: LightKind) -> Result<()> {
        let g = &self.base.scene.grid;
        let (c, w) = (g.centre(), g.width());
        let point = Light::Point(crate::scene::PointLight {
            position: c + glam::DVec3::new(0.0, w, 0.0),
            color: glam::DVec3::ONE,
            // 384 at 16 voxels of width 1, scaling with distance squared.
            intensity: 384.0 * (w / 16.0).powi(2),
        });
        let light = kind.convert(&point, c, 0.25 * w);
        self.base.scene.lights.push(light);
        self.commit_shared()
    }

    pub fn remove_light(&mut self, index: usize) -> Result<()> {
        if index < self.base.scene.lights.len() {
            self.base.scene.lights.remove(index);
        }
        self.commit_shared()
    }
}
