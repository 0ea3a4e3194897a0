//! The way back: an [`Experiment`] written as an experiment file that parses to it again.
//!
//! The voxels are not written: they come from the `[scene]` table of the file the
//! experiment was read from (the *scene source*, [`scene_source`]), copied verbatim, so
//! a `.vox` model or a mesh is referred to by its path and loaded again. Everything else
//! (camera, lights, materials, render settings, features, cone knobs) is written in
//! full, defaults included, so the file does not depend on the defaults of the version
//! that reads it.
//!
//! For `e2 = parse(to_toml(e))`: `to_toml(e2) == to_toml(e)` byte for byte and
//! `parse(to_toml(e2)) == e2`. `e2 == e` itself holds except for angles that no decimal
//! number of degrees parses to exactly: the file holds degrees rounded to 1e-9 there
//! (see [`degrees`]), so such an angle moves by less than 1e-9 degrees in the first
//! cycle. The palette is written by name, as `[[materials]]` override it, which needs
//! unique names ([`WriteError`]).

use std::path::{Component, Path, PathBuf};

use glam::DVec3;
use toml::{Table, Value};

use super::{Ctx, Experiment, ExperimentError};
use crate::render::{Features, RenderSettings};
use crate::scene::{AreaShape, Light, Material, OrbitCamera};

/// Why an experiment cannot be written as a file that parses back to it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("cannot write experiment `{name}` as TOML: {key}: {message}")]
pub struct WriteError {
    /// The experiment's name.
    pub name: String,
    /// Dotted key as the file would have it, e.g. `materials[3].name`.
    pub key: String,
    pub message: String,
}

/// The first line of every file [`to_toml`] writes.
pub(crate) const HEADER: &str = "# Written by voxlab from an experiment, every value resolved: \
                          `voxlab render` renders exactly this.";

/// [`HEADER`] where the voxels were given in memory (Python's `with_grid`): no `[scene]`
/// table gives them, and the file renders its settings over the seed's scene.
pub(crate) const IN_MEMORY_HEADER: &str = "# Written by voxlab from an experiment whose voxels \
    were given in memory (its image's record names them: \"grid\", their blake3 hash), every \
    other value resolved: `voxlab render` renders these settings over the seed's scene, \
    not those voxels.";

/// The `[scene]` table of experiment text as written (empty if the file has none), with
/// relative `vox` and `mesh` paths resolved against the file's directory, as the loader
/// resolves them, and made absolute (canonical where the file exists); absolute paths
/// are kept as given. This is where the voxels come from, for [`to_toml`].
pub fn scene_source(text: &str, path: &Path) -> Result<Table, ExperimentError> {
    let ctx = Ctx::new(text, path);
    let doc: Table = toml::from_str(text).map_err(|e| ctx.serde_error(&e))?;
    let mut scene = match doc.get("scene") {
        None => Table::new(),
        Some(Value::Table(t)) => t.clone(),
        Some(_) => return Err(ctx.invalid("scene", "must be a table")),
    };
    let dir = path.parent().unwrap_or(Path::new(""));
    let mut bad_path = None;
    for_each_source_path(&mut scene, |key, v| {
        let Value::String(p) = v else {
            bad_path.get_or_insert(key);
            return;
        };
        if Path::new(p.as_str()).is_absolute() {
            return;
        }
        let joined = dir.join(p.as_str());
        let resolved = std::fs::canonicalize(&joined)
            .or_else(|_| std::path::absolute(&joined))
            .unwrap_or(joined);
        *v = Value::String(resolved.to_string_lossy().into_owned());
    });
    if let Some(key) = bad_path {
        return Err(ctx.invalid(&key, "must be a path (a string)"));
    }
    Ok(scene)
}

/// Every file [`input_files`] names with the blake3 hash of its content (hex), as
/// provenance records them: a stored experiment names its assets by path, and the
/// hash says whether the file at that path is still the one it was made from. A file
/// that cannot be read is left out. Each as the records write it: `{path, blake3}`.
pub(crate) fn input_hashes(text: &str, path: &Path) -> Vec<serde_json::Value> {
    input_files(text, path)
        .into_iter()
        .filter_map(|f| crate::output::file_record(&f))
        .collect()
}

/// [`input_hashes`] less the experiment file's own: its assets (`path` places their
/// relative paths and may name no file, as text's label does).
pub(crate) fn asset_hashes(text: &str, path: &Path) -> Vec<serde_json::Value> {
    input_files(text, path)
        .into_iter()
        .skip(1)
        .filter_map(|f| crate::output::file_record(&f))
        .collect()
}

