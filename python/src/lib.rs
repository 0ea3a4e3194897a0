//! The native half of the Python package `voxlab` (`python/voxlab/__init__.py` wraps
//! it): the library's facade ([`voxlab::Session`], [`voxlab::Experiment`],
//! [`voxlab::Grid`], [`voxlab::Image`], [`voxlab::Error`]) with numpy arrays for images
//! and voxels. Everything a user calls is documented in `python/voxlab/__init__.pyi`;
//! the Python layer adds dicts, TOML values, tqdm and pandas.

use std::path::PathBuf;
use std::sync::{Arc, Condvar, Mutex, OnceLock};
use std::time::Duration;

use glam::{DVec3, UVec3};
use numpy::ndarray::Axis;
use numpy::{
    PyArray1, PyArray3, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods, npyffi::NPY_ORDER,
};
use pyo3::exceptions::{PyKeyboardInterrupt, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict};
use voxlab::experiment::{Override, SceneCache};
use voxlab::frame::{DisplayEncoding, DisplayTransform, Frame};
use voxlab::progress::Watch;
use voxlab::scene::Material;
use voxlab::{Backend, ErrorKind};

pyo3::create_exception!(
    voxlab,
    VoxlabError,
    PyValueError,
    "A voxlab error: the message the command line prints, with `kind`, `file`, `line` and \
     `key` where known."
);

/// A voxlab error as Python sees it: `VoxlabError` with the library's message and
/// location, or `KeyboardInterrupt` for a render stopped by Ctrl-C.
fn to_py(err: voxlab::Error) -> PyErr {
    if err.kind() == ErrorKind::Interrupted {
        return PyKeyboardInterrupt::new_err(err.to_string());
    }
    Python::attach(|py| {
        let e = VoxlabError::new_err(err.to_string());
        let v = e.value(py);
        let kind = format!("{:?}", err.kind()).to_lowercase();
        // Attributes of a fresh exception object: setting them cannot fail.
        let _ = v.setattr("kind", kind);
        let _ = v.setattr("file", err.file());
        let _ = v.setattr("line", err.line());
        let _ = v.setattr("key", err.key());
        e
    })
}

fn err(kind: ErrorKind, message: impl Into<String>) -> PyErr {
    to_py(voxlab::Error::new(kind, message))
}

fn overrides(list: &[String]) -> PyResult<Vec<Override>> {
    list.iter()
        .map(|s| {
            s.parse::<Override>()
                .map_err(|m| err(ErrorKind::Invalid, format!("--set {m}")))
        })
        .collect()
}

/// JSON text (what Python's `json.dumps` makes of a dict) as TOML text.
fn json_to_toml(json: &str, what: &str) -> PyResult<String> {
    let value: serde_json::Value =
        serde_json::from_str(json).map_err(|e| err(ErrorKind::Invalid, format!("{what}: {e}")))?;
    if let Some(key) = first_null(&value, String::new()) {
        return Err(to_py(voxlab::Error::from(
            voxlab::experiment::ExperimentError::Invalid {
                file: what.to_string(),
                line: None,
                key,
                message: ": None has no TOML value (leave the key out for its default)".to_string(),
            },
        )));
    }
    let mut raw = Vec::new();
    let value = toml_of(value, String::new(), json, &mut raw).map_err(|(key, message)| {
        to_py(voxlab::Error::from(
            voxlab::experiment::ExperimentError::Invalid {
                file: what.to_string(),
                line: None,
                key,
                message,
            },
        ))
    })?;
    let text = toml::to_string(&value).map_err(|e| {
        err(
            ErrorKind::Invalid,
            format!("{what}: not expressible as TOML ({e}); None has no TOML value"),
        )
    })?;
    Ok(voxlab::experiment::write_raw(text, &raw))
}

/// What `voxlab._json_text` writes for the floats JSON has no word for and TOML has:
/// the experiment's own checks then name the key and its range.
const NON_FINITE: [(&str, f64); 3] = [
    ("\u{0}voxlab:nan", f64::NAN),
    ("\u{0}voxlab:inf", f64::INFINITY),
    ("\u{0}voxlab:-inf", f64::NEG_INFINITY),
];

/// What `voxlab._json_text` puts before the digits of an integer past 64 bits, which a
/// JSON reader would take as a float.
const BIG_INT: &str = "\u{0}voxlab:int:";

/// `v` as TOML, at the dotted key `at`. An integer TOML cannot hold stands as a mark
/// pushed to `raw` with its digits ([`voxlab::experiment::write_raw`]), so the
/// experiment's parser names its key and range as in a file; `json`, the whole text, is
/// what the marks must not occur in. Nulls are found before (`first_null`).
fn toml_of(
    v: serde_json::Value,
    at: String,
    json: &str,
    raw: &mut Vec<(String, String)>,
) -> Result<toml::Value, (String, String)> {
    use serde_json::Value as J;
    let child = |k: &str| {
        if at.is_empty() {
            k.to_string()
        } else {
            format!("{at}.{k}")
        }
    };
    let mut written_raw = |digits: String| {
        let mark = voxlab::experiment::raw_mark(json, raw.len());
        raw.push((mark.clone(), digits));
        toml::Value::String(mark)
    };
    Ok(match v {
        J::Null => return Err((at, ": None has no TOML value".to_string())),
        J::Bool(b) => toml::Value::Boolean(b),
        J::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) if !n.is_f64() => toml::Value::Integer(i),
            (_, Some(f)) if n.is_f64() => toml::Value::Float(f),
            _ => written_raw(n.to_string()),
        },
        J::String(s) => match NON_FINITE.iter().find(|(mark, _)| *mark == s) {
            Some(&(_, f)) => toml::Value::Float(f),
            None => match s.strip_prefix(BIG_INT) {
                Some(digits) if is_digits(digits) => written_raw(digits.to_string()),
                _ => toml::Value::String(s),
            },
        },
        J::Array(a) => toml::Value::Array(
            a.into_iter()
                .enumerate()
                .map(|(i, v)| toml_of(v, format!("{at}[{i}]"), json, raw))
                .collect::<Result<_, _>>()?,
        ),
        J::Object(m) => toml::Value::Table(
            m.into_iter()
                .map(|(k, v)| {
                    let key = child(&k);
                    Ok::<_, (String, String)>((k, toml_of(v, key, json, raw)?))
                })
                .collect::<Result<_, _>>()?,
        ),
    })
}

