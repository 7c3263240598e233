#!/usr/bin/env python3
"""Writes Mitsuba `serialized` mesh files and records what Mitsuba 3 reads from them.

    /work/venv-mi/bin/python scripts/make_serialized_fixtures.py   # any Python with mitsuba

Mitsuba 3 reads this format and does not write it, so the files are written here from its
documentation (Mitsuba 3 documentation, plugin `serialized`; the versions 3 and 4 that
Mitsuba 3.9's src/shapes/serialized.cpp reads): per shape a little-endian header 0x041C and
the version, then a zlib stream of the flag word (0x1 normals, 0x2 texture coordinates, 0x8
colours, 0x10 face normals, 0x1000 single, 0x2000 double precision), the null-terminated name
(version 4), the vertex and triangle counts (uint64), positions, normals, texture coordinates,
colours (3, 3, 2, 3 values per vertex) and 3 uint32 indices per triangle; the file ends with
the shapes' offsets (uint64 in version 4, uint32 in version 3) and their count (uint32).

Written:
  tests/fixtures/serialized/multi.serialized   version 4: shape 0 `tetra` (single precision,
      normals that are not unit, texture coordinates), shape 1 `panel` (double precision, values
      f32 cannot hold, texture coordinates and colours, an unused vertex), shape 2 `pyramid`
      (no normals, the face-normals flag Mitsuba 3 ignores)
  tests/fixtures/serialized/legacy.serialized  version 3: `tetra` again, and `panel` with
      double-precision normals
  tests/fixtures/serialized/mitsuba.json       what Mitsuba 3 (scalar_rgb) loads for every
      shape: vertex positions, normals, texture coordinates and faces
  scenes/xml/spheres.serialized                version 4: shape 0 the sphere of
      scenes/xml/sphere-vn.obj with its normals (double precision), shape 1 the sphere of
      sphere-bare.obj (single, no normals), shape 2 a floor with texture coordinates; read by
      scenes/xml/serialized.xml
"""
import json
import os
import struct
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIXTURES = os.path.join(ROOT, "tests", "fixtures", "serialized")
MAGIC = 0x041C
HAS_NORMALS, HAS_TEXCOORDS, HAS_COLORS, FACE_NORMALS = 0x1, 0x2, 0x8, 0x10
SINGLE, DOUBLE = 0x1000, 0x2000


def shape(version, name, pos, faces, normals=None, uvs=None, colors=None, double=False,
          extra=0):
    """One shape: its header and its zlib stream."""
    flags = (DOUBLE if double else SINGLE) | extra
    arrays = [pos]
    for bit, a in ((HAS_NORMALS, normals), (HAS_TEXCOORDS, uvs), (HAS_COLORS, colors)):
        if a is not None:
            flags |= bit
            arrays.append(a)
    body = struct.pack("<I", flags)
    if version == 4:
        body += name.encode() + b"\0"
    body += struct.pack("<QQ", len(pos), len(faces))
    real = "d" if double else "f"
    for a in arrays:
        flat = [x for v in a for x in v]
        body += struct.pack(f"<{len(flat)}{real}", *flat)
    flat = [i for f in faces for i in f]
    body += struct.pack(f"<{len(flat)}I", *flat)
    return struct.pack("<HH", MAGIC, version) + zlib.compress(body, 9)


def serialized(version, shapes):
    """The shapes one after the other, then the dictionary of their offsets."""
    out, offsets = b"", []
    for s in shapes:
        offsets.append(len(out))
        out += s
    entry = "Q" if version == 4 else "I"
    return out + struct.pack(f"<{len(offsets)}{entry}I", *offsets, len(offsets))


TETRA = dict(
    pos=[(0.1, -0.2, 0.3), (1.7, 0.05, -0.4), (0.2, 1.3, 0.6), (-0.3, 0.4, 1.9)],
    faces=[(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)],
    normals=[(-1.0, -1.0, -1.0), (2.0, -0.5, -0.25), (0.1, 3.0, 0.2), (-0.3, 0.2, 0.7)],
    uvs=[(0.1, 0.9), (0.8, 0.15), (0.45, 0.6), (-0.2, 1.25)],
)
PANEL = dict(
    pos=[(-1 / 3, 0.0, -2 / 7), (1.1, 1e-3, -0.7), (1.3, 0.01, 0.9), (-0.9, -0.02, 1 / 9),
         (5.0, 5.0, 5.0)],
    faces=[(0, 1, 2), (0, 2, 3)],
    uvs=[(0.0, 0.0), (1 / 3, 0.1), (0.7, 2 / 3), (0.05, 0.95), (0.5, 0.5)],
)
PANEL_NORMALS = [(0.01, 1.0, -0.02), (0.0, 1 / 3, 0.0), (-0.1, 0.9, 0.1), (0.2, 0.8, 0.0),
                 (0.0, 1.0, 0.0)]
