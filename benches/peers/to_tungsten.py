#!/usr/bin/env python3
"""pathspace TOML -> tungsten scene JSON, for the peers' harness (`run.py`).

    python3 benches/peers/to_tungsten.py scenes/fog-box.toml bidirectional_path_tracer [--res 64] > scene.json

tungsten is Benedikt Bitterli's research renderer (github.com/tunabrain/tungsten, read at
commit 88ea020: `src/core/primitives/{Quad,Cube,Sphere}.cpp`, `bsdfs/{Lambert,RoughConductor}Bsdf.cpp`,
`integrators/*/…Settings.hpp`); it is never part of this repository. Exact counterparts only;
anything else is refused with the reason (`scene.Refused`), exit status 2. tungsten's Lambert
is one-sided, so the integrator's `enable_two_sided_shading` makes it pathspace's two-sided
one; a quad's frame has edge0 = the matrix's x column, edge1 = its z column and the normal
edge1 x edge0, so pathspace's (u, v) become the columns (v, n, u). Medium boxes are grown by
`scene.GROW` (tungsten leaks light through a null face coplanar with a wall, as Mitsuba 3
does); the camera and every emitter are given the medium they sit in (an emitter without it
starts its light paths in vacuum: BDPT and Kelemen MLT come out 22% too bright in the fog box).

A grid medium (a procedural field baked with `resolution`, tracked) becomes a `voxel` medium
over a `vdb` grid (`src/core/media/VoxelMedium.cpp`, `src/core/grids/VdbGrid.cpp`): pathspace's
baked lattice (`pathspace info --write-grids`) is written under `--grids` as an OpenVDB
FloatGrid `density` with every lattice voxel active, by python3-openvdb (this Python's
`pyopenvdb`, else `$VDB_PYTHON`, default Debian's /usr/bin/python3). tungsten samples the grid
with OpenVDB's `BoxSampler` (trilinear, values at integer index coordinates, zero outside), so
with `normalize_size` off the grid's `transform` (index -> world: scale h, then translate to
min) puts voxel i on pathspace's vertex min + i h: the interpolant inside the box is the same
and falls to zero over one cell outside, as in `to_mitsuba.py`. Free paths and transmittance
are tungsten's `exact_linear` (trapezoids of the trilinear density between a ray's crossings of
the lattice planes, for free paths the planes half a voxel off): the one approximation. The
trilinear density is cubic along a ray, so a trapezoid misses by a part in 10^4 of
transmittance on average over the cloud's lattice (the book, *Measuring a renderer*). Its
`raymarching` divides by zero where the density is constant along a step (the cloud's clamped
core) and is not used. It needs a tungsten built with OpenVDB; one without fails at render time
with its message.
"""

import argparse
import json
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scene import Refused, Scene, quad_frame, resolution  # noqa: E402

INTEGRATORS = ("path_tracer", "bidirectional_path_tracer", "kelemen_mlt", "multiplexed_mlt",
               "photon_beams", "photon_planes")


def mat(x, y, z, t):
    """Row-major 4x4 with columns x, y, z and the translation t."""
    return [x[0], y[0], z[0], t[0], x[1], y[1], z[1], t[1], x[2], y[2], z[2], t[2], 0, 0, 0, 1]


def primitive(sc, s):
    if s["type"] == "quad":
        c, hu, hv, n = quad_frame(s)
        p = {"type": "quad", "transform": mat([2 * x for x in hv], n, [2 * x for x in hu], c)}
    elif s["type"] == "box":
        lo, hi = s["min"], s["max"]
        p = {"type": "cube", "transform": {"position": [(lo[i] + hi[i]) / 2 for i in range(3)],
                                           "scale": [hi[i] - lo[i] for i in range(3)]}}
    else:
        p = {"type": "sphere", "transform": {"position": s["center"], "scale": float(s["radius"])}}
    if "emission" in s:
        p["emission"] = s["emission"]
        p["bsdf"] = "black"
        c = quad_frame(s)[0]
        m = sc.medium_at(c)
        if m:
            p["int_medium"] = p["ext_medium"] = m
    else:
        p["bsdf"] = "null" if s["material"] == "null" else s["material"]
        for side, key in (("interior", "int_medium"), ("exterior", "ext_medium")):
            # "vacuum" is no medium: the key left out (tungsten refuses an empty name)
            if s.get(side) not in (None, "vacuum"):
                p[key] = s[side]
    return p


