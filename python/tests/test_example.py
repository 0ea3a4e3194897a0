"""The example notebook (a percent-format script) runs end to end and writes its figure
and its numbers."""

import csv
import os
import subprocess
import sys
from pathlib import Path

from PIL import Image

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "compare_shadows.py"


def test_the_example_notebook_runs(tmp_path):
    env = dict(os.environ, VOXLAB_EXAMPLE_QUICK="1", VOXLAB_EXAMPLE_OUT=str(tmp_path))
    proc = subprocess.run(
        [sys.executable, str(EXAMPLE)], capture_output=True, text=True, env=env, timeout=900
    )
    assert proc.returncode == 0, proc.stderr
    figure = tmp_path / "error_vs_spp.png"
    assert Image.open(figure).size == (600, 432)
    rows = list(csv.DictReader(open(tmp_path / "error_vs_spp.csv")))
    area = [r for r in rows if r["model"] == "area"]
    assert len(area) == 3 * 3 and any(r["model"] == "sdf" for r in rows)
    # More samples, less error: the sampled model converges to its own reference.
    mean = lambda spp: sum(float(r["rmse"]) for r in area if r["spp"] == spp) / 3
    assert mean("4") < mean("1")
    assert (tmp_path / "reference.exr").is_file() and (tmp_path / "reference.exr.json").is_file()


def test_the_readmes_python_quick_start_runs(tmp_path):
    """The README's Python block, as a user pastes it (from the repository's root)."""
    readme = (EXAMPLE.parents[2] / "README.md").read_text()
    block = readme.split("```python\n", 1)[1].split("```", 1)[0]
    assert len(block.strip().splitlines()) <= 11
    # At the test's size: the README renders 128x128 with 16 frames.
    block = block.replace('"render.width": 128, "render.height": 128', '"render.width": 32, "render.height": 32')
    block = block.replace('"out/mine.exr"', repr(str(tmp_path / "mine.exr")))
    proc = subprocess.run(
        [sys.executable, "-c", block], capture_output=True, text=True,
        cwd=EXAMPLE.parents[2], timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "mine.exr").is_file() and (tmp_path / "mine.exr.json").is_file()
