#!/usr/bin/env python3
"""Mutation fuzzing of pathspace's inputs: scene files (TOML and Mitsuba XML), density grids
(text, `.vol` and OpenVDB), OBJ, PLY and Mitsuba `serialized` meshes, EXR and Radiance (.hdr) environment maps and PNG
textures, Mitsuba `.spd` spectra, and of the
files it reads back: checkpoints and renders.

Each scene case copies one shipped scene (with the grid, OBJ or EXR file it reads) into a
scratch directory, mutates the scene, its grid or its mesh (extreme numbers, wrong types,
deleted or duplicated lines, resized arrays, control bytes and bad UTF-8, truncation, huge
headers and arrays), and runs `pathspace info` and `pathspace render` on it under a time and a
memory limit. A quarter of the cases are adversarial instead, made from an 8x8 fog box (and its
mesh and grid variants) rendered once per campaign:

  checkpoint  a checkpoint flipped, cut, extended, or forged (payload bytes set to NaN, inf or
              huge floats and the FNV-1a checksum recomputed), then `render --resume`
  merge       one of two renders given a lying header (spp, shard, streams, scene_inputs,
              seed), extreme pixels or a changed byte (half the time with its checksum
              dropped), then `merge`; the merged image must read back finite, and a changed
              byte that kept its checksum must be refused or change nothing
  changed     the mesh or grid a checkpoint's scene reads edited, then `render --resume`:
              it must be refused naming that file
  xml         a Mitsuba scene with an attribute flood, deep nesting, a huge text node, a DTD
              with entities or a million elements: refused or imported within the time limit
  kill        a render writing over an existing output killed (SIGKILL, or SIGINT) at a
              random moment: the output is the earlier file or a whole new one, a checkpoint
              left behind has a matching checksum, and `.partial` files only after SIGKILL
  writers     two renders with the same output at once: both succeed, the output reads back

What a case may end as:

  ok        the render finished and its mean is finite
  refused   a nonzero exit with an error that names the file it is about
  --------  anything below is a bug and makes the script exit 1 ----------------------------
  panic     a Rust panic (exit 101 or "panicked at")
  timeout   info or render exceeded its time limit
  memory    the memory limit was hit (an allocation failure or a kill)
  crash     killed by another signal
  nonfinite a finished render or merge whose mean is NaN or infinite
  unnamed   an error that names no file, or a silent nonzero exit
  control   an error that echoes raw control bytes
  merged-damage  a changed byte under a kept checksum merged into another image
  harness   the fuzzer itself failed on the case (kept for its author, not a renderer bug)
  partial   a killed write left a damaged output, or `.partial` files after a clean stop
  resumed-changed  a resume went on although a file its scene reads had changed
  writers   one of two concurrent renders failed, or their output does not read back

Cases are reproducible: case k of `--seed S` is the same mutation on every machine (a base
checkpoint's pass count depends on timing, so its bytes may differ; `--keep` saves them).
`--keep DIR` saves every case that is a bug, with the command lines, for replay; `--only KIND`
runs only the cases of one kind among the indices (`--only vdb`: the scene cases that mutate
an OpenVDB file; `--only hdr`: the scene cases that read a Radiance map; `--only png`: those
that read a PNG texture; `--only uv`: those that mutate a textured mesh, an OBJ with `vt` or a
PLY with `u`, `v`; `--only serialized`: those that mutate a Mitsuba `serialized` mesh file;
`--only spd`: those that mutate a `.spd` spectrum of scenes/xml/spectrum-lists.xml).

  python3 scripts/fuzz.py --cases 20000 --jobs 2        # the campaign before an issue closes
  python3 scripts/fuzz.py --cases 500 --jobs 2          # the short version .ci/run runs
"""

import argparse
import collections
import concurrent.futures
import json
import os
import random
import re
import resource
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BAD = ("panic", "timeout", "memory", "crash", "nonfinite", "unnamed", "control", "partial",
       "resumed-changed", "writers", "merged-damage")

EXTREME_NUMBERS = [
    "0", "-0.0", "-1", "0.5", "3", "1e-9", "1e-30", "1e9", "1e30", "-1e30", "1e308",
    "nan", "inf", "-inf", "2147483648", "4294967296", "18446744073709551615",
    "99999999999999999999", "1e5", "65536", "-2147483649", "0.999999", "1.000001",
]
ODD_STRINGS = [
    "", "x", "bpdt", "pth", "grid ", "NULL", "\\u0007bell", "\\u001b[31mred", "../../etc/passwd",
    "/dev/zero", "/dev/null", "a" * 300, "dir/", "\\u0000",
]
ODD_VALUES = [
    "true", "[]", "{}", "[1]", "[1, 2]", "[1, 2, 3, 4]", '"1"', "[[1, 2, 3]]",
    "{ type = \"isotropic\" }", "1979-05-27", "[\"a\", 1]", "0x10",
]
ODD_PATHS = ["/dev/zero", "/dev/urandom", "/dev/null", ".", "..", "/", "/etc/passwd",
             "missing.grid", "scene.toml", "a/b/c.obj", ""]
GRID_WORDS = ["0", "-1", "nan", "inf", "1e30", "1e-30", "1024", "100000", "3", "x", ""]


def corpus():
    """The seed inputs: every shipped scene (TOML and Mitsuba XML), and the agreement matrix's,
    with their files."""
    seeds = []
    for d in ("scenes", os.path.join("tests", "fixtures", "agreement"), os.path.join("scenes", "xml")):
        for name in sorted(os.listdir(os.path.join(ROOT, d))):
            if name.endswith(".toml") or name.endswith(".xml"):
                seeds.append(os.path.join(d, name))
    return seeds + [os.path.join("benches", "mitsuba-fog-box.xml")]


MESH_SCENE = """
[[shapes]]
type = "mesh"
obj = "cube.obj"
material = "null"
interior = "fog"
"""


def load_seed(rel):
    """A seed scene's text and the companion files it reads (relative to its directory)."""
    path = os.path.join(ROOT, rel)
    with open(path, "rb") as f:
        text = f.read()
    files = {}
    companions = (rb'(?:file|obj|map)\s*=\s*"([^"]+)"|name="filename"\s+value="([^"]+)"'
                  rb'|<spectrum[^>]*\sfilename="([^"]+)"')
    for m in re.finditer(companions, text):
        name = (m.group(1) or m.group(2) or m.group(3)).decode()
        src = os.path.join(os.path.dirname(path), name)
        if os.path.isfile(src):
            with open(src, "rb") as f:
                # a companion in another directory (`../vdb/blosc.vdb`) is copied beside the scene
                local = os.path.basename(name)
                text = text.replace(name.encode(), local.encode())
                files[local] = f.read()
    return text, files


def fog_box_with_mesh():
    """The fog box whose fog boundary is an OBJ cube, so that OBJ mutations reach the parser
    (the box's lines end at the next table or comment)."""
    text, _ = load_seed(os.path.join("scenes", "fog-box.toml"))
    text = re.sub(rb'\[\[shapes\]\]\ntype = "box"\n(?:[^\[#\n][^\n]*\n|\n)*', b"", text) + MESH_SCENE.encode()
    with open(os.path.join(ROOT, "tests", "fixtures", "cube.obj"), "rb") as f:
        return text, {"cube.obj": f.read()}


def grid_with_vol():
    """The agreement matrix's grid scene reading its blob as a Mitsuba `.vol`, so that binary
    grid mutations reach that parser."""
    text, files = load_seed(os.path.join("tests", "fixtures", "agreement", "grid.toml"))
    words = [w for l in files["blob.grid"].split(b"\n") if not l.startswith(b"#") for w in l.split()]
    res, values = [int(w) for w in words[:3]], [float(w) for w in words[3:]]
    head = b"VOL" + bytes([3]) + struct.pack("<5i", 1, *res, 1) + struct.pack("<6f", -1, -1, -1, 1, 1, 1)
    vol = head + struct.pack(f"<{len(values)}f", *values)
    return text.replace(b"blob.grid", b"blob.vol"), {"blob.vol": vol}