/// An optional minus and decimal digits: what Python's `str` writes of an integer.
fn is_digits(s: &str) -> bool {
    let d = s.strip_prefix('-').unwrap_or(s);
    !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit())
}

/// The dotted key of the first `null` in `v` (TOML has none), `lights[1].color` style.
fn first_null(v: &serde_json::Value, at: String) -> Option<String> {
    match v {
        serde_json::Value::Null => Some(at),
        serde_json::Value::Object(m) => m.iter().find_map(|(k, v)| {
            first_null(
                v,
                if at.is_empty() {
                    k.clone()
                } else {
                    format!("{at}.{k}")
                },
            )
        }),
        serde_json::Value::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, v)| first_null(v, format!("{at}[{i}]"))),
        _ => None,
    }
}

/// The voxels a user gave, with their palette, kept so that an experiment re-read with
/// new overrides keeps them.
#[derive(Clone)]
struct UserGrid {
    grid: voxlab::Grid,
    palette: Vec<Material>,
}

/// An experiment: the parsed file (or text, or dict) with its overrides.
#[pyclass(module = "voxlab", name = "Experiment", frozen)]
struct Experiment {
    inner: Arc<voxlab::Experiment>,
    text: String,
    /// What names the text in messages; the file's path when read from one.
    path: PathBuf,
    from_file: bool,
    overrides: Vec<Override>,
    grid: Option<UserGrid>,
    cache: Mutex<SceneCache>,
}

impl Experiment {
    fn parse(
        text: String,
        path: PathBuf,
        from_file: bool,
        overrides: Vec<Override>,
        grid: Option<UserGrid>,
        mut cache: SceneCache,
    ) -> PyResult<Self> {
        let mut e = voxlab::Experiment::from_str_with_cache(&text, &path, &overrides, &mut cache)
            .map_err(|e| to_py(e.into()))?;
        if from_file {
            e.set_source(&path, &text, &overrides)
                .map_err(|e| to_py(e.into()))?;
        }
        if let Some(g) = &grid {
            e.set_grid(g.grid.clone(), g.palette.clone())
                .map_err(to_py)?;
        }
        Ok(Self {
            inner: Arc::new(e),
            text,
            path,
            from_file,
            overrides,
            grid,
            cache: Mutex::new(cache),
        })
    }

    fn take_cache(&self) -> SceneCache {
        self.cache
            .lock()
            .map(|mut c| std::mem::take(&mut *c))
            .unwrap_or_default()
    }
}

#[pymethods]
impl Experiment {
    /// The experiment with more `KEY=VALUE` overrides (after its own), re-read and
    /// checked as `--set` is.
    fn with_overrides(&self, set: Vec<String>) -> PyResult<Self> {
        let mut all = self.overrides.clone();
        all.extend(overrides(&set)?);
        Self::parse(
            self.text.clone(),
            self.path.clone(),
            self.from_file,
            all,
            self.grid.clone(),
            self.take_cache(),
        )
    }

    /// The experiment with its voxels and palette replaced by `grid`'s.
    fn with_grid(&self, grid: &Grid) -> PyResult<Self> {
        Self::parse(
            self.text.clone(),
            self.path.clone(),
            self.from_file,
            self.overrides.clone(),
            Some(UserGrid {
                grid: grid.grid.clone(),
                palette: grid.palette.clone(),
            }),
            self.take_cache(),
        )
    }

    #[getter]
    fn name(&self) -> String {
        self.inner.name.clone()
    }

    /// The file's `description` key, as its records keep it; None without one.
    #[getter]
    fn description(&self) -> Option<String> {
        self.inner.description.clone()
    }

    /// Text without a file (`voxlab.load` of text or a dict, the grid its own): the text
    /// as given, before its overrides, and its label; `None` otherwise. What `ablate`
    /// sweeps when there is no file to read.
    fn _text_source(&self) -> Option<(String, String)> {
        (!self.from_file && self.grid.is_none())
            .then(|| (self.text.clone(), self.path.display().to_string()))
    }

    #[getter]
    fn source(&self) -> Option<String> {
        self.inner
            .source_path
            .as_ref()
            .map(|p| p.display().to_string())
    }

    /// Whether the file it was read from holds other text now (or cannot be read): a
    /// command that reads the file again (ablate) would not run this experiment.
    fn _source_changed(&self) -> bool {
        self.from_file
            && voxlab::experiment::read_text(&self.path).ok().as_ref() != Some(&self.text)
    }

