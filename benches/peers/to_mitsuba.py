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
"""

import argparse
import os
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


def convert(sc, res=None, integrator="volpath", spp=64, seed=0):
    w, h = sc.resolution(res)
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
        out.append(f'    <medium type="homogeneous" id="{name}">\n        <rgb name="albedo" value="{v3(al)}"/>\n'
                   f'        <rgb name="sigma_t" value="{v3(st)}"/>\n        {phase}\n    </medium>')
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
    for name, m in sc.materials.items():
        if m["type"] == "lambert":
            out.append(f'    <bsdf type="twosided" id="{name}"><bsdf type="diffuse">'
                       f'<rgb name="reflectance" value="{v3(m["albedo"])}"/></bsdf></bsdf>')
        else:
            out.append(f'    <bsdf type="dielectric" id="{name}"><float name="int_ior" value="{m["ior"]!r}"/>'
                       '<float name="ext_ior" value="1.0"/></bsdf>')
    out += [shape(s).rstrip("\n") for s in sc.shapes]
    out.append("</scene>")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--res", type=resolution, help="N or WxH (default: the scene's)")
    ap.add_argument("--integrator", default="volpath")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    try:
        sys.stdout.write(convert(Scene(a.scene), a.res,
                                 a.integrator, a.spp, a.seed))
    except Refused as e:
        print(f"{a.scene}: refused: {e}", file=sys.stderr)
        sys.exit(2)


if __name__ == "__main__":
    main()
