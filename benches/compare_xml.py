#!/usr/bin/env python3
"""One Mitsuba 3 scene XML rendered by Mitsuba 3 and by pathspace (its importer), side by side.

    python3 -m venv venv && venv/bin/pip install mitsuba numpy openexr
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so   # llvm_ad_rgb
    cargo build --release
    venv/bin/python benches/compare_xml.py scenes/xml/hg-sphere.xml --spp 256 --runs 4

Each renderer renders the scene `--runs` times with independent seeds at `--spp` (a process per
render, charged its CPU seconds from RUSAGE_CHILDREN, scene loading and Mitsuba's JIT
included). Printed per renderer: the image mean per channel with its standard error (from the
spread of the runs' means, Student-t with runs - 1 degrees of freedom), the CPU seconds per
render, and relMSE (pathspace's metric, mean of (a - b)^2 / (b^2 + 1e-2)) of one run against
the other renderer's converged image (the mean of its runs) next to the same run against its own
renderer's other runs (the noise level). The verdict per channel is Welch's t of the two means,
its p-value from Student's t with the Welch-Satterthwaite degrees of freedom (no SciPy needed);
the 8x8 block test applies the same per block and channel, Bonferroni over all of them.

`-D name=value` overrides a `<default>` of the XML (both renderers read a copy written beside it),
`--res N` is `-D res=N`;
`--variant` picks Mitsuba's variant (`llvm_ad_rgb` by default, `scalar_rgb` needs no LLVM).
pathspace reads the XML with its own defaults ($spp is overridden by --spp in both).
"""
import argparse
import math
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
from exr_metrics import EPSILON, child_cpu, read, relmse, student_t_two_sided  # noqa: E402,F401


def worker(variant, xml, spp, seed, out):
    """Renders `xml` with Mitsuba in this process (a child of the main script)."""
    import mitsuba as mi
    mi.set_variant(variant)
    import drjit as dr
    dr.set_thread_count(2)
    scene = mi.load_file(xml)
    img = mi.render(scene, spp=int(spp), seed=int(seed))
    mi.Bitmap(img).write(out)


def render(renderer, a, seed, out):
    """Renders and returns the CPU seconds of the process."""
    if renderer == "pathspace":
        cmd = [a.bin, "render", a.xml, "--spp", str(a.spp), "--seed", str(seed),
               "--threads", "2", "-o", out]
    else:
        cmd = [sys.executable, __file__, "--worker", a.variant, a.xml, str(a.spp), str(seed),
               out]
    before = child_cpu()
    r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit(f"{renderer} failed:\n{r.stderr}")
    return child_cpu() - before


def t_and_p(m1, s1, n1, m2, s2, n2):
    """Welch's t for means m with standard errors s from n runs, and its two-sided p-value from
    Student's t with Welch-Satterthwaite degrees of freedom (a normal tail would call a
    difference real too often at a few runs)."""
    if s1 + s2 <= 0:
        return 0.0, 1.0
    t = (m1 - m2) / math.sqrt(s1 * s1 + s2 * s2)
    dof = (s1 ** 2 + s2 ** 2) ** 2 / (s1 ** 4 / (n1 - 1) + s2 ** 4 / (n2 - 1))
    return t, student_t_two_sided(t, dof)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        worker(*sys.argv[2:])
        return
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("xml")
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--runs", type=int, default=4)
    p.add_argument("--res", type=int, default=0, help="-D res=N")
    p.add_argument("-D", action="append", default=[], metavar="NAME=VALUE",
                   help="override a <default> of the XML")
    p.add_argument("--variant", default="llvm_ad_rgb")
    p.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "pathspace"))
    a = p.parse_args()
    a.xml = os.path.abspath(a.xml)
    shown = a.xml
    if a.res > 0:
        a.D.append(f"res={a.res}")
    if a.D:
        a.xml = with_defaults(a.xml, a.D)
    try:
        compare(a, shown)
    finally:
        if a.xml != shown:
            os.remove(a.xml)


