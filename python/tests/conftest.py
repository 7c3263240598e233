"""Shared fixtures: the repository, the command line's binary (the bit-for-bit reference of the
binding) and an independent EXR reader (the `OpenEXR` package)."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
FOG_BOX = ROOT / "scenes" / "fog-box.toml"
# small enough for CI, not square: rows and columns cannot be confused
SIZE = (12, 8)


def cli_binary() -> pathlib.Path:
    if os.environ.get("PATHSPACE_BIN"):
        return pathlib.Path(os.environ["PATHSPACE_BIN"])
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return target / "release" / "pathspace"


@pytest.fixture(scope="session")
def cli():
    """Runs `pathspace ARGS...`; the completed process."""
    binary = cli_binary()
    if not binary.exists():
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)

    def run(*args, check=True):
        p = subprocess.run([str(binary), *map(str, args)], cwd=ROOT, capture_output=True,
                           text=True)
        if check and p.returncode != 0:
            raise AssertionError(f"pathspace {' '.join(map(str, args))}: {p.stderr}")
        return p

    return run


def read_exr_independently(path) -> np.ndarray:
    """R, G, B of an EXR as float32 H x W x 3, read by the OpenEXR package (not pathspace)."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as f:
        ch = f.channels()
        return np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], axis=-1)


def bits(a: np.ndarray) -> np.ndarray:
    """The float32 values' bits: equality of these is equality bit for bit (NaN included)."""
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)
