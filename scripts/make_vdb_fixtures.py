#!/usr/bin/python3
"""Writes the OpenVDB fixtures of tests/fixtures/vdb/ with the real OpenVDB library.

Run with Debian's Python, which has the bindings (`apt-get install python3-openvdb
libopenvdb-dev libboost-dev g++`): `/usr/bin/python3 scripts/make_vdb_fixtures.py`. CI never runs it: the
files it writes are committed, with PROVENANCE.md.

Each `NAME.vdb` holds a float grid `density` (uniform scale 0.125, translated by (-1, -0.5, -0.5): the box
(-1.125, -0.625, -0.625) .. (1, 0.5, 0.5)): voxels in
[0,7]^3 with distinct values (two of them inactive, one of those with a value that is not the
background), and an active tile (one 8^3 leaf-sized tile of value 0.7) beside them, so the
reader meets leaves, value masks, inactive values and tiles. `NAME.vol` is what OpenVDB itself
reads back from `NAME.vdb`: the value of every voxel of the active bounding box grown by one
voxel on every side, as a Mitsuba float32 `.vol` whose box is the world position of the first
and last of these voxels. pathspace must read the `.vdb` into exactly that grid.

Variants: `blosc` (OpenVDB's default: Blosc-LZ4 + active mask), `zip` (zlib + active mask),
`none` (no codec: the active values stored as they are), `half` (Blosc, values saved as half floats), and
`two_grids` (Blosc, the density and a second grid `temperature`); and two files the reader
must refuse: `huge` (a 4096^3 active region held by tiles) and `rotated` (a rotated transform).
"""
import os
import struct
import subprocess
import sys
import tempfile

import pyopenvdb as vdb

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "..", "tests", "fixtures", "vdb")
SCALE = 0.125
TRANSLATE = (-1.0, -0.5, -0.5)


def density_grid():
    g = vdb.FloatGrid()
    g.name = "density"
    t = vdb.createLinearTransform(voxelSize=SCALE)
    t.translate(TRANSLATE)
    g.transform = t
    a = g.getAccessor()
    for x in range(8):
        for y in range(8):
            for z in range(8):
                a.setValueOn((x, y, z), 0.1 * x + 0.05 * y + 0.01 * z)
    g.fill((8, 0, 0), (15, 7, 7), 0.7)  # one active tile of the 16^3 internal node
    a.setValueOff((1, 1, 1), 0.0)  # inactive, the background
    a.setValueOff((2, 2, 2), 0.3)  # inactive, another value
    return g


def temperature_grid():
    g = vdb.FloatGrid()
    g.name = "temperature"
    g.transform = density_grid().transform
    g.fill((0, 0, 0), (3, 3, 3), 2.0)
    return g


def world(t, ijk):
    """The world position of index point ijk, in double as OpenVDB's map computes it."""
    return tuple(ijk[k] * SCALE + TRANSLATE[k] for k in range(3))


def write_vol(path, grid):
    """The grid's values over its active bounding box grown by one voxel, as OpenVDB reads
    them, as a float32 .vol (x fastest)."""
    lo, hi = grid.evalActiveVoxelBoundingBox()
    lo = [c - 1 for c in lo]
    hi = [c + 1 for c in hi]
    res = [hi[k] - lo[k] + 1 for k in range(3)]
    acc = grid.getConstAccessor()
    values = []
    for z in range(lo[2], hi[2] + 1):
        for y in range(lo[1], hi[1] + 1):
            for x in range(lo[0], hi[0] + 1):
                values.append(acc.getValue((x, y, z)))
    box = world(grid.transform, lo) + world(grid.transform, hi)
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]) + struct.pack("<i", 1) + struct.pack("<3i", *res))
        f.write(struct.pack("<i", 1) + struct.pack("<6f", *box))
        f.write(struct.pack("<%df" % len(values), *values))


def main():
    os.makedirs(OUT, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        tool = os.path.join(tmp, "vdb_recompress")
        subprocess.check_call(["g++", "-O1", "-std=c++17", "-o", tool,
                               os.path.join(HERE, "vdb_recompress.cpp"),
                               "-lopenvdb", "-ltbb", "-lpthread"])
        blosc = os.path.join(OUT, "blosc.vdb")
        vdb.write(blosc, grids=[density_grid()])
        subprocess.check_call([tool, blosc, os.path.join(OUT, "zip.vdb"), "3"])
        subprocess.check_call([tool, blosc, os.path.join(OUT, "none.vdb"), "2"])
    half = density_grid()
    half.saveFloatAsHalf = True
    vdb.write(os.path.join(OUT, "half.vdb"), grids=[half])
    vdb.write(os.path.join(OUT, "two_grids.vdb"), grids=[temperature_grid(), density_grid()])
    # refused: a 4096^3 active region in a file of a few KB (tiles), and a rotated transform
    huge = vdb.FloatGrid()
    huge.name = "density"
    huge.fill((0, 0, 0), (4095, 4095, 4095), 1.0)
    vdb.write(os.path.join(OUT, "huge.vdb"), grids=[huge])
    rotated = density_grid()
    t = vdb.createLinearTransform(voxelSize=SCALE)
    t.rotate(0.5, vdb.Axis.Z)
    rotated.transform = t
    vdb.write(os.path.join(OUT, "rotated.vdb"), grids=[rotated])
    for name in ["blosc", "zip", "none", "half", "two_grids"]:
        grid = vdb.read(os.path.join(OUT, name + ".vdb"), "density")
        write_vol(os.path.join(OUT, name + ".vol"), grid)
    print("OpenVDB %d.%d.%d, file format %d" % (vdb.LIBRARY_VERSION + (vdb.FILE_FORMAT_VERSION,)),
          file=sys.stderr)


if __name__ == "__main__":
    main()
