"""pathspace from Python: load a scene, render it to numpy, change a parameter and render again.

    import pathspace
    scene = pathspace.load_file("scenes/fog-box.toml")
    result = scene.render(integrator="path", spp=64, seed=1)
    result.image          # float32 array, height x width x 3
    params = scene.traverse()
    params["media.fog.sigma_s"] = [0.5, 0.5, 0.5]
    thicker = params.update()   # a changed copy, built without parsing the file again

The options of ``render`` are the keys of a scene file's ``[render]`` table (one schema for
the file, the command line and Python); nested tables are dictionaries, e.g.
``smc={"variant": "is1_cv2"}``. Errors raise ``pathspace.Error`` with the command line's
message (file, line, key).
"""

from __future__ import annotations

import json
from typing import Any, Callable, Dict, List, Optional, Tuple

from . import _pathspace
from ._pathspace import Error

__all__ = [
    "Error",
    "Interrupted",
    "Scene",
    "Result",
    "SceneParameters",
    "load_file",
    "load_string",
    "load_dict",
    "diff",
    "converge",
    "read_exr",
    "integrators",
]


class Interrupted(KeyboardInterrupt):
    """Ctrl-C (or an exception of the progress callback) stopped a render after the pass in
    flight; ``.result`` holds the samples done so far (``result.complete`` is False)."""

    def __init__(self, result: "Result"):
        super().__init__(f"render interrupted after {result.spp} spp")
        self.result = result


class Result:
    """A render's outcome: ``image`` and ``variance`` (of each pixel's mean) as float32
    H x W x 3 arrays, ``sensors`` (irradiance meters with standard errors), ``stats`` (what
    ``pathspace render --json`` prints), ``provenance`` (the EXR header's record)."""

    def __init__(self, raw):
        self._raw = raw
        self.image = raw.image
        self.variance = raw.variance
        self.stats: Dict[str, Any] = json.loads(raw.stats_json)
        self.provenance: Dict[str, str] = raw.provenance
        self.sensors: List[Dict[str, Any]] = [
            {"name": n, "value": list(v), "stderr": list(e), "samples": s}
            for (n, v, e, s) in raw.meters
        ]

    @property
    def spp(self) -> int:
        return self.stats["spp"]

    @property
    def complete(self) -> bool:
        return self.provenance.get("complete") == "true"

    def write(self, path, reproducible: bool = False) -> None:
        """Writes the EXR ``pathspace render -o path`` writes (``reproducible``: without the
        timings, as ``--reproducible``)."""
        self._raw.write(str(path), reproducible)

    def __repr__(self) -> str:
        return f"<pathspace.Result {self.stats['integrator']} {self.spp} spp>"


class Scene:
    """A loaded scene (immutable: ``traverse().update()`` builds a changed copy)."""

    def __init__(self, raw):
        self._raw = raw

    @property
    def name(self) -> str:
        return self._raw.name

    @property
    def size(self) -> Optional[Tuple[int, int]]:
        """The camera's (width, height)."""
        return self._raw.size

    def to_toml(self) -> str:
        """The scene as a scene file (what ``pathspace render`` renders to the same image)."""
        return self._raw.to_toml()

    def render(
        self,
        integrator: Optional[str] = None,
        spp: Optional[int] = None,
        seed: Optional[int] = None,
        threads: Optional[int] = None,
        time: Optional[float] = None,
        progress: Optional[Callable[[int, Optional[int]], Any]] = None,
        **options: Any,
    ) -> Result:
        """Renders the scene. ``options`` are ``[render]`` keys over the scene file's
        (``max_depth=8``, ``smc={"variant": "is1_cv0"}``, ...); ``threads`` defaults to all
        cores (the image is the same for any count); ``time`` renders for that many seconds
        instead of ``spp``; ``progress(spp_done, spp_target)`` is called after every pass.
        The GIL is released during the passes; Ctrl-C stops after the pass in flight and
        raises ``Interrupted`` (a ``KeyboardInterrupt``) carrying the partial result."""
        given = dict(options)
        for key, value in (("integrator", integrator), ("spp", spp), ("seed", seed)):
            if value is not None:
                given[key] = value
        raw, interrupted = self._raw.render(json.dumps(given), threads, time, progress)
        result = Result(raw)
        if interrupted:
            raise Interrupted(result)
        return result

    def traverse(self) -> "SceneParameters":
        """The scene's parameters by key path (``media.fog.sigma_s``,
        ``materials.white.albedo``, ``lights[0].radiance``, ``camera.eye``, ...)."""
        return SceneParameters(self)

    def __repr__(self) -> str:
        return f"<pathspace.Scene {self.name} {self.size}>"