    #[getter]
    fn overrides(&self) -> Vec<String> {
        self.overrides.iter().map(|o| o.to_string()).collect()
    }

    #[getter]
    fn width(&self) -> u32 {
        self.inner.settings.width
    }

    #[getter]
    fn height(&self) -> u32 {
        self.inner.settings.height
    }

    #[getter]
    fn spp(&self) -> u32 {
        self.inner.settings.spp
    }

    #[getter]
    fn shadow_model(&self) -> &'static str {
        self.inner.settings.features.shadow_model.name
    }

    /// The scene's voxels and palette.
    #[getter]
    fn grid(&self) -> Grid {
        Grid {
            grid: self.inner.scene.grid.clone(),
            palette: self.inner.scene.materials.clone(),
        }
    }

    /// Writes the scene for Mitsuba 3 into `dir` (`voxlab export --to mitsuba`): all or
    /// nothing, never over the experiment's inputs. Returns the approximations made, as
    /// (key, mapping) pairs; with `strict`, any approximation is an error.
    #[pyo3(signature = (dir, strict=false))]
    fn export_mitsuba(
        &self,
        py: Python<'_>,
        dir: PathBuf,
        strict: bool,
    ) -> PyResult<Vec<(String, String)>> {
        let text = voxlab::experiment::apply_overrides(&self.text, &self.overrides)
            .map_err(|e| to_py(e.into()))?;
        let inner = Arc::clone(&self.inner);
        let scene = py
            .detach(move || voxlab::export::write_mitsuba(&inner, &text, &dir, strict))
            .map_err(to_py)?;
        Ok(scene
            .approximations
            .into_iter()
            .map(|a| (a.key, a.mapping))
            .collect())
    }

    /// The plan both tracers follow for this experiment, as `render --check` prints it.
    #[getter]
    fn plan(&self) -> String {
        voxlab::plan::Plan::new(&self.inner.scene, &self.inner.settings).to_string()
    }

    fn __repr__(&self) -> String {
        format!(
            "Experiment({:?}, {}x{}, spp {}, shadow_model {:?})",
            self.inner.name,
            self.inner.settings.width,
            self.inner.settings.height,
            self.inner.settings.spp,
            self.inner.settings.features.shadow_model.name
        )
    }
}

/// An experiment file, with `KEY=VALUE` overrides.
#[pyfunction]
fn load_path(path: PathBuf, set: Vec<String>) -> PyResult<Experiment> {
    let text = voxlab::experiment::read_text(&path).map_err(|e| to_py(e.into()))?;
    Experiment::parse(text, path, true, overrides(&set)?, None, SceneCache::new())
}

/// Experiment text; `name` names it in messages (and gives the experiment's name).
#[pyfunction]
fn load_text(text: String, name: String, set: Vec<String>) -> PyResult<Experiment> {
    Experiment::parse(
        text,
        PathBuf::from(name),
        false,
        overrides(&set)?,
        None,
        SceneCache::new(),
    )
}

/// JSON text of an experiment as a dict, converted to TOML and read as `load_text`.
#[pyfunction]
fn load_json(json: String, name: String, set: Vec<String>) -> PyResult<Experiment> {
    let text = json_to_toml(&json, &name)?;
    load_text(text, name, set)
}

/// A grid of voxels (material indices) with its palette.
#[pyclass(module = "voxlab", name = "Grid", frozen)]
struct Grid {
    grid: voxlab::Grid,
    palette: Vec<Material>,
}