def vdb_scene(rng):
    """The agreement matrix's VDB scene reading one of the OpenVDB fixtures (Blosc, zip, no
    codec, half floats), so that VDB mutations reach that reader."""
    text, _ = load_seed(os.path.join("tests", "fixtures", "agreement", "vdb.toml"))
    name = rng.choice(["blosc", "zip", "none", "half"]) + ".vdb"
    with open(os.path.join(ROOT, "tests", "fixtures", "vdb", name), "rb") as f:
        return text.replace(b"blosc.vdb", b"smoke.vdb"), {"smoke.vdb": f.read()}


def rgbe_map(w, h, rle):
    """A small sky as a Radiance RGBE file: a blue gradient and a bright sun, its scanlines
    run-length encoded per channel (`rle`) or flat."""
    out = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n" % (h, w)
    for y in range(h):
        row = []
        for x in range(w):
            sun = abs(x - w // 3) <= 1 and abs(y - h // 4) <= 1
            row.append([255, 240, 200, 140] if sun else [60 + y, 90 + y, 200, 128])
        if not rle:
            out += bytes(b for p in row for b in p)
            continue
        out += bytes([2, 2, w >> 8, w & 0xFF])
        for c in range(4):
            v = [p[c] for p in row]
            x = 0
            while x < w:
                n = 1
                while x + n < w and n < 127 and v[x + n] == v[x]:
                    n += 1
                if n >= 3:
                    out += bytes([128 + n, v[x]])
                else:
                    out += bytes([n] + v[x:x + n])
                x += n
    return out


def sky_with_hdr(rng):
    """The envmap scene reading a Radiance sky, so that RGBE mutations reach that reader."""
    text, _ = load_seed(os.path.join("scenes", "envmap.toml"))
    w, h = rng.choice([(32, 16), (64, 32), (4, 3)])
    return text.replace(b"envmap-sky.exr", b"sky.hdr"), {"sky.hdr": rgbe_map(w, h, w >= 8 and rng.random() < 0.7)}


def mutate_hdr(rng, data):
    """A Radiance map's bytes: a truncation, a flipped byte, a run-length code set to an edge
    value, or a header line (format, resolution, the blank line) replaced."""
    op = rng.choice(["truncate", "byte", "code", "header", "header"])
    end = data.find(b"\n", data.find(b"-Y")) + 1 if b"-Y" in data else 0
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"hdr: truncate at {at}"
    if op in ("byte", "code") or end == 0:
        at = rng.randrange(max(end, 1) if op == "code" and end < len(data) else 0, len(data))
        v = rng.choice([0, 1, 2, 127, 128, 129, 255]) if op == "code" else rng.randrange(256)
        return data[:at] + bytes([v]) + data[at + 1:], f"hdr: byte {at} -> {v}"
    head = data[:end].split(b"\n")
    lines = [
        b"-Y %s +X %s" % (rng.choice([b"0", b"1", b"16", b"99999999", b"-3", b"x"]),
                          rng.choice([b"0", b"7", b"8", b"32", b"32768", b"4294967296"])),
        rng.choice([b"+Y 16 +X 32", b"-Y 16 -X 32", b"+X 32 -Y 16", b"-Y 16", b""]),
        rng.choice([b"FORMAT=32-bit_rle_xyze", b"FORMAT=", b"EXPOSURE=nan", b"#?RGBE", b"P6"]),
    ]
    i = rng.randrange(len(head))
    head[i] = rng.choice(lines)
    return b"\n".join(head) + data[end:], f"hdr: header line {i} -> {head[i]!r}"


def textured_with_png(rng):
    """The textured agreement scene, so that PNG mutations reach the texture reader."""
    return load_seed(os.path.join("tests", "fixtures", "agreement", "textured.toml"))


def textured_with_mesh(rng):
    """The textured agreement scene with its mesh mutated first: the OBJ with texture coordinates
    (`vt`, `f v/vt`), or in its place the PLY with `u`, `v` properties, so that mutations reach
    the meshes' texture coordinates (read only for textured meshes)."""
    text, files = load_seed(os.path.join("tests", "fixtures", "agreement", "textured.toml"))
    if rng.random() < 0.5:
        with open(os.path.join(ROOT, "tests", "fixtures", "textures", "mesh-uv.ply"), "rb") as f:
            files["mesh-uv.ply"] = f.read()
        del files["mesh-vt.obj"]
        text = text.replace(b"mesh-vt.obj", b"mesh-uv.ply")
    name = "mesh-uv.ply" if "mesh-uv.ply" in files else "mesh-vt.obj"
    mutate = mutate_ply if name.endswith(".ply") else mutate_obj_uv
    files[name], what = mutate(rng, files[name])
    return text, files, what


def mutate_obj_uv(rng, data):
    words = ["0", "-1", "1e30", "nan", "inf", "1/1", "1/9", "1//1", "9/1", "1/0", "vt", "vn", "x"]
    return mutate_words(rng, data, words, "obj")


def mutate_ply(rng, data):
    words = ["0", "-1", "4294967295", "nan", "inf", "1e30", "u", "v", "s", "t", "texture_u",
             "double", "uchar", "list", "binary_little_endian", "end_header", "x"]
    return mutate_words(rng, data, words, "ply")


def serialized_scene(rng):
    """scenes/xml/serialized.xml, whose three meshes come from one `serialized` file, with that
    file mutated first."""
    text, files = load_seed(os.path.join("scenes", "xml", "serialized.xml"))
    files["spheres.serialized"], what = mutate_serialized(rng, files["spheres.serialized"])
    return text, files, what


SERIALIZED_COUNTS = [0, 1, 3, 2**31, 2**32, 2**40, 2**63, 2**64 - 1]


def spd_scene(rng):
    """scenes/xml/spectrum-lists.xml, whose lamp is a `.spd` spectrum, with that file mutated
    first."""
    text, files = load_seed(os.path.join("scenes", "xml", "spectrum-lists.xml"))
    files["lamp.spd"], what = mutate_spd(rng, files["lamp.spd"])
    return text, files, what


def mutate_spd(rng, data):
    """A `.spd` spectrum: a word set to an extreme, a comma or a third number, lines swapped
    (wavelengths no longer increasing), or the file grown past the reader's 1 MiB bound."""
    op = rng.choice(["words", "words", "swap", "huge"])
    if op == "huge":
        n = rng.choice([10, 200000])
        body = b"".join(b"%d 0.5\n" % (400 + i) for i in range(n))
        return body, f"spd: {n} lines"
    if op == "swap":
        lines = data.split(b"\n")
        i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        return b"\n".join(lines), f"spd: lines {i} and {j} swapped"
    words = ["0", "-1", "1e308", "-1e308", "nan", "inf", "x", "#", "400,", "1 2", "5e-324", "+3"]
    return mutate_words(rng, data, words, "spd")


def mutate_serialized_stream(rng, body):
    """One shape's inflated stream: its flags, its counts, a face index, a value or its end."""
    name_end = body.find(b"\0", 4) + 1 if body.find(b"\0", 4) >= 0 else 4
    op = rng.choice(["flags", "count", "count", "index", "float", "cut"])
    if op == "flags":
        v = rng.choice([0, 1, 2, 3, 8, 0x10, 0x2000, 0x2003, 0x3000, 0x40, 0xFFFFFFFF])
        return struct.pack("<I", v) + body[4:], f"flags -> 0x{v:x}"
    if op == "count":
        at = name_end + rng.choice([0, 8])
        v = rng.choice(SERIALIZED_COUNTS)
        return body[:at] + struct.pack("<Q", v) + body[at + 8:], f"count at {at} -> {v}"
    if op == "index" and len(body) >= 4:
        at = len(body) - 4 * rng.randrange(1, 7)
        v = rng.choice([0, 3, 2**31, 2**32 - 1])
        return body[:at] + struct.pack("<I", v) + body[at + 4:], f"index at {at} -> {v}"
    if op == "float":
        at = rng.randrange(name_end + 16, max(name_end + 17, len(body) - 4))
        v = rng.choice([float("nan"), float("inf"), -1e30, 0.0])
        return body[:at] + struct.pack("<f", v) + body[at + 4:], f"float at {at} -> {v}"
    at = rng.randrange(len(body) + 1)
    return body[:at], f"inflated stream cut at {at}"


def mutate_serialized(rng, data):
    """A `serialized` file: a truncation, a flipped byte, a dictionary entry or count set to an
    extreme, or one shape's stream inflated, mutated (`mutate_serialized_stream`) and
    compressed again, so that mutations get past zlib's checksum."""
    import zlib
    if not data:
        return data, "serialized: empty"
    op = rng.choice(["truncate", "byte", "dictionary", "stream", "stream", "stream"])
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"serialized: truncate at {at}"
    if op == "byte":
        at = rng.randrange(len(data))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:], f"serialized: byte {at}"
    count = struct.unpack("<I", data[-4:])[0] if len(data) >= 4 else 0
    table_start = len(data) - 4 - 8 * count
    offsets = list(struct.unpack(f"<{count}Q", data[table_start:-4])) if table_start >= 4 else []
    if not (offsets and offsets == sorted(offsets) and offsets[-1] < table_start):
        # an earlier step broke the dictionary: its shapes cannot be found, so flip a byte
        at = rng.randrange(max(len(data), 1))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:], f"serialized: byte {at}"
    if op == "dictionary":
        v = rng.choice(SERIALIZED_COUNTS)
        at = len(data) - 4 if rng.random() < 0.4 else len(data) - 4 - 8 * rng.randrange(1, count + 1)
        fmt = "<I" if at == len(data) - 4 else "<Q"
        if fmt == "<I":
            v &= 0xFFFFFFFF
        out = data[:at] + struct.pack(fmt, v) + data[at + struct.calcsize(fmt):]
        return out, f"serialized: dictionary at {at} -> {v}"
    k = rng.randrange(count)
    end = offsets[k + 1] if k + 1 < count else len(data) - 4 - 8 * count
    try:
        body = zlib.decompress(data[offsets[k] + 4:end])
    except zlib.error:  # an earlier step damaged the stream
        return data[:end - 1], f"serialized: truncate at {end - 1}"
    body, what = mutate_serialized_stream(rng, body)
    shape = data[offsets[k]:offsets[k] + 4] + zlib.compress(body)
    shift = len(shape) - (end - offsets[k])
    rest = data[end:len(data) - 4 - 8 * count]
    table = [o if i <= k else o + shift for i, o in enumerate(offsets)]
    out = data[:offsets[k]] + shape + rest + struct.pack(f"<{count}QI", *table, count)
    return out, f"serialized: shape {k}: {what}"


