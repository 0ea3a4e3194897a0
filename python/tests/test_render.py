"""Sessions and images: the record re-renders through the command line, saving is all
or nothing, Ctrl-C stops a render, the GIL is released, progress is reported."""

import json
import threading
import time

import numpy as np
import pytest
from PIL import Image as PILImage

import voxlab as vx

from conftest import EXPERIMENTS, cli, ctrl_c_after, small


def test_image_fields(cpu):
    e = small("area_lights.toml", spp=2)
    im = cpu.render(e)
    assert im.radiance.shape == (16, 24, 3) and im.radiance.dtype == np.float32
    assert (im.width, im.height, im.frames) == (24, 16, 2)
    assert not im.radiance.flags.writeable
    assert im.rays["primary"] == 24 * 16 * 2 and im.rays["shadow"] > 0
    assert im.time_ms > 0 and im.wall_ms >= im.time_ms
    p = im.provenance
    assert p["width"] == 24 and p["spp"] == 2 and p["plan"] == im.plan
    assert p["overrides"] == ["render.width=24", "render.height=16", "render.spp=2"]
    assert p["source"] == str(EXPERIMENTS / "area_lights.toml")


@pytest.mark.parametrize("backend", ["cpu", "gpu"])
def test_the_record_re_renders_the_same_image_through_the_command_line(backend, tmp_path, request):
    session = request.getfixturevalue(backend)
    e = small("area_lights.toml", spp=2, **{"features.transmittance": "beer-lambert"})
    im = session.render(e, set={"render.seed": 7})
    mine = tmp_path / "python.png"
    im.save(mine)
    record = json.loads((tmp_path / "python.png.json").read_text())
    assert record["output"] == str(mine)
    resolved = tmp_path / "resolved.toml"
    resolved.write_text(record["resolved_experiment"])
    theirs = tmp_path / "cli.png"
    cli("render", resolved, "--backend", backend, "--out", theirs)
    a = np.asarray(PILImage.open(mine))
    b = np.asarray(PILImage.open(theirs))
    if backend == "cpu":
        assert np.array_equal(a, b)
    else:
        # The device's own floating point: the GPU tests' tolerance on 8-bit values.
        d = np.abs(a.astype(int) - b.astype(int)).max(axis=2)
        assert np.mean(d > 2) <= 0.005


@pytest.mark.parametrize(
    "source, name, want",
    [
        ({"scene": {"size": 8}, "render": {"width": 8, "height": 8}}, None, "_dict_"),
        ("[scene]\nsize = 8\n[render]\nwidth = 8\nheight = 8\n", None, "_text_"),
        ({"render": {"width": 8, "height": 8}}, "my sweep", "my_sweep"),
    ],
)
def test_a_dict_or_text_renders_saves_and_records(cpu, tmp_path, source, name, want):
    """Loaded without a file, the experiment is named after its label made a valid name
    (its image once rendered and then had no record: "<dict>" is no experiment name),
    and its record's resolved experiment keeps its [scene] (it once gave an empty one,
    which rendered the seed's 16^3 scene in place of the 8^3)."""
    e = vx.load(source, name=name)
    assert e.name == want
    im = cpu.render(e)
    assert im.provenance["experiment"] == want
    im.save(tmp_path / "a.png")
    resolved = tmp_path / "resolved.toml"
    resolved.write_text(json.loads((tmp_path / "a.png.json").read_text())["resolved_experiment"])
    cli("render", resolved, "--backend", "cpu", "--out", tmp_path / "b.png")
    assert np.array_equal(
        np.asarray(PILImage.open(tmp_path / "a.png")), np.asarray(PILImage.open(tmp_path / "b.png"))
    )


def test_a_record_of_voxels_in_memory_says_it_does_not_give_them(cpu):
    a = np.zeros((6, 6, 6), dtype=np.uint8)
    a[1:5, 0, 1:5] = 3
    e = small("baseline.toml").with_grid(vx.Grid.from_numpy(a))
    resolved = cpu.render(e).provenance["resolved_experiment"]
    assert resolved.startswith(
        "# Written by voxlab from an experiment whose voxels were given in memory"
    )


def test_an_experiment_edited_on_disk_renders_and_records_what_was_loaded(cpu, tmp_path):
    """The file changed after vx.load: the image is the loaded experiment's, and its
    record quotes the file as it was read (it used to read the file again: the record's
    hash and scene were the edited file's, and re-rendered another image); ablate,
    which reads the file, refuses."""
    text = (EXPERIMENTS / "reconstruction.toml").read_text()
    path, original = tmp_path / "mine.toml", tmp_path / "original.toml"
    path.write_text(text)
    original.write_text(text)
    e = vx.load(path, set={"render.width": 12, "render.height": 9})
    edited = text.replace("min = [6, 1, 8]", "min = [2, 1, 2]").replace("yaw_deg = 25.0", "yaw_deg = 70.0")
    assert edited != text
    path.write_text(edited)
    im = cpu.render(e)
    # The record of the same text rendered through the command line.
    theirs = tmp_path / "cli.exr"
    cli("render", original, "--backend", "cpu", "--width", 12, "--height", 9, "--out", theirs)
    record = json.loads((tmp_path / "cli.exr.json").read_text())
    assert im.provenance["assets"][0]["blake3"] == record["assets"][0]["blake3"]
    again = tmp_path / "again.toml"
    again.write_text(im.provenance["resolved_experiment"])
    assert np.array_equal(cpu.render(vx.load(again)).radiance, im.radiance)
    with pytest.raises(vx.VoxlabError, match="changed on disk since the experiment was loaded"):
        vx.ablate(e, tmp_path / "ablate")
    assert not (tmp_path / "ablate").exists()


