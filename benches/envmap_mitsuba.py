#!/usr/bin/env python3
"""Checks the environment-map convention pathspace documents against Mitsuba 3 itself.

    python3 -m venv venv && venv/bin/pip install mitsuba numpy
    venv/bin/python benches/envmap_mitsuba.py

pathspace's `scene::envmap` (book: "Environment maps"; `tests/spec/scene/envmap.rs` pins pathspace to
the same formulas) says that texel (x, y) of a W x H latitude-longitude map is centred on the
local direction

    d(u, v) = (sin phi sin theta, cos theta, -cos phi sin theta),
    phi = 2 pi (x + 1/2) / W,  theta = pi y / (H - 1),

seen in the world at to_world * d. This script builds Mitsuba's `envmap` emitter on a map of
distinct random texels, turned by a `to_world` rotation, and evaluates it at those directions:
Mitsuba's bilinear lookup at a texel centre is the texel itself, so every value must match to
float rounding. Rows 0 and H - 1 are checked a little off the poles (where every column
meets), against the bilinear blend with the next row that Mitsuba makes there. It prints the
largest relative difference and exits non-zero above 1e-4.

Between the centres it checks the bilinear lookup pathspace makes (`EnvMap::lookup`): at 2000
random directions Mitsuba's value against the interpolation of the four nearest centres,
wrapped around in u and clamped in theta (relative 1e-4), and Mitsuba's `pdf_direction` against
the piecewise-bilinear density pathspace samples (`Bilinear2D`): the interpolation of
Y(L) sin(theta_y) at the centres shifted by half a texel, over its integral and over
2 pi^2 sin(theta) (relative 1e-3: the luminance weights differ in their fourth digit).
"""

import math
import os
import sys
import tempfile

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

W, H = 8, 5
# a rotation about an oblique axis, as the Rust tests use (axis (1, 2, 3), angle 0.7)
AXIS = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
ANGLE = 0.7


def rotation(axis, angle):
    """Rodrigues' rotation matrix."""
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def main():
    rng = np.random.default_rng(7)
    texels = rng.uniform(0.1, 2.0, size=(H, W, 3)).astype(np.float32)
    r = rotation(AXIS, ANGLE)
    to_world = np.eye(4)
    to_world[:3, :3] = r
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "map.exr")
        mi.Bitmap(texels).write(path)
        emitter = mi.load_dict({
            "type": "envmap",
            "filename": path,
            "to_world": mi.ScalarTransform4f(to_world.tolist()),
        })
    worst = 0.0
    for y in range(H):
        # 0.01 off the poles in rows 0 and H - 1, blended with the next row by Mitsuba's
        # bilinear weight t (the offset in rows)
        theta = math.pi * y / (H - 1)
        theta = min(max(theta, 0.01), math.pi - 0.01)
        t = theta * (H - 1) / math.pi - y
        nxt = y + 1 if t > 0 else y - 1
        for x in range(W):
            phi = 2 * math.pi * (x + 0.5) / W
            local = np.array([math.sin(phi) * math.sin(theta), math.cos(theta),
                              -math.cos(phi) * math.sin(theta)])
            world = r @ local
            si = mi.SurfaceInteraction3f()
            # Mitsuba looks up the direction -wi (the escaping ray's direction)
            si.wi = mi.Vector3f(*(-world))
            value = np.array(emitter.eval(si))
            want = (1 - abs(t)) * texels[y, x] + abs(t) * texels[nxt, x]
            rel = float(np.max(np.abs(value - want) / want))
            worst = max(worst, rel)
            if rel > 1e-4:
                print(f"texel ({x}, {y}): Mitsuba {value}, expected {want}")
    print(f"{W * H} texel centres, largest relative difference {worst:.2e}")
    lookup, density = between_centres(emitter, texels, r, rng)
    print(f"2000 random directions: lookup {lookup:.2e}, pdf {density:.2e} (largest relative differences)")
    sys.exit(0 if worst <= 1e-4 and lookup <= 1e-4 and density <= 1e-3 else 1)


def bilinear(grid, x, y):
    """The bilinear interpolation of grid[row][column] at column x, row y (in cells)."""
    x0, y0 = min(int(math.floor(x)), grid.shape[1] - 2), min(int(math.floor(y)), grid.shape[0] - 2)
    fx, fy = x - x0, y - y0
    return ((1 - fy) * ((1 - fx) * grid[y0, x0] + fx * grid[y0, x0 + 1])
            + fy * ((1 - fx) * grid[y0 + 1, x0] + fx * grid[y0 + 1, x0 + 1]))


def between_centres(emitter, texels, r, rng):
    """Largest relative differences of Mitsuba's lookup and density at random directions."""
    # the texels with column 0 repeated after column W - 1 (the wrap at u = 0), and column W - 1
    # before column 0
    wrapped = np.concatenate([texels[:, -1:], texels, texels[:, :1]], axis=1)
    lum = texels @ np.array([0.212671, 0.715160, 0.072169])
    rows = np.array([0.0 if y in (0, H - 1) else math.sin(math.pi * y / (H - 1)) for y in range(H)])
    f = np.concatenate([lum, lum[:, :1]], axis=1) * rows[:, None]
    integral = sum((f[y, x] + f[y, x + 1] + f[y + 1, x] + f[y + 1, x + 1]) / 4
                   for y in range(H - 1) for x in range(W)) / (W * (H - 1))
    worst_l, worst_p = 0.0, 0.0
    for _ in range(2000):
        v = rng.normal(size=3)
        world = v / np.linalg.norm(v)
        d = r.T @ world
        u = (math.atan2(d[0], -d[2]) / (2 * math.pi)) % 1.0
        theta = math.acos(max(-1.0, min(1.0, d[1])))
        want = bilinear(wrapped, u * W - 0.5 + 1, theta / math.pi * (H - 1))
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-world))
        got = np.array(emitter.eval(si))
        worst_l = max(worst_l, float(np.max(np.abs(got - want) / want)))
        s = (u - 0.5 / W) % 1.0
        p = bilinear(f, s * W, theta / math.pi * (H - 1)) / integral
        want_pdf = p / (2 * math.pi ** 2 * math.sin(theta))
        it = mi.Interaction3f()
        ds = mi.DirectionSample3f()
        ds.d = mi.Vector3f(*world)
        got_pdf = float(emitter.pdf_direction(it, ds))
        worst_p = max(worst_p, abs(got_pdf - want_pdf) / want_pdf)
    return worst_l, worst_p


if __name__ == "__main__":
    main()