def png_chunk(kind, body):
    import zlib
    return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))


def mutate_png(rng, data):
    """A texture's PNG bytes: a truncation, a flipped byte, or the header (IHDR: width, height,
    bit depth, colour type) rewritten with a valid checksum, so the sizes reach the reader."""
    op = rng.choice(["truncate", "byte", "header", "header"])
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"png: truncate at {at}"
    if op == "byte" or data[12:16] != b"IHDR":
        at = rng.randrange(len(data))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:], f"png: byte {at}"
    w, h, depth, colour = struct.unpack(">IIBB", data[16:26])
    edge = [0, 1, 2, 3, 2**14, 2**16, 2**31 - 1, 2**32 - 1]
    field = rng.choice(["width", "height", "depth", "colour"])
    if field == "width":
        w = rng.choice(edge)
    elif field == "height":
        h = rng.choice(edge)
    elif field == "depth":
        depth = rng.choice([0, 1, 2, 4, 8, 16, 3, 255])
    else:
        colour = rng.choice([0, 2, 3, 4, 6, 1, 7, 255])
    body = struct.pack(">IIBB", w, h, depth, colour) + data[26:29]
    return data[:8] + png_chunk(b"IHDR", body) + data[33:], f"png: {field} -> {w} x {h}, depth {depth}, colour {colour}"


# ---- mutations of TOML text ------------------------------------------------------------

NUMBER = re.compile(rb"(?<![\w.\"])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![\w.\"])")
STRING = re.compile(rb'"[^"\n]*"')
VALUE = re.compile(rb"^(\s*[\w.\"-]+\s*=\s*)(.+)$", re.M)
FILE_VALUE = re.compile(rb'((?:^\s*(?:file|obj|map)\s*=\s*")|(?:name="filename"\s+value="))[^"\n]*"', re.M)
ARRAY = re.compile(rb"\[([^\[\]\n]+)\]")


def sub_one(rng, pattern, text, make):
    hits = list(pattern.finditer(text))
    if not hits:
        return text, None
    m = rng.choice(hits)
    new = make(m)
    return text[: m.start()] + new + text[m.end():], new


def lines_op(rng, text, kind):
    lines = text.split(b"\n")
    i = rng.randrange(len(lines))
    if kind == "delete":
        del lines[i]
    elif kind == "duplicate":
        lines.insert(i, lines[i])
    else:
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
    return b"\n".join(lines), f"{kind} line {i + 1}"


def resize_array(rng, text):
    def make(m):
        items = m.group(1).split(b",")
        if rng.random() < 0.5 and len(items) > 1:
            items.pop(rng.randrange(len(items)))
        else:
            items.append(items[-1])
        return b"[" + b",".join(items) + b"]"

    text, new = sub_one(rng, ARRAY, text, make)
    return text, f"array -> {new!r}"


def insert_key(rng, text, keys, strings):
    lines = text.split(b"\n")
    headers = [i for i, l in enumerate(lines) if l.startswith(b"[")] or [0]
    at = rng.choice(headers) + 1
    value = rng.choice(
        [rng.choice(EXTREME_NUMBERS), '"' + rng.choice(strings + ODD_STRINGS) + '"',
         rng.choice(ODD_VALUES)]
    )
    line = (rng.choice(keys) + " = " + value).encode()
    lines.insert(at, line)
    return b"\n".join(lines), f"insert {line!r} at line {at + 1}"


def noise(rng, text):
    at = rng.randrange(len(text) + 1)
    junk = bytes(rng.choice([0, 7, 8, 13, 27, 127, 0xC3, 0xFF, 0x80, 0xE2]) for _ in range(rng.randint(1, 4)))
    return text[:at] + junk + text[at:], f"bytes {junk!r} at offset {at}"


def huge_array(rng, text):
    n = rng.choice([10_000, 200_000, 2_000_000])
    key = rng.choice([b"albedo", b"eye", b"emission", b"resolution", b"weights"])
    return text + b"\n[extra]\n" + key + b" = [" + b"0," * n + b"0]\n", f"array of {n + 1} at the end"


