"""Grids from and to numpy: the axis order ([x, y, z], y up), dtypes, strides,
palettes, and the errors of arrays that are no grid."""

import numpy as np
import pytest

import voxlab as vx

from conftest import EXPERIMENTS


@pytest.mark.parametrize("shape", [(1, 1, 1), (3, 5, 7), (7, 1, 4), (16, 9, 2)])
def test_round_trip_and_index_order(shape):
    rng = np.random.default_rng(sum(shape))
    a = rng.integers(0, 4, size=shape, dtype=np.uint8)
    g = vx.Grid.from_numpy(a)
    assert g.shape == shape
    back = g.to_numpy()
    assert back.dtype == np.uint8 and back.shape == shape
    assert np.array_equal(back, a)
    # Axis 0 is x, 1 is y, 2 is z: every voxel through the grid's own lookup.
    for x, y, z in np.ndindex(*shape):
        assert g.get(x, y, z) == a[x, y, z]
    # Outside the grid is void.
    assert g.get(-1, 0, 0) == 0 and g.get(shape[0], 0, 0) == 0
    # Held x fastest: the array is a Fortran-ordered view of the grid's order.
    assert back.flags["F_CONTIGUOUS"]


def test_one_voxel_lands_where_its_index_says():
    a = np.zeros((4, 3, 2), dtype=np.uint8)
    a[3, 1, 0] = 2
    g = vx.Grid.from_numpy(a)
    assert [g.get(3, 1, 0), g.get(0, 1, 3), g.get(1, 3, 0)] == [2, 0, 0]


def test_axis_1_is_up_in_the_image(cpu):
    """A slab at y = 0 is seen below one at the top: the seed's camera looks down on the
    grid with +y up (row 0 of an image is its top)."""
    base = vx.load(EXPERIMENTS / "baseline.toml", set={"render.width": 32, "render.height": 32})

    def lit_row(slab):
        a = np.zeros((8, 8, 8), dtype=np.uint8)
        a[slab] = 3
        img = cpu.render(base.with_grid(vx.Grid.from_numpy(a))).radiance.max(axis=2)
        rows = np.nonzero(img > img.min() + 1e-3)[0]
        return rows.mean()

    bottom = lit_row((slice(None), 0, slice(None)))
    top = lit_row((slice(None), 7, slice(None)))
    assert bottom > top + 4, (bottom, top)


@pytest.mark.parametrize(
    "view",
    [
        lambda a: a.T.copy().T,  # Fortran order
        lambda a: np.asfortranarray(a),
        lambda a: np.ascontiguousarray(a[::-1, :, :])[::-1, :, :],  # negative strides
        lambda a: np.repeat(a, 2, axis=2)[:, :, ::2],  # a strided view
    ],
)
def test_any_layout_gives_the_same_grid(view):
    rng = np.random.default_rng(5)
    a = rng.integers(0, 4, size=(5, 4, 3), dtype=np.uint8)
    v = view(a)
    assert np.array_equal(v, a)
    assert np.array_equal(vx.Grid.from_numpy(v).to_numpy(), a)


def test_integer_dtypes_in_range_are_accepted():
    a = np.array([[[0, 1], [2, 3]]], dtype=np.int64)
    assert np.array_equal(vx.Grid.from_numpy(a).to_numpy(), a.astype(np.uint8))
    assert vx.Grid.from_numpy(np.ones((2, 2, 2), dtype=bool)).get(1, 1, 1) == 1


@pytest.mark.parametrize(
    "array, words",
    [
        (np.full((2, 2, 2), 300, dtype=np.int32), "0..=255"),
        (np.full((2, 2, 2), -1, dtype=np.int8), "0..=255"),
        (np.zeros((2, 2, 2), dtype=np.float32), "dtype float32"),
        (np.zeros((4, 4), dtype=np.uint8), "3D array"),
        (np.zeros((0, 2, 2), dtype=np.uint8), "at least 1"),
        (np.full((2, 2, 2), 9, dtype=np.uint8), "material 9"),
    ],
)
def test_arrays_that_are_no_grid_are_refused(array, words):
    with pytest.raises(vx.VoxlabError, match=words):
        vx.Grid.from_numpy(array)


def test_a_palette_of_ones_own():
    a = np.zeros((4, 4, 4), dtype=np.uint8)
    a[:, 0, :] = 1
    a[1, 1, 1] = 2
    palette = [
        {"name": "chalk", "albedo": [0.9, 0.9, 0.85], "kd": 0.9},
        {"name": "mirror", "kr": 0.9, "ks": 0.5, "shininess": 100.0},
    ]
    g = vx.Grid.from_numpy(a, palette=palette)
    assert g.palette == ["void", "chalk", "mirror"]
    with pytest.raises(vx.VoxlabError, match="material 2"):
        vx.Grid.from_numpy(a, palette=palette[:1])
    with pytest.raises(vx.VoxlabError) as bad:
        vx.Grid.from_numpy(a, palette=[{"name": "x", "kd": -1.0}, palette[1]])
    assert bad.value.key == "materials[0].kd"
    with pytest.raises(vx.VoxlabError, match="unknown|not allowed|colour"):
        vx.Grid.from_numpy(a, palette=[{"name": "x", "colour": [1, 1, 1]}])


def test_a_grid_through_numpy_renders_as_the_generator_made_it(cpu):
    """The seed's voxels out to numpy and back: the same image, bit for bit, on the
    f64 reference; and the record names the same voxels."""
    e = vx.load(EXPERIMENTS / "baseline.toml", set={"render.width": 24, "render.height": 16})
    again = e.with_grid(vx.Grid.from_numpy(e.grid.to_numpy()))
    a, b = cpu.render(e), cpu.render(again)
    assert np.array_equal(a.radiance, b.radiance)
    assert a.provenance["grid"] == b.provenance["grid"]
    assert again.source is None  # no longer the file's scene


def test_the_camera_and_lights_follow_a_new_grid_unless_the_file_set_them(cpu):
    base = vx.load(EXPERIMENTS / "baseline.toml", set={"render.width": 16, "render.height": 16})
    small = np.zeros((4, 4, 4), dtype=np.uint8)
    small[:, 0, :] = 3
    # The seed's camera aims at the grid's centre from 2.5 widths + 3: a 4^3 grid fills
    # the frame as the 16^3 one does, not a speck in the corner.
    img = cpu.render(base.with_grid(vx.Grid.from_numpy(small))).radiance
    lit = np.mean(img.max(axis=2) > img.max() * 0.05)
    assert lit > 0.05
