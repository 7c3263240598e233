#!/usr/bin/env python3
"""Render the fog box with Mitsuba 3 (volpath, scalar_rgb, 2 threads) for the equal-time
comparison of benches/README.md. Writes one EXR per (spp, seed) and prints the wall and CPU
seconds of each render (scene loading excluded).

    pip install mitsuba numpy
    python3 benches/mitsuba_fogbox.py --spp 128 384 1264 --seeds 0 1 --out out/mitsuba
    python3 benches/mitsuba_fogbox.py --spp 256 --coplanar --out out/mitsuba   # the leak
"""
import argparse, os, resource, time

def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime

def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default=os.path.join(os.path.dirname(__file__), "mitsuba-fog-box.xml"))
    ap.add_argument("--spp", type=int, nargs="+", required=True)
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--coplanar", action="store_true", help="the exact cube, coplanar with the walls")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", default="out/mitsuba")
    a = ap.parse_args()
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    import drjit as dr
    dr.set_thread_count(a.threads)
    os.makedirs(a.out, exist_ok=True)
    extra = dict(gx=1.0, gz=1.0, tz=0.0) if a.coplanar else {}
    scene = mi.load_file(a.scene, **extra)
    for spp in a.spp:
        for seed in a.seeds:
            c0, t0 = cpu_seconds(), time.perf_counter()
            img = mi.render(scene, spp=spp, seed=seed)
            wall, cpu = time.perf_counter() - t0, cpu_seconds() - c0
            name = f"fogbox{'-coplanar' if a.coplanar else ''}-{spp}spp-seed{seed}.exr"
            # synchronous write: the asynchronous default can stall (seen with Mitsuba 3.9.1)
            mi.Bitmap(img).write(os.path.join(a.out, name))
            print(f"{name}: {wall:.2f} s wall, {cpu:.2f} s CPU")

if __name__ == "__main__":
    main()
