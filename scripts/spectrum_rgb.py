#!/usr/bin/env python3
"""Records the RGB colours Mitsuba 3's RGB variants give `<spectrum>` properties, for
`tests/spec/spectrum/cie.rs` (which checks `spectrum::cie` and the importer's `<spectrum>`
reader against them, bit for bit in f32).

    DRJIT_LIBLLVM_PATH=... /work/venv-mi/bin/python scripts/spectrum_rgb.py [--check]

Each case is a plugin loaded from XML (`mi.load_string`, the XML parser's path:
`Properties::Spectrum` reads the list or the `.spd` file, `Properties::get_texture_impl` turns
it into an `srgb` texture with `spectrum_list_to_srgb(.., bounded, d65)`), whose parameter is
read back with `mi.traverse`: `diffuse`'s `reflectance` (bounded, under D65), `conductor`'s
`eta` and `k` (unbounded, under D65), `area`'s `radiance` (an emitter: unbounded, no D65; a
uniform value times `xyz_to_srgb(1, 1, 1)`), `homogeneous`'s `sigma_t` and `albedo` (read as
bounded textures through `get_volume`: clamped to [0, 1]). Lists inside [360, 830] nm, beyond
both ends, starting and ending inside, with values above 1, and the `.spd` files of
`tests/fixtures/spectra/`. Every case is loaded in `scalar_rgb` and in `llvm_ad_rgb` and must
give the same f32 colour in both.

Writes tests/fixtures/spectra/mitsuba.txt: one case a line, `response|value or file|r g b`
(the f32 values in their shortest decimal, exact when parsed back as f32); with `--check`,
fails if the file differs.
"""
import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FIXTURES = os.path.join(ROOT, "tests", "fixtures", "spectra")
OUT = os.path.join(FIXTURES, "mitsuba.txt")

LISTS = [
    "400:0.1, 500:0.5, 600:0.7, 700:0.8",  # inside [360, 830]
    "300:0.2, 450:0.9, 550:0.1, 900:0.6",  # beyond both ends
    "450:0.3 650:0.6",  # starts and ends inside, space separated
    "380:1.5, 480:0.2, 580:2.5, 780:0.7",  # above 1 (a bounded response clamps)
    "360:0, 830:1",  # the tables' ends
    "555:0, 556:4, 557:0",  # a spike between the 1000 sampled wavelengths' grid and the tables'
]
FILES = ["ramp.spd", "crlf.spd"]
UNIFORM = ["0.1", "5", "0.123456789", "0.7", "3.3", "1e-3", "17.25"]

# (response, plugin XML with {prop}, parameter read back)
PLUGINS = [
    ("bounded", '<bsdf version="3.0.0" type="diffuse">{prop}</bsdf>', "reflectance", "reflectance.value"),
    ("unbounded", '<bsdf version="3.0.0" type="conductor">{prop}</bsdf>', "eta", "eta.value"),
    ("unbounded", '<bsdf version="3.0.0" type="conductor">{prop}</bsdf>', "k", "k.value"),
    ("emissive", '<emitter version="3.0.0" type="area">{prop}</emitter>', "radiance", "radiance.value"),
    ("bounded", '<medium version="3.0.0" type="homogeneous">{prop}</medium>', "sigma_t", "sigma_t.value.value"),
    ("bounded", '<medium version="3.0.0" type="homogeneous">{prop}</medium>', "albedo", "albedo.value.value"),
]


def cases():
    out = []
    for response, xml, name, param in PLUGINS:
        for v in LISTS:
            out.append((response, xml, name, param, "value", v))
        for f in FILES:
            out.append((response, xml, name, param, "filename", f))
        if response == "emissive":
            for v in UNIFORM:
                out.append((response, xml, name, param, "value", v))
    return out


def record(variant):
    import mitsuba as mi
    mi.set_variant(variant)
    mi.set_log_level(mi.LogLevel.Error)  # the clamping warnings are expected
    mi.file_resolver().prepend(FIXTURES)
    rows = []
    for response, xml, name, param, attr, v in cases():
        obj = mi.load_string(xml.format(prop=f'<spectrum name="{name}" {attr}="{v}"/>'))
        c = np.array(mi.traverse(obj)[param], dtype=np.float32).reshape(-1)
        c = np.broadcast_to(c, (3,)) if c.size == 1 else c
        rows.append((response, v, tuple(c)))
    return mi.__version__, rows


def text():
    version, rows = record("scalar_rgb")
    _, llvm = record("llvm_ad_rgb")
    for a, b in zip(rows, llvm):
        if a != b:
            sys.exit(f"scalar_rgb and llvm_ad_rgb differ: {a} {b}")
    lines = [
        f"# Mitsuba {version} (scalar_rgb and llvm_ad_rgb): the RGB colours of <spectrum> properties,",
        "# written by scripts/spectrum_rgb.py: response|value or .spd file|r g b (f32)",
    ]
    seen = set()
    for response, v, c in rows:
        line = f"{response}|{v}|" + " ".join(str(np.float32(x)) for x in c)
        if line not in seen:  # the same response and spectrum through two plugins: one line
            seen.add(line)
            lines.append(line)
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="fail if the file differs")
    a = ap.parse_args()
    t = text()
    if a.check:
        with open(OUT) as f:
            if f.read() != t:
                sys.exit(f"{OUT} differs from what Mitsuba gives; rerun without --check")
        print("mitsuba.txt matches Mitsuba")
    else:
        with open(OUT, "w") as f:
            f.write(t)
        print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
