# %% [markdown]
# # The book's anisotropy sweep of SMC, from Python
# "SMC: experiments", *Anisotropy (Henyey-Greenstein g)*: on the albedo-0.8 test bed, SMC's
# control variate (is0_cv2) gains over plain Monte Carlo (is0_cv0) at g = 0 and loses it as the
# phase function grows anisotropic. Each g is a changed copy of the scene (the medium's phase
# parameter); each variant is an option of the one schema (`smc={"variant": ...}`); the RMSE
# is `pathspace.diff` against a reference of many more samples. Small sizes with
# `PATHSPACE_EXAMPLE_SMALL=1` (the trend, not the book's numbers).

# %%
import os
import pathlib

import pathspace

ROOT = pathlib.Path(os.environ.get("PATHSPACE_ROOT", pathlib.Path.cwd()))
while not (ROOT / "scenes").is_dir() and ROOT != ROOT.parent:
    ROOT = ROOT.parent
SMALL = bool(os.environ.get("PATHSPACE_EXAMPLE_SMALL"))
size, spp, ref_spp = ((12, 12), 16, 256) if SMALL else ((32, 32), 256, 16384)
gs = [0.0, 0.3, 0.9]
variants = ["is0_cv0", "is0_cv2"]

# %%
scene = pathspace.load_file(ROOT / "scenes" / "smc-testbed-albedo-0.8.toml", resolution=size)
table = []
for g in gs:
    params = scene.traverse()
    params["media.fog.phase"] = {"type": "hg", "g": g}
    tilted = params.update()
    reference = tilted.render(integrator="path", spp=ref_spp, seed=1000)
    row = {"g": g}
    for v in variants:
        r = tilted.render(integrator="smc", spp=spp, seed=1, smc={"variant": v})
        row[v] = pathspace.diff(r, reference)["rmse"]
    row["gain"] = (row["is0_cv0"] / row["is0_cv2"]) ** 2
    table.append(row)

# %%
print(f"{'g':>4} {'is0_cv0 RMSE':>13} {'is0_cv2 RMSE':>13} {'cv2 gain (relMSE)':>18}")
for row in table:
    print(f"{row['g']:4.1f} {row['is0_cv0']:13.3e} {row['is0_cv2']:13.3e} {row['gain']:18.2f}")
