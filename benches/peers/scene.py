"""A pathspace TOML scene read for the peers' converters (`to_mitsuba.py`, `to_tungsten.py`):
the subset both peers can render exactly (quads, boxes and spheres; Lambert and smooth
dielectric surfaces, GGX rough conductors with a complex index; homogeneous media with isotropic or Henyey-Greenstein phase; emitting
quads; a pinhole camera), everything else refused by name with `Refused`.

Two facts of the peers shape the conversion (book: *Measuring a renderer*, "Against other
renderers"): both Mitsuba 3 and tungsten lose light where a null medium boundary is coplanar
with an opaque wall, so every medium box is grown by `GROW` on all sides; and neither finds by
itself the medium a camera or an emitter sits in, so `medium_at` names it for them. A box of a
grid medium (a procedural field baked with `resolution`, tracked) is grown only on its faces
that lie on an opaque quad covering them: there the grown shell is behind the wall; elsewhere
it would add medium that pathspace's box does not have.

`VARIANTS` are scenes the peers can render exactly made from a paper scene by one named change
(`python3 benches/peers/scene.py NAME` prints the TOML): the harness's `--scenes` takes them.
"""

import math
import os
import sys
import tomllib

GROW = 1e-3
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# name: (paper scene, [(text, replacement)], what changes and why)
VARIANTS = {
    "cloud-tracking": ("cloud", [('propagation = "random-offset"', 'propagation = "delta-tracking"'),
                                 ("step = 0.125\n", "")],
                       "delta tracking instead of Pauly et al.'s random-offset marching (biased)"),
    # k = 2 sqrt(R0 / (1 - R0)) with eta 1: the Fresnel reflectance at normal incidence is R0
    "door-slit-ior": ("door-slit", [("reflectance = [0.6, 0.55, 0.5]",
                                     f"eta = 1.0\nk = [{2 * math.sqrt(0.6 / 0.4)!r}, "
                                     f"{2 * math.sqrt(0.55 / 0.45)!r}, {2 * math.sqrt(1.0)!r}]")],
                      "the floor's Schlick Fresnel (R0 = 0.6, 0.55, 0.5) replaced by the complex "
                      "index eta 1, k = 2 sqrt(R0 / (1 - R0)), equal at normal incidence"),
    "volume-caustic-hard-cone": ("volume-caustic", [("falloff_deg = 2.0", "falloff_deg = 0.0")],
                                 "the spot light's 2-degree smoothstep falloff removed (a hard cone)"),
    # u x v points down; radiance x area = the spot's 60 W/sr along the axis
    "volume-caustic-quad": ("volume-caustic", [('[[lights]]\ntype = "spot"\nposition = [0.0, 3.3, 0.0]\n'
                                                'direction = [0.0, -1.0, 0.0]\nintensity = 60.0\n'
                                                'cone_deg = 12.0\nfalloff_deg = 2.0\n',
                                                '[[shapes]]\ntype = "quad"\norigin = [-0.1, 3.3, -0.1]\n'
                                                'u = [0.2, 0.0, 0.0]\nv = [0.0, 0.0, 0.2]\n'
                                                'emission = 1500.0\n')],
                            "the spot light replaced by a 0.2 m square light facing down at its "
                            "place, 1500 W/m^2/sr (60 W/sr along the axis): a light both peers have"),
}


