"""earshot.Scene(...).ir / ir_batch: the same numbers as `earshot ir`, pair i
of a batch the same as ir(seed=seed + i), and errors that raise."""
import json
import math
import os

import numpy as np
import pytest

import earshot
from earshot.dataset import read_wav_float
from conftest import SHOEBOX, SHOEBOX_MAP, SOURCE_DIR, run_cli

SRC, LIS = (2.0, 3.5, 1.5), (7.0, 3.5, 1.5)


def cli_ir(tmp_path, *args):
    out, js = tmp_path / "ir.wav", tmp_path / "ir.json"
    run_cli("ir", *args, "-o", out, "--json", js)
    x, rate = read_wav_float(out)
    return x, rate, json.loads(js.read_text())


@pytest.mark.parametrize("receiver", ["omni", "binaural"])
def test_ir_equals_the_cli(tmp_path, shoebox, receiver):
    x, rate, stats = cli_ir(tmp_path, SHOEBOX, "--material-map", SHOEBOX_MAP, "--source", "2,3.5,1.5",
                            "--listener", "7,3.5,1.5", "--receiver", receiver, "--forward", "-1,0,0",
                            "--up", "0,0,1", "--seed", 5, "--threads", 2)
    r = shoebox.ir(SRC, LIS, receiver=receiver, forward=(-1, 0, 0), up=(0, 0, 1), seed=5, threads=1)
    assert r.samples.dtype == np.float32
    assert r.samples.shape == x.shape == ((1 if receiver == "omni" else 2), stats["ir_samples"])
    assert rate == r.sample_rate == 48000
    # Bit-identical (different thread counts too).
    assert np.array_equal(r.samples, x)
    assert r.params["rays"] == stats["settings"]["rays"] == 16384
    assert r.params["seed"] == 5 and r.params["receiver"] == receiver
    assert r.stats["direct"] == stats["direct"]
    assert r.stats["decay"] == stats["decay"]
    assert set(r.time_ms) == set(stats["time_ms"])


@pytest.mark.parametrize("receiver", ["omni", "binaural"])
def test_third_octave_ir_equals_the_cli(tmp_path, shoebox, receiver):
    x, rate, stats = cli_ir(tmp_path, SHOEBOX, "--material-map", SHOEBOX_MAP, "--source", "2,3.5,1.5",
                            "--listener", "7,3.5,1.5", "--receiver", receiver, "--forward", "-1,0,0", "--up", "0,0,1",
                            "--seed", 3, "--rays", 2000, "--bands", "third-octave", "--threads", 2)
    r = shoebox.ir(SRC, LIS, receiver=receiver, forward=(-1, 0, 0), up=(0, 0, 1), seed=3, rays=2000,
                   bands="third-octave", threads=1)
    assert np.array_equal(r.samples, x)
    assert r.params["bands"] == "third-octave" and r.stats["bands"] == "third-octave"
    assert r.stats["third_octave"]["decay"] == stats["third_octave"]["decay"]
    assert len(r.stats["third_octave"]["decay"]["t20_s"]) == 21
    assert [p["shift_octaves"] for p in r.stats["third_octave"]["passes"]] == [-1 / 3, 0.0, 1 / 3]
    # A batch's pair i is ir(seed=seed + i), as with octaves.
    b = shoebox.ir_batch([(SRC, LIS), ((3.0, 2.0, 1.2), LIS)], receiver=receiver, forward=(-1, 0, 0), up=(0, 0, 1),
                         seed=2, rays=2000, bands="third-octave", threads=2)
    assert np.array_equal(b[1].samples, r.samples) is False
    assert np.array_equal(b[0].samples, shoebox.ir(SRC, LIS, receiver=receiver, forward=(-1, 0, 0), up=(0, 0, 1),
                                                   seed=2, rays=2000, bands="third-octave").samples)


