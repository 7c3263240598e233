#!/usr/bin/env python3
"""Records the (u, v) Mitsuba 3 gives on its shapes under flips, rotations and to_world maps.

    /work/venv-mi/bin/python scripts/make_shape_uv_fixtures.py   # any Python with mitsuba, numpy

Writes tests/fixtures/textures/mitsuba-shapes.json: per case the XML of a `shape` element
(opening tag and children; the test adds a textured BSDF and the closing tag), the rays cast at
it and, per ray, the point, normal and uv of Mitsuba's hit (scalar_rgb). The cases are what a
primitive's uv depends on: a flipped `rectangle` and `disk` (flip_normals turns the normal, not
the uv), a `sphere` rotated by its to_world (uv in the sphere's own frame), and `cylinder`s whose
angle starts in the frame Mitsuba builds about the axis (`Frame3f(p1 - p0)`) mapped by to_world,
with an axis along -z (the other branch of that frame), a flip and a scale along the axis.
"""
import json
import os

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
OUT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                   "tests", "fixtures", "textures", "mitsuba-shapes.json")


def tf(ops):
    """An XML `to_world` from (op, attributes) pairs, applied in order."""
    attrs = [" ".join('%s="%s"' % kv for kv in a.items()) for _, a in ops]
    body = "".join(f"<{op} {at}/>" for (op, _), at in zip(ops, attrs))
    return f'<transform name="to_world">{body}</transform>'


def unit(v):
    v = np.array(v, dtype=float)
    return v / np.linalg.norm(v)


def perpendicular(axis, angle):
    """A unit vector perpendicular to `axis` at `angle` about it (any fixed reference)."""
    a = unit(axis)
    ref = unit(np.cross(a, [0.3, 0.5, 0.8]))
    return np.cos(angle) * ref + np.sin(angle) * np.cross(a, ref)


def planar_rays(m):
    """Rays at local points of a planar shape at z = 0, from both sides."""
    rays = []
    for k, (x, y) in enumerate([(0.3, 0.2), (-0.5, 0.4), (0.1, -0.7), (-0.35, -0.3), (0.6, 0.55)]):
        p = np.array(m @ mi.ScalarPoint3f(x, y, 0))
        w = unit(np.array(m @ mi.ScalarNormal3f(0, 0, 1)) + [0.1, -0.2, 0.15])
        w = w if k % 2 == 0 else -w
        rays.append((p + 4 * w, -w))
    return rays


def sphere_rays(m):
    c, r = np.array(m @ mi.ScalarPoint3f(0, 0, 0)), np.linalg.norm(m @ mi.ScalarVector3f(1, 0, 0))
    rays = []
    for w in [(1, 0.2, 0.1), (-0.3, 1, 0.4), (0.2, -0.5, 1), (-1, -0.7, -0.2), (0.4, 0.3, -1),
              (-0.2, -1, 0.6)]:
        w = unit(w)
        aim = c + 0.3 * r * unit(np.cross(w, [0.2, 0.7, 0.1]))
        rays.append((aim + 5 * r * w, -w))
    return rays


def cylinder_rays(m):
    p0, p1 = np.array(m @ mi.ScalarPoint3f(0, 0, 0)), np.array(m @ mi.ScalarPoint3f(0, 0, 1))
    r = np.linalg.norm(m @ mi.ScalarVector3f(1, 0, 0))
    rays = []
    for h, phi in [(0.2, 0.3), (0.5, 1.9), (0.8, 3.5), (0.35, 4.4), (0.65, 5.6)]:
        a = p0 + h * (p1 - p0)
        w = perpendicular(p1 - p0, phi)
        rays.append((a + (r + 3) * w, -w))
    # from the axis outwards: the inside of the tube
    rays.append((p0 + 0.45 * (p1 - p0), perpendicular(p1 - p0, 2.7)))
    return rays


RAYS = {"rectangle": planar_rays, "disk": planar_rays, "sphere": sphere_rays,
        "cylinder": cylinder_rays}
cases = []
# a rotation about a unit axis (Mitsuba's `rotate` takes the axis as given)
ROT = ("rotate", {"x": 0.48, "y": 0.8, "z": -0.36, "angle": 50})
for kind, ops in [
    ("rectangle", [("scale", {"x": 2, "y": 0.5}), ROT, ("translate", {"x": 1, "y": 2, "z": 3})]),
    ("disk", [("scale", {"x": 2, "y": 1}), ("rotate", {"x": 1, "angle": 60}),
              ("translate", {"z": 1})]),
]:
    for flip in ["true", "false"]:
        cases.append((f"{kind} flip {flip}",
                      f'<shape type="{kind}"><boolean name="flip_normals" value="{flip}"/>{tf(ops)}'))
# spheres: centre and radius inside a rotating to_world, and a quarter turn
s_ops = [("scale", {"value": 1.5}), ROT, ("translate", {"x": 0.5, "y": -1, "z": 2})]
cases.append(("sphere rotated", '<shape type="sphere"><point name="center" x="1" y="-1" z="0.5"/>'
              f'<float name="radius" value="2"/>{tf(s_ops)}'))
cases.append(("sphere quarter turn", f'<shape type="sphere">{tf([("rotate", {"y": 1, "angle": 90})])}'))


def cylinder(name, p0, p1, r, ops, flip="false"):
    cases.append((name, f'<shape type="cylinder"><point name="p0" x="{p0[0]}" y="{p0[1]}" z="{p0[2]}"/>'
                  f'<point name="p1" x="{p1[0]}" y="{p1[1]}" z="{p1[2]}"/>'
                  f'<float name="radius" value="{r}"/>'
                  f'<boolean name="flip_normals" value="{flip}"/>' + (tf(ops) if ops else "")))


cylinder("cylinder default", (0, 0, 0), (0, 0, 1), 1, [])
cylinder("cylinder tilted", (1, 0, 0), (0, 2, 1), 0.5, [])
cylinder("cylinder down -z", (0.2, 0, 1), (0, 0.1, -1), 0.7, [])
cylinder("cylinder to_world flipped", (1, 0, 0), (0, 2, 1), 0.5,
         [("scale", {"value": 1.3}), ROT, ("translate", {"x": -1, "y": 0.5, "z": 2})], flip="true")
cylinder("cylinder stretched along its axis", (0, 0, 0), (0, 0, 1), 1,
         [("scale", {"x": 0.5, "y": 0.5, "z": 3}), ("rotate", {"x": 1, "angle": 120})])

out = []
for name, xml in cases:
    scene = mi.load_string(f'<scene version="3.0.0">{xml}</shape></scene>')
    params = mi.traverse(scene)
    key = next(k for k in params.keys() if k.endswith("to_world"))
    m = mi.ScalarTransform4f(np.array(params[key].matrix, dtype=float).reshape(4, 4))
    hits = []
    for o, d in RAYS[name.split()[0]](m):
        si = scene.ray_intersect(mi.Ray3f(list(map(float, o)), list(map(float, d))))
        assert si.is_valid(), (name, o, d)
        hits.append({"o": list(map(float, o)), "d": list(map(float, d)),
                     "p": list(map(float, si.p)), "n": list(map(float, si.n)),
                     "uv": list(map(float, si.uv))})
    out.append({"name": name, "xml": xml, "hits": hits})

with open(OUT, "w") as f:
    json.dump({"mitsuba": mi.__version__, "cases": out}, f, indent=1)
print("wrote", OUT)
