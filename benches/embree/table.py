"""The table of benches/embree/run.sh: reads the `ALTERNATION RESULT ...` and `ALTERNATION BUILD
...` lines both sides printed and writes, per ray set, the median rays per second of each side
over the alternations and the median of the per-alternation ratios pathspace / Embree (the
machine may be shared: a ratio of two runs made one after the other is steadier than either).
Where the processor has AVX2, the rates of pathspace's four-wide and eight-wide trees follow
(`pathspace4`, `pathspace8`, whatever the scene's size), each with its ratio to Embree's single
rays, and whether their checksums are identical (they must be: the same hits bit for bit).

Checksums are equal when the hit counts are equal and the sums of hit distances agree to 1e-6
relative (the two triangle tests round t differently: f32 t carries a few ulps)."""

import statistics
import sys
from collections import defaultdict


def main(path):
    rate = defaultdict(dict)  # (scene, set, kind, side) -> {alternation: rays/s}
    check = {}  # (scene, set, side) -> (hits, sum_t)
    build = defaultdict(list)  # (scene, side) -> seconds
    version = "?"
    for line in open(path):
        f = line.split()
        if len(f) >= 3 and f[1] == "EMBREE":
            version = f[2]
        if len(f) >= 2 and f[1] == "BUILD":
            build[(f[3], f[2])].append(float(f[5]))
        if len(f) != 12 or f[1] != "RESULT":
            continue
        run, _, side, scene, rays_set, kind, mode, rays, secs, hits, sum_t, _ = f
        side = side if mode == "1" else f"{side}{mode}"
        rate[(scene, rays_set, kind, side)][run] = int(rays) / float(secs)
        check[(scene, rays_set, side)] = (int(hits), float(sum_t))
    rows = sorted({k[:3] for k in rate}, key=lambda k: list(rate).index(k + ("pathspace",)))
    runs = len(next(iter(rate.values())))
    print(f"Embree {version}; median of {runs} alternations, one thread, Mrays/s of thread CPU time")
    four = any(k[3] == "pathspace4" for k in rate)
    extra = " 4-wide | ratio | 8-wide | ratio | 4 = 8 |" if four else ""
    print("| ray set | kind | pathspace | Embree 1 | ratio | Embree 8 | ratio | checksums equal |"
          + extra)
    print("|---|---|---|---|---|---|---|---|" + ("---|---|---|---|---|" if four else ""))
    notes = []
    for scene, rays_set, kind in rows:
        ps = rate[(scene, rays_set, kind, "pathspace")]
        cells = [f"{statistics.median(ps.values()) * 1e-6:.2f}"]
        for side in ("embree", "embree8"):
            e = rate[(scene, rays_set, kind, side)]
            ratio = statistics.median(ps[r] / e[r] for r in ps if r in e)
            cells += [f"{statistics.median(e.values()) * 1e-6:.2f}", f"{ratio:.2f}"]
        (h0, s0) = check[(scene, rays_set, "pathspace")]
        same = all(
            check[(scene, rays_set, side)][0] == h0
            and abs(check[(scene, rays_set, side)][1] - s0) <= 1e-6 * max(abs(s0), 1.0)
            for side in ("embree", "embree8")
        )
        if not same:
            (h1, s1) = check[(scene, rays_set, "embree")]
            notes.append(f"{scene}.{rays_set}: hits {h0} (pathspace) vs {h1} (Embree), "
                         f"sum t {s0:.6f} vs {s1:.6f}")
        if four:
            cells.append("yes" if same else "no")
            e = rate[(scene, rays_set, kind, "embree")]
            for side in ("pathspace4", "pathspace8"):
                p = rate[(scene, rays_set, kind, side)]
                ratio = statistics.median(p[r] / e[r] for r in p if r in e)
                cells += [f"{statistics.median(p.values()) * 1e-6:.2f}", f"{ratio:.2f}"]
            identical = check[(scene, rays_set, "pathspace4")] == check[(scene, rays_set, "pathspace8")]
            cells.append("yes" if identical else "NO")
            print(f"| {scene}.{rays_set} | {kind} | " + " | ".join(cells) + " |")
            continue
        print(f"| {scene}.{rays_set} | {kind} | " + " | ".join(cells)
              + f" | {'yes' if same else 'no'} |")
    for note in notes:
        print("differs:", note)
    for (scene, side), secs in sorted(build.items()):
        print(f"build {scene} {side}: {statistics.median(secs):.3f} CPU s")


if __name__ == "__main__":
    main(sys.argv[1])
