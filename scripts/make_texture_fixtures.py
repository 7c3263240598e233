#!/usr/bin/env python3
"""Writes the texture fixtures of tests/spec/texture.rs and the values Mitsuba 3 gives for them.

    /work/venv-mi/bin/python scripts/make_texture_fixtures.py   # any Python with mitsuba, numpy

Images (tests/fixtures/textures/): `rgb4x3.png`, a 4 x 3 8-bit RGB PNG whose bytes are
(10 + 60 i + 7 j, 200 - 50 j, 30 i) at texel (i, j) (column i, row j from the top), and
`rgb4x3.exr`, the same texels as linear floats (byte / 255). `mitsuba.json`: Mitsuba 3's
`bitmap` evaluated (scalar_rgb) at a list of uv points for every filter_type, wrap_mode and
raw, `checkerboard` at the same points, and the uv Mitsuba's `rectangle`, `disk`, `sphere` and
`cube` give at the points rays hit; meshes with and without texture coordinates
(`mesh-vt.obj`, `mesh.obj`, `mesh-uv.ply`, `mesh-st.ply`) and the uv Mitsuba's `obj` and `ply`
give at ray hits for each `flip_tex_coords`; and the bitmaps' one-channel `eval_1`.
"""
import json
import os

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
OUT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                   "tests", "fixtures", "textures")
os.makedirs(OUT, exist_ok=True)

W, H = 4, 3
data = np.zeros((H, W, 3), dtype=np.uint8)
for j in range(H):
    for i in range(W):
        data[j, i] = (10 + 60 * i + 7 * j, 200 - 50 * j, 30 * i)
mi.Bitmap(data, pixel_format=mi.Bitmap.PixelFormat.RGB).write(os.path.join(OUT, "rgb4x3.png"))
mi.Bitmap(data.astype(np.float32) / 255.0, pixel_format=mi.Bitmap.PixelFormat.RGB).write(
    os.path.join(OUT, "rgb4x3.exr"))

UVS = [(0.125, 1 / 6), (0.375, 0.5), (0.5, 0.5), (0.0, 0.0), (1.0, 1.0), (0.99, 0.01),
       (-0.1, 0.3), (1.3, -0.45), (2.2, 1.7), (-1.05, -0.8), (0.61, 0.83)]


def eval_tex(props):
    tex = mi.load_dict(props)
    si = mi.SurfaceInteraction3f()
    out = []
    for u, v in UVS:
        si.uv = mi.Point2f(u, v)
        out.append(list(map(float, tex.eval(si))))
    return out


lookups = []
for f in ["bilinear", "nearest"]:
    for w in ["repeat", "mirror", "clamp"]:
        for file in ["rgb4x3.png", "rgb4x3.exr"]:
            for raw in [False, True]:
                d = {"type": "bitmap", "filename": os.path.join(OUT, file),
                     "filter_type": f, "wrap_mode": w, "raw": raw}
                lookups.append({"file": file, "filter_type": f, "wrap_mode": w, "raw": raw,
                                "values": eval_tex(d)})
to_uv = mi.ScalarTransform4f().translate([0.25, -0.5, 0]) @ mi.ScalarTransform4f().scale([2, 3, 1])
lookups.append({"file": "rgb4x3.png", "filter_type": "bilinear", "wrap_mode": "repeat",
                "raw": False, "to_uv": [[2, 0, 0.25], [0, 3, -0.5]],
                "values": eval_tex({"type": "bitmap", "filename": os.path.join(OUT, "rgb4x3.png"),
                                    "to_uv": to_uv})})
checker = eval_tex({"type": "checkerboard", "to_uv": mi.ScalarTransform4f().scale([3, 2, 1])})


def shape_uvs(props, hits):
    """uv at the points where rays (origin, direction) hit the shape."""
    scene = mi.load_dict({"type": "scene", "s": props})
    out = []
    for o, d in hits:
        si = scene.ray_intersect(mi.Ray3f(o, dr_normalize(d)))
        out.append({"p": list(map(float, si.p)), "n": list(map(float, si.n)),
                    "uv": list(map(float, si.uv))})
    return out


def dr_normalize(d):
    d = np.array(d, dtype=float)
    return (d / np.linalg.norm(d)).tolist()


T = mi.ScalarTransform4f
shapes = {
    "rectangle": shape_uvs({"type": "rectangle",
                            "to_world": T().translate([1, 2, 3]) @ T().rotate([0, 0, 1], 30) @ T().scale([2, 0.5, 1])},
                           [([1.3, 2.1, 5], [0, 0, -1]), ([0.2, 1.9, 5], [0.1, 0.05, -1])]),
    "disk": shape_uvs({"type": "disk", "to_world": T().translate([0, 0, 1]) @ T().scale([2, 1, 1])},
                      [([0.5, 0.3, 5], [0, 0, -1]), ([-1.2, -0.4, 5], [0, 0, -1])]),
    "sphere": shape_uvs({"type": "sphere", "center": [1, -1, 0.5], "radius": 2},
                        [([5, -0.5, 1], [-1, 0, 0]), ([1.2, -5, 0.1], [0, 1, 0.2]),
                         ([0.5, 0.0, 5], [0, -0.1, -1])]),
    "cube": shape_uvs({"type": "cube", "to_world": T().translate([0.5, 0, -1]) @ T().scale([1, 2, 0.5])},
                      [([5, 0.3, -1.1], [-1, 0, 0]), ([-5, -0.7, -0.8], [1, 0, 0]),
                       ([0.3, 5, -1.2], [0, -1, 0]), ([0.9, -5, -0.9], [0, 1, 0]),
                       ([0.2, 0.5, 5], [0, 0, -1]), ([0.7, -1.3, -5], [0, 0, 1])]),
}

