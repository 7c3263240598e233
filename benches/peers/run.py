#!/usr/bin/env python3
"""pathspace, Mitsuba 3 and tungsten on the papers' scenes at equal CPU time, in one command.

    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1   # Mitsuba's llvm_ad_rgb
    export TUNGSTEN=/path/to/tungsten/build/tungsten                      # optional (book: how to build it)
    cargo build --release
    venv/bin/python benches/peers/run.py --cpu 8 --seeds 3 --res 64

Per scene (`--scenes`: TOML names under scenes/, `rooms`, the 100 rooms of `pathspace rooms
--n 10`, or a variant of `scene.VARIANTS`, a paper scene with one named change that lets the
peers render it exactly, written to `--cache`), per renderer (`--renderers`), per method, `--seeds` renders of `--cpu` CPU seconds
each, one render at a time on one thread, each a process of its own charged its user + system
time (RUSAGE_CHILDREN: loading, JIT compilation and preprocessing included). A method's spp for
the budget comes from two probes (cost = fixed + per-spp x spp). Every render is compared with
the scene's reference: the average of two independent pathspace renders (`pathspace reference`,
seeds 999 and 998, `--ref-time` s each on `--ref-threads` threads, cached in `--cache`, outside
the repository) by the scene's best method (`REF_INTEGRATOR`: BDPT where it wins, the path
tracer in the maze, the rooms and the cloud), relMSE as pathspace defines it
(`benches/exr_metrics.py`). The reference's own noise, estimated from its two halves as
mean((r1 - r2)^2 / 4 / (r^2 + eps)), is subtracted from every relMSE (and printed), so each
figure estimates the error against the truth: without it a noisy reference adds the same
amount to every method and narrows all ratios towards 1. The table gives per method
the mean CPU-s, relMSE mean +- standard error and median over the seeds, and relMSE x CPU-s
(lower is better); per scene the ratio of pathspace's best product to each peer's best.
`--spp N` renders every seed at N samples per pixel instead (per-sample comparisons, e.g. of two
builds given as `--bin`), and `--first-seed` moves the seeds (FIRST..FIRST+N-1).
`--pathspace-flags` adds flags to every pathspace render (not to the reference), e.g. a
method's settings: `--pathspace mlt --pathspace-flags '--mlt-bidirectional 3'`.
Methods that converge to a different, consistent-but-biased answer (tungsten's photon beams
and planes) are marked and left out of the ratios. A scene a peer cannot render (the converters
`to_mitsuba.py`, `to_tungsten.py` refuse it) is listed with the reason; a render that fails is
listed with its last message. tungsten is skipped, with a message, when `$TUNGSTEN` is unset.
"""

import argparse
import math
import os
import shlex
import shutil
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))
from exr_metrics import EPSILON, child_cpu, read, relmse  # noqa: E402
from scene import VARIANTS, Refused, Scene, variant_text  # noqa: E402
import to_mitsuba  # noqa: E402
import to_tungsten  # noqa: E402

SCENES = ["fog-box", "door-slit-ior", "volume-caustic-hard-cone", "volume-caustic-quad", "cloud-tracking",
          "maze-fog", "rooms"]
PATHSPACE = ["path", "path-equiangular", "bdpt", "mlt", "pssmlt", "mmlt", "smc"]
MITSUBA = ["llvm_ad_rgb/volpath", "llvm_ad_rgb/volpathmis"]
TUNGSTEN = ["path_tracer", "bidirectional_path_tracer", "bidirectional_path_tracer@16",
            "kelemen_mlt", "multiplexed_mlt", "photon_beams", "photon_planes"]
BIASED = {("tungsten", "photon_beams"), ("tungsten", "photon_planes")}
# tungsten has no Russian roulette: its bidirectional tracer is cheaper per sample with a lower
# bounce cap ("@16"), at the price of the longer paths' light (the screening flags a visible loss)
REF_SEEDS = (999, 998)
# the reference's method per scene: the scene's most efficient unbiased method in pathspace
REF_INTEGRATOR = {"maze-fog": "path", "rooms": "path", "cloud-tracking": "path"}


class Failed(Exception):
    """A render that did not produce an image; the message is its last words."""


def mitsuba_worker(xml, spp, seed, out):
    """Renders `xml` with Mitsuba in this process (a child of the harness), on one thread."""
    variant = os.environ["PEERS_MITSUBA_VARIANT"]
    import mitsuba as mi
    mi.set_variant(variant)
    import drjit as dr
    dr.set_thread_count(1)
    scene = mi.load_file(xml)
    img = mi.render(scene, spp=spp, seed=seed)
    # a NumPy file: mi.Bitmap.write hangs after dr.set_thread_count(1) (Mitsuba 3.9.1)
    import numpy as np
    np.save(out, np.array(img, dtype=np.float64)[:, :, :3])


