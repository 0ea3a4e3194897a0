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
test. Only the tree's shape comes from voxlab (docs/mitsuba.md).

The integrator is Python called once per sample, so it is meant for Mitsuba's scalar
variants (a 48 x 48 image at 16 spp takes about a second); a vectorised variant is
refused.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Union

PathLike = Union[str, "os.PathLike[str]"]

__all__ = ["Whitted", "load", "limits"]


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
):
    """A Mitsuba integrator of Whitted's model with voxlab's depth rule
    (`RenderSettings::may_spawn`): a reflection may be spawned while the path has made
    fewer than `max_reflection_depth` reflections, a refraction while it has made fewer
    than `max_refraction_depth` refractions (under the seed's rules both count the
    path's whole depth), and neither once reflections and refractions together reach
    `max_depth` (absent: their sum)."""
    mi = _mi()
    total = max_reflection_depth + max_refraction_depth
    total = total if max_depth is None else min(max_depth, total)

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

        def _trace(self, scene, sampler, ray, a: int, b: int):
            si = scene.ray_intersect(ray)
            radiance = mi.Color3f(0.0)
            if not si.is_valid():
                return radiance
            bsdf = si.bsdf(ray)
            if has(bsdf.flags(), mi.BSDFFlags.Smooth):
                ctx = mi.BSDFContext()
                # Every emitter once: the Whitted tree sums the lights.
                for emitter in scene.emitters():
                    ds, weight = emitter.sample_direction(si, sampler.next_2d())
                    if ds.pdf <= 0.0 or max(weight) <= 0.0:
                        continue
                    if scene.ray_test(si.spawn_ray_to(ds.p)):
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
                ctx = mi.BSDFContext()
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
            return f"Whitted[max_reflection_depth={max_reflection_depth}, max_refraction_depth={max_refraction_depth}, max_depth={max_depth}]"

    return _Whitted(mi.Properties())


def load(directory: PathLike):
    """The exported scene of `directory` and the Whitted integrator of its limits."""
    mi = _mi()
    directory = Path(directory)
    return mi.load_file(str(directory / "scene.xml")), Whitted(**limits(directory))
