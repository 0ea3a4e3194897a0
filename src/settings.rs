//! Every numeric setting of an experiment file, declared once: its key, type, allowed
//! range, default, unit and meaning. Technique settings (`crate::technique`) use the
//! same [`Setting`]; this module declares the model's own (the camera, the render
//! settings, the materials and the lights), the scene's and `voxlab ablate`'s.
//!
//! The parser checks a value with [`Setting::check`] and names the range in the words of
//! [`Setting::range_text`]; the writer writes [`Field::get`]; the viewer's widgets span
//! [`Setting::widget_range`], which holds every value the file accepts, so showing a
//! valid value never clamps it (egui clamps a value to its widget's range when the widget
//! is shown, and reports that as an edit). `tests/settings.rs` walks every declaration.

use std::f64::consts::PI;

use crate::render::{
    MAX_DEPTH_LIMIT, MAX_FILTER_WIDTH, MAX_IMAGE_SIDE, MAX_PATH_FRAMES, MAX_SAMPLES,
    MAX_TOTAL_DEPTH_LIMIT, RenderSettings,
};
use crate::scene::mesh::MAX_RESOLUTION;
use crate::scene::{
    DENSE_MAX_VOXELS, MAX_SPARSE_SIDE, MAX_VOXEL_SIZE, MIN_VOXEL_SIZE, Material, OrbitCamera,
};

/// The type and allowed range of a setting.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// An integer in `min..=max`.
    Int { min: i64, max: i64 },
    /// A finite number between `min` and `max`, each end included unless its `_open`
    /// flag says otherwise. `f64::MAX` (or `-f64::MAX`) stands for "no bound".
    Float {
        min: f64,
        max: f64,
        min_open: bool,
        max_open: bool,
    },
}

impl Kind {
    /// A number in `[min, max]`.
    pub const fn closed(min: f64, max: f64) -> Self {
        Kind::Float {
            min,
            max,
            min_open: false,
            max_open: false,
        }
    }

    /// An integer in `min..=max`.
    pub const fn int(min: i64, max: i64) -> Self {
        Kind::Int { min, max }
    }

    /// A number `> min` (up to `max`, included).
    pub const fn above(min: f64, max: f64) -> Self {
        Kind::Float {
            min,
            max,
            min_open: true,
            max_open: false,
        }
    }
}

/// Any finite number.
pub const ANY: Kind = Kind::closed(-f64::MAX, f64::MAX);
/// Any finite number `>= 0`.
pub(crate) const NON_NEGATIVE: Kind = Kind::closed(0.0, f64::MAX);
/// Any finite number `> 0`.
pub(crate) const POSITIVE: Kind = Kind::above(0.0, f64::MAX);
/// A number in `[0, 1]`.
pub(crate) const UNIT: Kind = Kind::closed(0.0, 1.0);

/// One setting of an experiment file, declared once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setting {
    /// Key within its table (`[techniques.<name>]` for plug-in techniques).
    pub key: &'static str,
    pub kind: Kind,
    /// The value when the file leaves the key out. `NaN` where there is no one default:
    /// it depends on the scene (the camera's distance is relative to the grid, a
    /// light's intensity is required) or absence means "no bound" (`max_depth`).
    pub default: f64,
    /// The unit of the value, or "" for a pure number.
    pub unit: &'static str,
    /// What it does, one line.
    pub doc: &'static str,
    /// Values `voxlab ablate` sweeps it over (empty: not a quality knob).
    pub sweep: &'static [f64],
}

impl Setting {
    /// A setting that is no quality knob (`sweep` empty).
    pub const fn new(
        key: &'static str,
        kind: Kind,
        default: f64,
        unit: &'static str,
        doc: &'static str,
    ) -> Self {
        Self {
            key,
            kind,
            default,
            unit,
            doc,
            sweep: &[],
        }
    }

