#!/usr/bin/env python3
"""Records the normals and (u, v) Mitsuba 3 gives on meshes with and without `flip_normals`.

    /work/venv-mi/bin/python scripts/make_mesh_normal_fixtures.py   # any Python with mitsuba

Writes tests/fixtures/textures/mitsuba-mesh-normals.json: per case the XML of a mesh `shape`
element (opening tag and children; the test closes it), and per ray cast at it the ray, the
point, the geometric normal `n`, the shading normal `sh_n` and the uv of Mitsuba's hit
(scalar_rgb), and `le`, the radiance an area emitter of 1 on the mesh sends back along the ray
(which side emits). The meshes: `mesh-vt.obj` (no `vn`: Mitsuba computes vertex normals), the
unit sphere `sphere-vn.obj` (its own `vn`) and `mesh-uv.ply`, each smooth, flipped and not,
and the OBJ with `face_normals` flipped.
"""
import json
import os

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIXTURES = os.path.join(ROOT, "tests", "fixtures", "textures")
OUT = os.path.join(FIXTURES, "mitsuba-mesh-normals.json")
mi.file_resolver().prepend(FIXTURES)


def unit(v):
    v = np.array(v, dtype=float)
    return v / np.linalg.norm(v)


def planar_rays():
    """Rays at points of the planar-ish meshes (x in [0, 3], y in [0, 1]), from both sides."""
    rays = []
    for k, (x, y) in enumerate([(0.3, 0.2), (1.2, 0.5), (1.7, 0.3), (2.4, 0.55), (0.8, 0.8)]):
        w = unit([0.1, -0.2, 1.0])
        w = w if k % 2 == 0 else -w
        rays.append((np.array([x, y, 0.2]) + 4 * w, -w))
    return rays


def sphere_rays():
    rays = []
    for w in [(1, 0.2, 0.1), (-0.3, 1, 0.4), (0.2, -0.5, 1), (-1, -0.7, -0.2), (0.4, 0.3, -1)]:
        w = unit(w)
        aim = 0.3 * unit(np.cross(w, [0.2, 0.7, 0.1]))
        rays.append((aim + 5 * w, -w))
    # from the centre outwards: the inside
    rays.append((np.zeros(3), unit([0.3, -0.4, 0.5])))
    return rays


cases = []
for flip in ["true", "false"]:
    for kind, file, rays in [("obj", "mesh-vt.obj", planar_rays), ("ply", "mesh-uv.ply", planar_rays),
                             ("obj", "../agreement/sphere-vn.obj", sphere_rays)]:
        cases.append((f"{file} flip {flip}", rays,
                      f'<shape type="{kind}"><string name="filename" value="{file}"/>'
                      f'<boolean name="flip_normals" value="{flip}"/>'))
cases.append(("mesh-vt.obj flat flip true", planar_rays,
              '<shape type="obj"><string name="filename" value="mesh-vt.obj"/>'
              '<boolean name="face_normals" value="true"/><boolean name="flip_normals" value="true"/>'))

out = []
for name, rays, xml in cases:
    lit = xml + '<emitter type="area"><rgb name="radiance" value="1"/></emitter>'
    scene = mi.load_string(f'<scene version="3.0.0">{lit}</shape></scene>')
    hits = []
    for o, d in rays():
        ray = mi.Ray3f(list(map(float, o)), list(map(float, d)))
        si = scene.ray_intersect(ray)
        assert si.is_valid(), (name, o, d)
        le = si.emitter(scene).eval(si)
        hits.append({"o": list(map(float, o)), "d": list(map(float, d)),
                     "p": list(map(float, si.p)), "n": list(map(float, si.n)),
                     "sh_n": list(map(float, si.sh_frame.n)), "uv": list(map(float, si.uv)),
                     "le": float(le[0])})
    out.append({"name": name, "xml": xml, "hits": hits})

with open(OUT, "w") as f:
    json.dump({"mitsuba": mi.__version__, "cases": out}, f, indent=1)
print("wrote", OUT)
