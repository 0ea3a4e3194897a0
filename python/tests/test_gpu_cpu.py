"""GPU = CPU through Python, over generated grids and the settings that change how the
kernel runs: the f64 reference is the oracle, as in the Rust tests (tests/gpu_cpu.rs),
with the same tolerance."""

import numpy as np
import pytest

import voxlab as vx

from conftest import EXPERIMENTS


def assert_close(gpu_image, cpu_image, label):
    """The command line's `--check` rule: displayed values (clamped to [0, 1]) differ
    by more than 2/255 on at most 0.5 % of the pixels, and by 1e-3 on average."""
    a = np.clip(gpu_image.radiance, 0.0, 1.0).astype(np.float64)
    b = np.clip(cpu_image.radiance, 0.0, 1.0).astype(np.float64)
    assert a.shape == b.shape
    d = np.abs(a - b)
    over = np.mean(d.max(axis=2) > 2.0 / 255.0)
    assert over <= 0.005 and d.mean() <= 1e-3, (
        f"{label}: {100 * over:.2f} % of pixels over 2/255, mean {d.mean():.2e}"
    )


def random_grid(rng, shape, fill):
    """Seed materials (1 glass, 2 semi-solid, 3 solid) on `fill` of the voxels, with a
    solid floor so that every image has shadows."""
    a = np.where(rng.random(shape) < fill, rng.integers(1, 4, size=shape), 0)
    a[:, 0, :] = 3
    return a.astype(np.uint8)


CASES = [
    # shape, fill, overrides
    ((6, 5, 7), 0.25, {}),
    ((9, 4, 3), 0.4, {"features.transmittance": "beer-lambert"}),
    ((16, 16, 16), 0.1, {"render.max_reflection_depth": 1, "render.max_refraction_depth": 6}),
    ((12, 7, 10), 0.3, {"render.traversal": "dense", "render.rules": "seed"}),
    ((5, 9, 6), 0.3, {"features.shadow_model": "sdf"}),
    ((10, 8, 6), 0.2, {"render.pixel_filter": "box", "render.spp": 3}),
    ((7, 6, 9), 0.35, {"render.pixel_filter": "gaussian", "render.spp": 2}),
]


def lights_on_voxel_faces(experiment, image):
    """The lights that lie on a face of a non-void voxel (a coordinate an integer number
    of voxels from the origin, next to a voxel that is not void): the case of
    test_a_light_on_a_voxel_face, kept out of the generated ones so each tests one thing."""
    import itertools
    import re

    grid = experiment.grid
    text = image.provenance["resolved_experiment"]
    faces = []
    for m in re.finditer(r"position = \[([^\]]*)\]", text):
        p = np.array([float(v) for v in m.group(1).split(",")])
        local = (p - np.array(grid.origin)) / grid.voxel_size
        on = np.abs(local - np.round(local)) < 1e-9
        if not on.any():
            continue
        # Every voxel the point touches: both sides along each axis it lies on.
        choices = [
            (int(round(c)) - 1, int(round(c))) if on[a] else (int(np.floor(c)),)
            for a, c in enumerate(local)
        ]
        if any(grid.get(*v) != 0 for v in itertools.product(*choices)):
            faces.append(tuple(p))
    return faces


@pytest.mark.parametrize("case", range(len(CASES)))
def test_gpu_matches_cpu_on_generated_grids(case, cpu, gpu):
    shape, fill, overrides = CASES[case]
    rng = np.random.default_rng(1000 + case)
    grid = vx.Grid.from_numpy(random_grid(rng, shape, fill))
    e = vx.load(
        EXPERIMENTS / "baseline.toml",
        set={"render.width": 24, "render.height": 16, **overrides},
    ).with_grid(grid)
    assert e.grid.shape == shape
    reference = cpu.render(e)
    assert not lights_on_voxel_faces(e, reference), "a light on a face: see the test below"
    assert_close(gpu.render(e), reference, f"case {case} {shape} {overrides}")


def test_a_light_on_a_voxel_face(cpu, gpu):
    """The seed's third light for an 8^3 grid sits at (6.5, 3.0, 6.5): on the top face
    of voxel (6, 2, 6). A shadow segment towards it used to enter that voxel exactly at
    its end, and rounding decided the whole light: the f32 kernel and the f64 reference
    disagreed (found by the generated grids above). Segments now end eps short of their
    light (the contract, "Shading a hit"), so both see it from the face's open side."""
    a = np.zeros((8, 8, 8), dtype=np.uint8)
    a[5, 3, 4] = a[6, 2, 6] = 3
    e = vx.load(
        EXPERIMENTS / "baseline.toml", set={"render.width": 24, "render.height": 16}
    ).with_grid(vx.Grid.from_numpy(a))
    reference = cpu.render(e)
    assert lights_on_voxel_faces(e, reference) == [(6.5, 3.0, 6.5)]
    assert_close(gpu.render(e), reference, "light on a face")


@pytest.mark.parametrize(
    "overrides",
    [
        {"features.shadow_model": "area", "render.light_samples": 2},
        {"features.shadow_model": "area", "render.light_samples": 1, "render.spp": 4},
        {"features.shadow_model": "cone"},
        # The a-trous filter of the sampled shadow term (docs/reconstruction.md).
        {"features.shadow_model": "ratio", "features.reconstruction": "atrous"},
        {
            "features.shadow_model": "area",
            "features.reconstruction": "atrous",
            "techniques.atrous.iterations": 2,
            "render.spp": 4,
        },
        # SVGF over a camera path of four frames on a slow orbit: the history crosses
        # the session's renders of the path on both backends.
        {
            "features.shadow_model": "ratio",
            "features.reconstruction": "svgf",
            "render.path_frames": 4,
            "render.orbit_deg": 1.5,
            "techniques.svgf.iterations": 2,
        },
    ],
)
def test_gpu_matches_cpu_with_area_lights(overrides, cpu, gpu):
    e = vx.load(
        EXPERIMENTS / "area_lights.toml",
        set={"render.width": 20, "render.height": 20, "render.spp": 2, **overrides},
    )
    assert_close(gpu.render(e), cpu.render(e), str(overrides))


def test_a_session_renders_many_experiments_in_turn(cpu, gpu):
    """One session, different kernels and scenes in turn: nothing of one render leaks
    into the next (the pipelines and uploads are cached by what they depend on)."""
    a = vx.load(EXPERIMENTS / "baseline.toml", set={"render.width": 16, "render.height": 12})
    b = a.with_overrides(["features.transmittance=beer-lambert"])
    first = gpu.render(a).radiance.copy()
    gpu.render(b)
    again = gpu.render(a).radiance
    assert np.array_equal(first, again)
    assert_close(gpu.render(b), cpu.render(b), "after a switch")


def test_a_ray_offset_the_kernel_cannot_resolve_is_warned_of(cpu, gpu):
    """A `render.ray_offset` below two f32 ulps of the grid's side is accepted (it is in
    the key's range) and warned of on the GPU, in the image and in its record; the CPU
    reference, in f64, has no such warning, nor has the default offset."""
    e = vx.load(EXPERIMENTS / "baseline.toml", set={"render.width": 8, "render.height": 8})
    for offset, warned in [(0.0, True), (1e-7, True), (1e-3, False)]:
        o = e.with_overrides([f"render.ray_offset={offset!r}"])
        image = gpu.render(o)
        assert bool(image.warnings) == warned, (offset, image.warnings)
        assert image.provenance["warnings"] == image.warnings
        for w in image.warnings:
            assert w.startswith("render.ray_offset") and "two f32 ulps" in w, w
        assert cpu.render(o).warnings == []