def test_save_is_all_or_nothing(cpu, tmp_path):
    im = cpu.render(small("baseline.toml"))
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / "image.bmp")  # a format voxlab does not write
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / "dir.png")
    (tmp_path / "file").write_text("not a directory")
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / "file" / "x.png")
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / "x.png", display="gamma")
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / "x.png", exposure=float("nan"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.png", "file"]
    im.save(tmp_path / "x.exr")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dir.png", "file", "x.exr", "x.exr.json"]


def test_save_takes_the_exposures_the_command_line_takes(cpu, tmp_path):
    """One range of exposures: `Image.save` took [-64, 64] where `render --exposure`
    took [-32, 32] (and the viewer 16)."""
    im = cpu.render(small("baseline.toml"))
    for ev in (-32, 32):
        im.save(tmp_path / f"ok{ev}.png", exposure=ev)
        cli("render", EXPERIMENTS / "baseline.toml", "--backend", "cpu", "--width", "8",
            "--height", "8", "--exposure", ev, "--out", tmp_path / f"cli{ev}.png")
        assert PILImage.open(tmp_path / f"ok{ev}.png").size == (24, 16)
    for ev in (-32.5, 33, 64):
        with pytest.raises(vx.VoxlabError) as e:
            im.save(tmp_path / "x.png", exposure=ev)
        proc = cli("render", EXPERIMENTS / "baseline.toml", "--backend", "cpu",
                   "--exposure", ev, "--out", tmp_path / "y.png", check=False)
        assert proc.returncode != 0
        assert str(e.value) in proc.stderr, (str(e.value), proc.stderr)
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "y.png").exists()


def long_render():
    """A CPU render of many seconds (area lights, 96x96, 64 frames)."""
    return small("area_lights.toml", 96, 96, spp=64)


def test_ctrl_c_stops_a_render_within_a_second_and_the_session_goes_on(cpu):
    e = long_render()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt), ctrl_c_after(0.5):
        cpu.render(e, progress=False)
    stopped = time.monotonic() - start - 0.5
    # Within a row of the reference (a row of 96 pixels x 64 frames); the whole render
    # takes far longer.
    assert stopped < 2.0, f"stopped {stopped:.2f} s after Ctrl-C"
    again = cpu.render(small("baseline.toml"))
    assert np.isfinite(again.radiance).all()


def test_ctrl_c_stops_a_gpu_render_and_the_session_goes_on(gpu):
    e = small("area_lights.toml", 256, 256, spp=4096)
    with pytest.raises(KeyboardInterrupt), ctrl_c_after(1.0):
        gpu.render(e, progress=False)
    a = gpu.render(small("baseline.toml")).radiance
    assert np.isfinite(a).all()


def test_the_gil_is_released_while_rendering(cpu):
    ticks = []
    done = threading.Event()

    def count():
        while not done.is_set():
            ticks.append(1)
            time.sleep(0.001)

    t = threading.Thread(target=count)
    t.start()
    try:
        cpu.render(small("area_lights.toml", 48, 48, spp=8))
    finally:
        done.set()
        t.join()
    assert len(ticks) > 20


def test_progress_reaches_its_total(cpu):
    seen = []
    cpu.render(small("area_lights.toml", 64, 64, spp=16), progress=lambda d, t: seen.append((d, t)))
    assert seen and seen[-1][0] == seen[-1][1] == 64  # rows of the CPU reference
    assert all(a[0] <= b[0] for a, b in zip(seen, seen[1:]))


def test_an_error_in_the_progress_callback_stops_the_render(cpu):
    def broken(done, total):
        raise RuntimeError("callback failed")

    with pytest.raises(RuntimeError, match="callback failed"):
        cpu.render(long_render(), progress=broken)


def test_spp_and_set_override_the_experiment(cpu):
    e = small("area_lights.toml")
    im = cpu.render(e, spp=3, set={"render.light_samples": 2})
    assert im.frames == 3 and im.provenance["light_samples"] == 2
    assert e.spp == 16  # the experiment itself is unchanged
    with pytest.raises(vx.VoxlabError, match="render.spp"):
        cpu.render(e, spp=0)


def test_save_fails_whole_on_an_odd_name_or_a_blocked_record(cpu, tmp_path):
    """An over-long name, and a record that cannot be written after the image could
    (`x.png.json` is a directory): an error, and nothing of the save is left."""
    im = cpu.render(small("baseline.toml", 8, 8))
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / ("n" * 300 + ".png"))
    (tmp_path / "x.png.json").mkdir()
    with pytest.raises(vx.VoxlabError):
        im.save(tmp_path / "x.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.png.json"]
    assert not any((tmp_path / "x.png.json").iterdir())


def test_an_experiment_keeps_its_description(cpu):
    """The file's `description`, as every record quotes it (the record's resolved
    experiment keeps it too); None without one."""
    e = vx.load(EXPERIMENTS / "ablate_area.toml")
    assert e.description == "seed scene, one rect area light, Beer-Lambert: error against time"
    text = '[render]\nwidth = 4\nheight = 4\n'
    assert vx.load(text).description is None
    d = vx.load('description = "odd \\"quoted\\" \\u00e9"\n' + text)
    assert d.description == 'odd "quoted" \u00e9'
    im = cpu.render(d)
    assert vx.load(im.provenance["resolved_experiment"]).description == d.description
