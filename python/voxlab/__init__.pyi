"""Type stubs of voxlab's Python package: every call an editor completes, documented."""

import os
from pathlib import Path
from typing import Any, Callable, Mapping, NamedTuple, Optional, Union

import numpy as np
import numpy.typing as npt

__version__: str

_PathLike = Union[str, os.PathLike[str]]

class VoxlabError(ValueError):
    """A voxlab error: the message the command line prints for the same input."""

    kind: str
    """io, syntax, unknownkey, invalid, scene, device, output or other."""
    file: Optional[str]
    """The file (or `--set KEY=VALUE`, or the name given to text and dicts)."""
    line: Optional[int]
    """1-based line in the file, where known."""
    key: Optional[str]
    """The dotted key: `render.width`, `lights[1].intensity`, `materials[0].kd`."""

class Grid:
    """Voxels (uint8 material indices, 0 void) and the palette they index."""

    @staticmethod
    def from_numpy(
        materials: npt.ArrayLike,
        palette: Optional[list[Mapping[str, Any]]] = None,
        voxel_size: float = 1.0,
        origin: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> Grid:
        """A grid from an integer array indexed `[x, y, z]`, y up (any integer dtype with
        values in 0..=255, any strides). Voxel (x, y, z) spans `origin + voxel_size *
        [x, x+1] x [y, y+1] x [z, z+1]`. `palette`: a list of material dicts with the
        keys of an experiment's `[[materials]]` (name, albedo, kd, ks, shininess, kr, kt,
        ior, sigma, emission); entry i is material i + 1. Default: the seed's palette
        (1 glass, 2 semi-solid, 3 solid)."""
    def to_numpy(self) -> npt.NDArray[np.uint8]:
        """The voxels as a uint8 array indexed `[x, y, z]`, Fortran-ordered (x fastest,
        as the grid holds them): `Grid.from_numpy(g.to_numpy())` is `g`."""
    def get(self, x: int, y: int, z: int) -> int:
        """The material of voxel (x, y, z); 0 outside the grid."""
    @property
    def shape(self) -> tuple[int, int, int]:
        """(nx, ny, nz)."""
    @property
    def voxel_size(self) -> float: ...
    @property
    def origin(self) -> tuple[float, float, float]: ...
    @property
    def palette(self) -> list[str]:
        """The materials' names, index 0 (void) first."""
    @property
    def blake3(self) -> str:
        """The hash of the voxels that image records (`provenance["grid"]`) carry."""

class Experiment:
    """A parsed, checked experiment (scene, render settings, techniques)."""

    def with_overrides(self, set: list[str]) -> Experiment:
        """A copy with more `KEY=VALUE` overrides (TOML values), as `--set`."""
    def with_grid(self, grid: Grid) -> Experiment:
        """A copy whose voxels and palette are `grid`'s. A camera and lights the file
        left to the seed's defaults follow the new grid; ones it set stay. The copy no
        longer renders from its file (`source` is None)."""
    def export_mitsuba(self, dir: _PathLike, strict: bool = False) -> list[tuple[str, str]]:
        """Writes the scene for Mitsuba 3 into `dir`: scene.xml, meshes/*.ply and
        scene.xml.json (as `voxlab export --to mitsuba`), all or nothing and never over
        the experiment's inputs. Returns the approximations made as (key, mapping)
        pairs (docs/mitsuba.md); `strict=True` raises VoxlabError on any."""
    @property
    def name(self) -> str: ...
    @property
    def description(self) -> Optional[str]:
        """The file's `description` key, as its records keep it; None without one."""
    @property
    def source(self) -> Optional[str]:
        """The file it was read from; None for text, dicts and replaced grids."""
    @property
    def overrides(self) -> list[str]:
        """Its `KEY=VALUE` overrides, in order."""
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def spp(self) -> int: ...
    @property
    def shadow_model(self) -> str: ...
    @property
    def grid(self) -> Grid: ...
    @property
    def plan(self) -> str:
        """What both tracers run for it and what they leave out, with reasons."""

class Image:
    """A rendered image and what made it."""

    @property
    def radiance(self) -> npt.NDArray[np.float32]:
        """Linear radiance, shape (height, width, 3), row 0 at the top; read-only (the
        render's own buffer, not a copy)."""
    @property
    def provenance(self) -> dict[str, Any]:
        """The record `voxlab render --json` prints: the resolved experiment, overrides,
        files read with their hashes, revision, backend, plan, timings, rays, grid."""
    @property
    def rays(self) -> dict[str, int]:
        """primary, secondary, shadow, voxel_steps, untraced (the secondary rays that
        leave the grid where they start, counted without being traced): counted by the
        tracer (the GPU counts only when its plan asks to; `provenance["rays"]["counted"]`
        says)."""
    @property
    def time_ms(self) -> float:
        """The trace: device time from timestamp queries where the GPU has them, else
        wall time (`timer` says which)."""
    @property
    def setup_ms(self) -> float: ...
    @property
    def wall_ms(self) -> float:
        """The whole library call."""
    @property
    def timer(self) -> str: ...
    @property
    def frames(self) -> int: ...
    @property
    def plan(self) -> str: ...
    @property
    def warnings(self) -> list[str]:
        """Where the GPU kernel may part from the f64 reference on this scene (a
        `render.ray_offset` below what its f32 resolves, docs/limits.md); empty on the
        CPU and at settings it resolves."""
    @property
    def backend(self) -> str: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    def save(self, path: _PathLike, display: str = "linear", exposure: float = 0.0) -> None:
        """Writes `.png` (8 bits; `display` "linear" or "srgb", `exposure` in stops, -32 to 32 as
        `voxlab render --exposure`) or
        `.exr` (linear) with the record inside and beside it (`<path>.json`): both or
        neither."""

class Session:
    """One tracer kept open across renders: "gpu" (the wgpu kernel on the first adapter)
    or "cpu" (the f64 reference). Kernel variants compile once per session, and either
    tracer builds the walk's data of its latest two grids and walks once."""

    def __new__(cls, backend: str = "gpu") -> Session: ...
    @property
    def label(self) -> str:
        """The backend and adapter, as reports name them."""
    def render(
        self,
        experiment: Experiment,
        spp: Optional[int] = None,
        *,
        set: Optional[Mapping[str, Any]] = None,
        progress: Union[bool, Callable[[int, int], Any], None] = None,
    ) -> Image:
        """Renders `experiment` with `spp` and `set` applied. The GIL is released;
        Ctrl-C stops the render (KeyboardInterrupt) and leaves the session usable.
        `progress`: None, a tqdm bar (when installed) for renders over a second; False,
        none; a callable, called with (done, total)."""

def load(
    source: Union[_PathLike, str, Mapping[str, Any]],
    set: Optional[Mapping[str, Any]] = None,
    *,
    name: Optional[str] = None,
) -> Experiment:
    """An experiment from a path, TOML text or a dict of tables, with `--set` overrides
    given as a dict (`{"render.spp": 8}`). Raises VoxlabError with the CLI's message."""

def rmse(a: Union[npt.ArrayLike, Image], b: Union[npt.ArrayLike, Image]) -> float:
    """Root-mean-square difference over every channel of two linear images; a NaN in
    either counts as an infinite difference (the result is inf, never a NaN that a
    comparison would pass over)."""

def flip(
    reference: Union[npt.ArrayLike, Image],
    test: Union[npt.ArrayLike, Image],
    ppd: Optional[float] = None,
) -> tuple[float, npt.NDArray[np.float32]]:
    """FLIP (LDR, on sRGB display values) at `ppd` pixels per degree (default 67):
    (mean, map (height, width)). A NaN in either image spreads through the map (its
    filters read around each pixel) and into the mean."""

def settings() -> list[dict[str, Any]]:
    """Every declared number of an experiment file: key (`table.key`), type, default,
    min, max, range, unit, doc."""

def techniques() -> list[dict[str, Any]]:
    """Every technique: name, slot, switch, summary (with its paper), settings."""

class AblateResult(NamedTuple):
    rows: Any
    """ablation.csv's rows: a pandas DataFrame when pandas is installed, else dicts."""
    files: list[Path]
    """Every file written."""
    out: Path
    tasks: Optional[int]
    """executor="ray": the tasks this run did (reference bands and points)."""
    resumed: Optional[int]
    """executor="ray": the points taken from the cache (`resume`)."""

def ablate(
    experiment: Union[_PathLike, Experiment],
    out: _PathLike,
    set: Optional[Mapping[str, Any]] = None,
    *,
    cache: Optional[_PathLike] = None,
    progress: Union[bool, Callable[[int, int], Any], None] = None,
    resume: bool = False,
    executor: str = "local",
    address: Optional[str] = None,
    workers: Optional[int] = None,
    bands: Optional[int] = None,
) -> AblateResult:
    """`voxlab ablate`: error against time of every shadow model and knob of the file's
    [ablate] table (or an Experiment's text or dict's), written under `out`. Ctrl-C
    stops it between renders. `resume`
    takes the points an earlier run left in the cache. `executor="ray"` spreads the
    reference's bands and the points over a Ray cluster (`address`, else a local one;
    `workers`, `bands`): the same rows and images, timings aside (docs/ray.md)."""
