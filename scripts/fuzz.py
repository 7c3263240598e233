#!/usr/bin/env python3
"""Mutation fuzzing of pathspace's inputs: scene files (TOML and Mitsuba XML), density grids,
OBJ meshes and EXR environment maps.

Each case copies one shipped scene (with the grid, OBJ or EXR file it reads) into a scratch
directory, mutates the scene, its grid or its mesh (extreme numbers, wrong types, deleted or
duplicated lines, resized arrays, control bytes and bad UTF-8, truncation, huge headers and
arrays), and runs `pathspace info` and `pathspace render` on it under a time and a memory
limit. What a case may end as:

  ok        the render finished and its mean is finite
  refused   a nonzero exit with an error that names the file it is about
  --------  anything below is a bug and makes the script exit 1 ----------------------------
  panic     a Rust panic (exit 101 or "panicked at")
  timeout   info or render exceeded its time limit
  memory    the memory limit was hit (an allocation failure or a kill)
  crash     killed by another signal
  nonfinite a finished render whose mean is NaN or infinite
  unnamed   an error that names no file, or a silent nonzero exit
  control   an error that echoes raw control bytes

Cases are reproducible: case k of `--seed S` is the same mutation on every machine.
`--keep DIR` saves every case that is a bug, with the command lines, for replay.

  python3 scripts/fuzz.py --cases 20000 --jobs 2        # the campaign before an issue closes
  python3 scripts/fuzz.py --cases 300                   # the short version .ci/run runs
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

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BAD = ("panic", "timeout", "memory", "crash", "nonfinite", "unnamed", "control")

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
    companions = rb'(?:file|obj|map)\s*=\s*"([^"]+)"|name="filename"\s+value="([^"]+)"'
    for m in re.finditer(companions, text):
        name = (m.group(1) or m.group(2)).decode()
        src = os.path.join(os.path.dirname(path), name)
        if os.path.isfile(src):
            with open(src, "rb") as f:
                files[name] = f.read()
    return text, files


def fog_box_with_mesh():
    """The fog box whose fog boundary is an OBJ cube, so that OBJ mutations reach the parser."""
    text, _ = load_seed(os.path.join("scenes", "fog-box.toml"))
    text = re.sub(rb'\[\[shapes\]\]\ntype = "box"[^\[]*', b"", text) + MESH_SCENE.encode()
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


# ---- one case --------------------------------------------------------------------------


def make_case(k, seed, seeds, keys, strings):
    rng = random.Random(f"{seed}:{k}")
    pick = rng.random()
    if pick < 0.08:
        name, (text, files) = "fog-box+mesh", fog_box_with_mesh()
    elif pick < 0.14:
        name, (text, files) = "grid+vol", grid_with_vol()
    else:
        name = rng.choice(seeds)
        text, files = load_seed(name)
    steps = []
    for _ in range(rng.choice([1, 1, 1, 2, 3])):
        if files and rng.random() < 0.3:
            f = rng.choice(sorted(files))
            mut = {".obj": mutate_obj, ".vol": mutate_vol, ".exr": mutate_exr}.get(f[-4:], mutate_grid)
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
    if not err.startswith(b"error"):
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


def case(args, k, seeds, keys, strings):
    name, text, files, steps, flags, small = make_case(k, args.seed, seeds, keys, strings)
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
            keep = os.path.join(args.keep, f"{outcome}-{k}")
            shutil.copytree(work, keep, dirs_exist_ok=True)
            with open(os.path.join(keep, "README"), "w") as f:
                f.write(f"seed scene {name}\nmutations {steps}\n")
                f.write("\n".join(" ".join(c) for c in cmds) + "\n")
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
    bugs = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        jobs = [pool.submit(case, args, k, seeds, keys, strings)
                for k in range(args.first, args.first + args.cases)]
        for done, fut in enumerate(concurrent.futures.as_completed(jobs), 1):
            k, name, steps, outcome = fut.result()
            counts[outcome] += 1
            if outcome in BAD:
                bugs.append((k, name, steps, outcome))
                print(f"fuzz: case {k} ({name}, {steps}): {outcome}", file=sys.stderr)
            if done % 500 == 0:
                print(f"fuzz: {done}/{args.cases} {dict(counts)}", file=sys.stderr)
    summary = {o: counts[o] for o in ("ok", "refused") + BAD}
    print(json.dumps({"cases": args.cases, "seed": args.seed, "first": args.first, **summary}))
    sys.exit(1 if bugs else 0)


if __name__ == "__main__":
    main()
