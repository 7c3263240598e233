# %% [markdown]
# # A sigma_s sweep
# The fog box with the scattering coefficient from thin to thick: each value a changed copy of
# the scene (`traverse` / `update`), rendered with the same seed; the mean radiance against
# sigma_s, and the images side by side.

# %%
import os
import pathlib

import numpy as np
import pathspace

ROOT = pathlib.Path(os.environ.get("PATHSPACE_ROOT", pathlib.Path.cwd()))
while not (ROOT / "scenes").is_dir() and ROOT != ROOT.parent:
    ROOT = ROOT.parent
SMALL = bool(os.environ.get("PATHSPACE_EXAMPLE_SMALL"))
size, spp = ((24, 24), 8) if SMALL else ((128, 128), 128)
values = [0.0, 0.2, 0.4, 0.8, 1.6, 3.2]

# %%
scene = pathspace.load_file(ROOT / "scenes" / "fog-box.toml", resolution=size)
params = scene.traverse()
print("sigma_s is", params["media.fog.sigma_s"])
rows = []
for s in values:
    params["media.fog.sigma_s"] = s
    r = params.update().render(spp=spp, seed=1)
    se = np.sqrt(r.variance.mean(axis=(0, 1)) / r.image[..., 0].size)
    rows.append((s, r.image, r.image.mean(axis=(0, 1)), se))
    print(f"sigma_s = {s:4.1f}: mean radiance {rows[-1][2]}")

# %%
try:
    import matplotlib

    if SMALL:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(rows) + 1, figsize=(3 * (len(rows) + 1), 3))
    for ax, (s, img, _, _) in zip(axes, rows):
        ax.imshow(np.clip(img, 0, 1) ** (1 / 2.2))
        ax.set_title(f"sigma_s = {s}")
        ax.axis("off")
    means = np.array([m for _, _, m, _ in rows])
    errors = np.array([e for _, _, _, e in rows])
    for c, colour in enumerate("rgb"):
        axes[-1].errorbar(values, means[:, c], yerr=errors[:, c], color=colour, marker="o")
    axes[-1].set_xlabel("sigma_s")
    axes[-1].set_ylabel("mean radiance")
    fig.tight_layout()
    fig.savefig("sigma-s-sweep.png")
    print("wrote sigma-s-sweep.png")
except ImportError:
    print("matplotlib is not installed: no plot")