    /// The allowed range in the words of the experiment parser's messages.
    pub fn range_text(&self) -> String {
        let unit = if self.unit.is_empty() {
            String::new()
        } else {
            format!(" ({})", self.unit)
        };
        match self.kind {
            Kind::Int { min, max } => format!("must be an integer in {min}..={max}{unit}"),
            Kind::Float {
                min,
                max,
                min_open,
                max_open,
            } => {
                let (lo, hi) = (min > -f64::MAX, max < f64::MAX);
                let op = |open: bool, strict: &str, loose: &str| {
                    if open { strict } else { loose }.to_string()
                };
                let range = match (lo, hi) {
                    (false, false) => String::new(),
                    (true, false) => format!(" {} {min}", op(min_open, ">", ">=")),
                    (false, true) => format!(" {} {max}", op(max_open, "<", "<=")),
                    (true, true) => format!(
                        " in {}{min}, {max}{}",
                        op(min_open, "(", "["),
                        op(max_open, ")", "]")
                    ),
                };
                format!("must be a finite number{range}{unit}")
            }
        }
    }

    /// `Ok(v)` when `v` is of the declared type and in range, else the requirement.
    pub fn check(&self, v: f64) -> Result<f64, String> {
        let ok = match self.kind {
            Kind::Int { min, max } => v.fract() == 0.0 && (min as f64..=max as f64).contains(&v),
            Kind::Float {
                min,
                max,
                min_open,
                max_open,
            } => {
                v.is_finite()
                    && if min_open { v > min } else { v >= min }
                    && if max_open { v < max } else { v <= max }
            }
        };
        if ok { Ok(v) } else { Err(self.range_text()) }
    }

    /// The closed range a widget spans: every accepted value and, at an open end, the
    /// end itself (which [`check`](Self::check) then refuses).
    pub fn widget_range(&self) -> (f64, f64) {
        match self.kind {
            Kind::Int { min, max } => (min as f64, max as f64),
            Kind::Float { min, max, .. } => (min, max),
        }
    }

    /// The record of `voxlab settings --json` and `voxlab techniques --json` under `key`:
    /// type, default (`null` where it has none), bounds (`null`: none), range, unit, doc.
    pub fn json(&self, key: &str) -> serde_json::Value {
        use serde_json::json;
        // An integer setting's numbers are JSON integers, so that a script can pass them
        // back as they are (a TOML float is no integer setting's value).
        let (kind, min, max, min_open, max_open, default) = match self.kind {
            Kind::Int { min, max } => (
                "int",
                json!(min),
                json!(max),
                false,
                false,
                json!(self.default.is_finite().then_some(self.default as i64)),
            ),
            Kind::Float {
                min,
                max,
                min_open,
                max_open,
            } => {
                // f64::MAX stands for "no bound".
                let bound = |v: f64| json!((v.abs() < f64::MAX).then_some(v));
                (
                    "float",
                    bound(min),
                    bound(max),
                    min_open,
                    max_open,
                    json!(self.default.is_finite().then_some(self.default)),
                )
            }
        };
        json!({
            "key": key,
            "type": kind,
            "default": default,
            "min": min,
            "max": max,
            "min_open": min_open,
            "max_open": max_open,
            "range": self.range_text().trim_start_matches("must be "),
            "unit": self.unit,
            "doc": self.doc,
        })
    }

    /// The TOML value of `v` in this setting's type.
    pub fn toml_value(&self, v: f64) -> toml::Value {
        match self.kind {
            Kind::Int { .. } => toml::Value::Integer(v as i64),
            Kind::Float { .. } => toml::Value::Float(v),
        }
    }
}

/// A declared setting and the field of `T` it is, in the file's units.
pub struct Field<T: 'static> {
    pub setting: Setting,
    pub get: fn(&T) -> f64,
    pub set: fn(&mut T, f64),
}

impl<T> Field<T> {
    pub fn key(&self) -> &'static str {
        self.setting.key
    }
}

