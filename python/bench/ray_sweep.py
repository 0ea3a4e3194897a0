"""What a sweep on Ray costs and gains (python/bench/ray_sweep.py; docs/ray.md has the
figures): the same ablation run locally (one process, `vx.ablate`) and on a local Ray
cluster with 1 and 2 workers, each with a fresh cache so every run renders the whole
sweep, reference included.

    target/python-venv/bin/python python/bench/ray_sweep.py [EXPERIMENT] [--set K=V ...]
        [--workers 1 2] [--rounds 1]

Default: the shipped experiments/ablate_area.toml. Printed per run: wall time, tasks,
the speedup over 1 worker, and the overhead of Ray's scheduling against the local run
(1 worker's wall time less the local run's, start-up of the cluster timed apart). The
runs alternate within each round (these machines are shared and noisy), and the
figures are medians over rounds; nothing is asserted.
"""

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import ray

import voxlab as vx
from voxlab import _RawToml

REPO = Path(__file__).resolve().parents[2]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("experiment", nargs="?", default=str(REPO / "experiments" / "ablate_area.toml"))
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    p.add_argument("--rounds", type=int, default=1)
    args = p.parse_args()
    sets = {}
    for s in args.set:
        k, _, v = s.partition("=")
        sets[k] = _RawToml(v)

    t = time.monotonic()
    ray.init(include_dashboard=False, log_to_driver=False)
    start = time.monotonic() - t
    cpus = int(ray.cluster_resources().get("CPU", 1))
    gpus = int(ray.cluster_resources().get("GPU", 0))
    print(f"{args.experiment} {sets or ''}")
    print(f"ray {ray.__version__}: local cluster with {cpus} CPUs, {gpus} GPUs, started in {start:.2f} s")

    times: dict = {}
    tasks: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            runs = [("local", None)] + [(f"ray x{n}", n) for n in args.workers]
            for name, n in runs:
                out = Path(tmp) / f"{name.replace(' ', '_')}-{r}"
                t = time.monotonic()
                if n is None:
                    vx.ablate(args.experiment, out, set=sets, progress=False)
                else:
                    res = vx.ablate(
                        args.experiment, out, set=sets, executor="ray", workers=n, progress=False
                    )
                    tasks[name] = res.tasks
                times.setdefault(name, []).append(time.monotonic() - t)
                print(f"  round {r + 1}: {name:8} {times[name][-1]:8.2f} s", flush=True)
    ray.shutdown()

    med = {k: statistics.median(v) for k, v in times.items()}
    base = med.get(f"ray x{args.workers[0]}")
    print("\nrun        wall s   tasks   speedup vs ray x1")
    for name, m in med.items():
        speed = f"{base / m:.2f}x" if base and name != "local" else "-"
        print(f"{name:8} {m:8.2f} {tasks.get(name, '-'):>7}   {speed}")
    if "ray x1" in med:
        over = med["ray x1"] - med["local"]
        print(
            f"\nscheduling overhead (ray x1 - local): {over:+.2f} s "
            f"({100 * over / med['local']:+.1f} %), cluster start-up {start:.2f} s apart"
        )


if __name__ == "__main__":
    main()