/// Every file experiment `e`, parsed from `text` (overrides applied), reads: from a file,
/// [`input_files`]; from text without a file (Python's dicts and text), the assets it
/// names, relative to where its label puts it (the label itself is no file); nothing
/// for an experiment made in code.
pub fn experiment_inputs(e: &crate::experiment::Experiment, text: &str) -> Vec<PathBuf> {
    match (&e.source_path, &e.source_record) {
        (Some(p), _) => input_files(text, p),
        (None, Some(r)) => {
            let label = r
                .inputs
                .first()
                .and_then(|i| i["path"].as_str())
                .unwrap_or("");
            input_files(text, Path::new(label)).split_off(1)
        }
        (None, None) => Vec::new(),
    }
}

/// Every file an experiment given as `text` (overrides applied) at `path` reads: the
/// file itself, its scene's and its models' `vox` and `mesh` files, and each OBJ's
/// material libraries (`mtllib`). What a command that writes must never overwrite.
/// Paths that do not resolve are left out (the loader reports them).
pub fn input_files(text: &str, path: &Path) -> Vec<PathBuf> {
    let mut files = vec![path.to_path_buf()];
    let Ok(mut scene) = scene_source(text, path) else {
        return files;
    };
    for_each_source_path(&mut scene, |_, v| {
        let Value::String(p) = v else { return };
        let asset = PathBuf::from(p.as_str());
        let is_obj = asset
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
        if is_obj
            && let Ok(bytes) = crate::input::read_file(&asset, crate::input::MAX_MESH_BYTES, "mesh")
        {
            let dir = asset.parent().unwrap_or(Path::new(""));
            for line in String::from_utf8_lossy(&bytes).lines() {
                if let Some(lib) = line.trim_start().strip_prefix("mtllib ") {
                    files.push(dir.join(lib.trim()));
                }
            }
        }
        files.push(asset);
    });
    files
}

/// The first of `outputs` that is one of `inputs` (the same file, however named), as
/// (output, input): a command's refusal to overwrite what it reads.
pub fn overwrites<'a>(
    outputs: &'a [PathBuf],
    inputs: &'a [PathBuf],
) -> Option<(&'a Path, &'a Path)> {
    let inputs: Vec<(PathBuf, &Path)> = inputs
        .iter()
        .filter_map(|i| Some((std::fs::canonicalize(i).ok()?, i.as_path())))
        .collect();
    outputs.iter().find_map(|o| {
        let o_canon = std::fs::canonicalize(o).ok()?;
        inputs
            .iter()
            .find(|(c, _)| *c == o_canon)
            .map(|(_, i)| (o.as_path(), *i))
    })
}

/// `source` (a [`scene_source`]) for a file written into `dest_dir`: each absolute
/// `vox`/`mesh` path that shares a directory (not just the root) with `dest_dir` becomes
/// relative to `dest_dir` (`..` up to the common ancestor, then down), so a file
/// exported beside its model keeps working when the tree is moved. Paths that share
/// only the root, relative paths and anything else are kept as they are.
pub fn relocate_scene_source(source: &Table, dest_dir: &Path) -> Table {
    let mut out = source.clone();
    // `..` climbs the physical directory: canonical, so no symbolic link is climbed.
    let dest = std::fs::canonicalize(dest_dir)
        .or_else(|_| std::path::absolute(dest_dir))
        .unwrap_or_else(|_| dest_dir.to_path_buf());
    for_each_source_path(&mut out, |_, v| {
        if let Value::String(p) = v
            && let Some(rel) = relative_path(Path::new(p.as_str()), &dest)
        {
            *p = rel.to_string_lossy().into_owned();
        }
    });
    out
}

/// Calls `f` with the key and value of every file path of a `[scene]` table: its own
/// `vox`/`mesh`, and each `[[scene.models]]` entry's.
fn for_each_source_path(scene: &mut Table, mut f: impl FnMut(String, &mut Value)) {
    const KEYS: [&str; 2] = ["vox", "mesh"];
    for key in KEYS {
        if let Some(v) = scene.get_mut(key) {
            f(format!("scene.{key}"), v);
        }
    }
    if let Some(Value::Array(models)) = scene.get_mut("models") {
        for (i, m) in models.iter_mut().enumerate() {
            if let Value::Table(t) = m {
                for key in KEYS {
                    if let Some(v) = t.get_mut(key) {
                        f(format!("scene.models[{i}].{key}"), v);
                    }
                }
            }
        }
    }
}