#[pymethods]
impl Grid {
    /// From an integer array of material indices indexed `[x, y, z]` (y up; any dtype
    /// whose values fit 0..=255, any strides); `palette` a list of material dicts (the
    /// keys of `[[materials]]`, entry i is material i + 1), or the seed's palette.
    #[staticmethod]
    #[pyo3(signature = (materials, palette=None, voxel_size=1.0, origin=(0.0, 0.0, 0.0)))]
    fn from_numpy(
        py: Python<'_>,
        materials: &Bound<'_, PyAny>,
        palette: Option<&Bound<'_, PyAny>>,
        voxel_size: f64,
        origin: (f64, f64, f64),
    ) -> PyResult<Self> {
        let np = py.import("numpy")?;
        let array = np.call_method1("asarray", (materials,))?;
        let ndim: usize = array.getattr("ndim")?.extract()?;
        if ndim != 3 {
            let shape = array.getattr("shape")?.repr()?.to_string();
            return Err(err(
                ErrorKind::Invalid,
                format!("materials: shape {shape}; a grid is a 3D array indexed [x, y, z]"),
            ));
        }
        let kind: String = array.getattr("dtype")?.getattr("kind")?.extract()?;
        let array = if array
            .getattr("dtype")?
            .getattr("name")?
            .extract::<String>()?
            == "uint8"
        {
            array
        } else if (kind == "i" || kind == "u" || kind == "b")
            && array.getattr("size")?.extract::<usize>()? > 0
        {
            let lo: i128 = array.call_method0("min")?.call_method0("item")?.extract()?;
            let hi: i128 = array.call_method0("max")?.call_method0("item")?.extract()?;
            if lo < 0 || hi > 255 {
                return Err(err(
                    ErrorKind::Invalid,
                    format!("materials: values {lo}..={hi}; material indices are 0..=255 (0 void)"),
                ));
            }
            array.call_method1("astype", (np.getattr("uint8")?,))?
        } else if kind == "i" || kind == "u" || kind == "b" {
            array.call_method1("astype", (np.getattr("uint8")?,))?
        } else {
            let name: String = array.getattr("dtype")?.getattr("name")?.extract()?;
            return Err(err(
                ErrorKind::Invalid,
                format!("materials: dtype {name}; material indices are integers 0..=255"),
            ));
        };
        let palette_toml = match palette {
            None => None,
            Some(p) if p.is_none() => None,
            Some(p) => {
                let doc = PyDict::new(py);
                doc.set_item("materials", p)?;
                let json: String = py
                    .import("voxlab")?
                    .call_method1("_json_text", (doc,))
                    .map_err(|e| err(ErrorKind::Invalid, format!("palette: {e}")))?
                    .extract()?;
                Some(json_to_toml(&json, "palette")?)
            }
        };
        let materials: PyReadonlyArray3<'_, u8> = array.extract()?;
        let view = materials.as_array();
        let shape = view.shape();
        let dims = [shape[0], shape[1], shape[2]];
        if dims.iter().any(|&d| d > u32::MAX as usize) {
            return Err(err(
                ErrorKind::Scene,
                format!("grid shape {dims:?}: every side must be below 2^32"),
            ));
        }
        let palette = match &palette_toml {
            Some(text) => voxlab::experiment::palette_from_str(text, "palette")
                .map_err(|e| to_py(e.into()))?,
            None => voxlab::scene::seed_palette(),
        };
        let mut grid = voxlab::Grid::new(
            UVec3::new(dims[0] as u32, dims[1] as u32, dims[2] as u32),
            voxel_size,
            DVec3::new(origin.0, origin.1, origin.2),
        )
        .map_err(|e| err(ErrorKind::Scene, e.0))?;
        // The grid stores x fastest: the reversed axes' logical order.
        let reversed = view.reversed_axes();
        for (dst, &src) in grid.data_mut().iter_mut().zip(reversed.iter()) {
            *dst = src;
        }
        let max = grid.max_material() as usize;
        if max >= palette.len() {
            let counts = grid.material_counts();
            let first = (palette.len()..256).find(|&m| counts[m] > 0).unwrap_or(max);
            return Err(err(
                ErrorKind::Scene,
                format!(
                    "the array holds material {first} ({} voxels) but the palette defines \
                     0..={} (0 void)",
                    counts[first],
                    palette.len() - 1
                ),
            ));
        }
        Ok(Self { grid, palette })
    }

    /// The voxels as a uint8 array indexed `[x, y, z]`, Fortran-ordered (x fastest,
    /// as the grid holds them).
    fn to_numpy<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<u8>>> {
        let dense = self
            .grid
            .to_dense()
            .map_err(|e| err(ErrorKind::Scene, e.0))?;
        // A sparse grid's dense copy is handed to numpy as it is, not copied again: one
        // copy of the voxels either way.
        let voxels = match dense {
            std::borrow::Cow::Borrowed(g) => g.data().to_vec(),
            std::borrow::Cow::Owned(g) => g
                .into_dense()
                .ok_or_else(|| err(ErrorKind::Scene, "the grid's dense copy is not dense"))?,
        };
        let d = self.grid.dims();
        PyArray1::from_vec(py, voxels).reshape_with_order(
            [d.x as usize, d.y as usize, d.z as usize],
            NPY_ORDER::NPY_FORTRANORDER,
        )
    }

    /// The material of voxel `(x, y, z)`; 0 (void) outside the grid.
    fn get(&self, x: i64, y: i64, z: i64) -> u8 {
        let c = |v: i64| v.clamp(-1, i64::from(i32::MAX)) as i32;
        self.grid.get(glam::IVec3::new(c(x), c(y), c(z)))
    }

    #[getter]
    fn shape(&self) -> (u32, u32, u32) {
        let d = self.grid.dims();
        (d.x, d.y, d.z)
    }

    #[getter]
    fn voxel_size(&self) -> f64 {
        self.grid.voxel_size()
    }

    #[getter]
    fn origin(&self) -> (f64, f64, f64) {
        self.grid.origin().into()
    }

    /// The palette's material names, index 0 (void) first.
    #[getter]
    fn palette(&self) -> Vec<String> {
        self.palette.iter().map(|m| m.name.clone()).collect()
    }

    /// The blake3 hash of the voxels, as image records give it.
    #[getter]
    fn blake3(&self) -> String {
        self.grid.content_hash().to_hex().to_string()
    }

    fn __repr__(&self) -> String {
        let d = self.grid.dims();
        format!(
            "Grid({}x{}x{}, voxel_size {}, {} materials)",
            d.x,
            d.y,
            d.z,
            self.grid.voxel_size(),
            self.palette.len()
        )
    }
}

/// One tracer kept open across renders.
#[pyclass(module = "voxlab", name = "Session", subclass)]
struct Session {
    inner: voxlab::Session,
}

#[pymethods]
impl Session {
    #[new]
    fn new(backend: &str) -> PyResult<Self> {
        let backend = match backend {
            "gpu" => Backend::Gpu,
            "cpu" => Backend::Cpu,
            other => {
                return Err(err(
                    ErrorKind::Invalid,
                    format!("backend {other:?}: must be \"gpu\" or \"cpu\""),
                ));
            }
        };
        Ok(Self {
            inner: voxlab::Session::new(backend).map_err(to_py)?,
        })
    }

    /// The backend and adapter, as reports name them.
    #[getter]
    fn label(&self) -> String {
        self.inner.label()
    }