class SceneParameters(dict):
    """The parameters of a scene as a dictionary (as Mitsuba's ``traverse``): change values,
    then ``update()`` returns the changed copy of the scene (the original stays as it was)."""

    def __init__(self, scene: Scene):
        super().__init__(json.loads(scene._raw.parameters_json()))
        self._scene = scene
        self._changed: Dict[str, Any] = {}

    def __setitem__(self, key: str, value: Any) -> None:
        value = _plain(value)
        super().__setitem__(key, value)
        self._changed[key] = value

    def update(self, changes: Optional[Dict[str, Any]] = None, **more: Any) -> Scene:  # type: ignore[override]
        """The scene with the changed parameters (and those of ``changes``), rebuilt from its
        changed description without parsing the file again."""
        changes = {k: _plain(v) for k, v in {**(changes or {}), **more}.items()}
        scene = Scene(self._scene._raw.updated(json.dumps({**self._changed, **changes})))
        for k, v in changes.items():
            self[k] = v
        return scene


def _plain(value: Any) -> Any:
    """numpy values and arrays as plain numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def load_file(path, resolution: Optional[Tuple[int, int]] = None) -> Scene:
    """A scene file: TOML, or Mitsuba 3 XML by its ``.xml`` extension. ``resolution``
    overrides the camera's as ``--resolution WxH`` does."""
    return Scene(_pathspace.load_file(str(path), resolution))


def load_string(text: str, name: str = "<string>", base_dir=None,
                resolution: Optional[Tuple[int, int]] = None) -> Scene:
    """A scene file's text (TOML); relative paths are read from ``base_dir``."""
    return Scene(_pathspace.load_string(text, name, None if base_dir is None else str(base_dir),
                                        resolution))


def load_dict(d: Dict[str, Any], base_dir=None,
              resolution: Optional[Tuple[int, int]] = None) -> Scene:
    """A scene as a dictionary of the scene file's schema (tables are dictionaries, arrays of
    tables lists of dictionaries)."""
    text = _pathspace.toml_of_json(json.dumps(d, default=_plain))
    return load_string(text, "<dict>", base_dir, resolution)


def _array(x):
    return x.image if isinstance(x, Result) else x


def diff(a, b) -> Dict[str, float]:
    """Error metrics of ``a`` against the reference ``b`` (arrays or results), as
    ``pathspace diff --json``: rmse, relmse, max_abs, max_f32_steps."""
    import numpy as np

    return _pathspace.diff(np.ascontiguousarray(_array(a), dtype=np.float32),
                           np.ascontiguousarray(_array(b), dtype=np.float32))


def converge(scene: Scene, reference, integrators=("path",), budget: float = 1.0,
             checkpoints: int = 8, runs: int = 1, seed: Optional[int] = None,
             threads: Optional[int] = None) -> List[Dict[str, Any]]:
    """An equal-time convergence study as ``pathspace converge``: one row (a dict: integrator,
    run, checkpoint, seconds, samples, rmse, relmse, efficiency) per integrator, run and
    checkpoint; ``pandas.DataFrame(rows)`` takes them."""
    import numpy as np

    ref = np.ascontiguousarray(_array(reference), dtype=np.float32)
    return _pathspace.converge(scene._raw, ref, list(integrators), budget, checkpoints, runs,
                               seed, threads)


def read_exr(path):
    """An EXR's pixels (float32 H x W x 3) and its header's attributes."""
    return _pathspace.read_exr(str(path))


def integrators() -> List[str]:
    """The integrators' names."""
    return _pathspace.integrators()