def mutate_toml(rng, text, keys, strings):
    op = rng.choices(
        ["scale", "number", "string", "value", "delete", "duplicate", "swap", "array", "insert",
         "noise", "truncate", "table", "huge", "path"],
        weights=[20, 30, 14, 10, 8, 5, 4, 8, 10, 4, 2, 4, 1, 3],
    )[0]
    if op == "scale":
        factor = rng.choice([0.01, 0.1, 0.5, 0.9, 1.1, 2.0, 10.0, 100.0, -1.0])
        text, new = sub_one(rng, NUMBER, text, lambda m: repr(float(m.group(0)) * factor).encode())
        return text, f"number scaled -> {new!r}"
    if op == "path":
        odd = rng.choice(ODD_PATHS)
        text, new = sub_one(rng, FILE_VALUE, text, lambda m: m.group(1) + odd.encode() + b'"')
        return text, f"file -> {new!r}"
    if op == "number":
        text, new = sub_one(rng, NUMBER, text, lambda m: rng.choice(EXTREME_NUMBERS).encode())
        return text, f"number -> {new!r}"
    if op == "string":
        pick = rng.choice(strings + ODD_STRINGS)
        text, new = sub_one(rng, STRING, text, lambda m: ('"' + pick + '"').encode())
        return text, f"string -> {new!r}"
    if op == "value":
        text, new = sub_one(rng, VALUE, text, lambda m: m.group(1) + rng.choice(ODD_VALUES).encode())
        return text, f"value -> {new!r}"
    if op in ("delete", "duplicate", "swap"):
        return lines_op(rng, text, op)
    if op == "array":
        return resize_array(rng, text)
    if op == "insert":
        return insert_key(rng, text, keys, strings)
    if op == "noise":
        return noise(rng, text)
    if op == "truncate":
        at = rng.randrange(len(text) + 1)
        return text[:at], f"truncate at {at}"
    if op == "table":
        headers = re.findall(rb"^\[[^\n]*\]$", text, re.M) or [b"[render]"]
        return text + b"\n" + rng.choice(headers) + b"\n", "table header repeated"
    return huge_array(rng, text)


# ---- mutations of grids and meshes -----------------------------------------------------


def mutate_words(rng, data, words, label):
    tokens = re.split(rb"(\s+)", data)
    slots = [i for i, t in enumerate(tokens) if t and not t.isspace()]
    op = rng.choice(["word", "word", "header", "truncate", "delete", "noise"])
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"{label}: truncate at {at}"
    if op == "noise":
        return noise(rng, data)[0], f"{label}: bytes"
    if not slots:
        return data, f"{label}: empty"
    if op == "header":
        i = slots[0] if not data.startswith(b"#") else rng.choice(slots[:12])
    else:
        i = rng.choice(slots)
    if op == "delete":
        tokens[i] = b""
        return b"".join(tokens), f"{label}: word {i} deleted"
    tokens[i] = rng.choice(words).encode()
    return b"".join(tokens), f"{label}: word {i} -> {tokens[i]!r}"


def mutate_grid(rng, data):
    lines = data.split(b"\n")
    # the header is the first line that is not a comment
    h = next((i for i, l in enumerate(lines) if l and not l.startswith(b"#")), 0)
    if rng.random() < 0.4:
        dims = [rng.choice(["6", "1", "0", "1024", "100000", "-6", "7", "x"]) for _ in range(3)]
        lines[h] = " ".join(dims).encode()
        return b"\n".join(lines), f"grid header -> {lines[h]!r}"
    return mutate_words(rng, data, GRID_WORDS, "grid")


def mutate_vol(rng, data):
    op = rng.choice(["int", "int", "float", "truncate", "byte"])
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"vol: truncate at {at}"
    if op == "byte":
        at = rng.randrange(len(data))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:], f"vol: byte {at}"
    if op == "int":
        at = rng.choice([4, 8, 12, 16, 20])
        v = rng.choice([0, 1, -1, 7, 1024, 2**20, 2**31 - 1, -(2**31)])
        return data[:at] + struct.pack("<i", v) + data[at + 4:], f"vol: int at {at} -> {v}"
    at = rng.choice([24, 28, 36, 44, 48, 52, len(data) - 4])
    v = rng.choice([float("nan"), float("inf"), -1.0, 1e30, 0.0, -0.0])
    return data[:at] + struct.pack("<f", v) + data[at + 4:], f"vol: float at {at} -> {v}"


def mutate_vdb(rng, data):
    """An OpenVDB file: a truncation, a flipped byte, or a 32- or 64-bit integer (string
    lengths, counts, grid offsets, compressed sizes, Blosc header fields) set to an extreme."""
    op = rng.choice(["truncate", "byte", "byte", "int", "int64"])
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"vdb: truncate at {at}"
    if op == "byte":
        at = rng.randrange(len(data))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:], f"vdb: byte {at}"
    if op == "int":
        at = rng.randrange(len(data) - 4)
        v = rng.choice([0, 1, -1, 7, 4096, 2**20, 2**31 - 1, -(2**31)])
        return data[:at] + struct.pack("<i", v) + data[at + 4:], f"vdb: int at {at} -> {v}"
    at = rng.randrange(len(data) - 8)
    v = rng.choice([0, 1, -1, 2**31, 2**40, 2**63 - 1, -(2**63)])
    return data[:at] + struct.pack("<q", v) + data[at + 8:], f"vdb: int64 at {at} -> {v}"


def mutate_exr(rng, data):
    """An environment map's OpenEXR bytes: a truncation, a flipped byte, or a header integer
    (the sizes and offsets live there) set to an extreme."""
    op = rng.choice(["truncate", "byte", "byte", "int"])
    if op == "truncate":
        at = rng.randrange(len(data) + 1)
        return data[:at], f"exr: truncate at {at}"
    if op == "byte":
        at = rng.randrange(len(data))
        return data[:at] + bytes([rng.randrange(256)]) + data[at + 1:], f"exr: byte {at}"
    at = rng.randrange(4, min(len(data), 400) - 4)
    v = rng.choice([0, 1, -1, 2**16, 2**24, 2**31 - 1, -(2**31)])
    return data[:at] + struct.pack("<i", v) + data[at + 4:], f"exr: int at {at} -> {v}"


def mutate_obj(rng, data):
    words = ["0", "-100", "100000", "nan", "inf", "1e30", "1/1/1", "x", "-1", "9"]
    return mutate_words(rng, data, words, "obj")


# ---- adversarial cases: checkpoints, merges, changed inputs, hostile XML, kills, writers -----

ADVERSARIAL = ["checkpoint", "merge", "changed", "xml", "kill", "writers"]
ADVERSARIAL_WEIGHTS = [30, 25, 10, 15, 12, 8]
ADVERSARIAL_SHARE = 0.25
CHECKPOINT_MAGIC = b"pathspace checkpoint v4\n"
HEAD = len(CHECKPOINT_MAGIC) + 8  # the magic line, then the payload's FNV-1a checksum
SPECIALS = [float("nan"), float("inf"), -float("inf"), 3.4e38, 1e300, -1.0, -1e30]
TINY = ["--resolution", "8x8", "--threads", "1"]
RESUME_SPP = 500  # a base checkpoint's target: its interruption comes long before, a resume is short


def adversarial_kind(seed, k):
    """Case k's adversarial kind, or None for a mutated scene (a separate stream, so that the
    scene cases keep their mutations)."""
    rng = random.Random(f"{seed}:{k}:kind")
    if rng.random() >= ADVERSARIAL_SHARE:
        return None
    return rng.choices(ADVERSARIAL, ADVERSARIAL_WEIGHTS)[0]


