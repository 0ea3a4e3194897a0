"""Mitsuba 3 renders voxlab's Whitted model: an integrator for scenes that
`voxlab export --to mitsuba` (Experiment.export_mitsuba) wrote.

    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    import voxlab.mitsuba

    scene, whitted = voxlab.mitsuba.load("out/glass")      # the export's directory
    image = mi.render(scene, integrator=whitted, spp=256)

Mitsuba's own `path` integrator, which the exported scene.xml names, also carries the
diffuse interreflection that Whitted's model leaves out, so a scene with mirrors or
glass agrees with voxlab only approximately under it. `Whitted` follows the paths
Whitted's model has and no others: from each hit, every emitter's direct light through
the BSDF's smooth (diffuse) part, then each delta lobe (mirror reflection, dielectric
reflection and refraction) traced on its own with its weight, within voxlab's depth
limits (read from the export's scene.xml.json). Everything physical in it is
Mitsuba's: the intersections, the BSDFs (the dielectric's Fresnel equations, its
refracted direction and radiance scaling), the emitters' sampling and the visibility
test. Only the tree's shape comes from voxlab, and that its lights are not surfaces:
every ray passes through Mitsuba's emitter shapes, as through voxlab's lights
(docs/mitsuba.md, "Light shapes in the way").

The integrator is Python called once per sample, so it is meant for Mitsuba's scalar
variants (a 48 x 48 image at 16 spp takes about a second); a vectorised variant is
refused. A converged reference for `voxlab ablate`'s `[ablate] reference`, over as many
processes as the machine has cores:

    python -m voxlab.mitsuba out/glass --spp 4096 --jobs 2 --out out/glass/mitsuba.exr
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Union

import numpy as np

PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["Whitted", "load", "limits", "render", "main"]


def _mi():
    import mitsuba as mi

    if not mi.variant() or not mi.variant().startswith("scalar_"):
        raise RuntimeError(
            f"voxlab.mitsuba.Whitted runs in Mitsuba's scalar variants; the variant is {mi.variant()!r} "
            "(mi.set_variant('scalar_rgb'))"
        )
    return mi


def limits(directory: PathLike) -> dict[str, Any]:
    """The Whitted tree's depth limits of an export: scene.xml.json's `whitted`."""
    record = Path(directory) / "scene.xml.json"
    try:
        data = json.loads(record.read_text())
    except FileNotFoundError:
        raise FileNotFoundError(
            f"{record}: not found; the directory is not one `voxlab export --to mitsuba` wrote"
        ) from None
    try:
        return dict(data["whitted"])
    except (KeyError, TypeError):
        raise ValueError(f"{record}: no `whitted` limits (written by an older voxlab?)") from None


def Whitted(
    max_reflection_depth: int = 4,
    max_refraction_depth: int = 4,
    max_depth: int | None = None,
    seed_rules: bool = False,
    grid_bounds: list | None = None,
):
    """A Mitsuba integrator of Whitted's model with voxlab's depth rule
    (`RenderSettings::may_spawn`): a reflection may be spawned while the path has made
    fewer than `max_reflection_depth` reflections, a refraction while it has made fewer
    than `max_refraction_depth` refractions (under the seed's rules both count the
    path's whole depth), and neither once reflections and refractions together reach
    `max_depth` (absent: their sum). Under the seed's rules the grid's boundary is
    one-way (docs/rules.md): a ray that meets it from inside, leaving glass that lies
    on it, is a miss; `grid_bounds` (`[min, max]`, world units) is where it lies."""
    mi = _mi()
    total = max_reflection_depth + max_refraction_depth
    total = total if max_depth is None else min(max_depth, total)
    if seed_rules and grid_bounds is not None:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in grid_bounds)
        # Mitsuba's hit points are 32-bit: a face on the boundary is met within a few of
        # their spacings there.
        near = 1e-5 * max(float(np.abs(lo).max()), float(np.abs(hi).max()), float((hi - lo).max()))
    else:
        lo = hi = None

    def leaves_grid(p, d) -> bool:
        """Whether a ray of direction `d` meets the grid's boundary at `p` from inside."""
        if lo is None:
            return False
        return any(
            (abs(p[a] - hi[a]) <= near and d[a] > 0) or (abs(p[a] - lo[a]) <= near and d[a] < 0)
            for a in range(3)
        )

    def may_spawn(a: int, b: int, reflection: bool) -> bool:
        if a + b >= total:
            return False
        own = a + b if seed_rules else (a if reflection else b)
        return own < (max_reflection_depth if reflection else max_refraction_depth)

    def has(flags, flag) -> bool:
        return (int(flags) & int(flag)) != 0

    class _Whitted(mi.SamplingIntegrator):
        def __init__(self, props):
            super().__init__(props)

        def sample(self, scene, sampler, ray, medium=None, active=True):
            return self._trace(scene, sampler, mi.Ray3f(ray), 0, 0), True, []

        # voxlab's lights are not surfaces: nothing meets them, and they hide nothing.
        # Mitsuba's area emitters are shapes that rays meet, so the camera's rays, the
        # reflected and refracted rays and the shadow rays pass through them here, as
        # they do in voxlab. A ray crosses a rectangle or a disk once and a sphere at
        # most twice, so two crossings an emitter bound the loop.
        def _hit(self, scene, ray):
            si = scene.ray_intersect(ray)
            for _ in range(2 * len(scene.emitters())):
                if not (si.is_valid() and si.shape is not None and si.shape.is_emitter()):
                    break
                si = scene.ray_intersect(si.spawn_ray(ray.d))
            return si

        def _unoccluded(self, scene, si, p) -> bool:
            ray = si.spawn_ray_to(p)
            for _ in range(2 * len(scene.emitters()) + 1):
                hit = scene.ray_intersect(ray)
                if not hit.is_valid():
                    return True
                if hit.shape is None or not hit.shape.is_emitter():
                    return False
                ray = hit.spawn_ray_to(p)
            return True

        def _trace(self, scene, sampler, ray, a: int, b: int):
            si = self._hit(scene, ray)
            radiance = mi.Color3f(0.0)
            if not si.is_valid() or leaves_grid(si.p, ray.d):
                return radiance
            bsdf = si.bsdf(ray)
            if has(bsdf.flags(), mi.BSDFFlags.Smooth):
                ctx = mi.BSDFContext()
                # Every emitter once: the Whitted tree sums the lights.
                for emitter in scene.emitters():
                    ds, weight = emitter.sample_direction(si, sampler.next_2d())
                    if ds.pdf <= 0.0 or max(weight) <= 0.0:
                        continue
                    if not self._unoccluded(scene, si, ds.p):
                        continue
                    radiance += weight * bsdf.eval(ctx, si, si.to_local(ds.d))
            for component in range(bsdf.component_count()):
                flags = bsdf.flags(component)
                if has(flags, mi.BSDFFlags.DeltaReflection):
                    reflection = True
                elif has(flags, mi.BSDFFlags.DeltaTransmission):
                    reflection = False
                else:
                    continue
                if not may_spawn(a, b, reflection):
                    continue
                # Importance mode: Mitsuba's dielectric then leaves out the radiance
                # scaling by the squared ratio of indices at a refraction, which voxlab's
                # model does not have (it cancels on a path that enters and leaves glass;
                # an eye or a light inside glass would be 2.25x off at ior 1.5).
                ctx = mi.BSDFContext(mi.TransportMode.Importance)
                ctx.component = component
                # One lobe alone: its weight (Fresnel's share for a dielectric), pdf 1.
                bs, weight = bsdf.sample(ctx, si, 0.5, mi.Point2f(0.5, 0.5))
                if bs.pdf <= 0.0 or max(weight) <= 0.0:
                    continue
                child = si.spawn_ray(si.to_world(bs.wo))
                na, nb = (a + 1, b) if reflection else (a, b + 1)
                radiance += weight * self._trace(scene, sampler, child, na, nb)
            return radiance

        def to_string(self):
            return (
                f"Whitted[max_reflection_depth={max_reflection_depth}, "
                f"max_refraction_depth={max_refraction_depth}, max_depth={max_depth}, "
                f"seed_rules={seed_rules}]"
            )

    # Mitsuba warns that a Python integrator is slow in scalar variants, which this one
    # is by design (the module's note); the warning says nothing the caller can act on.
    level = mi.log_level()
    mi.set_log_level(mi.LogLevel.Error)
    try:
        return _Whitted(mi.Properties())
    finally:
        mi.set_log_level(level)


def load(directory: PathLike):
    """The exported scene of `directory` and the Whitted integrator of its limits."""
    mi = _mi()
    directory = Path(directory)
    return mi.load_file(str(directory / "scene.xml")), Whitted(**limits(directory))


def _render_part(directory: str, spp: int, seed: int, integrator: str):
    import mitsuba as mi

    if not mi.variant():
        mi.set_variant("scalar_rgb")
    scene, whitted = load(directory)
    chosen = whitted if integrator == "whitted" else None
    return np.asarray(mi.render(scene, integrator=chosen, spp=spp, seed=seed), dtype=np.float64)


def render(
    directory: PathLike, spp: int, seed: int = 0, jobs: int = 1, integrator: str = "whitted"
):
    """The mean of `jobs` independent renders of `spp / jobs` samples each (seeds
    `seed`, `seed + 1`, ...; in parallel processes when `jobs > 1`), as float64 RGB:
    Mitsuba's estimate of the export in `directory` at `spp` samples per pixel, by
    Whitted's paths or by Mitsuba's own `path` integrator (`integrator="path"`)."""
    if integrator not in ("whitted", "path"):
        raise ValueError(f"integrator {integrator!r}: must be 'whitted' or 'path'")
    if not (isinstance(spp, int) and 1 <= spp <= 1 << 20):
        raise ValueError(f"spp {spp!r}: must be an integer in 1..={1 << 20}")
    if not (isinstance(jobs, int) and 1 <= jobs <= spp):
        raise ValueError(f"jobs {jobs!r}: must be an integer in 1..=spp ({spp})")
    limits(directory)  # the directory is an export, before any work
    parts = [spp // jobs + (1 if k < spp % jobs else 0) for k in range(jobs)]
    args = [(str(directory), n, seed + k, integrator) for k, n in enumerate(parts)]
    if jobs == 1:
        images = [_render_part(*args[0])]
    else:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        context = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(jobs, mp_context=context, initializer=_variant_of_parent,
                                 initargs=(_mi().variant(),)) as pool:
            images = list(pool.map(_render_part, *zip(*args)))
    image = sum(n * im for n, im in zip(parts, images)) / spp
    return image[..., :3]


def _variant_of_parent(variant: str):
    import mitsuba as mi

    mi.set_variant(variant)


def main(argv: list | None = None) -> int:
    """`python -m voxlab.mitsuba DIR --spp N [--jobs J] [--seed S] [--integrator
    whitted|path] --out FILE.exr`: a reference render of an export, written whole or
    not at all."""
    import argparse
    import sys
    import tempfile

    parser = argparse.ArgumentParser(prog="python -m voxlab.mitsuba")
    parser.add_argument("directory", help="a directory `voxlab export --to mitsuba` wrote")
    parser.add_argument("--spp", type=int, required=True)
    parser.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--integrator", choices=["whitted", "path"], default="whitted")
    parser.add_argument("--out", required=True, help="the image to write (.exr, linear RGB)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if out.suffix.lower() != ".exr":
        parser.error(f"--out {out}: must name an .exr file")
    if len(out.name.encode()) > 255:
        parser.error(f"--out: a file name of {len(out.name.encode())} bytes; at most 255")
    if out.is_dir():
        parser.error(f"--out {out}: is a directory")
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    try:
        image = render(args.directory, args.spp, args.seed, args.jobs, args.integrator)
    except (FileNotFoundError, ValueError) as e:
        print(f"python -m voxlab.mitsuba: {e}", file=sys.stderr)
        return 2
    # Written beside its destination and renamed: the file is whole or absent.
    tmp = None
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(suffix=".exr", dir=out.parent, prefix=".mitsuba-")
        os.close(fd)
        mi.Bitmap(image.astype(np.float32)).write(tmp)
        os.chmod(tmp, 0o644)
        os.replace(tmp, out)
    except (OSError, RuntimeError) as e:
        print(f"python -m voxlab.mitsuba: cannot write {out}: {e}", file=sys.stderr)
        return 2
    finally:
        if tmp is not None and Path(tmp).exists():
            Path(tmp).unlink()
    print(f"{out}: Mitsuba {mi.__version__} {mi.variant()}, {args.integrator}, {args.spp} spp")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
