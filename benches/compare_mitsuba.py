#!/usr/bin/env python3
"""pathspace against Mitsuba 3 on the fog box at equal CPU time, in one command.

    python3 -m venv venv && venv/bin/pip install mitsuba numpy openexr
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so   # llvm_ad_rgb (Debian libllvm19)
    cargo build --release
    venv/bin/python benches/compare_mitsuba.py --cpu 20 --runs 4

Every render is a process of its own and is charged the CPU seconds of the whole process (scene
loading and Mitsuba's JIT compilation included), read from the kernel (RUSAGE_CHILDREN), so a
comparison on a busy machine stays fair. Each renderer's spp for the budget comes from two
timed probes (cost = fixed + per-spp). The reference is the average of a pathspace render and a
Mitsuba `scalar_rgb` render of `--reference-spp` each: neither renderer judges itself alone, and
the reference's own noise (estimated from the two halves' difference, which also bounds any bias
between the renderers) is subtracted from every relMSE. relMSE is pathspace's metric
(`measure::metrics::compare`): the mean over pixels and channels of (a - b)^2 / (b^2 + 1e-2).

pathspace renders one row per integrator of `--integrators` (default: `path`, the same estimator
family as Mitsuba's `volpath`, and `bdpt`, which Mitsuba has no volumetric counterpart of), and
the last lines give each row's relMSE x CPU-s over each Mitsuba variant's.

`--pathspace-flags "..."` adds flags to pathspace's rows (`"--halo-cone 0.1"`), not to its
half of the reference.

`--max-depth D` counts scattering vertices as pathspace does; Mitsuba's `max_depth` is D + 1
(its depth 1 is emission seen directly). `--per-depth` prints the variance per sample of each
renderer at depths 1, 2, 3 and unlimited (independent runs, no reference needed): the
term-by-term comparison of the book's "Measuring a renderer".
"""
import argparse
import os
import shlex
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
XML = os.path.join(ROOT, "benches", "mitsuba-fog-box.xml")
SCENE = os.path.join(ROOT, "scenes", "fog-box.toml")
from exr_metrics import EPSILON, child_cpu, read, relmse  # noqa: E402,F401


def worker(variant, spp, seed, out, res, max_depth):
    """Renders the fog box with Mitsuba in this process (a child of the main script)."""
    import mitsuba as mi
    mi.set_variant(variant)
    import drjit as dr
    dr.set_thread_count(2)
    md = -1 if max_depth < 0 else max_depth + 1
    scene = mi.load_file(XML, res=res, max_depth=md)
    img = mi.render(scene, spp=spp, seed=seed)
    mi.Bitmap(img).write(out)




def render(renderer, spp, seed, out, a, flags=True):
    """Renders and returns the CPU seconds of the process. `renderer` is a Mitsuba variant or
    `pathspace-INTEGRATOR`; a pathspace render takes `--pathspace-flags` unless `flags` is
    false (the reference)."""
    if renderer.startswith("pathspace-"):
        integrator = renderer.split("-", 1)[1]
        cmd = [a.bin, "render", SCENE, "--integrator", integrator, "--spp", str(spp),
               "--seed", str(seed), "--threads", "2", "--resolution", f"{a.res}x{a.res}",
               "-o", out]
        if a.max_depth >= 0:
            cmd += ["--max-depth", str(a.max_depth)]
        if flags:
            cmd += shlex.split(a.pathspace_flags)
    else:
        cmd = [sys.executable, __file__, "--worker", renderer, str(spp), str(seed), out,
               str(a.res), str(a.max_depth)]
    before = child_cpu()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return child_cpu() - before






def spp_for_budget(renderer, a, scratch):
    """spp whose render costs `a.cpu` CPU seconds: cost = fixed + per_spp * spp, from probes."""
    lo, hi = 4, 32
    c_lo = render(renderer, lo, 1000, os.path.join(scratch, f"{renderer}-probe-lo.exr"), a)
    c_hi = render(renderer, hi, 1001, os.path.join(scratch, f"{renderer}-probe-hi.exr"), a)
    per_spp = max((c_hi - c_lo) / (hi - lo), 1e-6)
    fixed = max(c_lo - lo * per_spp, 0.0)
    return max(1, round((a.cpu - fixed) / per_spp)), fixed, per_spp