def test_ambisonic_ir_equals_the_cli(tmp_path, shoebox):
    """receiver='ambisonic' (issue 15): `earshot ir --receiver ambisonic`'s
    IR bit for bit, (order+1)^2 channels, W the omni IR."""
    x, rate, stats = cli_ir(tmp_path, SHOEBOX, "--material-map", SHOEBOX_MAP, "--source", "2,3.5,1.5",
                            "--listener", "7,3.5,1.5", "--receiver", "ambisonic", "--order", 2, "--forward",
                            "-1,0,0", "--up", "0,0,1", "--seed", 5, "--quality", "draft")
    r = shoebox.ir(SRC, LIS, receiver="ambisonic", order=2, forward=(-1, 0, 0), up=(0, 0, 1), seed=5,
                   quality="draft")
    assert r.samples.shape == x.shape == (9, stats["ir_samples"])
    assert np.array_equal(r.samples, x)
    omni = shoebox.ir(SRC, LIS, receiver="omni", seed=5, quality="draft")
    assert np.max(np.abs(r.samples[0] - omni.samples[0])) <= 1e-6 * np.max(np.abs(omni.samples[0]))


def test_options_reach_the_engine(tmp_path):
    x, _, stats = cli_ir(tmp_path, "--source", "0,0,-10", "--listener", "0,0,0", "--receiver", "omni",
                         "--rate", 44100, "--length", 0.25, "--air", "off")
    r = earshot.Scene().ir((0, 0, -10), (0, 0, 0), receiver="omni", sample_rate=44100, length=0.25, air="off")
    assert np.array_equal(r.samples, x)
    assert r.samples.shape == (1, round(0.25 * 44100))
    # Free field, no air: the direct sound is 1/r at r/c.
    d = r.stats["direct"]
    assert d["distance_m"] == pytest.approx(10.0)
    assert d["delay_s"] == pytest.approx(10.0 / 343.0)
    assert float(np.sum(r.samples.astype(np.float64) ** 2)) == pytest.approx(1 / 100.0, rel=1e-3)
    assert int(np.argmax(np.abs(r.samples[0]))) == pytest.approx(10.0 / 343.0 * 44100, abs=1)


def test_batch_pair_i_is_ir_with_seed_plus_i(shoebox):
    pairs = [((2, 3.5, 1.5), (7, 3.5, 1.5)), ((1, 1, 1), (8, 5, 2)), ((5, 5, 2), (3, 2, 1.2))]
    batch = shoebox.ir_batch(pairs, receiver="omni", quality="draft", seed=11, threads=2)
    assert len(batch) == 3
    for i, (s, l) in enumerate(pairs):
        one = shoebox.ir(s, l, receiver="omni", quality="draft", seed=11 + i, threads=1)
        assert np.array_equal(batch[i].samples, one.samples), i
        assert batch[i].params["seed"] == 11 + i
        assert batch[i].params["source"] == list(map(float, s))
    # Noise depends on the seed: two pairs never share samples.
    assert not np.array_equal(batch[0].samples[:, :1000], batch[1].samples[:, :1000])


def test_shared_trace_equals_the_cli(tmp_path, shoebox):
    """trace='shared' (issue 16): `earshot ir --trace shared`'s IR bit for
    bit; the listener-centred trace gives another realisation than the
    source's own, so the samples differ, not the energies."""
    x, _, stats = cli_ir(tmp_path, SHOEBOX, "--material-map", SHOEBOX_MAP, "--source", "2,3.5,1.5",
                         "--listener", "7,3.5,1.5", "--receiver", "omni", "--seed", 5, "--quality", "draft",
                         "--trace", "shared")
    r = shoebox.ir(SRC, LIS, receiver="omni", seed=5, quality="draft", trace="shared", threads=1)
    assert np.array_equal(r.samples, x)
    assert r.params["trace"] == stats["trace"] == "shared"
    own = shoebox.ir(SRC, LIS, receiver="omni", seed=5, quality="draft")
    assert own.params["trace"] == "per-source"
    assert not np.array_equal(own.samples, r.samples)
    assert np.sum(own.samples.astype(np.float64) ** 2) == pytest.approx(np.sum(r.samples.astype(np.float64) ** 2),
                                                                         rel=0.1)
    # auto is per source for one pair.
    assert shoebox.ir(SRC, LIS, receiver="omni", quality="draft", trace="auto").params["trace"] == "per-source"