def integrator(kind, max_bounces, radius):
    base = {"min_bounces": 0, "max_bounces": max_bounces, "enable_consistency_checks": False,
            "enable_two_sided_shading": True}
    if kind in ("photon_beams", "photon_planes"):
        return dict(base, type="photon_map", volume_photon_type=kind.split("_")[1],
                    photon_count=100000, volume_photon_count=100000, gather_radius=radius,
                    volume_gather_radius=radius, fixed_volume_radius=True)
    out = dict(base, type=kind)
    if kind == "multiplexed_mlt":
        # tungsten's default pool, 3,000,000 bootstrap samples, alone outlasts the budgets
        out["initial_sample_pool"] = 300000
    # Kelemen MLT keeps tungsten's defaults: a pool of 10,000, large steps 0.1, bidirectional
    return out


def vol_to_vdb(src, dst):
    """Writes pathspace's `.vol` lattice `src` (x fastest) as the OpenVDB FloatGrid `density`
    in `dst`, index (i, j, k) holding vertex (i, j, k), every lattice voxel active."""
    import numpy as np
    import pyopenvdb
    b = open(src, "rb").read()
    nx, ny, nz = (int(x) for x in np.frombuffer(b[8:20], "<i4"))
    lattice = np.frombuffer(b[48:], "<f4").reshape(nz, ny, nx).transpose(2, 1, 0)
    grid = pyopenvdb.FloatGrid(0.0)
    grid.copyFromArray(np.ascontiguousarray(lattice, np.float32), tolerance=-1.0)
    grid.name = "density"
    pyopenvdb.write(dst, grids=[grid])