def per_depth(a, renderers, scratch):
    """Variance per sample at depths 1, 2, 3 and unlimited, from `a.runs` runs of 16 spp."""
    import numpy as np
    print(f"variance per sample (relative, eps {EPSILON}), {a.runs} runs of 16 spp at {a.res}x{a.res}")
    print(f"{'renderer':<15}" + "".join(f"{'depth ' + d:>12}" for d in ["1", "2", "3", "all"]))
    for r in renderers:
        row = []
        for d in [1, 2, 3, -1]:
            a.max_depth = d
            imgs = []
            for k in range(a.runs):
                out = os.path.join(scratch, f"{r}-d{d}-{k}.exr")
                render(r, 16, k + 1, out, a)
                imgs.append(read(out))
            imgs = np.stack(imgs)
            var = imgs.var(0, ddof=1)
            row.append(float((var / (imgs.mean(0) ** 2 + EPSILON)).mean()) * 16)
        print(f"{r:<15}" + "".join(f"{v:>12.4f}" for v in row))


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        v, spp, seed, out, res, md = sys.argv[2:8]
        worker(v, int(spp), int(seed), out, int(res), int(md))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cpu", type=float, default=20.0, help="CPU seconds per render")
    ap.add_argument("--runs", type=int, default=4, help="independent runs per renderer")
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--max-depth", type=int, default=-1)
    ap.add_argument("--reference-spp", type=int, default=2048)
    ap.add_argument("--variants", nargs="+", default=["scalar_rgb", "llvm_ad_rgb"])
    ap.add_argument("--integrators", nargs="+", default=["path", "bdpt"],
                    help="pathspace integrators to compare (each a row)")
    ap.add_argument("--per-depth", action="store_true")
    ap.add_argument("--pathspace-flags", default="",
                    help="more flags for pathspace's rows (not its reference render), one string")
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "pathspace"))
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "compare-mitsuba"))
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    renderers = [f"pathspace-{i}" for i in a.integrators] + a.variants
    if a.per_depth:
        per_depth(a, renderers, a.out)
        return
    import numpy as np
    ref_a = os.path.join(a.out, "reference-pathspace.exr")
    ref_b = os.path.join(a.out, "reference-mitsuba.exr")
    render("pathspace-path", a.reference_spp, 99, ref_a, a, flags=False)
    render("scalar_rgb", a.reference_spp, 99, ref_b, a)
    ra, rb = read(ref_a), read(ref_b)
    ref = 0.5 * (ra + rb)
    # E relMSE(ra, rb) = var_a + var_b (+ bias^2); the average's own variance is a quarter of it
    halves = relmse(ra, rb)
    ref_noise = halves / 4
    print(f"reference: {a.reference_spp} spp of pathspace and of Mitsuba scalar_rgb at "
          f"{a.res}x{a.res}; relMSE between the two {halves:.3e}, the average's own noise "
          f"{ref_noise:.3e} (subtracted below)")
    print(f"{'renderer':<15} {'spp':>6} {'CPU s':>8} {'relMSE':>10} {'+-':>9} {'relMSE x CPU-s':>15}")
    product = {}
    for r in renderers:
        spp, fixed, per_spp = spp_for_budget(r, a, a.out)
        errs, cpus = [], []
        for k in range(a.runs):
            out = os.path.join(a.out, f"{r}-{spp}spp-{k}.exr")
            cpus.append(render(r, spp, k + 1, out, a))
            errs.append(relmse(read(out), ref) - ref_noise)
        e, c = np.mean(errs), np.mean(cpus)
        se = np.std(errs, ddof=1) / np.sqrt(len(errs)) if len(errs) > 1 else float("nan")
        product[r] = e * c
        print(f"{r:<15} {spp:>6} {c:>8.1f} {e:>10.3e} {se:>9.1e} {e * c:>15.4f}"
              f"   (fixed {fixed:.1f} s, {per_spp * 1e3:.1f} ms per spp)")
    # the target: relMSE x CPU-s of pathspace at most half of llvm_ad_rgb's
    for v in [v for v in a.variants if v in product]:
        for r in [r for r in renderers if r.startswith("pathspace-")]:
            print(f"{r} / {v}: relMSE x CPU-s ratio {product[r] / product[v]:.2f}")


if __name__ == "__main__":
    main()