    /// Renders `experiment` on a worker thread with the GIL released (see
    /// [`run_watched`]: Ctrl-C stops it, `progress(done, total)` is called).
    #[pyo3(signature = (experiment, progress=None))]
    fn render(
        &mut self,
        py: Python<'_>,
        experiment: &Experiment,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Image> {
        let e = experiment.inner.clone();
        let session = &mut self.inner;
        let mut image = run_watched(py, progress.as_ref(), |watch| {
            session.render_watched(&e, watch)
        })?;
        let (w, h) = (image.width() as usize, image.height() as usize);
        let pixels = std::mem::take(&mut image.frame.pixels);
        let radiance = PyArray1::from_vec(py, flatten(pixels)).reshape([h, w, 3])?;
        Ok(Image {
            radiance: radiance.unbind(),
            meta: image,
            experiment: e,
            overrides: experiment.overrides.clone(),
            provenance: OnceLock::new(),
        })
    }

    fn __repr__(&self) -> String {
        format!("Session({:?})", self.inner.label())
    }
}

/// Runs `work` on a worker thread with the GIL released. Every 50 ms the calling
/// thread checks for signals (Ctrl-C asks `work`'s [`Watch`] to stop, and
/// KeyboardInterrupt is raised once it has) and calls `progress(done, total)` (an
/// exception it raises stops the work too, and is raised); at the end `progress(total,
/// total)`.
fn run_watched<T: Send>(
    py: Python<'_>,
    progress: Option<&Py<PyAny>>,
    work: impl FnOnce(&Arc<Watch>) -> voxlab::Result<T> + Send,
) -> PyResult<T> {
    let watch = Watch::new();
    let slot: Arc<(Mutex<Option<voxlab::Result<T>>>, Condvar)> = Arc::default();
    let mut stop_reason: Option<PyErr> = None;
    let outcome = std::thread::scope(|s| {
        let (worker_watch, worker_slot) = (watch.clone(), slot.clone());
        s.spawn(move || {
            let result =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| work(&worker_watch)))
                    .unwrap_or_else(|_| {
                        Err(voxlab::Error::new(
                            ErrorKind::Other,
                            "voxlab panicked (a bug: please report it)",
                        ))
                    });
            let (lock, ready) = &*worker_slot;
            if let Ok(mut r) = lock.lock() {
                *r = Some(result);
            }
            ready.notify_all();
        });
        loop {
            let done = py.detach(|| {
                let (lock, ready) = &*slot;
                let guard = lock.lock().ok()?;
                let (mut guard, _) = ready
                    .wait_timeout_while(guard, Duration::from_millis(50), |r| r.is_none())
                    .ok()?;
                guard.take()
            });
            if let Some(r) = done {
                return r;
            }
            if stop_reason.is_none() {
                if let Err(e) = py.check_signals() {
                    watch.stop();
                    stop_reason = Some(e);
                } else if let Some(cb) = progress {
                    let (d, t) = watch.done();
                    if let Err(e) = cb.call1(py, (d, t)) {
                        watch.stop();
                        stop_reason = Some(e);
                    }
                }
            }
        }
    });
    if let Some(reason) = stop_reason {
        return Err(reason);
    }
    let value = outcome.map_err(to_py)?;
    if let Some(cb) = progress {
        let (_, t) = watch.done();
        cb.call1(py, (t, t))?;
    }
    Ok(value)
}

/// `[r, g, b]` pixels as one flat vector, without a copy where the allocator allows.
fn flatten(pixels: Vec<[f32; 3]>) -> Vec<f32> {
    bytemuck::allocation::try_cast_vec(pixels)
        .unwrap_or_else(|(_, pixels)| pixels.into_iter().flatten().collect())
}

/// A rendered image and what made it.
#[pyclass(module = "voxlab", name = "Image", frozen)]
struct Image {
    radiance: Py<PyArray3<f32>>,
    /// The library's image, its pixels moved into `radiance`.
    meta: voxlab::Image,
    experiment: Arc<voxlab::Experiment>,
    overrides: Vec<Override>,
    provenance: OnceLock<serde_json::Value>,
}

impl Image {
    fn frame(&self, py: Python<'_>) -> PyResult<Frame> {
        let a = self.radiance.bind(py).readonly();
        let data = a.as_slice()?;
        Ok(Frame {
            width: self.meta.width(),
            height: self.meta.height(),
            pixels: data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        })
    }

    fn record(&self, py: Python<'_>) -> PyResult<&serde_json::Value> {
        if let Some(p) = self.provenance.get() {
            return Ok(p);
        }
        let finite = self
            .radiance
            .bind(py)
            .readonly()
            .as_slice()?
            .iter()
            .all(|c| c.is_finite());
        let mut p = self
            .meta
            .provenance(
                &self.experiment,
                &self.overrides,
                DisplayTransform::default(),
                None,
            )
            .map_err(to_py)?;
        // The library's image gave its pixels to the array: the record's check is the
        // array's.
        p["finite"] = finite.into();
        Ok(self.provenance.get_or_init(|| p))
    }
}

#[pymethods]
impl Image {
    /// Linear radiance, float32, shape (height, width, 3), row 0 at the top.
    #[getter]
    fn radiance<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f32>> {
        self.radiance.bind(py).clone()
    }

