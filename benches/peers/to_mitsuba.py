#!/usr/bin/env python3
"""pathspace TOML -> Mitsuba 3 XML, for the peers' harness (`run.py`).

    python3 benches/peers/to_mitsuba.py scenes/fog-box.toml [--res 64] [--integrator volpath] > fog-box.xml

Exact counterparts only (Mitsuba 3 documentation, plugins `rectangle`, `cube`, `sphere`,
`diffuse`, `twosided`, `dielectric`, `null`, `homogeneous`, `isotropic`, `hg`, `area`,
`perspective`, `hdrfilm`, `box`); anything else is refused with the reason (`scene.Refused`),
exit status 2. pathspace's Lambert is two-sided, Mitsuba's `diffuse` one-sided: it is wrapped in
`twosided`. An emitter is a black one-sided `diffuse` with an `area` emitter on the side of
u x v. `fov_deg` is pathspace's vertical field of view (`fov_axis` y). Medium boxes are grown by
`scene.GROW` (Mitsuba 3 leaks light through a null face coplanar with a wall), and the sensor
is given the medium its eye is in. pathspace's depth is unlimited with Russian roulette, so
`max_depth` is -1.

A grid medium (a procedural field baked with `resolution`, tracked) becomes `heterogeneous`
(Mitsuba 3 documentation, plugins `heterogeneous`, `gridvolume`): `scale` sigma_t, a constant
`albedo`, and pathspace's baked lattice (`pathspace info --write-grids`) as a `.vol` under
`--grids`. pathspace's vertices span the box [min, max]; Mitsuba 3 puts a `.vol`'s values at the
cell centres of the unit cube `to_world` maps and holds the outer values beyond the outer
centres. So the lattice is padded with one layer of zeros and `to_world` spans [min - 1.5 h,
max + 1.5 h] (h the lattice spacing): the centres then sit on pathspace's vertices, the
trilinear interpolant inside the box is the same, and it falls to zero over one cell outside,
where a path goes only behind a wall covering the face or inside a shape that inherits the
medium across the box's face. A rough conductor is `roughconductor` (GGX, alpha as pathspace's,
`eta`, `k`, `specular_reflectance`) in `twosided`; a hard-cone spot light is `spot` with
`beam_width` = `cutoff_angle` = `cone_deg`.
"""

import argparse
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from scene import Refused, Scene, quad_frame, resolution  # noqa: E402


def v3(a):
    return ", ".join(repr(float(x)) for x in a)


def matrix(x, y, z, t):
    """A 4x4 `<matrix>` whose columns are x, y, z and the translation t."""
    rows = [[x[i], y[i], z[i], t[i]] for i in range(3)] + [[0, 0, 0, 1]]
    return " ".join(repr(float(v)) for r in rows for v in r)


def media_refs(s):
    out = ""
    for side in ("interior", "exterior"):
        m = s.get(side)
        if m not in (None, "vacuum"):
            out += f'        <ref name="{side}" id="{m}"/>\n'
    return out


def shape(s):
    if s["type"] == "quad":
        c, hu, hv, n = quad_frame(s)
        geo = (f'    <shape type="rectangle">\n        <transform name="to_world"><matrix value="'
               f'{matrix(hu, hv, n, c)}"/></transform>\n')
    elif s["type"] == "box":
        lo, hi = s["min"], s["max"]
        c = [(lo[i] + hi[i]) / 2 for i in range(3)]
        h = [(hi[i] - lo[i]) / 2 for i in range(3)]
        geo = (f'    <shape type="cube">\n        <transform name="to_world">'
               f'<matrix value="{matrix([h[0], 0, 0], [0, h[1], 0], [0, 0, h[2]], c)}"/></transform>\n')
    else:
        geo = (f'    <shape type="sphere">\n        <point name="center" value="{v3(s["center"])}"/>\n'
               f'        <float name="radius" value="{float(s["radius"])!r}"/>\n')
    if "emission" in s:
        body = ('        <bsdf type="diffuse"><rgb name="reflectance" value="0, 0, 0"/></bsdf>\n'
                f'        <emitter type="area"><rgb name="radiance" value="{v3(s["emission"])}"/></emitter>\n')
    elif s["material"] == "null":
        body = '        <bsdf type="null"/>\n'
    else:
        body = f'        <ref id="{s["material"]}"/>\n'
    return geo + body + media_refs(s) + "    </shape>\n"


def padded_vol(src, dst):
    """Copies pathspace's `.vol` `src` to `dst` with one layer of zeros around the lattice."""
    from array import array
    b = open(src, "rb").read()
    nx, ny, nz = struct.unpack("<3i", b[8:20])
    g = array("f", b[48:])
    if sys.byteorder != "little":
        g.byteswap()
    out = array("f", bytes(4 * (nx + 2) * (ny + 2) * (nz + 2)))
    for z in range(nz):
        for y in range(ny):
            at = 1 + (nx + 2) * (y + 1 + (ny + 2) * (z + 1))
            out[at:at + nx] = g[nx * (y + ny * z):nx * (y + ny * z) + nx]
    if sys.byteorder != "little":
        out.byteswap()
    with open(dst, "wb") as f:
        f.write(b"VOL" + bytes([3]) + struct.pack("<5i", 1, nx + 2, ny + 2, nz + 2, 1))
        f.write(b[24:48])
        f.write(out.tobytes())


