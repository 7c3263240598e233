#!/usr/bin/env python3
"""Recomputes src/bsdf/named_conductor.rs: Mitsuba 3's named conductors as the RGB eta and k its
RGB variants use.

    DRJIT_LIBLLVM_PATH=... venv/bin/python scripts/conductor_rgb.py [--check]

Mitsuba 3 (`ior_from_file` in include/mitsuba/render/ior.h) reads `data/ior/NAME.eta.spd` and
`NAME.k.spd` and, in its RGB variants, turns each spectrum into sRGB with
`spectrum_list_to_srgb(wavelengths, values, bounded=false, d65=false)` (src/core/spectrum.cpp):
1000 wavelengths evenly spaced over [360, 830] nm (both ends included), those outside the
file's range skipped, the spectrum linearly interpolated, weighted by the CIE 1931 colour
matching functions (linearly interpolated in f64 from Mitsuba's f32 table at 5 nm), summed times 470 / 1000,
normalized by 1 / 106.7502593994140625 (Mitsuba's MI_CIE_Y_NORMALIZATION), taken to linear
sRGB by the XYZ-to-sRGB matrix below (its entries f32, as Mitsuba's `ScalarMatrix3f`), negative values clamped to 0. The spectra (Luxpop, Palik
et al.) ship with the mitsuba Python package; the colour matching functions are read through
`mi.cie1931_xyz`; each result is checked against Mitsuba's own `mi.spectrum_list_to_srgb` and,
as f32, bit for bit against the eta and k a `conductor` with that `material` holds.
Without `--check` the Rust file is rewritten; with it, the script fails if the file differs.
"""
import argparse
import os
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "src", "bsdf", "named_conductor.rs")
XYZ_TO_SRGB = np.array([[3.240479, -1.537150, -0.498535],
                        [-0.969256, 1.875991, 0.041556],
                        [0.055648, -0.204043, 1.057311]], dtype=np.float32).astype(np.float64)
CIE_MIN, CIE_MAX, STEPS = 360.0, 830.0, 1000
Y_NORMALIZATION = 1.0 / 106.7502593994140625


def read_spd(path):
    """(wavelengths, values) of a `.spd` file: two numbers a line, `#` starts a comment."""
    w, v = [], []
    with open(path) as f:
        for line in f:
            fields = line.split("#")[0].split()
            if len(fields) == 2:
                w.append(float(fields[0]))
                v.append(float(fields[1]))
    return w, v


def to_srgb(w, v, cmf):
    """The spectrum's unbounded sRGB colour (see the module note)."""
    xyz = np.zeros(3)
    for i in range(STEPS):
        x = CIE_MIN + (i / (STEPS - 1)) * (CIE_MAX - CIE_MIN)
        if x < w[0] or x > w[-1]:
            continue
        j = int(np.searchsorted(w, x, side="right")) - 1
        j = min(max(j, 0), len(w) - 2)
        w0, w1, v0, v1 = w[j], w[j + 1], v[j], v[j + 1]
        y = ((x - w1) * v0 + (w0 - x) * v1) / (w0 - w1)
        xyz += np.array(cmf(x)) * y
    xyz *= (CIE_MAX - CIE_MIN) / STEPS * Y_NORMALIZATION
    return np.maximum(XYZ_TO_SRGB @ xyz, 0.0)


def table():
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    data = os.path.join(os.path.dirname(mi.__file__), "data", "ior")
    # Mitsuba's 5 nm table (f32), read at its own wavelengths, interpolated here in f64 as
    # `cie1931_xyz<double>` does
    grid = [np.array(mi.cie1931_xyz(CIE_MIN + 5.0 * i), dtype=np.float64) for i in range(95)]

    def cmf(x):
        t = (x - CIE_MIN) * (94 / (CIE_MAX - CIE_MIN))
        i0 = min(max(int(t), 0), 93)
        w1 = t - i0
        return (1.0 - w1) * grid[i0] + w1 * grid[i0 + 1]

    names = sorted({f.rsplit(".", 2)[0] for f in os.listdir(data) if f.endswith(".eta.spd")})
    rows = []
    for name in names:
        rgb = []
        for part in ("eta", "k"):
            w, v = read_spd(os.path.join(data, f"{name}.{part}.spd"))
            mine = to_srgb(w, v, cmf)
            theirs = np.array(mi.spectrum_list_to_srgb(w, v, False, False), dtype=float)
            if not np.allclose(mine, theirs, rtol=1e-5, atol=1e-6):
                sys.exit(f"{name}.{part}: {mine} here, {theirs} from Mitsuba")
            rgb.append(mine)
        # and the f32 values a loaded `conductor` holds, bit for bit
        params = mi.traverse(mi.load_dict({"type": "conductor", "material": name}))
        for part, mine in zip(("eta", "k"), rgb):
            held = np.array(params[f"{part}.value"], dtype=np.float32)
            if not np.array_equal(held, mine.astype(np.float32)):
                sys.exit(f"{name}.{part}: {mine} here, {held} in Mitsuba's conductor")
        rows.append((name, rgb[0], rgb[1]))
    return mi.__version__, rows


def rust(version, rows):
    # the shortest decimal of each f32 (Mitsuba's texture stores f32): exact when parsed back
    f = lambda c: ", ".join(str(np.float32(x)) for x in c)  # noqa: E731
    out = [
        "//! Mitsuba 3's named conductors (`material = \"Au\"`) as the RGB complex index its RGB",
        "//! variants use: the spectra of its `data/ior/NAME.eta.spd` and `NAME.k.spd` (Luxpop,",
        "//! Palik et al.) through `spectrum_list_to_srgb(.., bounded = false, d65 = false)`, as",
        "//! `ior_from_file` (include/mitsuba/render/ior.h) does. Generated by",
        f"//! `scripts/conductor_rgb.py` from the data of mitsuba {version}; do not edit by hand.",
        "",
        "use crate::spectrum::Rgb;",
        "",
        "/// (name, eta, k) for every spectrum pair Mitsuba 3 ships, by name.",
        "#[rustfmt::skip]",
        f"pub const NAMED_CONDUCTORS: [(&str, [f32; 3], [f32; 3]); {len(rows)}] = [",
    ]
    for name, eta, k in rows:
        out.append(f"    (\"{name}\", [{f(eta)}], [{f(k)}]),")
    out += [
        "];",
        "",
        "/// The RGB (eta, k) of a named conductor, `None` for a name Mitsuba 3 has no spectra for.",
        "pub fn named_conductor(name: &str) -> Option<(Rgb, Rgb)> {",
        "    NAMED_CONDUCTORS",
        "        .iter()",
        "        .find(|(n, _, _)| *n == name)",
        "        .map(|(_, eta, k)| (Rgb::from_array(*eta), Rgb::from_array(*k)))",
        "}",
        "",
    ]
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="fail if the file differs")
    a = ap.parse_args()
    text = rust(*table())
    if a.check:
        with open(OUT) as f:
            if f.read() != text:
                sys.exit(f"{OUT} differs from what the data give; rerun without --check")
        print("named_conductor.rs matches the data")
    else:
        with open(OUT, "w") as f:
            f.write(text)
        print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