    /// The record `voxlab render --json` prints (and stores beside a saved image), as a
    /// dict.
    #[getter]
    fn provenance<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let text = serde_json::to_string(self.record(py)?)
            .map_err(|e| err(ErrorKind::Other, e.to_string()))?;
        py.import("json")?.call_method1("loads", (text,))
    }

    /// Rays and voxel steps, counted by the tracer: primary, secondary, shadow,
    /// voxel_steps, and untraced (the secondary rays counted without being traced: they
    /// leave the grid where they start).
    #[getter]
    fn rays<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.meta.stats;
        let d = PyDict::new(py);
        d.set_item("primary", s.primary)?;
        d.set_item("secondary", s.secondary)?;
        d.set_item("shadow", s.shadow)?;
        d.set_item("voxel_steps", s.voxel_steps)?;
        d.set_item("untraced", s.untraced)?;
        Ok(d)
    }

    #[getter]
    fn width(&self) -> u32 {
        self.meta.width()
    }

    #[getter]
    fn height(&self) -> u32 {
        self.meta.height()
    }

    fn __repr__(&self) -> String {
        format!(
            "Image({}x{}, {} frames, {:.3} ms, {})",
            self.meta.width(),
            self.meta.height(),
            self.meta.frames,
            self.meta.trace_time.as_secs_f64() * 1e3,
            self.meta.backend
        )
    }

    /// The trace: device time where the GPU has timestamp queries, else wall time.
    #[getter]
    fn time_ms(&self) -> f64 {
        self.meta.trace_time.as_secs_f64() * 1e3
    }

    #[getter]
    fn setup_ms(&self) -> f64 {
        self.meta.setup_time.as_secs_f64() * 1e3
    }

    /// The whole library call.
    #[getter]
    fn wall_ms(&self) -> f64 {
        self.meta.wall_time.as_secs_f64() * 1e3
    }

    #[getter]
    fn timer(&self) -> &'static str {
        self.meta.timer
    }

    #[getter]
    fn frames(&self) -> u32 {
        self.meta.frames
    }

    #[getter]
    fn plan(&self) -> String {
        self.meta.plan.to_string()
    }

    /// Where the GPU kernel may part from the f64 reference on this scene (a
    /// `render.ray_offset` below what its f32 resolves): empty on the CPU and at
    /// settings it resolves.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.meta.plan.warnings.clone()
    }

    #[getter]
    fn backend(&self) -> String {
        self.meta.backend.clone()
    }

    /// Writes the image (`.png`: 8 bits with `display` and `exposure`; `.exr`: linear)
    /// with its record inside and beside it (`<path>.json`), all or nothing.
    #[pyo3(signature = (path, display="linear", exposure=0.0))]
    fn save(&self, py: Python<'_>, path: PathBuf, display: &str, exposure: f64) -> PyResult<()> {
        let encoding = match display {
            "linear" => DisplayEncoding::Linear,
            "srgb" => DisplayEncoding::Srgb,
            other => {
                return Err(err(
                    ErrorKind::Invalid,
                    format!("display {other:?}: must be \"linear\" or \"srgb\""),
                ));
            }
        };
        DisplayTransform::check_exposure(exposure).map_err(|e| err(ErrorKind::Invalid, e))?;
        let transform = DisplayTransform { encoding, exposure };
        let mut record = self
            .meta
            .provenance(&self.experiment, &self.overrides, transform, Some(&path))
            .map_err(to_py)?;
        let frame = self.frame(py)?;
        record["finite"] = frame.all_finite().into();
        let image = voxlab::Image {
            frame,
            ..self.meta.clone()
        };
        py.detach(|| image.save(&path, &record, transform))
            .map_err(to_py)
    }
}

fn frame_of(a: &PyReadonlyArray3<'_, f32>, what: &str) -> PyResult<Frame> {
    let shape = a.shape();
    if shape[2] != 3 || shape[0] == 0 || shape[1] == 0 {
        return Err(err(
            ErrorKind::Invalid,
            format!("{what}: shape {shape:?}; an image is (height, width, 3)"),
        ));
    }
    let view = a.as_array();
    let pixels = view
        .lanes(Axis(2))
        .into_iter()
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    Ok(Frame {
        width: shape[1] as u32,
        height: shape[0] as u32,
        pixels,
    })
}

fn same_size(a: &Frame, b: &Frame) -> PyResult<()> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(err(
            ErrorKind::Invalid,
            format!(
                "images of different sizes: {}x{} and {}x{}",
                a.width, a.height, b.width, b.height
            ),
        ));
    }
    Ok(())
}

/// Root-mean-square difference of two linear images, over every channel.
#[pyfunction]
fn rmse(a: PyReadonlyArray3<'_, f32>, b: PyReadonlyArray3<'_, f32>) -> PyResult<f64> {
    let (a, b) = (frame_of(&a, "a")?, frame_of(&b, "b")?);
    same_size(&a, &b)?;
    voxlab::metrics::compare(&a, &b, voxlab::metrics::Domain::Linear, 0.0)
        .map(|d| d.rmse)
        .ok_or_else(|| err(ErrorKind::Invalid, "images of different sizes"))
}

