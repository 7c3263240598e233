#!/usr/bin/env python3
"""Whether tungsten renders a pathspace TOML scene as pathspace does: means and Welch's t.

    export TUNGSTEN=/path/to/tungsten/build/tungsten
    python3 benches/peers/agree.py SCENE.toml --pathspace path bdpt \\
        --tungsten path_tracer bidirectional_path_tracer --spp 64 --runs 4 --res 32

Each method renders the scene (converted by `to_tungsten.py` for tungsten) `--runs` times at
`--spp` with seeds 1..runs, one process per render on `--threads` threads. Printed per method:
the image mean per channel with its standard error from the spread of the runs' means; per
method after the first, against the first (pathspace's first): the per-channel difference,
Welch's t and its p-value (Student's t, Welch-Satterthwaite degrees of freedom), and the 8x8
block test of `benches/compare_xml.py` (Bonferroni over all blocks and channels). Where the
runs do not tell apart, the methods agree within noise; the test can only find a difference,
never prove there is none.
"""

import argparse
import json
import math
import os
import sys
import tempfile
from types import SimpleNamespace

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
from compare_xml import blocks, t_and_p  # noqa: E402
from run import ROOT, image, run  # noqa: E402
from scene import Refused, Scene  # noqa: E402
import to_tungsten  # noqa: E402


def render(a, renderer, method, seed, work):
    out = os.path.join(work, f"{renderer}-{method}-{seed}")
    if renderer == "pathspace":
        integ, _, variant = method.partition("-")
        cmd = [a.bin, "render", a.scene, "--integrator", integ, "--spp", str(a.spp), "--seed",
               str(seed), "--threads", str(a.threads), "--resolution", f"{a.res}x{a.res}",
               "-o", out + ".exr"]
        if variant == "equiangular":
            cmd += ["--distance", "equiangular-mis"]
        run(cmd, out + ".log", limit=3600)
        return image(out + ".exr")
    scene = os.path.join(work, f"{method}.json")
    if not os.path.exists(scene):
        with open(scene, "w") as f:
            json.dump(to_tungsten.convert(Scene(a.scene), method, [a.res, a.res], grids=work,
                                          binary=a.bin), f)
    os.makedirs(out, exist_ok=True)
    run([a.tungsten, "--threads", str(a.threads), "--seed", str(seed), "--spp", str(a.spp),
         "-d", out, scene], out + ".log", limit=3600)
    return image(os.path.join(out, "out.pfm"))


def main():
    import numpy as np
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--pathspace", nargs="*", default=["path"], help="pathspace methods")
    ap.add_argument("--tungsten", nargs="*", default=["path_tracer"], help="tungsten methods")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--runs", type=int, default=4)
    ap.add_argument("--res", type=int, default=32, help="square resolution")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "pathspace"))
    a = ap.parse_args()
    a.scene = os.path.abspath(a.scene)
    a.tungsten_bin = os.environ.get("TUNGSTEN")
    if a.tungsten and not (a.tungsten_bin and os.access(a.tungsten_bin, os.X_OK)):
        raise SystemExit("set TUNGSTEN to tungsten's binary")
    methods = [("pathspace", m) for m in a.pathspace] + [("tungsten", m) for m in a.tungsten]
    a.tungsten = a.tungsten_bin
    runs = {}
    with tempfile.TemporaryDirectory(prefix="agree-") as work:
        try:
            for r, m in methods:
                runs[(r, m)] = np.stack([render(a, r, m, s, work) for s in range(1, a.runs + 1)])
        except Refused as e:
            raise SystemExit(f"{a.scene}: tungsten refused: {e}")
    print(f"{os.path.relpath(a.scene)}: {a.runs} runs of {a.spp} spp at {a.res}x{a.res}")
    stats = {}
    for k, imgs in runs.items():
        means = imgs.reshape(a.runs, -1, 3).mean(1)
        stats[k] = (means.mean(0), means.std(0, ddof=1) / math.sqrt(a.runs))
        m, se = stats[k]
        print(f"  {k[0]} {k[1]}: mean RGB " + ", ".join(f"{m[c]:.6g} +- {se[c]:.2g}" for c in range(3)))
    first = methods[0]
    for k in methods[1:]:
        (m1, s1), (m2, s2) = stats[k], stats[first]
        print(f"  {k[0]} {k[1]} against {first[0]} {first[1]}: mean ratio "
              f"{m1.sum() / m2.sum():.4f}")
        for c in range(3):
            t, pv = t_and_p(m1[c], s1[c], a.runs, m2[c], s2[c], a.runs)
            print(f"    channel {'RGB'[c]}: difference {m1[c] - m2[c]:+.3g}, combined standard "
                  f"error {math.hypot(s1[c], s2[c]):.3g}, t = {t:+.2f}, p = {pv:.3f}")
        print("   ", end="")
        blocks(SimpleNamespace(runs=a.runs), runs[k], runs[first])


if __name__ == "__main__":
    main()