def write_vdb(src, dst):
    """`vol_to_vdb` in this Python, or in `$VDB_PYTHON` (Debian's python3-openvdb) without
    `pyopenvdb` here."""
    try:
        import pyopenvdb  # noqa: F401
    except ImportError:
        py = os.environ.get("VDB_PYTHON", "/usr/bin/python3")
        r = subprocess.run([py, os.path.abspath(__file__), "--vol-to-vdb", src, dst],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise Refused(f"writing {dst} needs python3-openvdb (`pyopenvdb` in {py}): "
                          f"{r.stderr.strip()[-200:]}")
        return
    vol_to_vdb(src, dst)


def voxel_grid(m, vdb):
    """tungsten's `vdb` grid for pathspace's grid medium `m` stored in `vdb`: index i at world
    min + i h (`normalize_size` off: the grid's own index space, then `transform`)."""
    lo, hi = m["min"], m["max"]
    h = [(hi[i] - lo[i]) / (m["res"][i] - 1) for i in range(3)]
    return {"type": "vdb", "file": vdb, "density_name": "density", "normalize_size": False,
            "integration_method": "exact_linear", "sampling_method": "exact_linear",
            "transform": mat([h[0], 0, 0], [0, h[1], 0], [0, 0, h[2]], lo)}


# tungsten's `roughnessToAlpha` raises a GGX alpha below this to it (`bsdfs/Microfacet.hpp`)
MIN_ALPHA = 1e-3


def refuse_beyond_tungsten(sc):
    """What the common subset (`scene.py`) has and tungsten cannot take: a spot light (it has
    none), a rough conductor smoother than tungsten's smallest alpha."""
    if sc.spots:
        raise Refused("a spot light (tungsten has none)")
    for name, m in sc.materials.items():
        if m["type"] == "rough_conductor" and m["alpha"] < MIN_ALPHA:
            raise Refused(f"material `{name}`: a rough conductor with alpha {m['alpha']!r} (tungsten "
                          f"raises alpha below {MIN_ALPHA} to it)")


def rough_conductor(name, m):
    """tungsten's `rough_conductor` (`bsdfs/RoughConductorBsdf.cpp`): Walter et al.'s GGX with
    D, the separable Smith G of G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2)) and the exact Fresnel
    term of the complex index `eta` + i `k` at the facet, as pathspace's; its `roughness` is
    alpha itself for GGX (`Microfacet::roughnessToAlpha`), its `albedo` the `specular` factor.
    pathspace's conductor without an index (F = 1) is eta 0, k 1: tungsten's Fresnel gives
    exactly 1 there (a = 0, Rs = Rp = 1). One-sided in tungsten; `enable_two_sided_shading`
    flips the frame on a back-side hit, as for Lambert."""
    eta, k = (m["eta"], m["k"]) if m["eta"] is not None else ([0.0] * 3, [1.0] * 3)
    return {"name": name, "type": "rough_conductor", "distribution": "ggx",
            "roughness": m["alpha"], "eta": eta, "k": k, "albedo": m["specular"]}


def convert(sc, kind, res=None, max_bounces=64, spp=1 << 20, grids=None, binary=None):
    """The scene JSON; a grid medium's lattice is written under `grids` (a folder, made if
    missing) by `binary` (pathspace's)."""
    if kind not in INTEGRATORS:
        raise SystemExit(f"unknown tungsten integrator {kind} ({', '.join(INTEGRATORS)})")
    refuse_beyond_tungsten(sc)
    vdbs = {}
    if any(m["kind"] == "grid" for m in sc.media.values()):
        grids = os.path.abspath(grids or os.path.splitext(os.path.basename(sc.path))[0] + "-grids")
        os.makedirs(grids, exist_ok=True)
        for name, src in sc.grids(grids, binary).items():
            vdbs[name] = os.path.join(grids, name + "-tungsten.vdb")
            write_vdb(src, vdbs[name])
    bsdfs = [{"name": "black", "type": "lambert", "albedo": 0.0},
             {"name": "null", "type": "forward"}]
    for name, m in sc.materials.items():
        if m["type"] == "lambert":
            bsdfs.append({"name": name, "type": "lambert", "albedo": m["albedo"]})
        elif m["type"] == "rough_conductor":
            bsdfs.append(rough_conductor(name, m))
        else:
            bsdfs.append({"name": name, "type": "dielectric", "ior": m["ior"], "enable_refraction": True})
    media = []
    for name, m in sc.media.items():
        phase = ({"type": "isotropic"} if m["g"] is None
                 else {"type": "henyey_greenstein", "g": m["g"]})
        medium = {"name": name, "type": "homogeneous", "sigma_a": m["sigma_a"],
                  "sigma_s": m["sigma_s"], "density": 1.0, "phase_function": phase,
                  "max_bounces": 1 << 20}
        if m["kind"] == "grid":
            del medium["density"]
            medium.update(type="voxel", grid=voxel_grid(m, vdbs[name]))
        media.append(medium)
    eye, look, up = sc.eye()
    w, h = sc.resolution(res)
    import math
    # pathspace's fov_deg is vertical, tungsten's fov horizontal
    fov = math.degrees(2 * math.atan(math.tan(math.radians(sc.camera["fov_deg"]) / 2) * w / h))
    camera = {"type": "pinhole", "fov": fov, "resolution": [w, h], "reconstruction_filter": "box",
              "transform": {"position": eye, "look_at": look, "up": up}}
    if sc.medium_at(eye):
        camera["medium"] = sc.medium_at(eye)
    lo = [min(s["min"][i] for s in sc.shapes if s["type"] == "box") for i in range(3)] if sc.boxes else None
    hi = [max(s["max"][i] for s in sc.shapes if s["type"] == "box") for i in range(3)] if sc.boxes else None
    diag = math.dist(lo, hi) if lo else 1.0
    return {"media": media, "bsdfs": bsdfs, "primitives": [primitive(sc, s) for s in sc.shapes],
            "camera": camera, "integrator": integrator(kind, max_bounces, 0.005 * diag),
            "renderer": {"output_file": "out.png", "hdr_output_file": "out.pfm",
                         "overwrite_output_files": True, "enable_resume_render": False,
                         "spp": spp, "spp_step": 1, "timeout": "0", "adaptive_sampling": False,
                         "stratified_sampler": False, "scene_bvh": True}}


def main():
    if sys.argv[1:2] == ["--vol-to-vdb"]:
        # `write_vdb`'s subprocess in a Python with pyopenvdb
        vol_to_vdb(*sys.argv[2:4])
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("integrator", choices=INTEGRATORS)
    ap.add_argument("--res", type=resolution, help="N or WxH (default: the scene's)")
    ap.add_argument("--max-bounces", type=int, default=64, help="tungsten's path length cap (its default 64)")
    ap.add_argument("--spp", type=int, default=1 << 20, help="spp cap (the harness stops by --timeout)")
    ap.add_argument("--grids", help="folder for grid media's .vdb files (default: SCENE-grids)")
    ap.add_argument("--bin", help="pathspace's binary (default: target/release/pathspace)")
    a = ap.parse_args()
    try:
        j = convert(Scene(a.scene), a.integrator, a.res,
                    a.max_bounces, a.spp, a.grids, a.bin)
    except Refused as e:
        print(f"{a.scene}: refused: {e}", file=sys.stderr)
        sys.exit(2)
    json.dump(j, sys.stdout, indent=1)
    print()


if __name__ == "__main__":
    main()
