"""`python -m voxlab ablate EXPERIMENT [--executor ray --address ADDR] ...`: `voxlab
ablate` through the Python package, whose executors include Ray (docs/ray.md)."""

from __future__ import annotations

import argparse
import sys

from . import VoxlabError, _RawToml, ablate


def main(argv: list | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m voxlab")
    commands = parser.add_subparsers(dest="command", required=True)
    a = commands.add_parser("ablate", help="error against time of every shadow model and knob")
    a.add_argument("experiment", help="the experiment file (TOML) with its [ablate] table")
    a.add_argument("--out", required=True, help="output directory")
    a.add_argument("--cache", help="where references and points done are kept (default OUT/cache)")
    a.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE",
        help="override a key of the file, as voxlab ablate --set (repeatable)",
    )
    a.add_argument("--resume", action="store_true", help="take the points done from the cache")
    a.add_argument("--executor", choices=["local", "ray"], default="local")
    a.add_argument("--address", help='a Ray cluster ("auto", or HOST:PORT); default: a local one')
    a.add_argument("--workers", type=int, help="point workers (default: one per GPU, else per CPU)")
    a.add_argument("--bands", type=int, help="bands of rows per reference half")
    args = parser.parse_args(argv)

    sets = {}
    for s in args.set:
        key, eq, value = s.partition("=")
        if not eq:
            parser.error(f"--set {s!r}: expected KEY=VALUE")
        sets[key] = _RawToml(value)
    try:
        result = ablate(
            args.experiment,
            args.out,
            set=sets,
            cache=args.cache,
            resume=args.resume,
            executor=args.executor,
            address=args.address,
            workers=args.workers,
            bands=args.bands,
        )
    except VoxlabError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print((result.out / "table.md").read_text())
    extra = ""
    if result.tasks is not None:
        extra = f"; {result.tasks} tasks on Ray, {result.resumed} points resumed"
    print(f"wrote {len(result.files)} files under {result.out}{extra}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
