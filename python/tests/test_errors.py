"""Every error of a bad file, text, dict or override is a VoxlabError (a ValueError)
with the command line's message, file, line and key."""

import numpy as np
import pytest

import voxlab as vx

from conftest import EXPERIMENTS, cli


def cli_error(*args) -> str:
    proc = cli("render", *args, "--backend", "cpu", "--out", "unused.png", check=False)
    assert proc.returncode != 0, "the command line accepted it"
    lines = [l for l in proc.stderr.splitlines() if l.startswith("error: ")]
    assert lines, proc.stderr
    return lines[0][len("error: "):]


BAD_FILES = {
    "range": ("[render]\nwidth = 0\n", "render.width", 2),
    "unknown key": ("[render]\nwidht = 5\n", "render.widht", 2),
    "type": ('[render]\nspp = "many"\n', "render.spp", 2),
    "syntax": ("[render\nwidth = 5\n", None, 1),
    "choice": ('[features]\nshadow_model = "fuzzy"\n', "features.shadow_model", 2),
    "light": ('[[lights]]\ntype = "point"\nposition = [0, 1]\nintensity = 1.0\n', "lights[0].position", 3),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_bad_file_raises_the_command_lines_error(case, tmp_path):
    text, key, line = BAD_FILES[case]
    path = tmp_path / f"{case.replace(' ', '_')}.toml"
    path.write_text(text)
    with pytest.raises(vx.VoxlabError) as e:
        vx.load(path)
    assert isinstance(e.value, ValueError)
    assert str(e.value) == cli_error(path)
    assert e.value.file == str(path)
    if key is not None:
        assert e.value.key == key
    assert e.value.line == line
    # The same text given as a string: the same message, named by `name`.
    with pytest.raises(vx.VoxlabError) as t:
        vx.load(text, name=str(path))
    assert str(t.value) == str(e.value)


OVERRIDES = [
    {"render.width": 0},
    {"render.widht": 5},
    {"render.spp": "many"},
    {"features.shadow_model": "fuzzy"},
    {"techniques.sdf.softness": -1.0},
    {"lights[7].intensity": 2.0},
    {"render.width": float("nan")},
    {"render.ray_cutoff": 1e300},
    {"render.width": 2**70},
    {"render.spp": -(2**63) - 1},
]


@pytest.mark.parametrize("overrides", OVERRIDES, ids=lambda o: ",".join(o))
def test_a_bad_override_raises_the_command_lines_error(overrides):
    path = EXPERIMENTS / "baseline.toml"
    with pytest.raises(vx.VoxlabError) as e:
        vx.load(path, set=overrides)
    args = []
    for k, v in overrides.items():
        args += ["--set", f"{k}={vx._toml_value(k, v)}"]
    assert str(e.value) == cli_error(path, *args)


def test_a_bad_dict_names_its_key():
    with pytest.raises(vx.VoxlabError) as e:
        vx.load({"render": {"width": 16, "height": -3}})
    assert e.value.key == "render.height"
    assert "1..=16384" in str(e.value)
    with pytest.raises(vx.VoxlabError, match="render.spp: None has no TOML value"):
        vx.load({"render": {"spp": None}})
    with pytest.raises(vx.VoxlabError, match=r"lights\[1\].color\[1\]: None"):
        vx.load({"lights": [{"type": "point"}, {"color": [1, None, 1]}]})
    with pytest.raises(vx.VoxlabError, match="has no TOML value"):
        vx.load(EXPERIMENTS / "baseline.toml", set={"render.width": object()})


NON_FINITE_DICTS = [
    ({"render": {"filter_width": float("inf")}}, "render.filter_width", "= inf: must be a finite number in (0, 4]"),
    ({"render": {"width": float("nan")}}, "render.width", "must be an integer in 1..=16384"),
    ({"materials": [{"name": "a"}, {"name": "b", "kd": float("-inf")}]}, "materials[1].kd", "= -inf: must be a finite number in [0, 1]"),
    ({"camera": {"target": np.array([0.0, np.nan, 0.0])}}, "camera.target", "= [0.0, nan, 0.0]"),
    ({"lights": [{"type": "point", "position": [1, 2, 3], "intensity": np.float32("inf")}]}, "lights[0].intensity", "must be a finite number >= 0"),
]


@pytest.mark.parametrize("d,key,says", NON_FINITE_DICTS, ids=lambda c: str(c)[:40])
def test_a_non_finite_number_in_a_dict_is_named_by_its_key(d, key, says):
    """JSON has no NaN or infinity: a dict's reach TOML's, so the key's own check says
    what it allows (the encoder used to refuse the whole dict, naming nothing)."""
    with pytest.raises(vx.VoxlabError) as e:
        vx.load(d)
    assert e.value.key == key, str(e.value)
    assert says in str(e.value)
    # A palette of Grid.from_numpy is read the same way.
    if "materials" in d:
        with pytest.raises(vx.VoxlabError) as p:
            vx.Grid.from_numpy(np.ones((2, 2, 2), np.uint8), palette=d["materials"])
        assert p.value.key == key and says in str(p.value), str(p.value)


BIG_INT_DICTS = [
    ({"render": {"width": 2**70}}, "render.width", "= 1180591620717411303424: past what 64 bits hold", "1..=16384"),
    ({"render": {"spp": 2**63}}, "render.spp", "= 9223372036854775808: past what 64 bits hold", "1..=65536"),
    ({"render": {"spp": np.uint64(2**64 - 1)}}, "render.spp", "= 18446744073709551615: past", "1..=65536"),
    ({"scene": {"generator": "empty", "dims": [4, -(2**80), 4]}}, "scene.dims[1]", "= -1208925819614629174706176: past", "1..=268435456"),
    ({"materials": [{"name": "a"}, {"name": "b", "shininess": 10**30}]}, "materials[1].shininess", "= 1000000000000000000000000000000: past", ">= 0"),
]


@pytest.mark.parametrize("d,key,says,range_", BIG_INT_DICTS, ids=lambda c: str(c)[:40])
def test_an_integer_past_64_bits_in_a_dict_is_named_with_its_range(d, key, says, range_):
    """A JSON reader takes an integer past 64 bits as a float (2**70 was "invalid type:
    floating point `1.18e21`"), and one past 63 bits was refused without its range: the
    integer reaches the parser as written, which says what a file's would."""
    with pytest.raises(vx.VoxlabError) as e:
        vx.load(d)
    assert e.value.key == key, str(e.value)
    assert says in str(e.value) and range_ in str(e.value), str(e.value)
    if "materials" in d:
        with pytest.raises(vx.VoxlabError) as p:
            vx.Grid.from_numpy(np.ones((2, 2, 2), np.uint8), palette=d["materials"])
        assert p.value.key == key and says in str(p.value), str(p.value)


def test_a_string_like_a_mark_stays_a_string():
    e = vx.load({"name": "voxlab-raw-0", "render": {"width": 8, "height": 8}})
    assert e.name == "voxlab-raw-0"


def test_numpy_values_in_a_palette_are_numbers():
    g = vx.Grid.from_numpy(
        np.ones((2, 2, 2), np.uint8),
        palette=[{"name": "chalk", "kd": np.float32(0.5), "albedo": np.array([1.0, 0.5, 0.25])}],
    )
    assert g.palette == ["void", "chalk"]


def test_a_missing_file_and_a_file_of_the_wrong_kind(tmp_path):
    with pytest.raises(vx.VoxlabError) as e:
        vx.load(tmp_path / "missing.toml")
    assert str(e.value) == cli_error(tmp_path / "missing.toml")
    png = tmp_path / "image.toml"
    png.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)))
    with pytest.raises(vx.VoxlabError) as e:
        vx.load(png)
    assert str(e.value) == cli_error(png)
    with pytest.raises(vx.VoxlabError):
        vx.load(tmp_path)  # a directory


def test_a_dict_loads_like_its_file():
    d = {
        "scene": {"generator": "seed", "size": 8},
        "render": {"width": 12, "height": 10, "spp": 3},
        "features": {"transmittance": "beer-lambert"},
    }
    e = vx.load(d, name="mine")
    assert (e.width, e.height, e.spp, e.name) == (12, 10, 3, "mine")
    assert e.grid.shape == (8, 8, 8)


def test_bad_sessions_and_render_arguments():
    with pytest.raises(vx.VoxlabError, match='"gpu" or "cpu"'):
        vx.Session("tpu")
    with pytest.raises(TypeError):
        vx.Session("cpu").render("experiments/baseline.toml")
