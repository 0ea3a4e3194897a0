"""The registry, the metrics, and ablate through Python."""

import json
import shutil

import numpy as np
import pytest

import voxlab as vx

from conftest import EXPERIMENTS, cli, ctrl_c_after


def test_techniques_are_the_command_lines_registry():
    mine = vx.techniques()
    assert mine == json.loads(cli("techniques", "--json").stdout)
    names = {(t["slot"], t["name"]) for t in mine}
    assert ("shadow model", "area") in names and ("transmittance", "beer-lambert") in names
    for t in mine:
        assert t["summary"] and t["switch"]
        for s in t["settings"]:
            if "type" in s:
                assert s["type"] in ("int", "float") and s["range"]


def test_settings_are_the_command_lines_and_the_parser_holds_them():
    mine = vx.settings()
    assert mine == json.loads(cli("settings", "--json").stdout)
    keys = [s["key"] for s in mine]
    assert len(keys) == len(set(keys))
    assert {"scene.size", "render.width", "camera.vfov_deg", "ablate.seeds"} <= set(keys)
    # Each [render] and [camera] number with a lower bound: the bound itself loads (if
    # closed) and a step below it is refused under the key, in the listed words.
    checked = 0
    for s in mine:
        table, key = s["key"].rsplit(".", 1)
        if table not in ("render", "camera") or s["min"] is None:
            continue
        step = 1 if s["type"] == "int" else max(abs(s["min"]) * 1e-3, 1e-9)
        if not s["min_open"]:
            vx.load({table: {key: s["min"]}})
        below = int(s["min"] - step) if s["type"] == "int" else s["min"] - step
        with pytest.raises(vx.VoxlabError) as e:
            vx.load({table: {key: below}})
        assert s["key"] in str(e.value) and s["range"] in str(e.value), (s, str(e.value))
        checked += 1
    assert checked >= 15


def test_rmse_is_the_root_mean_square_over_every_channel():
    rng = np.random.default_rng(3)
    a = rng.random((5, 7, 3), dtype=np.float32)
    b = rng.random((5, 7, 3), dtype=np.float32)
    expected = np.sqrt(np.mean((a.astype(np.float64) - b) ** 2))
    assert vx.rmse(a, b) == pytest.approx(expected, rel=1e-12)
    assert vx.rmse(a, a) == 0.0
    assert vx.rmse(a.astype(np.float64), b) == pytest.approx(expected, rel=1e-6)
    with pytest.raises(vx.VoxlabError, match="different sizes"):
        vx.rmse(a, b[:4])
    with pytest.raises(vx.VoxlabError, match="height, width, 3"):
        vx.rmse(a[..., :2], b[..., :2])


def test_flip_mean_and_map(cpu):
    a = np.full((16, 16, 3), 0.5, dtype=np.float32)
    mean, m = vx.flip(a, a)
    assert mean == 0.0 and m.shape == (16, 16) and m.dtype == np.float32
    b = a.copy()
    b[4:8, 4:8] = 1.0
    mean, m = vx.flip(a, b)
    assert 0 < mean < 1 and m[5, 5] > m[12, 12]
    assert mean == pytest.approx(float(m.astype(np.float64).mean()), rel=1e-6)
    # The viewing distance matters, and the default is ablate's (67 pixels per degree).
    assert vx.flip(a, b, ppd=200)[0] != vx.flip(a, b, ppd=20)[0]
    assert vx.flip(a, b)[0] == vx.flip(a, b, ppd=67)[0]
    with pytest.raises(vx.VoxlabError, match="ppd"):
        vx.flip(a, b, ppd=0)


ABLATE = """name = "tiny"
[scene]
size = 8
[[lights]]
type = "rect"
position = [7.0, 12.0, 11.0]
normal = [-3.0, -8.0, -7.0]
size = [4.0, 4.0]
intensity = 200.0
[render]
width = 16
height = 16
[ablate]
reference_spp = 16
spp = [1, 2]
seeds = 2
runs = 1
warmup = 0
backend = "cpu"
reference_backend = "cpu"
"""


def test_ablate_returns_the_csvs_rows_and_its_files(tmp_path):
    src = tmp_path / "tiny.toml"
    src.write_text(ABLATE)
    result = vx.ablate(src, tmp_path / "out")
    csv_text = (tmp_path / "out" / "ablation.csv").read_text().splitlines()
    header = csv_text[0].split(",")
    rows = result.rows
    assert list(rows.columns) == header  # a DataFrame: pandas is installed here
    assert len(rows) == len(csv_text) - 1 > 0
    assert set(rows["spp"]) >= {1, 2}
    assert all(p.exists() for p in result.files)
    assert tmp_path / "out" / "plot.png" in result.files
    # An experiment loaded from the file brings its overrides.
    e = vx.load(src, set={"ablate.spp": [1]})
    again = vx.ablate(e, tmp_path / "out2")
    assert set(again.rows["spp"]) == {1}
    # Its own input as output (ablate writes experiment.toml): refused, nothing written.
    own = tmp_path / "own"
    own.mkdir()
    (own / "experiment.toml").write_text(ABLATE)
    with pytest.raises(vx.VoxlabError, match="input"):
        vx.ablate(own / "experiment.toml", own)
    assert [p.name for p in own.iterdir()] == ["experiment.toml"]
    assert (own / "experiment.toml").read_text() == ABLATE
    # Refusals name the keyword argument, not the command line's option.
    with pytest.raises(vx.VoxlabError) as refused:
        vx.ablate(own / "experiment.toml", own)
    assert f"out={own}:" in str(refused.value) and "--out" not in str(refused.value)
    with pytest.raises(vx.VoxlabError) as refused:
        vx.ablate(src, own / "experiment.toml")
    said = str(refused.value)
    assert f"out={own / 'experiment.toml'}:" in said and "this is a file" in said, said
    with pytest.raises(vx.VoxlabError) as refused:
        vx.load(src).export_mitsuba(own / "experiment.toml")
    said = str(refused.value)
    assert said.startswith(f"{own / 'experiment.toml'}:") and "--to" not in said, said