/// `target` relative to the directory `dir`, both absolute; `None` where they share no
/// directory below the root or `dir` has `.`/`..` components below the shared part.
fn relative_path(target: &Path, dir: &Path) -> Option<PathBuf> {
    if !target.is_absolute() || !dir.is_absolute() {
        return None;
    }
    let t: Vec<Component> = target.components().collect();
    let d: Vec<Component> = dir.components().collect();
    let common = t.iter().zip(&d).take_while(|(a, b)| a == b).count();
    let shares_a_dir = t[..common]
        .iter()
        .any(|c| matches!(c, Component::Normal(_)));
    let below_is_plain = d[common..]
        .iter()
        .all(|c| matches!(c, Component::Normal(_)));
    if !shares_a_dir || !below_is_plain || common == t.len() {
        return None;
    }
    let mut rel = PathBuf::new();
    for _ in common..d.len() {
        rel.push("..");
    }
    for c in &t[common..] {
        rel.push(c);
    }
    Some(rel)
}

pub use crate::settings::degrees;

fn v3(v: DVec3) -> Value {
    Value::Array(vec![v.x.into(), v.y.into(), v.z.into()])
}

/// Every declared number of `fields` (`crate::settings`) as `target` has it.
fn insert_fields<T>(t: &mut Table, fields: &[crate::settings::Field<T>], target: &T) {
    for f in fields {
        t.insert(f.key().into(), f.setting.toml_value((f.get)(target)));
    }
}

/// `[camera]`: target, distance and the angles in degrees.
pub(crate) fn camera_table(c: &OrbitCamera) -> Table {
    let mut t = Table::new();
    t.insert("target".into(), v3(c.target));
    insert_fields(&mut t, crate::settings::CAMERA, c);
    t
}

/// One `[[lights]]` entry, with the keys its type allows and no others: a sphere's
/// normal and rotation have no key (the parser sets -y and 0).
pub(crate) fn light_table(l: &Light) -> Table {
    let mut t = Table::new();
    let kind = match l {
        Light::Point(_) => "point",
        Light::Area(a) => match a.shape {
            AreaShape::Rect { .. } => "rect",
            AreaShape::Disk { .. } => "disk",
            AreaShape::Sphere { .. } => "sphere",
        },
    };
    t.insert("type".into(), kind.into());
    t.insert("position".into(), v3(l.position()));
    t.insert("color".into(), v3(l.color()));
    t.insert("intensity".into(), l.intensity().into());
    if let Light::Area(a) = l {
        match a.shape {
            AreaShape::Rect { width, height } => {
                t.insert("normal".into(), v3(a.normal));
                t.insert(
                    "size".into(),
                    Value::Array(vec![width.into(), height.into()]),
                );
                t.insert("rotation_deg".into(), degrees(a.rotation).into());
                t.insert("emission".into(), a.emission.name().into());
            }
            AreaShape::Disk { radius } => {
                t.insert("normal".into(), v3(a.normal));
                t.insert("radius".into(), radius.into());
                t.insert("rotation_deg".into(), degrees(a.rotation).into());
                t.insert("emission".into(), a.emission.name().into());
            }
            AreaShape::Sphere { radius } => {
                t.insert("radius".into(), radius.into());
            }
        }
    }
    t
}

/// One `[[materials]]` entry with every field; `sigma` only where the material has one
/// (absent means the default derived from kt).
pub(crate) fn material_table(m: &Material) -> Table {
    let mut t = Table::new();
    t.insert("name".into(), m.name.clone().into());
    t.insert("albedo".into(), v3(m.albedo));
    insert_fields(&mut t, crate::settings::MATERIAL, m);
    if let Some(s) = m.sigma {
        t.insert("sigma".into(), v3(s));
    }
    t.insert("emission".into(), v3(m.emission));
    t.insert("dielectric".into(), m.dielectric.name().into());
    t
}

/// `[render]`: every setting, and the scene's ambient colour (which the file keeps
/// here).
pub fn render_table(s: &RenderSettings, ambient: DVec3) -> Table {
    // Exhaustive on purpose: a new setting does not compile until it is written here
    // (or, for `features` and `cones`, in their own tables).
    let RenderSettings {
        width: _,
        height: _,
        max_reflection_depth: _,
        max_refraction_depth: _,
        max_depth: _,
        rules: _,
        falloff: _,
        falloff_min_distance: _,
        ray_offset: _,
        ray_cutoff: _,
        features: _,
        light_samples: _,
        spp: _,
        seed: _,
        path_frames: _,
        orbit_deg: _,
        cones: _,
        technique_params: _,
        pixel_filter: _,
        filter_width: _,
        traversal: _,
        walk_budget_mib: _,
        surface: _,
    } = s;
    let mut t = Table::new();
    insert_fields(&mut t, crate::settings::RENDER, s);
    if let Some(d) = s.max_depth {
        t.insert("max_depth".into(), Value::Integer(i64::from(d)));
    }
    t.insert("rules".into(), s.rules.name().into());
    t.insert("falloff".into(), s.falloff.into());
    t.insert("ambient".into(), v3(ambient));
    t.insert("pixel_filter".into(), s.pixel_filter.name().into());
    t.insert("traversal".into(), s.traversal.name().into());
    t.insert("surface".into(), s.surface.name().into());
    t
}