# Meshes: a non-planar quad (one OBJ face, split into a fan) and a triangle, with texture
# coordinates (OBJ `vt`; PLY `u`, `v` and `s`, `t`) and without; the rays come from +z.
MESH_V = [(0, 0, 0), (2, 0, 0), (0, 1, 0), (2, 1, 0.5), (3, 0.5, 0.2)]
MESH_VT = [(0.1, 0.2), (0.9, 0.3), (0.2, 0.7), (0.8, 0.95), (1.4, -0.3)]
MESH_F = [(0, 1, 3, 2), (1, 4, 3)]
with open(os.path.join(OUT, "mesh-vt.obj"), "w") as f:
    f.write("".join(f"v {x} {y} {z}\n" for x, y, z in MESH_V))
    f.write("".join(f"vt {u} {v}\n" for u, v in MESH_VT))
    f.write("".join("f " + " ".join(f"{i + 1}/{i + 1}" for i in face) + "\n" for face in MESH_F))
with open(os.path.join(OUT, "mesh.obj"), "w") as f:
    f.write("".join(f"v {x} {y} {z}\n" for x, y, z in MESH_V))
    f.write("".join("f " + " ".join(f"{i + 1}" for i in face) + "\n" for face in MESH_F))
for name, (a, b) in [("mesh-uv.ply", ("u", "v")), ("mesh-st.ply", ("s", "t"))]:
    with open(os.path.join(OUT, name), "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex 5\n")
        f.write("".join(f"property float {c}\n" for c in ["x", "y", "z", a, b]))
        # Mitsuba's `ply` reads triangles only: the quad as the OBJ's fan
        tris = [(0, 1, 3), (0, 3, 2), (1, 4, 3)]
        f.write("element face 3\nproperty list uchar int vertex_indices\nend_header\n")
        f.write("".join(f"{x} {y} {z} {u} {v}\n" for (x, y, z), (u, v) in zip(MESH_V, MESH_VT)))
        f.write("".join("3 " + " ".join(map(str, t)) + "\n" for t in tris))
MESH_RAYS = [([x, y, 5], [0, 0, -1]) for x, y in
             [(0.5, 0.3), (1.5, 0.8), (1.0, 0.1), (0.2, 0.9), (2.5, 0.5), (2.2, 0.3)]]
meshes = []
for file in ["mesh-vt.obj", "mesh.obj", "mesh-uv.ply", "mesh-st.ply"]:
    for flip in [None, True, False]:
        props = {"type": file.rsplit(".", 1)[1], "filename": os.path.join(OUT, file),
                 "face_normals": True}
        if flip is not None:
            props["flip_tex_coords"] = flip
        meshes.append({"file": file, "flip_tex_coords": flip, "hits": shape_uvs(props, MESH_RAYS)})

# a texture's one-channel value (`eval_1`, what a textured roughness reads)
eval_1 = []
for file in ["rgb4x3.png", "rgb4x3.exr"]:
    tex = mi.load_dict({"type": "bitmap", "filename": os.path.join(OUT, file)})
    si = mi.SurfaceInteraction3f()
    values = []
    for u, v in UVS:
        si.uv = mi.Point2f(u, v)
        values.append(float(tex.eval_1(si)))
    eval_1.append({"file": file, "values": values})
# Mitsuba 3's checkerboard `eval_1` gives color1 where `eval` gives color0 and back
tex = mi.load_dict({"type": "checkerboard", "color0": 0.05, "color1": 0.4,
                    "to_uv": mi.ScalarTransform4f().scale([3, 2, 1])})
si = mi.SurfaceInteraction3f()
values = []
for u, v in UVS:
    si.uv = mi.Point2f(u, v)
    values.append(float(tex.eval_1(si)))
eval_1.append({"checkerboard": {"color0": 0.05, "color1": 0.4, "to_uv": [[3, 0, 0], [0, 2, 0]]},
               "values": values})

with open(os.path.join(OUT, "mitsuba.json"), "w") as f:
    json.dump({"mitsuba": mi.__version__, "uvs": UVS, "lookups": lookups,
               "checkerboard": {"to_uv": [[3, 0, 0], [0, 2, 0]], "values": checker},
               "shapes": shapes, "meshes": meshes, "eval_1": eval_1}, f,
              separators=(",", ":"))
print("wrote", OUT)
