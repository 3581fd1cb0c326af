"""earshot.render: a scene file to audio in memory, the same as `earshot render`."""
import json
import os

import numpy as np
import pytest

import earshot
from earshot.dataset import read_wav_float
from conftest import SOURCE_DIR, run_cli

SCENE = os.path.join(SOURCE_DIR, "samples", "shoebox", "static.json")


def test_render_equals_the_cli(tmp_path):
    run_cli("render", SCENE, "-o", tmp_path / "x.wav", "--from", 0, "--to", 0.5, "--quality", "draft", "--quiet")
    x, rate = read_wav_float(tmp_path / "x.wav")
    r = earshot.render(SCENE, quality="draft", start=0, end=0.5)
    assert r.samples.dtype == np.float32 and r.samples.shape == (2, 24000) == x.shape
    assert r.sample_rate == rate
    assert np.array_equal(r.samples, x)
    assert r.info["simulations"] >= 1 and r.info["peak"] > 0


def test_render_from_a_dict_resolves_paths_against_base_dir():
    with open(SCENE) as f:
        scene = json.load(f)
    a = earshot.render(scene, base_dir=os.path.dirname(SCENE), quality="draft", start=0, end=0.25)
    b = earshot.render(SCENE, quality="draft", start=0, end=0.25)
    assert np.array_equal(a.samples, b.samples)


def test_render_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        earshot.render(tmp_path / "none.json")
    with pytest.raises(ValueError, match="geometry"):
        earshot.render('{"geometry": null, "listener": {"position": [0,0,0]}, "sources": [], '
                       '"settings": {"sample_rate": "48k"}}')
    with pytest.raises(ValueError, match="quality"):
        earshot.render(SCENE, quality="ultra")
    with pytest.raises(ValueError, match="end"):
        earshot.render(SCENE, start=1.0, end=0.5)
    with pytest.raises(TypeError):
        earshot.render(42)
    # A NaN in a dict is named (json.dumps would write NaN, not JSON).
    with open(SCENE) as f:
        scene = json.load(f)
    scene["listener"]["position"] = [float("nan"), 0, 0]
    with pytest.raises(ValueError, match="scene: every number must be finite"):
        earshot.render(scene, base_dir=os.path.dirname(SCENE))
    # A dict nested past Python's recursion limit is a ValueError like any
    # bad scene, and a long string that is neither JSON text nor a file is
    # named in 200 characters, not echoed whole.
    deep = cur = {}
    for _ in range(100_000):
        cur["x"] = {}
        cur = cur["x"]
    with pytest.raises(ValueError, match="scene: nested too deeply"):
        earshot.render(deep)
    with pytest.raises(ValueError, match="materials: nested too deeply"):
        earshot.Scene(materials=deep)
    with pytest.raises(FileNotFoundError) as e:
        earshot.render("[" * 1_000_000)
    assert len(str(e.value)) < 250 and str(e.value).endswith("...: no such scene file")
