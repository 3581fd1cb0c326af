"""earshot.analysis on numpy arrays: known decays, the CLI's numbers, JND
comparison, and errors."""
import json
import math

import numpy as np
import pytest

import earshot
from earshot import analysis
from conftest import run_cli


def decaying_noise(t60, rate=48000, seconds=None, seed=0, delay=0.01):
    seconds = seconds or 3 * t60  # 90 dB: no truncation bias
    n = int(seconds * rate)
    t = np.arange(n) / rate
    x = np.random.default_rng(seed).standard_normal(n) * 10 ** (-3 * t / t60)
    d = int(delay * rate)
    out = np.zeros(n + d)
    out[d] = 1.0  # a direct sound
    out[d:] += 0.3 * x
    return out


def test_known_decay_time():
    # One noise realisation's T scatters by several % in an octave (few
    # independent samples over the fit); the mean over 4 seeds is within
    # 1 JND (5 %) of the true 0.8 s in every band.
    runs = [analysis.analyze(decaying_noise(0.8, seed=s), 48000, noise="none") for s in range(4)]
    assert runs[0]["T30"].shape == (1, 8)
    for m in ("T20", "T30"):
        mean = np.mean([a[m][0] for a in runs], axis=0)
        assert np.allclose(mean, 0.8, rtol=0.05), (m, mean)
    assert 0 <= runs[0]["D50"][0, 7] <= 1


def test_same_numbers_as_the_cli(tmp_path):
    x = decaying_noise(0.5, seconds=1.0).astype(np.float32)
    from earshot.dataset import _write_wav_float
    _write_wav_float(str(tmp_path / "x.wav"), x[None, :], 48000)
    cli = json.loads(run_cli("analyze", tmp_path / "x.wav", "--json").stdout)
    a = analysis.analyze(x, 48000)
    text = json.dumps(cli)
    # Every T30 and C80 the CLI printed is ours, to the digits it printed.
    ours = set()
    for m in ("T30", "C80"):
        for v in a[m][0]:
            if math.isfinite(v):
                ours.add(round(v, 3))
    found = [round(v, 3) for v in _numbers(cli)]
    assert ours and ours <= set(found), (ours, text[:400])


def test_third_octaves_same_numbers_as_the_cli(tmp_path):
    x = decaying_noise(0.8, seconds=1.5).astype(np.float32)
    from earshot.dataset import _write_wav_float
    _write_wav_float(str(tmp_path / "x.wav"), x[None, :], 48000)
    cli = json.loads(run_cli("analyze", tmp_path / "x.wav", "--json", "--bands", "third-octave").stdout)
    a = analysis.analyze(x, 48000, bands="third-octave")
    bands = cli["channels"][0]["bands"]
    assert a["T30"].shape == (1, 22) and len(bands) == 22
    assert a.bands_hz[-1] == 0 and abs(a.bands_hz[0] - 99.21) < 0.01
    for k, b in enumerate(bands):
        for m in ("T20", "C80"):
            if b[m] is None:
                assert math.isnan(a[m][0][k])
            else:
                assert a[m][0][k] == pytest.approx(b[m], rel=1e-9), (k, m)
    # Noise decaying at one rate reads it in every third octave from 250 Hz
    # to 8 kHz, within 4 sigma of ISO 3382-2 A.2's scatter for T30 (0.55 T
    # sqrt(1 / (B T)), B the band's width, 0.23 fc).
    for k in range(4, 20):
        bandwidth = 0.2316 * a.bands_hz[k]
        assert abs(a["T30"][0][k] / 0.8 - 1) < 4 * 0.55 * math.sqrt(1 / (bandwidth * 0.8)), (a.bands_hz[k], a["T30"][0][k])
    with pytest.raises(ValueError, match="bands"):
        analysis.analyze(x, 48000, bands="sixth")


def _numbers(obj):
    if isinstance(obj, dict):
        for v in obj.values():
            yield from _numbers(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _numbers(v)
    elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
        yield float(obj)


def test_compare_in_jnd():
    a = decaying_noise(0.6, seed=1)
    b = decaying_noise(0.6, seed=1)
    c = decaying_noise(0.9, seed=1)
    same = analysis.compare(a, b, 48000)
    assert same["within_tolerance"] and same["failures"] == 0 and same["worst_jnd"] == 0
    diff = analysis.compare(c, a, 48000, tolerance={"metrics": {"C50": False}}, bands=["1000"])
    t30 = [r for r in diff["rows"] if r["metric"] == "T30"][0]
    assert t30["band"] == "1 kHz"
    assert t30["difference_jnd"] == pytest.approx((t30["test"] - t30["reference"]) / (0.05 * t30["reference"]))
    assert t30["difference_jnd"] > 5 and t30["verdict"] == "fail"
    assert not diff["within_tolerance"]
    assert [r["verdict"] for r in diff["rows"] if r["metric"] == "C50"] == ["skipped"]
    with pytest.raises(ValueError, match="tolerance: every number must be finite"):
        analysis.compare(c, a, 48000, tolerance={"default_jnd": float("inf")})
    assert analysis.jnd("T30", 2.0) == pytest.approx(0.1)
    assert analysis.difference_in_jnd("C80", 3.0, 1.0) == pytest.approx(2.0)


def test_binaural_cues_of_an_ir(shoebox):
    # Source on the listener's left (forward -x, up +z: left is -y).
    r = shoebox.ir((5, 1.5, 1.5), (5, 3.5, 1.5), forward=(-1, 0, 0), up=(0, 0, 1), quality="draft")
    b = analysis.binaural(r.samples, r.sample_rate)
    assert b["itd_s"] > 0.0004 and b["ild_db"] > 3
    assert 0 <= b["iacc_e3"] <= 1


@pytest.mark.parametrize("x,rate,exc", [
    (np.zeros(1000), 48000, ValueError),            # silent
    (np.array([1.0, np.nan, 0.0]), 48000, ValueError),
    (np.ones((2, 3, 4)), 48000, ValueError),
    (np.array(["a", "b"]), 48000, TypeError),
    (np.ones(100), -1, ValueError),
    (np.ones(100), "fast", TypeError),
    (np.ones((0,)), 48000, ValueError),
])
def test_bad_input_raises(x, rate, exc):
    with pytest.raises(exc):
        analysis.analyze(x, rate)


def test_frames_by_channels_is_refused_with_the_fix():
    # soundfile and scipy read a WAV as (frames, channels); taken as it
    # stands that was 48,000 channels of 2 samples (12 s of NaNs, no error).
    ir = np.zeros((2, 4800), dtype=np.float32)
    ir[:, 10] = 1.0
    ir[:, 11:] = np.exp(-np.arange(4789) / 500.0) * 0.1
    for call in (lambda x: analysis.analyze(x, 48000), lambda x: analysis.binaural(x, 48000),
                 lambda x: analysis.compare(x, ir, 48000)):
        with pytest.raises(ValueError, match=r"more channels than frames.*\.T"):
            call(ir.T)
    assert analysis.analyze(ir, 48000).channels == 2
    with pytest.raises(ValueError, match=r"reference: shape \(4800, 2\)"):
        analysis.compare(ir, ir.T, 48000)


def test_binaural_needs_two_channels():
    with pytest.raises(ValueError, match="2 channels"):
        analysis.binaural(np.ones((1, 100)), 48000)