def heterogeneous(name, m, vol):
    """A grid medium: the padded lattice and a `to_world` putting its centres on pathspace's
    vertices."""
    st = m["sigma_a"][0] + m["sigma_s"][0]
    al = [m["sigma_s"][i] / st if st > 0 else 0.0 for i in range(3)]
    lo, hi = m["min"], m["max"]
    step = [(hi[i] - lo[i]) / (m["res"][i] - 1) for i in range(3)]
    size = [(m["res"][i] + 2) * step[i] for i in range(3)]
    corner = [lo[i] - 1.5 * step[i] for i in range(3)]
    to_world = matrix([size[0], 0, 0], [0, size[1], 0], [0, 0, size[2]], corner)
    return (f'    <medium type="heterogeneous" id="{name}">\n        <rgb name="albedo" value="{v3(al)}"/>\n'
            f'        <float name="scale" value="{st!r}"/>\n'
            f'        <volume name="sigma_t" type="gridvolume"><string name="filename" value="{vol}"/>'
            f'<transform name="to_world"><matrix value="{to_world}"/></transform></volume>\n')


def material(name, m):
    if m["type"] == "lambert":
        return (f'    <bsdf type="twosided" id="{name}"><bsdf type="diffuse">'
                f'<rgb name="reflectance" value="{v3(m["albedo"])}"/></bsdf></bsdf>')
    if m["type"] == "dielectric":
        return (f'    <bsdf type="dielectric" id="{name}"><float name="int_ior" value="{m["ior"]!r}"/>'
                '<float name="ext_ior" value="1.0"/></bsdf>')
    index = "" if m["eta"] is None else (f'<rgb name="eta" value="{v3(m["eta"])}"/>'
                                         f'<rgb name="k" value="{v3(m["k"])}"/>')
    return (f'    <bsdf type="twosided" id="{name}"><bsdf type="roughconductor">'
            f'<string name="distribution" value="ggx"/><float name="alpha" value="{m["alpha"]!r}"/>'
            f'{index}<rgb name="specular_reflectance" value="{v3(m["specular"])}"/></bsdf></bsdf>')


def spot(s):
    p, d = s["position"], s["direction"]
    up = [1.0, 0.0, 0.0] if abs(d[1]) > 0.9 * max(abs(x) for x in d) else [0.0, 1.0, 0.0]
    target = [p[i] + d[i] for i in range(3)]
    return (f'    <emitter type="spot"><transform name="to_world"><lookat origin="{v3(p)}" '
            f'target="{v3(target)}" up="{v3(up)}"/></transform>\n'
            f'        <rgb name="intensity" value="{v3(s["intensity"])}"/>'
            f'<float name="cutoff_angle" value="{s["cone_deg"]!r}"/>'
            f'<float name="beam_width" value="{s["cone_deg"]!r}"/></emitter>')


def convert(sc, res=None, integrator="volpath", spp=64, seed=0, grids=None, binary=None):
    """The XML; a grid medium's lattice is written under `grids` (a folder, made if missing)."""
    w, h = sc.resolution(res)
    vols = {}
    if any(m["kind"] == "grid" for m in sc.media.values()):
        grids = os.path.abspath(grids or os.path.splitext(os.path.basename(sc.path))[0] + "-grids")
        os.makedirs(grids, exist_ok=True)
        for name, src in sc.grids(grids, binary).items():
            vols[name] = os.path.join(grids, name + "-mitsuba.vol")
            padded_vol(src, vols[name])
    eye, look, up = sc.eye()
    cam_medium = sc.medium_at(eye)
    out = ['<scene version="3.0.0">',
           f'    <!-- converted from {os.path.basename(sc.path)} by benches/peers/to_mitsuba.py -->',
           f'    <integrator type="{integrator}"><integer name="max_depth" value="-1"/></integrator>']
    for name, m in sc.media.items():
        st = [m["sigma_a"][i] + m["sigma_s"][i] for i in range(3)]
        al = [m["sigma_s"][i] / st[i] if st[i] > 0 else 0.0 for i in range(3)]
        phase = ('<phase type="isotropic"/>' if m["g"] is None
                 else f'<phase type="hg"><float name="g" value="{m["g"]!r}"/></phase>')
        head = heterogeneous(name, m, vols[name]) if m["kind"] == "grid" else (
            f'    <medium type="homogeneous" id="{name}">\n        <rgb name="albedo" value="{v3(al)}"/>\n'
            f'        <rgb name="sigma_t" value="{v3(st)}"/>\n')
        out.append(f'{head}        {phase}\n    </medium>')
    out.append('    <sensor type="perspective">\n'
               f'        <float name="fov" value="{float(sc.camera["fov_deg"])!r}"/>\n'
               '        <string name="fov_axis" value="y"/>\n'
               f'        <transform name="to_world"><lookat origin="{v3(eye)}" target="{v3(look)}" up="{v3(up)}"/></transform>\n'
               f'        <sampler type="independent"><integer name="sample_count" value="{spp}"/>'
               f'<integer name="seed" value="{seed}"/></sampler>\n'
               f'        <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/>'
               '<string name="pixel_format" value="rgb"/><rfilter type="box"/></film>\n'
               + (f'        <ref name="medium" id="{cam_medium}"/>\n' if cam_medium else "")
               + '    </sensor>')
    out += [material(name, m) for name, m in sc.materials.items()]
    out += [shape(s).rstrip("\n") for s in sc.shapes]
    out += [spot(s) for s in sc.spots]
    out.append("</scene>")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--res", type=resolution, help="N or WxH (default: the scene's)")
    ap.add_argument("--integrator", default="volpath")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grids", help="folder for grid media's .vol files (default: SCENE-grids)")
    ap.add_argument("--bin", help="pathspace's binary (default: target/release/pathspace)")
    a = ap.parse_args()
    try:
        sys.stdout.write(convert(Scene(a.scene), a.res,
                                 a.integrator, a.spp, a.seed, a.grids, a.bin))
    except Refused as e:
        print(f"{a.scene}: refused: {e}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
