#!/usr/bin/env python3
"""Denoise a pathspace render with Intel Open Image Denoise, guided by its feature layers.

    pathspace render scenes/fog-box.toml --spp 16 --resolution 256x256 \
        --aovs albedo,normal -o fog.exr
    python3 -m pip install numpy openexr pyoidn
    python3 examples/python/denoise.py fog.exr fog-denoised.exr

The layers of `--aovs` already follow the denoiser's conventions: linear float32 colour (HDR),
albedo in [0, 1] (`Albedo.R/G/B`: a surface's reflectance, a medium's single-scattering albedo
sigma_s / sigma_t), world-space shading normals in [-1, 1] (`Ns.X/Y/Z`: facing the camera,
zero in a medium and where the ray leaves the scene). Both are means over 16 camera rays per
pixel, so they are not noise-free in media: the denoiser prefilters them (no `clean_aux`).
Without the layers the colour is denoised alone. The output holds the denoised R, G, B and
the input's header attributes.
"""

import sys

import numpy as np
import OpenEXR
import pyoidn


def read_layers(path):
    """The file's header and its channels by name, each an (H, W) float32 array."""
    with OpenEXR.File(path, separate_channels=True) as f:
        header = dict(f.header())
        channels = {name: np.asarray(c.pixels, dtype=np.float32)
                    for name, c in f.channels().items()}
    return header, channels


def stack(channels, names):
    """An (H, W, 3) float32 image of three channels, or None when one is missing."""
    if not all(n in channels for n in names):
        return None
    return np.ascontiguousarray(np.stack([channels[n] for n in names], axis=-1))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    source, target = sys.argv[1], sys.argv[2]
    header, channels = read_layers(source)
    color = stack(channels, ["R", "G", "B"])
    if color is None:
        sys.exit(f"{source}: no R, G, B channels")
    albedo = stack(channels, ["Albedo.R", "Albedo.G", "Albedo.B"])
    normal = stack(channels, ["Ns.X", "Ns.Y", "Ns.Z"])
    if normal is not None and albedo is None:
        # the denoiser takes normals only together with an albedo
        normal = None
    used = [n for n, a in (("albedo", albedo), ("normal", normal)) if a is not None]
    print(f"denoising {source} ({color.shape[1]}x{color.shape[0]}) guided by "
          f"{', '.join(used) or 'the colour alone'}")
    out = pyoidn.denoise(np.maximum(color, 0.0), albedo, normal, hdr=True)
    keep = {k: v for k, v in header.items()
            if k not in ("channels", "dataWindow", "displayWindow", "compression",
                         "lineOrder", "pixelAspectRatio", "screenWindowCenter",
                         "screenWindowWidth", "type", "name")}
    keep["denoised"] = "Open Image Denoise (pyoidn), guided by " + (", ".join(used) or "nothing")
    denoised = {"RGB": np.ascontiguousarray(out, dtype=np.float32)}
    with OpenEXR.File(keep, denoised) as f:
        f.write(target)
    print(f"wrote {target}")


if __name__ == "__main__":
    main()
