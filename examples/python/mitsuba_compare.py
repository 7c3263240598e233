# %% [markdown]
# # pathspace and Mitsuba 3 on one Mitsuba XML scene
# The same Mitsuba 3 XML file rendered by both (`pip install mitsuba`), side by side with the
# difference image and pathspace's error metrics. Not run in CI (it needs Mitsuba).

# %%
import os
import pathlib

import numpy as np
import pathspace

ROOT = pathlib.Path(os.environ.get("PATHSPACE_ROOT", pathlib.Path.cwd()))
while not (ROOT / "scenes").is_dir() and ROOT != ROOT.parent:
    ROOT = ROOT.parent
xml = ROOT / "scenes" / "xml" / "hg-sphere.xml"
spp = int(os.environ.get("SPP", "256"))

# %%
ours = pathspace.load_file(xml).render(integrator="path", spp=spp, seed=1).image

# %%
import mitsuba as mi

mi.set_variant("scalar_rgb")
theirs = np.array(mi.render(mi.load_file(str(xml)), spp=spp), dtype=np.float32)[..., :3]
print("shapes", ours.shape, theirs.shape)
print("pathspace vs Mitsuba:", pathspace.diff(ours, theirs))

# %%
import matplotlib.pyplot as plt

fig, axes = plt.subplots(1, 3, figsize=(12, 4))
for ax, (title, img) in zip(axes, [("pathspace", ours), ("Mitsuba 3", theirs)]):
    ax.imshow(np.clip(img, 0, 1) ** (1 / 2.2))
    ax.set_title(title)
    ax.axis("off")
d = (ours - theirs).mean(axis=-1)
lim = np.abs(d).max() or 1.0
im = axes[2].imshow(d, cmap="RdBu", vmin=-lim, vmax=lim)
axes[2].set_title("pathspace - Mitsuba")
axes[2].axis("off")
fig.colorbar(im, ax=axes[2])
plt.show()