/// The field of `fields` with key `key`.
pub fn field<T>(fields: &'static [Field<T>], key: &str) -> &'static Field<T> {
    fields
        .iter()
        .find(|f| f.setting.key == key)
        .unwrap_or_else(|| panic!("`{key}` is declared"))
}

/// The parser's degrees to radians: `deg / 180 * pi`, so round numbers give the very
/// radians the seed writes as fractions of pi (36 deg == 0.2 * PI bit for bit).
pub fn radians(deg: f64) -> f64 {
    deg / 180.0 * PI
}

/// Radians as the degrees an experiment file holds: the shortest decimal that parses
/// ([`radians`]) to exactly `rad`, trying `rad / pi * 180` rounded to 1e-9 first, so
/// angles parsed from round numbers come out round (`36.0` for `0.2 * PI`). About a
/// quarter of all angles have no exact decimal (`radians` skips them); those get the
/// rounded value, within 1e-9 degrees. Either way, writing the parsed angle again gives
/// the same degrees (a fixed point for |angle| < 4e5 degrees). Exactness comes first so
/// that an angle just inside an open end of its range (`vfov_deg` just below 180) is
/// not rounded onto it.
pub fn degrees(rad: f64) -> f64 {
    let d = rad / PI * 180.0;
    let scaled = d * 1e9;
    // Beyond 2^52 every f64 is an integer: nothing to round (and no overflow to inf).
    let rounded = if scaled.is_finite() && scaled.abs() < 4_503_599_627_370_496.0 {
        scaled.round() / 1e9
    } else {
        d
    };
    [rounded]
        .into_iter()
        .chain((0..17).filter_map(|digits| format!("{d:.digits$e}").parse::<f64>().ok()))
        .chain([d, d.next_up(), d.next_down()])
        .find(|&c| radians(c) == rad)
        .unwrap_or(rounded)
}

const DEGREES: &str = "degrees";

/// `[camera]`'s numbers (its `target` is a vector of any finite numbers).
pub const CAMERA: &[Field<OrbitCamera>] = &[
    Field {
        setting: Setting::new(
            "distance",
            POSITIVE,
            f64::NAN,
            "world units",
            "from the target to the eye; default 2.5 grid widths + the seed's offset",
        ),
        get: |c| c.distance,
        set: |c, v| c.distance = v,
    },
    Field {
        setting: Setting::new("yaw_deg", ANY, 36.0, DEGREES, "about +y, from +z"),
        get: |c| degrees(c.yaw),
        set: |c, v| c.yaw = radians(v),
    },
    Field {
        setting: Setting::new(
            "pitch_deg",
            Kind::closed(-90.0, 90.0),
            22.5,
            DEGREES,
            "above the horizontal plane",
        ),
        get: |c| degrees(c.pitch),
        set: |c, v| c.pitch = radians(v),
    },
    Field {
        setting: Setting::new(
            "vfov_deg",
            // From a millionth of a degree: below some 1e-300 degrees the radians
            // underflow to 0, a camera that sees nothing.
            Kind::Float {
                min: 1e-6,
                max: 180.0,
                min_open: false,
                max_open: true,
            },
            36.86989764584402,
            DEGREES,
            "vertical field of view",
        ),
        get: |c| degrees(c.vfov),
        set: |c, v| c.vfov = radians(v),
    },
];

const fn int(key: &'static str, max: u32, min: i64, default: u32, doc: &'static str) -> Setting {
    Setting::new(
        key,
        Kind::Int {
            min,
            max: max as i64,
        },
        default as f64,
        "",
        doc,
    )
}

/// `[render] ray_cutoff`'s default: 0, the exact tree. The largest cutoff that keeps every
/// shipped experiment within 1/255 of its exact tree (`crate::ray_cutoff::WITHIN_ONE_LEVEL`)
/// cuts 0.2 % of the rays and makes a frame 5 % slower (the test per ray and light costs
/// more than it saves): docs/benchmarks.md, "Ray cutoff".
pub const RAY_CUTOFF_DEFAULT: f64 = 0.0;

/// `[render]`'s numbers. `max_depth` is optional (no default: the two depths alone
/// bound the tree), so it is declared here for its range and written only when set.
pub const RENDER: &[Field<RenderSettings>] = &[
    Field {
        setting: Setting::new(
            "width",
            Kind::Int {
                min: 1,
                max: MAX_IMAGE_SIDE as i64,
            },
            512.0,
            "pixels",
            "image width",
        ),
        get: |s| s.width as f64,
        set: |s, v| s.width = v as u32,
    },
    Field {
        setting: Setting::new(
            "height",
            Kind::Int {
                min: 1,
                max: MAX_IMAGE_SIDE as i64,
            },
            512.0,
            "pixels",
            "image height",
        ),
        get: |s| s.height as f64,
        set: |s, v| s.height = v as u32,
    },
    Field {
        setting: int(
            "max_reflection_depth",
            MAX_DEPTH_LIMIT,
            0,
            4,
            "reflections along one path",
        ),
        get: |s| s.max_reflection_depth as f64,
        set: |s, v| s.max_reflection_depth = v as u32,
    },
    Field {
        setting: int(
            "max_refraction_depth",
            MAX_DEPTH_LIMIT,
            0,
            4,
            "refractions along one path",
        ),
        get: |s| s.max_refraction_depth as f64,
        set: |s, v| s.max_refraction_depth = v as u32,
    },
    Field {
        setting: int(
            "light_samples",
            MAX_SAMPLES,
            1,
            1,
            "shadow rays per area light per hit",
        ),
        get: |s| s.light_samples as f64,
        set: |s, v| s.light_samples = v as u32,
    },
    Field {
        setting: int("spp", MAX_SAMPLES, 1, 1, "frames accumulated per image"),
        get: |s| s.spp as f64,
        set: |s, v| s.spp = v as u32,
    },
    Field {
        setting: int("seed", u32::MAX, 0, 0, "seed of every sample"),
        get: |s| s.seed as f64,
        set: |s, v| s.seed = v as u32,
    },
    Field {
        setting: int(
            "path_frames",
            MAX_PATH_FRAMES,
            1,
            1,
            "frames of a camera path per image, the image the last (a temporal reconstruction's history)",
        ),
        get: |s| s.path_frames as f64,
        set: |s, v| s.path_frames = v as u32,
    },
    Field {
        setting: Setting::new(
            "orbit_deg",
            Kind::closed(-180.0, 180.0),
            0.0,
            DEGREES,
            "the camera's turn about its target from one frame of the path to the next",
        ),
        get: |s| s.orbit_deg,
        set: |s, v| s.orbit_deg = v,
    },
    Field {
        setting: Setting::new(
            "filter_width",
            Kind::above(0.0, MAX_FILTER_WIDTH),
            0.5,
            "pixels",
            "the box filter's half-width, the Gaussian's sigma",
        ),
        get: |s| s.filter_width,
        set: |s, v| s.filter_width = v,
    },
    Field {
        setting: Setting::new(
            "falloff_min_distance",
            POSITIVE,
            0.01,
            "world units",
            "distance below which inverse-square falloff stops growing",
        ),
        get: |s| s.falloff_min_distance,
        set: |s, v| s.falloff_min_distance = v,
    },
    Field {
        setting: Setting::new(
            "ray_offset",
            Kind::Float {
                min: 0.0,
                max: 1.0,
                min_open: false,
                max_open: true,
            },
            0.001,
            "voxel widths",
            "secondary rays start this far off the surface",
        ),
        get: |s| s.ray_offset,
        set: |s, v| s.ray_offset = v,
    },
    Field {
        setting: Setting::new(
            "ray_cutoff",
            UNIT,
            RAY_CUTOFF_DEFAULT,
            "path weight",
            "rays and lights whose weight along their path falls below it are not traced (0: the whole tree)",
        ),
        get: |s| s.ray_cutoff,
        set: |s, v| s.ray_cutoff = v,
    },
    Field {
        setting: Setting::new(
            "walk_budget_mib",
            Kind::Int {
                min: 0,
                max: MAX_WALK_BUDGET_MIB as i64,
            },
            0.0,
            "MiB",
            "the most each binding of a traversal's own data may take where it chooses what to \
             hold (the sparse octant walk's codes, in up to three bindings beside its tree): \
             the same image, other steps (0: the tracer's own, the device's largest binding \
             on the GPU, 128 MiB on the CPU reference)",
        ),
        get: |s| s.walk_budget_mib as f64,
        set: |s, v| s.walk_budget_mib = v as u32,
    },
];

/// Largest `render.walk_budget_mib`: 64 GiB, past any device's binding.
pub const MAX_WALK_BUDGET_MIB: u32 = 1 << 16;

/// `[render] max_depth`: optional, so not a [`Field`] of [`RENDER`].
pub(crate) const MAX_DEPTH: Setting = Setting::new(
    "max_depth",
    Kind::int(0, MAX_TOTAL_DEPTH_LIMIT as i64),
    f64::NAN,
    "",
    "reflections and refractions together along one path (absent: no joint bound)",
);

/// `[[materials]]`' numbers (albedo, sigma and emission are vectors `>= 0`).
pub(crate) const MATERIAL: &[Field<Material>] = &[
    Field {
        setting: Setting::new("kd", UNIT, 0.0, "", "diffuse coefficient"),
        get: |m| m.kd,
        set: |m, v| m.kd = v,
    },
    Field {
        setting: Setting::new("ks", UNIT, 0.0, "", "specular coefficient"),
        get: |m| m.ks,
        set: |m, v| m.ks = v,
    },
    Field {
        setting: Setting::new(
            "shininess",
            NON_NEGATIVE,
            crate::scene::SEED_SHININESS,
            "",
            "Phong exponent",
        ),
        get: |m| m.shininess,
        set: |m, v| m.shininess = v,
    },
    Field {
        setting: Setting::new("kr", UNIT, 0.0, "", "reflection coefficient"),
        get: |m| m.kr,
        set: |m, v| m.kr = v,
    },
    Field {
        setting: Setting::new("kt", UNIT, 0.0, "", "transmission coefficient"),
        get: |m| m.kt,
        set: |m, v| m.kt = v,
    },
    Field {
        setting: Setting::new("ior", POSITIVE, 1.0, "", "index of refraction"),
        get: |m| m.ior,
        set: |m, v| m.ior = v,
    },
];

/// `[[lights]] intensity`, of every type.
pub const LIGHT_INTENSITY: Setting = Setting::new(
    "intensity",
    NON_NEGATIVE,
    f64::NAN,
    "",
    "radiant intensity (point) or radiance scale (area) times color",
);
/// Each side of a rect light's `size`.
pub const LIGHT_SIDE: Setting = Setting::new(
    "size",
    NON_NEGATIVE,
    f64::NAN,
    "world units",
    "each of a rect light's [width, height]",
);
/// A disk or sphere light's `radius`.
pub const LIGHT_RADIUS: Setting = Setting::new(
    "radius",
    NON_NEGATIVE,
    f64::NAN,
    "world units",
    "a disk or sphere light's radius",
);
/// A rect or disk light's `rotation_deg` about its normal.
pub const LIGHT_ROTATION: Setting = Setting::new(
    "rotation_deg",
    ANY,
    0.0,
    DEGREES,
    "about the light's normal",
);

/// `[scene] size`: the side of a generator's cube. Larger cubes than a dense grid holds
/// (`scene::DENSE_MAX_VOXELS`) are held as a sparse tree, whose sides are at most
/// `scene::MAX_SPARSE_SIDE`.
pub const SCENE_SIZE: Setting = Setting::new(
    "size",
    Kind::int(1, MAX_SPARSE_SIDE as i64),
    crate::scene::seed::SEED_SIZE as f64,
    "voxels",
    "a generator's grid: a cube of this side (or give dims)",
);
/// Each of `[scene] dims`. A side past `DENSE_MAX_VOXELS` makes the grid sparse, whose
/// sides are at most `MAX_SPARSE_SIDE`: no grid has one, so the range ends there.
pub const SCENE_SIDE: Setting = Setting::new(
    "dims",
    Kind::int(1, DENSE_MAX_VOXELS as i64),
    f64::NAN,
    "voxels",
    "each of a generator's grid's [x, y, z]; past 2^28 voxels in all the grid is a sparse tree, \
     each side at most 4096",
);
/// `[scene] voxel_size`, for every source (a `.vox` file's voxels, a mesh's units).
pub const SCENE_VOXEL_SIZE: Setting = Setting::new(
    "voxel_size",
    Kind::closed(MIN_VOXEL_SIZE, MAX_VOXEL_SIZE),
    1.0,
    "world units",
    "a voxel's width (with a mesh, in its units and instead of resolution)",
);
/// `[scene] resolution`, with a mesh.
pub const SCENE_RESOLUTION: Setting = Setting::new(
    "resolution",
    Kind::int(1, MAX_RESOLUTION as i64),
    f64::NAN,
    "voxels",
    "with a mesh: voxels along its longest axis (or give voxel_size)",
);
/// `model` of `[scene]` and of `[[scene.models]]`, with a `.vox` file.
pub const VOX_MODEL: Setting = Setting::new(
    "model",
    Kind::int(0, u32::MAX as i64),
    f64::NAN,
    "",
    "with a .vox file: only this model of the file (0-based), unmoved (absent: the whole scene graph)",
);

/// `[[scene.models]] resolution`, with a mesh; the grid's longest side bounds it too.
pub const MODEL_RESOLUTION: Setting = Setting::new(
    "resolution",
    Kind::int(1, MAX_RESOLUTION as i64),
    f64::NAN,
    "voxels",
    "with mesh: voxels along its longest axis, at most the grid's longest side",
);
/// `[[scene.models]] scale`: each voxel of a `.vox` model becomes scale^3 voxels.
pub const MODEL_SCALE: Setting = Setting::new(
    "scale",
    Kind::int(1, 16),
    1.0,
    "",
    "with vox: each voxel becomes a cube of scale^3 voxels",
);

/// `[ablate]`'s numbers: `crate::ablate::AblateConfig::from_str` checks them.
pub mod ablate {
    use super::{Kind, Setting};
    use crate::render::MAX_SAMPLES;

    /// Seeds per point when `[ablate] seeds` is not given: three is the fewest with an
    /// interval (t = 4.30 at 2 degrees of freedom) at three times the cost of one.
    pub(crate) const DEFAULT_SEEDS: u32 = 3;

    /// The most seeds per point; far below the reference's seed offsets
    /// (`crate::ablate`), so a point's seeds never draw the reference's samples.
    pub(crate) const MAX_SEEDS: u32 = 64;

    pub const REFERENCE_SPP: Setting = Setting::new(
        "reference_spp",
        Kind::int(2, MAX_SAMPLES as i64),
        1024.0,
        "frames",
        "the converged reference's samples (in two halves), at least the largest swept spp",
    );
    pub const SPP: Setting = Setting::new(
        "spp",
        Kind::int(1, MAX_SAMPLES as i64),
        f64::NAN,
        "frames",
        "each of the stochastic curve's sample counts, strictly ascending (default 1, 2, 4 .. 256)",
    );
    pub const SEEDS: Setting = Setting::new(
        "seeds",
        Kind::int(1, MAX_SEEDS as i64),
        DEFAULT_SEEDS as f64,
        "",
        "independent renders of each point: its mean and 95 % interval",
    );
    pub const RUNS: Setting = Setting::new(
        "runs",
        Kind::int(1, 1000),
        3.0,
        "",
        "timed renders of each point and seed: their median is its time",
    );
    pub const WARMUP: Setting = Setting::new(
        "warmup",
        Kind::int(0, 100),
        1.0,
        "",
        "untimed renders before a point's timed ones",
    );

    /// Every one, in the order `voxlab settings` lists them.
    pub const SETTINGS: &[Setting] = &[REFERENCE_SPP, SPP, SEEDS, RUNS, WARMUP];

    /// What a declared `[ablate]` number takes (`ablate.seeds`, an entry `ablate.spp[2]`),
    /// as its declaration says it; `None` for any other key.
    pub fn declared_range(key: &str) -> Option<String> {
        let s = SETTINGS.iter().find(|s| {
            key.strip_prefix("ablate.")
                .and_then(|k| k.strip_prefix(s.key))
                .is_some_and(|rest| rest.is_empty() || rest.starts_with('['))
        })?;
        Some(if s.key == SPP.key {
            format!("every entry {}", s.range_text())
        } else {
            s.range_text()
        })
    }
}

/// Every declared table of the model, for listings and tests: (table, its numbers).
pub fn model_settings() -> Vec<(&'static str, Vec<Setting>)> {
    let mut render = RENDER.iter().map(|f| f.setting).collect::<Vec<_>>();
    render.push(MAX_DEPTH);
    vec![
        ("camera", CAMERA.iter().map(|f| f.setting).collect()),
        ("render", render),
        ("materials", MATERIAL.iter().map(|f| f.setting).collect()),
        (
            "lights",
            vec![LIGHT_INTENSITY, LIGHT_SIDE, LIGHT_RADIUS, LIGHT_ROTATION],
        ),
    ]
}

/// The range of `s` as a reader writes it: `1..=16384`, `[0, 1]`, `(0, 4]`, `> 0`, any.
fn range_cell(s: &Setting) -> String {
    let text = Setting { unit: "", ..*s }.range_text();
    let range = text
        .trim_start_matches("must be an integer in ")
        .trim_start_matches("must be a finite number")
        .trim_start_matches(" in ")
        .trim();
    if range.is_empty() {
        "any".to_string()
    } else {
        range.to_string()
    }
}

/// Every declared number of an experiment file: the model's ([`model_settings`]), the
/// scene's and `voxlab ablate`'s.
pub fn file_settings() -> Vec<(&'static str, Vec<Setting>)> {
    let mut all = model_settings();
    all.insert(
        0,
        (
            "scene",
            vec![
                SCENE_SIZE,
                SCENE_SIDE,
                SCENE_VOXEL_SIZE,
                SCENE_RESOLUTION,
                VOX_MODEL,
            ],
        ),
    );
    all.insert(
        1,
        (
            "scene.models",
            vec![VOX_MODEL, MODEL_RESOLUTION, MODEL_SCALE],
        ),
    );
    all.push(("ablate", ablate::SETTINGS.to_vec()));
    all
}

/// Every declared number of an experiment file as records (`voxlab settings --json`, the
/// Python `settings()`), each keyed `table.key` as [`Setting::json`] writes it.
pub fn listing_json() -> serde_json::Value {
    file_settings()
        .into_iter()
        .flat_map(|(table, s)| {
            s.into_iter()
                .map(move |s| s.json(&format!("{table}.{}", s.key)))
        })
        .collect()
}

/// Every declared number of an experiment file as a markdown table (`voxlab settings
/// --markdown`; `docs/experiments.md` holds it, and a test keeps the two equal).
pub fn markdown() -> String {
    let mut out = String::from("| key | type | range | default | unit | what it does |\n");
    out += "|---|---|---|---|---|---|\n";
    for (table, settings) in file_settings() {
        for s in settings {
            let kind = match s.kind {
                Kind::Int { .. } => "integer",
                Kind::Float { .. } => "number",
            };
            let default = if s.default.is_nan() {
                "-".to_string()
            } else {
                format!("{}", s.default)
            };
            out += &format!(
                "| `{table}.{}` | {kind} | {} | {default} | {} | {} |\n",
                s.key,
                range_cell(&s),
                s.unit,
                s.doc
            );
        }
    }
    out
}