/// `[features]`: every lighting term's flag, and the shadow and transmittance models by
/// name (`crate::technique`).
pub(crate) fn features_table(f: &Features) -> Table {
    let mut t = Table::new();
    for term in crate::technique::LIGHTING_TERMS {
        t.insert(term.name.into(), f.term(term.name).into());
    }
    t.insert("transmittance".into(), f.transmittance.name().into());
    t.insert("shadow_model".into(), f.shadow_model.name.into());
    t.insert("reconstruction".into(), f.reconstruction.name.into());
    t
}

/// `[techniques.<name>]` of each plug-in technique with a setting given, in each
/// setting's declared type; `None` when none is given.
pub(crate) fn techniques_table(p: &crate::technique::TechniqueParams) -> Option<Table> {
    let mut t = Table::new();
    for (name, values) in p.iter() {
        let declared = crate::technique::technique_table(name).map_or(&[][..], |(_, s)| s);
        let table: Table = values
            .iter()
            .map(|(k, &v)| {
                let value = declared
                    .iter()
                    .find(|s| s.key == k)
                    .map_or(Value::Float(v), |s| s.toml_value(v));
                (k.clone(), value)
            })
            .collect();
        t.insert(name.to_string(), Value::Table(table));
    }
    (!t.is_empty()).then_some(t)
}

/// A shared group's table (`crate::technique::SETTING_GROUPS`): every setting, each in
/// its declared type.
pub(crate) fn group_table(g: &crate::technique::SettingGroup, s: &RenderSettings) -> Table {
    g.settings
        .iter()
        .map(|k| (k.setting.key.to_string(), k.setting.toml_value((k.get)(s))))
        .collect()
}

/// `e` as a complete experiment file: a comment line, `name`, `[scene]` = `scene_source`
/// verbatim (the voxels: [`scene_source`], or [`relocate_scene_source`] for a file in
/// another directory), then every camera, light, material (void excepted), render,
/// feature and cone value. `voxlab render` on the file renders `e` (angles to 1e-9
/// degrees; see the module documentation for the round trip).
///
/// The grid is not written: `e.scene.grid` must be what `scene_source` gives (with its
/// boxes and mesh material), as it is for an experiment parsed from that source and
/// edited in anything but its voxels. Likewise the palette must be the source's,
/// overridden and extended: `[[materials]]` override a palette entry of the same name
/// and append new names.
///
/// Errors where no file can express `e`: a name the parser would reject, material names
/// that are empty or not unique (including void's, so no material can be named like
/// material 0), or a value that is not finite.
pub fn to_toml(e: &Experiment, scene_source: &Table) -> Result<String, WriteError> {
    let err = |key: String, message: String| WriteError {
        name: e.name.clone(),
        key,
        message,
    };
    if !super::is_valid_name(&e.name) {
        return Err(err(
            "name".into(),
            format!("{:?}: an experiment name is {}", e.name, super::NAME_RULE),
        ));
    }
    let materials = &e.scene.materials;
    for (i, m) in materials.iter().enumerate() {
        if m.name.is_empty() {
            return Err(err(
                format!("materials[{i}].name"),
                "is empty; [[materials]] are matched by name".into(),
            ));
        }
        if let Some(j) = materials[..i].iter().position(|p| p.name == m.name) {
            return Err(err(
                format!("materials[{i}].name"),
                format!(
                    "{:?} is also the name of material {j}: [[materials]] override palette \
                     entries by name, so a file cannot give two materials one name",
                    m.name
                ),
            ));
        }
    }

    let mut head = Table::new();
    head.insert("name".into(), e.name.clone().into());
    if let Some(d) = &e.description {
        head.insert("description".into(), d.clone().into());
    }
    if e.scene.lights.is_empty() {
        // Absent would mean the seed's lights.
        head.insert("lights".into(), Value::Array(Vec::new()));
    }
    let lights: Vec<Table> = e.scene.lights.iter().map(light_table).collect();
    let mats: Vec<Table> = materials.iter().skip(1).map(material_table).collect();
    let scene = Table::from_iter([("scene".to_string(), Value::Table(scene_source.clone()))]);
    let check = |key: &str, t: &Table| match non_finite(&Value::Table(t.clone()), key) {
        Some(bad) => Err(err(bad, "is not a finite number".into())),
        None => Ok(()),
    };
    let to_string =
        |key: &str, t: &Table| toml::to_string(t).map_err(|e| err(key.to_string(), e.to_string()));

    let mut out = format!("{HEADER}\n\n");
    out +=
        &ordered(&head, &["name", "description"]).map_err(|e| err("name".into(), e.to_string()))?;
    // The scene source as toml writes it (nested `[[scene.boxes]]` included).
    check("", &scene)?;
    out += "\n";
    out += &to_string("scene", &scene)?;
    let mut section = |header: &str, key: &str, t: &Table, order: &[&str]| {
        check(key, t)?;
        out += &format!("\n{header}\n");
        out += &ordered(t, order).map_err(|e| err(key.to_string(), e.to_string()))?;
        Ok::<(), WriteError>(())
    };
    section(
        "[camera]",
        "camera",
        &camera_table(&e.scene.camera),
        CAMERA_KEYS,
    )?;
    for (i, l) in lights.iter().enumerate() {
        section("[[lights]]", &format!("lights[{i}]"), l, LIGHT_KEYS)?;
    }
    for (i, m) in mats.iter().enumerate() {
        section(
            "[[materials]]",
            &format!("materials[{i}]"),
            m,
            MATERIAL_KEYS,
        )?;
    }
    let render = render_table(&e.settings, e.scene.ambient);
    section("[render]", "render", &render, RENDER_KEYS)?;
    let features = features_table(&e.settings.features);
    section(
        "[features]",
        "features",
        &features,
        &crate::technique::feature_keys(),
    )?;
    for g in crate::technique::SETTING_GROUPS {
        section(
            &format!("[{}]", g.table),
            g.table,
            &group_table(g, &e.settings),
            &g.settings.iter().map(|c| c.setting.key).collect::<Vec<_>>(),
        )?;
    }
    if let Some(t) = techniques_table(&e.settings.technique_params) {
        for (name, v) in &t {
            if let Value::Table(table) = v {
                let key = format!("techniques.{name}");
                section(&format!("[{key}]"), &key, table, &[])?;
            }
        }
    }
    Ok(out)
}

