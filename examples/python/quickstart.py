# %% [markdown]
# # pathspace quick start
# Load the fog box, render it to a numpy array, look at it, write the EXR the command line
# writes. `PATHSPACE_EXAMPLE_SMALL=1` renders small (as CI does).

# %%
import os
import pathlib

import numpy as np
import pathspace

ROOT = pathlib.Path(os.environ.get("PATHSPACE_ROOT", pathlib.Path.cwd()))
while not (ROOT / "scenes").is_dir() and ROOT != ROOT.parent:
    ROOT = ROOT.parent
SMALL = bool(os.environ.get("PATHSPACE_EXAMPLE_SMALL"))
size, spp = ((32, 32), 16) if SMALL else ((256, 256), 256)

# %%
scene = pathspace.load_file(ROOT / "scenes" / "fog-box.toml", resolution=size)
result = scene.render(integrator="path", spp=spp, seed=1)
print(result, result.image.shape, result.image.dtype)
print("mean pixel", result.image.mean(axis=(0, 1)))
print("estimated relMSE", result.stats["estimated_relmse"])

# %%
try:
    import matplotlib

    if SMALL:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.imshow(np.clip(result.image, 0, 1) ** (1 / 2.2))
    plt.title(f"fog box, {result.spp} spp")
    plt.axis("off")
    plt.show()
except ImportError:
    print("matplotlib is not installed: no picture")

# %%
result.write("fog-box-python.exr")
print("wrote fog-box-python.exr:", result.provenance["render_options"])
