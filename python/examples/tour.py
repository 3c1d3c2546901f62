# %% [markdown]
# # phenomena from Python
#
# A notebook-style tour (cells marked `# %%`: open it in Jupyter with jupytext, VS Code
# or Spyder, or run it as a script). Every frame and export here is what the
# `phenomena` command writes for the same scene. Run from the repository's root:
#
#     pip install ./python
#     python python/examples/tour.py

# %%
import os
import re
import sys
import tempfile

import numpy as np

import phenomena

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
OUT = sys.argv[1] if len(sys.argv) > 1 else tempfile.mkdtemp(prefix="phenomena-tour-")
os.makedirs(OUT, exist_ok=True)

# %% [markdown]
# ## A scene file, its frames as linear radiance

# %%
flame = phenomena.Scene(os.path.join(REPO, "scenes", "flame-paper.toml"))
print(flame)
image = flame.render(30, width=320, height=180)  # frame 30: the state after 31 steps
print("frame 30:", image.shape, image.dtype, "mean radiance", float(image.mean()))
flame.save_exr(os.path.join(OUT, "flame_00030.exr"))  # `render --format exr --width 320 --height 180`

# %% [markdown]
# ## Particles, volumes and checkpoints

# %%
particles = flame.points()
print("particles:", len(particles["x"]), "hottest", float(particles["temperature"].max()), "K")
grids = flame.volume(voxel_m=0.01)
density, origin = grids["density"].to_dense()
print("density grid:", density.shape, "voxels from index", origin)
checkpoint = flame.state()
later = flame.render(60)
again = phenomena.Scene(os.path.join(REPO, "scenes", "flame-paper.toml"))
again.restore(checkpoint)  # continues bit for bit
assert np.array_equal(again.render(60, width=320, height=180), later)

# %% [markdown]
# ## A scene written in Python, with a progress callback

# %%
text = re.sub(r"^frames = \d+", "frames = 24", phenomena.starter("aurora"), flags=re.M)
aurora = phenomena.Scene.from_toml(text, name="aurora.toml")
sky, lines = aurora.render(12, width=320, height=180, layers=True,
                           progress=lambda done, total: print(f"  {done}/{total}", end="\r"))
print("\naurora layers:", sorted(lines))

# %% [markdown]
# ## Snow on geometry held in memory

# %%
ground = [[-2, 0, -2], [2, 0, -2], [2, 0, 2], [-2, 0, 2]]
box = [[x, y, z] for x in (-0.5, 0.5) for y in (0.0, 1.0) for z in (-0.5, 0.5)]
vertices = np.array(ground + box, dtype=np.float32)
c = lambda x, y, z: 4 + 4 * x + 2 * y + z  # noqa: E731
quads = [(c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)), (c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)),
         (c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)), (c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)),
         (c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1))]
triangles = [[0, 2, 1], [0, 3, 2]] + [t for a, b, cc, d in quads for t in ([a, b, cc], [a, cc, d])]
objects = [0, 0] + [1] * (len(triangles) - 2)
cover = phenomena.snow_cover(vertices, triangles, objects, depth_cm=6.0, snow={"repose_deg": 40.0})
print("snow:", len(cover.triangles), "triangles, highest at", float(cover.positions[:, 1].max()), "m")
with open(os.path.join(OUT, "snow.toml"), "w") as f:
    f.write(cover.scene_toml)  # `phenomena export snow-mesh snow.toml` makes the same snow
with open(os.path.join(OUT, "geometry.obj"), "wb") as f:
    f.write(cover.geometry_obj)

# %% [markdown]
# ## Problems are located

# %%
try:
    phenomena.Scene.from_toml("[scene]\nframes = 0\n[flame]\n", name="broken.toml")
except phenomena.SceneError as e:
    for p in e.problems:
        print(f"{p.file}:{p.line}:{p.column}: {p.message}")
print("outputs in", OUT)