def variant_text(name):
    """The TOML of the variant `name` (`VARIANTS`)."""
    base, subs, _ = VARIANTS[name]
    with open(os.path.join(ROOT, "scenes", base + ".toml")) as f:
        text = f.read()
    for old, new in subs:
        if old not in text:
            raise SystemExit(f"variant {name}: scenes/{base}.toml no longer contains {old!r}")
        text = text.replace(old, new)
    return text


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
        if t.get("hide_emitters", False):
            raise Refused("hide_emitters (the converters show every emitter, so the peers would "
                          "render another image)")
        self.spots = []
        for x in t.get("lights", []):
            if x.get("type") == "spot" and float(x.get("falloff_deg", 0.0)) != 0.0:
                raise Refused("a spot light with a falloff (Mitsuba 3's `spot` falls off linearly in "
                              "the angle, pathspace's as a smoothstep in the cosine; tungsten has no "
                              "spot light)")
            if x.get("type") == "spot":
                self.spots.append(dict(position=[float(v) for v in x["position"]],
                                       direction=[float(v) for v in x["direction"]],
                                       intensity=rgb(x["intensity"]), cone_deg=float(x["cone_deg"])))
        if len(self.spots) != len(t.get("lights", [])):
            raise Refused("[lights] other than hard-cone spot lights: only emitting quads are converted")
        for key in ("environment", "meters", "textures"):
            if t.get(key):
                kinds = sorted({x.get("type", key) for x in t[key]}) if isinstance(t[key], list) else [key]
                raise Refused(f"[{key}] ({', '.join(kinds)}): only emitting quads are converted")
        cam = t["camera"]
        if cam.get("type", "pinhole") != "pinhole" or "filter" in cam:
            raise Refused("only a pinhole camera with the box filter is converted")
        self.camera = cam
        self.media = {}
        for name, m in t.get("media", {}).items():
            if m.get("emission") is not None:
                raise Refused(f"medium `{name}` emits")
            ph = m.get("phase", {"type": "isotropic"})
            if ph["type"] not in ("isotropic", "hg"):
                raise Refused(f"medium `{name}` has the phase function {ph['type']}")
            self.media[name] = dict(kind="homogeneous", sigma_a=rgb(m["sigma_a"]), sigma_s=rgb(m["sigma_s"]),
                                    g=float(ph.get("g", 0.0)) if ph["type"] == "hg" else None)
            if m["type"] != "homogeneous":
                self.media[name].update(self._grid(name, m))
        self.materials = {n: self._material(n, m) for n, m in t.get("materials", {}).items()}
        self.shapes = [self._shape(s) for s in t["shapes"]]
        for s in self.shapes:
            if s["type"] == "box" and s.get("material") == "null" and s.get("interior") in self.media:
                self._grow(s, self.media[s["interior"]]["kind"] == "grid")
        self.boxes = [(s["min"], s["max"], s["interior"]) for s in self.shapes
                      if s["type"] == "box" and s.get("interior") not in (None, "vacuum")]

    def _material(self, name, m):
        if m["type"] == "lambert" and not m.get("one_sided", False) and "texture" not in m:
            return dict(type="lambert", albedo=rgb(m["albedo"]))
        if m["type"] == "dielectric" and not ({"specular_reflectance", "specular_transmittance"} & m.keys()):
            return dict(type="dielectric", ior=float(m["ior"]))
        if m["type"] == "rough_conductor":
            return self._rough_conductor(name, m)
        raise Refused(f"material `{name}` ({m['type']}): only two-sided lambert, clear (untinted) "
                      "dielectric and rough conductor with a complex index are converted")

    def _rough_conductor(self, name, m):
        """A GGX rough conductor with a scalar alpha and the Fresnel term of a complex index
        (`eta`, `k`), or none (1); pathspace's Schlick `reflectance`, a named `material` and
        textures have no exact counterpart in both peers."""
        if m.get("distribution", "ggx") != "ggx":
            raise Refused(f"material `{name}`: a rough conductor with distribution {m['distribution']}")
        if "reflectance" in m:
            raise Refused(f"material `{name}`: a rough conductor with a Schlick `reflectance` (Mitsuba 3's "
                          "roughconductor has the Fresnel term of a complex index only)")
        if "alpha_u" in m or "alpha_v" in m:
            raise Refused(f"material `{name}`: a rough conductor with anisotropic roughness "
                          "(`alpha_u`, `alpha_v`; the peers' frames are not pathspace's)")
        if "material" in m or m.get("one_sided", False) or not isinstance(m["alpha"], (int, float)) \
                or not isinstance(m.get("specular", 1.0), (int, float, list)):
            raise Refused(f"material `{name}`: a rough conductor with a named material, one side or a texture")
        for key in ("eta", "k"):
            if key in m and not isinstance(m[key], (int, float, list)):
                raise Refused(f"material `{name}`: a rough conductor with a textured `{key}`")
        has_index = "eta" in m or "k" in m
        return dict(type="rough_conductor", alpha=float(m["alpha"]),
                    eta=rgb(m.get("eta", 0.0)) if has_index else None,
                    k=rgb(m.get("k", 1.0)) if has_index else None, specular=rgb(m.get("specular", 1.0)))

    def _grid(self, name, m):
        """A procedural field baked onto a grid and tracked: the baked lattice (written by
        `pathspace info --write-grids`) over [min, max]."""
        if m["type"] != "procedural" or "resolution" not in m:
            raise Refused(f"medium `{name}` is {m['type']}" + (" evaluated on the fly" if m["type"] == "procedural" else "")
                          + " (homogeneous media and procedural fields baked with `resolution` are converted)")
        if m.get("propagation", "delta-tracking") != "delta-tracking":
            raise Refused(f"medium `{name}` is ray-marched ({m['propagation']}, biased): the peers track "
                          "(variant cloud-tracking)")
        st = [a + b for a, b in zip(rgb(m["sigma_a"]), rgb(m["sigma_s"]))]
        if max(st) != min(st):
            raise Refused(f"medium `{name}`: a grid medium with a coloured sigma_t")
        n = int(m["resolution"])
        return dict(kind="grid", res=[n, n, n], min=[float(x) for x in m["min"]],
                    max=[float(x) for x in m["max"]])

    def grids(self, out_dir, binary=None):
        """Writes each grid medium's lattice to OUT_DIR/NAME.vol (pathspace's layout: vertices
        spanning the box) and returns {name: path}."""
        import subprocess
        binary = binary or os.path.join(ROOT, "target", "release", "pathspace")
        if not any(m["kind"] == "grid" for m in self.media.values()):
            return {}
        subprocess.run([binary, "info", self.path, "--write-grids", out_dir], check=True,
                       stdout=subprocess.DEVNULL)
        return {n: os.path.join(out_dir, n + ".vol") for n, m in self.media.items() if m["kind"] == "grid"}

    def _grow(self, box, grid):
        """Grows a medium box by GROW on every face, or a grid medium's only on the faces
        opaque quads cover."""
        grow = [[-GROW * (not grid or self._covered(box, i, box["min"][i])) for i in range(3)],
                [GROW * (not grid or self._covered(box, i, box["max"][i])) for i in range(3)]]
        box["min"] = [x + d for x, d in zip(box["min"], grow[0])]
        box["max"] = [x + d for x, d in zip(box["max"], grow[1])]

    def _covered(self, box, axis, c):
        """Whether opaque axis-aligned quads in the plane x[axis] = c together cover the box's
        face there (each cell between the rectangles' edges lies in one of them)."""
        others = [j for j in range(3) if j != axis]
        rects = []
        for q in self.shapes:
            if q["type"] != "quad" or "emission" in q or q["material"] == "null" \
                    or self.materials[q["material"]]["type"] == "dielectric":
                continue
            o, u, v = q["origin"], q["u"], q["v"]
            if u[axis] != 0 or v[axis] != 0 or o[axis] != c \
                    or any(sum(1 for e in (u, v) if e[j] != 0) != 1 for j in others):
                continue
            rects.append([(min(o[j], o[j] + u[j] + v[j]), max(o[j], o[j] + u[j] + v[j])) for j in others])
        face = [(box["min"][j], box["max"][j]) for j in others]
        cuts = [sorted({x for r in rects + [face] for x in r[k] if face[k][0] <= x <= face[k][1]})
                for k in range(2)]
        return all(any(all(r[k][0] <= m[k] <= r[k][1] for k in range(2)) for r in rects)
                   for m in ((a, b) for a in mids(cuts[0]) for b in mids(cuts[1])))

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
            if isinstance(s["emission"], dict):
                raise Refused("a textured emission")
            out["emission"] = rgb(s["emission"])
        elif mat is None:
            raise Refused(f"a {kind} without material")
        elif mat != "null" and mat not in self.materials:
            raise Refused(f"material `{mat}`")
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


def mids(xs):
    return [(a + b) / 2 for a, b in zip(xs, xs[1:])]


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


if __name__ == "__main__":
    if len(sys.argv) != 2 or sys.argv[1] not in VARIANTS:
        raise SystemExit("usage: scene.py VARIANT (" + ", ".join(VARIANTS) + ")")
    sys.stdout.write(variant_text(sys.argv[1]))