def with_defaults(xml, overrides):
    """A copy of `xml` beside it (relative paths still resolve) with `<default>`s replaced."""
    text = open(xml).read()
    for o in overrides:
        name, value = o.split("=", 1)
        pattern = r'(<default\s+name="%s"\s+value=")[^"]*(")' % re.escape(name)
        text, n = re.subn(pattern, lambda m: m.group(1) + value + m.group(2), text)
        if n != 1:
            sys.exit(f"-D {o}: the scene declares no <default name=\"{name}\" value=...>")
    fd, path = tempfile.mkstemp(suffix=".xml", dir=os.path.dirname(xml))
    with os.fdopen(fd, "w") as f:
        f.write(text)
    return path


def compare(a, shown):
    import numpy as np
    runs = {}
    with tempfile.TemporaryDirectory() as scratch:
        for renderer in ["pathspace", a.variant]:
            imgs, cpu = [], []
            for k in range(a.runs):
                out = os.path.join(scratch, f"{renderer}-{k}.exr")
                cpu.append(render(renderer, a, 1000 + k, out))
                imgs.append(read(out))
            runs[renderer] = (np.stack(imgs), cpu)
    names = list(runs)
    extra = f" with {', '.join(a.D)}" if a.D else ""
    print(f"{os.path.relpath(shown, ROOT)}{extra}: {a.runs} runs of {a.spp} spp each")
    stats = {}
    for r in names:
        imgs, cpu = runs[r]
        means = imgs.reshape(a.runs, -1, 3).mean(1)
        m, se = means.mean(0), means.std(0, ddof=1) / math.sqrt(a.runs)
        stats[r] = (m, se)
        shown = ", ".join(f"{m[c]:.6g} +- {se[c]:.2g}" for c in range(3))
        print(f"  {r:>12}: mean RGB {shown}; CPU s per render {np.mean(cpu):.2f}")
    for r in names:
        o = names[1] if r == names[0] else names[0]
        imgs = runs[r][0]
        own = imgs[1:].mean(0)
        other = runs[o][0].mean(0)
        print(f"  {r:>12}: relMSE of run 0 vs {o}'s converged {relmse(imgs[0], other):.4e},"
              f" vs its own other runs {relmse(imgs[0], own):.4e}")
    (m1, s1), (m2, s2) = stats[names[0]], stats[names[1]]
    for c in range(3):
        t, pv = t_and_p(m1[c], s1[c], a.runs, m2[c], s2[c], a.runs)
        print(f"  channel {'RGB'[c]}: difference {m1[c] - m2[c]:+.3g}, "
              f"combined standard error {math.hypot(s1[c], s2[c]):.3g}, t = {t:+.2f}, p = {pv:.3f}")
    blocks(a, runs[names[0]][0], runs[names[1]][0])


def blocks(a, x, y, b=8):
    """Welch's t of the two renderers' run means per 8x8 block and channel: the largest |t| and
    the blocks beyond Bonferroni's p < 0.05 over all of them."""
    import numpy as np
    h, w = (x.shape[1] // b) * b, (x.shape[2] // b) * b
    if h == 0 or w == 0:
        return
    means = [v[:, :h, :w].reshape(a.runs, h // b, b, w // b, b, 3).mean((2, 4)) for v in (x, y)]
    n = (h // b) * (w // b) * 3
    worst, off = (0.0, None), 0
    for i in range(h // b):
        for j in range(w // b):
            for c in range(3):
                (m1, s1), (m2, s2) = [(m[:, i, j, c].mean(), m[:, i, j, c].std(ddof=1)
                                       / math.sqrt(a.runs)) for m in means]
                t, pv = t_and_p(m1, s1, a.runs, m2, s2, a.runs)
                off += pv < 0.05 / n
                if abs(t) > abs(worst[0]):
                    worst = (t, (j, i, "RGB"[c], (m1 - m2) / max(abs(m2), 1e-12)))
    t, (bx, by, c, rel) = worst
    print(f"  8x8 blocks: {n // 3} x 3 channels, largest |t| {abs(t):.2f} at block ({bx}, {by}) "
          f"{c} (relative difference {rel:+.2%}), {off} beyond Bonferroni p < 0.05")


if __name__ == "__main__":
    main()