def test_shared_batch_groups_the_pairs_by_listener(shoebox):
    """ir_batch(trace='shared'): the pairs at one listener are one trace with
    seed + the index of the group's first pair, and each IR equals that
    source traced alone the same way (a source's IR does not depend on who
    shares its trace); auto leaves a listener with fewer than 3 pairs per
    source."""
    other = (3.0, 2.0, 1.2)
    pairs = [((2, 3.5, 1.5), LIS), ((1, 1, 1), other), ((5, 5, 2), LIS), ((8, 1, 2), LIS), ((6, 6, 1), other)]
    shared = shoebox.ir_batch(pairs, receiver="omni", quality="draft", seed=20, threads=2, trace="shared")
    assert [r.params["trace"] for r in shared] == ["shared"] * 5
    for k, first in [(0, 0), (2, 0), (3, 0), (1, 1), (4, 1)]:
        alone = shoebox.ir(pairs[k][0], pairs[k][1], receiver="omni", quality="draft", seed=20 + first,
                           trace="shared", threads=1)
        assert np.array_equal(shared[k].samples, alone.samples), k
    auto = shoebox.ir_batch(pairs, receiver="omni", quality="draft", seed=20, threads=2, trace="auto")
    assert [r.params["trace"] for r in auto] == ["shared", "per-source", "shared", "shared", "per-source"]
    for k in (0, 2, 3):
        assert np.array_equal(auto[k].samples, shared[k].samples), k
    for k in (1, 4):
        own = shoebox.ir(pairs[k][0], pairs[k][1], receiver="omni", quality="draft", seed=20 + k, threads=1)
        assert np.array_equal(auto[k].samples, own.samples), k


def test_batch_accepts_an_array_and_is_thread_count_independent(shoebox):
    pairs = np.array([[[2, 3.5, 1.5], [7, 3.5, 1.5]], [[3, 3, 1], [6, 4, 2]]], dtype=np.float32)
    a = shoebox.ir_batch(pairs, receiver="binaural", quality="draft", threads=1)
    b = shoebox.ir_batch(pairs, receiver="binaural", quality="draft", threads=2)
    for x, y in zip(a, b):
        assert np.array_equal(x.samples, y.samples)
        assert x.samples.shape[0] == 2


def test_from_arrays_matches_the_same_room_from_gltf(tmp_path):
    import sys
    sys.path.insert(0, os.path.join(SOURCE_DIR, "tools"))
    from gltf_writer import Gltf
    v = np.array([[0, 0, 0], [6, 0, 0], [6, 4, 0], [0, 4, 0], [0, 0, 3], [6, 0, 3], [6, 4, 3], [0, 4, 3]], float)
    t = np.array([[0, 3, 7], [0, 7, 4], [1, 5, 6], [1, 6, 2], [0, 4, 5], [0, 5, 1], [3, 2, 6], [3, 6, 7],
                  [0, 1, 2], [0, 2, 3], [4, 7, 6], [4, 6, 5]])
    ids = np.array([0] * 8 + [1, 1, 2, 2])
    names = ["brick", "carpet_thick", "acoustic_ceiling_tile"]
    g = Gltf()
    prims = [g.primitive([tuple(p) for p in v.tolist()], [tuple(x) for x in t[ids == k].tolist()],
                         g.material(name)) for k, name in enumerate(names)]
    g.scene([g.node(mesh=g.mesh("box", prims))])
    g.write_gltf(str(tmp_path / "box.gltf"))
    a = earshot.Scene.from_arrays(v, t, ids, names)
    b = earshot.Scene(tmp_path / "box.gltf")
    assert a.triangle_count == b.triangle_count == 12
    assert a.closed and a.contains((1, 1, 1)) and a.contains((7, 1, 1)) is False
    assert a.distance_to_surface((1, 2, 1)) == pytest.approx(1.0)
    ra = a.ir((1, 1, 1.2), (4.5, 3, 1.6), receiver="omni", quality="draft")
    rb = b.ir((1, 1, 1.2), (4.5, 3, 1.6), receiver="omni", quality="draft")
    # Same triangles in the same order with the same materials: the same IR.
    assert np.array_equal(ra.samples, rb.samples)
    ea = np.array(ra.stats["decay"]["t30_s"])
    # The carpet and ceiling tiles matter: a room all of brick decays slower.
    brick = earshot.Scene.from_arrays(v, t, np.zeros(12, int), ["brick"])
    rbrick = brick.ir((1, 1, 1.2), (4.5, 3, 1.6), receiver="omni", quality="draft")
    assert np.all(np.array(rbrick.stats["decay"]["t30_s"][2:5]) > 1.5 * ea[2:5])


