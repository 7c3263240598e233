#!/usr/bin/env python3
"""The scale model of shards (book: "Measuring a renderer", section "Shards"), measured on this
machine with the release binary:

  scripts/shard-scale.py throughput   # CPU and wall seconds of 1, 2, 4 concurrent shards
                                      # against one process on both cores (3 repetitions)
  scripts/shard-scale.py merge        # merge cost against the input count and image size
  scripts/shard-scale.py mlt REF.exr  # relMSE of 4 merged MLT shards against one run of the
                                      # same total mutations (8 seeds; REF: a 64x64 reference)

CPU seconds are the children's rusage, so other work on a shared machine changes the wall
times, not the CPU times.
"""
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BIN = os.environ.get("PATHSPACE", os.path.join(ROOT, "target/release/pathspace"))
FOG = os.path.join(ROOT, "scenes/fog-box.toml")


def timed(commands):
    """Runs the commands side by side; (wall seconds, CPU seconds of all of them)."""
    import time

    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.time()
    procs = [subprocess.Popen(c, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for c in commands]
    for p in procs:
        if p.wait() != 0:
            sys.exit(f"failed: {' '.join(p.args)}")
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return time.time() - t0, cpu


def throughput(tmp):
    base = [BIN, "render", FOG, "--resolution", "128x128", "--spp", "256", "--seed", "7"]
    rows = {}
    for _ in range(3):
        rows.setdefault("one process, 2 threads", []).append(
            timed([base + ["--threads", "2", "-o", f"{tmp}/one.exr"]]))
        for n in (1, 2, 4):
            shards = [base + ["--threads", "1", "--shard", f"{i}/{n}", "-o", f"{tmp}/s{i}.exr"]
                      for i in range(1, n + 1)]
            rows.setdefault(f"{n} concurrent shards, 1 thread each", []).append(timed(shards))
    one_wall = statistics.mean(w for w, _ in rows["one process, 2 threads"])
    one_cpu = statistics.mean(c for _, c in rows["one process, 2 threads"])
    for name, runs in rows.items():
        wall = statistics.mean(w for w, _ in runs)
        cpu = statistics.mean(c for _, c in runs)
        print(f"{name:36s} wall {wall:6.2f} s ({one_wall / wall:.2f} x the throughput)  "
              f"cpu {cpu:6.2f} s ({cpu / one_cpu:.3f} x)")


def merge_cost(tmp):
    for res in ("256x256", "1024x1024"):
        inputs = []
        for seed in range(1, 17):
            out = f"{tmp}/{res}-{seed}.exr"
            timed([[BIN, "render", FOG, "--resolution", res, "--spp", "1", "--seed", str(seed), "-o", out]])
            inputs.append(out)
        for n in (1, 2, 4, 8, 16):
            runs = [timed([[BIN, "merge", *inputs[:n], "-o", f"{tmp}/m.exr"]]) for _ in range(3)]
            print(f"merge {n:2d} inputs of {res:9s}: wall {min(w for w, _ in runs):.3f} s, "
                  f"cpu {min(c for _, c in runs):.3f} s (least of 3)")


def mlt(tmp, reference):
    base = [BIN, "render", FOG, "--integrator", "mlt", "--resolution", "64x64", "--spp", "256",
            "--mlt-chains", "16", "--threads", "2"]

    def relmse(f):
        out = subprocess.run([BIN, "diff", f, reference, "--json"], check=True,
                             capture_output=True, text=True).stdout
        return json.loads(out)["relmse"]

    rows = {"one run": ([], []), "4 shards merged": ([], [])}
    for seed in map(str, range(1, 9)):
        one = f"{tmp}/one{seed}.exr"
        rows["one run"][1].append(timed([base + ["--seed", seed, "-o", one]])[1])
        rows["one run"][0].append(relmse(one))
        parts = [f"{tmp}/s{seed}-{i}.exr" for i in range(1, 5)]
        cpu = sum(timed([base + ["--seed", seed, "--shard", f"{i}/4", "-o", parts[i - 1]]])[1]
                  for i in range(1, 5))
        merged = f"{tmp}/four{seed}.exr"
        timed([[BIN, "merge", *parts, "-o", merged]])
        rows["4 shards merged"][0].append(relmse(merged))
        rows["4 shards merged"][1].append(cpu)
    for name, (errors, cpus) in rows.items():
        se = statistics.stdev(errors) / len(errors) ** 0.5
        print(f"{name:16s} relMSE {statistics.mean(errors):.4e} +- {se:.1e} (8 seeds), "
              f"cpu {statistics.mean(cpus):.2f} s")


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else ""
    with tempfile.TemporaryDirectory() as tmp:
        if what == "throughput":
            throughput(tmp)
        elif what == "merge":
            merge_cost(tmp)
        elif what == "mlt" and len(sys.argv) == 3:
            mlt(tmp, os.path.abspath(sys.argv[2]))
        else:
            sys.exit(__doc__)
