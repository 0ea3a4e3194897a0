"""voxlab from Python: ray tracing in voxel space.

    import voxlab as vx

    exp = vx.load("experiments/area_lights.toml", set={"render.width": 128, "render.height": 128})
    session = vx.Session("gpu")            # one device, its pipelines kept across renders
    image = session.render(exp, spp=8)     # image.radiance: float32 (H, W, 3), linear
    hard = session.render(exp, set={"features.shadow_model": "hard"})
    print(vx.rmse(image.radiance, hard.radiance), image.provenance["plan"])

The TOML experiment files stay the record: `load` reads them with the command line's
parser and checks, and every error is a `VoxlabError` (a `ValueError`) with the
command line's message, file, line and key. The native module (`voxlab._native`, built
from python/src/lib.rs) holds the library; this layer turns dicts into TOML values,
drives tqdm and pandas when they are installed, and reads ablation tables.
"""

from __future__ import annotations

import csv
import json
import math
import os
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, NamedTuple, Optional, Union

import numpy as np

from . import _native
from ._native import Experiment, Grid, Image, VoxlabError

__version__ = _native.__version__

__all__ = [
    "Experiment",
    "Grid",
    "Image",
    "Session",
    "VoxlabError",
    "AblateResult",
    "load",
    "rmse",
    "flip",
    "settings",
    "techniques",
    "ablate",
]

PathLike = Union[str, "os.PathLike[str]"]


def _error(message: str, key: Optional[str] = None) -> VoxlabError:
    e = VoxlabError(message)
    e.kind, e.file, e.line, e.key = "invalid", None, None, key
    return e


class _RawToml(str):
    """A `--set` value as typed on a command line (`python -m voxlab`): TOML text,
    passed through unchanged and checked by the parser."""


def _toml_value(key: str, v: Any) -> str:
    """A Python value as a TOML literal, for `--set KEY=VALUE`."""
    if isinstance(v, _RawToml):
        return str(v)
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        # A JSON string is a TOML basic string (the same escapes, \uXXXX included).
        return json.dumps(v)
    if isinstance(v, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(key, x) for x in list(v)) + "]"
    raise _error(f"--set {key}: a {type(v).__name__} has no TOML value", key)


# JSON has no NaN or infinity and TOML has: they cross to python/src/lib.rs as these
# strings (its NON_FINITE), which it writes as TOML's nan and inf, so that the
# experiment's own check names the key and its range ("must be a finite number in
# [0, 1]") rather than the JSON encoder refusing the whole dict.
_NON_FINITE = {"nan": "\x00voxlab:nan", "inf": "\x00voxlab:inf", "-inf": "\x00voxlab:-inf"}
_BIG_INT = "\x00voxlab:int:"


def _json_text(v: Any) -> str:
    """`v` (dicts, lists, numbers, numpy arrays and scalars) as JSON for the native
    loader, non-finite floats and integers past 64 bits marked."""

    def walk(x: Any) -> Any:
        if isinstance(x, np.ndarray):
            return walk(x.tolist())
        if isinstance(x, np.generic):
            return walk(x.item())
        if isinstance(x, float) and not math.isfinite(x):
            return _NON_FINITE["nan" if math.isnan(x) else "inf" if x > 0 else "-inf"]
        if isinstance(x, int) and not -(2**63) <= x < 2**63:
            # JSON readers take such an integer as a float (2**70 as 1.18e21): marked,
            # it reaches the parser as written, which names its key and range.
            return _BIG_INT + str(x)
        if isinstance(x, Mapping):
            return {k: walk(y) for k, y in x.items()}
        if isinstance(x, (list, tuple)):
            return [walk(y) for y in x]
        return x

    return json.dumps(walk(v), allow_nan=False)


def _overrides(set: Optional[Mapping[str, Any]]) -> list:
    if set is None:
        return []
    if not isinstance(set, Mapping):
        raise _error(f"set: a dict of KEY: VALUE, not a {type(set).__name__}")
    out = []
    for key, value in set.items():
        if not isinstance(key, str):
            raise _error(f"set: key {key!r} is not a string (e.g. 'render.width')")
        out.append(f"{key}={_toml_value(key, value)}")
    return out


