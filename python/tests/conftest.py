"""Shared fixtures: the repository, the CLI binary, and one session per backend.

A GPU session needs a Vulkan adapter (lavapipe on a machine without a GPU, installed by
tests/run.sh): a missing adapter fails the GPU tests, it never skips them.
"""

import contextlib
import os
import signal
import subprocess
import threading
from pathlib import Path

import pytest

import voxlab as vx

REPO = Path(__file__).resolve().parents[2]
EXPERIMENTS = REPO / "experiments"


def cli_path() -> Path:
    path = Path(os.environ.get("VOXLAB_BIN", REPO / "target" / "release" / "voxlab"))
    if not path.is_file():
        pytest.fail(f"{path}: build the command line first (cargo build --release)")
    return path


def cli(*args, check=True, cwd=None):
    """Runs `voxlab ARGS`; returns the finished process (text output)."""
    proc = subprocess.run(
        [str(cli_path()), *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )
    if check and proc.returncode != 0:
        raise AssertionError(f"voxlab {' '.join(map(str, args))} failed:\n{proc.stderr}")
    return proc


@contextlib.contextmanager
def ctrl_c_after(seconds: float):
    """Sends this process SIGINT `seconds` after the block starts, as Ctrl-C would.

    Python installs its KeyboardInterrupt handler only where SIGINT was not ignored when
    it started, and a job started in the background of a shell (`cmd &`, some CI
    runners) inherits SIGINT ignored: there the signal would do nothing and the render
    meant to be stopped would run to its end. So the handler is installed for the
    block and the inherited one put back after it.
    """
    inherited = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(seconds, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
        timer.join()
        signal.signal(signal.SIGINT, inherited)


@pytest.fixture(scope="session")
def cpu():
    return vx.Session("cpu")


@pytest.fixture(scope="session")
def gpu():
    return vx.Session("gpu")


def small(name: str, width: int = 24, height: int = 16, spp=None, **set):
    """An experiment of the repository at a test's size (`set`: dotted keys, given as
    `**{"features.transmittance": "beer-lambert"}`)."""
    size = {"render.width": width, "render.height": height}
    if spp is not None:
        size["render.spp"] = spp
    return vx.load(EXPERIMENTS / name, set={**size, **set})
