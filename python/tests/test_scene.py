"""Loading (TOML file, Mitsuba XML, string, dictionary), the errors (the command line's
messages, with file, line and key), the options through the one schema, and parameter
updates (a changed copy, equal bit for bit to the scene file with the value edited)."""

import pathlib
import re

import numpy as np
import pytest

import pathspace
from conftest import FOG_BOX, ROOT, SIZE, bits

try:
    import tomllib
except ImportError:  # Python < 3.11
    tomllib = None


def image(scene, **kw):
    return scene.render(spp=4, seed=11, threads=2, **kw).image


def test_string_and_dict_are_the_file():
    text = FOG_BOX.read_text()
    a = image(pathspace.load_file(FOG_BOX, resolution=SIZE))
    b = image(pathspace.load_string(text, resolution=SIZE))
    assert np.array_equal(bits(a), bits(b))
    if tomllib is not None:
        c = image(pathspace.load_dict(tomllib.loads(text), resolution=SIZE))
        assert np.array_equal(bits(a), bits(c))


def test_mitsuba_xml_loads_and_renders(cli, tmp_path):
    xml = ROOT / "scenes" / "xml" / "hg-sphere.xml"
    scene = pathspace.load_file(xml, resolution=SIZE)
    out = tmp_path / "x.exr"
    cli("render", xml, "--spp", 4, "--seed", 11, "--threads", 2, "--resolution",
        f"{SIZE[0]}x{SIZE[1]}", "-o", out)
    theirs, _ = pathspace.read_exr(out)
    assert np.array_equal(bits(image(scene)), bits(theirs))


@pytest.mark.parametrize("text", [
    "[camera]\ntype = \"pinhole\"\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nfov_deg = 40\n"
    "resolution = [8, 8]\nbogus = 1\n",
    "[render]\nspp = 0\n" + FOG_BOX.read_text().split("[render]")[1].split("\n", 4)[4],
    "[media.fog]\ntype = \"homogeneous\"\nsigma_a = -1\nsigma_s = 1\n",
    "this is not toml\n",
])
def test_errors_are_the_cli_messages(text, cli, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(pathspace.Error) as e:
        pathspace.load_file(path)
    p = cli("info", path, check=False)
    assert p.returncode != 0
    assert str(e.value) in p.stderr, (str(e.value), p.stderr)
    assert e.value.file == str(path) and e.value.line >= 1 and e.value.key
    assert re.match(rf"{re.escape(str(path))}:\d+: key `", str(e.value))


def test_missing_file_and_bad_dict():
    with pytest.raises(pathspace.Error, match="cannot read the scene file"):
        pathspace.load_file("no/such/scene.toml")
    with pytest.raises(pathspace.Error, match="camera"):
        pathspace.load_dict({"camera": {"type": "pinhole"}})


def test_options_go_through_the_schema():
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    with pytest.raises(pathspace.Error, match=r"unknown field `bogus`, expected one of .*`spp`"):
        scene.render(spp=1, bogus=3)
    with pytest.raises(pathspace.Error, match="spp must be at least 1"):
        scene.render(spp=0)
    with pytest.raises(pathspace.Error, match="unknown integrator"):
        scene.render(integrator="nope", spp=1)
    with pytest.raises(pathspace.Error, match=r"render\.smc"):
        scene.render(integrator="smc", spp=1, smc={"variant": "no-such-variant"})
    # a nested table and a top-level key reach the integrators
    a = scene.render(spp=4, seed=3, max_depth=1, threads=1)
    b = scene.render(spp=4, seed=3, threads=1)
    assert a.stats["options"]["max_depth"] == 1
    assert not np.array_equal(bits(a.image), bits(b.image))


def edited(text: str, old: str, new: str) -> str:
    assert text.count(old) == 1, old
    return text.replace(old, new)


UPDATES = [
    ("media.fog.sigma_s", [0.8, 0.8, 0.8], "\nsigma_s = 0.4\n", "\nsigma_s = [0.8, 0.8, 0.8]\n"),
    ("media.fog.sigma_a", 0.3, "\nsigma_a = 0.1\n", "\nsigma_a = 0.3\n"),
    ("media.fog.phase", {"type": "hg", "g": 0.6}, 'phase = { type = "isotropic" }',
     'phase = { type = "hg", g = 0.6 }'),
    ("materials.red.albedo", [0.2, 0.6, 0.2], "albedo = [0.63, 0.065, 0.05]",
     "albedo = [0.2, 0.6, 0.2]"),
    ("shapes[6].emission", [4.0, 4.0, 4.0], "emission = [10.0, 10.0, 10.0]",
     "emission = [4.0, 4.0, 4.0]"),
    ("camera.eye", [0.2, 0.1, 3.5], "eye = [0.0, 0.0, 3.9]", "eye = [0.2, 0.1, 3.5]"),
]


@pytest.mark.parametrize("key,value,old,new", UPDATES)
def test_an_update_is_the_edited_file(key, value, old, new):
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    before = image(scene)
    params = scene.traverse()
    assert any(k.startswith(key) for k in params), key
    params[key] = value
    changed = params.update()
    after = image(changed)
    assert not np.array_equal(bits(before), bits(after)), "the change shows"
    assert np.array_equal(bits(image(scene)), bits(before)), "the original is unchanged"
    text = edited(FOG_BOX.read_text(), old, new)
    fresh = image(pathspace.load_string(text, resolution=SIZE))
    assert np.array_equal(bits(after), bits(fresh))


def test_the_changed_copy_is_what_the_cli_renders(cli, tmp_path):
    scene = pathspace.load_file(FOG_BOX, resolution=SIZE)
    changed = scene.traverse().update({"media.fog.sigma_s": 1.5})
    path = tmp_path / "changed.toml"
    path.write_text(changed.to_toml())
    out = tmp_path / "changed.exr"
    cli("render", path, "--spp", 4, "--seed", 11, "--threads", 2, "--resolution",
        f"{SIZE[0]}x{SIZE[1]}", "-o", out)
    theirs, meta = pathspace.read_exr(out)
    r = changed.render(spp=4, seed=11, threads=2)
    assert np.array_equal(bits(r.image), bits(theirs))
    assert r.provenance["scene_hash"] == meta["scene_hash"]


def test_bad_updates_are_refused():
    params = pathspace.load_file(FOG_BOX, resolution=SIZE).traverse()
    with pytest.raises(pathspace.Error, match="no parameter"):
        params.update({"media.smoke.sigma_s": 1.0})
    with pytest.raises(pathspace.Error, match="render options are arguments of render"):
        params.update({"render.spp": 1})
    params = pathspace.load_file(FOG_BOX, resolution=SIZE).traverse()
    with pytest.raises(pathspace.Error, match="sigma_a"):
        params.update({"media.fog.sigma_a": -1.0})