def test_from_arrays_with_material_dicts():
    v = np.array([[0, 0, 0], [5, 0, 0], [5, 4, 0], [0, 4, 0], [0, 0, 3], [5, 0, 3], [5, 4, 3], [0, 4, 3]], float)
    t = np.array([[0, 3, 7], [0, 7, 4], [1, 5, 6], [1, 6, 2], [0, 4, 5], [0, 5, 1], [3, 2, 6], [3, 6, 7],
                  [0, 1, 2], [0, 2, 3], [4, 7, 6], [4, 6, 5]])
    hard = {"absorption": [0.05] * 7, "scattering": 0.5}
    soft = {"absorption": [0.5] * 7, "scattering": 0.5}
    t_hard = earshot.Scene.from_arrays(v, t, np.zeros(12, int), {"hard": hard, "soft": soft}).ir(
        (1, 1, 1), (4, 3, 2), receiver="omni", quality="draft").stats["decay"]["t30_s"]
    t_soft = earshot.Scene.from_arrays(v, t, np.ones(12, int), {"hard": hard, "soft": soft}).ir(
        (1, 1, 1), (4, 3, 2), receiver="omni", quality="draft").stats["decay"]["t30_s"]
    # Eyring: T = 0.161 V / (-S ln(1 - a)); V = 60, S = 94.
    for a, t60 in ((0.05, t_hard), (0.5, t_soft)):
        eyring = 0.161 * 60 / (-94 * math.log(1 - a))
        assert t60[3] == pytest.approx(eyring, rel=0.25), (a, t60)


def test_an_ir_cut_by_the_automatic_lengths_cap_says_so():
    # A box that does not absorb rings past the 30 s cap: the IR stops there,
    # and its warnings say so (as `earshot ir` does); a given length does not.
    v = np.array([[0, 0, 0], [5, 0, 0], [5, 4, 0], [0, 4, 0], [0, 0, 3], [5, 0, 3], [5, 4, 3], [0, 4, 3]], float)
    t = np.array([[0, 3, 7], [0, 7, 4], [1, 5, 6], [1, 6, 2], [0, 4, 5], [0, 5, 1], [3, 2, 6], [3, 6, 7],
                  [0, 1, 2], [0, 2, 3], [4, 7, 6], [4, 6, 5]])
    lossless = earshot.Scene.from_arrays(v, t, np.zeros(12, int), {"w": {"absorption": [0] * 7, "scattering": 0.5}})
    r = lossless.ir((1, 1, 1), (4, 3, 2), receiver="omni", quality="draft", air="off")
    assert r.stats["tail"]["length_capped_at_s"] == 30.0
    assert r.samples.shape[-1] == pytest.approx(30.0 * r.sample_rate, rel=0.01)
    assert any("had not decayed by 60 dB at 30 s" in w for w in r.warnings), r.warnings
    given = lossless.ir((1, 1, 1), (4, 3, 2), receiver="omni", quality="draft", air="off", length=1.0)
    assert not any("had not decayed" in w for w in given.warnings), given.warnings


