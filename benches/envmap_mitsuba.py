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
    sys.exit(0 if worst <= 1e-4 else 1)


if __name__ == "__main__":
    main()