def fnv1a64(data):
    h = 0xCBF29CE484222325
    for b in data:
        h = ((h ^ b) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def checkpoint_sound(data):
    """A checkpoint file that is whole: its magic line and a checksum that matches its payload."""
    return (data.startswith(CHECKPOINT_MAGIC) and len(data) >= HEAD
            and struct.unpack("<Q", data[len(CHECKPOINT_MAGIC):HEAD])[0] == fnv1a64(data[HEAD:]))


def interrupted(bin_, work, scene, out):
    """Render `scene` at 8x8 with a checkpoint after every pass and stop it by SIGINT once the
    checkpoint exists: the passes it finished (a finished render removes its checkpoint)."""
    p = subprocess.Popen([bin_, "render", scene, "--spp", str(RESUME_SPP), "--checkpoint", "0", "-o", out]
                         + TINY, cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    ckpt = os.path.join(work, out[:-4] + ".checkpoint")
    for _ in range(1000):
        if os.path.exists(ckpt):
            break
        time.sleep(0.01)
    time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    err = p.communicate(timeout=30)[1].decode(errors="replace")
    m = re.search(r"after (\d+) of", err)
    if not m or not os.path.exists(ckpt):
        sys.exit(f"fuzz: could not make a checkpoint of {scene}: {err}")
    return int(m.group(1))


def prepare_bases(args):
    """The inputs the adversarial cases mutate, made once per campaign (a checkpoint's passes
    depend on timing; a case's mutation depends only on the seed and its index)."""
    base = tempfile.mkdtemp(prefix="fuzz-base-", dir=args.scratch)
    bases = {}
    fog, _ = load_seed(os.path.join("scenes", "fog-box.toml"))
    grid, grid_files = load_seed(os.path.join("tests", "fixtures", "agreement", "grid.toml"))
    mesh, mesh_files = fog_box_with_mesh()
    for name, text, files in (("fog", fog, {}), ("mesh", mesh, mesh_files), ("grid", grid, grid_files)):
        d = os.path.join(base, name)
        os.makedirs(d)
        with open(os.path.join(d, "scene.toml"), "wb") as f:
            f.write(text)
        for fname, data in files.items():
            with open(os.path.join(d, fname), "wb") as f:
                f.write(data)
        bases[name] = (d, interrupted(args.bin, d, "scene.toml", "c.exr"), sorted(files))
    d = os.path.join(base, "merge")
    os.makedirs(d)
    with open(os.path.join(d, "scene.toml"), "wb") as f:
        f.write(fog)
    for s in ("1", "2"):
        subprocess.run([args.bin, "render", "scene.toml", "--spp", "2", "--seed", s, "-o", f"m{s}.exr"]
                       + TINY, cwd=d, check=True, capture_output=True)
    bases["merge"] = (d, 2, [])
    return base, bases


def exr_header(data):
    """An EXR's header attributes [(name, type, value)] and where the header ends."""
    attrs, i = [], 8
    while data[i] != 0:
        name = data[i:data.index(b"\0", i)]
        i += len(name) + 1
        kind = data[i:data.index(b"\0", i)]
        i += len(kind) + 1
        size = struct.unpack("<i", data[i:i + 4])[0]
        attrs.append([name, kind, data[i + 4:i + 4 + size]])
        i += 4 + size
    return attrs, i + 1


def exr_rebuilt(data, attrs, end):
    """The EXR `data` (header ending at `end`) with the header attributes `attrs`; the chunk
    offsets shifted by the header's change of length."""
    head = data[:8] + b"".join(n + b"\0" + t + b"\0" + struct.pack("<i", len(v)) + v
                               for n, t, v in attrs) + b"\0"
    chunks = struct.unpack("<i", dict((a[0], a[2]) for a in attrs)[b"chunkCount"])[0]
    delta = len(head) - end
    table = struct.unpack(f"<{chunks}Q", data[end:end + 8 * chunks])
    return head + struct.pack(f"<{chunks}Q", *(o + delta for o in table)) + data[end + 8 * chunks:]


def exr_with(data, name, kind, value):
    """The EXR with one header attribute set (added if missing)."""
    attrs, end = exr_header(data)
    hit = [a for a in attrs if a[0] == name]
    if hit:
        hit[0][1:] = [kind, value]
    else:
        attrs.append([name, kind, value])
    return exr_rebuilt(data, attrs, end)


def exr_without(data, name):
    """The EXR without the header attribute `name` (a forger who recomputes nothing drops the
    checksum)."""
    attrs, end = exr_header(data)
    return exr_rebuilt(data, [a for a in attrs if a[0] != name], end)


def exr_raw_pixels(rng, data):
    """The 8x8 RGB EXR's one chunk replaced by uncompressed floats, some of them extreme."""
    attrs, end = exr_header(data)
    values = [0.1] * 192
    for _ in range(rng.randint(1, 4)):
        values[rng.randrange(192)] = rng.choice(SPECIALS)
    raw = struct.pack("<192f", *[max(min(v, 3.4e38), -3.4e38) if v == v and abs(v) != float("inf")
                                 else v for v in values])
    return data[:end + 8] + struct.pack("<ii", 0, len(raw)) + raw, f"pixels {sorted(set(map(str, values)))}"


def image_finite(args, work, name):
    """A written image reads back (`pathspace diff` against itself) with a finite mean."""
    p = run([args.bin, "diff", "--json", name, name], work, args.info_timeout, args.memory)
    if p is None or p.returncode != 0:
        return False
    try:
        record = json.loads(p.stdout.decode().strip().splitlines()[-1])
        return finite(v for k, v in record.items() if k.startswith("mean") for v in (v if isinstance(v, list) else [v]))
    except (ValueError, IndexError, UnicodeDecodeError):
        return False


def copy_base(src, work):
    for name in os.listdir(src):
        shutil.copy(os.path.join(src, name), work)


def forge(rng, payload):
    """Payload bytes altered in place: special floats (f32 or f64) or random bytes."""
    payload = bytearray(payload)
    steps = []
    for _ in range(rng.randint(1, 3)):
        if rng.random() < 0.7 and len(payload) > 16:
            wide = rng.random() < 0.6
            v = rng.choice(SPECIALS)
            b = struct.pack("<d", v) if wide else struct.pack("<f", max(min(v, 3.4e38), -3.4e38) if abs(v) > 3.4e38 and v == v and abs(v) != float("inf") else v)
            at = rng.randrange(len(payload) - len(b))
            payload[at:at + len(b)] = b
            steps.append(f"{'f64' if wide else 'f32'} {v} at {at}")
        else:
            at = rng.randrange(len(payload))
            payload[at] = rng.randrange(256)
            steps.append(f"byte {payload[at]} at {at}")
    return bytes(payload), steps


def mutate_checkpoint(rng, data):
    op = rng.choice(["forged", "forged", "forged", "flip", "truncate", "extend", "magic"])
    if op == "forged":
        payload, steps = forge(rng, data[HEAD:])
        return CHECKPOINT_MAGIC + struct.pack("<Q", fnv1a64(payload)) + payload, ["forged"] + steps
    if op == "flip":
        at = rng.randrange(len(data))
        return data[:at] + bytes([data[at] ^ (1 << rng.randrange(8))]) + data[at + 1:], [f"flip at {at}"]
    if op == "truncate":
        at = rng.randrange(len(data))
        return data[:at], [f"truncate at {at}"]
    if op == "extend":
        n = rng.choice([1, 100, 1 << 16])
        return data + bytes(rng.randrange(256) for _ in range(n)), [f"extend by {n}"]
    return b"pathspace checkpoint v2\n" + data[len(CHECKPOINT_MAGIC):], ["old magic"]


def checkpoint_case(args, rng, work, bases):
    d, done, _ = bases["fog"]
    copy_base(d, work)
    path = os.path.join(work, "c.checkpoint")
    with open(path, "rb") as f:
        data, steps = mutate_checkpoint(rng, f.read())
    with open(path, "wb") as f:
        f.write(data)
    cmd = [args.bin, "render", "--resume", "c.checkpoint", "--json"]
    if rng.random() < 0.7:
        cmd += ["--spp", str(done + rng.randint(1, 2))]
    p = run(cmd, work, args.render_timeout, args.memory)
    outcome = judge(p, ["c.checkpoint", "c.exr", "scene.toml"])
    return steps, (render_outcome(p) if outcome == "ok" else outcome), [cmd]


def merge_case(args, rng, work, bases):
    copy_base(bases["merge"][0], work)
    victim = rng.choice(["m1.exr", "m2.exr"])
    path = os.path.join(work, victim)
    with open(path, "rb") as f:
        data = f.read()
    op = rng.choice(["spp", "spp", "shard", "streams", "scene_inputs", "seed", "pixels", "pixels", "byte"])
    garbage = rng.choice(["", "x", "1:0..1", "1:5..2", "1:0..18446744073709551615", "\x07\x1b[31m",
                          "1/4294967295", "0/0", "2/1", "a" * 5000, "cube.obj=zz", "\xff"])
    if op == "spp":
        v = rng.choice([0, -1, 2**31 - 1, -(2**31), 2**30, None])
        data = exr_with(data, b"spp", b"string", b"many") if v is None else \
            exr_with(data, b"spp", b"int", struct.pack("<i", v))
        step = f"{victim}: spp -> {v}"
    elif op == "shard":
        v = rng.choice(["1/4294967295", "1/1000000000", "0/0", "2/1", "1/18446744073709551616", garbage])
        data = exr_with(data, b"shard", b"string", v.encode())
        step = f"{victim}: shard -> {v!r}"
    elif op in ("streams", "scene_inputs", "seed"):
        data = exr_with(data, op.encode(), b"string", garbage.encode())
        step = f"{victim}: {op} -> {garbage[:40]!r}"
    elif op == "pixels":
        data, what = exr_raw_pixels(rng, data)
        step = f"{victim}: {what}"
    else:
        at = rng.randrange(len(data))
        data = data[:at] + bytes([rng.randrange(256)]) + data[at + 1:]
        step = f"{victim}: byte at {at}"
    steps = [step]
    # half the time a forger who drops the checksum, so that the checks behind it are reached
    forged = b"checksum" in data and rng.random() < 0.5
    if forged:
        try:
            data = exr_without(data, b"checksum")
            steps.append(f"{victim}: checksum dropped")
        except (IndexError, KeyError, ValueError, struct.error):
            forged = False  # the damage left no header to take the checksum out of
    with open(path, "wb") as f:
        f.write(data)
    cmd = [args.bin, "merge", "m1.exr", "m2.exr", "-o", "merged.exr"] + (["--force"] if rng.random() < 0.3 else [])
    outcome = judge(run(cmd, work, args.render_timeout, args.memory), ["m1.exr", "m2.exr"])
    if outcome == "ok" and not image_finite(args, work, "merged.exr"):
        outcome = "nonfinite"
    if outcome == "ok" and not forged and op == "byte" and not same_as_intact(args, work, bases):
        outcome = "merged-damage"  # a damaged file merged into another image than the intact
    return steps, outcome, [cmd]


def same_as_intact(args, work, bases):
    """The merged image equals the merge of the files before the damage."""
    intact = os.path.join(work, "intact")
    os.makedirs(intact, exist_ok=True)
    copy_base(bases["merge"][0], intact)
    merged = [args.bin, "merge", "m1.exr", "m2.exr", "-o", "merged.exr", "--force"]
    if run(merged, intact, args.render_timeout, args.memory).returncode != 0:
        return False
    p = run([args.bin, "diff", "--json", "merged.exr", os.path.join(intact, "merged.exr")], work,
            args.info_timeout, args.memory)
    try:
        return json.loads(p.stdout.decode().strip().splitlines()[-1])["max_abs"] == 0
    except (ValueError, IndexError, KeyError, UnicodeDecodeError, AttributeError):
        return False


def changed_case(args, rng, work, bases):
    d, done, files = bases[rng.choice(["mesh", "grid"])]
    copy_base(d, work)
    fname = rng.choice(files)
    path = os.path.join(work, fname)
    with open(path, "rb") as f:
        data = f.read()
    op = rng.choice(["append", "digit", "truncate"])
    if op == "append":
        data += b"\n# edited\n"
    elif op == "digit":
        at = rng.choice([m.start() for m in re.finditer(rb"[1-9]", data)])
        data = data[:at] + bytes([data[at] ^ 1]) + data[at + 1:]
    else:
        data = data[:len(data) * 9 // 10]
    with open(path, "wb") as f:
        f.write(data)
    cmd = [args.bin, "render", "--resume", "c.checkpoint", "--spp", str(done + 1)]
    p = run(cmd, work, args.render_timeout, args.memory)
    # a cut or changed file may no longer load at all: then the scene's error is the refusal
    names = [fname] + (["scene.toml"] if op != "append" else [])
    outcome = "resumed-changed" if p is not None and p.returncode == 0 else judge(p, names)
    return [f"{fname}: {op}"], outcome, [cmd]


def hostile_xml(rng, text):
    """A Mitsuba scene given a hostile part before its closing tag: an attribute flood, deep
    nesting, a huge text node, a DTD with entities, very many elements, or very many valid
    spheres (which it must import and render within the time limit)."""
    op = rng.choice(["attributes", "nesting", "text", "entities", "elements", "attribute", "shapes",
                     "shapes", "typed"])
    if op == "attributes":
        n = rng.choice([64, 65, 1000, 100_000])
        part = "<float " + " ".join(f'a{i}="{i}"' for i in range(n)) + ' name="x" value="1"/>'
    elif op == "nesting":
        n = rng.choice([100, 10_000, 200_000])
        part = "<shape>" * n + "</shape>" * n
    elif op == "text":
        n = rng.choice([1 << 10, 1 << 20, 1 << 24])
        part = "<string name=\"x\" value=\"" + "a" * n + "\"/>" if rng.random() < 0.5 else "<ref>" + "b" * n + "</ref>"
    elif op == "entities":
        dtd = ('<!DOCTYPE scene [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">'
               '<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;">]>\n')
        return dtd.encode() + text.replace(b'value="', b'value="&c;', 1), "DTD with nested entities"
    elif op == "typed":
        n = rng.choice([100, 10_000, 300_000])
        part = '<shape type="sphere">' * n + "</shape>" * n
    elif op == "shapes":
        n = rng.choice([10, 1000, 20_000])
        part = "".join(f'<shape type="sphere"><point name="center" x="{i % 7 * 0.1}" y="0.1" z="{i % 5 * 0.1}"/>'
                       f'<float name="radius" value="0.01"/><bsdf type="diffuse"/></shape>' for i in range(n))
    elif op == "elements":
        n = rng.choice([1000, 100_000, 1_000_000])
        part = '<float name="x" value="1"/>' * n
    else:
        part = "<float " + 'name="x" ' * rng.choice([2, 1000]) + 'value="1"/>'
    at = text.rfind(b"</scene>")
    at = at if at >= 0 else len(text)
    return text[:at] + part.encode() + b"\n" + text[at:], f"{op} ({len(part)} bytes)"


def started(p, bin_):
    """Waits until the child runs the binary: a SIGINT that reaches the forked Python child
    before its exec is lost (the exec resets the handler that took it)."""
    for _ in range(2000):
        try:
            if os.readlink(f"/proc/{p.pid}/exe") == os.path.realpath(bin_) or p.poll() is not None:
                return
        except OSError:
            return
        time.sleep(0.001)


def kill_case(args, rng, work, bases):
    """A render killed while it writes an output that exists: the output is then the earlier
    file or a whole new one, never a partial one."""
    copy_base(bases["merge"][0], work)
    shutil.copy(os.path.join(work, "m1.exr"), os.path.join(work, "out.exr"))
    with open(os.path.join(work, "out.exr"), "rb") as f:
        earlier = f.read()
    sig = signal.SIGKILL if rng.random() < 0.8 else signal.SIGINT
    every_pass = rng.random() < 0.6
    spp = "100000000" if every_pass else str(rng.randint(1, 64))
    delay = rng.uniform(0, 0.15 if every_pass else 0.03)
    cmd = [args.bin, "render", "scene.toml", "--spp", spp, "-o", "out.exr"] + TINY
    cmd += ["--checkpoint", "0"] if every_pass else []
    p = subprocess.Popen(cmd, cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         preexec_fn=limit_memory(args.memory))
    started(p, args.bin)
    time.sleep(delay)
    p.send_signal(sig)
    try:
        err = p.communicate(timeout=args.render_timeout)[1]
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        return [f"signal {int(sig)} after {delay:.3f} s"], "timeout", [cmd]
    steps = [f"signal {int(sig)} after {delay:.3f} s, exit {p.returncode}"]
    outcome = "ok"
    if p.returncode not in (0, 130, -signal.SIGKILL, -signal.SIGINT):
        outcome = judge(subprocess.CompletedProcess(cmd, p.returncode, b"", err), [])
    with open(os.path.join(work, "out.exr"), "rb") as f:
        now = f.read()
    if now != earlier and not image_finite(args, work, "out.exr"):
        outcome = "partial"
    ckpt = os.path.join(work, "out.checkpoint")
    if os.path.exists(ckpt):
        with open(ckpt, "rb") as f:
            if not checkpoint_sound(f.read()):
                outcome, steps = "partial", steps + ["out.checkpoint unsound"]
    leftovers = [n for n in os.listdir(work) if n.endswith(".partial")]
    if leftovers:
        steps.append(f"leftovers {leftovers}")
        if p.returncode != -signal.SIGKILL:
            outcome = "partial"
    return steps, outcome, [cmd]


def writers_case(args, rng, work, bases):
    """Two renders with the same output at once: both finish and the output reads back."""
    copy_base(bases["merge"][0], work)
    cmds = [[args.bin, "render", "scene.toml", "--spp", str(rng.randint(1, 8)), "--seed", str(s),
             "-o", "out.exr"] + TINY for s in (1, 2)]
    procs = [subprocess.Popen(c, cwd=work, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                              preexec_fn=limit_memory(args.memory)) for c in cmds]
    outcome = "ok"
    for c, p in zip(cmds, procs):
        try:
            err = p.communicate(timeout=args.render_timeout)[1]
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
            outcome = "timeout"
            continue
        o = judge(subprocess.CompletedProcess(c, p.returncode, b"", err), [])
        if o != "ok" and outcome == "ok":
            outcome = o if o in BAD else "writers"
    if outcome == "ok" and not image_finite(args, work, "out.exr"):
        outcome = "writers"
    if outcome == "ok" and any(n.endswith(".partial") for n in os.listdir(work)):
        outcome = "partial"
    return [cmds[0][4] + " and " + cmds[1][4] + " spp"], outcome, cmds


ADVERSARIAL_CASES = {"checkpoint": checkpoint_case, "merge": merge_case, "changed": changed_case,
                     "kill": kill_case, "writers": writers_case}


# ---- one case --------------------------------------------------------------------------


# the share of scene cases (a range of `make_case`'s first draw) that mutate an OpenVDB scene
VDB_PICK = (0.14, 0.20)


def is_vdb_case(seed, k):
    """Whether scene case k mutates the OpenVDB scene (`--only vdb`)."""
    return VDB_PICK[0] <= random.Random(f"{seed}:{k}").random() < VDB_PICK[1]


def hdr_case(seed, k):
    """Whether scene case k reads a Radiance map (a stream of its own, so that the other scene
    cases keep their seeds and mutations); drawn after the OpenVDB range of the first draw."""
    return random.Random(f"{seed}:{k}:hdr").random() < 0.06


def png_case(seed, k):
    """Whether scene case k reads a PNG texture (a stream of its own, as `hdr_case`)."""
    return random.Random(f"{seed}:{k}:png").random() < 0.06


def uv_case(seed, k):
    """Whether scene case k mutates a textured mesh (a stream of its own, as `hdr_case`)."""
    return random.Random(f"{seed}:{k}:uv").random() < 0.05


def serialized_case(seed, k):
    """Whether scene case k mutates a `serialized` mesh file (a stream of its own, as `hdr_case`)."""
    return random.Random(f"{seed}:{k}:serialized").random() < 0.05


def spd_case(seed, k):
    """Whether scene case k mutates a `.spd` spectrum (a stream of its own, as `hdr_case`)."""
    return random.Random(f"{seed}:{k}:spd").random() < 0.04


def make_case(k, seed, seeds, keys, strings):
    rng = random.Random(f"{seed}:{k}")
    pick = rng.random()
    if pick < 0.08:
        name, (text, files) = "fog-box+mesh", fog_box_with_mesh()
    elif pick < 0.14:
        name, (text, files) = "grid+vol", grid_with_vol()
    elif pick < VDB_PICK[1]:
        name, (text, files) = "vdb", vdb_scene(rng)
    elif hdr_case(seed, k):
        name, (text, files) = "envmap+hdr", sky_with_hdr(rng)
    elif png_case(seed, k):
        name, (text, files) = "textured+png", textured_with_png(rng)
    elif uv_case(seed, k):
        name, (text, files, what) = "textured+mesh", textured_with_mesh(rng)
    elif serialized_case(seed, k):
        name, (text, files, what) = "serialized.xml", serialized_scene(rng)
    elif spd_case(seed, k):
        name, (text, files, what) = "spectrum-lists.xml", spd_scene(rng)
    else:
        name = rng.choice(seeds)
        text, files = load_seed(name)
    steps = [what] if name in ("textured+mesh", "serialized.xml", "spectrum-lists.xml") else []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        if files and rng.random() < 0.3:
            f = rng.choice(sorted(files))
            mut = {".obj": mutate_obj, ".vol": mutate_vol, ".exr": mutate_exr, ".vdb": mutate_vdb,
                   ".hdr": mutate_hdr, ".png": mutate_png, ".ply": mutate_ply}.get(f[-4:], mutate_grid)
            mut = mutate_serialized if f.endswith(".serialized") else mut
            mut = mutate_spd if f.endswith(".spd") else mut
            files[f], what = mut(rng, files[f])
        else:
            text, what = mutate_toml(rng, text, keys, strings)
        steps.append(what)
    flags = []
    if rng.random() < 0.25:
        flags += ["--integrator", rng.choice(["path", "light", "bdpt", "mlt", "smc"])]
    if rng.random() < 0.1:
        flags += ["--max-depth", rng.choice(["1", "3", "1000000"])]
    small = rng.random() < 0.85
    return name, text, files, steps, flags, small


def limit_memory(limit_bytes):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    return apply


def run(cmd, cwd, timeout, mem):
    try:
        p = subprocess.run(
            cmd, cwd=cwd, capture_output=True, timeout=timeout, preexec_fn=limit_memory(mem)
        )
    except subprocess.TimeoutExpired:
        return None
    return p


CONTROL = re.compile(rb"[\x00-\x08\x0b-\x1f\x7f]")


def judge(p, names):
    """The outcome of one process run (None: timed out). A refusal must name one of `names`
    (the scene's files), or be a one-line `error:` where `names` is empty (the render's refusal
    of a flag or an integrator for a scene that `info` accepted)."""
    if p is None:
        return "timeout"
    err = p.stderr
    if b"panicked at" in err or p.returncode == 101:
        return "panic"
    if b"memory allocation of" in err or p.returncode in (-signal.SIGKILL, -signal.SIGABRT):
        return "memory"
    if p.returncode < 0:
        return "crash"
    if p.returncode == 0:
        return "ok"
    # ANSI colour codes of a terminal are not written when stderr is a pipe, so any control
    # byte but tab and newline in an error came from the input
    if CONTROL.search(err):
        return "control"
    if names and not any(n.encode() in err for n in names):
        return "unnamed"
    # notes may come first (a resume says what it continues), but an error line must follow
    if not re.search(rb"^error", err, re.M):
        return "unnamed"
    return "refused"


def finite(values):
    return all(isinstance(c, (int, float)) and abs(c) != float("inf") and c == c for c in values)


def render_outcome(p):
    """A finished render's JSON: its image mean and every sensor's value finite, or `nonfinite`."""
    try:
        record = json.loads(p.stdout.decode().strip().splitlines()[-1])
        values = list(record["mean"] or [])
        for s in record["sensors"]:
            values += s["value"] + s["stderr"]
    except (ValueError, KeyError, IndexError, TypeError, UnicodeDecodeError):
        return "nonfinite"
    return "ok" if finite(values) else "nonfinite"


def keep_case(args, k, outcome, work, name, steps, cmds):
    keep = os.path.join(args.keep, f"{outcome}-{k}")
    shutil.copytree(work, keep, dirs_exist_ok=True)
    with open(os.path.join(keep, "README"), "w") as f:
        f.write(f"seed scene {name}\nmutations {steps}\n")
        f.write("\n".join(" ".join(c) for c in cmds) + "\n")


def adversarial_case(args, k, kind, bases):
    rng = random.Random(f"{args.seed}:{k}:{kind}")
    work = tempfile.mkdtemp(prefix=f"fuzz-{k}-", dir=args.scratch)
    try:
        try:
            steps, outcome, cmds = ADVERSARIAL_CASES[kind](args, rng, work, bases)
        except Exception as e:  # the harness's own fault: counted apart, the campaign goes on
            steps, outcome, cmds = [f"harness: {type(e).__name__}: {e}"], "harness", []
        if outcome in BAD + ("harness",) and args.keep:
            keep_case(args, k, outcome, work, kind, steps, cmds)
        return k, kind, steps, outcome
    finally:
        shutil.rmtree(work, ignore_errors=True)


def case(args, k, seeds, keys, strings, bases):
    kind = adversarial_kind(args.seed, k)
    if kind in ADVERSARIAL_CASES:
        return adversarial_case(args, k, kind, bases)
    name, text, files, steps, flags, small = make_case(k, args.seed, seeds, keys, strings)
    if kind == "xml":
        rng = random.Random(f"{args.seed}:{k}:xml")
        name = rng.choice([s for s in seeds if s.endswith(".xml")])
        text, files = load_seed(name)
        text, what = hostile_xml(rng, text)
        steps, flags = [what], []
    work = tempfile.mkdtemp(prefix=f"fuzz-{k}-", dir=args.scratch)
    try:
        xml = name.endswith(".xml")
        scene_name = "scene.xml" if xml else "scene.toml"
        with open(os.path.join(work, scene_name), "wb") as f:
            f.write(text)
        for fname, data in files.items():
            with open(os.path.join(work, fname), "wb") as f:
                f.write(data)
        names = [scene_name] + list(files)
        info = [args.bin, "info", scene_name]
        outcome = judge(run(info, work, args.info_timeout, args.memory), names)
        cmds = [info]
        if outcome in ("ok", "refused"):
            render = [args.bin, "render", scene_name, "--threads", "1", "--json",
                      "-o", "out.exr", "--spp", "1"] + flags
            if small and (b"[camera]" in text or b"<sensor" in text):
                render += ["--resolution", "8x8"]
            cmds.append(render)
            p = run(render, work, args.render_timeout, args.memory)
            outcome = judge(p, [])
            if outcome == "ok":
                outcome = render_outcome(p)
        if outcome in BAD and args.keep:
            keep_case(args, k, outcome, work, name, steps, cmds)
        return k, name, steps, outcome
    finally:
        shutil.rmtree(work, ignore_errors=True)


def vocabulary(seeds):
    """Every key and string value of the seed scenes: mutations draw on them."""
    keys, strings = set(), set()
    for rel in seeds:
        text, _ = load_seed(rel)
        for m in re.finditer(rb"^\s*([\w-]+)\s*=", text, re.M):
            keys.add(m.group(1).decode())
        for m in STRING.finditer(text):
            strings.add(m.group(0)[1:-1].decode(errors="replace"))
    return sorted(keys), sorted(strings)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", type=int, default=300)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--first", type=int, default=0, help="the first case's index")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release", "pathspace"))
    ap.add_argument("--info-timeout", type=float, default=10.0)
    ap.add_argument("--render-timeout", type=float, default=60.0)
    ap.add_argument("--memory-gib", type=float, default=4.0, help="address-space limit per process")
    ap.add_argument("--only", choices=["scene", "vdb", "hdr", "png", "uv", "serialized", "spd"] + ADVERSARIAL,
                    help="run only the cases of this kind among the indices (replays, tests)")
    ap.add_argument("--keep", help="directory for the cases that are bugs")
    ap.add_argument("--scratch", default=None, help="where cases run (default: the system's temp)")
    args = ap.parse_args()
    args.bin = os.path.abspath(args.bin)
    args.memory = int(args.memory_gib * 2**30)
    if not os.access(args.bin, os.X_OK):
        sys.exit(f"fuzz: no binary at {args.bin} (cargo build --release first)")
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
    seeds = corpus()
    keys, strings = vocabulary(seeds)
    counts = collections.Counter()
    kinds = collections.defaultdict(collections.Counter)
    bugs = []
    base, bases = prepare_bases(args)
    try:
        run_cases(args, seeds, keys, strings, bases, counts, kinds, bugs)
    finally:
        shutil.rmtree(base, ignore_errors=True)
    summary = {o: counts[o] for o in ("ok", "refused") + BAD + ("harness",)}
    print(json.dumps({"cases": args.cases, "seed": args.seed, "first": args.first, **summary,
                      "kinds": {k: dict(c) for k, c in sorted(kinds.items())}}))
    sys.exit(1 if bugs else 0)


def run_cases(args, seeds, keys, strings, bases, counts, kinds, bugs):
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        ks = range(args.first, args.first + args.cases)
        if args.only == "vdb":
            ks = [k for k in ks if adversarial_kind(args.seed, k) is None and is_vdb_case(args.seed, k)]
        elif args.only == "hdr":
            ks = [k for k in ks if adversarial_kind(args.seed, k) is None and hdr_case(args.seed, k)
                  and random.Random(f"{args.seed}:{k}").random() >= VDB_PICK[1]]
        elif args.only == "png":
            ks = [k for k in ks if adversarial_kind(args.seed, k) is None and png_case(args.seed, k)
                  and not hdr_case(args.seed, k)
                  and random.Random(f"{args.seed}:{k}").random() >= VDB_PICK[1]]
        elif args.only == "uv":
            ks = [k for k in ks if adversarial_kind(args.seed, k) is None and uv_case(args.seed, k)
                  and not hdr_case(args.seed, k) and not png_case(args.seed, k)
                  and random.Random(f"{args.seed}:{k}").random() >= VDB_PICK[1]]
        elif args.only == "serialized":
            ks = [k for k in ks if adversarial_kind(args.seed, k) is None
                  and serialized_case(args.seed, k) and not uv_case(args.seed, k)
                  and not hdr_case(args.seed, k) and not png_case(args.seed, k)
                  and random.Random(f"{args.seed}:{k}").random() >= VDB_PICK[1]]
        elif args.only == "spd":
            ks = [k for k in ks if adversarial_kind(args.seed, k) is None
                  and spd_case(args.seed, k) and not serialized_case(args.seed, k)
                  and not uv_case(args.seed, k)
                  and not hdr_case(args.seed, k) and not png_case(args.seed, k)
                  and random.Random(f"{args.seed}:{k}").random() >= VDB_PICK[1]]
        elif args.only:
            ks = [k for k in ks if (adversarial_kind(args.seed, k) or "scene") == args.only]
        jobs = [pool.submit(case, args, k, seeds, keys, strings, bases) for k in ks]
        for done, fut in enumerate(concurrent.futures.as_completed(jobs), 1):
            k, name, steps, outcome = fut.result()
            counts[outcome] += 1
            kinds[adversarial_kind(args.seed, k) or "scene"][outcome] += 1
            if outcome in BAD:
                bugs.append((k, name, steps, outcome))
                print(f"fuzz: case {k} ({name}, {steps}): {outcome}", file=sys.stderr)
            if done % 500 == 0:
                print(f"fuzz: {done}/{args.cases} {dict(counts)}", file=sys.stderr)


if __name__ == "__main__":
    main()