@pytest.mark.parametrize("kwargs,exc,text", [
    (dict(source=(float("nan"), 0, 0)), ValueError, "finite"),
    (dict(source="1,2,3"), TypeError, "string"),
    (dict(source=(1, 2)), ValueError, "shape"),
    (dict(listener=(0, 0, float("inf"))), ValueError, "finite"),
    (dict(sample_rate=-48000), ValueError, "sample_rate"),
    (dict(sample_rate="48k"), TypeError, "sample_rate"),
    (dict(rays=-5), ValueError, "rays"),
    (dict(rays=2.5), TypeError, "rays"),
    (dict(rays=0), ValueError, "rays"),
    (dict(receiver="ambisonic", order=4), ValueError, "order"),
    (dict(receiver="ambisonic", order=1.5), TypeError, "order"),
    (dict(receiver="ambisonic", hrtf="x.sofa"), ValueError, "hrtf"),
    (dict(receiver="stereo"), ValueError, "receiver"),
    (dict(quality="ultra"), ValueError, "ultra"),
    (dict(seed=-1), ValueError, "seed"),
    (dict(forward=(0, 1, 0), up=(0, 1, 0)), ValueError, "parallel"),
    (dict(source=(2e6, 0, 0)), ValueError, ""),
    (dict(length=0), ValueError, "length"),
    (dict(air="hot"), ValueError, ""),
    (dict(hrtf="/nonexistent.sofa"), FileNotFoundError, "nonexistent"),
    (dict(receiver="omni", hrtf="x.sofa"), ValueError, "hrtf"),
    (dict(order=2), ValueError, "order"),
    (dict(trace="both"), ValueError, "trace"),
    (dict(trace=1), TypeError, "trace"),
    (dict(trace="shared", converge=0.5), ValueError, "converge"),
    (dict(bands="sixth"), ValueError, "bands"),
    (dict(bands=3), TypeError, "bands"),
    (dict(bands="third-octave", trace="shared"), ValueError, "per-source"),
    (dict(colour="red"), TypeError, r"unknown option\(s\) \['colour'\]; the options are \['receiver'"),
])
def test_bad_arguments_raise(shoebox, kwargs, exc, text):
    args = dict(source=SRC, listener=LIS, quality="draft")
    args.update(kwargs)
    s, l = args.pop("source"), args.pop("listener")
    with pytest.raises(exc, match=text):
        shoebox.ir(s, l, **args)


def test_memory_limit_refuses_a_trace_past_it_until_raised(shoebox):
    # 30000 rays hold ~6 MB of trace state: refused under 4 MiB, traced
    # under 64 MiB; None sets the default (1 GiB) back.
    assert earshot.memory_limit() == 1 << 30
    try:
        earshot.set_memory_limit(4 << 20)
        assert earshot.memory_limit() == 4 << 20
        with pytest.raises(ValueError, match=r"30000 rays.*over the memory limit of 4.0 MiB "
                                             r"\(earshot.set_memory_limit\)"):
            shoebox.ir(SRC, LIS, quality="draft", receiver="omni", rays=30000)
        earshot.set_memory_limit(64 << 20)
        ir = shoebox.ir(SRC, LIS, quality="draft", receiver="omni", rays=30000)
        assert ir.samples.shape[-1] > 0
    finally:
        earshot.set_memory_limit(None)
    assert earshot.memory_limit() == 1 << 30
    with pytest.raises(ValueError):
        earshot.set_memory_limit(-1)
    with pytest.raises(TypeError):
        earshot.set_memory_limit("1G")


def _bytes_in(message):
    """The bytes of "needs about 12.3 MiB" in an error message, from above."""
    import re
    m = re.search(r"needs about ([0-9.]+) (MiB|GiB|bytes)", message)
    assert m, message
    scale = {"bytes": 1, "MiB": 1 << 20, "GiB": 1 << 30}[m.group(2)]
    return int((float(m.group(1)) + (0.05 if scale > 1 else 0)) * scale) + 1


def test_batch_ir_side_by_side_share_the_memory_limit(shoebox):
    """ir_batch on T threads checks each IR against the limit / T, so that
    the IRs at once stay within the limit; one over its share is made again
    alone, under the whole limit: nothing is lost, the same bits."""
    kw = dict(receiver="binaural", quality="draft", length=1.5)
    pairs = [(SRC, LIS), ((3.0, 2.0, 1.2), LIS)]
    alone = [shoebox.ir(s, l, seed=3 + i, threads=1, **kw) for i, (s, l) in enumerate(pairs)]  # HRTF loaded
    try:
        # The least limit one IR passes: raised to what each refusal names.
        limit = 1 << 20
        for _ in range(20):
            earshot.set_memory_limit(limit)
            try:
                shoebox.ir(*pairs[0], seed=3, threads=1, **kw)
                break
            except ValueError as e:
                assert "over the memory limit" in str(e)
                limit = max(_bytes_in(str(e)), limit + 1)
        else:
            pytest.fail("no limit found")
        batch = shoebox.ir_batch(pairs, seed=3, threads=2, trace="per-source", **kw)
        for i, one in enumerate(alone):
            assert np.array_equal(batch[i].samples, one.samples), i
            assert not one.warnings
        # Pair 0 needs the whole limit, so it was refused by its half of it
        # and made alone.
        assert any("made alone" in w and "2 IRs at once" in w for w in batch[0].warnings), batch[0].warnings
        # With room for both, nothing is made twice.
        earshot.set_memory_limit(4 * limit)
        again = shoebox.ir_batch(pairs, seed=3, threads=2, trace="per-source", **kw)
        assert all(not r.warnings for r in again)
        assert np.array_equal(again[0].samples, batch[0].samples)
    finally:
        earshot.set_memory_limit(None)


