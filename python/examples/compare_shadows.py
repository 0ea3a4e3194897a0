# %% [markdown]
# # Two shadow models on the bunny: error against samples per pixel
#
# A notebook in percent format (Jupyter opens it through jupytext; VS Code and PyCharm
# run its cells as they are; `python compare_shadows.py` runs it whole). It lights the
# Stanford bunny (experiments/data/bunny.obj, public domain) with one rectangular
# light, renders a converged reference with the sampled `area` model, then measures
# against it:
#
# - `area` at increasing spp, over several sample seeds: the error falls as 1/sqrt(spp)
#   towards zero, and the seeds give its spread (mean and 95 % interval);
# - `sdf` (distance-field soft shadows, Quilez 2010): deterministic, one frame, so one
#   error, biased: the price of its speed.
#
# `VOXLAB_EXAMPLE_QUICK=1` makes it small enough for a test; `VOXLAB_BACKEND=cpu`
# renders with the f64 reference instead of the GPU kernel.

# %%
import os
from pathlib import Path

import numpy as np

import voxlab as vx

QUICK = os.environ.get("VOXLAB_EXAMPLE_QUICK") == "1"
BACKEND = os.environ.get("VOXLAB_BACKEND", "gpu")
OUT = Path(os.environ.get("VOXLAB_EXAMPLE_OUT", "out/compare_shadows"))
REPO = Path(__file__).resolve().parents[2] if "__file__" in globals() else Path.cwd()

SIZE = 48 if QUICK else 256
RESOLUTION = 32 if QUICK else 96
SPP = [1, 2, 4] if QUICK else [1, 2, 4, 8, 16, 32]
SEEDS = 3 if QUICK else 5
REFERENCE_SPP = 64 if QUICK else 1024

session = vx.Session(BACKEND)
print(session.label)

# %% [markdown]
# The bunny is voxelized on load; its grid tells where to put the light: above and in
# front, a quarter of the bunny's size across.

# %%
bunny = REPO / "experiments" / "data" / "bunny.obj"
scene = f"""
[scene]
mesh = {str(bunny)!r}
resolution = {RESOLUTION}
material = "solid"

[render]
width = {SIZE}
height = {SIZE}
"""
grid = vx.load(scene, name="bunny").grid
lo = np.array(grid.origin)
extent = np.array(grid.shape) * grid.voxel_size
centre = lo + extent / 2
light = centre + extent * np.array([0.4, 0.9, 0.6])
side = 0.25 * extent.max()

lights = f"""
[[lights]]
type = "rect"
position = {list(map(float, light))}
normal = {list(map(float, centre - light))}
size = [{side}, {side}]
intensity = {4.0 * float(np.sum((light - centre) ** 2))}
"""
experiment = vx.load(scene + lights, name="bunny_area", set={"render.light_samples": 1})
print(experiment, experiment.plan, sep="\n")

# %% [markdown]
# The reference: the sampled model with many frames, from seeds no measured render uses.

# %%
reference = session.render(
    experiment,
    spp=REFERENCE_SPP,
    set={"features.shadow_model": "area", "render.seed": 1_000_000},
)
reference.save(OUT / "reference.exr")

# %% [markdown]
# Error against spp for `area` (each spp over `SEEDS` seeds), and `sdf` once.

# %%
rows = []
for spp in SPP:
    for seed in range(SEEDS):
        image = session.render(
            experiment,
            spp=spp,
            set={"features.shadow_model": "area", "render.seed": seed},
        )
        rows.append(("area", spp, seed, vx.rmse(image, reference), image.time_ms))
sdf = session.render(experiment, set={"features.shadow_model": "sdf"})
rows.append(("sdf", 1, 0, vx.rmse(sdf, reference), sdf.time_ms))


def mean_interval(values):
    """Mean and half-width of its 95 % interval (Student's t, as voxlab ablate)."""
    values = np.asarray(values, dtype=float)
    t975 = {2: 12.706, 3: 4.303, 4: 3.182, 5: 2.776, 6: 2.571}
    if len(values) < 2:
        return values.mean(), 0.0
    return values.mean(), t975.get(len(values), 2.0) * values.std(ddof=1) / np.sqrt(len(values))


area = {spp: mean_interval([r[3] for r in rows if r[0] == "area" and r[1] == spp]) for spp in SPP}
for spp, (m, h) in area.items():
    print(f"area  spp {spp:5d}: rmse {m:.4g} +- {h:.2g}")
print(f"sdf   (1 frame): rmse {rows[-1][3]:.4g}, {rows[-1][4]:.2f} ms")

# %% [markdown]
# The figure: error bars are the 95 % intervals over seeds; a difference inside them is
# no finding.

# %%
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(5, 3.6), dpi=120)
means = np.array([area[s][0] for s in SPP])
halves = np.array([area[s][1] for s in SPP])
ax.errorbar(SPP, means, yerr=halves, marker="o", capsize=3, label=f"area ({SEEDS} seeds, 95 %)")
ax.axhline(rows[-1][3], color="tab:orange", linestyle="--", label="sdf (deterministic)")
ax.set_xscale("log", base=2)
ax.set_yscale("log")
ax.set_xlabel("samples per pixel (frames)")
ax.set_ylabel(f"RMSE against {REFERENCE_SPP} spp")
ax.set_title("Soft shadows on the bunny")
ax.legend()
fig.tight_layout()
OUT.mkdir(parents=True, exist_ok=True)
figure = OUT / "error_vs_spp.png"
fig.savefig(figure)
with open(OUT / "error_vs_spp.csv", "w") as f:
    f.write("model,spp,seed,rmse,trace_ms\n")
    for r in rows:
        f.write(",".join(map(str, r)) + "\n")
print("wrote", figure)