def test_ablate_sweeps_an_experiment_given_as_text_or_a_dict(tmp_path):
    """An experiment without a file (text, a dict, with overrides) is swept as its file
    would be: the same rows, errors and images, its text copied into the outputs; one
    whose grid was replaced is refused, naming why."""
    import tomllib

    from PIL import Image

    src = tmp_path / "tiny.toml"
    src.write_text(ABLATE)
    by_file = vx.ablate(src, tmp_path / "file", set={"ablate.seeds": 1})
    by_text = vx.ablate(vx.load(ABLATE, set={"ablate.seeds": 1}), tmp_path / "text")
    by_dict = vx.ablate(vx.load(tomllib.loads(ABLATE)), tmp_path / "dict", set={"ablate.seeds": 1})
    errors = [c for c in by_file.rows.columns if c.startswith(("rmse", "flip"))]
    assert errors, list(by_file.rows.columns)
    for other in (by_text, by_dict):
        assert [p.name for p in other.files] == [p.name for p in by_file.files]
        assert other.rows[errors].equals(by_file.rows[errors])
        pngs = sorted((other.out / "images").glob("*.png"))
        assert pngs
        for image in pngs:
            # The pixels: the records beside them name where the experiment came from.
            same = by_file.out / "images" / image.name
            assert Image.open(image).tobytes() == Image.open(same).tobytes(), image.name
    copied = tomllib.loads((tmp_path / "text" / "experiment.toml").read_text())
    assert copied["ablate"]["seeds"] == 1 and copied["name"] == "tiny"
    # Its inputs are as safe as a file's: a model kept where ablate writes its images.
    kept = tmp_path / "kept"
    (kept / "images").mkdir(parents=True)
    shutil.copy(EXPERIMENTS / "data" / "deer.vox", kept / "images" / "deer.vox")
    text = ABLATE.replace("size = 8\n", f'vox = "{kept / "images" / "deer.vox"}"\n')
    with pytest.raises(vx.VoxlabError, match="lies in"):
        vx.ablate(vx.load(text), kept)
    assert sorted(p.name for p in kept.rglob("*")) == ["deer.vox", "images"]
    grid = vx.load(ABLATE).grid
    with pytest.raises(vx.VoxlabError, match="grid was replaced"):
        vx.ablate(vx.load(ABLATE).with_grid(grid), tmp_path / "grid")
    assert not (tmp_path / "grid").exists()


def test_the_type_stubs_cover_every_public_name():
    """voxlab/__init__.pyi documents every public function, class and member, so an
    editor completes and documents each call."""
    import ast
    import inspect
    from pathlib import Path

    stub = ast.parse((Path(vx.__file__).parent / "__init__.pyi").read_text())
    declared = {}
    for node in stub.body:
        if isinstance(node, ast.ClassDef):
            declared[node.name] = {
                n.name for n in node.body if isinstance(n, (ast.FunctionDef, ast.AnnAssign))
                for n in [n] if not isinstance(n, ast.AnnAssign)
            } | {n.target.id for n in node.body if isinstance(n, ast.AnnAssign)}
        elif isinstance(node, ast.FunctionDef):
            declared[node.name] = set()
    for name in vx.__all__:
        assert name in declared, f"{name} has no stub"
        obj = getattr(vx, name)
        if inspect.isclass(obj) and name not in ("VoxlabError", "AblateResult"):
            public = {m for m in dir(obj) if not m.startswith("_")}
            assert public <= declared[name], f"{name}: {public - declared[name]} have no stub"


def test_ctrl_c_stops_ablate_between_renders(tmp_path):
    src = tmp_path / "tiny.toml"
    # Many points and runs: the sweep takes far longer than the test waits.
    src.write_text(ABLATE.replace("runs = 1", "runs = 50"))
    seen = []
    with pytest.raises(KeyboardInterrupt), ctrl_c_after(1.0):
        vx.ablate(src, tmp_path / "out", progress=lambda d, t: seen.append((d, t)))
    assert seen and seen[-1][1] > 0
    # No table of a sweep that did not finish.
    assert not (tmp_path / "out" / "ablation.csv").exists()