def test_empty_arrays_are_the_free_field():
    """No triangles, given as empty lists (float64 of shape (0,) to numpy)."""
    empty = earshot.Scene.from_arrays([], [], [], ["brick"])
    assert empty.triangle_count == 0
    a = empty.ir((0, 0, 0), (3, 0, 0), receiver="omni", quality="draft")
    b = earshot.Scene(None).ir((0, 0, 0), (3, 0, 0), receiver="omni", quality="draft")
    assert np.array_equal(a.samples, b.samples)
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(ValueError, match="materials: every number must be finite"):
        earshot.Scene.from_arrays(v, [[0, 1, 2]], [0], {"x": {"absorption": [float("nan")] * 7}})


def test_bad_scenes_raise(tmp_path):
    with pytest.raises(FileNotFoundError):
        earshot.Scene(tmp_path / "missing.gltf")
    bad = tmp_path / "bad.gltf"
    bad.write_text('{"asset": {"version": "2.0"}, "buffers": [{"byteLength": 1e30}] SECRET')
    with pytest.raises(ValueError) as e:
        earshot.Scene(bad)
    assert "bad.gltf" in str(e.value) and "SECRET" not in str(e.value)
    with pytest.raises(ValueError, match="no material"):
        earshot.Scene.from_arrays(np.zeros((3, 3)), [[0, 1, 2]], [0], ["no_such_material"])
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(TypeError, match="integer"):
        earshot.Scene.from_arrays(v, np.array([[0, 1, 2]], float), [0], ["brick"])
    with pytest.raises(ValueError, match="outside"):
        earshot.Scene.from_arrays(v, [[0, 1, 3]], [0], ["brick"])
    with pytest.raises(ValueError, match="material_ids"):
        earshot.Scene.from_arrays(v, [[0, 1, 2]], [1], ["brick"])
    with pytest.raises(ValueError, match="shape"):
        earshot.Scene.from_arrays(v[:, :2], [[0, 1, 2]], [0], ["brick"])
    with pytest.raises(ValueError, match="finite"):
        earshot.Scene.from_arrays(np.full((3, 3), np.nan), [[0, 1, 2]], [0], ["brick"])
    with pytest.raises(TypeError):
        earshot.Scene.from_arrays(np.array([["a", "b", "c"]] * 3), [[0, 1, 2]], [0], ["brick"])
    with pytest.raises(ValueError, match=r"absorption"):
        earshot.Scene.from_arrays(v, [[0, 1, 2]], [0], {"x": {"absorption": [1.7] * 7}})
    with pytest.raises(ValueError, match="outside"):
        # A glTF may not reach outside its folder (unless allowed).
        (tmp_path / "sub").mkdir()
        esc = tmp_path / "sub" / "escape.gltf"
        esc.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "../x.bin", "byteLength": 4}]}))
        (tmp_path / "x.bin").write_bytes(b"\0" * 4)
        earshot.Scene(esc)


def test_batch_errors_name_the_pair(shoebox):
    with pytest.raises(ValueError, match=r"pairs\[1\]"):
        shoebox.ir_batch([(SRC, LIS), (SRC, (0, float("nan"), 0))], receiver="omni")
    with pytest.raises(ValueError, match="shape"):
        shoebox.ir_batch(np.zeros((2, 3, 3)), receiver="omni")