def read_pfm(path):
    import numpy as np
    with open(path, "rb") as f:
        if f.readline().strip() != b"PF":
            raise Failed(f"{path}: not an RGB PFM")
        w, h = map(int, f.readline().split())
        s = float(f.readline())
        d = np.frombuffer(f.read(), dtype="<f4" if s < 0 else ">f4").reshape(h, w, 3)
    return d[::-1].astype(np.float64)


def run(cmd, log, env=None, limit=600):
    """Runs `cmd`, returning its CPU seconds (user + system of the child); a render still
    running after `limit` wall-clock seconds has failed."""
    before = child_cpu()
    with open(log, "w") as f:
        try:
            r = subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT, env=env, timeout=limit)
        except subprocess.TimeoutExpired:
            raise Failed(f"still running after {limit} s")
    cpu = child_cpu() - before
    if r.returncode != 0:
        lines = [x.strip() for x in open(log, errors="replace") if x.strip()]
        how = {-6: "aborted", -11: "segmentation fault"}.get(r.returncode, f"exit status {r.returncode}")
        raise Failed(f"{how}: {lines[-1][-160:]}" if lines else how)
    return cpu


class Job:
    """One (scene, renderer, method): how to render it at a given spp and seed."""

    def __init__(self, a, scene, toml, renderer, method, work):
        self.a, self.scene, self.toml = a, scene, toml
        self.renderer, self.method, self.work = renderer, method, work
        self.input = None
        if renderer == "mitsuba":
            variant, integ = method.split("/")
            self.input = os.path.join(work, f"{scene}-{integ}.xml")
            with open(self.input, "w") as f:
                f.write(to_mitsuba.convert(Scene(toml), [a.res, a.res], integ, grids=work, binary=a.bin))
        elif renderer == "tungsten":
            import json
            self.input = os.path.join(work, f"{scene}-{method}.json")
            kind, _, cap = method.partition("@")  # "@N": max_bounces N instead of tungsten's 64
            with open(self.input, "w") as f:
                json.dump(to_tungsten.convert(Scene(toml), kind, [a.res, a.res], max_bounces=int(cap or 64),
                                              grids=work, binary=a.bin), f)

    def render(self, spp, seed, tag):
        out = os.path.join(self.work, f"{self.scene}-{self.renderer}-{self.method.replace('/', '-')}-{tag}")
        a = self.a
        if self.renderer == "pathspace":
            integ, _, variant = self.method.partition("-")
            cmd = [a.bin, "render", self.toml, "--integrator", integ, "--spp", str(spp),
                   "--seed", str(seed), "--threads", "1", "--resolution", f"{a.res}x{a.res}",
                   "-o", out + ".exr"]
            if variant == "equiangular":
                cmd += ["--distance", "equiangular-mis"]
            cmd += shlex.split(a.pathspace_flags)
            return run(cmd, out + ".log"), out + ".exr"
        if self.renderer == "mitsuba":
            env = dict(os.environ, PEERS_MITSUBA_VARIANT=self.method.split("/")[0])
            cmd = [sys.executable, __file__, "--mitsuba-worker", self.input, str(spp), str(seed), out + ".npy"]
            return run(cmd, out + ".log", env), out + ".npy"
        os.makedirs(out, exist_ok=True)
        cmd = [a.tungsten, "--threads", "1", "--seed", str(seed), "--spp", str(spp), "-d", out, self.input]
        cpu = run(cmd, out + ".log")
        if not os.path.exists(os.path.join(out, "out.pfm")):
            raise Failed("no image written")
        return cpu, os.path.join(out, "out.pfm")

    def spp_for_budget(self):
        """spp whose render costs `--cpu` CPU seconds, from the line cost = fixed + per_spp x
        spp through two probes: 4 spp, then 4 times more until a probe costs an eighth of the
        budget and twice the first (a JIT compilation or a bootstrap is the fixed part)."""
        lo = hi = 4
        c_lo, _ = self.render(lo, 1000, "probe-lo")
        c_hi = c_lo
        while c_hi < max(self.a.cpu / 8, 2 * c_lo) and hi < 1 << 16:
            hi *= 4
            c_hi, _ = self.render(hi, 1001, "probe-hi")
        per_spp = max((c_hi - c_lo) / (hi - lo), 1e-7)
        fixed = max(c_lo - lo * per_spp, 0.0)
        return max(1, round((self.a.cpu - fixed) / per_spp))


def image(path):
    import numpy as np
    img = {".pfm": read_pfm, ".npy": np.load}.get(os.path.splitext(path)[1], read)(path)
    if not np.all(np.isfinite(img)):
        raise Failed("non-finite pixels")
    return img