/// FLIP of `test` against `reference` at `ppd` pixels per degree: the mean and the map
/// (height, width), float32 in [0, 1].
#[pyfunction]
fn flip<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray3<'py, f32>,
    test: PyReadonlyArray3<'py, f32>,
    ppd: f32,
) -> PyResult<(f64, Bound<'py, numpy::PyArray2<f32>>)> {
    if !(ppd.is_finite() && ppd > 0.0 && ppd <= 1e4) {
        return Err(err(
            ErrorKind::Invalid,
            format!("ppd {ppd}: must be pixels per degree in (0, 10000]"),
        ));
    }
    let (r, t) = (frame_of(&reference, "reference")?, frame_of(&test, "test")?);
    same_size(&r, &t)?;
    let (mean, map) = py.detach(|| voxlab::metrics::flip_at(&r, &t, ppd));
    let map = PyArray1::from_vec(py, map).reshape([r.height as usize, r.width as usize])?;
    Ok((mean, map))
}

/// The registry of techniques as JSON text (`voxlab techniques --json`).
#[pyfunction]
fn techniques_json() -> String {
    voxlab::technique::listing_json().to_string()
}

/// Every declared number of an experiment file as JSON text (`voxlab settings --json`).
#[pyfunction]
fn settings_json() -> String {
    voxlab::settings::listing_json().to_string()
}

/// FLIP's default viewing distance, pixels per degree (the one ablate uses).
#[pyfunction]
fn flip_default_ppd() -> f32 {
    voxlab::metrics::FLIP_PPD
}

/// An ablate sweep's experiment: the file at `path`, or `text` named by `path` (Python's
/// text and dicts; `Experiment._text_source`).
fn load_ablate(
    path: &std::path::Path,
    text: Option<&str>,
    set: &[Override],
) -> Result<(voxlab::Experiment, voxlab::ablate::AblateConfig, String), voxlab::Error> {
    Ok(match text {
        Some(t) => voxlab::ablate::load_text_with(t, path, set)?,
        None => voxlab::ablate::load_with(path, set)?,
    })
}

/// Runs `voxlab ablate` on an experiment file (its `[ablate]` table) on a worker thread
/// (Ctrl-C stops it between renders): the files it wrote, relative to `out`.
#[pyfunction]
#[pyo3(signature = (path, set, out, cache=None, progress=None, resume=false, text=None))]
#[allow(clippy::too_many_arguments)]
fn ablate(
    py: Python<'_>,
    path: PathBuf,
    set: Vec<String>,
    out: PathBuf,
    cache: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
    resume: bool,
    text: Option<String>,
) -> PyResult<Vec<String>> {
    let set = overrides(&set)?;
    run_watched(py, progress.as_ref(), |watch| {
        let (e, config, source) = load_ablate(&path, text.as_deref(), &set)?;
        let opts = voxlab::ablate::AblateOptions {
            out_dir: out,
            out_option: "out",
            cache_dir: cache,
            progress: false,
            log: false,
            watch: Some(watch.clone()),
            resume,
        };
        let report = voxlab::ablate::run(&e, &config, Some(&source), &opts);
        match report {
            Ok(r) => Ok(r.files),
            Err(_) if watch.stopped() => Err(voxlab::Error::new(
                ErrorKind::Interrupted,
                "ablate stopped on request",
            )),
            Err(err) => Err(err.into()),
        }
    })
}

/// A sweep spread over other processes: the driver's side (`voxlab.distributed`). It
/// lists the tasks still to do, takes their encoded outputs, and writes what `ablate`
/// writes; the references and the points done are kept in its cache directory (the
/// workers never touch it).
#[pyclass(module = "voxlab", name = "AblateDriver")]
struct AblateDriver {
    inner: Option<voxlab::ablate::tasks::Driver>,
}

impl AblateDriver {
    fn driver(&mut self) -> PyResult<&mut voxlab::ablate::tasks::Driver> {
        self.inner
            .as_mut()
            .ok_or_else(|| err(ErrorKind::Other, "this sweep has finished already"))
    }
}

#[pymethods]
impl AblateDriver {
    /// `reference_label`: the reference's renderer as a worker names it
    /// (`AblateWorker.reference_label`), part of its cache key.
    #[new]
    #[pyo3(signature = (path, set, out, reference_label, cache=None, resume=false, text=None))]
    fn new(
        path: PathBuf,
        set: Vec<String>,
        out: PathBuf,
        reference_label: &str,
        cache: Option<PathBuf>,
        resume: bool,
        text: Option<String>,
    ) -> PyResult<Self> {
        let set = overrides(&set)?;
        let (e, c, source) = load_ablate(&path, text.as_deref(), &set).map_err(to_py)?;
        let opts = voxlab::ablate::AblateOptions {
            out_dir: out,
            out_option: "out",
            cache_dir: cache,
            progress: false,
            log: false,
            watch: None,
            resume,
        };
        let d = voxlab::ablate::tasks::Driver::new(&e, &c, Some(&source), &opts, reference_label)
            .map_err(|e| to_py(e.into()))?;
        Ok(Self { inner: Some(d) })
    }

    /// The tasks still to do as JSON (`{"kind": "reference-tile", "reference", "half",
    /// "rows": [start, end]}` or `{"kind": "point", "index"}`), each reference half in
    /// `bands` bands of rows.
    fn tasks(&mut self, bands: u32) -> PyResult<Vec<String>> {
        let d = self.driver()?;
        Ok(d.tasks(bands)
            .iter()
            .map(|t| serde_json::to_string(t).expect("a task serialises"))
            .collect())
    }

    /// Points taken from the cache (`resume`).
    #[getter]
    fn resumed(&mut self) -> PyResult<usize> {
        Ok(self.driver()?.resumed)
    }

    /// Points in the sweep.
    #[getter]
    fn points(&mut self) -> PyResult<usize> {
        Ok(self.driver()?.schedule.points.len())
    }

