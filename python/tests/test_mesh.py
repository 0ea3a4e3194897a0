"""`voxlab mesh` calls each material's surface a "closed 2-manifold": checked here by
trimesh, a tool nobody here wrote (`is_watertight`, `is_winding_consistent`,
`is_volume`), on the files the command writes (PLY and OBJ), for the shipped
experiments and for generated grids full of voxels that touch only along an edge or at
a corner, at several relaxations. Vertex manifoldness (open3d's `is_vertex_manifold`:
a vertex's triangles are one fan) has no trimesh call and is counted here from the
faces."""

import re
from collections import defaultdict

import numpy as np
import pytest
import trimesh

from conftest import EXPERIMENTS, cli


def materials_said_closed(stdout):
    """{material index: its line} for the materials `voxlab mesh` reports."""
    said = {}
    for line in stdout.splitlines():
        m = re.match(r"\s+(\d+)\s.*\s(\d+) triangles, (.*)$", line)
        if m:
            said[int(m.group(1))] = m.group(3)
    return said


def ply_by_material(path):
    """The PLY's vertices, faces and each face's material (its `material` property)."""
    mesh = trimesh.load(path, process=False)
    raw = mesh.metadata["_ply_raw"]["face"]["data"]
    return mesh.vertices, mesh.faces, np.asarray(raw["material"]).reshape(-1)


def obj_by_material(path, names):
    """The OBJ's vertices, faces and each face's material (its `usemtl` group),
    read as text: trimesh would split the groups into a scene of its own."""
    vertices, faces, material = [], [], []
    current = None
    for line in path.read_text().splitlines():
        word, _, rest = line.partition(" ")
        if word == "v":
            vertices.append([float(x) for x in rest.split()])
        elif word == "usemtl":
            current = names[rest]
        elif word == "f":
            faces.append([int(c.split("/")[0]) - 1 for c in rest.split()])
            material.append(current)
    return np.array(vertices), np.array(faces), np.array(material)


def vertex_fans_are_single(faces):
    """Each vertex's triangles are connected through the edges at the vertex."""
    around = defaultdict(list)
    for f, tri in enumerate(faces):
        for v in tri:
            around[v].append(f)
    for v, fs in around.items():
        others = [set(faces[f]) - {v} for f in fs]
        seen, stack = {0}, [0]
        while stack:
            i = stack.pop()
            for j in range(len(fs)):
                if j not in seen and others[i] & others[j]:
                    seen.add(j)
                    stack.append(j)
        if len(seen) != len(fs):
            return False
    return True


def check_closed(vertices, faces, material, said, label):
    assert said, f"{label}: voxlab reported no material"
    assert set(np.unique(material)) == set(said), (label, said)
    for k, words in said.items():
        # Welded by position, as trimesh does on load.
        sub = trimesh.Trimesh(vertices, faces[material == k], process=True)
        verdict = {
            "watertight": sub.is_watertight,
            "winding consistent": sub.is_winding_consistent,
            "volume": sub.is_volume,
            "vertex manifold": vertex_fans_are_single(sub.faces),
        }
        if words == "closed 2-manifold":
            assert all(verdict.values()), f"{label}: material {k} said closed, trimesh: {verdict}"
        else:
            assert not all(verdict.values()), f"{label}: material {k} said {words!r}, trimesh: {verdict}"


def random_contacts(rng, dims, fill):
    """An experiment of single-voxel boxes of the seed's three materials, placed at
    random: neighbours that meet only along edges and at corners everywhere."""
    lines = ['name = "contacts"', "[scene]", 'generator = "empty"', f"dims = {list(dims)}"]
    for x in range(dims[0]):
        for y in range(dims[1]):
            for z in range(dims[2]):
                if rng.random() < fill:
                    lines += [
                        "[[scene.boxes]]",
                        f"min = [{x}, {y}, {z}]",
                        f"max = [{x + 1}, {y + 1}, {z + 1}]",
                        f"material = {int(rng.integers(1, 4))}",
                    ]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("name", ["baseline.toml", "deer_smooth.toml", "bunny_glass.toml"])
def test_shipped_surfaces_are_closed_by_trimesh(name, tmp_path):
    out = tmp_path / "surface.ply"
    proc = cli("mesh", EXPERIMENTS / name, "--out", out)
    vertices, faces, material = ply_by_material(out)
    said = materials_said_closed(proc.stdout)
    check_closed(vertices, faces, material, said, name)
    # The check itself: one triangle gone, or one turned over, and trimesh says so.
    first = int(np.flatnonzero(material == min(said))[0])
    with pytest.raises(AssertionError, match="said closed"):
        check_closed(vertices, np.delete(faces, first, 0), np.delete(material, first), said, name)
    flipped = faces.copy()
    flipped[first] = flipped[first][::-1]
    with pytest.raises(AssertionError, match="said closed"):
        check_closed(vertices, flipped, material, said, name)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("relax", [0, 8, 64])
def test_generated_contacts_are_closed_by_trimesh_in_both_formats(seed, relax, tmp_path):
    rng = np.random.default_rng(seed)
    exp = tmp_path / "contacts.toml"
    exp.write_text(random_contacts(rng, (6, 5, 7), 0.3 + 0.1 * seed))
    ply, obj = tmp_path / "s.ply", tmp_path / "s.obj"
    said = materials_said_closed(cli("mesh", exp, "--out", ply, "--relax", relax).stdout)
    check_closed(*ply_by_material(ply), said, f"seed {seed}, relax {relax}, PLY")
    again = materials_said_closed(cli("mesh", exp, "--out", obj, "--relax", relax).stdout)
    assert again == said
    # The seed's palette (`info`'s names, as `usemtl` writes them).
    names = {"glass": 1, "semi-solid": 2, "solid": 3}
    check_closed(*obj_by_material(obj, names), said, f"seed {seed}, relax {relax}, OBJ")