def reference(a, scene, toml):
    """The scene's reference, the average of two independent halves made once and then read
    from the cache, and its own relMSE noise as estimated from the halves."""
    integ = REF_INTEGRATOR.get(scene, "bdpt")
    halves = []
    for seed in REF_SEEDS:
        path = os.path.join(a.cache, f"{scene}-{a.res}x{a.res}-{integ}-{a.ref_time:g}s-seed{seed}.exr")
        if not os.path.exists(path):
            print(f"# making the reference {path} ({a.ref_time:g} s on {a.ref_threads} threads)", file=sys.stderr)
            subprocess.run([a.bin, "reference", toml, "--integrator", integ, "--resolution",
                            f"{a.res}x{a.res}", "--time", str(a.ref_time), "--threads", str(a.ref_threads),
                            "--seed", str(seed), "-o", path], check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        halves.append(read(path))
    ref = (halves[0] + halves[1]) / 2
    # Var of the average = E[(r1 - r2)^2] / 4 for independent halves of equal variance
    noise = float((((halves[0] - halves[1]) ** 2 / 4) / (ref ** 2 + EPSILON)).mean())
    return ref, integ, noise


def scene_file(a, scene):
    if scene == "rooms":
        path = os.path.join(a.cache, "rooms.toml")
        subprocess.run([a.bin, "rooms", "--n", "10", "-o", path], check=True, stdout=subprocess.DEVNULL)
        return path
    if scene in VARIANTS:
        path = os.path.join(a.cache, scene + ".toml")
        with open(path, "w") as f:
            f.write(variant_text(scene))
        return path
    return os.path.join(ROOT, "scenes", scene + ".toml")


def measure(job, ref, noise):
    """The method's row: spp, CPU-s per render, relMSE per seed (the reference's own noise
    subtracted), and each render's image mean over the reference's."""
    spp = job.a.spp or job.spp_for_budget()
    cpus, errs, means = [], [], []
    for seed in range(job.a.first_seed, job.a.first_seed + job.a.seeds):
        cpu, out = job.render(spp, seed, f"seed{seed}")
        img = image(out)
        cpus.append(cpu)
        errs.append(relmse(img, ref) - noise)
        means.append(float(img.mean() / ref.mean()))
    return spp, cpus, errs, means


def disagrees(means):
    """The renders' image mean is off the reference's by more than 1% and 4 standard errors of
    the seeds' spread: another image, not noise (a screening, not a test)."""
    m = statistics.mean(means)
    se = statistics.stdev(means) / math.sqrt(len(means)) if len(means) > 1 else 0.0
    return abs(m - 1) > max(0.01, 4 * se)


def fmt(x):
    return "—" if x is None or math.isnan(x) else f"{x:.2e}"


def table(a, rows, notes, ratios):
    budget = f"Equal samples: {a.spp} per pixel" if a.spp else f"Equal CPU time: {a.cpu:g} CPU-s per render"
    print(f"{budget}, one thread, {a.res}x{a.res}, seeds "
          f"{a.first_seed}..{a.first_seed + a.seeds - 1}; reference: two halves of {a.ref_time:g} s on {a.ref_threads} threads "
          f"(seeds {REF_SEEDS[0]}, {REF_SEEDS[1]}), their noise subtracted (notes). Methods marked biased (consistent, not unbiased) or another image (mean off "
          "the reference's by over 1% and 4 s.e.) are left out of the ratios.\n")
    print("| scene | renderer | method | spp | CPU-s | mean / ref | relMSE (mean ± s.e.) | median | relMSE × CPU-s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(str(x) for x in r) + " |")
    if ratios:
        print("\n| scene | pathspace's best | " + " | ".join(f"ratio to {p}'s best" for p in a.renderers if p != "pathspace") + " |")
        print("|---|---|" + "---|" * (len(a.renderers) - 1))
        for scene, best, rs in ratios:
            print(f"| {scene} | {best} | " + " | ".join(rs.get(p, "—") for p in a.renderers if p != "pathspace") + " |")
    if notes:
        print()
        for n in notes:
            print(f"- {n}")


def methods_of(a, renderer):
    return {"pathspace": a.pathspace, "mitsuba": a.mitsuba, "tungsten": a.tungsten_methods}[renderer]


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--mitsuba-worker":
        xml, spp, seed, out = sys.argv[2:6]
        mitsuba_worker(xml, int(spp), int(seed), out)
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cpu", type=float, default=8.0, help="CPU seconds per render")
    ap.add_argument("--seeds", type=int, default=3, help="renders per method (seeds 1..N)")
    ap.add_argument("--first-seed", type=int, default=1, help="the seeds are FIRST..FIRST+N-1")
    ap.add_argument("--spp", type=int, default=0,
                    help="samples per pixel for every render instead of --cpu's budget (per-sample comparisons)")
    ap.add_argument("--res", type=int, default=64, help="square resolution")
    ap.add_argument("--scenes", nargs="+", default=SCENES)
    ap.add_argument("--renderers", nargs="+", default=["pathspace", "mitsuba", "tungsten"])
    ap.add_argument("--pathspace", nargs="+", default=PATHSPACE, help="pathspace methods")
    ap.add_argument("--pathspace-flags", default="",
                    help="flags added to every pathspace render, e.g. '--mlt-bidirectional 3'")
    ap.add_argument("--mitsuba", nargs="+", default=MITSUBA, help="VARIANT/INTEGRATOR")
    ap.add_argument("--tungsten-methods", nargs="+", default=TUNGSTEN)
    ap.add_argument("--ref-time", type=float, default=60.0, help="reference seconds")
    ap.add_argument("--ref-threads", type=int, default=2)
    ap.add_argument("--all-scenes", action="store_true",
                    help="render pathspace's methods also on scenes every peer refuses")
    ap.add_argument("--cache", default=os.path.join(os.path.expanduser("~"), ".cache", "pathspace-peers"))
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "pathspace"))
    ap.add_argument("--keep", action="store_true", help="keep the renders (their folder goes to stderr)")
    a = ap.parse_args()
    a.tungsten = os.environ.get("TUNGSTEN")
    notes = []
    if "tungsten" in a.renderers and not (a.tungsten and os.access(a.tungsten, os.X_OK)):
        notes.append("tungsten skipped: set TUNGSTEN to its binary (book: *Measuring a renderer*)")
        a.renderers = [r for r in a.renderers if r != "tungsten"]
    if "mitsuba" in a.renderers:
        try:
            import mitsuba  # noqa: F401
        except ImportError:
            notes.append("Mitsuba 3 skipped: `import mitsuba` failed in this Python")
            a.renderers = [r for r in a.renderers if r != "mitsuba"]
    os.makedirs(a.cache, exist_ok=True)
    work = tempfile.mkdtemp(prefix="peers-")
    print(f"# renders in {work}", file=sys.stderr)
    rows, ratios = [], []
    for scene in a.scenes:
        toml = scene_file(a, scene)
        refused = {}
        for peer in (p for p in a.renderers if p != "pathspace"):
            try:
                (Scene(toml) if peer == "mitsuba" else to_tungsten.refuse_beyond_tungsten(Scene(toml)))
            except Refused as e:
                refused[peer] = str(e)
                notes.append(f"{scene}: {peer} refused: {e}")
        if all(p in refused for p in a.renderers if p != "pathspace") and not a.all_scenes \
                and len(a.renderers) > 1:
            continue
        ref, ref_integ, noise = reference(a, scene, toml)
        notes.append(f"{scene}: reference {ref_integ}, 2 x {a.ref_time:g} s on {a.ref_threads} threads, "
                     f"its own relMSE {noise:.2e} (subtracted from every row)")
        best = {}
        for renderer in a.renderers:
            if renderer in refused:
                continue
            for method in methods_of(a, renderer):
                print(f"# {scene} {renderer} {method}", file=sys.stderr, flush=True)
                try:
                    job = Job(a, scene, toml, renderer, method, work)
                    spp, cpus, errs, means = measure(job, ref, noise)
                except Failed as e:
                    rows.append([scene, renderer, method, "", "", "", f"failed: {e}", "", ""])
                    continue
                e, c = statistics.mean(errs), statistics.mean(cpus)
                se = statistics.stdev(errs) / math.sqrt(len(errs)) if len(errs) > 1 else float("nan")
                biased = (renderer, method) in BIASED
                off = disagrees(means)
                label = " (biased)" if biased else " (another image)" if off else ""
                rows.append([scene, renderer, method + label, spp, f"{c:.1f}",
                             f"{statistics.mean(means):.3f}", f"{fmt(e)} ± {fmt(se)}",
                             fmt(statistics.median(errs)), f"{fmt(e * c)} ± {fmt(se * c)}"])
                biased = biased or off
                if not biased and (renderer not in best or e * c < best[renderer][1]):
                    best[renderer] = (method, e * c)
        if "pathspace" in best:
            m, p = best["pathspace"]
            ratios.append((scene, f"{m} {fmt(p)}", {r: f"{p / q:.2f} ({mm})"
                                                   for r, (mm, q) in best.items() if r != "pathspace"}))
    table(a, rows, notes, ratios)
    if not a.keep:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