def load(
    source: Union[PathLike, str, Mapping[str, Any]],
    set: Optional[Mapping[str, Any]] = None,
    *,
    name: Optional[str] = None,
) -> Experiment:
    """An experiment from a file path, TOML text (any string with a newline or that
    starts with '['), or a dict of the file's tables; `set` overrides keys as the
    command line's `--set` does (`{"render.spp": 8, "features.shadow_model": "sdf"}`).
    `name` names text or a dict in messages (default "<dict>", "<text>") and, unless
    the file gives `name`, the experiment, each character other than A-Z a-z 0-9 - _ .
    as '_' ("_dict_"), as a file's stem does. Raises VoxlabError with the command
    line's message."""
    sets = _overrides(set)
    if isinstance(source, Mapping):
        label = name or "<dict>"
        try:
            text = _json_text(source)
        except (TypeError, ValueError) as e:
            raise _error(f"{label}: {e}") from None
        return _native.load_json(text, label, sets)
    if isinstance(source, os.PathLike):
        return _native.load_path(os.fspath(source), sets)
    if isinstance(source, str):
        if "\n" in source or source.lstrip().startswith("["):
            return _native.load_text(source, name or "<text>", sets)
        return _native.load_path(source, sets)
    raise TypeError(
        f"load(): a path, TOML text or a dict, not a {type(source).__name__}"
    )


class _Bar:
    """A tqdm bar for one render, shown once the render has run for a second (a sweep
    of short renders prints nothing)."""

    def __init__(self, label: str, tqdm: Any):
        self.label, self.tqdm, self.bar = label, tqdm, None
        self.start = time.monotonic()

    def __call__(self, done: int, total: int) -> None:
        if self.bar is None:
            if time.monotonic() - self.start < 1.0 or total == 0:
                return
            self.bar = self.tqdm(total=total, desc=self.label, leave=False)
        self.bar.n = done
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _tqdm() -> Any:
    try:
        from tqdm.auto import tqdm
    except ImportError:
        return None
    return tqdm


def _progress_callback(progress: Any, label: str) -> tuple:
    """(callback, bar to close) for a `progress` argument: a callable as it is, False
    none, None a tqdm bar when tqdm is installed."""
    if callable(progress):
        return progress, None
    if progress is False:
        return None, None
    tqdm = _tqdm()
    if tqdm is None:
        return None, None
    bar = _Bar(label, tqdm)
    return bar, bar


class Session(_native.Session):
    """One tracer kept open across renders: the GPU kernel ("gpu", the first adapter
    wgpu finds) or the f64 CPU reference ("cpu"). Each kernel variant is compiled and
    each scene uploaded once per session."""

    def __new__(cls, backend: str = "gpu") -> "Session":
        return super().__new__(cls, backend)

    def render(
        self,
        experiment: Experiment,
        spp: Optional[int] = None,
        *,
        set: Optional[Mapping[str, Any]] = None,
        progress: Union[bool, Callable[[int, int], Any], None] = None,
    ) -> Image:
        """Renders `experiment` (with `spp` and `set` applied, as `--set` would). The GIL
        is released; Ctrl-C stops the render within a row (CPU) or a dispatch (GPU) and
        raises KeyboardInterrupt. `progress`: None shows a tqdm bar (when tqdm is
        installed) for renders over a second; False none; a callable gets
        (done, total)."""
        if not isinstance(experiment, Experiment):
            raise TypeError(
                f"render(): an Experiment (voxlab.load), not a {type(experiment).__name__}"
            )
        extra = dict(set or {})
        if spp is not None:
            extra["render.spp"] = spp
        if extra:
            experiment = experiment.with_overrides(_overrides(extra))
        callback, bar = _progress_callback(progress, experiment.name)
        try:
            image = super().render(experiment, callback)
        finally:
            if bar is not None:
                bar.close()
        image.radiance.flags.writeable = False
        return image


def _image_array(a: Any, what: str) -> np.ndarray:
    if isinstance(a, Image):
        return a.radiance
    array = np.asarray(a, dtype=np.float32)
    if array.ndim != 3 or array.shape[2] != 3:
        raise _error(f"{what}: shape {array.shape}; an image is (height, width, 3)")
    return array


def rmse(a: Any, b: Any) -> float:
    """Root-mean-square difference of two linear images (arrays (H, W, 3) or Images),
    over every channel: what `voxlab ablate` reports."""
    return _native.rmse(_image_array(a, "a"), _image_array(b, "b"))


def flip(reference: Any, test: Any, ppd: Optional[float] = None) -> tuple:
    """FLIP (Andersson et al. 2020, LDR) of `test` against `reference` on their sRGB
    display values, at `ppd` pixels per degree (default 67, ablate's): (mean, map), the
    map float32 (H, W) in [0, 1]."""
    p = _native.flip_default_ppd() if ppd is None else float(ppd)
    return _native.flip(
        _image_array(reference, "reference"), _image_array(test, "test"), p
    )


