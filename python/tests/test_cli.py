"""Bit for bit the command line: for every integrator, the binding's image equals the pixels of
the EXR `pathspace render` writes for the same scene, seed and settings (read by an independent
EXR reader), and `Result.write` writes that EXR."""

import numpy as np
import pytest

import pathspace
from conftest import FOG_BOX, SIZE, bits, read_exr_independently


@pytest.mark.parametrize("integrator", pathspace.integrators())
def test_image_equals_the_cli_exr(integrator, cli, tmp_path):
    w, h = SIZE
    out = tmp_path / "cli.exr"
    cli("render", FOG_BOX, "--integrator", integrator, "--spp", 8, "--seed", 7,
        "--resolution", f"{w}x{h}", "--threads", 2, "-o", out)
    expected = read_exr_independently(out)
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    result = scene.render(integrator=integrator, spp=8, seed=7, threads=2)
    assert result.image.shape == (h, w, 3) and result.image.dtype == np.float32
    assert np.array_equal(bits(result.image), bits(expected))
    # the same EXR: pixels, and the header's record but for the timings
    mine = tmp_path / "mine.exr"
    result.write(mine)
    assert np.array_equal(bits(read_exr_independently(mine)), bits(expected))
    _, theirs = pathspace.read_exr(out)
    _, ours = pathspace.read_exr(mine)
    timings = {"seconds", "guide_seconds"}
    assert {k: v for k, v in ours.items() if k not in timings} == \
        {k: v for k, v in theirs.items() if k not in timings}


def test_stats_are_the_cli_json(cli, tmp_path):
    import json

    w, h = SIZE
    p = cli("render", FOG_BOX, "--spp", 4, "--seed", 2, "--resolution", f"{w}x{h}", "--json",
            "-o", tmp_path / "x.exr")
    theirs = json.loads(p.stdout)
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    r = scene.render(spp=4, seed=2, threads=1)
    assert set(r.stats) == set(theirs)
    for key in ["integrator", "spp", "mean", "nan_count", "negative_pixels", "options",
                "sensors", "estimated_relmse", "guide", "adjoint"]:
        assert r.stats[key] == theirs[key], key
    assert r.provenance["seed"] == "2" and r.provenance["spp"] == "4"


def test_threads_do_not_change_the_image():
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    one = scene.render(spp=8, seed=5, threads=1)
    two = scene.render(spp=8, seed=5, threads=2)
    assert np.array_equal(bits(one.image), bits(two.image))
    assert np.array_equal(bits(one.variance), bits(two.variance))
    with pytest.raises(pathspace.Error, match="--threads must be at least 1"):
        scene.render(spp=1, threads=0)
