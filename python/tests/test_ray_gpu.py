"""`executor="ray"` with GPU workers: a local Ray cluster that declares two GPUs (Ray's
GPU resource is a count; the workers open the machine's Vulkan adapter, lavapipe in
CI), so the point workers ask for `num_gpus=1` and the f64 reference's bands run as CPU
tasks of their own. The rows and images equal a local run's, whose points render on
the same adapter.
"""

from pathlib import Path

import pytest
import ray

import voxlab as vx

from test_ray import TINY, assert_same_sweep, reference_exr, rows

GPU_SWEEP = TINY.replace('backend = "cpu"\n', "")


@pytest.fixture(scope="module")
def gpu_cluster():
    ray.init(num_cpus=2, num_gpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_gpu_workers_and_cpu_bands_give_the_local_runs_rows_and_images(gpu_cluster, tmp_path):
    src = tmp_path / "tiny.toml"
    src.write_text(GPU_SWEEP)
    vx.ablate(src, tmp_path / "local", cache=tmp_path / "local-cache", progress=False)
    local = rows(tmp_path / "local")
    assert {r["backend"] for r in local} == {"gpu"}, "the points render on the GPU"
    result = vx.ablate(
        src, tmp_path / "ray", cache=tmp_path / "ray-cache", executor="ray", bands=5,
        progress=False,
    )
    assert_same_sweep(tmp_path / "local", tmp_path / "ray")
    assert reference_exr(tmp_path / "ray-cache") == reference_exr(tmp_path / "local-cache")
    assert result.tasks == 2 * 5 + len(local) // 2
    assert "(ray, 2 workers)" in (tmp_path / "ray" / "run.txt").read_text()
