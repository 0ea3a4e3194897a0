"""Shared fixtures: the repository, the CLI binary, and one session per backend.

A GPU session needs a Vulkan adapter (lavapipe on a machine without a GPU, installed by
tests/run.sh): a missing adapter fails the GPU tests, it never skips them.
"""

import os
import subprocess
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
