"""A pathspace TOML scene read for the peers' converters (`to_mitsuba.py`, `to_tungsten.py`):
the subset both peers can render exactly (quads, boxes and spheres; Lambert and smooth
dielectric surfaces; homogeneous media with isotropic or Henyey-Greenstein phase; emitting
quads; a pinhole camera), everything else refused by name with `Refused`.

Two facts of the peers shape the conversion (book: *Measuring a renderer*, "Against other
renderers"): both Mitsuba 3 and tungsten lose light where a null medium boundary is coplanar
with an opaque wall, so every medium box is grown by `GROW` on all sides; and neither finds by
itself the medium a camera or an emitter sits in, so `medium_at` names it for them.
"""

import math
import tomllib

GROW = 1e-3


class Refused(Exception):
    """The scene uses something a peer has no exact counterpart for; the message says what."""


def rgb(v):
    return [float(x) for x in v] if isinstance(v, list) else [float(v)] * 3


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def add(a, b):
    return [a[i] + b[i] for i in range(3)]


def scale(a, s):
    return [x * s for x in a]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def dot(a, b):
    return sum(a[i] * b[i] for i in range(3))


def normalize(a):
    n = math.sqrt(dot(a, a))
    return [x / n for x in a]


class Scene:
    """The parts of a TOML scene the converters need, checked against the common subset."""

    def __init__(self, path):
        with open(path, "rb") as f:
            self.toml = tomllib.load(f)
        t = self.toml
        self.path = path
        if any(x.get("type") == "spot" for x in t.get("lights", [])):
            raise Refused("a spot light (Mitsuba 3's `spot` falls off linearly in the angle, "
                          "pathspace's as a smoothstep in the cosine; tungsten has none)")
        for key in ("lights", "environment", "meters", "textures"):
            if t.get(key):
                kinds = sorted({x.get("type", key) for x in t[key]}) if isinstance(t[key], list) else [key]
                raise Refused(f"[{key}] ({', '.join(kinds)}): only emitting quads are converted")
        cam = t["camera"]
        if cam.get("type", "pinhole") != "pinhole" or "filter" in cam:
            raise Refused("only a pinhole camera with the box filter is converted")
        self.camera = cam
        self.media = {}
        for name, m in t.get("media", {}).items():
            if m["type"] != "homogeneous":
                raise Refused(f"medium `{name}` is {m['type']} (only homogeneous media are converted)")
            if m.get("emission") is not None:
                raise Refused(f"medium `{name}` emits")
            ph = m.get("phase", {"type": "isotropic"})
            if ph["type"] not in ("isotropic", "hg"):
                raise Refused(f"medium `{name}` has the phase function {ph['type']}")
            self.media[name] = dict(sigma_a=rgb(m["sigma_a"]), sigma_s=rgb(m["sigma_s"]),
                                    g=float(ph.get("g", 0.0)) if ph["type"] == "hg" else None)
        self.materials = {}
        for name, m in t.get("materials", {}).items():
            if m["type"] == "lambert" and not m.get("one_sided", False) and "texture" not in m:
                self.materials[name] = dict(type="lambert", albedo=rgb(m["albedo"]))
            elif m["type"] == "dielectric" and not ({"specular_reflectance", "specular_transmittance"} & m.keys()):
                self.materials[name] = dict(type="dielectric", ior=float(m["ior"]))
            else:
                raise Refused(f"material `{name}` ({m['type']}): only two-sided lambert and "
                              "clear (untinted) dielectric are converted")
        self.shapes = [self._shape(s) for s in t["shapes"]]
        self.boxes = [(s["min"], s["max"], s["interior"]) for s in self.shapes
                      if s["type"] == "box" and s.get("interior") not in (None, "vacuum")]

    def _shape(self, s):
        kind = s["type"]
        if kind not in ("quad", "box", "sphere"):
            raise Refused(f"shape {kind}: only quads, boxes and spheres are converted")
        if s.get("flip_normals"):
            raise Refused(f"a {kind} with flip_normals")
        out = dict(s)
        mat = s.get("material")
        if "emission" in s:
            if kind != "quad" or mat is not None:
                raise Refused("only black quads emit in the converted scenes")
            out["emission"] = rgb(s["emission"])
        elif mat is None:
            raise Refused(f"a {kind} without material")
        elif mat != "null" and mat not in self.materials:
            raise Refused(f"material `{mat}`")
        if kind == "box" and mat == "null" and s.get("interior") not in (None, "vacuum"):
            out["min"] = [x - GROW for x in s["min"]]
            out["max"] = [x + GROW for x in s["max"]]
        return out

    def medium_at(self, p):
        """The medium whose (grown) box holds the point `p`, or None (vacuum)."""
        inside = [m for lo, hi, m in self.boxes if all(lo[i] < p[i] < hi[i] for i in range(3))]
        if len(inside) > 1:
            raise Refused(f"nested medium boxes around {p}")
        return inside[0] if inside else None

    def resolution(self, res):
        return list(res) if res else list(self.camera["resolution"])

    def eye(self):
        c = self.camera
        return [float(x) for x in c["eye"]], [float(x) for x in c["look_at"]], \
            [float(x) for x in c.get("up", [0.0, 1.0, 0.0])]


def quad_frame(s):
    """A quad's centre, half edges and unit normal u x v (the side pathspace's emitters face)."""
    o, u, v = s["origin"], s["u"], s["v"]
    if abs(dot(u, v)) > 1e-6 * math.sqrt(dot(u, u) * dot(v, v)):
        raise Refused("a quad whose edges are not perpendicular")
    return add(o, scale(add(u, v), 0.5)), scale(u, 0.5), scale(v, 0.5), normalize(cross(u, v))


def resolution(text):
    """`N` (square) or `WxH`, for the converters' `--res`."""
    w, _, h = text.partition("x")
    return [int(w), int(h or w)]
