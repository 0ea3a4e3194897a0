"""What the Python layer costs (python/bench/overhead.py; docs/python.md has the figures).

1. Per render: the Python call (`session.render`, numpy image included) against the
   library call it wraps (`Image.wall_ms`, measured inside Rust), at 64x64 and 512x512;
   goals: under 1 ms at 64x64 and under 2 % at 512x512.
2. A sweep of N renders (+ PNG, at 16x16 and 64x64) in one session against N `voxlab render` processes, each
   of which opens the device and compiles its kernel again; goal: at least 5x faster.

    target/python-venv/bin/python python/bench/overhead.py [--backend gpu] [--count 100]

Figures are medians over interleaved repetitions, printed, never asserted.
"""

import argparse
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import voxlab as vx

REPO = Path(__file__).resolve().parents[2]


def per_render(session, size, runs):
    e = vx.load(
        REPO / "experiments" / "area_lights.toml",
        set={"render.width": size, "render.height": size, "render.spp": 1},
    )
    session.render(e, progress=False)  # compile and upload once
    total, inner = [], []
    for _ in range(runs):
        t = time.perf_counter()
        image = session.render(e, progress=False)
        total.append((time.perf_counter() - t) * 1e3)
        inner.append(image.wall_ms)
    over = statistics.median(a - b for a, b in zip(total, inner))
    wall = statistics.median(inner)
    print(
        f"{size:4d}x{size:<4d} library call {wall:9.3f} ms  python call "
        f"{statistics.median(total):9.3f} ms  overhead {over * 1e3:8.1f} us "
        f"({100 * over / wall:.2f} %)"
    )


def sweep(session, count, backend, out, exp, side):
    size = {"render.width": side, "render.height": side, "render.spp": 1}
    e = vx.load(exp, set=size)
    t = time.perf_counter()
    for i in range(count):
        session.render(e, set={"render.seed": i}, progress=False).save(out / f"py{i}.png")
    in_session = time.perf_counter() - t
    cli = REPO / "target" / "release" / "voxlab"
    sets = [a for k, v in size.items() for a in ("--set", f"{k}={v}")]
    t = time.perf_counter()
    for i in range(count):
        subprocess.run(
            [cli, "render", exp, *sets, "--set", f"render.seed={i}", "--backend", backend,
             "--out", out / f"cli{i}.png"],
            check=True, capture_output=True,
        )
    processes = time.perf_counter() - t
    print(
        f"sweep of {count} renders of {exp.name} at {side}x{side} (+ PNG): one session "
        f"{in_session:.2f} s, {count} processes {processes:.2f} s: "
        f"{processes / in_session:.1f}x"
    )


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--backend", default="gpu", choices=["gpu", "cpu"])
    p.add_argument("--count", type=int, default=100, help="renders in the sweep")
    p.add_argument("--runs", type=int, default=30, help="repetitions per size")
    p.add_argument(
        "--sweep", nargs="+", default=["baseline.toml", "area_lights.toml"],
        help="experiments/ files swept over render.seed",
    )
    p.add_argument(
        "--sides", nargs="+", type=int, default=[16, 64], help="image sides of the sweep"
    )
    a = p.parse_args()
    session = vx.Session(a.backend)
    print(f"backend: {session.label}")
    for size in (64, 512):
        per_render(session, size, a.runs if size == 64 else max(3, a.runs // 6))
    with tempfile.TemporaryDirectory() as d:
        for name in a.sweep:
            for side in a.sides:
                sweep(session, a.count, a.backend, Path(d), REPO / "experiments" / name, side)


if __name__ == "__main__":
    main()