    /// What a task is, as the progress names it.
    fn describe(&mut self, task: &str) -> PyResult<String> {
        let d = self.driver()?;
        let t: voxlab::ablate::tasks::Task = serde_json::from_str(task)
            .map_err(|e| err(ErrorKind::Invalid, format!("task {task:?}: {e}")))?;
        Ok(match t {
            voxlab::ablate::tasks::Task::Point { index } => d
                .schedule
                .points
                .get(index)
                .map_or_else(|| format!("point {index}"), |p| p.label()),
            voxlab::ablate::tasks::Task::ReferenceTile { half, rows, .. } => {
                format!("reference half {half}, rows {}..{}", rows[0], rows[1])
            }
        })
    }

    /// Takes a task's encoded output (`AblateWorker.run`'s bytes).
    fn put(&mut self, py: Python<'_>, output: &[u8]) -> PyResult<()> {
        let d = self.driver()?;
        py.detach(|| {
            let out = voxlab::ablate::tasks::TaskOutput::decode(output)?;
            d.put(out)
        })
        .map_err(|e| to_py(e.into()))
    }

    /// Measures every point and writes the outputs: the files written, relative to
    /// `out`. `adapter` names the workers' adapters for the run's record.
    fn finish(&mut self, py: Python<'_>, adapter: &str) -> PyResult<Vec<String>> {
        let d = self
            .inner
            .take()
            .ok_or_else(|| err(ErrorKind::Other, "this sweep has finished already"))?;
        let report = py
            .detach(|| d.finish(adapter))
            .map_err(|e| to_py(e.into()))?;
        Ok(report.files)
    }
}

/// A sweep's worker: one tracer kept open across tasks (its pipelines compile once),
/// the experiment read from `path` with `set` as the driver read it.
#[pyclass(module = "voxlab", name = "AblateWorker")]
struct AblateWorker {
    worker: voxlab::ablate::tasks::Worker,
    e: voxlab::Experiment,
    c: voxlab::ablate::AblateConfig,
    schedule: voxlab::ablate::tasks::Schedule,
}

#[pymethods]
impl AblateWorker {
    /// `cpu_only`: no GPU is opened (a worker for the CPU reference's bands).
    #[new]
    #[pyo3(signature = (path, set, cpu_only=false, text=None))]
    fn new(
        py: Python<'_>,
        path: PathBuf,
        set: Vec<String>,
        cpu_only: bool,
        text: Option<String>,
    ) -> PyResult<Self> {
        let set = overrides(&set)?;
        py.detach(|| {
            let (e, c, _) = load_ablate(&path, text.as_deref(), &set)?;
            let worker = if cpu_only {
                voxlab::ablate::tasks::Worker::cpu()
            } else {
                voxlab::ablate::tasks::Worker::new(&c)?
            };
            let schedule = voxlab::ablate::tasks::Schedule::new(&e, &c);
            Ok::<_, voxlab::Error>(Self {
                worker,
                e,
                c,
                schedule,
            })
        })
        .map_err(to_py)
    }

    /// The adapter the rows this worker renders record.
    #[getter]
    fn adapter(&self) -> String {
        self.worker.adapter()
    }

    /// The points' backend as `[ablate] backend` asks: `auto`, `gpu` or `cpu`.
    #[getter]
    fn backend(&self) -> &'static str {
        self.c.backend.name()
    }

    /// `[ablate] reference_backend`: `cpu` or `gpu`.
    #[getter]
    fn reference_backend(&self) -> &'static str {
        self.c.reference_backend.name()
    }

    /// The reference's renderer as its cache key names it.
    #[getter]
    fn reference_label(&self) -> String {
        self.worker.reference_label(&self.c)
    }

    /// Does a task (`AblateDriver.tasks`' JSON) with the GIL released: its encoded output.
    fn run<'py>(&mut self, py: Python<'py>, task: &str) -> PyResult<Bound<'py, PyBytes>> {
        let t: voxlab::ablate::tasks::Task = serde_json::from_str(task)
            .map_err(|e| err(ErrorKind::Invalid, format!("task {task:?}: {e}")))?;
        let Self {
            worker,
            e,
            c,
            schedule,
        } = self;
        let bytes = py
            .detach(|| worker.run(e, c, schedule, &t).map(|o| o.encode()))
            .map_err(|e| to_py(e.into()))?;
        Ok(PyBytes::new(py, &bytes))
    }
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("VoxlabError", m.py().get_type::<VoxlabError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<Experiment>()?;
    m.add_class::<Grid>()?;
    m.add_class::<Session>()?;
    m.add_class::<Image>()?;
    m.add_class::<AblateDriver>()?;
    m.add_class::<AblateWorker>()?;
    m.add_function(wrap_pyfunction!(load_path, m)?)?;
    m.add_function(wrap_pyfunction!(load_text, m)?)?;
    m.add_function(wrap_pyfunction!(load_json, m)?)?;
    m.add_function(wrap_pyfunction!(rmse, m)?)?;
    m.add_function(wrap_pyfunction!(flip, m)?)?;
    m.add_function(wrap_pyfunction!(flip_default_ppd, m)?)?;
    m.add_function(wrap_pyfunction!(techniques_json, m)?)?;
    m.add_function(wrap_pyfunction!(settings_json, m)?)?;
    m.add_function(wrap_pyfunction!(ablate, m)?)?;
    Ok(())
}