PYRAMID = dict(
    pos=[(-0.5, 0.0, -0.5), (0.5, 0.0, -0.5), (0.5, 0.0, 0.5), (-0.5, 0.0, 0.5), (0.0, 0.8, 0.0)],
    faces=[(0, 1, 2), (0, 2, 3), (0, 4, 1), (1, 4, 2), (2, 4, 3), (3, 4, 0)],
)


def fixtures():
    os.makedirs(FIXTURES, exist_ok=True)
    multi = serialized(4, [
        shape(4, "tetra", **TETRA),
        shape(4, "panel", colors=[(0.2, 0.4, 0.6)] * 5, double=True, **PANEL),
        shape(4, "pyramid", extra=FACE_NORMALS, **PYRAMID),
    ])
    legacy = serialized(3, [
        shape(3, "", **TETRA),
        shape(3, "", normals=PANEL_NORMALS, double=True, **PANEL),
    ])
    files = {"multi.serialized": (multi, [True, False, False]),
             "legacy.serialized": (legacy, [True, True])}
    for name, (data, _) in files.items():
        with open(os.path.join(FIXTURES, name), "wb") as f:
            f.write(data)
    return {name: stored for name, (_, stored) in files.items()}


def obj_mesh(name):
    """Positions, normals (`vn`, by the position's index) and triangles of an OBJ of
    scenes/xml whose faces are `f i//i` or `f i`."""
    pos, nrm, faces = [], [], []
    with open(os.path.join(ROOT, "scenes", "xml", name)) as f:
        for line in f:
            w = line.split()
            if w and w[0] == "v":
                pos.append(tuple(float(x) for x in w[1:4]))
            elif w and w[0] == "vn":
                nrm.append(tuple(float(x) for x in w[1:4]))
            elif w and w[0] == "f":
                ids = [int(x.split("/")[0]) - 1 for x in w[1:]]
                assert all(x.split("/")[-1] == x.split("/")[0] for x in w[1:]), line
                faces.append(tuple(ids))
    return pos, (nrm or None), faces


def scene_file():
    pos0, nrm0, faces0 = obj_mesh("sphere-vn.obj")
    pos1, _, faces1 = obj_mesh("sphere-bare.obj")
    floor = [(-3.0, 0.0, 3.0), (3.0, 0.0, 3.0), (3.0, 0.0, -3.0), (-3.0, 0.0, -3.0)]
    data = serialized(4, [
        shape(4, "sphere-vn", pos0, faces0, normals=nrm0, double=True),
        shape(4, "sphere-bare", pos1, faces1),
        shape(4, "floor", floor, [(0, 1, 2), (0, 2, 3)],
              uvs=[(0.0, 0.0), (3.0, 0.0), (3.0, 3.0), (0.0, 3.0)]),
    ])
    with open(os.path.join(ROOT, "scenes", "xml", "spheres.serialized"), "wb") as f:
        f.write(data)


def mitsuba_reads(stored):
    """What Mitsuba 3 loads for every shape of every fixture (`stored`: per file, whether each
    shape stores its normals)."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    shapes = []
    for name, has_normals in stored.items():
        for k in range(len(has_normals)):
            s = mi.load_dict({"type": "serialized", "filename": os.path.join(FIXTURES, name),
                              "shape_index": k})
            p = mi.traverse(s)
            rec = {"file": name, "shape_index": k, "stored_normals": has_normals[k]}
            for key, dim in (("vertex_positions", 3), ("vertex_normals", 3),
                             ("vertex_texcoords", 2), ("faces", 3)):
                flat = list(p[key]) if key in p else []
                rec[key] = [flat[i:i + dim] for i in range(0, len(flat), dim)]
            rec["faces"] = [[int(i) for i in f] for f in rec["faces"]]
            rec["vertex_positions"] = [[float(x) for x in v] for v in rec["vertex_positions"]]
            rec["vertex_normals"] = [[float(x) for x in v] for v in rec["vertex_normals"]]
            rec["vertex_texcoords"] = [[float(x) for x in v] for v in rec["vertex_texcoords"]]
            shapes.append(rec)
    out = {"mitsuba": mi.__version__, "variant": "scalar_rgb", "shapes": shapes}
    with open(os.path.join(FIXTURES, "mitsuba.json"), "w") as f:
        f.write(json.dumps(out, separators=(",", ":")).replace("},{", "},\n{") + "\n")


if __name__ == "__main__":
    stored = fixtures()
    scene_file()
    mitsuba_reads(stored)