def settings() -> list:
    """Every declared number of an experiment file (`voxlab settings --json`): per key
    (`table.key`) its type, default (None where it has none), min, max, range, unit and
    doc."""
    return json.loads(_native.settings_json())


def techniques() -> list:
    """The registry: per technique its name, slot, switch, summary (with its paper),
    and settings (key, type, default, min, max, range, unit, doc)."""
    return json.loads(_native.techniques_json())


class AblateResult(NamedTuple):
    """What `ablate` measured: the CSV's rows (a DataFrame when pandas is installed,
    else a list of dicts) and the files it wrote; with executor="ray", the tasks this
    run did and the points it took from the cache (`resume`)."""

    rows: Any
    files: list
    out: Path
    tasks: Optional[int] = None
    resumed: Optional[int] = None


def _number(text: str) -> Any:
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def ablate(
    experiment: Union[PathLike, Experiment],
    out: PathLike,
    set: Optional[Mapping[str, Any]] = None,
    *,
    cache: Optional[PathLike] = None,
    progress: Union[bool, Callable[[int, int], Any], None] = None,
    resume: bool = False,
    executor: str = "local",
    address: Optional[str] = None,
    workers: Optional[int] = None,
    bands: Optional[int] = None,
) -> AblateResult:
    """`voxlab ablate` on an experiment file (its [ablate] table; an Experiment loaded
    from a file, text or a dict brings its overrides and is swept as its file would
    be; one whose grid was replaced is refused): error against time of every shadow
    model and knob, written under `out` (images, grid, CSV, plot, tables). Returns the CSV's rows
    and the paths of the files written. The GIL is released; Ctrl-C stops the sweep
    between renders (KeyboardInterrupt; the images and cached references done stay, no
    table is written). `progress` as for `Session.render` (units: estimated work; with
    Ray, tasks). `resume`: take the points an earlier run left in the cache.

    `executor="ray"` spreads the reference's bands of rows and the points over a Ray
    cluster (`address`, or a local one; `workers` point workers, default one per GPU
    or CPU; `bands` per reference half): the same rows and images as a local run,
    timings aside (each row records its worker's adapter). docs/ray.md."""
    sets = _overrides(set)
    text = None
    if isinstance(experiment, Experiment) and experiment.source is None:
        given = experiment._text_source()
        if given is None:
            raise _error(
                "ablate(): the experiment's grid was replaced (Experiment.with_grid): "
                "ablate sweeps what an experiment's text describes; save the grid "
                "(voxlab voxelize's .vox) and name it in the experiment"
            )
        text, path = given
        sets = list(experiment.overrides) + sets
    elif isinstance(experiment, Experiment):
        path = experiment.source
        # ablate reads the file (its [ablate] table too): it must hold what was loaded.
        if experiment._source_changed():
            raise _error(
                f"ablate(): {path} changed on disk since the experiment was loaded, and "
                "ablate reads the file: load it again (voxlab.load) to sweep what it "
                "holds now"
            )
        sets = list(experiment.overrides) + sets
    else:
        path = os.fspath(experiment)
    out = Path(out)
    cache_path = None if cache is None else os.fspath(cache)
    if executor not in ("local", "ray"):
        raise _error(f'executor {executor!r}: must be "local" or "ray"', key="executor")
    if executor == "local" and (address, workers, bands) != (None, None, None):
        raise _error('address, workers and bands are options of executor="ray"', key="executor")
    for name, value in (("workers", workers), ("bands", bands)):
        if value is not None and (
            isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 4096
        ):
            raise _error(f"{name} = {value!r}: an integer in 1..=4096", key=name)
    callback, bar = _progress_callback(progress, f"ablate {Path(path).stem}")
    tasks = resumed = None
    try:
        if executor == "ray":
            from .distributed import ablate_on_ray

            files, tasks, resumed = ablate_on_ray(
                os.fspath(path),
                sets,
                os.fspath(out),
                cache_path,
                address=address,
                workers=workers,
                bands=bands,
                resume=resume,
                progress=callback,
                text=text,
            )
        else:
            files = _native.ablate(
                path, sets, os.fspath(out), cache_path, callback, resume, text
            )
    finally:
        if bar is not None:
            bar.close()
    with open(out / "ablation.csv", newline="") as f:
        rows = [{k: _number(v) for k, v in row.items()} for row in csv.DictReader(f)]
    try:
        import pandas
    except ImportError:
        pass
    else:
        rows = pandas.DataFrame(rows)
    return AblateResult(
        rows=rows, files=[out / f for f in files], out=out, tasks=tasks, resumed=resumed
    )

