"""ISO 3382-1 room-acoustic parameters of impulse responses (numpy arrays),
binaural cues, and comparison in just-noticeable differences: the engine's
analysis (`earshot analyze` / `earshot compare`), the same numbers.

    a = earshot.analysis.analyze(ir, 48000)     # ir: (frames,) or (channels, frames)
    a["T30"]            # array (channels, 8): 125 Hz .. 8 kHz octaves, then broadband; NaN where n/a
    a.na_reasons        # {(channel, metric, band_hz): why}
    a.bands_hz          # the bands' centres (0: broadband); bands="third-octave": 21 + broadband
    earshot.analysis.compare(test, reference, 48000, tolerance=1.0)["within_tolerance"]

Bands: BANDS_HZ = (125, 250, 500, 1000, 2000, 4000, 8000, 0), 0 meaning
broadband. Metrics: EDT, T20, T30 (s), C50, C80 (dB), D50 (fraction), Ts (s).
JND (ISO 3382-1 Table A.1): 5 % for EDT/T20/T30, 1 dB for C50/C80, 0.05 for
D50, 10 ms for Ts. Samples are analysed as float32 (the engine's type).
"""
import json as _json
import math as _math
import os as _os

import numpy as _np

from . import _earshot


def _json_text(doc, what):
    """JSON text of a dict the engine reads (here and in earshot's Scene and
    render); a NaN or infinity is named here: json.dumps would write NaN,
    which JSON does not have."""
    try:
        return _json.dumps(doc, allow_nan=False)
    except ValueError:
        raise ValueError(f"{what}: every number must be finite (a NaN or infinity was given)") from None
    except TypeError as e:
        raise TypeError(f"{what}: not JSON-serialisable: {e}") from None
    except RecursionError:  # the engine's JSON readers stop at 128 levels in any case
        raise ValueError(f"{what}: nested too deeply") from None


METRICS = ("EDT", "T20", "T30", "C50", "C80", "D50", "Ts")
BANDS_HZ = tuple(_earshot.bands_hz) + (0.0,)

__all__ = ["METRICS", "BANDS_HZ", "Analysis", "analyze", "binaural", "compare", "jnd", "difference_in_jnd"]


def _samples(name, x, channels=None):
    if isinstance(x, (str, bytes)):
        raise TypeError(f"{name}: expected an array of samples")
    a = _np.asarray(x)
    if a.dtype.kind not in "fiu" or a.dtype == _np.bool_:
        raise TypeError(f"{name}: expected real samples, got dtype {a.dtype}")
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2:
        raise ValueError(f"{name}: expected shape (frames,) or (channels, frames), got {a.shape}")
    if a.shape[0] > a.shape[1]:
        # (frames, channels), as soundfile and scipy read a WAV: analysed as
        # it stands it was thousands of channels of a few samples each.
        raise ValueError(f"{name}: shape {a.shape} has more channels than frames; expected (channels, frames) "
                         f"(for a (frames, channels) array, as soundfile reads a WAV, pass {name}.T)")
    if channels is not None and a.shape[0] != channels:
        raise ValueError(f"{name}: expected {channels} channels, got {a.shape[0]}")
    if a.shape[1] == 0:
        raise ValueError(f"{name}: no samples")
    return _np.ascontiguousarray(a, dtype=_np.float32)


def _rate(rate):
    if isinstance(rate, bool) or not isinstance(rate, (int, float, _np.integer, _np.floating)):
        raise TypeError("sample_rate: expected a number")
    r = float(rate)
    if not (_math.isfinite(r) and 1000.0 <= r <= 1e6):
        raise ValueError(f"sample_rate: expected 1000 .. 1e6 Hz, got {r}")
    return r