// The order keys are written in (as in `experiments/baseline.toml`); `toml::Table`
// sorts them.
const CAMERA_KEYS: &[&str] = &["target", "distance", "yaw_deg", "pitch_deg", "vfov_deg"];
const LIGHT_KEYS: &[&str] = &[
    "type",
    "position",
    "normal",
    "size",
    "radius",
    "rotation_deg",
    "color",
    "intensity",
];
const MATERIAL_KEYS: &[&str] = &[
    "name",
    "albedo",
    "kd",
    "ks",
    "shininess",
    "kr",
    "kt",
    "ior",
    "sigma",
    "emission",
    "dielectric",
];
const RENDER_KEYS: &[&str] = &[
    "width",
    "height",
    "max_reflection_depth",
    "max_refraction_depth",
    "max_depth",
    "rules",
    "falloff",
    "falloff_min_distance",
    "ray_offset",
    "ray_cutoff",
    "ambient",
    "light_samples",
    "spp",
    "seed",
    "path_frames",
    "orbit_deg",
    "pixel_filter",
    "filter_width",
    "traversal",
    "walk_budget_mib",
    "surface",
];

/// `key = value` lines of a table of plain values, the keys in `order` first, then any
/// others in the table's order.
fn ordered(t: &Table, order: &[&str]) -> Result<String, toml::ser::Error> {
    let rest = t.keys().filter(|k| !order.contains(&k.as_str()));
    let mut out = String::new();
    for k in order.iter().copied().chain(rest.map(String::as_str)) {
        if let Some(v) = t.get(k) {
            out += &toml::to_string(&Table::from_iter([(k.to_string(), v.clone())]))?;
        }
    }
    Ok(out)
}

/// The dotted key of the first NaN or infinity in `v`.
fn non_finite(v: &Value, key: &str) -> Option<String> {
    let join = |k: &str| {
        if key.is_empty() {
            k.to_string()
        } else {
            format!("{key}.{k}")
        }
    };
    match v {
        Value::Float(x) if !x.is_finite() => Some(key.to_string()),
        Value::Array(a) => a.iter().enumerate().find_map(|(i, x)| {
            let k = match x {
                Value::Table(_) => format!("{key}[{i}]"),
                _ => key.to_string(),
            };
            non_finite(x, &k)
        }),
        Value::Table(t) => t.iter().find_map(|(k, x)| non_finite(x, &join(k))),
        _ => None,
    }
}
