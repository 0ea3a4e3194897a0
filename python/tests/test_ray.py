"""`vx.ablate(..., executor="ray")` on a local Ray cluster of two CPU workers: the same
rows and images as a local run (timings aside), a reference in bands equal to the
one-piece reference bit for bit, a worker killed mid-point retried with nothing lost,
`resume` rendering only the missing points, an experiment's error not retried, and
`python -m voxlab ablate --executor ray`.

The sweeps render on the CPU (`[ablate] backend = "cpu"`), so the images are the f64
oracle's and the comparison is exact; docs/ray.md covers GPU workers.
"""

import csv
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image as PILImage

import voxlab as vx

import ray  # installed by tests/run.sh: a missing Ray fails these tests, never skips them

from voxlab import distributed

TINY = """name = "tiny"
[scene]
size = 8
[[lights]]
type = "rect"
position = [7.0, 12.0, 11.0]
normal = [-3.0, -8.0, -7.0]
size = [4.0, 4.0]
intensity = 110.0
[render]
width = 40
height = 30
[ablate]
backend = "cpu"
reference_spp = 32
spp = [1, 4, 16]
seeds = 2
runs = 1
warmup = 0
cone_step_factor = [1]
cone_aperture_deg = []
transmittance = []
"""

# Columns that depend on when and where a point ran, not on what it rendered.
TIMING = ("ms_median", "ms_runs", "runs", "trace_ms_median", "setup_ms_median", "adapter")


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of two CPUs (what CI has), shut down after the module."""
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """The experiment file and its local run (output directory, cache)."""
    d = tmp_path_factory.mktemp("ray")
    src = d / "tiny.toml"
    src.write_text(TINY)
    vx.ablate(src, d / "local", cache=d / "local-cache", progress=False)
    return src, d


def rows(out: Path) -> list:
    with open(out / "ablation.csv", newline="") as f:
        return list(csv.DictReader(f))


def assert_same_sweep(a: Path, b: Path) -> None:
    """The same rows (timings aside) and the same pixels in every image."""
    ra, rb = rows(a), rows(b)
    assert len(ra) == len(rb) > 0
    for x, y in zip(ra, rb):
        for k in x:
            if k not in TIMING:
                assert x[k] == y[k], (k, x, y)
    images = sorted(p.name for p in (a / "images").glob("*.png"))
    assert images == sorted(p.name for p in (b / "images").glob("*.png"))
    assert len(images) > 3
    for name in images:
        pa = np.asarray(PILImage.open(a / "images" / name))
        pb = np.asarray(PILImage.open(b / "images" / name))
        assert np.array_equal(pa, pb), name


def reference_exr(cache: Path) -> bytes:
    (exr,) = cache.glob("reference-*.exr")
    return exr.read_bytes()


def test_an_address_nobody_answers_is_an_error_not_a_wait(sweep, tmp_path):
    """ray.init retries an unreachable head for minutes: the address is tried first.
    (First in the file: the module's cluster is not started yet.)"""
    src, _ = sweep
    # A port nothing listens on (bound, then closed).
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    assert not ray.is_initialized()
    start = time.monotonic()
    for address, message in (
        (f"127.0.0.1:{port}", "no Ray cluster answers"),
        ("127.0.0.1", "expected HOST:PORT"),
        ("127.0.0.1:99999", "expected HOST:PORT"),
    ):
        with pytest.raises(vx.VoxlabError, match=message):
            vx.ablate(src, tmp_path / "x", executor="ray", address=address)
    assert time.monotonic() - start < 30
    assert not ray.is_initialized()
    assert not (tmp_path / "x").exists()


def test_python_m_voxlab_ablate_runs_on_ray(sweep, tmp_path):
    src, d = sweep
    proc = subprocess.run(
        [sys.executable, "-m", "voxlab", "ablate", str(src), "--out", str(tmp_path / "cli"),
         "--executor", "ray", "--workers", "2", "--set", "ablate.seeds=2"],
        capture_output=True, text=True, timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert "tasks on Ray" in proc.stdout
    assert_same_sweep(d / "local", tmp_path / "cli")
    bad = subprocess.run(
        [sys.executable, "-m", "voxlab", "ablate", str(src), "--out", str(tmp_path / "bad"),
         "--set", "ablate.seeds=0"],
        capture_output=True, text=True, timeout=600,
    )
    assert bad.returncode == 1 and "seeds" in bad.stderr, bad.stderr
    assert not (tmp_path / "bad" / "ablation.csv").exists()


def test_a_ray_sweep_equals_the_local_run_and_its_banded_reference_is_exact(cluster, sweep):
    src, d = sweep
    result = vx.ablate(
        src, d / "ray", cache=d / "ray-cache", executor="ray", workers=2, bands=7, progress=False
    )
    assert_same_sweep(d / "local", d / "ray")
    # The reference, in 7 bands per half over two workers, is the one-piece reference
    # bit for bit (the cache's EXR holds the f32 values as rendered).
    assert reference_exr(d / "ray-cache") == reference_exr(d / "local-cache")
    points = len(rows(d / "ray")) // 2
    assert result.tasks == 2 * 7 + points
    assert result.resumed == 0
    # Every row names what rendered it; the run's record names the workers.
    assert all(r["adapter"].startswith("CPU reference (f64") for r in rows(d / "ray"))
    assert "(ray, 2 workers)" in (d / "ray" / "run.txt").read_text()


def test_a_text_experiment_runs_on_ray(cluster, sweep, tmp_path):
    """An experiment given as text (no file for the workers to read) travels to them as
    its text: the local file's sweep again, reference bands included."""
    _, d = sweep
    vx.ablate(vx.load(TINY), tmp_path / "text", executor="ray", workers=2, bands=3, progress=False)
    assert_same_sweep(d / "local", tmp_path / "text")


def worker_processes() -> list:
    """(pid, title) of the Ray point workers now running a task."""
    out = []
    for p in os.listdir("/proc"):
        if not p.isdigit():
            continue
        try:
            title = open(f"/proc/{p}/cmdline", "rb").read().split(b"\0")[0].decode()
        except OSError:
            continue
        if title.startswith("ray::_PointWorker.run"):
            out.append(int(p))
    return out


def test_a_worker_killed_mid_point_is_retried_and_nothing_is_lost(cluster, sweep):
    src, d = sweep
    outcome: dict = {}

    def run():
        try:
            outcome["result"] = vx.ablate(
                src, d / "killed", cache=d / "killed-cache", executor="ray", workers=2,
                progress=False,
            )
        except BaseException as e:  # reported below
            outcome["error"] = e

    t = threading.Thread(target=run)
    t.start()
    killed = None
    deadline = time.monotonic() + 120
    while killed is None and t.is_alive() and time.monotonic() < deadline:
        busy = worker_processes()
        if busy:
            killed = busy[0]
            os.kill(killed, signal.SIGKILL)
        else:
            time.sleep(0.001)
    t.join(timeout=600)
    assert killed is not None, "no worker was seen running a point: the sweep was too short"
    assert "error" not in outcome, outcome.get("error")
    assert_same_sweep(d / "local", d / "killed")


def test_resume_renders_only_the_missing_points(cluster, sweep):
    src, d = sweep
    cache = d / "resume-cache"
    first = vx.ablate(src, d / "r1", cache=cache, executor="ray", workers=2, progress=False)
    points = len(rows(d / "r1")) // 2
    assert first.tasks > points
    # Everything done: nothing is rendered, the same rows come out, times included.
    again = vx.ablate(src, d / "r2", cache=cache, executor="ray", resume=True, progress=False)
    assert (again.tasks, again.resumed) == (0, points)
    assert rows(d / "r1") == rows(d / "r2")
    # Two points lost: those two, and nothing else, are rendered.
    kept = sorted((cache / "points").glob("point-*.bin"))
    assert len(kept) == points
    for p in kept[:2]:
        p.unlink()
    third = vx.ablate(src, d / "r3", cache=cache, executor="ray", resume=True, progress=False)
    assert (third.tasks, third.resumed) == (2, points - 2)
    assert_same_sweep(d / "local", d / "r3")


def test_an_experiments_error_is_raised_once_and_not_retried(cluster, sweep):
    src, _ = sweep
    # The sweep's own options: a task that raises (here: a point the sweep does not
    # have) is not run again, and the worker keeps its process.
    actor = ray.remote(distributed._PointWorker).options(
        **distributed.actor_options(False, 1)
    ).remote(str(src), [], False)
    pid, calls = ray.get(actor.stats.remote())
    with pytest.raises(ray.exceptions.RayTaskError) as info:
        ray.get(actor.run.remote('{"kind": "point", "index": 9999}'))
    assert isinstance(distributed._unwrap(info.value), vx.VoxlabError)
    assert "no point 9999" in str(info.value)
    assert ray.get(actor.stats.remote()) == (pid, calls + 1)
    ray.kill(actor)


def test_bad_executor_options_are_refused(sweep, tmp_path):
    src, _ = sweep
    with pytest.raises(vx.VoxlabError, match="executor"):
        vx.ablate(src, tmp_path / "x", executor="dask")
    with pytest.raises(vx.VoxlabError, match="executor"):
        vx.ablate(src, tmp_path / "x", workers=2)
    for bad in (0, -1, 2.5, True, 10**9):
        with pytest.raises(vx.VoxlabError, match="workers"):
            vx.ablate(src, tmp_path / "x", executor="ray", workers=bad)
        with pytest.raises(vx.VoxlabError, match="bands"):
            vx.ablate(src, tmp_path / "x", executor="ray", bands=bad)
    assert not (tmp_path / "x").exists()