class Analysis:
    """Per channel and band metrics. a[metric] -> float array (channels,
    len(BANDS_HZ)); a.bands (a list per channel of dicts per band with every
    field: onset_s, decay_end_s, noise_floor_db, dynamic_range_db, ...);
    a.na_reasons {(channel, metric, band_hz): reason}."""

    def __init__(self, raw, sample_rate):
        self.sample_rate = sample_rate
        self.bands = raw
        self.bands_hz = _np.array([b["band_hz"] for b in raw[0]]) if raw else _np.array(BANDS_HZ)
        self._values = {m: _np.array([[b[m] for b in ch] for ch in raw], dtype=float) for m in METRICS}
        self.na_reasons = {}
        for c, ch in enumerate(raw):
            for b in ch:
                for m in METRICS:
                    if m + "_na" in b:
                        self.na_reasons[(c, m, b["band_hz"])] = b[m + "_na"]

    def __getitem__(self, metric):
        if metric not in self._values:
            raise KeyError(f"{metric!r}: metrics are {', '.join(METRICS)}")
        return self._values[metric]

    @property
    def channels(self):
        return len(self.bands)

    def table(self):
        """Rows {channel, band_hz, EDT, ..., Ts}: e.g. for csv.DictWriter."""
        return [dict(channel=c, band_hz=b["band_hz"], **{m: b[m] for m in METRICS})
                for c, ch in enumerate(self.bands) for b in ch]


def analyze(samples, sample_rate, *, noise="lundeby", window=(0.0, _math.inf), window_origin="emission",
            exclude_direct=False, bands="octave"):
    """ISO 3382-1 parameters of each channel of `samples` ((frames,) or
    (channels, frames)). noise: 'lundeby' (measured IRs: truncate at the
    noise, compensate) or 'none' (exact, noise-free data). window: (start,
    end) seconds from the emission (window_origin 'emission') or the direct
    sound ('direct'); exclude_direct zeroes the direct sound. bands:
    'octave' (BANDS_HZ) or 'third-octave' (21 third octaves 100 Hz - 10 kHz
    at their exact centres, then broadband 0; `earshot analyze --bands
    third-octave`); the result's bands_hz says which. Raises ValueError for
    silent, non-finite or too short signals."""
    if not isinstance(bands, str):
        raise TypeError("bands: expected 'octave' or 'third-octave'")
    a = _samples("samples", samples)
    r = _rate(sample_rate)
    try:
        w0, w1 = (float(window[0]), float(window[1]))
    except (TypeError, ValueError, IndexError):
        raise TypeError("window: expected (start_s, end_s)") from None
    return Analysis(_earshot._analyze(a, r, noise, w0, w1, window_origin, bool(exclude_direct), bands), r)


def binaural(samples, sample_rate):
    """Binaural cues of a (2, frames) IR (left, right): itd_s (positive: left
    ear leads), ild_db (positive: left louder), iacc per band (early, late),
    iacc_e3, iacc_l3."""
    return _earshot._binaural(_samples("samples", samples, channels=2), _rate(sample_rate))


def compare(test, reference, sample_rate, *, tolerance=1.0, bands=None, noise="lundeby"):
    """Compares two IRs' parameters channel by channel in JND. tolerance: a
    number of JND for every metric and band, a dict or a path in the format
    of `earshot compare --tolerance` (docs). bands: names to compare ('125'
    .. '8000', 'broadband'), default all. Returns {rows: [{channel, metric,
    band, test, reference, difference_jnd, limit_jnd, verdict, note}],
    failures, worst_jnd, within_tolerance}."""
    t = _samples("test", test)
    ref = _samples("reference", reference)
    r = _rate(sample_rate)
    text, jnd_limit = None, 1.0
    if isinstance(tolerance, dict):
        text = _json_text(tolerance, "tolerance")
    elif isinstance(tolerance, (str, _os.PathLike)):
        p = _os.fspath(tolerance)
        if not _os.path.isfile(p):
            raise FileNotFoundError(f"{p}: no such tolerance file")
        with open(p, "rb") as f:
            text = f.read(1 << 20).decode("utf-8", errors="replace")
    elif isinstance(tolerance, (int, float)) and not isinstance(tolerance, bool):
        jnd_limit = float(tolerance)
    else:
        raise TypeError("tolerance: expected a number of JND, a dict or a path")
    names = [] if bands is None else [str(b) for b in bands]
    return _earshot._compare(t, ref, r, text, jnd_limit, names, noise)


def jnd(metric, reference):
    """Size of one JND of `metric` at the reference value."""
    return _earshot._jnd_size(metric, float(reference))


def difference_in_jnd(metric, test, reference):
    """(test - reference) / JND."""
    return _earshot._difference_in_jnd(metric, float(test), float(reference))
